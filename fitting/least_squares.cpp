#include "fitting/least_squares.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "fitting/enum_names.h"
#include "fitting/minimizer.h"

namespace s2m {

namespace {

constexpr std::array<EnumName<DampingScaling>, 3> kDampingScalingNames = {{
    {DampingScaling::kIsotropic, "isotropic"},
    {DampingScaling::kMarquardt, "marquardt"},
    {DampingScaling::kAutomatic, "automatic"},
}};

}  // namespace

const char* ToString(DampingScaling scaling) {
  return NameOf(kDampingScalingNames, scaling, "?");
}

namespace {

// The general least-squares problem min 1/2 |r(x)|^2 as the minimizer's problem: the Jacobian and residual
// of the current x in a DenseJacobianSystem (QR-solved, docs/method.md eq. 38), the damping scale D of the
// chosen scaling, and the trial's residual and Jacobian kept for its acceptance.
class DenseLeastSquaresProblem : public NonlinearProblem {
 public:
  DenseLeastSquaresProblem(const LeastSquaresProblem& problem, const Eigen::VectorXd& x0,
                           DampingScaling scaling, const LeastSquaresOptions& options)
      : problem_(problem), scaling_(scaling), options_(options), x_(x0) {
    const int m = problem.num_residuals, n = problem.num_parameters;
    system_.r().resize(m);
    system_.J().resize(m, n);
    if (!problem.evaluate(x_, system_.r(), &system_.J()) || !system_.r().allFinite() ||
        !system_.J().allFinite()) {
      throw std::invalid_argument("the least-squares problem cannot be evaluated at the starting point");
    }
    ++evaluations_;
    cost_ = 0.5 * system_.r().squaredNorm();
    const Eigen::VectorXd start_column_norms = system_.J().colwise().norm().transpose();
    // Marquardt's floor keeps a parameter damped after its column vanishes (Ceres' min_diagonal = 1e-6,
    // applied in its Jacobi-scaled variables, i.e. relative to (1 + the column's start norm)^2).
    marquardt_floor_ = 1e-6 * (Eigen::VectorXd::Ones(n) + start_column_norms).cwiseAbs2();
    UpdateScale();
  }

  double Cost() const override { return cost_; }
  LinearSystem& Linearize() override { return system_; }

  double EvaluateTrial(const Eigen::VectorXd& step, bool /*final_if_accepted*/) override {
    trial_x_ = x_ + step;
    trial_r_.resize(system_.r().size());
    const bool ok = problem_.evaluate(trial_x_, trial_r_, nullptr) && trial_r_.allFinite();
    ++evaluations_;
    const double trial_cost = ok ? 0.5 * trial_r_.squaredNorm() : std::numeric_limits<double>::infinity();
    if (!(trial_cost < cost_)) return trial_cost;
    // Only a trial the minimizer will accept needs its Jacobian; one that cannot be evaluated is rejected.
    trial_j_.resize(system_.J().rows(), system_.J().cols());
    ++evaluations_;
    if (!problem_.evaluate(trial_x_, trial_r_, &trial_j_) || !trial_j_.allFinite())
      return std::numeric_limits<double>::infinity();
    return trial_cost;
  }

  void AcceptTrial() override {
    x_.swap(trial_x_);
    system_.r().swap(trial_r_);
    system_.J().swap(trial_j_);
    cost_ = 0.5 * system_.r().squaredNorm();
    // Levenberg's isotropic scale stays at its start value (re-scaling it each step was measured to lose
    // MGH17 and Thurber); Marquardt's follows the current columns.
    if (scaling_ == DampingScaling::kMarquardt) UpdateScale();
  }

  // |D dx| <= tol (|D x| + tol): the step measured in the damping's own metric.
  bool StepIsNegligible(const Eigen::VectorXd& step, double tolerance) const override {
    const Eigen::VectorXd& d = system_.D();
    return d.cwiseProduct(step).norm() <= tolerance * (d.cwiseProduct(x_).norm() + tolerance);
  }

  void DescribeState(IterationRecord& record) const override {
    record.rms = std::sqrt(2.0 * cost_ / static_cast<double>(std::max<Eigen::Index>(system_.r().size(), 1)));
    record.max_distance = system_.r().size() > 0 ? system_.r().cwiseAbs().maxCoeff() : 0.0;
  }

  // The objective criterion also asks the linear model's predicted decrease to be below the tolerance, so a
  // step that happened to gain little while much more is predicted does not end the run.
  std::optional<StopReason> AfterIteration(const IterationSummary& summary,
                                           std::optional<StopReason> proposed) override {
    if (proposed == StopReason::kObjectiveTolerance &&
        summary.predicted_decrease / (summary.cost_after + 1e-300) > options_.function_tolerance)
      return std::nullopt;
    return proposed;
  }

  const Eigen::VectorXd& x() const { return x_; }
  int evaluations() const { return evaluations_; }

 private:
  void UpdateScale() {
    const Eigen::VectorXd diagonal = system_.J().colwise().squaredNorm().transpose();
    if (scaling_ == DampingScaling::kMarquardt) {
      system_.D() = diagonal.cwiseMax(marquardt_floor_).cwiseSqrt();
    } else {
      system_.D() =
          Eigen::VectorXd::Constant(diagonal.size(), std::sqrt(std::max(diagonal.maxCoeff(), 1e-300)));
    }
  }

  const LeastSquaresProblem& problem_;
  DampingScaling scaling_;
  LeastSquaresOptions options_;
  DenseJacobianSystem system_;
  Eigen::VectorXd x_, trial_x_, trial_r_, marquardt_floor_;
  Eigen::MatrixXd trial_j_;
  double cost_ = 0.0;
  int evaluations_ = 0;
};

LeastSquaresResult RunLevenbergMarquardt(const LeastSquaresProblem& problem, const Eigen::VectorXd& x0,
                                         const LeastSquaresOptions& options, DampingScaling scaling) {
  DenseLeastSquaresProblem fit(problem, x0, scaling, options);
  OptimizerOptions minimizer;
  minimizer.max_iterations = options.max_iterations;
  minimizer.objective_tolerance = options.function_tolerance;
  minimizer.step_tolerance = options.step_tolerance;
  minimizer.gradient_tolerance = options.gradient_tolerance;
  minimizer.damping.update = DampingUpdate::kNielsen;
  // mu is dimensionless: the damping term mu |D dx|^2 carries the scale through D.
  minimizer.damping.initial = scaling == DampingScaling::kMarquardt ? 1e-4 : options.initial_damping;
  minimizer.damping.min = 0.0;
  minimizer.damping.max = 1e300;
  const MinimizerSummary summary = TrustRegionMinimizer(minimizer).Minimize(fit);
  LeastSquaresResult result;
  result.x = fit.x();
  result.cost = fit.Cost();
  result.iterations = summary.iterations;
  result.evaluations = fit.evaluations();
  result.stop_reason = summary.stop_reason;
  result.scaling_used = scaling;
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
