#include "acquisition/depth_frame.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "acquisition/format_error.h"
#include "acquisition/formats/readers.h"

namespace s2m {
namespace {

// TIFF 6.0 tags we read or must refuse.
constexpr std::uint16_t kImageWidth = 256, kImageLength = 257, kBitsPerSample = 258, kCompression = 259,
                        kPhotometric = 262, kStripOffsets = 273, kSamplesPerPixel = 277, kRowsPerStrip = 278,
                        kStripByteCounts = 279, kPlanarConfig = 284, kPredictor = 317, kTileWidth = 322,
                        kSampleFormat = 339;
constexpr std::uint64_t kNoCompression = 1, kPackBits = 32773;
// Far above any depth sensor, low enough that a corrupt header cannot make us allocate gigabytes.
constexpr std::uint64_t kMaxPixels = std::uint64_t{1} << 26;

class TiffBytes {
 public:
  TiffBytes(const std::string& bytes, std::string file) : bytes_(bytes), file_(std::move(file)) {
    if (bytes_.size() < 8)
      Fail("", "too short for a TIFF header (" + std::to_string(bytes_.size()) + " bytes)");
    if (bytes_.compare(0, 2, "II") == 0) {
      little_ = true;
    } else if (bytes_.compare(0, 2, "MM") == 0) {
      little_ = false;
    } else {
      Fail(AtByte(0), "not a TIFF file (no II/MM byte-order mark)");
    }
    const std::uint16_t magic = U16(2);
    if (magic == 43) Fail(AtByte(2), "BigTIFF is not supported");
    if (magic != 42) Fail(AtByte(2), "not a TIFF file (magic " + std::to_string(magic) + ", expected 42)");
  }

  [[noreturn]] void Fail(const std::string& where, const std::string& problem) const {
    throw FormatError(file_, where, problem);
  }
  void Need(std::uint64_t offset, std::uint64_t length, const std::string& what) const {
    if (offset > bytes_.size() || length > bytes_.size() - offset)
      Fail(AtByte(static_cast<std::size_t>(std::min<std::uint64_t>(offset, bytes_.size()))),
           "truncated: " + what + " needs " + std::to_string(length) + " bytes at offset " +
               std::to_string(offset) + ", the file has " + std::to_string(bytes_.size()));
  }
  std::uint16_t U16(std::uint64_t at) const {
    Need(at, 2, "a 16-bit field");
    const auto* p = reinterpret_cast<const unsigned char*>(bytes_.data() + at);
    return static_cast<std::uint16_t>(little_ ? p[0] | (p[1] << 8) : (p[0] << 8) | p[1]);
  }
  std::uint32_t U32(std::uint64_t at) const {
    Need(at, 4, "a 32-bit field");
    const auto* p = reinterpret_cast<const unsigned char*>(bytes_.data() + at);
    const std::uint32_t b0 = p[0], b1 = p[1], b2 = p[2], b3 = p[3];
    return little_ ? b0 | (b1 << 8) | (b2 << 16) | (b3 << 24) : (b0 << 24) | (b1 << 16) | (b2 << 8) | b3;
  }
  const unsigned char* At(std::uint64_t at) const {
    return reinterpret_cast<const unsigned char*>(bytes_.data() + at);
  }
  bool little() const { return little_; }

