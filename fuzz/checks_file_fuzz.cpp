// Fuzz target: inspection checks files (scan2model.checks/1, pipeline/inspection.h), parsed from memory.

#include "fuzz/fuzz_input.h"
#include "pipeline/inspection.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(s2m::fuzz::AsText(data, size));
  s2m::fuzz::ExpectOnlyFormatErrors([&] { (void)s2m::pipeline::ParseChecksFile(text, "fuzz.checks.json"); });
  return 0;
}
