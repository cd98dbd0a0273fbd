// Fuzz target: a recording frame's payload (acquisition/recording.h) without the database around it: the
// first byte picks the compression, the rest is the stored payload, decompressed and decoded as points.

#include "acquisition/recording.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  s2m::RecordingFrame frame;
  frame.compression = data[0] % 2 == 0 ? s2m::kNoCompression : s2m::kZlibCompression;
  frame.payload.assign(data + 1, data + size);
  s2m::fuzz::ExpectOnlyFormatErrors([&] {
    const std::vector<std::uint8_t> payload = s2m::FramePayload(frame, "fuzz.s2mrec", "frame 1");
    (void)s2m::DecodePoints(payload, "fuzz.s2mrec", "frame 1");
  });
  return 0;
}
