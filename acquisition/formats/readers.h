#pragma once
// Internal: one reader per format, each parsing a whole file already in memory.

#include <cstdint>
#include <string>
#include <vector>

#include "registration/scan.h"

namespace s2m::formats {

// The whole file, gunzipped when the name ends in .gz. Throws FormatError when it cannot be read.
std::string ReadFileBytes(const std::string& path);

Scan ParsePly(const std::string& bytes, const std::string& file);
// A PLY mesh's faces: face i's vertex indices are indices[offsets[i] .. offsets[i + 1]) (offsets has one
// entry more than there are faces); labels (one per face) when the face element has a "label", "group" or
// "region" property.
struct PlyFaces {
  std::vector<std::int64_t> indices;
  std::vector<std::size_t> offsets;
  std::vector<std::int64_t> labels;
  bool has_labels = false;
};
// The vertices (as ParsePly) and the faces; throws FormatError when the file has no face element.
Scan ParsePlyMesh(const std::string& bytes, const std::string& file, PlyFaces& faces);
Scan ParsePcd(const std::string& bytes, const std::string& file);
Scan ParseTextPoints(const std::string& bytes, const std::string& file);
Scan ParseNistDs(const std::string& bytes, const std::string& file);

}  // namespace s2m::formats