 private:
  const std::string& bytes_;
  std::string file_;
  bool little_ = true;
};

struct IfdEntry {
  std::uint16_t type = 0;
  std::uint32_t count = 0;
  std::uint64_t entry_offset = 0;  // of the 12-byte entry, for error messages and inline values
};

// The integer values of one entry (BYTE, SHORT or LONG, inline when they fit in 4 bytes).
std::vector<std::uint64_t> Values(const TiffBytes& tiff, const IfdEntry& e, const std::string& name) {
  std::size_t size = 0;
  switch (e.type) {
    case 1:
      size = 1;
      break;
    case 3:
      size = 2;
      break;
    case 4:
      size = 4;
      break;
    default:
      tiff.Fail(AtByte(e.entry_offset),
                name + " has field type " + std::to_string(e.type) + ", expected BYTE, SHORT or LONG");
  }
  if (e.count == 0) tiff.Fail(AtByte(e.entry_offset), name + " has no values");
  const std::uint64_t total = std::uint64_t{e.count} * size;
  const std::uint64_t data = total <= 4 ? e.entry_offset + 8 : tiff.U32(e.entry_offset + 8);
  tiff.Need(data, total, name + " values");
  std::vector<std::uint64_t> out(e.count);
  for (std::uint32_t i = 0; i < e.count; ++i) {
    const std::uint64_t at = data + std::uint64_t{i} * size;
    out[i] = size == 1 ? *tiff.At(at) : size == 2 ? tiff.U16(at) : tiff.U32(at);
  }
  return out;
}

// PackBits (TIFF 6.0 section 9): a signed header byte n, then n+1 literal bytes (n >= 0) or one byte repeated
// 1-n times (n < 0; -128 is a no-op). Decodes exactly `out_size` bytes; a strip that ends early is truncated
// and one that overruns its rows is corrupt, both reported.
void UnpackBits(const TiffBytes& tiff, std::uint64_t in_offset, std::uint64_t in_size, unsigned char* out,
                std::uint64_t out_size) {
  std::uint64_t i = 0, o = 0;
  const unsigned char* in = tiff.At(in_offset);
  while (o < out_size) {
    if (i >= in_size)
      tiff.Fail(AtByte(in_offset + i), "truncated PackBits strip: decoded " + std::to_string(o) + " of " +
                                           std::to_string(out_size) + " bytes");
    const int n = static_cast<signed char>(in[i++]);
    if (n == -128) continue;
    const std::uint64_t run = n >= 0 ? static_cast<std::uint64_t>(n) + 1 : static_cast<std::uint64_t>(1 - n);
    if (o + run > out_size)
      tiff.Fail(AtByte(in_offset + i - 1), "corrupt PackBits strip: a run overruns the strip's rows");
    if (n >= 0) {
      if (in_size - i < run)
        tiff.Fail(AtByte(in_offset + i), "truncated PackBits strip: literal run cut short");
      std::memcpy(out + o, in + i, run);
      i += run;
    } else {
      if (i >= in_size)
        tiff.Fail(AtByte(in_offset + i), "truncated PackBits strip: repeat run without its byte");
      std::memset(out + o, in[i++], run);
    }
    o += run;
  }
}

std::size_t LineOf(std::string_view text, std::size_t offset) {
  return 1 + static_cast<std::size_t>(
                 std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(offset), '\n'));
}

}  // namespace

