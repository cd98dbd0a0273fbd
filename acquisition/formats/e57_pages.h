#pragma once
// Internal: the paged file layer of E57 (ASTM E2807, docs/e57.md). The whole file is a sequence of 1024-byte
// physical pages; each holds 1020 bytes of the file's logical byte stream followed by the CRC-32C
// (Castagnoli) of those 1020 bytes, stored most significant byte first (every E57 writer does so, although
// the standard's other binary values are little-endian). Offsets written in the file (header, XML attributes,
// section headers) are physical; the sections themselves are contiguous in the logical stream.

#include <cstddef>
#include <cstdint>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

namespace s2m::formats::e57 {

inline constexpr std::uint64_t kPageSize = 1024;
inline constexpr std::uint64_t kPageChecksumSize = 4;
inline constexpr std::uint64_t kPagePayload = kPageSize - kPageChecksumSize;  // logical bytes per page

// CRC-32C (Castagnoli polynomial 0x1EDC6F41, reflected 0x82F63B78, initial value and final xor 0xFFFFFFFF).
std::uint32_t Crc32c(const void* data, std::size_t size);

// Offset mapping: logical byte L lies in page L / 1020 at L % 1020.
inline std::uint64_t LogicalToPhysical(std::uint64_t logical) {
  return (logical / kPagePayload) * kPageSize + logical % kPagePayload;
}
// The logical offset of a physical one, or nothing when it points into a page's checksum.
inline std::optional<std::uint64_t> PhysicalToLogical(std::uint64_t physical) {
  if (physical % kPageSize >= kPagePayload) return std::nullopt;
  return (physical / kPageSize) * kPagePayload + physical % kPageSize;
}

// Reads the logical stream of an E57 file page by page, checking every page's CRC as it is loaded. Every
// error is a FormatError naming the file, the physical byte offset and the problem (bad checksum, a page cut
// short, a read past the end).
class PagedReader {
 public:
  explicit PagedReader(const std::string& file);

  const std::string& file() const { return file_; }
  std::uint64_t physical_size() const { return physical_size_; }
  // Logical bytes in the whole pages of the file.
  std::uint64_t logical_size() const { return (physical_size_ / kPageSize) * kPagePayload; }

  // Copies `size` logical bytes starting at `logical` into `out`; `what` names them in errors ("XML section",
  // "data packet", ...).
  void Read(std::uint64_t logical, std::size_t size, char* out, const std::string& what);
  std::string Read(std::uint64_t logical, std::size_t size, const std::string& what);

 private:
  void LoadPage(std::uint64_t page, const std::string& what);

  std::string file_;
  std::ifstream in_;
  std::uint64_t physical_size_ = 0;
  std::uint64_t loaded_page_ = ~std::uint64_t{0};
  std::vector<char> page_;
};

// The physical file for a logical stream: its bytes cut into 1020-byte payloads, the last one padded with
// zeros, each followed by its CRC-32C.
std::string PageLogicalStream(const std::string& logical);

}  // namespace s2m::formats::e57
