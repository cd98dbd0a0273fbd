#pragma once
// The one set of termination and damping settings of every fit's minimizer (fitting/minimizer.h;
// docs/method.md section 14). Each fit embeds an OptimizerOptions; the defaults below are the documented
// defaults, and a fit states in its own header where and why it starts from other values.

#include <string>

#include "fitting/robust_loss.h"

namespace s2m {

// How the Levenberg-Marquardt damping lambda evolves (trust_region_strategy.h).
enum class DampingUpdate {
  // Marquardt's: x increase on a rejected step, x decrease on an accepted one, kept in [min, max].
  kMultiplicative,
  // Nielsen's from the gain ratio rho = actual / predicted decrease (Madsen, Nielsen, Tingleff 2004,
  // eq. 3.16):
  // lambda x max(1/3, 1 - (2 rho - 1)^3) on acceptance, x nu (nu doubling) on rejection.
  kNielsen,
};
const char* ToString(DampingUpdate update);

// The damped system (H + lambda D^2) dx = -g: D^2 = max(|diag H|, diagonal_floor x max |diag H|) for the
// normal-equation solvers (linear_solver.h); the QR solver of the dense least-squares core has its own
// scaling choice (least_squares.h).
struct DampingOptions {
  DampingUpdate update = DampingUpdate::kMultiplicative;
  double initial = 1e-4;
  double increase = 10.0;  // kMultiplicative only
  double decrease = 0.1;   // kMultiplicative only
  double min = 1e-12;      // lambda never falls below this after an accepted step
  double max = 1e16;       // beyond this no step decreases the objective: the fit stops (kNoFurtherDecrease)
  // Relative to the largest |diag H| of the block being damped: keeps damping effective along (near-)null
  // directions where the diagonal alone vanishes.
  double diagonal_floor = 1e-6;
  bool IsValid(std::string* why) const;
};

// How a step is taken once the linear system is solved.
enum class StepStrategy {
  kTrustRegion,  // Levenberg-Marquardt: re-solve with more damping until the true objective decreases
                 // (default)
  kFullStep,     // the undamped step, accepted whatever the objective does (plain TDM/PDM/ICP as usually run)
  kArmijo,       // the undamped step, halved until Armijo's sufficient decrease holds (at most 40 halvings)
};
const char* ToString(StepStrategy strategy);

struct OptimizerOptions {
  StepStrategy step_strategy = StepStrategy::kTrustRegion;
  int max_iterations = 100;  // accepted iterations
  // Stop when an accepted step decreases the objective by less than this, relative to the objective.
  double objective_tolerance = 1e-10;
  // Stop when the step is below this relative to the parameters, |dx| <= tol (1 + |x|), in the fit's working
  // (normalized) units; a fit may measure its step its own way (rotation and translation of a rigid motion).
  double step_tolerance = 1e-12;
  // Stop when the scale-free first-order optimality measure (the largest cosine between the residual vector
  // and a Jacobian column, linear_solver.h) is below this. 0: never checked.
  double gradient_tolerance = 1e-13;
  double target_rms = 0.0;  // stop as soon as the RMS (input units) is at most this (0: off)
  double armijo_c = 1e-4;   // sufficient-decrease constant of kArmijo
  DampingOptions damping;
  RobustLoss loss;  // the per-point loss (robust_loss.h); none by default
  bool IsValid(std::string* why) const;
};

}  // namespace s2m
