// Scan-to-scan registration on real data: the ten Stanford bunny range scans.

#include "registration/scan_to_scan.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "acquisition/scan_set_io.h"
#include "test_paths.h"

namespace s2m {
namespace {

TEST(ScanToScan, NormalsOfAPlaneAreItsNormal) {
  Eigen::Matrix3Xd p(3, 400);
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 20; ++j) p.col(i * 20 + j) << i * 0.1, j * 0.1, 0.3 * i * 0.1 - 0.2 * j * 0.1;
  const Eigen::Matrix3Xd n = EstimateNormals(p, 8);
  const Eigen::Vector3d truth = Eigen::Vector3d(-0.3, 0.2, 1.0).normalized();
  for (Eigen::Index i = 0; i < n.cols(); ++i) EXPECT_NEAR(std::abs(n.col(i).dot(truth)), 1.0, 1e-12);
}

TEST(ScanToScan, BunnyViewsPerturbedByTwoDegreesAndTwoMillimetresAreRecovered) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  const ScanSet set = ReadScanSet(test::SharedData("stanford_bunny_scans/bun.conf"));
  std::vector<Eigen::Matrix3Xd> scans;
  std::vector<RigidMotion> reference, start;
  std::mt19937_64 rng(42);
  std::normal_distribution<double> gauss(0.0, 1.0);
  for (const Scan& s : set.scans) {
    scans.push_back(s.points);
    reference.push_back(s.world_T_scan);
    // 2 degrees about a random axis through the view's centroid, and 2 mm in a random direction.
    const Eigen::Vector3d axis = Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
    const Eigen::Vector3d shift = Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized() * 0.002;
    const Eigen::Vector3d centroid = s.world_T_scan * Eigen::Vector3d(s.points.rowwise().mean());
    const Eigen::Matrix3d rotation = RotationAboutAxis(axis, 2.0 * M_PI / 180.0);
    const RigidMotion perturbation(rotation, centroid - rotation * centroid + shift);
    start.push_back(perturbation * s.world_T_scan);
  }
  const ScanToScanResult r = RegisterScansToEachOther(scans, start);
  EXPECT_TRUE(r.converged) << r.sweeps << " sweeps";
  // Compare relative to view 0, which the registration holds fixed (the views are determined only relative to
  // each other): pose errors at each view's centroid.
  double worst_angle = 0, worst_shift = 0;
  for (std::size_t k = 1; k < scans.size(); ++k) {
    const RigidMotion fit = r.world_T_scan[0].inverse() * r.world_T_scan[k];
    const RigidMotion ref = reference[0].inverse() * reference[k];
    const RigidMotion error = fit * ref.inverse();
    const Eigen::Vector3d centroid = ref * Eigen::Vector3d(scans[k].rowwise().mean());
    worst_angle = std::max(worst_angle, error.angle() * 180.0 / M_PI);
    worst_shift = std::max(worst_shift, (error * centroid - centroid).norm());
  }
  std::printf("bunny: worst view error %.3f deg, %.3f mm after %d sweeps (RMS %.3f mm)\n", worst_angle,
              worst_shift * 1e3, r.sweeps, r.rms_per_sweep.back() * 1e3);
  EXPECT_LT(worst_angle, 0.5);
  EXPECT_LT(worst_shift, 0.001);
}

}  // namespace
}  // namespace s2m
