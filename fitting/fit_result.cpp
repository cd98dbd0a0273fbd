#include "fitting/fit_result.h"

#include <array>
#include <cmath>

#include "fitting/enum_names.h"

namespace s2m {

ResidualStatistics ComputeResidualStatistics(const Eigen::VectorXd& d) {
  ResidualStatistics s;
  s.count = d.size();
  if (d.size() == 0) return s;
  s.rms = std::sqrt(d.squaredNorm() / static_cast<double>(d.size()));
  s.max_abs = d.cwiseAbs().maxCoeff();
  s.mean = d.mean();
  return s;
}

namespace {

constexpr std::array<EnumName<StopReason>, 7> kStopReasonNames = {{
    {StopReason::kClosedForm, "closed form"},
    {StopReason::kStepTolerance, "step below tolerance"},
    {StopReason::kGradientTolerance, "gradient below tolerance"},
    {StopReason::kObjectiveTolerance, "objective decrease below tolerance"},
    {StopReason::kNoFurtherDecrease, "no further decrease at machine precision"},
    {StopReason::kMaxIterations, "iteration limit reached"},
    {StopReason::kTargetReached, "target RMS reached"},
}};

}  // namespace

const char* ToString(StopReason reason) {
  return NameOf(kStopReasonNames, reason);
}

}  // namespace s2m
