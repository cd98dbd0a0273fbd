#include <zlib.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

#include "acquisition/format_error.h"
#include "acquisition/formats/readers.h"

namespace s2m::formats {
namespace {

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::string ReadGzip(const std::string& path) {
  gzFile gz = gzopen(path.c_str(), "rb");
  if (gz == nullptr) throw FormatError(path, "", std::string("cannot open: ") + std::strerror(errno));
  std::string out;
  char buffer[1 << 16];
  while (true) {
    const int n = gzread(gz, buffer, sizeof buffer);
    if (n < 0) {
      int code = 0;
      const std::string message = gzerror(gz, &code);
      gzclose(gz);
      throw FormatError(
          path, AtByte(out.size()),
          "corrupt gzip data after " + std::to_string(out.size()) + " uncompressed bytes (" + message + ")");
    }
    if (n == 0) break;
    out.append(buffer, static_cast<std::size_t>(n));
  }
  int code = Z_OK;
  const std::string message = gzerror(gz, &code);
  const int close_status = gzclose(gz);
  if (code != Z_OK || close_status == Z_BUF_ERROR) {
    throw FormatError(path, AtByte(out.size()),
                      "truncated gzip stream after " + std::to_string(out.size()) + " uncompressed bytes" +
                          (code != Z_OK ? " (" + message + ")" : ""));
  }
  return out;
}

}  // namespace

std::string ReadFileBytes(const std::string& path) {
  if (EndsWith(path, ".gz")) return ReadGzip(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FormatError(path, "", std::string("cannot open: ") + std::strerror(errno));
  std::ostringstream content;
  content << in.rdbuf();
  if (in.bad()) throw FormatError(path, "", "read error");
  return std::move(content).str();
}

}  // namespace s2m::formats
