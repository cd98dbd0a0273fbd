#!/usr/bin/env python3
"""Writes the fuzz targets' seed corpora (fuzz/corpus/<target>/): small valid inputs of every format a target
reads, each prefixed by the target's selector byte where the target has one (see the target's source). The seeds
are generated, not copied from third-party data; run again after changing a target's selector."""
import json
import os
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
POINTS = [(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.5), (1.0, 1.0, 0.25), (0.5, 0.5, 2.0)]


def write(target, name, data):
    folder = os.path.join(HERE, "corpus", target)
    os.makedirs(folder, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(folder, name), "wb") as f:
        f.write(data)


def ply_ascii():
    body = "".join(f"{x} {y} {z}\n" for x, y, z in POINTS)
    return ("ply\nformat ascii 1.0\ncomment units mm\nelement vertex %d\nproperty double x\nproperty double y\n"
            "property double z\nend_header\n" % len(POINTS)) + body


def ply_binary():
    header = ("ply\nformat binary_little_endian 1.0\nelement vertex %d\nproperty float x\nproperty float y\n"
              "property float z\nproperty float nx\nproperty float ny\nproperty float nz\n"
              "element face 1\nproperty list uchar int vertex_indices\nend_header\n" % len(POINTS)).encode()
    body = b"".join(struct.pack("<6f", x, y, z, 0.0, 0.0, 1.0) for x, y, z in POINTS)
    return header + body + struct.pack("<B3i", 3, 0, 1, 2)


def pcd(data_kind):
    header = ("# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgba\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\n"
              "WIDTH %d\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS %d\nDATA %s\n" % (len(POINTS), len(POINTS), data_kind))
    nan = float("nan")
    pts = POINTS + [(nan, nan, nan)]
    header = header.replace("WIDTH %d" % len(POINTS), "WIDTH %d" % len(pts)).replace(
        "POINTS %d" % len(POINTS), "POINTS %d" % len(pts))
    if data_kind == "ascii":
        return header + "".join(f"{x} {y} {z} 4278190080\n" for x, y, z in pts)
    if data_kind == "binary":
        return header.encode() + b"".join(struct.pack("<3fI", x, y, z, 0xFF000000) for x, y, z in pts)
    # binary_compressed: fields stored column by column, LZF-compressed. A literal-only LZF stream (control bytes
    # 0..31 = a run of control+1 literal bytes) is valid LZF.
    raw = b"".join(struct.pack("<%df" % len(pts), *[p[i] for p in pts]) for i in range(3))
    raw += struct.pack("<%dI" % len(pts), *([0xFF000000] * len(pts)))
    lzf = bytearray()
    for start in range(0, len(raw), 32):
        chunk = raw[start:start + 32]
        lzf.append(len(chunk) - 1)
        lzf += chunk
    return header.encode() + struct.pack("<II", len(lzf), len(raw)) + bytes(lzf)


# A tetrahedron with counter-clockwise faces seen from outside (the nominal meshes' orientation).
TET_VERTICES = [(0.0, 0.0, 0.0), (10.0, 0.0, 0.0), (0.0, 10.0, 0.0), (0.0, 0.0, 10.0)]
TET_FACES = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]


def stl_binary():
    header = b"scan2model fuzz seed".ljust(80, b" ")
    body = b""
    for face in TET_FACES:
        body += struct.pack("<3f", 0.0, 0.0, 0.0)
        for v in face:
            body += struct.pack("<3f", *TET_VERTICES[v])
        body += b"\x00\x00"
    return header + struct.pack("<I", len(TET_FACES)) + body


def stl_ascii():
    # Two solids: the bottom face and the rest (an ASCII STL file's solids are its face groups).
    out = ""
    for name, faces in (("bottom", TET_FACES[:1]), ("sides", TET_FACES[1:])):
        out += "solid %s\n" % name
        for face in faces:
            out += "  facet normal 0 0 0\n    outer loop\n"
            for v in face:
                out += "      vertex %g %g %g\n" % TET_VERTICES[v]
            out += "    endloop\n  endfacet\n"
        out += "endsolid %s\n" % name
    return out


def obj():
    # Groups, a comment, normals and texture coordinates, every face-vertex form, a negative (relative) index
    # and a quad (split into a fan).
    out = "# tetrahedron and a quad\nmtllib none.mtl\no part\n"
    out += "".join("v %g %g %g\n" % p for p in TET_VERTICES)
    out += "v 0 0 20 1\nvt 0 0\nvn 0 0 1\ng bottom\nusemtl grey\nf 1 3 2\ng sides\ns 1\n"
    out += "f 1/1 2/1 4/1\nf 1//1 4//1 3//1\nf 2/1/1 3/1/1 -2/1/1\ng lid\nf 1 2 5 4\n"
    return out


