#include "fitting/least_squares.h"

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace s2m {

LeastSquaresResult SolveLeastSquares(const LeastSquaresProblem& problem, const Eigen::VectorXd& x0,
                                     const LeastSquaresOptions& options) {
  const int m = problem.num_residuals, n = problem.num_parameters;
  LeastSquaresResult result;
  result.x = x0;
  Eigen::VectorXd r(m), r_new(m);
  Eigen::MatrixXd J(m, n);
  if (!problem.evaluate(result.x, r, &J) || !r.allFinite() || !J.allFinite()) {
    throw std::invalid_argument("the least-squares problem cannot be evaluated at the starting point");
  }
  ++result.evaluations;
  result.cost = 0.5 * r.squaredNorm();
  // Levenberg's isotropic damping mu * max(diag(J^T J)) * I. Moré's per-parameter scaling was measured worse
  // on the StRD set (BoxBOD from start 1 stalls on a plateau with it).
  const Eigen::VectorXd scale =
      Eigen::VectorXd::Constant(n, std::max(std::sqrt(J.colwise().squaredNorm().maxCoeff()), 1e-300));
  // mu is dimensionless: the damping term mu |D dx|^2 carries the scale through D (Marquardt's diag(J^T J)).
  double mu = options.initial_damping;
  double nu = 2.0;
  Eigen::MatrixXd augmented(m + n, n);
  Eigen::VectorXd rhs(m + n);

  while (result.iterations < options.max_iterations) {
    const Eigen::VectorXd g = J.transpose() * r;
    const double col_max = J.colwise().norm().maxCoeff();
    if (result.cost == 0.0 || g.cwiseAbs().maxCoeff() <= options.gradient_tolerance * col_max * r.norm()) {
      result.stop_reason = StopReason::kGradientTolerance;
      return result;
    }
    // min |J dx + r|^2 + mu |D dx|^2 as one QR-solved least-squares problem.
    augmented.topRows(m) = J;
    augmented.bottomRows(n) = std::sqrt(mu) * scale.asDiagonal();
    rhs.head(m) = -r;
    rhs.tail(n).setZero();
    const Eigen::VectorXd dx = augmented.colPivHouseholderQr().solve(rhs);
    ++result.iterations;
    const bool tiny_step =
        (scale.cwiseProduct(dx)).norm() <=
        options.step_tolerance * ((scale.cwiseProduct(result.x)).norm() + options.step_tolerance);
    const Eigen::VectorXd x_new = result.x + dx;
    const double predicted = 0.5 * (r.squaredNorm() - (J * dx + r).squaredNorm());
    Eigen::MatrixXd J_new(m, n);
    const bool ok = problem.evaluate(x_new, r_new, nullptr) && r_new.allFinite();
    ++result.evaluations;
    const double cost_new = ok ? 0.5 * r_new.squaredNorm() : std::numeric_limits<double>::infinity();
    const double actual = result.cost - cost_new;
    const double rho = predicted > 0 ? actual / predicted : -1.0;
    if (ok && rho > 0 && actual > 0) {
      if (!problem.evaluate(x_new, r_new, &J_new) || !J_new.allFinite()) {
        mu *= nu;
        nu *= 2.0;
        continue;
      }
      ++result.evaluations;
      const double relative = actual / result.cost;
      result.x = x_new;
      r = r_new;
      J = J_new;
      result.cost = cost_new;

      mu *= std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * rho - 1.0, 3));
      nu = 2.0;
      if (tiny_step) {
        result.stop_reason = StopReason::kStepTolerance;
        return result;
      }
      if (relative <= options.function_tolerance &&
          predicted / (cost_new + 1e-300) <= options.function_tolerance) {
        result.stop_reason = StopReason::kObjectiveTolerance;
        return result;
      }
    } else {
      if (tiny_step &&
          mu < 1.0) {  // an undamped step too small to change the cost: converged at rounding level
        result.stop_reason = StopReason::kStepTolerance;
        return result;
      }
      mu *= nu;
      nu *= 2.0;
      if (!(mu < 1e300)) {
        result.stop_reason = StopReason::kNoFurtherDecrease;
        return result;
      }
    }
  }
  result.stop_reason = StopReason::kMaxIterations;
  return result;
}

}  // namespace s2m
