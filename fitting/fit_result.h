#pragma once
// What every fit reports: residual statistics, the iteration history and why the iteration stopped.

#include <Eigen/Core>
#include <string>
#include <vector>

namespace s2m {

// Residual statistics at exact foot points (docs/method.md section 2: RMS = sqrt(1/n sum ||X_j - s_j||^2),
// max distance).
struct ResidualStatistics {
  Eigen::Index count = 0;
  double rms = 0.0;
  double max_abs = 0.0;
  double mean = 0.0;  // mean signed distance (outside positive)
};
ResidualStatistics ComputeResidualStatistics(const Eigen::VectorXd& signed_distances);

struct IterationRecord {
  int iteration = 0;
  double rms = 0.0;           // after the iteration, input units
  double max_distance = 0.0;  // after the iteration, input units
  double objective = 0.0;     // 1/2 sum d^2 in normalized units
  double damping = 0.0;       // Levenberg-Marquardt lambda used for the accepted step
  double step_norm = 0.0;     // norm of the accepted parameter step (normalized units)
  double seconds = 0.0;       // wall time since the start of the fit
};

enum class StopReason {
  kClosedForm,          // exact solution, no iteration needed
  kStepTolerance,       // the step fell below the step tolerance
  kGradientTolerance,   // the residual vector is orthogonal to the Jacobian's range (first-order optimal)
  kObjectiveTolerance,  // relative decrease of the objective below tolerance
  kNoFurtherDecrease,   // damping reached its limit: the objective cannot decrease at machine precision
  kMaxIterations,
  kTargetReached,  // the caller's target RMS was reached
};
const char* ToString(StopReason reason);

}  // namespace s2m
