#pragma once
// Second-order local geometry of a sampled surface: a quadric height field fitted over a point's k nearest
// neighbours in the frame of its tangent plane, its principal curvatures and directions (the
// eigen-decomposition of the shape operator), foot points on it, and the second-order approximant of the
// squared distance function that SDM minimizes (docs/method.md section 2; Pottmann & Hofer 2003; Pottmann,
// Leopoldseder & Hofer, "Registration without ICP", CVIU 95(1) 2004). Pure Eigen, no files.

#include <Eigen/Core>
#include <vector>

namespace s2m {

// The SDM weight of one tangential direction, delta*kappa / (delta*kappa - 1) clamped at 0 (docs/method.md
// section 2; Wang, Pottmann, Liu, ACM TOG 25 (2006), eq. 9), with kappa signed w.r.t. the unit normal n and
// delta = n.(X - s). It is the coefficient d/(d - rho_k) of the second-order approximant of the squared
// distance function in the principal frame at the foot point (Pottmann & Hofer, "Geometry of the squared
// distance function to curves and surfaces", Visualization and Mathematics III, 2003), written with kappa =
// 1/rho so that flat directions (kappa = 0) need no special case.
inline double SdmWeight(double delta, double kappa) {
  const double dk = delta * kappa;
  const double denom = dk - 1.0;
  if (denom > -1e-12 && denom < 1e-12) return 0.0;
  return dk / denom > 0.0 ? dk / denom : 0.0;
}

// A point of a surface with its first- and second-order geometry. kappa1 <= kappa2 are signed w.r.t.
// `normal`: positive when the surface bends towards the normal (docs/method.md section 2). direction1,
// direction2, normal are orthonormal.
struct SurfacePoint {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d direction1 = Eigen::Vector3d::UnitX(), direction2 = Eigen::Vector3d::UnitY();
  double kappa1 = 0.0, kappa2 = 0.0;

  // The same geometry seen from the other side: the normal reversed, the curvatures negated and the two
  // principal pairs swapped, so that kappa1 <= kappa2 still holds and the frame stays right-handed.
  SurfacePoint Flipped() const;
};

// The height field z = a x^2 + b x y + c y^2 + d x + e y + f over the tangent plane (x, y) of a point, z
// along the plane's normal: the local quadric of Cazals & Pouget, "Estimating differential quantities using
// polynomial fitting of osculating jets", CAGD 22(2) 2005 (degree-2 jet), and Goldfeather & Interrante, ACM
// TOG 23(1) 2004. The linear terms absorb the tilt of the plane estimated from the neighbours (PCA) against
// the surface's true tangent plane, and f the offset of a noisy centre point.
class LocalQuadric {
 public:
  LocalQuadric() = default;
  // frame: columns t1, t2, n (orthonormal, right-handed) in world coordinates; origin: where x = y = z = 0;
  // coefficients: (a, b, c, d, e, f).
  LocalQuadric(const Eigen::Vector3d& origin, const Eigen::Matrix3d& frame,
               const Eigen::Matrix<double, 6, 1>& coefficients, double radius, bool quadratic);

  // Least-squares fit to `neighbours` (the k nearest points of `centre`, usually including it) in the frame
  // of their PCA plane through `centre`. At least 6 points are needed (std::invalid_argument otherwise, and
  // for non-finite input). When the neighbours do not determine the quadratic terms (fewer than 6 distinct
  // points spread over the plane, e.g. one scan line) the fit falls back to the plane z = d x + e y + f and
  // quadratic() is false: zero curvature.
  static LocalQuadric Fit(const Eigen::Matrix3Xd& neighbours, const Eigen::Vector3d& centre);

  double Height(double x, double y) const;
  // Point, unit normal (the side of +z), principal curvatures and directions of the height field at (x, y),
  // in world coordinates.
  SurfacePoint At(double x, double y) const;
  // The orthogonal projection of q onto the height field (Newton on the squared distance in (x, y), started
  // at q's projection onto the plane); the surface point nearest q for q within the neighbourhood and closer
  // than the curvature radii.
  SurfacePoint FootPoint(const Eigen::Vector3d& q) const;

  const Eigen::Vector3d& origin() const { return origin_; }
  const Eigen::Matrix3d& frame() const { return frame_; }
  const Eigen::Matrix<double, 6, 1>& coefficients() const { return coefficients_; }
  double radius() const { return radius_; }  // largest distance of a fitted neighbour from the origin
  bool quadratic() const { return quadratic_; }

 private:
  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d frame_ = Eigen::Matrix3d::Identity();
  Eigen::Matrix<double, 6, 1> coefficients_ = Eigen::Matrix<double, 6, 1>::Zero();
  double radius_ = 0.0;
  bool quadratic_ = false;
};

// Principal curvatures and directions at every point by a local quadric fit over its `neighbours` nearest
// points (the point included), evaluated at the point's foot point on its own fit. The normal's sign follows
// the PCA plane and is therefore arbitrary; kappa1, kappa2 are signed w.r.t. the normal returned. Throws
// std::invalid_argument for fewer than 6 neighbours or points, or non-finite points.
std::vector<SurfacePoint> EstimatePrincipalCurvatures(const Eigen::Matrix3Xd& points, int neighbours);

// The SDM error matrix M = sum_k SdmWeight(delta, kappa_k) T_k T_k^T + n n^T at the foot point s of x, with
// the normal oriented towards x so that delta = n.(x - s) >= 0 (docs/method.md section 2). (x' - s)^T M (x' -
// s) is the second-order approximant of the squared distance of x' to the surface (Pottmann & Hofer 2003).
Eigen::Matrix3d SdmErrorMatrix(const SurfacePoint& foot, const Eigen::Vector3d& x);

}  // namespace s2m
