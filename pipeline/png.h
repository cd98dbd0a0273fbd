#pragma once
// A small PNG writer (W3C PNG specification, 2nd edition): 8-bit RGB, one IDAT chunk compressed with zlib,
// CRCs by zlib's crc32. For the interrogation images (pipeline/surface_render.h) of the report and
// `scan2model interrogate`; no image library needed.

#include <cstdint>
#include <string>
#include <vector>

namespace s2m::pipeline {

// An 8-bit RGB image, rows top to bottom, 3 bytes per pixel.
struct RgbImage {
  int width = 0, height = 0;
  std::vector<std::uint8_t> pixels;  // width * height * 3
  RgbImage() = default;
  RgbImage(int w, int h, std::uint8_t grey = 255);
  std::uint8_t* at(int x, int y) {
    return &pixels[3 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                        static_cast<std::size_t>(x))];
  }
  const std::uint8_t* at(int x, int y) const {
    return &pixels[3 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                        static_cast<std::size_t>(x))];
  }
  void Set(int x, int y, std::uint8_t r, std::uint8_t g, std::uint8_t b);
};

// The PNG file's bytes (signature, IHDR, IDAT, IEND). Throws std::invalid_argument for an empty image or one
// whose pixel buffer does not match its size, std::runtime_error when zlib fails.
std::string EncodePng(const RgbImage& image);

// RFC 4648 base64 (for data: URIs in the HTML report).
std::string Base64(const std::string& bytes);

}  // namespace s2m::pipeline
