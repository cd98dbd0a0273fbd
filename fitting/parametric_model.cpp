#include "fitting/parametric_model.h"

#include <Eigen/Geometry>
#include <cmath>

namespace s2m {
namespace {

// Any unit vector orthogonal to u (3D).
Eigen::Vector3d AnyPerpendicular(const Eigen::Vector3d& u) {
  Eigen::Index k;
  u.cwiseAbs().minCoeff(&k);
  return u.cross(Eigen::Vector3d::Unit(k)).normalized();
}
}  // namespace

PrincipalFrame ComputePrincipalFrame(const LocalGeometry& g, const VecS& data_point) {
  PrincipalFrame f;
  const int s = static_cast<int>(g.point.size());
  const int m = static_cast<int>(g.d1.cols());
  const Eigen::Vector3d offset = To3(data_point - g.point);
  if (m == 1) {
    // Curve: T = C'/|C'|, curvature vector k = (C'' - (C''.T) T) / |C'|^2 (do Carmo, section 1-5).
    const Eigen::Vector3d c1 = To3(g.d1.col(0)), c2 = To3(g.d2.col(0));
    const double speed = c1.norm();
    const Eigen::Vector3d t = speed > 0 ? Eigen::Vector3d(c1 / speed) : Eigen::Vector3d::UnitX();
    const Eigen::Vector3d k =
        speed > 0 ? Eigen::Vector3d((c2 - c2.dot(t) * t) / (speed * speed)) : Eigen::Vector3d::Zero();
    f.tangent_count = 1;
    f.tangents[0] = t;
    Eigen::Vector3d normal_offset = offset - offset.dot(t) * t;
    Eigen::Vector3d n;
    if (normal_offset.norm() > 1e-14 * (1.0 + offset.norm())) {
      n = normal_offset.normalized();
    } else if (s == 2) {
      n = Eigen::Vector3d(-t.y(), t.x(), 0.0);
    } else {
      n = k.norm() > 0 ? Eigen::Vector3d(k.normalized()) : AnyPerpendicular(t);
    }
    f.normals[0] = n;
    f.normal_count = s - 1;
    if (s == 3) f.normals[1] = t.cross(n);
    f.curvatures[0] = k.dot(n);
    f.delta = n.dot(offset);
    return f;
  }
  // Surface in 3D: principal curvatures from the generalized eigenproblem II v = kappa I v (first and second
  // fundamental forms); I-orthonormal eigenvectors give orthonormal principal directions T = C_t v.
  const Eigen::Vector3d su = To3(g.d1.col(0)), sv = To3(g.d1.col(1));
  Eigen::Vector3d n = su.cross(sv);
  n = n.norm() > 0 ? Eigen::Vector3d(n.normalized())
                   : AnyPerpendicular(su.norm() > 0 ? su.normalized() : Eigen::Vector3d::UnitX());
  if (n.dot(offset) < 0) n = -n;
  Eigen::Matrix2d first, second;
  first << su.dot(su), su.dot(sv), su.dot(sv), sv.dot(sv);
  second << n.dot(To3(g.d2.col(0))), n.dot(To3(g.d2.col(1))), n.dot(To3(g.d2.col(1))),
      n.dot(To3(g.d2.col(2)));
  f.tangent_count = 2;
  f.normal_count = 1;
  f.normals[0] = n;
  f.delta = n.dot(offset);
  Eigen::Matrix2d directions;
  Eigen::Vector2d curvatures;
  if (SolvePrincipalCurvatures(second, first, directions, curvatures)) {
    for (int k = 0; k < 2; ++k) {
      const Eigen::Vector2d v = directions.col(k);
      f.tangents[static_cast<std::size_t>(k)] = (v.x() * su + v.y() * sv).normalized();
      f.curvatures[static_cast<std::size_t>(k)] = curvatures[k];
    }
  } else {  // degenerate metric: fall back to an orthonormal tangent basis with zero curvature
    f.tangents[0] = AnyPerpendicular(n);
    f.tangents[1] = n.cross(f.tangents[0]);
  }
  return f;
}

bool ParametricModel::ClosedFormFoot(const VecS& x, ParamT& t, double& distance, bool& on_boundary,
                                     bool& ambiguous) const {
  if (!ClosedFormFootPoint(x, t)) return false;
  LocalGeometry g;
  Evaluate(t, 0, g);
  distance = (g.point - x).norm();
  on_boundary = FootPointOnBoundary(x, t);
  ambiguous = AmbiguousFootPoint(x, t);
  return true;
}

}  // namespace s2m