def ply_mesh_ascii():
    header = ("ply\nformat ascii 1.0\ncomment units mm\nelement vertex %d\nproperty float x\nproperty float y\n"
              "property float z\nelement face %d\nproperty list uchar int vertex_indices\nproperty int label\n"
              "end_header\n" % (len(TET_VERTICES), len(TET_FACES)))
    return header + "".join("%g %g %g\n" % p for p in TET_VERTICES) + "".join(
        "3 %d %d %d %d\n" % (a, b, c, 1 if k else 0) for k, (a, b, c) in enumerate(TET_FACES))


def ply_mesh_binary():
    header = ("ply\nformat binary_little_endian 1.0\nelement vertex %d\nproperty double x\nproperty double y\n"
              "property double z\nelement face %d\nproperty list uchar uint vertex_indices\nend_header\n"
              % (len(TET_VERTICES), len(TET_FACES))).encode()
    body = b"".join(struct.pack("<3d", *p) for p in TET_VERTICES)
    body += b"".join(struct.pack("<B3I", 3, *f) for f in TET_FACES)
    return header + body


def main():
    # point_cloud_fuzz: selector = index into {.ply, .ply.gz, .pcd, .xyz, .csv, .ds}.
    write("point_cloud", "ascii.ply", b"\x00" + ply_ascii().encode())
    write("point_cloud", "binary.ply", b"\x00" + ply_binary())
    write("point_cloud", "gzipped.ply.gz", b"\x01" + gzip_bytes(ply_ascii().encode()))
    write("point_cloud", "ascii.pcd", b"\x02" + pcd("ascii").encode())
    write("point_cloud", "binary.pcd", b"\x02" + pcd("binary"))
    write("point_cloud", "compressed.pcd", b"\x02" + pcd("binary_compressed"))
    write("point_cloud", "points.xyz", b"\x03" + "".join(f"{x} {y} {z}\n" for x, y, z in POINTS).encode())
    write("point_cloud", "points.csv", b"\x04" + ("x,y,z\n" + "".join(f"{x},{y},{z}\n" for x, y, z in POINTS)).encode())
    write("point_cloud", "points.ds", b"\x05" + (f"{len(POINTS)}\n" + "".join(f"{x} {y} {z}\n" for x, y, z in POINTS)).encode())

    write("nist_fit", "plane.fit", "0.5 0.5 0.1\n0 0 1\n")
    write("nist_fit", "sphere.fit", "1 2 3\n10\n")
    write("nist_fit", "cylinder.fit", "0 0 0\n0 0 1\n20\n")
    write("nist_fit", "cone.fit", "0 0 0\n0 0 1\n5\n30\n")

    views = {"format": "scan2model.views/1", "units": "mm", "views": [
        {"file": "view_000.ply", "world_T_scan": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]},
        {"file": "view_001.ply", "world_T_scan": [[0, -1, 0, 5], [1, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]}]}
    write("scan_set", "views.json", b"\x00" + json.dumps(views, indent=1).encode())
    write("scan_set", "bun.conf", b"\x01" + b"camera 0 0 0 0 0 0 1\nbmesh bun000.ply 0 0 0 0 0 0 1\n"
          b"bmesh bun045.ply -0.0520211 -0.000383981 -0.0109223 0.00548449 -0.294635 -0.0038555 0.955586\n")

    for name in ("counterbored_block.part.json", "freeform_plate.part.json"):
        with open(os.path.join(HERE, "..", "docs", "examples", name), "rb") as f:
            write("part_file", name, f.read())

    write("glyph", "o.glif", """<?xml version="1.0" encoding="UTF-8"?>
<glyph name="o" format="2">
  <advance width="500"/>
  <outline>
    <contour>
      <point x="250" y="0" type="curve" smooth="yes"/>
      <point x="400" y="0"/>
      <point x="500" y="100"/>
      <point x="500" y="250" type="curve" smooth="yes"/>
      <point x="500" y="400"/>
      <point x="400" y="500"/>
      <point x="250" y="500" type="curve"/>
      <point x="100" y="500" type="line"/>
      <point x="0" y="250" type="qcurve"/>
    </contour>
  </outline>
</glyph>
""")

    payload = b"".join(struct.pack("<3d", *p) for p in POINTS)
    write("frame_payload", "plain.bin", b"\x00" + payload)
    write("frame_payload", "zlib.bin", b"\x01" + zlib.compress(payload))

    # A 4x3 16-bit grey TIFF, little endian, one strip, uncompressed.
    width, height = 4, 3
    pixels = struct.pack("<%dH" % (width * height), *[1000 + 10 * i for i in range(width * height)])
    entries = [(256, 3, 1, width), (257, 3, 1, height), (258, 3, 1, 16), (259, 3, 1, 1), (262, 3, 1, 1),
               (273, 4, 1, 0), (277, 3, 1, 1), (278, 3, 1, height), (279, 4, 1, len(pixels))]
    ifd_offset = 8
    data_offset = ifd_offset + 2 + 12 * len(entries) + 4
    ifd = struct.pack("<H", len(entries))
    for tag, kind, count, value in entries:
        if tag == 273:
            value = data_offset
        ifd += struct.pack("<HHI", tag, kind, count) + (struct.pack("<HH", value, 0) if kind == 3 else struct.pack("<I", value))
    tiff = b"II*\x00" + struct.pack("<I", ifd_offset) + ifd + struct.pack("<I", 0) + pixels
    write("depth_frame", "depth.tiff", b"\x00" + tiff)
    write("depth_frame", "intrinsics.xml", b"\x01" + b"""<?xml version="1.0"?>
<depth>
  <focal_length_x>525</focal_length_x>
  <focal_length_y>525</focal_length_y>
  <principal_point_x>320</principal_point_x>
  <principal_point_y>240</principal_point_y>
  <z_multiplication_factor>0.001</z_multiplication_factor>
</depth>
""")

    batch = {"format": "scan2model.batch/1", "defaults": {"model": "sphere", "max_iterations": 50},
             "objects": [{"id": "a", "file": "a.ply"}, {"id": "b", "file": "b.xyz", "model": "plane", "loss": "huber"}]}
    write("batch_manifest", "batch.json", b"\x00" + json.dumps(batch, indent=1).encode())
    write("batch_manifest", "batch.csv", b"\x01" + b"id,file,model,max_iterations\na,a.ply,sphere,50\nb,b.xyz,plane,20\n")

    # mesh_fuzz: selector = index into {.stl, .obj, .ply, .ply.gz}; .stl is binary or ASCII by its bytes.
    write("mesh", "binary.stl", b"\x00" + stl_binary())
    write("mesh", "ascii.stl", b"\x00" + stl_ascii().encode())
    write("mesh", "groups.obj", b"\x01" + obj().encode())
    write("mesh", "labels.ply", b"\x02" + ply_mesh_ascii().encode())
    write("mesh", "binary.ply", b"\x02" + ply_mesh_binary())
    write("mesh", "gzipped.ply.gz", b"\x03" + gzip_bytes(ply_mesh_ascii().encode()))

    # checks_file_fuzz: no selector. Every check type, datums, a check without a name, a diameter with and
    # without its nominal.
    checks = {"schema": "scan2model.checks/1", "part": "block 60 x 40 x 20", "datums": ["bottom", "-x", "-y"],
              "checks": [{"name": "top profile", "type": "profile", "group": "top", "tolerance": 0.1},
                         {"type": "flatness", "group": "top", "tolerance": 0.05},
                         {"name": "bore position", "type": "position", "group": "bore", "tolerance": 0.1},
                         {"name": "bore diameter", "type": "diameter", "group": "bore", "nominal": 10,
                          "lower": -0.05, "upper": 0.05},
                         {"type": "diameter", "group": "pin", "lower": -0.1, "upper": 0}]}
    write("checks_file", "block.checks.json", json.dumps(checks, indent=1))
    write("checks_file", "minimal.checks.json", json.dumps({"schema": "scan2model.checks/1", "checks": []}))

    calibration = {"horus": {"camera": {"width": 1280, "height": 960, "fx": 1430.0, "fy": 1430.0, "cx": 640.0,
                                        "cy": 480.0, "distortion": [0.1, -0.2, 0.0, 0.0, 0.0]},
                             "lasers": [{"normal": [0.7, 0.0, 0.7], "distance": 100.0},
                                        {"normal": [-0.7, 0.0, 0.7], "distance": 100.0}],
                             "platform_T_camera": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 300], [0, 0, 0, 1]]}}
    write("horus_calibration", "calibration.json", json.dumps(calibration, indent=1))

    # e57_fuzz: the hand-made E57 files of the tests (tests/data/e57/make_e57_files.py builds them byte by byte):
    # spherical and cartesian scans, every field kind, data, empty and index packets, plus a four-point file that
    # mutates fast. Selector: 0 = the file as it is, 1 = its logical byte stream (the target adds the checksums).
    import importlib.util
    spec = importlib.util.spec_from_file_location(
        "make_e57_files", os.path.join(HERE, "..", "tests", "data", "e57", "make_e57_files.py"))
    e57 = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(e57)
    for name, build in (("spherical_grid", e57.spherical_grid), ("cartesian_mixed", e57.cartesian_mixed),
                        ("tiny", e57.with_points())):
        physical = e57.e57_file(build)
        logical = b"".join(physical[p:p + e57.PAYLOAD] for p in range(0, len(physical), e57.PAGE))
        write("e57", name + ".e57", b"\x00" + physical)
        write("e57", name + ".logical", b"\x01" + logical)

def gzip_bytes(data):
    import gzip
    import io
    out = io.BytesIO()
    with gzip.GzipFile(fileobj=out, mode="wb", mtime=0) as g:
        g.write(data)
    return out.getvalue()


if __name__ == "__main__":
    main()
