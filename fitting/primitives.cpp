#include "fitting/primitives.h"

#include <Eigen/Geometry>
#include <cmath>

namespace s2m {

double Cone::SurfaceDistanceFromAxisPoint() const {
  return radius * std::cos(half_angle);
}

Eigen::Vector3d Cone::Apex() const {
  return axis_point - (radius / std::tan(half_angle)) * axis_direction;
}

double SignedDistance(const Plane& plane, const Eigen::Vector3d& x) {
  return plane.normal.dot(x - plane.point);
}

double SignedDistance(const Sphere& sphere, const Eigen::Vector3d& x) {
  return (x - sphere.center).norm() - sphere.radius;
}

double SignedDistance(const Cylinder& cylinder, const Eigen::Vector3d& x) {
  const Eigen::Vector3d v = x - cylinder.axis_point;
  return (v - cylinder.axis_direction.dot(v) * cylinder.axis_direction).norm() - cylinder.radius;
}

double SignedDistance(const Cone& cone, const Eigen::Vector3d& x) {
  // Forbes, NPL report DITC 140/89, section 7: d = rho cos(psi) - z sin(psi) - s, with s the orthogonal
  // distance from the axis point to the surface, rho the distance from the axis and z the axial coordinate.
  const Eigen::Vector3d v = x - cone.axis_point;
  const double z = cone.axis_direction.dot(v);
  const double rho = (v - z * cone.axis_direction).norm();
  return rho * std::cos(cone.half_angle) - z * std::sin(cone.half_angle) -
         cone.SurfaceDistanceFromAxisPoint();
}

double SignedDistance(const Line3d& line, const Eigen::Vector3d& x) {
  const Eigen::Vector3d v = x - line.point;
  return (v - line.direction.dot(v) * line.direction).norm();
}

double SignedDistance(const Circle3d& circle, const Eigen::Vector3d& x) {
  // In the circle's plane the nearest point is on the ray from the centre through x's projection: the
  // distance is sqrt(h^2 + (rho - r)^2) with h the height over the plane and rho the in-plane radius.
  const Eigen::Vector3d v = x - circle.center;
  const double h = circle.normal.dot(v);
  const double rho = (v - h * circle.normal).norm();
  return std::hypot(h, rho - circle.radius);
}

double SignedDistance(const Torus& torus, const Eigen::Vector3d& x) {
  const Eigen::Vector3d v = x - torus.center;
  const double z = torus.axis.dot(v);
  const double rho = (v - z * torus.axis).norm();
  return std::hypot(rho - torus.major_radius, z) - torus.minor_radius;
}

Plane Transformed(const Plane& s, double scale, const Eigen::Vector3d& offset) {
  return {scale * s.point + offset, s.normal};
}
Sphere Transformed(const Sphere& s, double scale, const Eigen::Vector3d& offset) {
  return {scale * s.center + offset, scale * s.radius};
}
Cylinder Transformed(const Cylinder& s, double scale, const Eigen::Vector3d& offset) {
  return {scale * s.axis_point + offset, s.axis_direction, scale * s.radius};
}
Cone Transformed(const Cone& s, double scale, const Eigen::Vector3d& offset) {
  return {scale * s.axis_point + offset, s.axis_direction, s.half_angle, scale * s.radius};
}

Line3d Transformed(const Line3d& s, double scale, const Eigen::Vector3d& offset) {
  return {scale * s.point + offset, s.direction};
}
Circle3d Transformed(const Circle3d& s, double scale, const Eigen::Vector3d& offset) {
  return {scale * s.center + offset, s.normal, scale * s.radius};
}
Torus Transformed(const Torus& s, double scale, const Eigen::Vector3d& offset) {
  return {scale * s.center + offset, s.axis, scale * s.major_radius, scale * s.minor_radius};
}

void MoveAxisPointNear(Line3d& line, const Eigen::Vector3d& reference) {
  line.point += line.direction.dot(reference - line.point) * line.direction;
}

void MoveAxisPointNear(Cylinder& cylinder, const Eigen::Vector3d& reference) {
  const double t = cylinder.axis_direction.dot(reference - cylinder.axis_point);
  cylinder.axis_point += t * cylinder.axis_direction;
}

void MoveAxisPointNear(Cone& cone, const Eigen::Vector3d& reference) {
  const double t = cone.axis_direction.dot(reference - cone.axis_point);
  cone.axis_point += t * cone.axis_direction;
  cone.radius += t * std::tan(cone.half_angle);
}

Eigen::Matrix3d FrameWithAxis(const Eigen::Vector3d& axis) {
  // Pick the coordinate axis least aligned with `axis` to build a well-conditioned perpendicular.
  Eigen::Index k;
  axis.cwiseAbs().minCoeff(&k);
  const Eigen::Vector3d e1 = axis.cross(Eigen::Vector3d::Unit(k)).normalized();
  const Eigen::Vector3d e2 = axis.cross(e1);
  Eigen::Matrix3d frame;
  frame << e1, e2, axis;
  return frame;
}

std::vector<Eigen::Vector3d> FibonacciHemisphere(int samples) {
  std::vector<Eigen::Vector3d> dirs;
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < samples; ++i) {
    const double z = 1.0 - (i + 0.5) / samples;
    const double r = std::sqrt(1.0 - z * z);
    dirs.emplace_back(r * std::cos(golden * i), r * std::sin(golden * i), z);
  }
  return dirs;
}

}  // namespace s2m
