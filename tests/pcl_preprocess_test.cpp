// Preprocessing with PCL: on a real Kinect frame (crop box and voxel grid checked against counts computed
// here independently), and on synthetic planes where the truth is known (outliers injected, normals'
// orientation).

#include "acquisition/pcl_preprocess.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <set>
#include <stdexcept>
#include <tuple>

#include "acquisition/depth_frame.h"
#include "test_paths.h"

namespace s2m {
namespace {

// Single-precision round trip inside PCL (coordinates shifted by the mean, so errors are relative to the
// extent).
constexpr double kFloatSlack = 1e-6;

bool InBox(const Eigen::Vector3d& p, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, double slack) {
  return (p.array() >= lo.array() - slack).all() && (p.array() <= hi.array() + slack).all();
}

Eigen::Index Total(const PreprocessResult& r) {
  return r.points.cols() + r.removed_by_crop + r.removed_by_voxel + r.removed_as_outliers +
         r.removed_without_normal;
}

TEST(PclPreprocess, KinectFrameCropAndVoxelGrid) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  const Scan frame =
      ReadDepthFrame(test::SharedData("pcl_kinect_frames/frame_20121214T142255.814212_depth.tiff"));
  PreprocessOptions options;
  options.crop = true;
  options.crop_min = Eigen::Vector3d(-0.4, -0.3, 0.6);
  options.crop_max = Eigen::Vector3d(0.4, 0.3, 1.2);
  options.voxel_size = 0.01;
  const PreprocessResult r = Preprocess(frame.points, Eigen::Vector3d::Zero(), options);

  // The crop, counted here.
  Eigen::Index inside = 0;
  std::set<std::tuple<long, long, long>> cells;
  for (Eigen::Index i = 0; i < frame.points.cols(); ++i) {
    const Eigen::Vector3d p = frame.points.col(i);
    if (!InBox(p, options.crop_min, options.crop_max, 0.0)) continue;
    ++inside;
    const Eigen::Vector3d c = (p / options.voxel_size).array().floor();
    cells.emplace(static_cast<long>(c.x()), static_cast<long>(c.y()), static_cast<long>(c.z()));
  }
  EXPECT_EQ(r.input, frame.points.cols());
  EXPECT_EQ(r.removed_by_crop, frame.points.cols() - inside);
  EXPECT_GT(r.removed_by_crop, 0);
  EXPECT_GT(inside, 10000);
  // Down-sampling: far fewer points, about one per occupied 1 cm cell. PCL's grid is anchored on the shifted
  // coordinates, ours here on the origin, so the two partitions differ slightly.
  EXPECT_EQ(r.removed_by_voxel, inside - r.points.cols());
  EXPECT_LT(r.points.cols(), inside / 5);
  EXPECT_NEAR(static_cast<double>(r.points.cols()), static_cast<double>(cells.size()),
              0.05 * static_cast<double>(cells.size()));
  for (Eigen::Index i = 0; i < r.points.cols(); ++i)
    ASSERT_TRUE(InBox(r.points.col(i), options.crop_min, options.crop_max, kFloatSlack))
        << r.points.col(i).transpose();
  EXPECT_EQ(r.normals.cols(), 0);
  EXPECT_EQ(Total(r), r.input);
  std::printf(
      "Kinect frame: %ld points, crop removed %ld, voxel grid (1 cm) removed %ld -> %ld (%zu cells counted "
      "here)\n",
      static_cast<long>(r.input), static_cast<long>(r.removed_by_crop), static_cast<long>(r.removed_by_voxel),
      static_cast<long>(r.points.cols()), cells.size());

