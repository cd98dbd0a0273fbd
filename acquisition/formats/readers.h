#pragma once
// Internal: one reader per format, each parsing a whole file already in memory.

#include <string>

#include "registration/scan.h"

namespace s2m::formats {

// The whole file, gunzipped when the name ends in .gz. Throws FormatError when it cannot be read.
std::string ReadFileBytes(const std::string& path);

Scan ParsePly(const std::string& bytes, const std::string& file);
Scan ParsePcd(const std::string& bytes, const std::string& file);
Scan ParseTextPoints(const std::string& bytes, const std::string& file);
Scan ParseNistDs(const std::string& bytes, const std::string& file);

}  // namespace s2m::formats
