// The model-free noise estimate (fitting/noise_estimate.h) on continuous noise and on layered data: a depth
// camera quantizes depth into steps, so the eight nearest neighbours of a point often lie in one layer and
// their quadric fits them exactly (docs/method.md section 17, "Layered data"). The reference in every case is
// the RMS orthogonal distance of the points from the true surface: the RMS a perfect model leaves.

#include "fitting/noise_estimate.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "acquisition/depth_frame.h"
#include "test_paths.h"

namespace s2m {
namespace {

// A plane through (0, 0, 1) with normal `normal`, seen by a pinhole camera at the origin looking along +z
// (640 x 480 rays, 1.5 mrad apart): depth z along each ray plus Gaussian noise `sigma_z`, then rounded to
// steps of `step` (0: no rounding). Returns the points and the RMS orthogonal distance from the plane.
struct PlaneView {
  ScanSet set;
  double true_rms = 0.0;
};

PlaneView ViewOfAPlane(const Eigen::Vector3d& normal, double sigma_z, double step, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, sigma_z);
  const Eigen::Vector3d n = normal.normalized(), on_plane(0, 0, 1);
  Scan scan;
  scan.points.resize(3, 640 * 480);
  Eigen::Index count = 0;
  double sum_squares = 0.0;
  for (int v = 0; v < 480; ++v) {
    for (int u = 0; u < 640; ++u) {
      const Eigen::Vector3d ray((u - 319.5) * 1.5e-3, (v - 239.5) * 1.5e-3, 1.0);
      const double t = n.dot(on_plane) / n.dot(ray);  // ray . z = 1, so t is the depth
      double z = t + gauss(rng);
      if (step > 0) z = step * std::round(z / step);
      const Eigen::Vector3d p = ray * z;
      scan.points.col(count++) = p;
      const double d = n.dot(p - on_plane);
      sum_squares += d * d;
    }
  }
  PlaneView out;
  out.true_rms = std::sqrt(sum_squares / static_cast<double>(count));
  out.set.scans.push_back(std::move(scan));
  return out;
}

TEST(NoiseEstimate, ContinuousNoiseIsEstimatedFromEightNeighbours) {
  const PlaneView view = ViewOfAPlane(Eigen::Vector3d(0.3, -0.5, 1.0), 1e-3, 0.0, 1);
  const NoiseEstimate e = EstimateNoiseWithDof(view.set);
  std::printf("[ continuous ] true RMS %.6f, estimate %.6f, exact fraction %.3f\n", view.true_rms, e.sigma,
              e.exact_fraction);
  EXPECT_FALSE(e.layered);
  EXPECT_EQ(e.neighbours, 8);
  EXPECT_EQ(e.exact_fraction, 0.0);
  // About 500 neighbourhoods with 2 degrees of freedom each: the median's relative standard error in sigma is
  // about 1 / sqrt(2 nu) with nu = 0.96 m (eq. 68), 3 %; 15 % is five of them.
  EXPECT_NEAR(e.sigma / view.true_rms, 1.0, 0.15);
}

// Depth rounded to 2 mm steps at about 1 m (a depth camera's steps there are 1-3 mm) with 0.2 mm noise
// before the rounding: most eight-point neighbourhoods lie in one layer, and the eight-point median is zero.
TEST(NoiseEstimate, DepthLayersAreRecognizedAndSpanned) {
  const double step = 2e-3;
  for (const Eigen::Vector3d& normal : {Eigen::Vector3d(0.3, -0.5, 1.0), Eigen::Vector3d(0.05, 0.1, 1.0)}) {
    const PlaneView view = ViewOfAPlane(normal, 2e-4, step, 2);
    const NoiseEstimate e = EstimateNoiseWithDof(view.set);
    std::printf(
        "[ layered ] normal (%.2f %.2f %.2f): true RMS %.6f (step / sqrt(12) = %.6f), estimate %.6f "
        "from %d neighbours, exact fraction %.3f\n",
        normal.x(), normal.y(), normal.z(), view.true_rms, step / std::sqrt(12.0), e.sigma, e.neighbours,
        e.exact_fraction);
    EXPECT_TRUE(e.layered);
    EXPECT_EQ(e.neighbours, 40);
    EXPECT_GT(e.exact_fraction, 0.05);
    // Rounding errors are not independent between neighbouring rays (they follow the layers' pattern), so
    // the quadric absorbs part of them: the estimate is within a third of the true RMS, never near zero.
    EXPECT_GT(e.sigma, view.true_rms / 1.5);
    EXPECT_LT(e.sigma, view.true_rms * 1.5);
  }
}

// A real Kinect frame (OpenNI, depth in whole millimetres over disparity steps of 1/8 pixel): 59 % of the
// eight-point quadrics fit exactly and their median was 1e-18 m before layered data were recognized. The
// frame spans 0.67-1.71 m, where a Kinect's depth step (z^2 / 8 / (f b), f = 525 px, b = 75 mm) is 1.4-9.3
// mm, i.e. a rounding RMS of 0.4-2.7 mm.
TEST(NoiseEstimate, RealKinectFrameIsLayered) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  ScanSet set;
  set.scans.push_back(
      ReadDepthFrame(test::SharedData("pcl_kinect_frames/frame_20121214T142255.814212_depth.tiff")));
  const NoiseEstimate e = EstimateNoiseWithDof(set);
  std::printf("[ kinect ] estimate %.6f m from %d neighbours (%d neighbourhoods), exact fraction %.3f\n",
              e.sigma, e.neighbours, e.neighbourhoods, e.exact_fraction);
  EXPECT_TRUE(e.layered);
  EXPECT_GT(e.sigma, 0.3e-3);
  EXPECT_LT(e.sigma, 3e-3);
}

}  // namespace
}  // namespace s2m