  // All four steps on the real frame: counts add up, normals face the camera.
  options.voxel_size = 0.005;
  options.remove_outliers = true;
  options.estimate_normals = true;
  const PreprocessResult all = Preprocess(frame.points, Eigen::Vector3d::Zero(), options);
  EXPECT_EQ(Total(all), all.input);
  EXPECT_GT(all.removed_as_outliers, 0);
  // A one-sided mean + 1 sd threshold: about 16 % of a normal distribution lies above it; a real frame's
  // neighbour distances are skewed (edges, flying pixels), and about 10 % go.
  EXPECT_LT(all.removed_as_outliers, inside / 5);
  ASSERT_EQ(all.normals.cols(), all.points.cols());
  for (Eigen::Index i = 0; i < all.points.cols(); ++i) {
    ASSERT_NEAR(all.normals.col(i).norm(), 1.0, 1e-6);
    ASSERT_GE(all.normals.col(i).dot(-all.points.col(i)), 0.0);
  }
  std::printf(
      "Kinect frame, all steps: crop %ld, outliers %ld, voxel grid (5 mm) %ld, no normal %ld -> %ld\n",
      static_cast<long>(all.removed_by_crop), static_cast<long>(all.removed_as_outliers),
      static_cast<long>(all.removed_by_voxel), static_cast<long>(all.removed_without_normal),
      static_cast<long>(all.points.cols()));
}

TEST(PclPreprocess, OutlierRemovalOnAKinectFrameWithInjectedFlyingPoints) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  const Scan frame =
      ReadDepthFrame(test::SharedData("pcl_kinect_frames/frame_20121214T142256.068683_depth.tiff"));
  // Every real return is farther than 0.6 m (the frame's nearest is 0.67 m); 300 injected points float
  // between the camera and the scene, 0.2 to 0.5 m away, spread over the field of view.
  ASSERT_GT(frame.points.row(2).minCoeff(), 0.6);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> depth(0.2, 0.5), slope(-0.5, 0.5);
  Eigen::Matrix3Xd points(3, frame.points.cols() + 300);
  points.leftCols(frame.points.cols()) = frame.points;
  for (Eigen::Index i = frame.points.cols(); i < points.cols(); ++i) {
    const double z = depth(rng);
    points.col(i) = Eigen::Vector3d(slope(rng) * z, slope(rng) * z, z);
  }
  PreprocessOptions options;
  options.remove_outliers = true;
  // 3 sd rather than PCL's tutorial 1 sd: at 1 sd about a tenth of a real frame goes (its edges and depth
  // discontinuities), which is a different question from whether isolated flying points are caught.
  options.outlier_stddev = 3.0;
  const PreprocessResult r = Preprocess(points, Eigen::Vector3d::Zero(), options);
  const Eigen::Index injected_left = (r.points.row(2).array() < 0.55).count();
  const Eigen::Index real_kept = r.points.cols() - injected_left;
  EXPECT_EQ(injected_left, 0);
  EXPECT_GT(static_cast<double>(real_kept), 0.95 * static_cast<double>(frame.points.cols()));
  std::printf(
      "Kinect frame + 300 flying points, SOR (k 50, 3 sd): %ld injected left, %ld of %ld real kept (%.2f "
      "%%)\n",
      static_cast<long>(injected_left), static_cast<long>(real_kept), static_cast<long>(frame.points.cols()),
      100.0 * static_cast<double>(real_kept) / static_cast<double>(frame.points.cols()));
}

