#pragma once
// Test set-up several core test files share: random points near a surface model, the tilted faces of the
// test parts, and the registration pose pair (truth and a start 3 degrees and about 1.9 mm off it).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <random>
#include <utility>

#include "fitting/bspline_basis.h"
#include "fitting/parametric_model.h"
#include "fitting/part_model.h"
#include "registration/rigid_motion.h"

namespace s2m::test {

// `count` points over the inner part [inner_lo, inner_hi] (fractions of each side) of a surface model's (u,
// v) domain, each moved off the model by three draws of `noise` (a random-number distribution: the x, y and z
// offsets).
template <typename Noise>
Eigen::Matrix3Xd PointsOverInnerDomain(const ParametricModel& model, int count, double inner_lo,
                                       double inner_hi, Noise noise, std::uint64_t seed) {
  const ParameterDomain d = model.domain();
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(inner_lo, inner_hi);
  Eigen::Matrix3Xd p(3, count);
  LocalGeometry g;
  for (int j = 0; j < count; ++j) {
    model.Evaluate({d.lo[0] + u(rng) * (d.hi[0] - d.lo[0]), d.lo[1] + u(rng) * (d.hi[1] - d.lo[1]), 0.0}, 0,
                   g);
    p.col(j) = To3(g.point) + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
  }
  return p;
}

// Face number `index` of the test parts: a face of `type` in a frame tilted more for each index, its
// quantities linear expressions in the parameters a (0), b (1) and angle (2) with several terms. A spline
// patch is cubic x quadratic with knots spanning [-2, 2] (the family tests' parameter band), its control
// points shifted by `patch_z_shift` along z; they depend on both lengths.
inline PartFace TiltedTestFace(FaceType type, int index, double patch_z_shift) {
  const double k = index;
  PartFace f;
  f.type = type;
  f.frame = Eigen::AngleAxisd(0.6 + 0.3 * k, Eigen::Vector3d(1, -2, 0.5 + k).normalized()).toRotationMatrix();
  f.origin[0] = {0.3 + 3.0 * k, {{0, 0.5}}};
  f.origin[1] = {-0.2, {{1, 1.0}}};
  f.origin[2] = {0.1, {}};
  f.offset = {0.25 + k, {{0, 1.0}, {1, -1.0}}};
  f.radius = {0.4, {{0, 1.0}, {1, 0.5}}};
  f.minor_radius = {0.1, {{1, 1.0}}};
  f.half_angle = {0.1, {{2, 1.0}}};
  if (type == FaceType::kSplinePatch) {
    SplinePatch patch{BSplineBasis::Clamped(4, {-2, -2, -2, -2, 0, 2, 2, 2, 2}),
                      BSplineBasis::Clamped(3, {-2, -2, -2, 0.3, 2, 2, 2}),
                      {}};
    for (int i = 0; i < 5; ++i) {
      for (int j = 0; j < 4; ++j) {
        patch.control_points.push_back(
            {LinearExpression{i - 2.0, {{0, 0.1 * i}}}, LinearExpression{j - 1.5, {{1, 0.2}}},
             LinearExpression{0.3 * std::sin(i + 2.0 * j) + patch_z_shift, {{0, 0.05 * j}, {1, 0.3}}}});
      }
    }
    f.patch = std::move(patch);
  }
  return f;
}

// The pose the registration tests place their scans with, and the start they recover it from: 3 degrees
// about a skew axis and (1.2, -1, 1) off the truth.
struct RegistrationPoses {
  RigidMotion truth, start;
};

inline RegistrationPoses ThreeDegreeRegistrationPoses() {
  RegistrationPoses p;
  p.truth =
      RigidMotion(RotationAboutAxis(Eigen::Vector3d(1, 2, 3).normalized(), 0.4), Eigen::Vector3d(30, -10, 5));
  p.start = RigidMotion(RotationAboutAxis(Eigen::Vector3d(-1, 1, 2).normalized(), 3 * M_PI / 180),
                        Eigen::Vector3d(1.2, -1.0, 1.0)) *
            p.truth;
  return p;
}

}  // namespace s2m::test
