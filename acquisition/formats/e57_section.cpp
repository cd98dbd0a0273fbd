#include "acquisition/formats/e57_section.h"

#include <algorithm>
#include <stdexcept>

#include "acquisition/format_error.h"
#include "acquisition/formats/binary_util.h"

namespace s2m::formats::e57 {
namespace {

constexpr std::uint64_t kSectionHeaderSize = 32;
constexpr std::uint64_t kDataPacketHeaderSize = 6;
constexpr std::uint64_t kIndexPacketHeaderSize = 16;
constexpr std::uint64_t kMaxPacketSize = 65536;
constexpr std::uint64_t kMaxIndexEntries = 2048;
constexpr std::uint8_t kIndexPacket = 0, kDataPacket = 1, kEmptyPacket = 2;
constexpr std::uint8_t kCompressedVectorSection = 1;

std::uint16_t U16(const char* p) {
  return LoadScalar<std::uint16_t>(p, true);
}
std::uint64_t U64(const char* p) {
  return LoadScalar<std::uint64_t>(p, true);
}

void PutU16(std::string& out, std::size_t at, std::uint64_t v) {
  for (int i = 0; i < 2; ++i)
    out[at + static_cast<std::size_t>(i)] = static_cast<char>((v >> (8 * i)) & 0xFFu);
}
void PutU64(std::string& out, std::size_t at, std::uint64_t v) {
  for (int i = 0; i < 8; ++i)
    out[at + static_cast<std::size_t>(i)] = static_cast<char>((v >> (8 * i)) & 0xFFu);
}

class SectionReader {
 public:
  SectionReader(PagedReader& reader, const std::vector<PrototypeField>& fields, const std::vector<bool>& keep,
                const std::string& what)
      : reader_(reader), fields_(fields), keep_(keep), what_(what), streams_(fields.size()) {
    for (const PrototypeField& f : fields) widths_.push_back(f.codec.BitWidth());
  }

  std::vector<std::vector<double>> Read(std::uint64_t section_physical, std::uint64_t record_count,
                                        std::vector<std::pair<std::uint64_t, std::uint64_t>>& claimed) {
    const std::optional<std::uint64_t> start = PhysicalToLogical(section_physical);
    if (!start)
      Fail(section_physical,
           "fileOffset " + std::to_string(section_physical) + " points into a page checksum");
    begin_ = *start;
    const std::string header = reader_.Read(begin_, kSectionHeaderSize, what_ + " section header");
    if (static_cast<std::uint8_t>(header[0]) != kCompressedVectorSection) {
      Fail(section_physical, "not a compressed-vector section (section id " +
                                 std::to_string(static_cast<unsigned>(static_cast<std::uint8_t>(header[0]))) +
                                 ", expected 1)");
    }
    const std::uint64_t length = U64(header.data() + 8);
    const std::uint64_t data_physical = U64(header.data() + 16);
    const std::uint64_t index_physical = U64(header.data() + 24);
    if (length < kSectionHeaderSize || length > reader_.logical_size() - begin_) {
      Fail(section_physical, "section length " + std::to_string(length) + " does not fit in the file (" +
                                 std::to_string(reader_.logical_size() - begin_) +
                                 " logical bytes from here)");
    }
    end_ = begin_ + length;
    for (const auto& [b, e] : claimed) {
      if (begin_ < e && b < end_) {
        Fail(section_physical, "the section overlaps another compressed vector's (logical bytes " +
                                   std::to_string(b) + "-" + std::to_string(e - 1) + ")");
      }
    }
    claimed.emplace_back(begin_, end_);
    // Refuse what the section cannot hold before allocating: every record takes at least its fields' bits,
    // and a record of constant fields only (no bits) is counted as one bit.
    std::uint64_t record_bits = 0;
    for (const int w : widths_) record_bits += static_cast<std::uint64_t>(w);
    record_bits = std::max<std::uint64_t>(record_bits, 1);
    const std::uint64_t capacity_bits = 8 * (length - kSectionHeaderSize);
    if (record_count > capacity_bits / record_bits) {
      Fail(section_physical, "recordCount " + std::to_string(record_count) + " needs at least " +
                                 std::to_string(record_bits) + " bits per record, but the section holds " +
                                 std::to_string(length - kSectionHeaderSize) + " bytes of packets");
    }
    if (index_physical != 0) CheckInSection(index_physical, section_physical, "indexPhysicalOffset");
    std::vector<std::vector<double>> columns(fields_.size());
    if (record_count == 0) return columns;
    for (std::size_t f = 0; f < fields_.size(); ++f)
      if (keep_[f]) columns[f].reserve(static_cast<std::size_t>(record_count));
    std::uint64_t pos = CheckInSection(data_physical, section_physical, "dataPhysicalOffset");
    std::string packet;
    while (decoded_ < record_count) {
      if (pos + 4 > end_) {
        Fail(LogicalToPhysical(pos), "truncated compressed vector: the section ends after " +
                                         std::to_string(decoded_) + " of " + std::to_string(record_count) +
                                         " records");
      }
      const std::string head = reader_.Read(pos, 4, what_ + " packet header");
      const auto type = static_cast<std::uint8_t>(head[0]);
      const std::uint64_t packet_length = std::uint64_t{U16(head.data() + 2)} + 1;
      const std::uint64_t at = LogicalToPhysical(pos);
      if (packet_length % 4 != 0)
        Fail(at, "packet length " + std::to_string(packet_length) + " is not a multiple of 4");
      if (packet_length > end_ - pos) {
        Fail(at, "packet of " + std::to_string(packet_length) + " bytes runs past the end of its section (" +
                     std::to_string(end_ - pos) + " bytes left)");
      }
      if (type == kDataPacket) {
        packet = reader_.Read(pos, static_cast<std::size_t>(packet_length), what_ + " data packet");
        DataPacket(packet, at, record_count, columns);
      } else if (type == kIndexPacket) {
        packet = reader_.Read(pos, static_cast<std::size_t>(packet_length), what_ + " index packet");
        IndexPacket(packet, at, section_physical);
      } else if (type != kEmptyPacket) {
        Fail(at, "unknown packet type " + std::to_string(static_cast<unsigned>(type)) +
                     " (0 index, 1 data, 2 empty)");
      }
      pos += packet_length;
    }
    return columns;
  }

