// Fuzz target: recordings as files (acquisition/recording.h): the SQLite checks on opening, the tables, the
// meta rows, the poses and the payloads of every stream.

#include "acquisition/recording.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const s2m::fuzz::ScratchFile file(data, size, ".s2mrec");
  s2m::fuzz::ExpectOnlyFormatErrors([&] {
    const s2m::RecordingReader reader = s2m::RecordingReader::Open(file.path());
    (void)reader.Summary();
    for (const s2m::RecordingStream& stream : reader.Streams()) {
      for (const s2m::RecordingFrame& frame : reader.Frames(stream.id)) {
        const std::vector<std::uint8_t> payload = s2m::FramePayload(frame, file.path().string(), "frame");
        if (stream.encoding == s2m::kPointsEncoding)
          (void)s2m::DecodePoints(payload, file.path().string(), "frame");
      }
    }
  });
  s2m::fuzz::ExpectOnlyFormatErrors([&] { (void)s2m::ReadRecording(file.path()); });
  return 0;
}
