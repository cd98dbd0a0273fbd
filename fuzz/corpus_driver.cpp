// The fuzz targets' main when they are not built with libFuzzer (docs/reliability.md): runs
// LLVMFuzzerTestOneInput once on every file named on the command line or found in a folder named there, so
// ctest replays the seed corpus and the regression files of each target in every build.

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size);

namespace {

int RunFile(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    std::fprintf(stderr, "cannot read %s\n", file.c_str());
    return 1;
  }
  const std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  LLVMFuzzerTestOneInput(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  int inputs = 0, failures = 0;
  for (int i = 1; i < argc; ++i) {
    const std::filesystem::path arg(argv[i]);
    std::error_code error;
    if (std::filesystem::is_directory(arg, error)) {
      std::vector<std::filesystem::path> files;
      for (const auto& entry : std::filesystem::recursive_directory_iterator(arg))
        if (entry.is_regular_file()) files.push_back(entry.path());
      std::sort(files.begin(), files.end());  // a fixed order: a failure is reproducible
      for (const auto& f : files) failures += RunFile(f), ++inputs;
    } else if (std::filesystem::exists(arg, error)) {
      failures += RunFile(arg), ++inputs;
    }
    // A regression folder that does not exist yet (no finding so far) is not an error.
  }
  std::printf("%d inputs replayed without a finding\n", inputs - failures);
  return failures == 0 && inputs > 0 ? 0 : 1;
}
