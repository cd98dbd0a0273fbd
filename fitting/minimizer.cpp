#include "fitting/minimizer.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace s2m {

bool NonlinearProblem::StepIsNegligible(const Eigen::VectorXd& step, double tolerance) const {
  return step.norm() <= tolerance * (1.0 + ParameterNorm());  // docs/method.md eq. 42
}

std::optional<StopReason> NonlinearProblem::AfterIteration(const IterationSummary& /*summary*/,
                                                           std::optional<StopReason> proposed) {
  return proposed;
}

namespace {

const OptimizerOptions& Validated(const OptimizerOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument("invalid optimizer options: " + why);
  return options;
}

}  // namespace

TrustRegionMinimizer::TrustRegionMinimizer(const OptimizerOptions& options)
    : options_(Validated(options)), strategy_(options.damping) {}

TrustRegionMinimizer::Outcome TrustRegionMinimizer::Iterate(NonlinearProblem& problem,
                                                            bool final_if_accepted) {
  Outcome out;
  LinearSystem& system = problem.Linearize();
  const double cost = problem.Cost();
  if (options_.gradient_tolerance > 0.0 &&
      (cost == 0.0 || system.GradientMeasure(cost) <= options_.gradient_tolerance)) {
    out.stop_reason = StopReason::kGradientTolerance;
    return out;
  }
  Eigen::VectorXd step;
  const auto accept = [&](const Eigen::VectorXd& taken, double trial_cost, double lambda, bool negligible) {
    problem.AcceptTrial();
    out.accepted = true;
    IterationSummary& s = out.summary;
    s.cost_before = cost;
    s.cost_after = trial_cost;
    s.predicted_decrease = -system.ModelChange(taken);
    s.relative_decrease = cost > 0.0 ? (cost - trial_cost) / cost : 0.0;
    s.step_negligible = negligible;
    s.record.objective = trial_cost;
    s.record.damping = lambda;
    s.record.step_norm = taken.norm();
    problem.DescribeState(s.record);
    return out;
  };
  switch (options_.step_strategy) {
    case StepStrategy::kTrustRegion:
      while (true) {
        const double lambda = strategy_.damping();
        const bool solved = system.Solve(lambda, step);
        const bool negligible = solved && problem.StepIsNegligible(step, options_.step_tolerance);
        if (solved) {
          const double trial = problem.EvaluateTrial(step, final_if_accepted || negligible);
          if (trial < cost) {  // the TRUE objective at new foot points decreased
            const double predicted = -system.ModelChange(step);
            strategy_.StepAccepted(predicted > 0.0 ? (cost - trial) / predicted : 0.0);
            return accept(step, trial, lambda, negligible);
          }
        }
        // An (almost) undamped step too small to change the objective: converged at rounding level.
        if (negligible && lambda < 1.0) {
          out.stop_reason = StopReason::kStepTolerance;
          return out;
        }
        strategy_.StepRejected();
        if (strategy_.Exhausted()) {
          out.stop_reason = StopReason::kNoFurtherDecrease;
          return out;
        }
      }
    case StepStrategy::kFullStep: {
      if (!system.Solve(0.0, step)) {
        out.stop_reason = StopReason::kNoFurtherDecrease;
        return out;
      }
      const bool negligible = problem.StepIsNegligible(step, options_.step_tolerance);
      const double trial = problem.EvaluateTrial(step, final_if_accepted || negligible);
      if (!std::isfinite(trial)) {
        out.stop_reason = StopReason::kNoFurtherDecrease;
        return out;
      }
      return accept(step, trial, 0.0, negligible);
    }
    case StepStrategy::kArmijo: {
      if (!system.Solve(0.0, step)) {
        out.stop_reason = StopReason::kNoFurtherDecrease;
        return out;
      }
      const double slope = system.Slope(step);
      double alpha = 1.0;
      for (int halving = 0; halving < 40; ++halving, alpha *= 0.5) {
        const Eigen::VectorXd taken = alpha * step;
        if (problem.StepIsNegligible(taken, options_.step_tolerance)) {
          out.stop_reason = StopReason::kStepTolerance;
          return out;
        }
        const double trial = problem.EvaluateTrial(taken, final_if_accepted);
        // Armijo's sufficient decrease along the step (docs/method.md eq. 28).
        if (trial <= cost + options_.armijo_c * alpha * slope) return accept(taken, trial, 0.0, false);
      }
      out.stop_reason = StopReason::kNoFurtherDecrease;
      return out;
    }
  }
  out.stop_reason = StopReason::kNoFurtherDecrease;
  return out;
}

bool TargetReachedAtStart(const NonlinearProblem& problem, const OptimizerOptions& options) {
  if (!(options.target_rms > 0.0)) return false;
  IterationRecord initial;
  problem.DescribeState(initial);
  return initial.rms <= options.target_rms;
}

MinimizerSummary TrustRegionMinimizer::Minimize(NonlinearProblem& problem, int first_iteration,
                                                std::chrono::steady_clock::time_point start) {
  MinimizerSummary summary;
  if (TargetReachedAtStart(problem, options_)) {
    summary.stop_reason = StopReason::kTargetReached;
    summary.final_damping = strategy_.damping();
    return summary;
  }
  while (true) {
    if (summary.iterations >= options_.max_iterations) {
      summary.stop_reason = StopReason::kMaxIterations;
      break;
    }
    Outcome outcome = Iterate(problem, summary.iterations + 1 >= options_.max_iterations);
    if (!outcome.accepted) {
      if (outcome.stop_reason == StopReason::kNoFurtherDecrease && problem.OnNoDecrease()) continue;
      summary.stop_reason = outcome.stop_reason;
      break;
    }
    ++summary.iterations;
    IterationRecord& record = outcome.summary.record;
    record.iteration = first_iteration + summary.iterations;
    record.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    summary.history.push_back(record);
    std::optional<StopReason> proposed;
    if (options_.target_rms > 0.0 && record.rms <= options_.target_rms) {
      proposed = StopReason::kTargetReached;
    } else if (outcome.summary.step_negligible) {
      proposed = StopReason::kStepTolerance;
    } else if (std::abs(outcome.summary.relative_decrease) <= options_.objective_tolerance) {
      proposed = StopReason::kObjectiveTolerance;
    }
    if (const std::optional<StopReason> decision = problem.AfterIteration(outcome.summary, proposed)) {
      summary.stop_reason = *decision;
      break;
    }
  }
  summary.final_damping = strategy_.damping();
  return summary;
}

}  // namespace s2m
