// The one minimizer (fitting/minimizer.h): a small problem with a known minimum solved by every step
// strategy and damping update, the options' validation messages, and the stop reasons.
#include "fitting/minimizer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace s2m {
namespace {

// y_i = a exp(b x_i) at x_i = 0, 0.1, ..., 1.9 with (a, b) = (2, -1.5), plus `noise` (-1)^i: a least-squares
// problem r_i = a exp(b x_i) - y_i whose minimum is the truth when noise = 0.
class ExponentialProblem : public NonlinearProblem {
 public:
  explicit ExponentialProblem(double noise = 0.0, Eigen::Vector2d start = {1.0, 0.0}) : p_(start) {
    x_ = Eigen::VectorXd::LinSpaced(20, 0.0, 1.9);
    y_.resize(20);
    for (int i = 0; i < 20; ++i) y_[i] = 2.0 * std::exp(-1.5 * x_[i]) + (i % 2 ? -noise : noise);
    cost_ = CostAt(p_);
  }
  double Cost() const override { return cost_; }
  LinearSystem& Linearize() override {
    system_.Resize(2);
    for (int i = 0; i < 20; ++i) {
      const double e = std::exp(p_[1] * x_[i]);
      const Eigen::Vector2d j(e, p_[0] * x_[i] * e);
      const double r = p_[0] * e - y_[i];
      system_.H() += j * j.transpose();
      system_.g() += j * r;
    }
    return system_;
  }
  double EvaluateTrial(const Eigen::VectorXd& step, bool /*final_if_accepted*/) override {
    trial_ = p_ + step;
    ++evaluations;
    return CostAt(trial_);
  }
  void AcceptTrial() override {
    p_ = trial_;
    cost_ = CostAt(p_);
  }
  double ParameterNorm() const override { return p_.norm(); }
  void DescribeState(IterationRecord& record) const override { record.rms = std::sqrt(2.0 * cost_ / 20.0); }
  const Eigen::Vector2d& parameters() const { return p_; }
  int evaluations = 0;

