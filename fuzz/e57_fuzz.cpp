// Fuzz target: E57 files (acquisition/e57_io.h): the header, the pages' CRC-32C, the XML section, the
// compressed vectors' packets and bit-pack codec, and the scans as one cloud and as views.

#include "acquisition/e57_io.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const s2m::fuzz::ScratchFile file(data, size, ".e57");
  s2m::fuzz::ExpectOnlyFormatErrors([&] {
    const s2m::E57Data e57 = s2m::ReadE57(file.path());
    (void)s2m::ToScanSet(e57, file.path());
    (void)s2m::ToOneCloud(e57, file.path());
  });
  return 0;
}