DepthImage ReadDepthTiff(const std::filesystem::path& path) {
  const std::string file = path.string();
  const std::string bytes = formats::ReadFileBytes(file);
  const TiffBytes tiff(bytes, file);

  const std::uint64_t ifd = tiff.U32(4);
  const std::uint16_t n_entries = tiff.U16(ifd);
  tiff.Need(ifd + 2, std::uint64_t{n_entries} * 12, "the first image directory");
  std::map<std::uint16_t, IfdEntry> entries;
  for (std::uint16_t k = 0; k < n_entries; ++k) {
    const std::uint64_t at = ifd + 2 + std::uint64_t{k} * 12;
    entries[tiff.U16(at)] = IfdEntry{tiff.U16(at + 2), tiff.U32(at + 4), at};
  }
  const auto single = [&](std::uint16_t tag, const std::string& name,
                          std::optional<std::uint64_t> fallback) -> std::uint64_t {
    const auto it = entries.find(tag);
    if (it == entries.end()) {
      if (!fallback) tiff.Fail(AtByte(ifd), "missing TIFF tag " + name + " (" + std::to_string(tag) + ")");
      return *fallback;
    }
    const std::vector<std::uint64_t> v = Values(tiff, it->second, name);
    // Per-sample tags repeat their value once per sample; more than one sample is refused below anyway.
    return v.front();
  };

  if (entries.count(kTileWidth)) tiff.Fail(AtByte(ifd), "tiled TIFF is not supported (strips only)");
  const std::uint64_t width = single(kImageWidth, "ImageWidth", std::nullopt);
  const std::uint64_t height = single(kImageLength, "ImageLength", std::nullopt);
  if (width == 0 || height == 0 || width * height > kMaxPixels)
    tiff.Fail(AtByte(ifd), "unsupported image size " + std::to_string(width) + "x" + std::to_string(height));
  const std::uint64_t samples = single(kSamplesPerPixel, "SamplesPerPixel", 1);
  if (samples != 1)
    tiff.Fail(AtByte(ifd), std::to_string(samples) + " samples per pixel: a depth image has exactly 1");
  const std::uint64_t bits = single(kBitsPerSample, "BitsPerSample", 1);
  if (bits != 16)
    tiff.Fail(AtByte(ifd), std::to_string(bits) + " bits per sample: only 16-bit depth images are supported");
  const std::uint64_t sample_format = single(kSampleFormat, "SampleFormat", 1);
  if (sample_format != 1)
    tiff.Fail(AtByte(ifd), "SampleFormat " + std::to_string(sample_format) + ": only unsigned integers (1)");
  const std::uint64_t photometric = single(kPhotometric, "PhotometricInterpretation", 1);
  if (photometric != 1)
    tiff.Fail(AtByte(ifd), "PhotometricInterpretation " + std::to_string(photometric) +
                               ": only BlackIsZero greyscale (1), where the stored value is the depth");
  const std::uint64_t planar = single(kPlanarConfig, "PlanarConfiguration", 1);
  if (planar != 1)
    tiff.Fail(AtByte(ifd), "PlanarConfiguration " + std::to_string(planar) + " is not supported");
  const std::uint64_t predictor = single(kPredictor, "Predictor", 1);
  if (predictor != 1)
    tiff.Fail(AtByte(ifd), "Predictor " + std::to_string(predictor) + " is not supported (only none)");
  const std::uint64_t compression = single(kCompression, "Compression", kNoCompression);
  if (compression != kNoCompression && compression != kPackBits)
    tiff.Fail(AtByte(ifd), "compression " + std::to_string(compression) +
                               " is not supported (only none (1) and PackBits (32773))");
  const std::uint64_t rows_per_strip = std::min(single(kRowsPerStrip, "RowsPerStrip", height), height);
  if (rows_per_strip == 0) tiff.Fail(AtByte(ifd), "RowsPerStrip is 0");

  if (!entries.count(kStripOffsets)) tiff.Fail(AtByte(ifd), "missing TIFF tag StripOffsets (273)");
  if (!entries.count(kStripByteCounts)) tiff.Fail(AtByte(ifd), "missing TIFF tag StripByteCounts (279)");
  const std::vector<std::uint64_t> offsets = Values(tiff, entries[kStripOffsets], "StripOffsets");
  const std::vector<std::uint64_t> counts = Values(tiff, entries[kStripByteCounts], "StripByteCounts");
  const std::uint64_t strips = (height + rows_per_strip - 1) / rows_per_strip;
  if (offsets.size() != strips || counts.size() != strips)
    tiff.Fail(AtByte(ifd), std::to_string(offsets.size()) + " strip offsets and " +
                               std::to_string(counts.size()) + " byte counts for " + std::to_string(strips) +
                               " strips");

  const std::uint64_t row_bytes = width * 2;
  std::vector<unsigned char> raw(static_cast<std::size_t>(row_bytes * height));
  for (std::uint64_t s = 0; s < strips; ++s) {
    const std::uint64_t rows = std::min(rows_per_strip, height - s * rows_per_strip);
    const std::uint64_t expected = rows * row_bytes;
    unsigned char* out = raw.data() + s * rows_per_strip * row_bytes;
    tiff.Need(offsets[s], counts[s], "strip " + std::to_string(s));
    if (compression == kNoCompression) {
      if (counts[s] < expected)
        tiff.Fail(AtByte(offsets[s]), "truncated strip " + std::to_string(s) + ": " +
                                          std::to_string(counts[s]) + " bytes for " +
                                          std::to_string(expected));
      std::memcpy(out, tiff.At(offsets[s]), expected);
    } else {
      UnpackBits(tiff, offsets[s], counts[s], out, expected);
    }
  }

  DepthImage image;
  image.width = static_cast<int>(width);
  image.height = static_cast<int>(height);
  image.values.resize(static_cast<std::size_t>(width * height));
  for (std::size_t i = 0; i < image.values.size(); ++i) {
    const unsigned char a = raw[2 * i], b = raw[2 * i + 1];
    image.values[i] = static_cast<std::uint16_t>(tiff.little() ? a | (b << 8) : (a << 8) | b);
  }
  return image;
}

