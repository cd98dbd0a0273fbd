// Fuzz target: Horus calibration documents (devices/horus_calibration.h), the JSON a recording carries and
// `scan2model calibrate` writes. Documented errors: std::runtime_error / std::invalid_argument with a
// message.

#include <nlohmann/json.hpp>

#include "devices/horus_calibration.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const s2m::fuzz::ScratchFile file(data, size, ".json");
  s2m::fuzz::ExpectOnlyStandardErrors([&] { (void)s2m::ReadHorusCalibrationFile(file.path()); });
  return 0;
}
