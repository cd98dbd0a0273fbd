#!/usr/bin/env python3
"""Writes the hand-made E57 test files of tests/e57_io_test.cpp (and the E57 fuzz seeds, fuzz/make_seeds.py).

They are built here byte by byte, from the standard's description of the format (ASTM E2807) and independently of
scan2model's C++ writer, to exercise the reader paths that writer never produces: spherical coordinates, colour,
row/column indices, sphericalInvalidState, isIntensityInvalid / isColorInvalid, constant (zero-bit) fields, a
namespaced extension field, ScaledInteger offsets, an explicit bitPackCodec entry, several data packets whose
bitstreams are cut in the middle of values, empty packets, index packets, a second compressed vector (a
groupingByLine scheme) that the reader must skip, and images2D entries. Their layout follows the ASTM's published
example files (the XML of the Z+F scan "sp412" on libe57.org, written by the reference implementation):
header at byte 0, compressed-vector sections from byte 48 on, each a 32-byte section header followed by data
packets and, at its end, an index packet; the XML section last.

Every value is a simple function of the record number, restated in the test (tests/e57_io_test.cpp), which checks
the points read back against it. Run again after a change: python3 tests/data/e57/make_e57_files.py
"""
import math
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))
PAGE = 1024
PAYLOAD = 1020
NAMESPACE = "http://www.astm.org/COMMIT/E57/2010-e57-v1.0"


def crc32c(data):
    """CRC-32C (Castagnoli): reflected polynomial 0x82F63B78, initial value and final xor 0xFFFFFFFF."""
    crc = 0xFFFFFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0x82F63B78 if crc & 1 else crc >> 1
    return crc ^ 0xFFFFFFFF


