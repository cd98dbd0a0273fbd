#pragma once
// Shared pieces of the fuzz targets (docs/reliability.md): the readers take file names, so each input is
// written to a scratch file first, and the target says which exceptions are a reader's documented answer to
// bad input. Anything else that escapes (another exception type, a crash, a sanitizer report, an allocation
// beyond the fuzzer's limit) is a finding.

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

#include "acquisition/format_error.h"

namespace s2m::fuzz {

// The bytes as a file named scratch<suffix> in a folder of this process, removed again on destruction.
class ScratchFile {
 public:
  ScratchFile(const std::uint8_t* data, std::size_t size, const std::string& suffix) {
    const std::filesystem::path folder =
        std::filesystem::temp_directory_path() / ("s2m_fuzz_" + std::to_string(::getpid()));
    std::filesystem::create_directories(folder);
    path_ = folder / ("scratch" + suffix);
    std::ofstream out(path_, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    if (!out) {
      std::fprintf(stderr, "fuzz: cannot write the scratch file %s\n", path_.c_str());
      std::abort();  // the harness, not the reader, failed: stop rather than report nonsense
    }
  }
  ~ScratchFile() {
    std::error_code ignored;
    std::filesystem::remove(path_, ignored);
  }
  ScratchFile(const ScratchFile&) = delete;
  ScratchFile& operator=(const ScratchFile&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

inline std::string_view AsText(const std::uint8_t* data, std::size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

// A documented error of the reader must name the file it read: an empty message is a finding as well.
[[noreturn]] inline void Finding(const char* what, const char* message) {
  std::fprintf(stderr, "fuzz finding: %s: %s\n", what, message);
  std::abort();
}

// Runs `read`; FormatError (every reader's documented error) is the expected answer to bad input and must
// carry a problem; any other exception is a finding.
template <typename Read>
void ExpectOnlyFormatErrors(Read&& read) {
  try {
    read();
  } catch (const FormatError& e) {
    if (e.problem().empty()) Finding("FormatError without a problem", e.what());
  } catch (const std::exception& e) {
    Finding("an exception other than FormatError escaped", e.what());
  }
}

// For the readers documented to throw a standard exception with a message (JSON documents handed over in
// memory).
template <typename Read>
void ExpectOnlyStandardErrors(Read&& read) {
  try {
    read();
  } catch (const std::exception& e) {
    if (std::string_view(e.what()).empty()) Finding("an exception without a message", "");
  }
}

}  // namespace s2m::fuzz
