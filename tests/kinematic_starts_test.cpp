// Global starts for kinematic surfaces (fitting/kinematic_starts.h, docs/method.md section 19): a pitch and a
// growth far from what the normals say, and sherds (small arcs of a surface of revolution, with and without
// points on their fracture faces), each fitted from scratch as `scan2model fit` does, and compared with the
// truth; the old start (normals' pitch or growth searched +-20 %, the best cylinder's axis) is run on the
// same data for the record.

#include "fitting/kinematic_starts.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "fitting/initial_models.h"
#include "fitting/kinematic_surfaces.h"
#include "fitting/primitive_fit.h"
#include "fitting/primitives.h"
#include "registration/scan_to_scan.h"
#include "synthetic/synthetic_cases.h"

namespace s2m {
namespace {

constexpr double kDegree = M_PI / 180.0;

struct AxisError {
  double angle_deg = 0.0;
  double distance = 0.0;  // of the true axis point at the data's mean height from the fitted line
};

AxisError Compare(const KinematicCloud& c, const Eigen::Vector3d& point, const Eigen::Vector3d& direction) {
  const Eigen::Vector3d d = direction.normalized(), t = c.axis_direction.normalized();
  const Eigen::Vector3d centroid = c.points.leftCols(c.surface_points).rowwise().mean();
  const Eigen::Vector3d true_point = c.axis_point + t * t.dot(centroid - c.axis_point);
  const Eigen::Vector3d offset = true_point - point;
  return {std::acos(std::min(1.0, std::abs(d.dot(t)))) / kDegree, (offset - d * d.dot(offset)).norm()};
}

JointFitOptions SingleCloudOptions() {
  JointFitOptions o;  // as pipeline/views.cpp: TDM, per-view motions from the start
  o.error_term = ErrorTerm::kTdm;
  o.shared_motion_iterations = 0;
  // These fits reach the noise in 10-25 iterations and then creep along the generatrix's re-parametrization
  // (docs/method.md sections 12 and 19) to the cap of 100 per pass; 60 per pass keeps the test's time in
  // bounds without changing the measured quantities beyond their uncertainty (the command's own cap is
  // exercised in tests/cli_test.cpp).
  o.optimizer.max_iterations = 60;
  return o;
}

struct Fitted {
  std::shared_ptr<ParametricModel> model;
  RigidMotion world_T_model_fit;
  JointFitResult result;
};

// The new path: starts, then the joint fit from the best few.
Fitted FitWithStarts(const KinematicCloud& c, KinematicKind kind, const KinematicStartOptions& options = {}) {
  const Eigen::Matrix3Xd normals = EstimateNormals(c.points, 12);
  const std::vector<KinematicStart> starts = FindKinematicStarts(c.points, normals, kind, options);
  const StartedJointFit fit =
      FitJointlyFromStarts(starts, {c.points}, {RigidMotion()}, {normals}, SingleCloudOptions());
  std::printf("    %zu starts (", starts.size());
  for (const KinematicStart& s : starts)
    std::printf(" %s %.4g score %.4g;", s.source.c_str(), s.searched_value, s.score);
  std::printf(" ) chose %zu, %lld points left out, RMS %.4f, %d iterations\n", fit.chosen,
              static_cast<long long>(fit.left_out), fit.result.residuals.rms, fit.result.iterations);
  return {fit.model, fit.result.model_T_scan[0].inverse(), fit.result};
}

// The old path: the normals' value searched +-20 % (helical, spiral) or the best cylinder (revolution).
Fitted FitWithOldStart(const KinematicCloud& c, KinematicKind kind, double estimate = 0.0) {
  RigidMotion world_T_model;
  std::shared_ptr<ParametricModel> model;
  if (kind == KinematicKind::kRevolution) {
    const Cylinder cyl = FitCylinder(c.points).shape;
    world_T_model = RigidMotion(FrameWithAxis(cyl.axis_direction), cyl.axis_point);
    model =
        std::make_shared<KinematicSurface>(InitialRevolution(world_T_model.inverse().apply(c.points), 8, 4));
  } else {
    KinematicAxis axis = KinematicAxisFromNormals(c.points, EstimateNormals(c.points, 12), kind);
    if (axis.growth < 0) {
      axis.growth = -axis.growth;
      axis.direction = -axis.direction;
    }
    if (estimate != 0.0) (kind == KinematicKind::kHelical ? axis.pitch : axis.growth) = estimate;
    world_T_model = RigidMotion(FrameWithAxis(axis.direction), axis.point);
    const Eigen::Matrix3Xd local = world_T_model.inverse().apply(c.points);
    if (kind == KinematicKind::kHelical)
      model = std::make_shared<KinematicSurface>(InitialHelicalWithPitchSearch(local, axis.pitch, 8, 4));
    else
      model = std::make_shared<SpiralSurface>(InitialSpiralWithGrowthSearch(local, axis.growth, 8, 4));
  }
  const JointFitResult r = FitJointly(*model, {c.points}, {world_T_model.inverse()}, SingleCloudOptions());
  return {model, r.model_T_scan[0].inverse(), r};
}

double ParameterUncertainty(const ParametricModel& m, const JointFitResult& r, const std::string& name) {
  for (int i = 0; i < m.num_parameters(); ++i)
    if (m.parameter_name(i) == name && i < r.shape_uncertainty.size()) return r.shape_uncertainty[i];
  return std::nan("");
}

TEST(KinematicStarts, PitchOfAShallowThreadFarFromTheNormals) {
  const KinematicCloud c = ShallowThreadCloud(0.1, 0.02, 3000, 5);
  const KinematicAxis normals_axis =
      KinematicAxisFromNormals(c.points, EstimateNormals(c.points, 12), KinematicKind::kHelical);
  std::printf("  normals' pitch %.4f (truth %.1f, factor %.2f)\n", normals_axis.pitch, c.pitch,
              c.pitch / normals_axis.pitch);
  const Fitted old_fit = FitWithOldStart(c, KinematicKind::kHelical);
  const auto& old_model = dynamic_cast<const KinematicSurface&>(*old_fit.model);
  std::printf("  old start: pitch %.5f, RMS %.4f\n", old_model.pitch(), old_fit.result.residuals.rms);
  const Fitted fit = FitWithStarts(c, KinematicKind::kHelical);
  const auto& model = dynamic_cast<const KinematicSurface&>(*fit.model);
  const double u = ParameterUncertainty(model, fit.result, "pitch");
  const AxisError e =
      Compare(c, fit.world_T_model_fit.translation(), fit.world_T_model_fit.rotation().col(2));
  std::printf("  new start: pitch %.6f +- %.2g (error %.2f u), axis %.4f deg, %.4f mm, RMS %.4f\n",
              model.pitch(), u, (model.pitch() - c.pitch) / u, e.angle_deg, e.distance,
              fit.result.residuals.rms);
  // The case is made for the normals to be far off (issue 22: a factor 3-10).
  EXPECT_GT(std::abs(c.pitch / normals_axis.pitch), 3.0);
  EXPECT_LT(std::abs(model.pitch() - c.pitch), 3 * u);
  EXPECT_GT(std::abs(old_model.pitch() - c.pitch), 10 * u);  // the +-20 % search stays near the normals'
}

// On the conical shell the normals find the growth (measured: -0.0489 about the opposite direction, i.e.
// 0.0489 for the truth 0.05; a shallower ripple did not bring them off by a factor 3 while the fit could
// still determine the growth). The far estimate is therefore given: a factor 5 below the truth, as a nominal
// value or an earlier stage would hand it over.
TEST(KinematicStarts, GrowthOfAConicalShellFromAFarEstimate) {
  const KinematicCloud c = ConicalShellCloud(0.3, 0.02, 4000, 7);
  const double estimate = c.growth / 5;
  const Fitted old_fit = FitWithOldStart(c, KinematicKind::kSpiral, estimate);
  const auto& old_model = dynamic_cast<const SpiralSurface&>(*old_fit.model);
  const double old_u = ParameterUncertainty(old_model, old_fit.result, "growth");
  std::printf("  old start from %.3f: growth %.5f +- %.2g (error %.1f u), RMS %.4f\n", estimate,
              old_model.growth(), old_u, (old_model.growth() - c.growth) / old_u,
              old_fit.result.residuals.rms);
  KinematicStartOptions options;
  options.estimate = estimate;
  const Fitted fit = FitWithStarts(c, KinematicKind::kSpiral, options);
  const auto& model = dynamic_cast<const SpiralSurface&>(*fit.model);
  const double u = ParameterUncertainty(model, fit.result, "growth");
  const AxisError e =
      Compare(c, fit.world_T_model_fit.translation(), fit.world_T_model_fit.rotation().col(2));
  std::printf(
      "  new start: growth %.6f +- %.2g (error %.2f u), axis %.4f deg, centre %.4f mm off the axis, "
      "RMS %.4f\n",
      model.growth(), u, (model.growth() - c.growth) / u, e.angle_deg, e.distance, fit.result.residuals.rms);
  EXPECT_LT(std::abs(model.growth() - c.growth), 3 * u);
  // The +-20 % search cannot reach it.
  EXPECT_GT(std::abs(old_model.growth() - c.growth), 10 * old_u);
}

TEST(KinematicStarts, AxisOfSherds) {
  for (const double fraction : {0.15, 0.25, 0.40}) {
    for (const bool breaks : {false, true}) {
      const KinematicCloud c = SherdCloud(fraction, breaks, 0.05, 8000, 11);
      std::printf("  %.0f %% arc, %s: %lld points (%lld on breaks)\n", 100 * fraction,
                  breaks ? "with fracture faces" : "surface only", static_cast<long long>(c.points.cols()),
                  static_cast<long long>(c.points.cols() - c.surface_points));
      const Fitted old_fit = FitWithOldStart(c, KinematicKind::kRevolution);
      const AxisError old_e =
          Compare(c, old_fit.world_T_model_fit.translation(), old_fit.world_T_model_fit.rotation().col(2));
      std::printf("    old start: axis %.3f deg, %.3f mm, RMS %.4f\n", old_e.angle_deg, old_e.distance,
                  old_fit.result.residuals.rms);
      const Fitted fit = FitWithStarts(c, KinematicKind::kRevolution);
      const AxisError e =
          Compare(c, fit.world_T_model_fit.translation(), fit.world_T_model_fit.rotation().col(2));
      std::printf("    new start: axis %.4f deg, %.4f mm, RMS %.4f\n", e.angle_deg, e.distance,
                  fit.result.residuals.rms);
      // Issue 22's tolerances.
      EXPECT_LT(e.angle_deg, 0.5) << fraction << (breaks ? " with breaks" : "");
      EXPECT_LT(e.distance, 0.3) << fraction << (breaks ? " with breaks" : "");
      // The best cylinder's axis failed there (measured: 87-89 degrees off at 15 %; 2-6 mm off with the
      // breaks' points at 25 and 40 %).
      if (fraction < 0.2 || breaks) {
        EXPECT_TRUE(old_e.angle_deg > 0.5 || old_e.distance > 0.3) << fraction;
      }
    }
  }
}

// eq. (77a): the normal limit reads the angles as Rayleigh distributed and puts its tail at the distance
// test's two-sided normal tail. Drawn from a known scale, the limit is that scale times the constant, within
// the sampling error of a median (relative standard deviation 0.72 / sqrt(N) for a Rayleigh sample:
// 1 / (2 f(m) sqrt N) with f(m) = sqrt(2 ln 2) / (2 s) at the median m = s sqrt(2 ln 2)).
TEST(OffSurface, NormalLimitIsTheRayleighTailAtTheDistanceTestsTail) {
  OffSurfaceTest test;
  test.angle_from_spread = true;
  const double factor = std::sqrt(-2.0 * std::log(std::erfc(test.distance_in_sigma / std::sqrt(2.0))));
  EXPECT_NEAR(factor, 5.06, 0.005);  // the figure docs/method.md states
  std::mt19937 rng(77);
  std::normal_distribution<double> normal(0.0, 1.0);
  const int n = 20000;
  for (const double scale_deg : {1.5, 3.0, 6.0}) {
    std::vector<double> angles(n);
    for (double& a : angles)
      a = std::hypot(normal(rng), normal(rng)) * scale_deg * kDegree;  // Rayleigh of that scale
    const double limit = NormalAngleLimitDeg(angles, test);
    EXPECT_NEAR(limit / (factor * scale_deg), 1.0, 4 * 0.72 / std::sqrt(static_cast<double>(n))) << scale_deg;
  }
  // Clamped to the range; the maximum without enough points or with the spread switched off.
  EXPECT_EQ(NormalAngleLimitDeg(std::vector<double>(100, 0.1 * kDegree), test), test.min_angle_deg);
  EXPECT_EQ(NormalAngleLimitDeg(std::vector<double>(100, 20 * kDegree), test), test.max_angle_deg);
  EXPECT_EQ(NormalAngleLimitDeg(std::vector<double>(test.min_points_for_spread - 1, 1 * kDegree), test),
            test.max_angle_deg);
  OffSurfaceTest fixed = test;
  fixed.angle_from_spread = false;
  EXPECT_EQ(NormalAngleLimitDeg(std::vector<double>(100, 1 * kDegree), fixed), fixed.max_angle_deg);
  OffSurfaceTest bad = test;
  bad.min_angle_deg = 50;
  std::string why;
  EXPECT_FALSE(bad.IsValid(&why));
  EXPECT_FALSE(why.empty());
}

// A cylinder's points whose normals err by 1.5 degrees (Rayleigh), and 2 % of them along a crease whose
// normals lean 20 degrees towards the axis' direction (a break's face mixed into the plane fits): the limit
// from the spread (about 7.6 degrees) leaves the crease out and keeps the surface; the fixed 45 degrees
// keeps both.
TEST(OffSurface, CreasePointsWithinFortyFiveDegreesAreLeftOutByTheSpread) {
  std::mt19937 rng(78);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const int n = 5000, crease = 100;
  const double radius = 50, noise = 0.02, spread = 1.5 * kDegree;
  Eigen::Matrix3Xd points(3, n), normals(3, n);
  for (int j = 0; j < n; ++j) {
    const double v = 1.2 * uniform(rng), z = -20 + 40 * uniform(rng);
    const Eigen::Vector3d radial(std::cos(v), std::sin(v), 0), along(-std::sin(v), std::cos(v), 0);
    points.col(j) = (radius + noise * normal(rng)) * radial + Eigen::Vector3d(0, 0, z);
    const double tilt = j < crease ? 20 * kDegree : 0.0;
    normals.col(j) = (std::cos(tilt) * radial + std::sin(tilt) * Eigen::Vector3d::UnitZ() +
                      spread * (normal(rng) * along + normal(rng) * Eigen::Vector3d::UnitZ()))
                         .normalized();
  }
  const KinematicSurface cylinder = InitialRevolution(points, 6, 4);
  const auto count = [&](const std::vector<bool>& off, int from, int to) {
    return std::count(off.begin() + from, off.begin() + to, true);
  };
  OffSurfaceTest from_spread;
  from_spread.angle_from_spread = true;
  double limit = 0;
  const std::vector<bool> off =
      PointsOffTheSurface(cylinder, points, normals, from_spread, nullptr, nullptr, &limit);
  std::printf("    limit %.2f degrees; off: crease %ld of %d, surface %ld of %d\n", limit,
              static_cast<long>(count(off, 0, crease)), crease, static_cast<long>(count(off, crease, n)),
              n - crease);
  EXPECT_NEAR(limit, 5.06 * 1.5, 0.5);
  EXPECT_EQ(count(off, 0, crease), crease);
  // A surface point is left out by the normal test with probability exp(-(limit/scale)^2 / 2), about 3e-6,
  // and by the distance test about as rarely: none of 4900 expected; allow a few for the fitted start.
  EXPECT_LE(count(off, crease, n), 5);
  const OffSurfaceTest fixed;  // the default: 45 degrees
  const std::vector<bool> off_fixed =
      PointsOffTheSurface(cylinder, points, normals, fixed, nullptr, nullptr, &limit);
  EXPECT_EQ(limit, 45.0);
  EXPECT_EQ(count(off_fixed, 0, crease), 0);
  // Without normals only the distance test runs.
  const std::vector<bool> off_distance = PointsOffTheSurface(cylinder, points, Eigen::Matrix3Xd(), {});
  EXPECT_LE(count(off_distance, 0, n), 5);
}

}  // namespace
}  // namespace s2m
