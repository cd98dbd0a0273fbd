#pragma once
// Interrogation of a parametric surface w(u, v) at one point from its exact derivatives
// (docs/interrogation.md): the first and second fundamental forms, Gaussian, mean, principal and absolute
// curvature (L. Fang's thesis, 1994, appendix A.2), isophotes (Poeschl 1984), Klass' reflection lines (1980),
// zebra stripes and contours of a height. Everything here is a function of the point, its normal and its
// first and second derivatives; sampling a surface and drawing the results is the pipeline's
// (pipeline/surface_render.h).
//
// Sign convention (Fang's): n = w_u x w_v / |w_u x w_v|, the parametrization's own normal, and the normal
// curvature of a tangent direction (du, dv) is
//   kappa_n = -(L du^2 + 2 M du dv + N dv^2) / (E du^2 + 2 F du dv + G dv^2),   L = n.w_uu, M = n.w_uv, N =
//   n.w_vv,
// positive when the centre of curvature lies on the side opposite to n: a sphere whose n points outwards has
// kappa = +1/radius everywhere. Gaussian curvature K does not depend on the side; H, kappa_max and kappa_min
// change sign with n.

#include <Eigen/Core>
#include <string>

#include "fitting/parametric_model.h"

namespace s2m {

// The curvatures of a surface at one point. When the point is singular (w_u and w_v parallel or zero within
// rounding, see `regular`) only `point` is set: the other members are NaN.
struct SurfacePointCurvature {
  // False where |w_u x w_v| <= sqrt(machine epsilon) |w_u| |w_v|: the unit normal would have lost half its
  // digits to rounding (its relative error grows as epsilon / sin of the angle between w_u and w_v), e.g.
  // where the generatrix of a surface of revolution meets the axis (w_v = 0) or the apex of a cone.
  bool regular = false;
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();  // n, unit
  Eigen::Matrix2d first = Eigen::Matrix2d::Zero();   // [E F; F G]
  Eigen::Matrix2d second = Eigen::Matrix2d::Zero();  // [L M; M N] with respect to n
  double gaussian = 0.0;                             // K = (LN - M^2) / (EG - F^2)
  double mean = 0.0;                                 // H = (2FM - (EN + GL)) / (2 (EG - F^2)), Fang's sign
  double kmax = 0.0, kmin = 0.0;                     // H +- sqrt(H^2 - K), kmax >= kmin
  double absolute = 0.0;                             // |kmax| + |kmin|
  // Unit principal directions in space (tangent to the surface), of kmax and kmin.
  Eigen::Vector3d direction_max = Eigen::Vector3d::Zero(), direction_min = Eigen::Vector3d::Zero();
};

// From the point w and its exact derivatives: d1 = [w_u w_v], d2 = [w_uu w_uv w_vv].
SurfacePointCurvature InterrogateSurfacePoint(const Eigen::Vector3d& point,
                                              const Eigen::Matrix<double, 3, 2>& d1,
                                              const Eigen::Matrix3d& d2);
// From ParametricModel::Evaluate(t, 2, g) of a surface in 3D (g.d1 3 x 2, g.d2 3 x 3). std::invalid_argument
// for other shapes (curves, plane models).
SurfacePointCurvature InterrogateSurfacePoint(const LocalGeometry& g);

// The curvature a map shows.
enum class CurvatureKind { kGaussian, kMean, kMax, kMin, kAbsolute };
double CurvatureValue(const SurfacePointCurvature& c, CurvatureKind kind);
// "gaussian", "mean", "kmax", "kmin", "absolute" (ParseCurvatureKind returns false for other names).
std::string ToString(CurvatureKind kind);
bool ParseCurvatureKind(const std::string& name, CurvatureKind& kind);

// Isophote value N.L of a unit normal and a unit light direction (Poeschl): the isophote of level c is the
// curve where it equals c, the points lit at angle acos(c); c = 0 is the silhouette seen from L.
double IsophoteValue(const Eigen::Vector3d& normal, const Eigen::Vector3d& light);

// A light plane of parallel straight lights (Klass): the lines L0 + c d + t s for every offset c, in the
// plane through `origin` spanned by the unit line direction `direction` (s) and the unit offset direction
// `across` (d, orthogonal to s), and an eye point `eye`.
struct LightPlane {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();
  Eigen::Vector3d across = Eigen::Vector3d::UnitY();
  Eigen::Vector3d eye = Eigen::Vector3d(0, 0, 1);
  bool IsValid(std::string* why) const;
};

// The light line the eye sees mirrored at a surface point: the ray from the eye to `point`, reflected about
// the normal, meets the light plane at origin + c d + t s; its offset c. The reflection line of light c is
// the level set {c(u, v) = c}. Not `hit` (c NaN) when the reflected ray runs parallel to the plane or away
// from it (the point mirrors no light of the plane to the eye) or when the eye lies on the point.
struct ReflectionHit {
  bool hit = false;
  double offset = 0.0;  // c
  Eigen::Vector3d on_plane = Eigen::Vector3d::Zero();
};
ReflectionHit ReflectionLineParameter(const LightPlane& light, const Eigen::Vector3d& point,
                                      const Eigen::Vector3d& normal);

// Zebra stripes: the stripe of a reflection-line offset c between lights `spacing` apart, 0 or 1 (the parity
// of floor(c / spacing)). spacing > 0.
int ZebraStripe(double offset, double spacing);

// Contours ("z-contours"): the height of `point` along the unit `direction` above `origin`; the contour lines
// are its level sets (the surface cut by parallel planes).
double ContourHeight(const Eigen::Vector3d& point, const Eigen::Vector3d& origin,
                     const Eigen::Vector3d& direction);

}  // namespace s2m
