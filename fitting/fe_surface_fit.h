#pragma once
// Fitting a fair finite-element surface (fitting/fe_surface.h) to scattered points (docs/fe-surfaces.md
// section 4, eqs. P5-P8): minimize the sum over the points of their squared distance to the surface plus the
// fairness energy Q^T K Q, the distances in the PDM, TDM or SDM approximation of docs/method.md (after Y.
// Liu) and the energy of Fang's plate (after L. Fang), by damped Gauss-Newton steps on all dofs at once, or
// by Fang's own sliding springs and SQP (section 4b), with the feet re-found on the surface after every step.

#include <Eigen/Core>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "fitting/fe_surface.h"
#include "fitting/geometric_fit.h"

namespace s2m {

// How the closeness is minimized. kGaussNewton: the engine's error terms (method) by damped Gauss-Newton
// steps (eq. P7). kFangSprings: Fang's sliding springs (thesis 5.1-5.2; docs/fe-surfaces.md section 4b):
// every point's spring force spread as a linear load over its foot's host triangle (eq. P15), the step from a
// quadratic model whose Hessian is the plate's stiffness (eq. P16), factored once for the whole fit.
enum class FeSolver { kGaussNewton, kFangSprings };

// The Hessian of Fang's quadratic model (eq. P16). kPlate: the plate's stiffness K alone, as in the thesis;
// it holds the surface only when the constraints do (boundary curves, eq. P12), and the iteration contracts
// only as fast as the plate resists the springs. kPlateOnSprings: K plus the springs' stiffness at the first
// feet (a plate on an elastic foundation), which holds any patch and contracts at Gauss-Newton's rate.
enum class FeSpringHessian { kPlate, kPlateOnSprings };

struct FeSurfaceFitOptions {
  ErrorTerm method = ErrorTerm::kSdm;  // pdm, tdm, sdm or cdm (fitting/geometric_fit.h); kGaussNewton only
  FeSolver solver = FeSolver::kGaussNewton;
  FeSpringHessian spring_hessian = FeSpringHessian::kPlateOnSprings;  // kFangSprings only
  // Relative (dimensionless) fairness weights of eq. P6: the energy enters as N * (weight * D^k / A) times
  // the integral, D the domain's diameter, A its area, k = 2 (stretch), 4 (bending), 3 (jump along edges), so
  // a weight means the same at any size and point count.
  double stretch = 0.0;
  double bending = 1e-7;
  double jump = 0.0;
  int max_iterations = 50;
  double tolerance = 1e-10;  // stop when the objective falls by less than this fraction
  bool IsValid(std::string* why = nullptr) const;
};

struct FeSurfaceFitResult {
  bool converged = false;
  int iterations = 0;
  std::vector<double> objective;  // per iteration, the first before any step
  double rms = 0.0;               // of the point-to-surface distances
  double max_distance = 0.0;
  FeSurfaceEnergy energy;   // with the absolute weights used
  FairnessWeights weights;  // the absolute weights (eq. P6)
  std::vector<FeSurfacePoint> feet;
  std::vector<double> distances;
  int boundary_feet = 0;  // points whose foot is on the domain's boundary
  // kFangSprings: the step length the line search took at every iteration (1 = Fang's full step).
  std::vector<double> step_lengths;
};

// The foot of x on the surface by Newton steps in (u, v) from `at`, walking across triangles (the surface is
// C1, so the steps see one smooth chart). Returns false when the foot is on the domain's boundary.
bool FeFootPoint(const FeSurface& surface, const Eigen::Vector3d& x, FeSurfacePoint& at);

// Fang's generalized spring forces (docs/fe-surfaces.md eq. P15): the force P_i - w(foot_i) of every point
// spread as a linear load over its foot's host triangle, integrated against the shape functions; entry
// 3 dof + c is coordinate c of the force on a dof. The load keeps each force's total and direction; its
// work on a linear field is that of the force applied at barycentric (1/4) (1, 1, 1) + Lbar / 4, not at the
// foot Lbar itself (eq. P15a).
Eigen::VectorXd FangSpringForces(const FeSurface& surface, const Eigen::Matrix3Xd& points,
                                 const std::vector<FeSurfacePoint>& feet);

// A linear constraint of the reduced transformation (docs/fe-surfaces.md eq. P9): the vector dof `dof` keeps
// its current component along `direction` (any non-zero vector; several per dof span the fixed subspace).
struct FeFixedDirection {
  int dof = 0;
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();
};

// A general linear constraint of the reduced transformation (eq. P9): sum of coefficient x unknown over its
// terms (unknown = 3 dof + coordinate) keeps its current value. Rows may couple several dofs (a boundary
// vertex's two slopes, eq. P12); set the dofs so that the rows hold their target values before fitting.
struct FeLinearConstraint {
  std::vector<std::pair<int, double>> terms;
};

// Fits surface's dofs to the points. start_uv holds each point's parameter to start from (for a patch
// projected onto a plane or a cylinder, its projection): the first step is the linear least-squares fit
// (PDM) with the points held at these parameters, from the surface's current dofs; later steps re-find the
// feet. Every dof keeps its components along its fixed directions: the steps are confined to the free
// subspace by the reduced transformation of eq. P9, as every row of `linear` keeps its value. Throws
// std::invalid_argument for mismatched sizes, non-finite input, a fixed direction of an out-of-range dof or a
// zero direction, a constraint row on an out-of-range unknown or with no non-zero coefficient, or invalid
// options.
FeSurfaceFitResult FitFeSurface(const Eigen::Matrix3Xd& points, const Eigen::Matrix2Xd& start_uv,
                                const FeSurfaceFitOptions& options, FeSurface& surface,
                                const std::vector<FeFixedDirection>& fixed = {},
                                const std::vector<FeLinearConstraint>& linear = {});

// A patch parametrized by its projection onto a plane (the points expressed in the plane's frame: x, y in the
// plane, z along its normal): sets the surface to the plane z = 0 with the identity chart w = (u, v, 0), and
// returns the constraints that pin the boundary's in-plane position and slopes to the domain polygon (x and
// y of every boundary vertex's value and slopes and of every boundary edge's normal slope, eq. P8), so that
// the fitted patch covers exactly the domain's projection and cannot shrink or slide along its plane.
std::vector<FeFixedDirection> SetPlanarChart(FeSurface& surface);

// A patch parametrized by its development onto a cylinder of radius R about the z axis (the points expressed
// in the cylinder's frame): u = R theta (arc length round the axis), v = z. Sets the surface to the cylinder,
// w = (R cos(u/R), R sin(u/R), v), and returns the constraints that let the boundary move only radially
// (eq. P8c): every boundary vertex keeps w's and w_v's components along the cylinder's tangents e_theta(u)
// and e_z, and w_u's and every boundary edge's w_n's component along e_z. A surface r(u, v) e_r(u) + v e_z
// with any radius function r meets them all, so they fix the development, not the shape. Throws
// std::invalid_argument for a radius that is not positive or a domain wider than the cylinder's
// circumference.
std::vector<FeFixedDirection> SetCylindricalChart(FeSurface& surface, double radius);

// Where the domain's boundary runs along given space curves (Fang's n-sided patches; docs/fe-surfaces.md eq.
// P12): for a point uv on the boundary and the unit direction of a boundary edge leaving it, the curves'
// point there and their derivative per unit length of the domain along that direction.
using FeBoundaryTrace = std::function<void(const Eigen::Vector2d& uv, const Eigen::Vector2d& direction,
                                           Eigen::Vector3d& point, Eigen::Vector3d& slope)>;

// Fang's boundary conformity (thesis 4.3.4.1; eq. P12): sets every boundary vertex's value to the curves'
// point and its slopes so that the slope along each boundary edge is the curves' (at a corner of the polygon
// both slopes follow; inside a straight side their combination along it), and returns the constraint rows
// that keep them. Along a boundary edge the surface is the cubic Hermite interpolant of its ends' values and
// slopes along the edge, so where the curves are cubic Hermite elements between the boundary vertices (the
// boundary vertices at the curves' nodes, or splitting their elements) the surface's boundary IS the curves.
// Throws std::invalid_argument when the curves do not meet at a vertex, or their slopes there disagree (at a
// corner; along a straight side, Fang's consistency condition h1 / l1 = h2 / l2 violated).
std::vector<FeLinearConstraint> SetBoundaryConformity(FeSurface& surface, const FeBoundaryTrace& trace);

// The fairest surface that keeps the constraint rows (docs/fe-surfaces.md eq. P14): the dofs minimizing the
// thin-plate energy with every row at its current value, e.g. the patch spanning its boundary curves after
// SetBoundaryConformity, where a fit starts. Throws std::invalid_argument when the rows do not make the
// minimum unique.
void FairFill(FeSurface& surface, const std::vector<FeLinearConstraint>& rows);

// The absolute weights of eq. P6 for a point count and a surface's domain.
FairnessWeights AbsoluteFairnessWeights(const FeSurfaceFitOptions& options, const FeSurface& surface,
                                        int point_count);

}  // namespace s2m
