// Fuzz target: depth frames (acquisition/depth_frame.h): a 16-bit depth TIFF (libtiff) or the camera
// intrinsics XML beside it, chosen by the first byte.

#include "acquisition/depth_frame.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  if (data[0] % 2 == 0) {
    const s2m::fuzz::ScratchFile file(data + 1, size - 1, ".tiff");
    s2m::fuzz::ExpectOnlyFormatErrors([&] { (void)s2m::ReadDepthTiff(file.path()); });
  } else {
    const s2m::fuzz::ScratchFile file(data + 1, size - 1, ".xml");
    s2m::fuzz::ExpectOnlyFormatErrors([&] { (void)s2m::ReadDepthIntrinsicsXml(file.path()); });
  }
  return 0;
}
