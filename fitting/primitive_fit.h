#pragma once
// Orthogonal-distance least-squares fits of primitives (plane, sphere, cylinder, cone).
//
// Foot points are closed form; each iteration builds the TDM or SDM normal equations of METHOD.md section 2
// at the frozen foot points and takes a Levenberg-Marquardt step (section 9). Cylinders and cones are
// linearized in a local frame whose z axis is the current axis (Forbes, "Least squares best fit geometric
// elements", NPL DITC 140/89), which keeps the normal matrix well conditioned; data are centred and scaled
// into the unit box first (section 3).

#include <Eigen/Core>
#include <stdexcept>
#include <string>
#include <vector>

#include "fitting/fit_result.h"
#include "fitting/primitives.h"

namespace s2m {

enum class PrimitiveMethod {
  kTdm,  // tangent-distance minimization: Gauss-Newton on the orthogonal distances
  kSdm,  // squared-distance minimization: TDM plus curvature-weighted tangential terms
};
const char* ToString(PrimitiveMethod method);

struct PrimitiveFitOptions {
  // TDM (Gauss-Newton on the distances, the algorithm behind the NIST reference fits) is the default for
  // primitives: near the solution the residuals straddle the surface, SDM clamps the inner half of its
  // curvature terms to zero and so converges linearly, while TDM's omitted terms cancel (measured on the NIST
  // sets: docs/primitives.md).
  PrimitiveMethod method = PrimitiveMethod::kTdm;
  SolverOptions solver;
  // Initial guess for cylinders and cones: axis directions tried on a Fibonacci hemisphere (plus the
  // principal axes of the data), scored by an algebraic fit; the best `refined_candidates` are refined and
  // the lowest objective wins. Only up to `max_initialization_points` evenly spaced points are used for the
  // search.
  int direction_samples = 400;
  int refined_candidates = 4;
  int max_initialization_points = 2000;
};

// A type-A standard uncertainty (GUM) from the Gauss-Newton covariance s^2 (J^T J)^-1 at the solution, with
// s^2 = sum d^2 / (n - p): valid for independent, equal-variance errors and an adequate model. Lengths are in
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
  std::vector<IterationRecord> history;
};

// Thrown for inputs no fit can use: too few points, non-finite coordinates, degenerate configurations.
class FitError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

PrimitiveFit<Plane> FitPlane(const Eigen::Matrix3Xd& points, const PrimitiveFitOptions& options = {});
PrimitiveFit<Sphere> FitSphere(const Eigen::Matrix3Xd& points, const PrimitiveFitOptions& options = {});
PrimitiveFit<Cylinder> FitCylinder(const Eigen::Matrix3Xd& points, const PrimitiveFitOptions& options = {});
PrimitiveFit<Cone> FitCone(const Eigen::Matrix3Xd& points, const PrimitiveFitOptions& options = {});

// Refinement from a caller's initial shape (no automatic initial guess).
PrimitiveFit<Sphere> RefineSphere(const Eigen::Matrix3Xd& points, const Sphere& initial,
                                  const PrimitiveFitOptions& options = {});
PrimitiveFit<Cylinder> RefineCylinder(const Eigen::Matrix3Xd& points, const Cylinder& initial,
                                      const PrimitiveFitOptions& options = {});
PrimitiveFit<Cone> RefineCone(const Eigen::Matrix3Xd& points, const Cone& initial,
                              const PrimitiveFitOptions& options = {});

// Exposed for the Jacobian property tests: rows d(distance)/d(local parameters) at the zero increment, and
// the update that applies an increment. Local parameters: sphere (cx, cy, cz, r); cylinder (u1, u2, a1, b1,
// r); cone (u1, u2, a1, b1, psi, s), all in the shape's local axis frame.
Eigen::MatrixXd DistanceJacobian(const Sphere& s, const Eigen::Matrix3Xd& points);
Eigen::MatrixXd DistanceJacobian(const Cylinder& s, const Eigen::Matrix3Xd& points);
Eigen::MatrixXd DistanceJacobian(const Cone& s, const Eigen::Matrix3Xd& points);
Sphere ApplyIncrement(const Sphere& s, const Eigen::VectorXd& delta);
Cylinder ApplyIncrement(const Cylinder& s, const Eigen::VectorXd& delta);
Cone ApplyIncrement(const Cone& s, const Eigen::VectorXd& delta);

}  // namespace s2m
