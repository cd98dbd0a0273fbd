// Fuzz target: batch manifests (pipeline/batch.h): scan2model.batch/1 JSON or CSV, chosen by the first byte;
// every option value goes through the fit option table's checks.

#include "fuzz/fuzz_input.h"
#include "pipeline/batch.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const s2m::fuzz::ScratchFile file(data + 1, size - 1, data[0] % 2 == 0 ? ".json" : ".csv");
  s2m::fuzz::ExpectOnlyFormatErrors([&] { (void)s2m::pipeline::ReadBatchManifest(file.path().string()); });
  return 0;
}