 private:
  double CostAt(const Eigen::Vector2d& p) const {
    double f = 0.0;
    for (int i = 0; i < 20; ++i) f += 0.5 * std::pow(p[0] * std::exp(p[1] * x_[i]) - y_[i], 2);
    return f;
  }
  Eigen::VectorXd x_, y_;
  Eigen::Vector2d p_, trial_;
  DenseNormalEquations system_;
  double cost_ = 0.0;
};

TEST(Minimizer, EveryStepStrategyAndDampingUpdateFindsTheKnownMinimum) {
  struct Variant {
    const char* name;
    StepStrategy strategy;
    DampingUpdate update;
  };
  for (const Variant v :
       {Variant{"lm multiplicative", StepStrategy::kTrustRegion, DampingUpdate::kMultiplicative},
        Variant{"lm nielsen", StepStrategy::kTrustRegion, DampingUpdate::kNielsen},
        Variant{"full step", StepStrategy::kFullStep, DampingUpdate::kMultiplicative},
        Variant{"armijo", StepStrategy::kArmijo, DampingUpdate::kMultiplicative}}) {
    ExponentialProblem problem;
    OptimizerOptions o;
    o.step_strategy = v.strategy;
    o.damping.update = v.update;
    const MinimizerSummary s = TrustRegionMinimizer(o).Minimize(problem);
    EXPECT_NEAR(problem.parameters()[0], 2.0, 1e-9) << v.name;
    EXPECT_NEAR(problem.parameters()[1], -1.5, 1e-9) << v.name;
    EXPECT_NE(s.stop_reason, StopReason::kMaxIterations) << v.name;
    EXPECT_EQ(static_cast<int>(s.history.size()), s.iterations) << v.name;
    for (std::size_t i = 1; i < s.history.size() && v.strategy != StepStrategy::kFullStep; ++i)
      EXPECT_LT(s.history[i].objective, s.history[i - 1].objective) << v.name;
  }
}

// Minimizes `problem` with `o` except for the tolerances given (the others off): the summary.
MinimizerSummary MinimizeWithTolerances(ExponentialProblem& problem, OptimizerOptions o, double objective,
                                        double step, double gradient) {
  o.objective_tolerance = objective;
  o.step_tolerance = step;
  o.gradient_tolerance = gradient;
  return TrustRegionMinimizer(o).Minimize(problem);
}

TEST(Minimizer, NoisyDataEndAtTheLeastSquaresMinimumWhereTheGradientVanishes) {
  ExponentialProblem problem(0.01);
  const MinimizerSummary s = MinimizeWithTolerances(problem, {}, 0.0, 0.0, 1e-10);
  EXPECT_EQ(s.stop_reason, StopReason::kGradientTolerance);
  EXPECT_LE(problem.Linearize().GradientMeasure(problem.Cost()), 1e-10);
}

TEST(Minimizer, StopReasons) {
  {
    ExponentialProblem problem;
    OptimizerOptions o;
    o.max_iterations = 2;
    const MinimizerSummary s = TrustRegionMinimizer(o).Minimize(problem);
    EXPECT_EQ(s.stop_reason, StopReason::kMaxIterations);
    EXPECT_EQ(s.iterations, 2);
    EXPECT_EQ(s.history.back().iteration, 2);
  }
  {
    ExponentialProblem problem;
    OptimizerOptions o;
    o.target_rms = 1e-3;
    const MinimizerSummary s = TrustRegionMinimizer(o).Minimize(problem);
    EXPECT_EQ(s.stop_reason, StopReason::kTargetReached);
    EXPECT_LE(s.history.back().rms, 1e-3);
  }
  {
    // Already at the target: no iteration.
    ExponentialProblem problem(0.0, {2.0, -1.5});
    OptimizerOptions o;
    o.target_rms = 1e-3;
    const MinimizerSummary s = TrustRegionMinimizer(o).Minimize(problem);
    EXPECT_EQ(s.stop_reason, StopReason::kTargetReached);
    EXPECT_EQ(s.iterations, 0);
  }
  {
    ExponentialProblem problem(0.01);
    EXPECT_EQ(MinimizeWithTolerances(problem, {}, 1e-6, 0.0, 0.0).stop_reason,
              StopReason::kObjectiveTolerance);
  }
  {
    // A problem whose every trial leaves its domain: the damping grows past its maximum.
    class Nowhere : public ExponentialProblem {
     public:
      double EvaluateTrial(const Eigen::VectorXd&, bool) override {
        return std::numeric_limits<double>::infinity();
      }
    } problem;
    OptimizerOptions o;
    o.damping.max = 1e3;
    const MinimizerSummary s = TrustRegionMinimizer(o).Minimize(problem);
    EXPECT_EQ(s.stop_reason, StopReason::kNoFurtherDecrease);
    EXPECT_EQ(s.iterations, 0);
    EXPECT_GT(s.final_damping, 1e3);
  }
}

TEST(Minimizer, IsValidNamesTheOffendingSetting) {
  const auto why = [](const OptimizerOptions& o) {
    std::string reason;
    EXPECT_FALSE(o.IsValid(&reason));
    return reason;
  };
  std::string reason;
  EXPECT_TRUE(OptimizerOptions().IsValid(&reason));
  OptimizerOptions o;
  o.max_iterations = -1;
  EXPECT_EQ(why(o), "max_iterations must be >= 0");
  o = {};
  o.objective_tolerance = -1.0;
  EXPECT_EQ(why(o), "objective_tolerance must be finite and >= 0");
  o = {};
  o.armijo_c = 1.0;
  EXPECT_EQ(why(o), "armijo_c must be in (0, 1)");
  o = {};
  o.damping.min = 1.0;
  o.damping.max = 0.5;
  EXPECT_EQ(why(o), "damping.min must not exceed damping.max");
  o = {};
  o.damping.increase = 1.0;
  EXPECT_EQ(why(o), "damping.increase must be > 1");
  o = {};
  o.loss = ParseRobustLoss("tukey");
  o.loss.scale = -1.0;
  EXPECT_EQ(why(o), "the loss scale must be finite and >= 0 (0: from the data)");
  // The minimizer refuses invalid options with the reason.
  o = {};
  o.damping.decrease = 2.0;
  try {
    TrustRegionMinimizer minimizer(o);
    FAIL() << "invalid options accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), "invalid optimizer options: damping.decrease must be in (0, 1)");
  }
}

}  // namespace
}  // namespace s2m
