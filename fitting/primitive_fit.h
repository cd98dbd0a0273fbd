#pragma once
// Orthogonal-distance least-squares fits of primitives (plane, sphere, cylinder, cone, line, circle, torus).
//
// Foot points are closed form; each iteration builds the TDM or SDM normal equations of docs/method.md
// section 2 at the frozen foot points and the one minimizer of every fit (minimizer.h: Levenberg-Marquardt,
// section 9) takes the step. Cylinders and cones are linearized in a local frame whose z axis is the current
// axis (Forbes, "Least squares best fit geometric elements", NPL DITC 140/89), which keeps the normal matrix
// well conditioned; data are centred and scaled into the unit box first (section 3).
//
// Robust fits (optimizer.loss): each point's rows are weighted by the IRLS weight rho'(d^2) at every
// linearization and the objective is 1/2 sum rho(d^2) (robust_loss.h; Triggs et al. 2000, section 4.3).
// The algebraic initial guesses are least squares, which gross outliers ruin; so a robust Fit* refines
// robustly from the usual starts and also from a start found on a trimmed set (the least-squares fit of the
// half of the points nearest the plain least-squares fit, then three concentration steps of least trimmed
// squares: refit the half nearest the last fit), and keeps the lower robust objective (both
// evaluated with the smaller of their two loss scales, so that neither wins by a wider scale alone).

#include <Eigen/Core>
#include <stdexcept>
#include <string>
#include <vector>

#include "fitting/fit_result.h"
#include "fitting/geometric_fit.h"
#include "fitting/optimizer_options.h"
#include "fitting/primitives.h"

namespace s2m {

struct PrimitiveFitOptions {
  // TDM (Gauss-Newton on the distances, the algorithm behind the NIST reference fits) is the default for
  // primitives: near the solution the residuals straddle the surface, SDM clamps the inner half of its
  // curvature terms to zero and so converges linearly, while TDM's omitted terms cancel (measured on the NIST
  // sets: docs/primitives.md). Primitives accept ErrorTerm::kTdm and ErrorTerm::kSdm only (others throw
  // std::invalid_argument).
  ErrorTerm error_term = ErrorTerm::kTdm;
  // Termination, damping and the robust loss. The primitives' defaults differ from the minimizer's: the
  // closed-form foot points are exact, so the fits are run to rounding level (the NIST certification asks
  // for agreement to about 1e-12 of the extent): at most 200 iterations, step 1e-14 relative to the
  // parameters, first-order optimality 1e-14 (the largest cosine between the residual vector and a Jacobian
  // column), relative objective decrease 1e-20; Marquardt's damping starts at 1e-6 relative to diag(H)
  // (x10 on a rejected step, x0.1 on an accepted one, within [1e-15, 1e16]), with the diagonal floored at
  // 1e-12 of its largest entry. Tolerances are in the normalized units of the unit box.
  OptimizerOptions optimizer = DefaultOptimizer();
  // Keep the per-iteration records (PrimitiveFit::history).
  bool record_history = true;
  // Initial guess for cylinders and cones: axis directions tried on a Fibonacci hemisphere (plus the
  // principal axes of the data), scored by an algebraic fit; the best `refined_candidates` are refined and
  // the lowest objective wins. Only up to `max_initialization_points` evenly spaced points are used for the
  // search.
  int direction_samples = 400;
  int refined_candidates = 4;
  int max_initialization_points = 2000;

