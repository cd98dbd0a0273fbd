// Fuzz target: part files (acquisition/part_file.h), parsed from memory.

#include "acquisition/part_file.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(s2m::fuzz::AsText(data, size));
  s2m::fuzz::ExpectOnlyFormatErrors([&] { (void)s2m::ParsePartFile(text, "fuzz.part.json"); });
  return 0;
}
