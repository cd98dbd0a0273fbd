#pragma once
// Chebyshev (minimum-zone) fits and form errors (ISO 1101; ISO 12780 straightness, ISO 12781 flatness,
// ISO 12181 roundness, ISO 12180 cylindricity), and the maximum-inscribed and minimum-circumscribed circle,
// cylinder and sphere (ISO 4291 / ISO 12181 reference features). docs/metrology.md sections 2-3.
//
// Each is a minimax problem over the shape's parameters: with d_i(p) the distances of the points,
//   minimum zone      min_p  max_i d_i - min_i d_i     (two parallel planes, concentric spheres, coaxial
//                                                      cylinders, ... enclosing every point)
//   circumscribed     min_p  max_i d_i                 (the size parameter then closes the feature on the
//   inscribed         max_p  min_i d_i                  outermost / innermost point)
//   straightness      min_p  max_i dist_i              (the thinnest cylinder about a line)
// solved by sequential linear programming (Carr & Ferreira, "Verification of form tolerances", Precision
// Engineering 17, 1995; Anthony et al., "Reference software for finding Chebyshev best-fit geometric
// elements", Precision Engineering 19, 1996): at the current shape d_i is linearized with the rows of the
// least-squares fits (primitive_local_models.h), the linear program over the step (bounded by a trust
// region) is solved (linear_program.h), and the step is taken when it lowers the exact criterion, else the
// region shrinks. At a first-order solution the linear program predicts no decrease for any step: that is
// the convergence test. The start is normally the least-squares fit; the problems are not convex in the
// orientation, so the result is the local solution nearest it (for the near-form data of metrology the
// global one; the tests compare with exhaustive solutions).
//
// The contacting points (those that define the zone) are the rows the final linear program holds active
// with a positive multiplier: p + 1 of them for p free parameters, generically.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "fitting/linear_program.h"
#include "fitting/primitives.h"

namespace s2m {

enum class FitCriterion { kLeastSquares, kMinimumZone, kInscribed, kCircumscribed };
// "lsq", "minzone", "inscribed", "circumscribed".
const char* ToString(FitCriterion criterion);
// Throws std::invalid_argument naming the accepted spellings.
FitCriterion FitCriterionFromString(const std::string& text);

struct ChebyshevFitOptions {
  // Linearizations at most.
  int max_iterations = 200;
  // Converged when the linear program predicts a decrease of the criterion below this (normalized units:
  // the data centred and scaled into the unit box, as the least-squares fits).
  double tolerance = 1e-13;
  LinearProgramOptions linear_program;

