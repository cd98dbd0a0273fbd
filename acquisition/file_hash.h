#pragma once
// SHA-256 (FIPS 180-4) of files and byte strings: the data file hashes of a metrology report's traceability
// block (docs/metrology.md section 9).

#include <filesystem>
#include <string>

namespace s2m {

// Lower-case hex digest of `bytes`.
std::string Sha256Hex(const std::string& bytes);
// Of a file's bytes as stored (not gunzipped). Throws FormatError naming the file when it cannot be read.
std::string Sha256OfFile(const std::filesystem::path& path);

}  // namespace s2m
