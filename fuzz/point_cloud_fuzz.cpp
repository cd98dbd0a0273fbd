// Fuzz target: the single-view point-cloud readers (acquisition/point_cloud_io.h). The first byte picks the
// format (the readers choose by file name), the rest is the file: PLY (ascii, binary, gzipped), PCD (ascii,
// binary, binary_compressed), XYZ/CSV text and NIST .ds.

#include "acquisition/point_cloud_io.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  static const char* const kSuffixes[] = {".ply", ".ply.gz", ".pcd", ".xyz", ".csv", ".ds"};
  const std::string suffix = kSuffixes[data[0] % (sizeof(kSuffixes) / sizeof(kSuffixes[0]))];
  const s2m::fuzz::ScratchFile file(data + 1, size - 1, suffix);
  s2m::fuzz::ExpectOnlyFormatErrors([&] { (void)s2m::ReadPointCloud(file.path()); });
  return 0;
}
