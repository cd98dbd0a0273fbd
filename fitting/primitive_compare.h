#pragma once
// Invariant comparison of two fits of the same primitive (e.g. ours against a certified reference): axes are
// compared as lines (direction up to sign for planes and cylinders, point projected onto the axis), not as
// the arbitrary points and signs a parametrization happens to carry.

#include "fitting/primitives.h"

namespace s2m {

struct PrimitiveDeviation {
  double position =
      0.0;  // plane: offset along the normal; sphere: centre distance; axes: reference point to our axis
  double direction = 0.0;  // radians between normals / axes (0 for spheres)
  double size = 0.0;       // |diameter difference| (sphere, cylinder), |surface-distance difference| (cone)
  double angle = 0.0;      // cone only: |full apex angle difference|, radians
};

PrimitiveDeviation Compare(const Plane& fit, const Plane& reference);
PrimitiveDeviation Compare(const Sphere& fit, const Sphere& reference);
PrimitiveDeviation Compare(const Cylinder& fit, const Cylinder& reference);
PrimitiveDeviation Compare(const Cone& fit, const Cone& reference);

// Angle between two lines with unit directions a and b (sign-free), accurate for tiny angles.
double LineAngle(const Eigen::Vector3d& a, const Eigen::Vector3d& b);
// Angle between two unit vectors (signed directions), accurate for tiny angles.
double VectorAngle(const Eigen::Vector3d& a, const Eigen::Vector3d& b);

}  // namespace s2m