def logical_to_physical(logical):
    return (logical // PAYLOAD) * PAGE + logical % PAYLOAD


def pages(logical):
    """The physical file: 1020 payload bytes per page (the last padded with zeros), each followed by its CRC-32C
    stored most significant byte first."""
    out = bytearray()
    for start in range(0, max(len(logical), 1), PAYLOAD):
        payload = logical[start:start + PAYLOAD].ljust(PAYLOAD, b"\0")
        out += payload + struct.pack(">I", crc32c(payload))
    return bytes(out)


def bit_width(minimum, maximum):
    return (maximum - minimum).bit_length()


class Field:
    """A prototype field and its values; `xml` is its prototype element."""

    def __init__(self, name, kind, values, minimum=None, maximum=None, scale=None, offset=None):
        self.name, self.kind, self.values = name, kind, values
        self.minimum, self.maximum, self.scale, self.offset = minimum, maximum, scale, offset

    def width(self):
        if self.kind == "single":
            return 32
        if self.kind == "double":
            return 64
        return bit_width(self.minimum, self.maximum)

    def bits(self):
        """The whole bytestream as a list of bits, least significant first (the bit-pack codec)."""
        out = []
        for v in self.values:
            if self.kind == "single":
                raw = struct.unpack("<I", struct.pack("<f", v))[0]
            elif self.kind == "double":
                raw = struct.unpack("<Q", struct.pack("<d", v))[0]
            else:
                assert self.minimum <= v <= self.maximum, (self.name, v)
                raw = v - self.minimum
            out += [(raw >> b) & 1 for b in range(self.width())]
        return out

    def xml(self):
        if self.kind in ("single", "double"):
            return f'<{self.name} type="Float" precision="{self.kind}"/>'
        attrs = f'minimum="{self.minimum}" maximum="{self.maximum}"'
        if self.kind == "scaled":
            attrs += f' scale="{self.scale!r}"'
            if self.offset is not None:
                attrs += f' offset="{self.offset!r}"'
            return f'<{self.name} type="ScaledInteger" {attrs}/>'
        return f'<{self.name} type="Integer" {attrs}/>'


def to_bytes(bits):
    out = bytearray((len(bits) + 7) // 8)
    for i, b in enumerate(bits):
        out[i // 8] |= b << (i % 8)
    return bytes(out)


def align4(buf):
    buf += b"\0" * (-len(buf) % 4)


def compressed_vector(logical, fields, cuts, empty_after=(), index=True):
    """Appends a compressed-vector section to the logical stream; `cuts` are the record numbers at which data
    packets end (the last one the record count). Each non-final packet carries the whole bytes of each bitstream
    up to its last record, so values straddle packets; the final packet carries the rest. Returns the section's
    physical offset (the XML's fileOffset)."""
    align4(logical)
    begin = len(logical)
    logical += b"\0" * 32
    streams = [to_bytes(f.bits()) for f in fields]
    emitted = [0] * len(fields)
    entries = []
    first = 0
    for p, last in enumerate(cuts):
        at = len(logical)
        entries.append((first, logical_to_physical(at)))
        chunks = []
        for k, f in enumerate(fields):
            upto = len(streams[k]) if last == cuts[-1] else last * f.width() // 8
            chunks.append(streams[k][emitted[k]:upto])
            emitted[k] = upto
        body = struct.pack("<%dH" % len(chunks), *[len(c) for c in chunks]) + b"".join(chunks)
        length = 6 + len(body)
        length += -length % 4
        logical += struct.pack("<BBHH", 1, 0, length - 1, len(fields)) + body
        align4(logical)
        if p in empty_after:  # an empty packet: type 2, a reserved byte, length - 1, then filler
            logical += struct.pack("<BBH", 2, 0, 12 - 1) + b"\0" * 8
        first = last
    index_physical = 0
    if index:
        at = len(logical)
        index_physical = logical_to_physical(at)
        length = 16 + 16 * len(entries)
        logical += struct.pack("<BBHHB9x", 0, 0, length - 1, len(entries), 0)
        for record, offset in entries:
            logical += struct.pack("<QQ", record, offset)
    struct.pack_into("<B7xQQQ", logical, begin, 1, len(logical) - begin, logical_to_physical(begin + 32),
                     index_physical)
    return logical_to_physical(begin)


def e57_file(sections_and_xml):
    """Header, then the sections (a function filling the logical stream and returning the data3D XML), then the
    XML section."""
    logical = bytearray(48)
    body = sections_and_xml(logical)
    xml = ('<?xml version="1.0" encoding="UTF-8"?>\n'
           f'<e57Root type="Structure" xmlns="{NAMESPACE}" xmlns:ext="http://example.org/ext">\n'
           '  <formatName type="String"><![CDATA[ASTM E57 3D Imaging Data File]]></formatName>\n'
           '  <guid type="String"><![CDATA[{8A3F0C2E-1D4B-4E5F-9A6B-7C8D9E0F1A2B}]]></guid>\n'
           '  <versionMajor type="Integer">1</versionMajor>\n'
           '  <versionMinor type="Integer"/>\n'
           '  <e57LibraryVersion type="String"><![CDATA[hand-made test file]]></e57LibraryVersion>\n'
           '  <coordinateMetadata type="String"/>\n'
           '  <creationDateTime type="Structure">\n'
           '    <dateTimeValue type="Float">9.6758299097398019e+008</dateTimeValue>\n'
           '    <isAtomicClockReferenced type="Integer"/>\n'
           '  </creationDateTime>\n' + body + '</e57Root>\n').encode()
    align4(logical)
    xml_logical = len(logical)
    logical += xml
    n_pages = (len(logical) + PAYLOAD - 1) // PAYLOAD
    struct.pack_into("<8sIIQQQQ", logical, 0, b"ASTM-E57", 1, 0, n_pages * PAGE, logical_to_physical(xml_logical),
                     len(xml), PAGE)
    return pages(bytes(logical))


def pose_xml(w, x, y, z, tx, ty, tz):
    return ('      <pose type="Structure">\n        <rotation type="Structure">\n'
            f'          <w type="Float">{w!r}</w>\n          <x type="Float">{x!r}</x>\n'
            f'          <y type="Float">{y!r}</y>\n          <z type="Float">{z!r}</z>\n'
            '        </rotation>\n        <translation type="Structure">\n'
            f'          <x type="Float">{tx!r}</x>\n          <y type="Float">{ty!r}</y>\n'
            f'          <z type="Float">{tz!r}</z>\n        </translation>\n      </pose>\n')


def points_xml(offset, count, fields, codecs=""):
    proto = "".join(f"          {f.xml()}\n" for f in fields)
    return (f'      <points type="CompressedVector" fileOffset="{offset}" recordCount="{count}">\n'
            f'        <prototype type="Structure">\n{proto}        </prototype>\n'
            f'        <codecs type="Vector" allowHeterogeneousChildren="1">{codecs}</codecs>\n      </points>\n')


# ----------------------------------------------------------------------------------------- spherical_grid.e57
# One scan of ROWS x COLS records on a scanner's grid (row i, column j, record r = i * COLS + j):
#   sphericalRange     ScaledInteger [0, 5000], scale 0.001 (13 bits): raw 2000 + 7 i + 3 j
#   sphericalAzimuth   Float single: -0.5 + 0.1 j        sphericalElevation  Float single: -0.3 + 0.05 i
#   intensity          Integer [0, 4095] (12 bits): (37 i + 11 j) mod 4096
#   isIntensityInvalid Integer [0, 1]: 1 when (i + j) mod 5 == 0
#   colorRed/Green/Blue Integer [0, 255]: 16 i mod 256, 8 j mod 256, (i + j) mod 256
#   rowIndex [0, ROWS - 1], columnIndex [0, COLS - 1]
#   sphericalInvalidState Integer [0, 2]: 2 when r mod 7 == 3, else 1 when r mod 11 == 5, else 0
# Pose: rotation by 0.5 rad about (0, 0, 1), translation (10, -5, 1.5). Data packets end at records 100, 101, 250
# and 480 (the second holds a single record, so several bitstreams give it no byte at all), an empty packet after
# the first, an index packet at the end. A groupingByLine scheme (one group per column) has its own section.
ROWS, COLS = 12, 40


def spherical_grid(logical):
    n = ROWS * COLS
    ij = [(r // COLS, r % COLS) for r in range(n)]
    fields = [
        Field("sphericalRange", "scaled", [2000 + 7 * i + 3 * j for i, j in ij], 0, 5000, 0.001),
        Field("sphericalAzimuth", "single", [-0.5 + 0.1 * j for i, j in ij]),
        Field("sphericalElevation", "single", [-0.3 + 0.05 * i for i, j in ij]),
        Field("intensity", "int", [(37 * i + 11 * j) % 4096 for i, j in ij], 0, 4095),
        Field("isIntensityInvalid", "int", [1 if (i + j) % 5 == 0 else 0 for i, j in ij], 0, 1),
        Field("colorRed", "int", [(16 * i) % 256 for i, j in ij], 0, 255),
        Field("colorGreen", "int", [(8 * j) % 256 for i, j in ij], 0, 255),
        Field("colorBlue", "int", [(i + j) % 256 for i, j in ij], 0, 255),
        Field("rowIndex", "int", [i for i, j in ij], 0, ROWS - 1),
        Field("columnIndex", "int", [j for i, j in ij], 0, COLS - 1),
        Field("sphericalInvalidState", "int", [2 if r % 7 == 3 else 1 if r % 11 == 5 else 0 for r in range(n)], 0, 2),
    ]
    offset = compressed_vector(logical, fields, [100, 101, 250, n], empty_after=(0,))
    groups = [Field("idElementValue", "int", list(range(COLS)), 0, COLS - 1),
              Field("startPointIndex", "int", list(range(COLS)), 0, n),
              Field("pointCount", "int", [ROWS] * COLS, 0, n)]
    groups_offset = compressed_vector(logical, groups, [COLS])
    c, s = math.cos(0.25), math.sin(0.25)
    return ('  <data3D type="Vector" allowHeterogeneousChildren="1">\n    <vectorChild type="Structure">\n'
            '      <guid type="String"><![CDATA[{D2629847-A1DB-4579-9E86-5D146B68BEA5}]]></guid>\n'
            '      <name type="String"><![CDATA[grid]]></name>\n      <description type="String"/>\n'
            '      <sensorVendor type="String"><![CDATA[none]]></sensorVendor>\n'
            '      <temperature type="Float"/>\n'
            + pose_xml(c, 0.0, 0.0, s, 10.0, -5.0, 1.5) +
            '      <indexBounds type="Structure">\n'
            f'        <rowMinimum type="Integer"/>\n        <rowMaximum type="Integer">{ROWS - 1}</rowMaximum>\n'
            f'        <columnMinimum type="Integer"/>\n        <columnMaximum type="Integer">{COLS - 1}</columnMaximum>\n'
            '      </indexBounds>\n'
            '      <intensityLimits type="Structure">\n        <intensityMinimum type="Integer"/>\n'
            '        <intensityMaximum type="Integer">4095</intensityMaximum>\n      </intensityLimits>\n'
            '      <pointGroupingSchemes type="Structure">\n        <groupingByLine type="Structure">\n'
            '          <idElementName type="String"><![CDATA[columnIndex]]></idElementName>\n'
            f'          <groups type="CompressedVector" fileOffset="{groups_offset}" recordCount="{COLS}">\n'
            '            <prototype type="Structure">\n'
            + "".join(f"              {g.xml()}\n" for g in groups) +
            '            </prototype>\n            <codecs type="Vector" allowHeterogeneousChildren="1"/>\n'
            '          </groups>\n        </groupingByLine>\n      </pointGroupingSchemes>\n'
            + points_xml(offset, n, fields) +
            '    </vectorChild>\n  </data3D>\n'
            '  <images2D type="Vector" allowHeterogeneousChildren="1">\n    <vectorChild type="Structure">\n'
            '      <guid type="String"><![CDATA[{5E36E0E0-D577-478D-8A45-3CA5D4809B0F}]]></guid>\n'
            '      <name type="String"><![CDATA[photo]]></name>\n    </vectorChild>\n  </images2D>\n')


# ----------------------------------------------------------------------------------------- cartesian_mixed.e57
# Two scans.
# Scan 0 ("no pose", 300 records k): cartesianX/Y/Z ScaledInteger [-1000, 1000] (11 bits), scale 0.0005, offset
#   10 / -20 / 0.5: raw (37 k) mod 2001 - 1000, (53 k) mod 2001 - 1000, (11 k) mod 2001 - 1000;
#   colorRed/Green/Blue Integer [0, 255]: k mod 256, (3 k) mod 256, (7 k) mod 256; isColorInvalid 1 when k mod 9 == 0;
#   returnIndex Integer [0, 0] (no bits); timeStamp Float double 0.25 k; ext:quality Integer [-3, 3] (3 bits):
#   k mod 7 - 3 (an extension field in its own namespace). An explicit bitPackCodec entry in codecs; packets end
#   at 150 and 300; no index packet.
# Scan 1 ("posed", 50 records k): cartesianX/Y/Z Float double: (0.1 k, 1 - 0.02 k, 0.003 k^2);
#   cartesianInvalidState Integer [0, 1]: 1 (a direction only) when k mod 4 == 1. Pose: rotation by 0.7 rad about
#   (1, 2, 2) / 3, translation (1.5, -2, 0.25). One data packet and an index packet.
def cartesian_mixed(logical):
    n0 = 300
    f0 = [
        Field("cartesianX", "scaled", [(37 * k) % 2001 - 1000 for k in range(n0)], -1000, 1000, 0.0005, 10.0),
        Field("cartesianY", "scaled", [(53 * k) % 2001 - 1000 for k in range(n0)], -1000, 1000, 0.0005, -20.0),
        Field("cartesianZ", "scaled", [(11 * k) % 2001 - 1000 for k in range(n0)], -1000, 1000, 0.0005, 0.5),
        Field("colorRed", "int", [k % 256 for k in range(n0)], 0, 255),
        Field("colorGreen", "int", [(3 * k) % 256 for k in range(n0)], 0, 255),
        Field("colorBlue", "int", [(7 * k) % 256 for k in range(n0)], 0, 255),
        Field("isColorInvalid", "int", [1 if k % 9 == 0 else 0 for k in range(n0)], 0, 1),
        Field("returnIndex", "int", [0] * n0, 0, 0),
        Field("timeStamp", "double", [0.25 * k for k in range(n0)]),
        Field("ext:quality", "int", [k % 7 - 3 for k in range(n0)], -3, 3),
    ]
    o0 = compressed_vector(logical, f0, [150, n0], index=False)
    n1 = 50
    f1 = [
        Field("cartesianX", "double", [0.1 * k for k in range(n1)]),
        Field("cartesianY", "double", [1.0 - 0.02 * k for k in range(n1)]),
        Field("cartesianZ", "double", [0.003 * k * k for k in range(n1)]),
        Field("cartesianInvalidState", "int", [1 if k % 4 == 1 else 0 for k in range(n1)], 0, 1),
    ]
    o1 = compressed_vector(logical, f1, [n1])
    half = 0.35
    axis = (1 / 3, 2 / 3, 2 / 3)
    bitpack = ('<vectorChild type="Structure"><inputs type="Vector" allowHeterogeneousChildren="1"/>'
               '<bitPackCodec type="Structure"/></vectorChild>')
    return ('  <data3D type="Vector" allowHeterogeneousChildren="1">\n'
            '    <vectorChild type="Structure">\n      <name type="String"><![CDATA[no pose]]></name>\n'
            + points_xml(o0, n0, f0, bitpack) + '    </vectorChild>\n'
            '    <vectorChild type="Structure">\n      <name type="String"><![CDATA[posed]]></name>\n'
            + pose_xml(math.cos(half), axis[0] * math.sin(half), axis[1] * math.sin(half), axis[2] * math.sin(half),
                       1.5, -2.0, 0.25)
            + points_xml(o1, n1, f1) + '    </vectorChild>\n  </data3D>\n'
            '  <images2D type="Vector" allowHeterogeneousChildren="1"/>\n')


# ------------------------------------------------------------------------------------------- error cases
def tiny_fields():
    return [Field("cartesianX", "single", [0.0, 1.0, 2.0, 3.0]), Field("cartesianY", "single", [0.0, 0.5, 1.0, 1.5]),
            Field("cartesianZ", "single", [1.0, 1.0, 1.0, 1.0])]


def with_points(codecs="", count=None):
    def build(logical):
        fields = tiny_fields()
        offset = compressed_vector(logical, fields, [4])
        return ('  <data3D type="Vector" allowHeterogeneousChildren="1">\n    <vectorChild type="Structure">\n'
                + points_xml(offset, 4 if count is None else count, fields, codecs)
                + '    </vectorChild>\n  </data3D>\n')
    return build


FILES = {
    "spherical_grid.e57": spherical_grid,
    "cartesian_mixed.e57": cartesian_mixed,
    # A codec the standard does not define (only bit-pack is): the reader must refuse it by name.
    "unknown_codec.e57": with_points('<vectorChild type="Structure"><inputs type="Vector" '
                                     'allowHeterogeneousChildren="1"/><zipCodec type="Structure"/></vectorChild>'),
    # A record count no section could hold (10^15 records of 96 bits in a few bytes): refused before allocating.
    "huge_record_count.e57": with_points(count=10**15),
}


def main():
    for name, build in FILES.items():
        with open(os.path.join(HERE, name), "wb") as f:
            f.write(e57_file(build))


if __name__ == "__main__":
    main()
