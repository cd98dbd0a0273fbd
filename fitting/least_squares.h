#pragma once
// A small dense Levenberg-Marquardt solver for general non-linear least squares, min 1/2 |r(x)|^2, for
// problems with up to a few hundred residuals and a few dozen parameters (model parameters of constrained
// parts, calibration, certification runs). Each step solves the damped problem [J; sqrt(mu) D] dx = [-r; 0]
// by QR, not by the normal equations, so ill-conditioned problems keep their digits (the NIST StRD problems
// are checked in the tests). Damping: Nielsen's update (Madsen, Nielsen, Tingleff, "Methods for non-linear
// least squares problems", 2004, section 3.2) of an isotropic damping mu * max(diag(J^T J)).

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

struct LeastSquaresOptions {
  int max_iterations = 1000;          // accepted and rejected steps together
  double function_tolerance = 1e-16;  // on the relative reduction of the cost, actual and predicted
  double step_tolerance = 1e-16;      // on |D dx| relative to |D x|
  double gradient_tolerance = 1e-16;  // on max |J^T r| relative to |J|_max |r|
  double initial_damping = 1e-3;      // mu, relative to max(diag(J^T J))
};

struct LeastSquaresResult {
  Eigen::VectorXd x;
  double cost = 0.0;  // 1/2 |r|^2
  int iterations = 0;
  int evaluations = 0;
  StopReason stop_reason = StopReason::kMaxIterations;
};

// Throws std::invalid_argument when the problem cannot be evaluated at x0.
LeastSquaresResult SolveLeastSquares(const LeastSquaresProblem& problem, const Eigen::VectorXd& x0,
                                     const LeastSquaresOptions& options = {});

}  // namespace s2m
