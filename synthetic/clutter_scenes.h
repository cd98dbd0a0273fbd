#pragma once
// Cluttered single-view scenes with ground truth for robust extraction (fitting/primitive_detection.h): a
// scanner at one position casts a regular grid of rays (constant angular steps, as a terrestrial laser
// scanner or a depth camera does) into a scene of spheres, finite cylinders and planes; each ray keeps its
// first hit (occlusion is exact), with Gaussian noise along the ray. Every point carries the index of the
// object it came from. Optionally, rays whose footprint straddles two objects return mixed ranges ("flying
// pixels" between a foreground and a background edge, as depth cameras and laser scanners do).

#include <Eigen/Core>
#include <cstdint>
#include <variant>
#include <vector>

#include "fitting/primitives.h"

namespace s2m {

// A cylinder's side from axis_point to axis_point + length * axis_direction (open: no caps).
struct FiniteCylinder {
  Cylinder cylinder;
  double length = 1.0;
};

using SceneObject = std::variant<Sphere, FiniteCylinder, Plane>;  // planes are unbounded

struct RayGrid {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d look_at = Eigen::Vector3d::UnitY();
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  double half_width = 0.1;   // radians, horizontal, either side of the centre ray
  double half_height = 0.1;  // radians, vertical
  double step = 1e-3;        // radians between neighbouring rays
  double range_noise = 0.0;  // standard deviation along the ray
  // Mixed pixels: a ray whose footprint (the rays half a step to either side, in both directions) meets two
  // objects returns, with this probability, a range between the two hits, w t_a + (1 - w) t_b with w
  // uniform in (0, 1), and the label kFlyingPixel. 0: off.
  double flying_pixel_probability = 0.0;
  std::uint64_t seed = 1;
};

constexpr int kFlyingPixel = -1;  // the label of a mixed pixel: on no object

struct LabelledCloud {
  Eigen::Matrix3Xd points;
  std::vector<int> labels;  // index into the scene's objects, or kFlyingPixel
};

LabelledCloud CastRays(const std::vector<SceneObject>& scene, const RayGrid& grid);

// The issue-22 case of a terrestrial laser scan of a calibration sphere (millimetres): a sphere of 25 mm
// radius (50 mm diameter) centred at the origin on a post (radius 6 mm) standing on a floor 65 mm below the
// centre, a wall 40 mm behind it, seen from `range` mm (6000-8000) by a scanner 0.21 rad above the horizontal
// with 1.2 mm spacing at the sphere and range noise `noise` mm, the window 56 mm wide and from 28 mm above
// the centre to 66 mm below it. Objects: 0 sphere, 1 post, 2 floor, 3 wall.
struct SphereOnStandScene {
  Sphere truth;
  std::vector<SceneObject> objects;
  LabelledCloud cloud;
};
// `flying_pixels`: RayGrid::flying_pixel_probability.
SphereOnStandScene MakeSphereOnStandScene(double range, double noise, std::uint64_t seed,
                                          double flying_pixels = 0.0);

// Three spheres (radii 30, 40, 50 mm) and a column (radius 40 mm, 1 m tall: its top is out of view) on a
// floor (z = 0), seen from about 1.7 m with 2.5 mm spacing and 0.3 mm range noise (millimetres). Objects: 0-2
// spheres, 3 cylinder, 4 floor.
struct SpheresAndCylinderScene {
  std::vector<SceneObject> objects;
  LabelledCloud cloud;
};
SpheresAndCylinderScene MakeSpheresAndCylinderScene(std::uint64_t seed, double flying_pixels = 0.0);

}  // namespace s2m