 private:
  [[noreturn]] void Fail(std::uint64_t physical, const std::string& problem) const {
    throw FormatError(reader_.file(), AtByte(physical), what_ + ": " + problem);
  }

  // The logical offset of a physical offset that must lie among the section's packets.
  std::uint64_t CheckInSection(std::uint64_t physical, std::uint64_t section_physical,
                               const std::string& name) {
    const std::optional<std::uint64_t> logical = PhysicalToLogical(physical);
    if (!logical || *logical < begin_ + kSectionHeaderSize || *logical >= end_) {
      Fail(section_physical, name + " " + std::to_string(physical) + " lies outside the section's packets");
    }
    return *logical;
  }

  void DataPacket(const std::string& p, std::uint64_t at, std::uint64_t record_count,
                  std::vector<std::vector<double>>& columns) {
    if (p.size() < kDataPacketHeaderSize) Fail(at, "data packet shorter than its 6-byte header");
    const std::uint64_t count = U16(p.data() + 4);
    if (count != fields_.size()) {
      Fail(at, "data packet has " + std::to_string(count) + " bytestreams, the prototype " +
                   std::to_string(fields_.size()) + " fields");
    }
    const std::uint64_t table_end = kDataPacketHeaderSize + 2 * count;
    if (table_end > p.size()) Fail(at, "data packet too short for its bytestream lengths");
    std::uint64_t offset = table_end;
    for (std::size_t f = 0; f < fields_.size(); ++f) {
      const std::uint64_t n = U16(p.data() + kDataPacketHeaderSize + 2 * f);
      if (n > p.size() - offset) {
        Fail(at, "bytestream " + std::to_string(f) + " (" + fields_[f].name + ") of " + std::to_string(n) +
                     " bytes runs past the end of its data packet");
      }
      streams_[f].Append(reinterpret_cast<const unsigned char*>(p.data() + offset),
                         static_cast<std::size_t>(n));
      offset += n;
    }
    // Records complete in every bytestream; constant fields (no bits) never limit.
    std::uint64_t ready = record_count - decoded_;
    for (std::size_t f = 0; f < fields_.size(); ++f) {
      if (widths_[f] > 0)
        ready = std::min<std::uint64_t>(
            ready, streams_[f].bits_available() / static_cast<std::uint64_t>(widths_[f]));
    }
    for (std::uint64_t r = 0; r < ready; ++r, ++decoded_) {
      for (std::size_t f = 0; f < fields_.size(); ++f) {
        double value = 0.0;
        if (!Decode(fields_[f].codec, streams_[f].Take(widths_[f]), value)) {
          Fail(at, "record " + std::to_string(decoded_) + ": " + fields_[f].name +
                       " is beyond the prototype's maximum " + std::to_string(fields_[f].codec.maximum));
        }
        if (keep_[f]) columns[f].push_back(value);
      }
    }
  }

  void IndexPacket(const std::string& p, std::uint64_t at, std::uint64_t section_physical) {
    if (p.size() < kIndexPacketHeaderSize) Fail(at, "index packet shorter than its 16-byte header");
    const std::uint64_t entries = U16(p.data() + 4);
    const unsigned level = static_cast<std::uint8_t>(p[6]);
    if (entries == 0 || entries > kMaxIndexEntries)
      Fail(at, "index packet with " + std::to_string(entries) + " entries (1 to 2048)");
    if (level > 5) Fail(at, "index packet of level " + std::to_string(level) + " (0 to 5)");
    if (kIndexPacketHeaderSize + 16 * entries > p.size()) {
      Fail(at, "index packet of " + std::to_string(p.size()) + " bytes cannot hold its " +
                   std::to_string(entries) + " entries");
    }
    for (std::uint64_t e = 0; e < entries; ++e) {
      const std::uint64_t chunk_physical = U64(p.data() + kIndexPacketHeaderSize + 16 * e + 8);
      CheckInSection(chunk_physical, section_physical,
                     "index entry " + std::to_string(e) + "'s packet offset");
    }
  }

