#include "acquisition/format_error.h"

namespace s2m {
namespace {
// Built with append: GCC 12 reports a false -Wrestrict on chains of operator+ (GCC bug 105651).
std::string Compose(const std::string& file, const std::string& location, const std::string& problem) {
  std::string out = file;
  out.append(": ");
  if (!location.empty()) out.append(location).append(": ");
  out.append(problem);
  return out;
}
}  // namespace

FormatError::FormatError(std::string file, std::string location, std::string problem)
    : std::runtime_error(Compose(file, location, problem)),
      file_(std::move(file)),
      location_(std::move(location)),
      problem_(std::move(problem)) {}

std::string AtLine(std::size_t line) {
  return "line " + std::to_string(line);
}
std::string AtByte(std::size_t offset) {
  return "byte " + std::to_string(offset);
}

}  // namespace s2m
