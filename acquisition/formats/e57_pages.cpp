#include "acquisition/formats/e57_pages.h"

#include <array>
#include <cerrno>
#include <cstring>
#include <filesystem>

#include "acquisition/format_error.h"

namespace s2m::formats::e57 {
namespace {

// The byte-wise table of the reflected polynomial: entry b is the CRC register after shifting b through it.
constexpr std::array<std::uint32_t, 256> MakeCrc32cTable() {
  std::array<std::uint32_t, 256> table{};
  for (std::uint32_t b = 0; b < 256; ++b) {
    std::uint32_t r = b;
    for (int k = 0; k < 8; ++k) r = (r & 1u) ? (r >> 1) ^ 0x82F63B78u : r >> 1;
    table[b] = r;
  }
  return table;
}
constexpr std::array<std::uint32_t, 256> kCrc32cTable = MakeCrc32cTable();

std::string Hex32(std::uint32_t v) {
  char text[11];
  std::snprintf(text, sizeof text, "0x%08x", v);
  return text;
}

}  // namespace

std::uint32_t Crc32c(const void* data, std::size_t size) {
  const auto* p = static_cast<const unsigned char*>(data);
  std::uint32_t crc = 0xFFFFFFFFu;
  for (std::size_t i = 0; i < size; ++i) crc = kCrc32cTable[(crc ^ p[i]) & 0xFFu] ^ (crc >> 8);
  return crc ^ 0xFFFFFFFFu;
}

PagedReader::PagedReader(const std::string& file) : file_(file), page_(kPageSize) {
  in_.open(file, std::ios::binary);
  if (!in_) throw FormatError(file, "", std::string("cannot open: ") + std::strerror(errno));
  std::error_code ec;
  const std::uintmax_t size = std::filesystem::file_size(file, ec);
  if (ec) throw FormatError(file, "", "cannot read the file size: " + ec.message());
  physical_size_ = size;
}

void PagedReader::LoadPage(std::uint64_t page, const std::string& what) {
  if (page == loaded_page_) return;
  const std::uint64_t start = page * kPageSize;
  if (start + kPageSize > physical_size_) {
    // The last page is cut short (or the offset lies beyond the file): the file was truncated.
    throw FormatError(file_, AtByte(start),
                      "truncated: " + what + " needs page " + std::to_string(page) + " (bytes " +
                          std::to_string(start) + "-" + std::to_string(start + kPageSize - 1) +
                          ") but the file has " + std::to_string(physical_size_) + " bytes");
  }
  in_.clear();
  in_.seekg(static_cast<std::streamoff>(start));
  in_.read(page_.data(), static_cast<std::streamsize>(kPageSize));
  if (!in_) throw FormatError(file_, AtByte(start), "read error in page " + std::to_string(page));
  const std::uint32_t computed = Crc32c(page_.data(), kPagePayload);
  const auto* c = reinterpret_cast<const unsigned char*>(page_.data() + kPagePayload);
  const std::uint32_t stored = (std::uint32_t{c[0]} << 24) | (std::uint32_t{c[1]} << 16) |
                               (std::uint32_t{c[2]} << 8) | std::uint32_t{c[3]};
  if (stored != computed) {
    loaded_page_ = ~std::uint64_t{0};
    throw FormatError(file_, AtByte(start + kPagePayload),
                      "bad CRC-32C checksum of page " + std::to_string(page) + " (stored " + Hex32(stored) +
                          ", computed " + Hex32(computed) + "): the page is corrupt");
  }
  loaded_page_ = page;
}

void PagedReader::Read(std::uint64_t logical, std::size_t size, char* out, const std::string& what) {
  if (size == 0) return;
  if (logical > logical_size() || size > logical_size() - logical) {
    throw FormatError(file_, AtByte(LogicalToPhysical(logical)),
                      "truncated: " + what + " (" + std::to_string(size) + " bytes at logical offset " +
                          std::to_string(logical) + ") runs past the end of the file (" +
                          std::to_string(physical_size_) + " bytes)");
  }
  while (size > 0) {
    const std::uint64_t page = logical / kPagePayload;
    const std::uint64_t within = logical % kPagePayload;
    LoadPage(page, what);
    const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(size, kPagePayload - within));
    std::memcpy(out, page_.data() + within, n);
    out += n;
    size -= n;
    logical += n;
  }
}

std::string PagedReader::Read(std::uint64_t logical, std::size_t size, const std::string& what) {
  std::string bytes(size, '\0');
  Read(logical, size, bytes.data(), what);
  return bytes;
}

std::string PageLogicalStream(const std::string& logical) {
  const std::size_t pages = std::max<std::size_t>(1, (logical.size() + kPagePayload - 1) / kPagePayload);
  std::string physical(pages * kPageSize, '\0');
  for (std::size_t p = 0; p < pages; ++p) {
    char* page = physical.data() + p * kPageSize;
    const std::size_t begin = p * kPagePayload;
    const std::size_t n =
        std::min<std::size_t>(kPagePayload, logical.size() - std::min(begin, logical.size()));
    if (n > 0) std::memcpy(page, logical.data() + begin, n);
    const std::uint32_t crc = Crc32c(page, kPagePayload);
    page[kPagePayload + 0] = static_cast<char>((crc >> 24) & 0xFFu);
    page[kPagePayload + 1] = static_cast<char>((crc >> 16) & 0xFFu);
    page[kPagePayload + 2] = static_cast<char>((crc >> 8) & 0xFFu);
    page[kPagePayload + 3] = static_cast<char>(crc & 0xFFu);
  }
  return physical;
}

}  // namespace s2m::formats::e57
