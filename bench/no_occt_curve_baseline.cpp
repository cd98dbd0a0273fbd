#include "bench/curve_baselines.h"

namespace s2m::bench {

bool OcctAvailable(std::string* why) {
  if (why) *why = "OpenCASCADE was not found at configure time (Debian: libocct-modeling-algorithms-dev)";
  return false;
}

std::optional<BSplineCurve> OcctSmoothing(const Eigen::Matrix2Xd&, double, double, double, int, double) {
  return std::nullopt;
}

}  // namespace s2m::bench
