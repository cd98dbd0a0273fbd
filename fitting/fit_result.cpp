#include "fitting/fit_result.h"

#include <cmath>

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

const char* ToString(StopReason reason) {
  switch (reason) {
    case StopReason::kClosedForm:
      return "closed form";
    case StopReason::kStepTolerance:
      return "step below tolerance";
    case StopReason::kGradientTolerance:
      return "gradient below tolerance";
    case StopReason::kObjectiveTolerance:
      return "objective decrease below tolerance";
    case StopReason::kNoFurtherDecrease:
      return "no further decrease at machine precision";
    case StopReason::kMaxIterations:
      return "iteration limit reached";
    case StopReason::kTargetReached:
      return "target RMS reached";
  }
  return "unknown";
}

}  // namespace s2m