  PagedReader& reader_;
  const std::vector<PrototypeField>& fields_;
  const std::vector<bool>& keep_;
  std::string what_;
  std::vector<BitReader> streams_;
  std::vector<int> widths_;
  std::uint64_t begin_ = 0, end_ = 0, decoded_ = 0;
};

void PadTo4(std::string& s) {
  s.append((4 - s.size() % 4) % 4, '\0');
}

}  // namespace

std::vector<std::vector<double>> ReadCompressedVector(
    PagedReader& reader, std::uint64_t section_physical, std::uint64_t record_count,
    const std::vector<PrototypeField>& fields, const std::vector<bool>& keep, const std::string& what,
    std::vector<std::pair<std::uint64_t, std::uint64_t>>& claimed) {
  if (fields.empty()) throw FormatError(reader.file(), "", what + ": the prototype has no fields");
  if (fields.size() > 0xFFFF)
    throw FormatError(reader.file(), "", what + ": more than 65535 prototype fields");
  if (keep.size() != fields.size()) throw std::logic_error("ReadCompressedVector: one keep flag per field");
  return SectionReader(reader, fields, keep, what).Read(section_physical, record_count, claimed);
}

std::uint64_t AppendCompressedVector(std::string& logical, const std::vector<FieldCodec>& fields,
                                     const std::vector<BitWriter>& streams, std::uint64_t record_count,
                                     std::uint64_t max_records_per_packet) {
  PadTo4(logical);
  const std::size_t begin = logical.size();
  logical.append(kSectionHeaderSize, '\0');
  const std::uint64_t F = fields.size();
  std::uint64_t record_bits = 0;
  for (const FieldCodec& f : fields) record_bits += static_cast<std::uint64_t>(f.BitWidth());
  // A packet of R records holds at most R * record_bits / 8 + 2 bytes per stream (a partial byte at each
  // end), plus its header, length table and up to 3 bytes of padding: R below keeps that within 64 KiB.
  std::uint64_t per_packet = record_bits == 0
                                 ? record_count
                                 : (kMaxPacketSize - kDataPacketHeaderSize - 4 * F - 3) * 8 / record_bits;
  per_packet = std::max<std::uint64_t>(per_packet, 1);
  if (max_records_per_packet > 0) per_packet = std::min(per_packet, max_records_per_packet);

  std::vector<std::pair<std::uint64_t, std::uint64_t>> index;  // (first record, packet's physical offset)
  std::vector<std::uint64_t> emitted(F, 0);                    // bytes of each stream written so far
  for (std::uint64_t first = 0; first < record_count; first += per_packet) {
    const std::uint64_t last = std::min(record_count, first + per_packet);
    const std::size_t at = logical.size();
    index.emplace_back(first, LogicalToPhysical(at));
    logical.append(kDataPacketHeaderSize + 2 * F, '\0');
    logical[at] = static_cast<char>(kDataPacket);
    PutU16(logical, at + 4, F);
    for (std::size_t f = 0; f < F; ++f) {
      // Only whole bytes of complete records, except in the last packet, which takes the rest (its last byte
      // padded): the bitstream continues in the next packet.
      const std::uint64_t bits = last * static_cast<std::uint64_t>(fields[f].BitWidth());
      const std::uint64_t upto = last == record_count ? streams[f].bytes().size() : bits / 8;
      const std::uint64_t n = upto - emitted[f];
      PutU16(logical, at + kDataPacketHeaderSize + 2 * f, n);
      logical.append(reinterpret_cast<const char*>(streams[f].bytes().data() + emitted[f]),
                     static_cast<std::size_t>(n));
      emitted[f] = upto;
    }
    PadTo4(logical);
    PutU16(logical, at + 2, logical.size() - at - 1);
  }
  std::uint64_t index_physical = 0;
  if (!index.empty() && index.size() <= kMaxIndexEntries) {
    const std::size_t at = logical.size();
    index_physical = LogicalToPhysical(at);
    logical.append(kIndexPacketHeaderSize + 16 * index.size(), '\0');
    logical[at] = static_cast<char>(kIndexPacket);
    PutU16(logical, at + 2, logical.size() - at - 1);
    PutU16(logical, at + 4, index.size());  // level 0: entries point at data packets
    for (std::size_t e = 0; e < index.size(); ++e) {
      PutU64(logical, at + kIndexPacketHeaderSize + 16 * e, index[e].first);
      PutU64(logical, at + kIndexPacketHeaderSize + 16 * e + 8, index[e].second);
    }
  }
  logical[begin] = static_cast<char>(kCompressedVectorSection);
  PutU64(logical, begin + 8, logical.size() - begin);
  PutU64(logical, begin + 16, LogicalToPhysical(begin + kSectionHeaderSize));
  PutU64(logical, begin + 24, index_physical);
  return LogicalToPhysical(begin);
}

}  // namespace s2m::formats::e57
