// The wall of revolution (fitting/revolution_wall.h, docs/archaeology.md section 10): the shape Jacobian of
// each face at its place in the wall's parameters, the feet on the nearer face, the thickness and its
// gradient against closed forms and finite differences, and the volumes.

#include "fitting/revolution_wall.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <functional>
#include <iostream>
#include <string>

#include "fitting/initial_models.h"
#include "fitting/joint_fit.h"
#include "synthetic/synthetic_cases.h"

namespace s2m {
namespace {

// A straight generatrix from (r0, 0) to (r0 + slope * height, height), 5 cubic control points on it.
KinematicSurface Cone(double r0, double slope, double height) {
  Eigen::Matrix2Xd profile(2, 5);
  for (int k = 0; k < 5; ++k) {
    const double z = height * k / 4.0;
    profile.col(k) << r0 + slope * z, z;
  }
  return KinematicSurface::Revolution(BSplineBasis::ClampedUniform(4, 5), profile);
}

// A curved generatrix (a bellied pot), 6 cubic control points.
KinematicSurface Belly(double shift) {
  Eigen::Matrix2Xd profile(2, 6);
  profile << 30, 42, 55, 58, 48, 40,  //
      0, 20, 45, 70, 95, 120;
  profile.row(0).array() += shift;
  return KinematicSurface::Revolution(BSplineBasis::ClampedUniform(4, 6), profile);
}

TEST(RevolutionWall, OuterFaceIsDecidedByRadiusAndParametersFollowIt) {
  const RevolutionWall wall(Cone(34, 0.0, 100), Cone(40, 0.0, 100));  // inner given first
  EXPECT_NEAR(wall.face(RevolutionWall::kOuter).ProfilePoint(0.5).x(), 40.0, 1e-12);
  EXPECT_NEAR(wall.face(RevolutionWall::kInner).ProfilePoint(0.5).x(), 34.0, 1e-12);
  EXPECT_EQ(wall.num_parameters(), 20);
  EXPECT_EQ(wall.parameters().head(10), wall.face(RevolutionWall::kOuter).parameters());
  EXPECT_EQ(wall.parameters().tail(10), wall.face(RevolutionWall::kInner).parameters());
  EXPECT_EQ(wall.parameter_name(0).rfind("outer ", 0), 0u);
  EXPECT_EQ(wall.parameter_name(10).rfind("inner ", 0), 0u);
  const KinematicSurface helical =
      KinematicSurface::Helical(BSplineBasis::ClampedUniform(4, 5), Cone(40, 0, 50).profile(), 1.0, 1.0);
  EXPECT_THROW(RevolutionWall(Cone(34, 0, 50), helical), std::invalid_argument);
  Eigen::Matrix2Xd high = Cone(40, 0, 50).profile();
  high.row(1).array() += 100.0;  // no common height
  EXPECT_THROW(
      RevolutionWall(Cone(34, 0, 50), KinematicSurface::Revolution(BSplineBasis::ClampedUniform(4, 5), high)),
      std::invalid_argument);
}

TEST(RevolutionWall, ShapeJacobianMatchesFiniteDifferencesOnBothFaces) {
  RevolutionWall wall(Belly(0.0), Belly(-6.0));
  const Eigen::VectorXd p0 = wall.parameters();
  for (int index = 0; index < 2; ++index) {
    const ParamT t{0.37, 1.1, static_cast<double>(index)};
    std::vector<JacobianEntry> columns;
    wall.ShapeJacobian(t, false, columns);
    Eigen::MatrixXd analytic = Eigen::MatrixXd::Zero(3, wall.num_parameters());
    for (const JacobianEntry& c : columns) analytic.col(c.index) += c.column;
    FactoredJacobian factored;
    ASSERT_TRUE(wall.FactoredShapeJacobian(t, factored));
    Eigen::MatrixXd from_factored = Eigen::MatrixXd::Zero(3, wall.num_parameters());
    for (int i = 0; i < factored.weight_count; ++i)
      for (int c = 0; c < factored.direction_count; ++c)
        from_factored.col(factored.first_index[static_cast<std::size_t>(i)] + c) +=
            factored.weights[static_cast<std::size_t>(i)] * factored.directions.col(c);
    LocalGeometry plus, minus;
    for (int k = 0; k < wall.num_parameters(); ++k) {
      const double h = 1e-6;
      Eigen::VectorXd p = p0;
      p[k] += h;
      wall.set_parameters(p);
      wall.Evaluate(t, 0, plus);
      p[k] -= 2 * h;
      wall.set_parameters(p);
      wall.Evaluate(t, 0, minus);
      const Eigen::Vector3d numeric = (To3(plus.point) - To3(minus.point)) / (2 * h);
      EXPECT_NEAR((analytic.col(k) - numeric).norm(), 0.0, 1e-7) << "face " << index << " parameter " << k;
      EXPECT_NEAR((from_factored.col(k) - numeric).norm(), 0.0, 1e-7)
          << "face " << index << " parameter " << k;
      // The other face's parameters do not move this face.
      if ((index == 0) == (k >= wall.offset(RevolutionWall::kInner))) {
        EXPECT_EQ(numeric.norm(), 0.0);
      }
    }
    wall.set_parameters(p0);
  }
}

TEST(RevolutionWall, FeetLieOnTheNearerFace) {
  const RevolutionWall wall(Belly(0.0), Belly(-6.0));
  LocalGeometry g;
  for (int index = 0; index < 2; ++index) {
    for (const double u : {0.2, 0.5, 0.8}) {
      // A point 1 mm off face `index` along its normal, on the side away from the other face: its foot is
      // the face's own point.
      const double v = 0.7;
      wall.face(index).Evaluate({u, v, 0.0}, 1, g);
      Eigen::Vector3d n = To3(g.d1.col(0)).cross(To3(g.d1.col(1))).normalized();
      const Eigen::Vector3d radial(std::cos(v), std::sin(v), 0.0);
      if ((n.dot(radial) > 0) != (index == RevolutionWall::kOuter)) n = -n;
      const Eigen::Vector3d surface = To3(g.point);
      VecS x = surface + 1.0 * n;
      ParamT t{0.0, 0.0, 0.0};
      double distance = 0.0;
      bool on_boundary = true, ambiguous = true;
      ASSERT_TRUE(wall.ClosedFormFoot(x, t, distance, on_boundary, ambiguous));
      EXPECT_EQ(static_cast<int>(t[2]), index);
      EXPECT_NEAR(distance, 1.0, 1e-9);
      EXPECT_NEAR(t[0], u, 1e-8);
      EXPECT_FALSE(on_boundary);
      EXPECT_FALSE(ambiguous);
    }
  }
}

TEST(RevolutionWall, ThicknessOfStraightWallsIsTheirNormalDistance) {
  // Outer and inner cones of slope 0.2, the inner 6 mm further in at every height: the thickness square to
  // the wall is 6 cos(atan 0.2).
  const RevolutionWall wall(Cone(40, 0.2, 100), Cone(34, 0.2, 100));
  for (const double z : {10.0, 50.0, 90.0})
    EXPECT_NEAR(wall.ThicknessAtHeight(z), 6.0 / std::sqrt(1.04), 1e-9) << z;
  // The inner foot: on the inner cone, square across from the outer point (along the normal (1, -0.2)).
  for (const double z : {10.0, 50.0, 90.0}) {
    Eigen::Vector2d foot;
    const double t = wall.ThicknessAtHeight(z, nullptr, &foot);
    const Eigen::Vector2d outer_point(40.0 + 0.2 * z, z);
    EXPECT_NEAR((outer_point - foot).norm(), t, 1e-9) << z;
    EXPECT_NEAR(foot.x(), 34.0 + 0.2 * foot.y(), 1e-9) << z;
    EXPECT_NEAR((outer_point - foot).normalized().dot(Eigen::Vector2d(1.0, -0.2).normalized()), 1.0, 1e-9)
        << z;
  }
  // Cylinders: 6.
  const RevolutionWall cylinders(Cone(40, 0.0, 100), Cone(34, 0.0, 100));
  EXPECT_NEAR(cylinders.ThicknessAtHeight(37.0), 6.0, 1e-9);
  // Where the outer point's nearest inner point is the inner generatrix's end the wall is not closed.
  const RevolutionWall short_inner(Cone(40, 0.0, 100), Cone(34, 0.0, 60));
  EXPECT_THROW(short_inner.ThicknessAtHeight(80.0), std::domain_error);
  EXPECT_THROW(short_inner.ThicknessAtHeight(120.0), std::domain_error);
}

// `measure` (with its gradient when given a vector) against each parameter's central difference (h = 1e-6),
// the wall's parameters restored after each.
void ExpectGradientMatchesCentralDifferences(RevolutionWall& wall,
                                             const std::function<double(Eigen::VectorXd*)>& measure,
                                             const std::string& where) {
  const Eigen::VectorXd p0 = wall.parameters();
  Eigen::VectorXd gradient;
  measure(&gradient);
  ASSERT_EQ(gradient.size(), wall.num_parameters()) << where;
  for (int k = 0; k < wall.num_parameters(); ++k) {
    const double h = 1e-6;
    Eigen::VectorXd p = p0;
    p[k] += h;
    wall.set_parameters(p);
    const double plus = measure(nullptr);
    p[k] -= 2 * h;
    wall.set_parameters(p);
    const double minus = measure(nullptr);
    EXPECT_NEAR(gradient[k], (plus - minus) / (2 * h), 1e-6) << where << ", parameter " << k;
  }
  wall.set_parameters(p0);
}

TEST(RevolutionWall, ThicknessGradientMatchesFiniteDifferences) {
  RevolutionWall wall(Belly(0.0), Belly(-6.0));
  for (const double z : {15.0, 60.0, 100.0})
    ExpectGradientMatchesCentralDifferences(
        wall, [&](Eigen::VectorXd* g) { return wall.ThicknessAtHeight(z, g); },
        "height " + std::to_string(z));
}

// A pot with its base (docs/archaeology.md eq. A21c): the outer generatrix level at height 0 out from the
// axis, the inner at height 6, both then rising as straight walls. From the outer point at a parameter on the
// level part the thickness is the bases' distance, 6, to the inner point straight above it; the gradient
// matches finite differences there and on the wall.
TEST(RevolutionWall, ThicknessAtAnOuterParameterAcrossTheBase) {
  Eigen::Matrix2Xd outer(2, 8), inner(2, 8);
  outer << 0, 12, 24, 36, 40, 40, 40, 40,  //
      0, 0, 0, 0, 10, 40, 70, 100;
  inner << 0, 11, 22, 30, 34, 34, 34, 34,  //
      6, 6, 6, 6, 14, 40, 70, 100;
  RevolutionWall wall(KinematicSurface::Revolution(BSplineBasis::ClampedUniform(4, 8), outer),
                      KinematicSurface::Revolution(BSplineBasis::ClampedUniform(4, 8), inner));
  const BSplineBasis& basis = wall.face(RevolutionWall::kOuter).basis();
  // Within the first of the five spans both generatrices are level (only their first four control points
  // act).
  const double u_base = basis.lo() + 0.05 * (basis.hi() - basis.lo());
  Eigen::Vector2d foot;
  EXPECT_NEAR(wall.ThicknessAtOuterParameter(u_base, nullptr, &foot), 6.0, 1e-9);
  EXPECT_NEAR(foot.x(), wall.face(RevolutionWall::kOuter).ProfilePoint(u_base).x(), 1e-9);
  EXPECT_NEAR(foot.y(), 6.0, 1e-9);
  for (const double u : {u_base, basis.lo() + 0.7 * (basis.hi() - basis.lo())})
    ExpectGradientMatchesCentralDifferences(
        wall, [&](Eigen::VectorXd* g) { return wall.ThicknessAtOuterParameter(u, g); },
        "parameter " + std::to_string(u));
}

TEST(RevolutionWall, VolumesOfCylindersAndTheirGradientsPerFace) {
  const RevolutionWall wall(Cone(40, 0.0, 100), Cone(34, 0.0, 100));
  Eigen::VectorXd outer_gradient, inner_gradient;
  const double outer = wall.EnclosedVolume(RevolutionWall::kOuter, 0.0, 100.0, &outer_gradient);
  const double inner = wall.EnclosedVolume(RevolutionWall::kInner, 0.0, 100.0, &inner_gradient);
  EXPECT_NEAR(outer, M_PI * 40 * 40 * 100, 1e-6);
  EXPECT_NEAR(inner, M_PI * 34 * 34 * 100, 1e-6);
  const int split = wall.offset(RevolutionWall::kInner);
  EXPECT_EQ(outer_gradient.tail(wall.num_parameters() - split).norm(), 0.0);
  EXPECT_EQ(inner_gradient.head(split).norm(), 0.0);
  // dV/dr for a common radial shift of all control points: 2 pi r h.
  double d_outer = 0.0;
  for (int k = 0; k < split; k += 2) d_outer += outer_gradient[k];
  EXPECT_NEAR(d_outer, 2 * M_PI * 40 * 100, 1e-6);
  const std::array<double, 2> common = wall.CommonHeights();
  EXPECT_NEAR(common[0], 0.0, 1e-12);
  EXPECT_NEAR(common[1], 100.0, 1e-12);
}

TEST(RevolutionWall, CopiesKeepTheirOwnFeet) {
  RevolutionWall a(Belly(0.0), Belly(-6.0));
  VecS x(3);
  x << 60.0, 0.0, 50.0;  // outside the outer face near its widest
  ParamT t{0, 0, 0};
  double before = 0, da = 0, db = 0, dc = 0;
  bool boundary = false, ambiguous = false;
  a.ClosedFormFoot(x, t, before, boundary, ambiguous);
  const RevolutionWall b = a;
  const std::unique_ptr<ParametricModel> c = b.Clone();
  Eigen::VectorXd p = a.parameters();
  for (int k = 0; k < a.offset(RevolutionWall::kInner); k += 2) p[k] += 3.0;  // a's outer face 3 mm out
  a.set_parameters(p);
  a.ClosedFormFoot(x, t, da, boundary, ambiguous);
  b.ClosedFormFoot(x, t, db, boundary, ambiguous);
  c->ClosedFormFoot(x, t, dc, boundary, ambiguous);
  EXPECT_EQ(db, before);
  EXPECT_EQ(dc, before);
  EXPECT_GT(std::abs(da - before), 1.0);
}

}  // namespace
}  // namespace s2m

