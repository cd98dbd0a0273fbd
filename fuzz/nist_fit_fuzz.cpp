// Fuzz target: the NIST reference-fit reader (.fit, acquisition/nist_reference.h), every layout on the same
// bytes.

#include "acquisition/nist_reference.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const s2m::fuzz::ScratchFile file(data, size, ".fit");
  s2m::fuzz::ExpectOnlyFormatErrors([&] { (void)s2m::ReadNistPlaneFit(file.path()); });
  s2m::fuzz::ExpectOnlyFormatErrors([&] { (void)s2m::ReadNistSphereFit(file.path()); });
  s2m::fuzz::ExpectOnlyFormatErrors([&] { (void)s2m::ReadNistCylinderFit(file.path()); });
  s2m::fuzz::ExpectOnlyFormatErrors([&] { (void)s2m::ReadNistConeFit(file.path()); });
  return 0;
}
