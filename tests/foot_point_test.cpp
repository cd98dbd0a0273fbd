// The fast paths of the foot-point driver (issue 7's performance push, fitting/foot_point.h): a trusted warm
// start goes straight to Newton from the previous parameter and must land on the cold foot; the one-call
// closed-form feet (ParametricModel::ClosedFormFoot) must agree with the separate calls they replace; the
// model registration's fused foot-point and assembly pass must still converge to the true pose.

#include "fitting/foot_point.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "fitting/bspline_models.h"
#include "fitting/initial_models.h"
#include "fitting/kinematic_surfaces.h"
#include "fitting/model_registration.h"
#include "fitting/part_model.h"
#include "fitting/primitive_models.h"
#include "synthetic/synthetic_cases.h"
#include "test_models.h"

namespace s2m {
namespace {

// Points over the inner part of a model's domain with Gaussian noise of standard deviation `noise`.
Eigen::Matrix3Xd PointsNear(const ParametricModel& model, int count, double noise, std::uint64_t seed) {
  return test::PointsOverInnerDomain(model, count, 0.1, 0.9, std::normal_distribution<double>(0.0, noise),
                                     seed);
}

// The points moved by a small rigid motion (0.2 degree, 0.05 % of the size): the next iteration's points.
Eigen::Matrix3Xd Moved(const Eigen::Matrix3Xd& p) {
  const RigidMotion m(RotationAboutAxis(Eigen::Vector3d(1, -2, 0.5).normalized(), 0.2 * M_PI / 180),
                      Eigen::Vector3d(0.03, -0.02, 0.01));
  return m.apply(p);
}

void ExpectWarmEqualsCold(const ParametricModel& model, const Eigen::Matrix3Xd& points, WarmStart mode) {
  std::vector<FootPoint> previous, warm, cold;
  ComputeFootPoints(model, points, previous);
  const Eigen::Matrix3Xd moved = Moved(points);
  ComputeFootPoints(model, moved, cold);
  ComputeFootPoints(model, moved, warm, &previous, mode);
  ASSERT_EQ(warm.size(), cold.size());
  const double size = (points.rowwise().maxCoeff() - points.rowwise().minCoeff()).norm();
  LocalGeometry gw, gc;
  for (std::size_t j = 0; j < warm.size(); ++j) {
    ASSERT_NEAR(warm[j].distance, cold[j].distance, 1e-12) << "point " << j;
    model.Evaluate(warm[j].t, 0, gw);
    model.Evaluate(cold[j].t, 0, gc);
    // The distance is stationary at the foot: the foot's position is settled only to about the square root
    // of the rounding of the distance (1e-10 to 1e-9 of the size here), by cold and warm Newton alike.
    ASSERT_LE((gw.point - gc.point).norm(), 1e-8 * size) << "point " << j;
    ASSERT_EQ(warm[j].on_boundary, cold[j].on_boundary) << "point " << j;
  }
}

TEST(FootPointFastPaths, WarmStartedFeetEqualColdFeetOnABSplineSurface) {
  const BSplineSurface patch = BumpyPatch(0.0);
  for (const WarmStart mode : {WarmStart::kTrusted, WarmStart::kVerified})
    ExpectWarmEqualsCold(patch, PointsNear(patch, 2000, 0.05, 1), mode);
}

TEST(FootPointFastPaths, WarmStartedFeetEqualColdFeetOnASurfaceOfRevolution) {
  const SyntheticCase c = MakeSyntheticCase("vase");
  Eigen::Matrix3Xd points = c.views.model_T_scan_true[0].apply(c.views.scans[0]);
  points.conservativeResize(3, std::min<Eigen::Index>(points.cols(), 2000));
  for (const WarmStart mode : {WarmStart::kTrusted, WarmStart::kVerified})
    ExpectWarmEqualsCold(*c.truth, points, mode);
}

// Newton handed the model's geometry at its start (RefineFootPoint's g_at_t0, as the model registration does
// from the previous pass) skips one evaluation and must return exactly the same foot.
TEST(FootPointFastPaths, NewtonFromAKnownGeometryReturnsTheSameFoot) {
  const BSplineSurface patch = BumpyPatch(0.0);
  const Eigen::Matrix3Xd points = PointsNear(patch, 500, 0.05, 11);
  std::vector<FootPoint> previous;
  ComputeFootPoints(patch, points, previous);
  const Eigen::Matrix3Xd moved = Moved(points);
  const ParameterDomain d = patch.domain();
  LocalGeometry g_plain, g_known;
  for (Eigen::Index j = 0; j < moved.cols(); ++j) {
    const ParamT t0 = previous[static_cast<std::size_t>(j)].t;
    const FootPoint plain = RefineFootPoint(patch, d, VecS(moved.col(j)), t0, g_plain);
    patch.Evaluate(t0, 2, g_known);
    const FootPoint known = RefineFootPoint(patch, d, VecS(moved.col(j)), t0, g_known, true);
    ASSERT_EQ(plain.t, known.t) << "point " << j;
    ASSERT_EQ(plain.distance, known.distance) << "point " << j;
    ASSERT_EQ(g_plain.point, g_known.point) << "point " << j;
    // And g is the geometry at the returned foot.
    LocalGeometry at_foot;
    patch.Evaluate(known.t, 2, at_foot);
    ASSERT_EQ(at_foot.point, g_known.point) << "point " << j;
    ASSERT_EQ(at_foot.d2, g_known.d2) << "point " << j;
  }
}

// An open arc (a 'C' of radius 10 from 20 to 340 degrees) and a point in its gap nearer the 340-degree end:
// Newton from the 20-degree end stops there (the distance grows inwards), a local minimum on the boundary.
// The warm start must fall back to the nearest sample and find the nearer end, as the cold search does.
TEST(FootPointFastPaths, WarmStartStuckOnABoundaryFallsBackToTheNearestSample) {
  const int n = 12;
  Eigen::MatrixXd control(2, n);
  for (int i = 0; i < n; ++i) {
    const double a = (20.0 + 320.0 * i / (n - 1)) * M_PI / 180;
    control.col(i) << 10 * std::cos(a), 10 * std::sin(a);
  }
  const BSplineCurve arc(UnitSpacedClamped(4, n), control);
  const ParameterDomain d = arc.domain();
  Eigen::MatrixXd x(2, 1);
  x << 12.0, -1.0;
  std::vector<FootPoint> cold, warm;
  ComputeFootPoints(arc, x, cold);
  ASSERT_EQ(cold.size(), 1u);
  EXPECT_DOUBLE_EQ(cold[0].t[0], d.hi[0]);  // the 340-degree end
  EXPECT_TRUE(cold[0].on_boundary);
  std::vector<FootPoint> stuck{cold[0]};
  stuck[0].t[0] = d.lo[0];  // the previous foot at the far end
  ComputeFootPoints(arc, x, warm, &stuck, WarmStart::kTrusted);
  EXPECT_DOUBLE_EQ(warm[0].t[0], d.hi[0]);
  EXPECT_NEAR(warm[0].distance, cold[0].distance, 1e-12);
  // Newton alone from there does stay at the far end, farther away.
  LocalGeometry g;
  const FootPoint far = RefineFootPoint(arc, d, VecS(x.col(0)), stuck[0].t, g);
  EXPECT_DOUBLE_EQ(far.t[0], d.lo[0]);
  EXPECT_GT(far.distance, cold[0].distance + 1.0);
}

// The one-call closed-form feet against ClosedFormFootPoint + Evaluate + FootPointOnBoundary +
// AmbiguousFootPoint (the base class's composition).
int ExpectClosedFormFootAgrees(const ParametricModel& model, const Eigen::Matrix3Xd& points) {
  LocalGeometry g;
  int ambiguous_count = 0;
  for (Eigen::Index j = 0; j < points.cols(); ++j) {
    const VecS x = points.col(j);
    ParamT t_fast{}, t_ref{};
    double distance = -1.0;
    bool on_boundary = true, ambiguous = true;
    EXPECT_TRUE(model.ClosedFormFoot(x, t_fast, distance, on_boundary, ambiguous));
    EXPECT_TRUE(model.ClosedFormFootPoint(x, t_ref));
    for (int k = 0; k < 3; ++k) EXPECT_EQ(t_fast[k], t_ref[k]) << "point " << j;
    model.Evaluate(t_ref, 0, g);
    EXPECT_NEAR(distance, (g.point - x).norm(), 1e-12 * (1.0 + x.norm())) << "point " << j;
    EXPECT_EQ(on_boundary, model.FootPointOnBoundary(x, t_ref)) << "point " << j;
    EXPECT_EQ(ambiguous, model.AmbiguousFootPoint(x, t_ref)) << "point " << j;
    if (::testing::Test::HasFailure()) return -1;
    ambiguous_count += ambiguous ? 1 : 0;
  }
  return ambiguous_count;
}

Eigen::Matrix3Xd RandomPoints(int count, double extent, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-extent, extent);
  Eigen::Matrix3Xd p(3, count);
  for (int j = 0; j < count; ++j) p.col(j) << u(rng), u(rng), u(rng);
  return p;
}

TEST(FootPointFastPaths, ClosedFormFootOfPrimitivesAgreesWithTheSeparateCalls) {
  const Eigen::Matrix3d frame =
      RotationAboutAxis(Eigen::Vector3d(0.3, -0.2, 1).normalized(), 0.7) * Eigen::Matrix3d::Identity();
  ExpectClosedFormFootAgrees(
      CylinderModel(Cylinder{Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(0.2, 0.3, 1).normalized(), 20.0}),
      RandomPoints(500, 40, 2));
  ExpectClosedFormFootAgrees(SphereModel(Sphere{Eigen::Vector3d(1, 2, 3), 25.0}, frame),
                             RandomPoints(500, 40, 3));
  // A negative radius (a fit may pass through one): the foot is on the opposite side of the axis.
  ExpectClosedFormFootAgrees(
      CylinderModel(Cylinder{Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(0.2, 0.3, 1).normalized(), -5.0}),
      RandomPoints(200, 40, 4));
  ExpectClosedFormFootAgrees(SphereModel(Sphere{Eigen::Vector3d(1, 2, 3), -5.0}), RandomPoints(200, 40, 5));
}

TEST(FootPointFastPaths, ClosedFormFootOfAPartAgreesWithTheSeparateCalls) {
  const SyntheticCase c = MakeSyntheticCase("part");
  auto model = c.truth->Clone();
  auto* part = dynamic_cast<PartModel*>(model.get());
  ASSERT_NE(part, nullptr);
  Eigen::Matrix3Xd points = c.views.model_T_scan_true[0].apply(c.views.scans[0]);
  points.conservativeResize(3, std::min<Eigen::Index>(points.cols(), 1500));
  EXPECT_EQ(ExpectClosedFormFootAgrees(*part, points), 0);  // no edge margin: nothing is ambiguous
  part->set_edge_margin(0.5);                               // wide: points near edges are ambiguous
  EXPECT_GT(ExpectClosedFormFootAgrees(*part, points), 0);
}

// The fused pass (feet and normal equations together, warm feet): from a 3-degree, 2-unit start on the
// bumpy patch, the noise-free scan's pose is recovered to rounding level.
TEST(FootPointFastPaths, ModelRegistrationWithFusedPassRecoversThePose) {
  const BSplineSurface patch = BumpyPatch(0.0);
  const Eigen::Matrix3Xd on_model = PointsNear(patch, 3000, 0.0, 9);
  const auto [truth, start] = test::ThreeDegreeRegistrationPoses();
  const Eigen::Matrix3Xd scan = truth.inverse().apply(on_model);
  for (const ErrorTerm term : {ErrorTerm::kSdm, ErrorTerm::kTdm}) {
    ModelRegistrationOptions o;
    o.error_term = term;
    o.rotation_tolerance = 1e-10;
    o.translation_tolerance = 1e-10;
    const ModelRegistrationResult r = RegisterToModel(patch, scan, start, o);
    const Eigen::Matrix3Xd placed = r.model_T_scan.apply(scan);
    EXPECT_LT((placed - on_model).colwise().norm().maxCoeff(), 1e-7) << ToString(term);
    EXPECT_LT(r.residuals.rms, 1e-7) << ToString(term);
    EXPECT_LE(r.iterations, 10) << ToString(term);
  }
}

// A helical surface whose generatrix spans 1.3 leads (as a fitted thread's can: its sheets overlap where one
// turn's end runs past the next turn's start). Plain Newton from the nearest sample pins some points on the
// end of one turn although they lie on the next; the continuation across that seam (docs/method.md eq. 30a,
// KinematicSurface::ContinuationSeed) finds every point at its noise.
TEST(FootPointFastPaths, HelicalFeetContinueAcrossTheGeneratrixSeam) {
  const double pitch = 4.0, lead = 2 * M_PI * pitch;
  const int m = 16;
  Eigen::Matrix2Xd profile(2, m);
  for (int k = 0; k < m; ++k) {
    const double z = -0.65 * lead + 1.3 * lead * k / (m - 1);
    profile.col(k) << 28.0 + 0.15 * std::cos(2 * M_PI * z / lead), z;
  }
  const KinematicSurface helix = KinematicSurface::Helical(UnitSpacedClamped(4, m), profile, pitch, 3.5);
  const double noise = 0.02;
  const Eigen::Matrix3Xd points = test::PointsOverInnerDomain(
      helix, 3000, 0.0, 1.0, std::normal_distribution<double>(0.0, noise / std::sqrt(3.0)), 7);
  // Plain Newton from the nearest of the model's samples (what the driver did before the continuation).
  const std::vector<ParamT> samples = helix.SampleParameters();
  const ParameterDomain domain = helix.domain();
  LocalGeometry g;
  std::vector<Eigen::Vector3d> sample_points;
  for (const ParamT& t : samples) {
    helix.Evaluate(t, 0, g);
    sample_points.push_back(To3(g.point));
  }
  int pinned = 0;
  for (Eigen::Index j = 0; j < points.cols(); ++j) {
    std::size_t nearest = 0;
    for (std::size_t i = 1; i < samples.size(); ++i)
      if ((sample_points[i] - points.col(j)).squaredNorm() <
          (sample_points[nearest] - points.col(j)).squaredNorm())
        nearest = i;
    const FootPoint plain = RefineFootPoint(helix, domain, points.col(j), samples[nearest], g);
    pinned += plain.on_boundary && plain.distance > 5 * noise;
  }
  std::vector<FootPoint> feet;
  ComputeFootPoints(helix, points, feet);
  double largest = 0.0;
  for (const FootPoint& f : feet) largest = std::max(largest, f.distance);
  std::printf(
      "[ seam     ] plain Newton pins %d of %ld points on a turn's end beyond 5 sigma; with the continuation "
      "the largest distance is %.4f\n",
      pinned, static_cast<long>(points.cols()), largest);
  EXPECT_GT(pinned, 0);  // the construction exercises the seam
  EXPECT_LT(largest, 5 * noise);
}

}  // namespace
}  // namespace s2m
