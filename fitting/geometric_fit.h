#pragma once
// The fitting engine: minimizes 1/2 sum_j d^2(X_j, C(P; .)) + F_s(P) over the shape parameters P of any
// ParametricModel by alternating exact foot points and one linear least-squares step on a local quadratic
// model built with one of the six error terms of docs/method.md section 2 (Wang, Pottmann, Liu, ACM TOG 25
// (2006); Liu & Wang, GMP 2008).

#include <Eigen/Core>
#include <functional>
#include <stdexcept>
#include <vector>

#include "fitting/fit_result.h"
#include "fitting/foot_point.h"
#include "fitting/optimizer_options.h"
#include "fitting/parametric_model.h"

namespace s2m {

enum class ErrorTerm {
  kPdm,   // point distance |e|^2: ICP-like, linear convergence
  kTdm,   // tangent distance (n.e)^2: Gauss-Newton-like, needs step control at high curvature
  kSdm,   // squared distance: curvature-weighted tangential terms plus the whole normal space (the default)
  kCdm,   // SDM with squared weights: Gauss-Newton without the mixed second derivative
  kGtdm,  // the whole normal space (N.e)^2: TDM generalized to curves in 3D
  kGn,  // Gauss-Newton with the full implicit-function Jacobian C_P - C_t G^-1 Q (reference, most expensive)
};
const char* ToString(ErrorTerm term);

// The 3x3 matrix M of the quadratic error term e^T M e of one data point in the principal frame `f` at its
// foot point (first s rows and columns used). For kGn, which builds its own Jacobian, the identity.
Eigen::Matrix3d ErrorMatrix(ErrorTerm term, const PrincipalFrame& f, int s);
// The error term of a data point whose foot point lies on an open boundary (the end rule of docs/method.md
// section 4), with offset = X - s: cos(theta) I + (1 - cos(theta)) M_term.
Eigen::Matrix3d EndRuleMatrix(ErrorTerm term, const PrincipalFrame& f, const Eigen::Vector3d& offset, int s);
ErrorTerm ErrorTermFromString(const std::string& name);  // "pdm", "tdm", ...; throws std::invalid_argument

struct GeometricFitOptions {
  ErrorTerm error_term = ErrorTerm::kSdm;
  // Fairness weights, applied to data normalized into the unit box (docs/method.md section 3): curves alpha
  // (stretch) and beta (bending); surfaces membrane and thin plate. Paper default for curves: bending 0.001.
  FairnessWeights fairness;
  bool normalize = true;      // scale data and model into the unit box while fitting
  bool open_end_rule = true;  // docs/method.md section 4 for points whose foot point lies on an open boundary
  // Termination, damping, step strategy (trust region by default; full step and Armijo backtracking are the
  // baselines) and the robust loss: the one minimizer's options (optimizer_options.h). Tolerances are in the
  // normalized units of the unit box, the target RMS in input units. The defaults are the minimizer's: at
  // most 100 iterations, relative decrease 1e-10, step 1e-12, first-order optimality 1e-13, damping from 1e-4
  // relative to diag(H).
  OptimizerOptions optimizer;
  // Called after every iteration (progress on long fits).
  std::function<void(const IterationRecord&)> on_iteration;
};

struct GeometricFitResult {
  ResidualStatistics residuals;  // at exact foot points, input units (all points, robust or not)
  int iterations = 0;
  StopReason stop_reason = StopReason::kMaxIterations;
  std::vector<IterationRecord> history;
  std::vector<FootPoint> foot_points;  // of the final model, distances in input units
  // Robust fits: the loss scale at the end (input units; estimated or given) and each point's final IRLS
  // weight rho'(d^2) (1 for plain least squares; Tukey's 0 marks a rejected point).
  double loss_scale = 0.0;
  Eigen::VectorXd weights;
};

// Thrown when the normal matrix of the chosen error term is singular (e.g. plain TDM for a curve in 3D fitted
// to planar data): the message names the unconstrained parameters instead of letting damping hide them.
class SingularSystemError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Fits `model` (updated in place) to the points (s x n, s = model.ambient_dimension()).
GeometricFitResult FitModel(ParametricModel& model, const Eigen::MatrixXd& points,
                            const GeometricFitOptions& options = {});

}  // namespace s2m
