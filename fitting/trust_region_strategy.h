#pragma once
// The Levenberg-Marquardt trust-region strategy: owns the damping lambda of the damped normal equations
// (H + lambda D^2) dx = -g and updates it from each trial's outcome (docs/method.md section 14,
// eq. 41). The minimizer (minimizer.h) asks it for lambda, tells it whether the trial decreased the
// true objective and by how much against the linear model's prediction, and stops when the strategy is
// exhausted.

#include "fitting/optimizer_options.h"

namespace s2m {

class LevenbergMarquardtStrategy {
 public:
  explicit LevenbergMarquardtStrategy(const DampingOptions& options);
  double damping() const { return lambda_; }
  // gain_ratio = actual / predicted decrease of the accepted trial (Nielsen's update uses it).
  void StepAccepted(double gain_ratio);
  void StepRejected();
  // No damping within the bounds gives a decrease: lambda has passed its maximum.
  bool Exhausted() const { return !(lambda_ <= options_.max); }
  void Reset();

 private:
  DampingOptions options_;
  double lambda_ = 0.0;
  double nu_ = 2.0;  // Nielsen's rejection factor
};

}  // namespace s2m
