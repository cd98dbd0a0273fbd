// Robust losses in the joint fit and in the registration to a model (fitting/robust_loss.h; docs/method.md
// section 15): gross outliers uniform in each view's bounding box, the scale of the loss estimated from the
// data (MAD of the normal distances). A robust loss recovers the poses to within the accuracy the clean data
// allow; plain least squares is pulled off by the outliers.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "fitting/bspline_models.h"
#include "fitting/foot_point.h"
#include "fitting/joint_fit.h"
#include "fitting/model_registration.h"
#include "fitting/robust_loss.h"
#include "synthetic/synthetic_cases.h"

namespace s2m {
namespace {

// `fraction` x n extra points uniform in the scan's bounding box (its own coordinates), appended.
Eigen::Matrix3Xd WithOutliers(const Eigen::Matrix3Xd& scan, double fraction, std::uint64_t seed) {
  const Eigen::Vector3d lo = scan.rowwise().minCoeff(), hi = scan.rowwise().maxCoeff();
  const auto extra = static_cast<Eigen::Index>(std::round(fraction * static_cast<double>(scan.cols())));
  Eigen::Matrix3Xd out(3, scan.cols() + extra);
  out.leftCols(scan.cols()) = scan;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (Eigen::Index j = 0; j < extra; ++j) {
    for (int c = 0; c < 3; ++c) out(c, scan.cols() + j) = lo[c] + u(rng) * (hi[c] - lo[c]);
  }
  return out;
}

struct PoseErrors {
  double rotation = 0.0;     // largest over the scans, radians
  double translation = 0.0;  // largest over the scans, model units
};

PoseErrors LargestPoseErrors(const ParametricModel& fitted, const JointFitResult& r,
                             const std::vector<RigidMotion>& truth) {
  PoseErrors e;
  for (Motion6 m : ObservablePoseErrors(fitted, r.model_T_scan, truth)) {
    m = m.unaryExpr([](double v) { return std::isnan(v) ? 0.0 : v; });  // NaN: a gauge component
    e.rotation = std::max(e.rotation, m.head<3>().norm());
    e.translation = std::max(e.translation, m.tail<3>().norm());
  }
  return e;
}

TEST(RobustJointFit, VaseWithTenPercentOutliersPerViewRecoversThePoses) {
  const SyntheticCase c = MakeSyntheticCase("vase");
  const std::vector<RigidMotion>& truth = c.views.model_T_scan_true;
  // The clean fit: its pose errors and reported uncertainties are the noise-limited accuracy.
  auto clean_model = c.start->Clone();
  const JointFitResult clean =
      FitJointly(*clean_model, c.views.scans, c.views.model_T_scan_recorded, c.options);
  const PoseErrors clean_error = LargestPoseErrors(*clean_model, clean, truth);
  double rotation_sigma = 0.0, translation_sigma = 0.0;
  for (const ScanPoseUncertainty& u : clean.pose_uncertainty) {
    rotation_sigma = std::max(rotation_sigma, u.rotation.norm());
    translation_sigma = std::max(translation_sigma, u.translation.norm());
  }
  ASSERT_TRUE(std::isfinite(rotation_sigma) && std::isfinite(translation_sigma));
  std::vector<Eigen::Matrix3Xd> scans;
  for (std::size_t k = 0; k < c.views.scans.size(); ++k)
    scans.push_back(WithOutliers(c.views.scans[k], 0.1, 40 + k));
  std::printf("clean: rotation %.3e rad, translation %.3e (sigma %.3e rad, %.3e)\n", clean_error.rotation,
              clean_error.translation, rotation_sigma, translation_sigma);

  PoseErrors plain_error;
  for (const char* loss : {"none", "tukey", "cauchy"}) {
    auto model = c.start->Clone();
    JointFitOptions o = c.options;
    o.optimizer.loss = ParseRobustLoss(loss);
    const JointFitResult r = FitJointly(*model, scans, c.views.model_T_scan_recorded, o);
    const PoseErrors e = LargestPoseErrors(*model, r, truth);
    std::printf("%s: rotation %.3e rad, translation %.3e, loss scale %.4f, %d iterations (%s)\n", loss,
                e.rotation, e.translation, r.loss_scale, r.iterations, ToString(r.stop_reason));
    if (std::string(loss) == "none") {
      plain_error = e;
      EXPECT_EQ(r.loss_scale, 0.0);
      continue;
    }
    // The scale comes from the inliers' spread: a few noise sigmas, far below the outliers' distances.
    EXPECT_GT(r.loss_scale, 0.0) << loss;
    EXPECT_LT(r.loss_scale, 20.0 * c.noise) << loss;
    EXPECT_LT(e.rotation, 3.0 * (clean_error.rotation + rotation_sigma)) << loss;
    EXPECT_LT(e.translation, 3.0 * (clean_error.translation + translation_sigma)) << loss;
    // Plain least squares on the same data is worse by far.
    EXPECT_GT(plain_error.rotation + plain_error.translation / 100.0,
              3.0 * (e.rotation + e.translation / 100.0))
        << loss;
  }
}

TEST(RobustRegistration, PatchWithOutliersRecoversThePose) {
  const BSplineSurface patch = BumpyPatch(0.03);
  // 3000 points on the inner part of the patch, 0.02 mm Gaussian noise along z, 10 % gross outliers.
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u(0.1, 0.9);
  std::normal_distribution<double> noise(0.0, 0.02);
  const ParameterDomain d = patch.domain();
  Eigen::Matrix3Xd on_model(3, 3000);
  LocalGeometry g;
  for (Eigen::Index j = 0; j < on_model.cols(); ++j) {
    patch.Evaluate({d.lo[0] + u(rng) * (d.hi[0] - d.lo[0]), d.lo[1] + u(rng) * (d.hi[1] - d.lo[1]), 0.0}, 0,
                   g);
    on_model.col(j) = To3(g.point) + Eigen::Vector3d(0.0, 0.0, noise(rng));
  }
  const RigidMotion truth(RotationAboutAxis(Eigen::Vector3d(1, 2, 3).normalized(), 0.4),
                          Eigen::Vector3d(30, -10, 5));
  const Eigen::Matrix3Xd scan = WithOutliers(truth.inverse().apply(on_model), 0.1, 3);
  const RigidMotion start =
      RigidMotion(RotationAboutAxis(Eigen::Vector3d(-1, 1, 2).normalized(), 2 * M_PI / 180),
                  Eigen::Vector3d(1.0, -0.8, 0.6)) *
      truth;
  double error[2] = {0.0, 0.0};
  for (int robust = 0; robust < 2; ++robust) {
    ModelRegistrationOptions o;
    o.optimizer.loss = ParseRobustLoss(robust ? "tukey" : "none");
    const ModelRegistrationResult r = RegisterToModel(patch, scan, start, o);
    // The inliers' displacement from their true place.
    error[robust] =
        (r.model_T_scan.apply(scan.leftCols(on_model.cols())) - on_model.leftCols(on_model.cols()))
            .colwise()
            .norm()
            .maxCoeff();
    std::printf("%s: largest inlier displacement %.4e mm, loss scale %.4f, %d iterations\n",
                robust ? "tukey" : "none", error[robust], r.loss_scale, r.iterations);
    if (robust) {
      EXPECT_GT(r.loss_scale, 0.0);
      EXPECT_LT(r.loss_scale, 0.5);
    }
  }
  // Noise 0.02 mm over 3000 points: the pose is determined to a few micrometres.
  EXPECT_LT(error[1], 0.02);
  EXPECT_GT(error[0], 5.0 * error[1]);
}

}  // namespace
}  // namespace s2m
