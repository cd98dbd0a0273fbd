// The closed-form feet of a part's analytic faces (fitting/part_model.h) use face quantities evaluated once
// per change of the parameters and compute the angle only on the nearest face: the feet must stay those of a
// freshly built part after set_parameters and ApplySimilarity (no stale quantity), the distance must be
// |C(t) - x| at the returned t, and C(t) - x orthogonal to the face there, for every analytic face type.

#include "fitting/part_model.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>

namespace s2m {
namespace {

// One face of each analytic type, in tilted frames, every quantity a linear expression of the parameters.
PartDefinition MixedPart() {
  PartDefinition d;
  d.name = "mixed";
  d.parameters = {{"a", 10.0, false}, {"b", 3.0, false}, {"angle", 0.4, true}};
  const Eigen::Matrix3d tilt =
      Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  auto face = [&](const char* name, FaceType type, const Eigen::Matrix3d& frame) {
    PartFace f;
    f.name = name;
    f.type = type;
    f.frame = frame;
    return f;
  };
  PartFace plane = face("plane", FaceType::kPlane, tilt);
  plane.offset = {4.0, {{1, 1.0}}};
  PartFace cylinder = face("cylinder", FaceType::kCylinder, tilt.transpose());
  cylinder.origin = {LinearExpression{0.0, {}}, LinearExpression{1.0, {{1, 0.5}}}, LinearExpression{0.0, {}}};
  cylinder.radius = {-3.0, {{0, 1.0}}};
  PartFace cone = face("cone", FaceType::kCone, tilt);
  cone.origin = {LinearExpression{1.0, {}}, LinearExpression{2.0, {}}, LinearExpression{3.0, {{1, -1.0}}}};
  cone.radius = {0.0, {{0, 1.0}}};
  cone.half_angle = {0.0, {{2, 1.0}}};
  PartFace sphere = face("sphere", FaceType::kSphere, tilt * tilt);
  sphere.origin = {LinearExpression{5.0, {}}, LinearExpression{-2.0, {}}, LinearExpression{1.0, {}}};
  sphere.radius = {2.0, {{0, 0.7}}};
  PartFace torus = face("torus", FaceType::kTorus, Eigen::Matrix3d::Identity());
  torus.origin = {LinearExpression{-3.0, {}}, LinearExpression{0.0, {}}, LinearExpression{2.0, {}}};
  torus.radius = {0.0, {{0, 1.2}}};
  torus.minor_radius = {0.0, {{1, 1.0}}};
  d.faces = {plane, cylinder, cone, sphere, torus};
  return d;
}

Eigen::Matrix3Xd RandomPoints(int count, double spread, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, spread);
  Eigen::Matrix3Xd p(3, count);
  for (int i = 0; i < count; ++i) p.col(i) << gauss(rng), gauss(rng), gauss(rng);
  return p;
}

// The part built from scratch at the model's current definition and values.
PartModel Fresh(const PartModel& model) {
  PartDefinition d = model.definition();
  for (std::size_t i = 0; i < d.parameters.size(); ++i)
    d.parameters[i].value = model.parameters()[static_cast<Eigen::Index>(i)];
  return PartModel(d);
}

// Feet of `model` equal to those of a fresh part, consistent with Evaluate and orthogonal to the face.
void ExpectFeetAsFreshAndConsistent(const PartModel& model, const Eigen::Matrix3Xd& points) {
  const PartModel fresh = Fresh(model);
  LocalGeometry g;
  int faces_hit[5] = {0, 0, 0, 0, 0};
  for (Eigen::Index j = 0; j < points.cols(); ++j) {
    const VecS x = points.col(j);
    ParamT t{0, 0, 0}, t_fresh{0, 0, 0};
    double d = 0.0, d_fresh = 0.0;
    bool boundary = false, ambiguous = false;
    model.ClosedFormFoot(x, t, d, boundary, ambiguous);
    fresh.ClosedFormFoot(x, t_fresh, d_fresh, boundary, ambiguous);
    ASSERT_EQ(t, t_fresh) << "point " << j;
    ASSERT_EQ(d, d_fresh) << "point " << j;
    ++faces_hit[PartModel::FaceOf(t)];
    model.Evaluate(t, 1, g);
    const Eigen::Vector3d r = To3(g.point) - To3(x);
    const double scale = 1.0 + To3(x).norm();
    EXPECT_NEAR(r.norm(), d, 1e-10 * scale) << "point " << j << " face " << PartModel::FaceOf(t);
    for (int k = 0; k < 2; ++k) {
      const Eigen::Vector3d tangent = g.d1.col(k);
      EXPECT_NEAR(r.dot(tangent), 0.0, 1e-9 * scale * (1.0 + tangent.norm()))
          << "point " << j << " face " << PartModel::FaceOf(t) << " direction " << k;
    }
  }
  for (int f = 0; f < 5; ++f) EXPECT_GT(faces_hit[f], 0) << "no point nearest to face " << f;
}

TEST(PartModelFeet, FeetOnEveryAnalyticFaceTypeAreConsistentWithEvaluate) {
  const PartModel part(MixedPart());
  ExpectFeetAsFreshAndConsistent(part, RandomPoints(4000, 8.0, 1));
}

TEST(PartModelFeet, FeetFollowSetParameters) {
  PartModel part(MixedPart());
  const Eigen::Matrix3Xd points = RandomPoints(4000, 8.0, 2);
  ExpectFeetAsFreshAndConsistent(part, points);
  part.set_parameters(Eigen::Vector3d(11.5, 2.5, 0.55));
  ExpectFeetAsFreshAndConsistent(part, points);
}

TEST(PartModelFeet, FeetFollowApplySimilarity) {
  PartModel part(MixedPart());
  part.ApplySimilarity(0.05, VecS(Eigen::Vector3d(0.3, -0.2, 0.1)));
  // The points scaled with the part: the same relative configuration.
  const Eigen::Matrix3Xd points =
      (0.05 * RandomPoints(4000, 8.0, 3)).colwise() + Eigen::Vector3d(0.3, -0.2, 0.1);
  ExpectFeetAsFreshAndConsistent(part, points);
}

}  // namespace
}  // namespace s2m
