// Global starts for kinematic surfaces (fitting/kinematic_starts.h, docs/method.md section 19): a pitch and a
// growth far from what the normals say, and sherds (small arcs of a surface of revolution, with and without
// points on their fracture faces), each fitted from scratch as `scan2model fit` does, and compared with the
// truth; the old start (normals' pitch or growth searched +-20 %, the best cylinder's axis) is run on the
// same data for the record.

#include "fitting/kinematic_starts.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>

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

}  // namespace
}  // namespace s2m