  static OptimizerOptions DefaultOptimizer() {
    OptimizerOptions o;
    o.max_iterations = 200;
    o.step_tolerance = 1e-14;
    o.gradient_tolerance = 1e-14;
    o.objective_tolerance = 1e-20;
    o.damping.update = DampingUpdate::kMultiplicative;
    o.damping.initial = 1e-6;
    o.damping.increase = 10.0;
    o.damping.decrease = 0.1;
    o.damping.min = 1e-15;
    o.damping.max = 1e16;
    o.damping.diagonal_floor = 1e-12;
    return o;
  }
};

// A type-A standard uncertainty (GUM) from the Gauss-Newton covariance s^2 (J^T J)^-1 at the solution, with
// s^2 = sum d^2 / (n - p): valid for independent, equal-variance errors and an adequate model. Robust fits
// use the weighted normal matrix with the effective degrees of freedom: s_w^2 (J^T W J)^-1 with
// s_w^2 = sum w d^2 / (sum w - p) and W the final IRLS weights rho'(d^2). Lengths are in
// input units, angles in radians. Axis positions are perpendicular to the axis, at the reported axis point.
struct ParameterUncertainty {
  std::string name;
  double standard_uncertainty = 0.0;
  bool is_angle = false;
};

template <class Shape>
struct PrimitiveFit {
  Shape shape;
  ResidualStatistics residuals;                     // input units
  std::vector<ParameterUncertainty> uncertainties;  // empty when n <= number of parameters
  int iterations = 0;
  StopReason stop_reason = StopReason::kMaxIterations;
  std::vector<IterationRecord> history;  // empty unless options.record_history
  // Robust fits: the loss scale c at the solution (input units; estimated from the data by MAD unless given)
  // and the number of points whose final IRLS weight rho'(d^2) is below 0.5 ("rejected"). 0 and 0 for plain
  // least squares.
  double loss_scale = 0.0;
  Eigen::Index rejected = 0;
};

// The points of a fit, one per column: a Matrix3Xd, or a Map over a caller's buffer (e.g. a NumPy array of N
// rows x, y, z, C-contiguous, which has exactly this layout) read in place without a copy.
using PointsRef = Eigen::Ref<const Eigen::Matrix3Xd>;

// Thrown for inputs no fit can use: too few points, non-finite coordinates, degenerate configurations.
class FitError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

PrimitiveFit<Plane> FitPlane(const PointsRef& points, const PrimitiveFitOptions& options = {});
PrimitiveFit<Sphere> FitSphere(const PointsRef& points, const PrimitiveFitOptions& options = {});
PrimitiveFit<Cylinder> FitCylinder(const PointsRef& points, const PrimitiveFitOptions& options = {});
PrimitiveFit<Cone> FitCone(const PointsRef& points, const PrimitiveFitOptions& options = {});

// The rest of the ISO 10360-6 set (docs/metrology.md section 1). A line's and a circle's residual is the
// 2-vector across the curve (its length the distance; PrimitiveFit::residuals then holds the non-negative
// distances). Line: closed form (centroid, principal direction); robust losses iterate. Circle: start from
// the least-squares plane and the algebraic circle of the points projected into it; at least 3 points, not
// collinear. Torus: starts from the axis of the points' normal lines and from the least-variance direction,
// each completed by the algebraic circle in the meridian plane; at least 7 points. Circle and torus take
// ErrorTerm::kTdm only (std::invalid_argument otherwise).
PrimitiveFit<Line3d> FitLine(const PointsRef& points, const PrimitiveFitOptions& options = {});
PrimitiveFit<Circle3d> FitCircle(const PointsRef& points, const PrimitiveFitOptions& options = {});
PrimitiveFit<Torus> FitTorus(const PointsRef& points, const PrimitiveFitOptions& options = {});

// Refinement from a caller's initial shape (no automatic initial guess).
PrimitiveFit<Sphere> RefineSphere(const PointsRef& points, const Sphere& initial,
                                  const PrimitiveFitOptions& options = {});
PrimitiveFit<Cylinder> RefineCylinder(const PointsRef& points, const Cylinder& initial,
                                      const PrimitiveFitOptions& options = {});
PrimitiveFit<Cone> RefineCone(const PointsRef& points, const Cone& initial,
                              const PrimitiveFitOptions& options = {});
PrimitiveFit<Circle3d> RefineCircle(const PointsRef& points, const Circle3d& initial,
                                    const PrimitiveFitOptions& options = {});
PrimitiveFit<Torus> RefineTorus(const PointsRef& points, const Torus& initial,
                                const PrimitiveFitOptions& options = {});

// Exposed for the Jacobian property tests: rows d(distance)/d(local parameters) at the zero increment, and
// the update that applies an increment. Local parameters: sphere (cx, cy, cz, r); cylinder (u1, u2, a1, b1,
// r); cone (u1, u2, a1, b1, psi, s); line (u1, u2, a1, b1); circle (c1, c2, c3, t1, t2, r); torus (u1, u2,
// w, a1, b1, R, r), all in the shape's local axis frame (docs/metrology.md eqs. 1-3). The line's and the
// circle's rows are those of the stacked 2-vector residuals (ResidualVector), two per point.
Eigen::MatrixXd DistanceJacobian(const Plane& s, const Eigen::Matrix3Xd& points);  // (w, t1, t2): PlaneLocal
Eigen::MatrixXd DistanceJacobian(const Sphere& s, const Eigen::Matrix3Xd& points);
Eigen::MatrixXd DistanceJacobian(const Cylinder& s, const Eigen::Matrix3Xd& points);
Eigen::MatrixXd DistanceJacobian(const Cone& s, const Eigen::Matrix3Xd& points);
Plane ApplyIncrement(const Plane& s, const Eigen::VectorXd& delta);
Sphere ApplyIncrement(const Sphere& s, const Eigen::VectorXd& delta);
Cylinder ApplyIncrement(const Cylinder& s, const Eigen::VectorXd& delta);
Cone ApplyIncrement(const Cone& s, const Eigen::VectorXd& delta);
Eigen::MatrixXd DistanceJacobian(const Line3d& s, const Eigen::Matrix3Xd& points);
Eigen::MatrixXd DistanceJacobian(const Circle3d& s, const Eigen::Matrix3Xd& points);
Eigen::MatrixXd DistanceJacobian(const Torus& s, const Eigen::Matrix3Xd& points);
Eigen::VectorXd ResidualVector(const Line3d& s, const Eigen::Matrix3Xd& points);
Eigen::VectorXd ResidualVector(const Circle3d& s, const Eigen::Matrix3Xd& points);
Line3d ApplyIncrement(const Line3d& s, const Eigen::VectorXd& delta);
Circle3d ApplyIncrement(const Circle3d& s, const Eigen::VectorXd& delta);
Torus ApplyIncrement(const Torus& s, const Eigen::VectorXd& delta);

}  // namespace s2m
