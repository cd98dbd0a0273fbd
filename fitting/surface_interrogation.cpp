#include "fitting/surface_interrogation.h"

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "registration/principal_curvatures.h"

namespace s2m {

SurfacePointCurvature InterrogateSurfacePoint(const Eigen::Vector3d& point,
                                              const Eigen::Matrix<double, 3, 2>& d1,
                                              const Eigen::Matrix3d& d2) {
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  SurfacePointCurvature c;
  c.point = point;
  c.normal.setConstant(kNaN);
  c.first.setConstant(kNaN);
  c.second.setConstant(kNaN);
  c.gaussian = c.mean = c.kmax = c.kmin = c.absolute = kNaN;
  c.direction_max.setConstant(kNaN);
  c.direction_min.setConstant(kNaN);
  const Eigen::Vector3d wu = d1.col(0), wv = d1.col(1);
  const Eigen::Vector3d cross = wu.cross(wv);
  const double area = cross.norm();
  if (!(area > std::sqrt(std::numeric_limits<double>::epsilon()) * wu.norm() * wv.norm()) ||
      !d2.allFinite() || !point.allFinite())
    return c;
  const Eigen::Vector3d n = cross / area;
  const double e = wu.dot(wu), f = wu.dot(wv), g = wv.dot(wv);
  const double l = n.dot(d2.col(0)), m = n.dot(d2.col(1)), nn = n.dot(d2.col(2));
  Eigen::Matrix2d first, second;
  first << e, f, f, g;
  second << l, m, m, nn;
  // Principal curvatures in Fang's sign: the eigenvalues of I^-1 (-II), ascending (kmin, kmax).
  Eigen::Matrix2d directions;
  Eigen::Vector2d kappa;
  if (!SolvePrincipalCurvatures(-second, first, directions, kappa)) return c;
  const double metric = e * g - f * f;
  c.regular = true;
  c.normal = n;
  c.first = first;
  c.second = second;
  c.gaussian = (l * nn - m * m) / metric;
  c.mean = (2 * f * m - (e * nn + g * l)) / (2 * metric);
  c.kmin = kappa[0];
  c.kmax = kappa[1];
  c.absolute = std::abs(c.kmax) + std::abs(c.kmin);
  c.direction_min = (directions(0, 0) * wu + directions(1, 0) * wv).normalized();
  c.direction_max = (directions(0, 1) * wu + directions(1, 1) * wv).normalized();
  return c;
}

SurfacePointCurvature InterrogateSurfacePoint(const LocalGeometry& g) {
  if (g.point.size() != 3 || g.d1.rows() != 3 || g.d1.cols() != 2 || g.d2.rows() != 3 || g.d2.cols() != 3)
    throw std::invalid_argument("surface interrogation needs a surface in 3D with second derivatives");
  const Eigen::Matrix<double, 3, 2> d1 = g.d1;
  const Eigen::Matrix3d d2 = g.d2;
  return InterrogateSurfacePoint(g.point, d1, d2);
}

double CurvatureValue(const SurfacePointCurvature& c, CurvatureKind kind) {
  switch (kind) {
    case CurvatureKind::kGaussian:
      return c.gaussian;
    case CurvatureKind::kMean:
      return c.mean;
    case CurvatureKind::kMax:
      return c.kmax;
    case CurvatureKind::kMin:
      return c.kmin;
    case CurvatureKind::kAbsolute:
      return c.absolute;
  }
  return std::numeric_limits<double>::quiet_NaN();
}

std::string ToString(CurvatureKind kind) {
  switch (kind) {
    case CurvatureKind::kGaussian:
      return "gaussian";
    case CurvatureKind::kMean:
      return "mean";
    case CurvatureKind::kMax:
      return "kmax";
    case CurvatureKind::kMin:
      return "kmin";
    case CurvatureKind::kAbsolute:
      return "absolute";
  }
  return "";
}

bool ParseCurvatureKind(const std::string& name, CurvatureKind& kind) {
  for (const CurvatureKind k : {CurvatureKind::kGaussian, CurvatureKind::kMean, CurvatureKind::kMax,
                                CurvatureKind::kMin, CurvatureKind::kAbsolute}) {
    if (ToString(k) == name) {
      kind = k;
      return true;
    }
  }
  return false;
}

double IsophoteValue(const Eigen::Vector3d& normal, const Eigen::Vector3d& light) {
  return normal.dot(light);
}

bool LightPlane::IsValid(std::string* why) const {
  auto fail = [&](const char* text) {
    if (why) *why = text;
    return false;
  };
  if (!origin.allFinite() || !direction.allFinite() || !across.allFinite() || !eye.allFinite())
    return fail("the light plane and the eye must be finite");
  constexpr double kRounding = 1e-12;  // unit length and orthogonality up to rounding of the caller's maths
  if (std::abs(direction.norm() - 1) > kRounding || std::abs(across.norm() - 1) > kRounding)
    return fail("the light lines' direction and the offset direction must be unit vectors");
  if (std::abs(direction.dot(across)) > kRounding)
    return fail("the offset direction must be orthogonal to the light lines");
  return true;
}

ReflectionHit ReflectionLineParameter(const LightPlane& light, const Eigen::Vector3d& point,
                                      const Eigen::Vector3d& normal) {
  ReflectionHit h;
  h.offset = std::numeric_limits<double>::quiet_NaN();
  h.on_plane.setConstant(h.offset);
  const Eigen::Vector3d view = point - light.eye;
  const double distance = view.norm();
  if (!(distance > 0) || !normal.allFinite()) return h;
  const Eigen::Vector3d e = view / distance;
  // Mirror the viewing ray about the normal: r = e - 2 (e.n) n (either orientation of n gives the same r).
  const Eigen::Vector3d r = e - 2 * e.dot(normal) * normal;
  const Eigen::Vector3d plane_normal = light.direction.cross(light.across);
  const double approach = r.dot(plane_normal);
  if (approach == 0) return h;
  const double lambda = (light.origin - point).dot(plane_normal) / approach;
  if (!(lambda >= 0) || !std::isfinite(lambda)) return h;
  h.on_plane = point + lambda * r;
  h.offset = (h.on_plane - light.origin).dot(light.across);
  h.hit = true;
  return h;
}

int ZebraStripe(double offset, double spacing) {
  const double band = std::floor(offset / spacing);
  return std::fmod(band, 2.0) == 0.0 ? 0 : 1;
}

double ContourHeight(const Eigen::Vector3d& point, const Eigen::Vector3d& origin,
                     const Eigen::Vector3d& direction) {
  return (point - origin).dot(direction);
}

}  // namespace s2m
