#pragma once
// The one error every reader throws: it names the file, where in it (line or byte offset) and what is wrong.

#include <stdexcept>
#include <string>

namespace s2m {

class FormatError : public std::runtime_error {
 public:
  FormatError(std::string file, std::string location, std::string problem);

  const std::string& file() const { return file_; }
  const std::string& location() const { return location_; }  // "line 12", "byte 4096", "header", or empty
  const std::string& problem() const { return problem_; }

 private:
  std::string file_, location_, problem_;
};

std::string AtLine(std::size_t line);
std::string AtByte(std::size_t offset);

}  // namespace s2m
