#pragma once
// Internal: E57 compressed-vector binary sections (ASTM E2807, docs/e57.md). A section starts with a 32-byte
// header (section id 1, reserved bytes, logical length, physical offsets of the first data packet and of the
// index packet), followed by packets, each 4-byte aligned and at most 64 KiB:
//   data packet  (type 1): flags, length - 1 (uint16), bytestream count (uint16), one uint16 buffer length
//   per
//                          bytestream, then the buffers one after the other; zero padding to a multiple of 4;
//   index packet (type 0): flags, length - 1, entry count (1..2048), index level (0..5), 9 reserved bytes,
//   then
//                          (first record number, physical offset of its data packet) pairs of uint64;
//   empty packet (type 2): reserved byte, length - 1; filler to be skipped.
// All numbers little-endian. Each prototype field has one bytestream, coded by the bit-pack codec
// (e57_bitpack.h), continuing from one data packet to the next.

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "acquisition/formats/e57_bitpack.h"
#include "acquisition/formats/e57_pages.h"

namespace s2m::formats::e57 {

struct PrototypeField {
  std::string name;  // e.g. "cartesianX", or a path "group/field" for nested prototypes
  FieldCodec codec;
};

// The records of the compressed vector whose section header is at `section_physical` (its fileOffset):
// columns[f][r] is field f of record r, for the fields with keep[f] (the others are decoded and dropped,
// their columns left empty). `what` names the vector in errors ("data3D/0/points"). Counts that the section's
// bytes cannot hold are refused before anything of their size is allocated: every record costs at least its
// fields' bits, and at least one bit. `claimed` holds the logical extents of the sections read before; one
// overlapping them is an error (so no two vectors share bytes, and the records of a whole file are bounded by
// its size), and this section's extent is added.
std::vector<std::vector<double>> ReadCompressedVector(
    PagedReader& reader, std::uint64_t section_physical, std::uint64_t record_count,
    const std::vector<PrototypeField>& fields, const std::vector<bool>& keep, const std::string& what,
    std::vector<std::pair<std::uint64_t, std::uint64_t>>& claimed);

// Appends a compressed-vector section to the logical stream `logical` (first padded to a 4-byte boundary):
// the header, data packets of at most `max_records_per_packet` records each (0: as many as fit in 64 KiB),
// and one index packet listing them when there are 2048 data packets at most. `streams[f]` holds the bits of
// field f for all `record_count` records. Returns the section's physical offset (its fileOffset).
std::uint64_t AppendCompressedVector(std::string& logical, const std::vector<FieldCodec>& fields,
                                     const std::vector<BitWriter>& streams, std::uint64_t record_count,
                                     std::uint64_t max_records_per_packet);

}  // namespace s2m::formats::e57
