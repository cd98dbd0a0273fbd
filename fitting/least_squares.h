#pragma once
// A small dense Levenberg-Marquardt solver for general non-linear least squares, min 1/2 |r(x)|^2, for
// problems with up to a few hundred residuals and a few dozen parameters (model parameters of constrained
// parts, calibration, certification runs). Each step solves the damped problem [J; sqrt(mu) D] dx = [-r; 0]
// by QR, not by the normal equations, so ill-conditioned problems keep their digits (the NIST StRD problems
// are checked in the tests). Damping: Nielsen's update (Madsen, Nielsen, Tingleff, "Methods for non-linear
// least squares problems", 2004, section 3.2) of the damping mu |D dx|^2, with D chosen by `DampingScaling`.

#include <Eigen/Core>
#include <functional>
#include <vector>

#include "fitting/fit_result.h"

namespace s2m {

struct LeastSquaresProblem {
  int num_residuals = 0;
  int num_parameters = 0;
  // Residuals at x and, when `jacobian` is not null, the Jacobian dr/dx (num_residuals x num_parameters).
  // Returns false when x is outside the model's domain (the step is then rejected, never accepted with NaNs).
  std::function<bool(const Eigen::VectorXd& x, Eigen::VectorXd& residuals, Eigen::MatrixXd* jacobian)>
      evaluate;
};

// How the damping term mu |D dx|^2 weighs the parameters. Neither choice alone solves every NIST StRD
// problem: the isotropic one ends on MGH10 from start 1 with b1 -> 0 (its parameters span seven orders of
// magnitude), Marquardt's ends on BoxBOD from start 1 on the plateau b2 -> infinity (as Ceres 2.1 does,
// measured).
enum class DampingScaling {
  kIsotropic,  // D = sqrt(max_i diag(J^T J)_i) I (Levenberg): robust on plateaus, not unit-invariant
  // D_i = sqrt(max(diag(J^T J)_i, 1e-6 (1 + |J_i(x0)|)^2)) (Marquardt, with Ceres' floor relative to the
  // column's start size): invariant to the units of each parameter.
  kMarquardt,
  // Both runs from x0, the lower final cost wins (twice the work; both fits are degenerate limits, not
  // minima, only where one of them fails).
  kAutomatic,
};
const char* ToString(DampingScaling scaling);

struct LeastSquaresOptions {
  int max_iterations = 1000;          // accepted steps (minimizer.h)
  double function_tolerance = 1e-16;  // on the relative reduction of the cost, actual and predicted
  double step_tolerance = 1e-16;      // on |D dx| relative to |D x|
  double gradient_tolerance = 1e-16;  // on max |J^T r| relative to |J|_max |r|
  double initial_damping = 1e-3;      // mu for the isotropic scaling (Marquardt's starts at 1e-4, as Ceres)
  DampingScaling damping_scaling = DampingScaling::kAutomatic;
};

struct LeastSquaresResult {
  Eigen::VectorXd x;
  double cost = 0.0;  // 1/2 |r|^2
  int iterations = 0;
  int evaluations = 0;
  StopReason stop_reason = StopReason::kMaxIterations;
  DampingScaling scaling_used = DampingScaling::kIsotropic;  // of the returned run (iterations are its own;
                                                             // evaluations count both runs)
};

// Throws std::invalid_argument when the problem cannot be evaluated at x0.
LeastSquaresResult SolveLeastSquares(const LeastSquaresProblem& problem, const Eigen::VectorXd& x0,
                                     const LeastSquaresOptions& options = {});

}  // namespace s2m
