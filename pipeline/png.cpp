#include "pipeline/png.h"

#include <zlib.h>

#include <stdexcept>

namespace s2m::pipeline {
namespace {

void PutUint32(std::string& out, std::uint32_t v) {
  out.push_back(static_cast<char>((v >> 24) & 0xff));
  out.push_back(static_cast<char>((v >> 16) & 0xff));
  out.push_back(static_cast<char>((v >> 8) & 0xff));
  out.push_back(static_cast<char>(v & 0xff));
}

// length, type, data, CRC of type and data.
void PutChunk(std::string& out, const char* type, const std::string& data) {
  PutUint32(out, static_cast<std::uint32_t>(data.size()));
  const std::string body = std::string(type, 4) + data;
  out += body;
  uLong crc = crc32(0L, Z_NULL, 0);
  crc = crc32(crc, reinterpret_cast<const Bytef*>(body.data()), static_cast<uInt>(body.size()));
  PutUint32(out, static_cast<std::uint32_t>(crc));
}

}  // namespace

RgbImage::RgbImage(int w, int h, std::uint8_t grey)
    : width(w), height(h), pixels(3 * static_cast<std::size_t>(w) * static_cast<std::size_t>(h), grey) {}

void RgbImage::Set(int x, int y, std::uint8_t r, std::uint8_t g, std::uint8_t b) {
  if (x < 0 || y < 0 || x >= width || y >= height) return;
  std::uint8_t* p = at(x, y);
  p[0] = r;
  p[1] = g;
  p[2] = b;
}

std::string EncodePng(const RgbImage& image) {
  if (image.width <= 0 || image.height <= 0) throw std::invalid_argument("PNG: empty image");
  const std::size_t row = 3 * static_cast<std::size_t>(image.width);
  if (image.pixels.size() != row * static_cast<std::size_t>(image.height))
    throw std::invalid_argument("PNG: the pixel buffer does not match the image size");
  // Scanlines, each preceded by its filter type (0: none).
  std::string raw;
  raw.reserve((row + 1) * static_cast<std::size_t>(image.height));
  for (int y = 0; y < image.height; ++y) {
    raw.push_back('\0');
    raw.append(reinterpret_cast<const char*>(image.at(0, y)), row);
  }
  uLongf size = compressBound(static_cast<uLong>(raw.size()));
  std::string compressed(size, '\0');
  if (compress2(reinterpret_cast<Bytef*>(compressed.data()), &size,
                reinterpret_cast<const Bytef*>(raw.data()), static_cast<uLong>(raw.size()),
                Z_BEST_COMPRESSION) != Z_OK)
    throw std::runtime_error("PNG: zlib compression failed");
  compressed.resize(size);
  std::string out = "\x89PNG\r\n\x1a\n";
  std::string header;
  PutUint32(header, static_cast<std::uint32_t>(image.width));
  PutUint32(header, static_cast<std::uint32_t>(image.height));
  header += std::string("\x08\x02\x00\x00\x00",
                        5);  // bit depth 8, colour type 2 (RGB), deflate, filters, no interlace
  PutChunk(out, "IHDR", header);
  PutChunk(out, "IDAT", compressed);
  PutChunk(out, "IEND", "");
  return out;
}

std::string Base64(const std::string& bytes) {
  static const char* kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve(4 * ((bytes.size() + 2) / 3));
  std::size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const std::uint32_t v = (static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i])) << 16) |
                            (static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i + 1])) << 8) |
                            static_cast<unsigned char>(bytes[i + 2]);
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += kAlphabet[(v >> 6) & 63];
    out += kAlphabet[v & 63];
  }
  if (i < bytes.size()) {
    std::uint32_t v = static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i])) << 16;
    if (i + 1 < bytes.size()) v |= static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i + 1])) << 8;
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += i + 1 < bytes.size() ? kAlphabet[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

}  // namespace s2m::pipeline
