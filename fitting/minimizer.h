#pragma once
// The one minimizer of every fit (docs/method.md section 14). A fit is a NonlinearProblem: it linearizes at
// its current state (foot points frozen, one error matrix per point, robust weights), evaluates the TRUE
// objective at a trial state (new foot points) and accepts it. The minimizer owns the iteration: the step
// strategy (Levenberg-Marquardt trust region, full step, Armijo backtracking), the damping
// (trust_region_strategy.h), termination and the iteration history. Geometric fits, primitive fits,
// registration to a model, joint fits and the dense least-squares core are short drivers over it.
//
// Design after Ceres Solver (TrustRegionMinimizer with TrustRegionStrategy and LinearSolver strategies) and
// small_gicp (per-point factors, a parallel reduction, the optimizer kept apart).

#include <Eigen/Core>
#include <chrono>
#include <optional>
#include <vector>

#include "fitting/fit_result.h"
#include "fitting/linear_solver.h"
#include "fitting/optimizer_options.h"
#include "fitting/trust_region_strategy.h"

namespace s2m {

// What the minimizer knows of one accepted iteration, handed to the problem's AfterIteration.
struct IterationSummary {
  IterationRecord record;
  double cost_before = 0.0;
  double cost_after = 0.0;
  double predicted_decrease = 0.0;  // of the linear model, for the accepted step
  double relative_decrease = 0.0;   // (cost_before - cost_after) / cost_before
  bool step_negligible = false;
};

class NonlinearProblem {
 public:
  virtual ~NonlinearProblem() = default;
  // The objective at the current state, as the last Linearize (or AcceptTrial) left it. A robust fit
  // re-estimates its loss scale in Linearize, which re-weighs the current objective: the minimizer reads the
  // cost after linearizing and compares a trial only with a cost of the same scale.
  virtual double Cost() const = 0;
  // The linear system at the current state. May reuse what the evaluation that found the current state
  // prepared (a fused foot-point pass).
  virtual LinearSystem& Linearize() = 0;
  // Evaluates the trial state current (+) step and returns its cost (+inf when the step leaves the model's
  // domain or the cost is not finite). `final_if_accepted`: the minimizer stops after this trial if it is
  // accepted, so the next linearization need not be prepared.
  virtual double EvaluateTrial(const Eigen::VectorXd& step, bool final_if_accepted) = 0;
  virtual void AcceptTrial() = 0;
  // Whether a step is below the tolerance: by default |dx| <= tolerance (1 + |x|) with x = ParameterNorm().
  virtual bool StepIsNegligible(const Eigen::VectorXd& step, double tolerance) const;
  virtual double ParameterNorm() const { return 0.0; }
  // Fills the fit's own fields of an iteration record: rms and max_distance of the current state, input
  // units.
  virtual void DescribeState(IterationRecord& record) const = 0;
  // After an accepted iteration, with the minimizer's own decision (nullopt: go on). A fit may change it (a
  // stage change of the joint fit, a criterion of its own). Default: the minimizer's decision.
  virtual std::optional<StopReason> AfterIteration(const IterationSummary& summary,
                                                   std::optional<StopReason> proposed);
  // No step within the damping bounds decreases the objective. True: the problem changed (another stage) and
  // minimization goes on; false: it stops with kNoFurtherDecrease.
  virtual bool OnNoDecrease() { return false; }
};

struct MinimizerSummary {
  int iterations = 0;
  StopReason stop_reason = StopReason::kMaxIterations;
  std::vector<IterationRecord> history;
  double final_damping = 0.0;
};

// Whether the problem's current state already meets options.target_rms (off when it is 0): then no iteration
// is needed.
bool TargetReachedAtStart(const NonlinearProblem& problem, const OptimizerOptions& options);

class TrustRegionMinimizer {
 public:
  // Throws std::invalid_argument when the options are not valid (OptimizerOptions::IsValid's reason).
  explicit TrustRegionMinimizer(const OptimizerOptions& options);

  // Iterates until a stop criterion holds. Iterations are numbered from `first_iteration` + 1 and records'
  // seconds count from `start` (a fit of several stages keeps one history).
  MinimizerSummary Minimize(NonlinearProblem& problem, int first_iteration = 0,
                            std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now());

  // One iteration: linearize, then steps until one is accepted. Returns the summary of the accepted step, or
  // the stop reason when none is (gradient below tolerance, negligible step, no further decrease). The
  // damping carries over between calls (the alternating baseline keeps one minimizer per half-step).
  struct Outcome {
    bool accepted = false;
    StopReason stop_reason = StopReason::kMaxIterations;  // when not accepted
    IterationSummary summary;                             // when accepted
  };
  Outcome Iterate(NonlinearProblem& problem, bool final_if_accepted);

  const OptimizerOptions& options() const { return options_; }
  double damping() const { return strategy_.damping(); }
  void ResetDamping() { strategy_.Reset(); }

 private:
  OptimizerOptions options_;
  LevenbergMarquardtStrategy strategy_;
};

}  // namespace s2m
