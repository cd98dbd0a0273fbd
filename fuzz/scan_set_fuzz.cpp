// Fuzz target: multi-view manifests (acquisition/scan_set_io.h): scan2model.views/1 JSON and Stanford .conf,
// chosen by the first byte. The views they name do not exist beside the scratch file, so a manifest that
// parses ends in the documented "view file missing" error: the parsing up to there is what is fuzzed.

#include "acquisition/scan_set_io.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const s2m::fuzz::ScratchFile file(data + 1, size - 1, data[0] % 2 == 0 ? ".json" : ".conf");
  s2m::fuzz::ExpectOnlyFormatErrors([&] { (void)s2m::ReadScanSet(file.path()); });
  return 0;
}
