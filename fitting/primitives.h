#pragma once
// Primitive surfaces with closed-form signed distances (outside positive).

#include <Eigen/Core>
#include <vector>

namespace s2m {

struct Plane {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // unit
};

struct Sphere {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  double radius = 1.0;
};

struct Cylinder {
  Eigen::Vector3d axis_point = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis_direction = Eigen::Vector3d::UnitZ();  // unit; sign is arbitrary
  double radius = 1.0;
};

// A circular cone. `radius` is the radius of the cross-section through `axis_point` (perpendicular to the
// axis); the radius grows along `axis_direction` with slope tan(half_angle), half_angle in (0, pi/2).
struct Cone {
  Eigen::Vector3d axis_point = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis_direction = Eigen::Vector3d::UnitZ();  // unit, towards increasing radius
  double half_angle = 0.5;
  double radius = 1.0;

  // Orthogonal distance from axis_point to the surface (the NIST / ASME B89.4.10 cone parameter).
  double SurfaceDistanceFromAxisPoint() const;
  Eigen::Vector3d Apex() const;
};

// A straight line (ISO 10360-6's line): a point on it and a unit direction (sign arbitrary).
struct Line3d {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();  // unit
};

// A circle in space (ISO 10360-6's circle): centre, unit normal of its plane (sign arbitrary), radius.
struct Circle3d {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // unit
  double radius = 1.0;
};

// A torus: the surface at distance `minor_radius` from the circle of radius `major_radius` about `axis`
// through `center` in the plane perpendicular to it (the spine). A ring torus has minor < major; the
// distance below is the orthogonal one for every point off the axis.
struct Torus {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // unit; sign arbitrary
  double major_radius = 2.0;
  double minor_radius = 0.5;
};

// Signed orthogonal distance, positive outside (on the side the outward normal points to).
double SignedDistance(const Plane& plane, const Eigen::Vector3d& x);
double SignedDistance(const Sphere& sphere, const Eigen::Vector3d& x);
double SignedDistance(const Cylinder& cylinder, const Eigen::Vector3d& x);
// Exact for points whose foot point lies on the nappe that axis_direction opens into.
double SignedDistance(const Cone& cone, const Eigen::Vector3d& x);
// Curves have no outside: the distance to a line or a circle is the (non-negative) orthogonal distance.
double SignedDistance(const Line3d& line, const Eigen::Vector3d& x);
double SignedDistance(const Circle3d& circle, const Eigen::Vector3d& x);
// sqrt((rho - R)^2 + z^2) - r with rho, z the point's distance from the axis and height over the centre:
// the distance to the spine circle minus the tube radius (positive away from the tube's core).
double SignedDistance(const Torus& torus, const Eigen::Vector3d& x);

template <class Shape>
Eigen::VectorXd SignedDistances(const Shape& shape, const Eigen::Matrix3Xd& points) {
  Eigen::VectorXd d(points.cols());
  for (Eigen::Index i = 0; i < points.cols(); ++i)
    d[i] = SignedDistance(shape, Eigen::Vector3d(points.col(i)));
  return d;
}

// The shape under the similarity x -> scale * x + offset (used to map fits out of normalized coordinates).
Plane Transformed(const Plane& s, double scale, const Eigen::Vector3d& offset);
Sphere Transformed(const Sphere& s, double scale, const Eigen::Vector3d& offset);
Cylinder Transformed(const Cylinder& s, double scale, const Eigen::Vector3d& offset);
Cone Transformed(const Cone& s, double scale, const Eigen::Vector3d& offset);
Line3d Transformed(const Line3d& s, double scale, const Eigen::Vector3d& offset);
Circle3d Transformed(const Circle3d& s, double scale, const Eigen::Vector3d& offset);
Torus Transformed(const Torus& s, double scale, const Eigen::Vector3d& offset);

// Moves the (free) axis point to the projection of `reference` onto the axis; the cone's radius follows.
void MoveAxisPointNear(Cylinder& cylinder, const Eigen::Vector3d& reference);
void MoveAxisPointNear(Cone& cone, const Eigen::Vector3d& reference);
void MoveAxisPointNear(Line3d& line, const Eigen::Vector3d& reference);

// An orthonormal basis (e1, e2, axis) with the given unit axis as third column.
Eigen::Matrix3d FrameWithAxis(const Eigen::Vector3d& axis);

// `samples` unit directions of a Fibonacci lattice on the upper hemisphere (z > 0), about evenly spaced
// (neighbours about sqrt(2 pi / samples) radians apart): candidate axis directions.
std::vector<Eigen::Vector3d> FibonacciHemisphere(int samples);

}  // namespace s2m
