#include "fitting/least_squares.h"

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace s2m {

const char* ToString(DampingScaling scaling) {
  switch (scaling) {
    case DampingScaling::kIsotropic:
      return "isotropic";
    case DampingScaling::kMarquardt:
      return "marquardt";
    case DampingScaling::kAutomatic:
      return "automatic";
  }
  return "?";
}

namespace {

LeastSquaresResult RunLevenbergMarquardt(const LeastSquaresProblem& problem, const Eigen::VectorXd& x0,
                                         const LeastSquaresOptions& options, DampingScaling scaling) {
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
  result.scaling_used = scaling;
  const Eigen::VectorXd start_column_norms = J.colwise().norm().transpose();
  // Marquardt's floor keeps a parameter damped after its column vanishes (Ceres' min_diagonal = 1e-6, applied
  // in its Jacobi-scaled variables, i.e. relative to (1 + the column's start norm)^2).
  const Eigen::VectorXd marquardt_floor = 1e-6 * (Eigen::VectorXd::Ones(n) + start_column_norms).cwiseAbs2();
  const auto damping_scale = [&](const Eigen::MatrixXd& jacobian) -> Eigen::VectorXd {
    const Eigen::VectorXd diagonal = jacobian.colwise().squaredNorm().transpose();
    if (scaling == DampingScaling::kMarquardt) return diagonal.cwiseMax(marquardt_floor).cwiseSqrt();
    return Eigen::VectorXd::Constant(n, std::sqrt(std::max(diagonal.maxCoeff(), 1e-300)));
  };
  Eigen::VectorXd scale = damping_scale(J);
  // mu is dimensionless: the damping term mu |D dx|^2 carries the scale through D.
  double mu = scaling == DampingScaling::kMarquardt ? 1e-4 : options.initial_damping;
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
      // Levenberg's isotropic scale stays at its start value (re-scaling it each step was measured to lose
      // MGH17 and Thurber); Marquardt's follows the current columns.
      if (scaling == DampingScaling::kMarquardt) scale = damping_scale(J);

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

}  // namespace

LeastSquaresResult SolveLeastSquares(const LeastSquaresProblem& problem, const Eigen::VectorXd& x0,
                                     const LeastSquaresOptions& options) {
  if (options.damping_scaling != DampingScaling::kAutomatic) {
    return RunLevenbergMarquardt(problem, x0, options, options.damping_scaling);
  }
  // Two independent runs (the problems this core serves are small): each scaling fails where the other
  // succeeds, and a lower cost from the same start is the better fit by definition.
  LeastSquaresResult isotropic = RunLevenbergMarquardt(problem, x0, options, DampingScaling::kIsotropic);
  LeastSquaresResult marquardt = RunLevenbergMarquardt(problem, x0, options, DampingScaling::kMarquardt);
  const int evaluations = isotropic.evaluations + marquardt.evaluations;
  LeastSquaresResult& best = marquardt.cost < isotropic.cost ? marquardt : isotropic;
  best.evaluations = evaluations;
  return best;
}

}  // namespace s2m