DepthIntrinsics ReadDepthIntrinsicsXml(const std::filesystem::path& path) {
  const std::string file = path.string();
  const std::string text = formats::ReadFileBytes(file);
  const std::string_view all(text);

  // The <depth> element (attributes allowed); intrinsics of the <rgb> camera must not be picked up instead.
  std::size_t open = all.find("<depth");
  while (open != std::string_view::npos && open + 6 < all.size() && all[open + 6] != '>' &&
         !std::isspace(static_cast<unsigned char>(all[open + 6])))
    open = all.find("<depth", open + 6);
  if (open == std::string_view::npos || open + 6 >= all.size())
    throw FormatError(file, "", "no <depth> element with the depth camera's intrinsics");
  const std::size_t body = all.find('>', open);
  const std::size_t close = all.find("</depth>", open);
  if (body == std::string_view::npos || close == std::string_view::npos || close < body)
    throw FormatError(file, AtLine(LineOf(all, open)), "<depth> element is not closed");
  const std::string_view section = all.substr(body + 1, close - body - 1);

  const auto number = [&](const std::string& tag, bool required) -> std::optional<double> {
    const std::string start = "<" + tag + ">", end = "</" + tag + ">";
    const std::size_t a = section.find(start);
    if (a == std::string_view::npos) {
      if (required) throw FormatError(file, AtLine(LineOf(all, open)), "missing <" + tag + "> in <depth>");
      return std::nullopt;
    }
    const std::size_t where = body + 1 + a;
    if (section.find(start, a + 1) != std::string_view::npos)
      throw FormatError(file, AtLine(LineOf(all, where)), "<" + tag + "> appears more than once in <depth>");
    const std::size_t b = section.find(end, a);
    if (b == std::string_view::npos)
      throw FormatError(file, AtLine(LineOf(all, where)), "<" + tag + "> is not closed");
    std::string_view v = section.substr(a + start.size(), b - a - start.size());
    while (!v.empty() && std::isspace(static_cast<unsigned char>(v.front()))) v.remove_prefix(1);
    while (!v.empty() && std::isspace(static_cast<unsigned char>(v.back()))) v.remove_suffix(1);
    double x = 0;
    const auto [ptr, ec] = std::from_chars(v.data(), v.data() + v.size(), x);
    if (v.empty() || ec != std::errc() || ptr != v.data() + v.size() || !std::isfinite(x))
      throw FormatError(file, AtLine(LineOf(all, where)),
                        "<" + tag + "> is not a finite number: '" + std::string(v) + "'");
    return x;
  };

  DepthIntrinsics k;
  k.fx = *number("focal_length_x", true);
  k.fy = *number("focal_length_y", true);
  k.cx = *number("principal_point_x", true);
  k.cy = *number("principal_point_y", true);
  if (const std::optional<double> scale = number("z_multiplication_factor", false)) {
    k.depth_scale = *scale;
    k.depth_scale_from_file = true;
  }
  if (k.fx <= 0 || k.fy <= 0) throw FormatError(file, "", "focal lengths must be positive");
  if (k.depth_scale <= 0) throw FormatError(file, "", "z_multiplication_factor must be positive");
  return k;
}

std::filesystem::path DepthIntrinsicsPathFor(const std::filesystem::path& depth_tiff) {
  const std::string name = depth_tiff.filename().string();
  for (const std::string suffix : {"_depth.tiff", "_depth.tif"}) {
    if (name.size() > suffix.size() && name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0)
      return depth_tiff.parent_path() / (name.substr(0, name.size() - suffix.size()) + ".xml");
  }
  throw FormatError(depth_tiff.string(), "",
                    "cannot find the intrinsics: the name should end in _depth.tiff (beside <frame>.xml)");
}

DepthCloud BackProject(const DepthImage& image, const DepthIntrinsics& k) {
  if (!(k.fx > 0 && k.fy > 0 && k.depth_scale > 0) || !std::isfinite(k.fx) || !std::isfinite(k.fy) ||
      !std::isfinite(k.cx) || !std::isfinite(k.cy) || !std::isfinite(k.depth_scale))
    throw std::invalid_argument("BackProject: focal lengths and depth scale must be positive and finite");
  if (image.width < 0 || image.height < 0 ||
      image.values.size() != static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height))
    throw std::invalid_argument("BackProject: the image has " + std::to_string(image.values.size()) +
                                " values for " + std::to_string(image.width) + "x" +
                                std::to_string(image.height));
  const auto valid = static_cast<Eigen::Index>(
      std::count_if(image.values.begin(), image.values.end(), [](std::uint16_t d) { return d != 0; }));
  DepthCloud cloud;
  cloud.points.resize(3, valid);
  cloud.no_return = static_cast<Eigen::Index>(image.values.size()) - valid;
  Eigen::Index j = 0;
  for (int v = 0; v < image.height; ++v) {
    for (int u = 0; u < image.width; ++u) {
      const std::uint16_t d = image.at(u, v);
      if (d == 0) continue;
      const double z = d * k.depth_scale;
      cloud.points.col(j++) << (u - k.cx) * z / k.fx, (v - k.cy) * z / k.fy, z;
    }
  }
  return cloud;
}

Scan ReadDepthFrame(const std::filesystem::path& depth_tiff) {
  const DepthImage image = ReadDepthTiff(depth_tiff);
  const std::filesystem::path xml = DepthIntrinsicsPathFor(depth_tiff);
  const DepthIntrinsics k = ReadDepthIntrinsicsXml(xml);
  DepthCloud cloud = BackProject(image, k);
  Scan scan;
  scan.points = std::move(cloud.points);
  scan.units = "m";
  scan.metadata.device = "file:depth-frame";
  scan.metadata.source = depth_tiff.string();
  scan.metadata.notes.push_back(std::to_string(cloud.no_return) + " of " +
                                std::to_string(image.values.size()) +
                                " pixels had no return (depth 0) and were dropped");
  scan.metadata.notes.push_back("intrinsics from " + xml.string() +
                                (k.depth_scale_from_file ? "" : "; depth scale assumed 0.001 m per unit"));
  return scan;
}

}  // namespace s2m
