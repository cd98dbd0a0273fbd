// Fuzz target: UFO glyph outlines (.glif, acquisition/glyph_outline.h).

#include "acquisition/glyph_outline.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const s2m::fuzz::ScratchFile file(data, size, ".glif");
  s2m::fuzz::ExpectOnlyFormatErrors([&] { (void)s2m::ReadGlifContours(file.path(), 4); });
  return 0;
}