// A noisy plane through `centre` with unit normal `normal`, n x n samples `spacing` apart.
Eigen::Matrix3Xd Plane(const Eigen::Vector3d& centre, const Eigen::Vector3d& normal, int n, double spacing,
                       double noise, std::mt19937& rng) {
  const Eigen::Vector3d a = normal.unitOrthogonal(), b = normal.cross(a);
  std::normal_distribution<double> gauss(0.0, noise);
  Eigen::Matrix3Xd p(3, n * n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      p.col(i * n + j) = centre + ((i - n / 2) * a + (j - n / 2) * b) * spacing + gauss(rng) * normal;
  return p;
}

TEST(PclPreprocess, OutlierRemovalDropsInjectedFarPointsAndKeepsTheSurface) {
  std::mt19937 rng(11);
  const Eigen::Matrix3Xd plane =
      Plane(Eigen::Vector3d(0, 0, 1), Eigen::Vector3d::UnitZ(), 100, 0.005, 0.001, rng);
  // Flying pixels: 100 points 0.2 to 0.6 m off the surface (about 40 to 120 sample spacings).
  std::uniform_real_distribution<double> xy(-0.25, 0.25), off(0.2, 0.6);
  Eigen::Matrix3Xd all(3, plane.cols() + 100);
  all.leftCols(plane.cols()) = plane;
  for (Eigen::Index i = plane.cols(); i < all.cols(); ++i)
    all.col(i) = Eigen::Vector3d(xy(rng), xy(rng), 1.0 + (i % 2 ? 1 : -1) * off(rng));

  PreprocessOptions options;
  options.remove_outliers = true;
  const PreprocessResult r = Preprocess(all, Eigen::Vector3d::Zero(), options);
  Eigen::Index far = 0;
  for (Eigen::Index i = 0; i < r.points.cols(); ++i) far += std::abs(r.points(2, i) - 1.0) > 0.05;
  EXPECT_EQ(far, 0) << "injected outliers survived";
  const Eigen::Index inliers_kept = r.points.cols() - far;
  EXPECT_GT(inliers_kept, 0.95 * static_cast<double>(plane.cols()));
  EXPECT_EQ(r.removed_as_outliers, all.cols() - r.points.cols());
  std::printf("SOR (k 50, 1 sd): removed %ld of 10000 plane + 100 outliers; kept %ld inliers (%.2f %%)\n",
              static_cast<long>(r.removed_as_outliers), static_cast<long>(inliers_kept),
              100.0 * static_cast<double>(inliers_kept) / static_cast<double>(plane.cols()));
}

TEST(PclPreprocess, NormalsOfAPlaneFaceTheSensor) {
  std::mt19937 rng(5);
  const Eigen::Vector3d true_normal = Eigen::Vector3d(0.3, -0.2, 1.0).normalized();
  const Eigen::Vector3d centre(0.1, 0.05, 1.5);
  const Eigen::Matrix3Xd plane = Plane(centre, true_normal, 60, 0.01, 0.0005, rng);
  PreprocessOptions options;
  options.estimate_normals = true;
  // Sensors on either side of the plane: the normals must flip with them.
  for (const Eigen::Vector3d& sensor : {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0.2, 0, 3.0)}) {
    SCOPED_TRACE(sensor.transpose());
    const double side = (sensor - centre).dot(true_normal) > 0 ? 1.0 : -1.0;
    const PreprocessResult r = Preprocess(plane, sensor, options);
    ASSERT_EQ(r.points.cols(), plane.cols());
    ASSERT_EQ(r.normals.cols(), plane.cols());
    EXPECT_EQ(r.removed_without_normal, 0);
    double worst = 1.0;
    for (Eigen::Index i = 0; i < r.points.cols(); ++i) {
      ASSERT_GT(r.normals.col(i).dot(sensor - r.points.col(i)), 0.0);
      worst = std::min(worst, side * r.normals.col(i).dot(true_normal));
    }
    EXPECT_GT(worst, 0.99);
  }
}

TEST(PclPreprocess, BadInputIsRejected) {
  const Eigen::Matrix3Xd points = Eigen::Matrix3Xd::Random(3, 100);
  const Eigen::Vector3d sensor = Eigen::Vector3d::Zero();
  EXPECT_THROW(Preprocess(Eigen::Matrix3Xd(3, 0), sensor, {}), std::invalid_argument);
  Eigen::Matrix3Xd nan = points;
  nan(1, 7) = std::nan("");
  EXPECT_THROW(Preprocess(nan, sensor, {}), std::invalid_argument);
  PreprocessOptions inverted;
  inverted.crop = true;
  inverted.crop_min.x() = 2.0;
  EXPECT_THROW(Preprocess(points, sensor, inverted), std::invalid_argument);
  PreprocessOptions tiny;
  tiny.voxel_size = 1e-7;
  EXPECT_THROW(Preprocess(points, sensor, tiny), std::invalid_argument);
  PreprocessOptions negative;
  negative.voxel_size = -0.1;
  EXPECT_THROW(Preprocess(points, sensor, negative), std::invalid_argument);
  PreprocessOptions sor;
  sor.remove_outliers = true;
  sor.outlier_neighbours = 0;
  EXPECT_THROW(Preprocess(points, sensor, sor), std::invalid_argument);
  PreprocessOptions normals;
  normals.estimate_normals = true;
  normals.normal_neighbours = 2;
  EXPECT_THROW(Preprocess(points, sensor, normals), std::invalid_argument);
  // Nothing enabled: the input unchanged; a crop that keeps nothing: an empty result, counted.
  const PreprocessResult same = Preprocess(points, sensor, {});
  EXPECT_EQ(same.points, points);
  PreprocessOptions away;
  away.crop = true;
  away.crop_min = Eigen::Vector3d::Constant(5);
  away.crop_max = Eigen::Vector3d::Constant(6);
  const PreprocessResult none = Preprocess(points, sensor, away);
  EXPECT_EQ(none.points.cols(), 0);
  EXPECT_EQ(none.removed_by_crop, 100);
}

}  // namespace
}  // namespace s2m
