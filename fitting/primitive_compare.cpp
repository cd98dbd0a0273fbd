#include "fitting/primitive_compare.h"

#include <Eigen/Geometry>
#include <cmath>

namespace s2m {
namespace {
double DistanceToAxis(const Eigen::Vector3d& x, const Eigen::Vector3d& point,
                      const Eigen::Vector3d& direction) {
  const Eigen::Vector3d v = x - point;
  return (v - direction.dot(v) * direction).norm();
}
}  // namespace

double VectorAngle(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  // atan2(|a x b|, a.b) keeps full relative precision near 0 and pi, unlike acos.
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

double LineAngle(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const double angle = VectorAngle(a, b);
  return std::min(angle, M_PI - angle);
}

PrimitiveDeviation Compare(const Plane& fit, const Plane& reference) {
  PrimitiveDeviation d;
  d.position = std::abs(fit.normal.dot(reference.point - fit.point));
  d.direction = LineAngle(fit.normal, reference.normal);
  return d;
}

PrimitiveDeviation Compare(const Sphere& fit, const Sphere& reference) {
  PrimitiveDeviation d;
  d.position = (fit.center - reference.center).norm();
  d.size = 2.0 * std::abs(fit.radius - reference.radius);
  return d;
}

PrimitiveDeviation Compare(const Cylinder& fit, const Cylinder& reference) {
  PrimitiveDeviation d;
  d.position = DistanceToAxis(reference.axis_point, fit.axis_point, fit.axis_direction);
  d.direction = LineAngle(fit.axis_direction, reference.axis_direction);
  d.size = 2.0 * std::abs(fit.radius - reference.radius);
  return d;
}

PrimitiveDeviation Compare(const Cone& fit, const Cone& reference) {
  PrimitiveDeviation d;
  d.position = DistanceToAxis(reference.axis_point, fit.axis_point, fit.axis_direction);
  d.direction = VectorAngle(fit.axis_direction, reference.axis_direction);
  Cone moved = fit;
  MoveAxisPointNear(moved, reference.axis_point);
  d.size = std::abs(moved.SurfaceDistanceFromAxisPoint() - reference.SurfaceDistanceFromAxisPoint());
  d.angle = 2.0 * std::abs(fit.half_angle - reference.half_angle);
  return d;
}

}  // namespace s2m