  bool IsValid(std::string* why = nullptr) const;
};

// A point on a boundary of the zone: `side` +1 on the outer one (the largest distance), -1 on the inner.
struct ZoneContact {
  Eigen::Index index = 0;
  int side = 1;
  double distance = 0.0;  // input units
};

template <class Shape>
struct ChebyshevFit {
  // The reference feature: the zone's median surface (minimum zone), the inscribed or circumscribed feature,
  // or the shape given (least squares).
  Shape shape;
  FitCriterion criterion = FitCriterion::kMinimumZone;
  // Distances of the points from `shape` (input units): signed for surfaces and roundness (outside
  // positive); non-negative for lines. `zone_width` is the form deviation relative to `shape`:
  // max - min for surfaces and roundness (peak-to-valley), 2 max for a line (the cylinder's diameter).
  double max_distance = 0.0;
  double min_distance = 0.0;
  double zone_width = 0.0;
  std::vector<ZoneContact> contacts;
  int iterations = 0;
  bool converged = false;
  // The final linear program's predicted decrease of the criterion (input units): 0 at a first-order
  // solution, up to the tolerance.
  double optimality = 0.0;
  std::string stop_reason;
};

// Minimum-zone fits from a start (normally the least-squares fit). Plane: flatness; sphere: sphericity;
// cylinder: cylindricity; cone: conicity; torus: the torus's form deviation (no ISO name); line:
// straightness (the thinnest cylinder enclosing the points; the shape is its axis); circle: roundness in
// the start's plane (the points projected onto it; the plane is kept). Throw FitError for too few points,
// non-finite points, degenerate data (e.g. collinear points for a circle), or a linear program that fails.
ChebyshevFit<Plane> MinimumZoneFit(const Eigen::Matrix3Xd& points, const Plane& start,
                                   const ChebyshevFitOptions& options = {});
ChebyshevFit<Sphere> MinimumZoneFit(const Eigen::Matrix3Xd& points, const Sphere& start,
                                    const ChebyshevFitOptions& options = {});
ChebyshevFit<Cylinder> MinimumZoneFit(const Eigen::Matrix3Xd& points, const Cylinder& start,
                                      const ChebyshevFitOptions& options = {});
ChebyshevFit<Cone> MinimumZoneFit(const Eigen::Matrix3Xd& points, const Cone& start,
                                  const ChebyshevFitOptions& options = {});
ChebyshevFit<Torus> MinimumZoneFit(const Eigen::Matrix3Xd& points, const Torus& start,
                                   const ChebyshevFitOptions& options = {});
ChebyshevFit<Line3d> MinimumZoneFit(const Eigen::Matrix3Xd& points, const Line3d& start,
                                    const ChebyshevFitOptions& options = {});
ChebyshevFit<Circle3d> MinimumZoneFit(const Eigen::Matrix3Xd& points, const Circle3d& start,
                                      const ChebyshevFitOptions& options = {});

// The maximum-inscribed (every point outside, largest size) and minimum-circumscribed (every point inside,
// smallest size) circle (in the start's plane), cylinder and sphere. An inscribed feature is bounded only
// when the points surround it: otherwise (a partial arc) FitError says so.
ChebyshevFit<Circle3d> InscribedFit(const Eigen::Matrix3Xd& points, const Circle3d& start,
                                    const ChebyshevFitOptions& options = {});
ChebyshevFit<Cylinder> InscribedFit(const Eigen::Matrix3Xd& points, const Cylinder& start,
                                    const ChebyshevFitOptions& options = {});
ChebyshevFit<Sphere> InscribedFit(const Eigen::Matrix3Xd& points, const Sphere& start,
                                  const ChebyshevFitOptions& options = {});
ChebyshevFit<Circle3d> CircumscribedFit(const Eigen::Matrix3Xd& points, const Circle3d& start,
                                        const ChebyshevFitOptions& options = {});
ChebyshevFit<Cylinder> CircumscribedFit(const Eigen::Matrix3Xd& points, const Cylinder& start,
                                        const ChebyshevFitOptions& options = {});
ChebyshevFit<Sphere> CircumscribedFit(const Eigen::Matrix3Xd& points, const Sphere& start,
                                      const ChebyshevFitOptions& options = {});

// The zone about a given shape, without optimizing (criterion kLeastSquares for a least-squares fit): the
// distances' extremes, the width as above and the two extreme points as contacts. Circles: in-plane radial
// distances (roundness).
ChebyshevFit<Plane> ZoneAbout(const Eigen::Matrix3Xd& points, const Plane& shape);
ChebyshevFit<Sphere> ZoneAbout(const Eigen::Matrix3Xd& points, const Sphere& shape);
ChebyshevFit<Cylinder> ZoneAbout(const Eigen::Matrix3Xd& points, const Cylinder& shape);
ChebyshevFit<Cone> ZoneAbout(const Eigen::Matrix3Xd& points, const Cone& shape);
ChebyshevFit<Torus> ZoneAbout(const Eigen::Matrix3Xd& points, const Torus& shape);
ChebyshevFit<Line3d> ZoneAbout(const Eigen::Matrix3Xd& points, const Line3d& shape);
ChebyshevFit<Circle3d> ZoneAbout(const Eigen::Matrix3Xd& points, const Circle3d& shape);

}  // namespace s2m