namespace s2m {
namespace {

// The joint fit of both faces to a synthetic vessel scanned inside and out (0.05 mm noise) from starts
// fitted to each face's points in the true axis frame: the thickness at every height within a few times
// its standard uncertainty of the truth's 6 mm and within the noise; the capacity within 3 standard
// uncertainties of the truth.
TEST(RevolutionWallFit, ThicknessAndCapacityOfASyntheticVessel) {
  const double noise = 0.05;
  const WallTruth truth = MakeTwoSurfaceVessel(noise, 6000, 7);
  const Eigen::Matrix3Xd local = truth.cloud.world_T_model.inverse().apply(truth.cloud.points);
  const Eigen::Index outer = truth.cloud.surface_points;
  const int n = 12;
  RevolutionWall wall(InitialRevolution(local.leftCols(outer), n, 4),
                      InitialRevolution(local.rightCols(truth.inner_points), n, 4));
  JointFitOptions options;
  const JointFitResult r = FitJointly(wall, {local}, {RigidMotion()}, options);
  EXPECT_LT(r.residuals.rms, 1.2 * noise);
  ASSERT_EQ(r.shape_covariance.rows(), wall.num_parameters());
  const std::array<double, 2> common = wall.CommonHeights();
  int measured = 0;
  double worst_thickness_error = 0.0, worst_thickness_z = 0.0;
  for (int i = 1; i < 10; ++i) {
    const double z = common[0] + (common[1] - common[0]) * i / 10.0;
    Eigen::VectorXd gradient;
    double thickness = 0.0;
    try {
      thickness = wall.ThicknessAtHeight(z, &gradient);
    } catch (const std::domain_error&) {
      continue;
    }
    ++measured;
    const double u = std::sqrt(gradient.dot(r.shape_covariance * gradient));
    EXPECT_NEAR(thickness, truth.thickness, noise) << "height " << z;
    worst_thickness_error = std::max(worst_thickness_error, std::abs(thickness - truth.thickness));
    worst_thickness_z = std::max(worst_thickness_z, std::abs(thickness - truth.thickness) / u);
    EXPECT_LT(std::abs(thickness - truth.thickness), 4 * u) << "height " << z << " u " << u;
  }
  EXPECT_GE(measured, 8);
  // The capacity between the truth's planes (the inner surface's end heights) placed in the fit's frame
  // (the truth's up to the gauge: a shift along the axis, a turn about it): within 3 standard uncertainties
  // of the shape and 0.05 %.
  auto model_height = [&](double z) {
    return (r.model_T_scan[0].rotation() * Eigen::Vector3d(0, 0, z) + r.model_T_scan[0].translation()).z();
  };
  Eigen::VectorXd gradient;
  const double capacity = wall.EnclosedVolume(RevolutionWall::kInner, model_height(truth.inner_lo),
                                              model_height(truth.inner_hi), &gradient);
  const double u = std::sqrt(gradient.dot(r.shape_covariance * gradient));
  EXPECT_LT(std::abs(capacity - truth.capacity), 3 * u)
      << capacity << " truth " << truth.capacity << " u " << u;
  EXPECT_LT(std::abs(capacity - truth.capacity), 5e-4 * truth.capacity);
  std::cout << "capacity " << capacity << " (truth " << truth.capacity << ", u " << u
            << "); thickness error up to " << worst_thickness_error << " (" << worst_thickness_z << " u)\n";
}

}  // namespace
}  // namespace s2m
