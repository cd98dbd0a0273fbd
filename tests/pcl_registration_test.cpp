// PCL at the edge: PCL's own ICP test on its bun0/bun4 pair reproduced with PCL and compared with our
// registration maths, and coarse alignment (FPFH + prerejective RANSAC) of real Stanford bunny views moved by
// large motions, refined by our scan-to-scan registration.

#include "acquisition/pcl_registration.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "acquisition/point_cloud_io.h"
#include "acquisition/scan_set_io.h"
#include "registration/nearest_index.h"
#include "registration/rigid_step.h"
#include "registration/scan_to_scan.h"
#include "test_paths.h"

namespace s2m {
namespace {

constexpr double kDeg = M_PI / 180.0;

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

// How far two poses are apart: the angle of a b^-1 and the distance between a(p) and b(p) at a point p of the
// data (a translation alone depends on where the origin happens to be).
struct PoseDifference {
  double angle = 0, shift = 0;
};
PoseDifference Compare(const RigidMotion& a, const RigidMotion& b, const Eigen::Vector3d& at) {
  return {(a * b.inverse()).angle(), (a * at - b * at).norm()};
}

double MedianNearestDistance(const Eigen::Matrix3Xd& from, const Eigen::Matrix3Xd& to) {
  const NearestIndex index(to);
  std::vector<double> d;
  for (Eigen::Index i = 0; i < from.cols(); ++i)
    d.push_back((to.col(index.Nearest(from.col(i))) - from.col(i)).norm());
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

// Median distance from each point to its nearest other point of the same cloud.
double MedianSpacing(const Eigen::Matrix3Xd& points) {
  const NearestIndex index(points);
  std::vector<double> d;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const std::vector<Eigen::Index> nn = index.KNearest(points.col(i), 2);  // itself and its neighbour
    d.push_back((points.col(nn[1]) - points.col(i)).norm());
  }
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

// ---------------------------------------------------------------------------------------------------------
// 1. PCL's registration test (PointCloudLibrary/pcl, test/registration/test_registration.cpp,
// TEST(PCL, IterativeClosestPoint)): bun0 (source) aligned to bun4 (target) by pcl::IterativeClosestPoint,
// 50 iterations, transformation epsilon 1e-8, maximum correspondence distance 0.05, identity start.

struct PclPair {
  Eigen::Matrix3Xd bun0, bun4;
};
PclPair ReadPclPair() {
  return {ReadPointCloud(test::SharedData("pcl_bunny_small/bun0.pcd")).points,
          ReadPointCloud(test::SharedData("pcl_bunny_small/bun4.pcd")).points};
}

TEST(PclRegistration, OurPcdReaderAgreesWithPcls) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  const PclPair ours = ReadPclPair();
  const Eigen::Matrix3Xd bun0 = ReadPcdPointsWithPcl(test::SharedData("pcl_bunny_small/bun0.pcd"));
  const Eigen::Matrix3Xd bun4 = ReadPcdPointsWithPcl(test::SharedData("pcl_bunny_small/bun4.pcd"));
  ASSERT_EQ(bun0.cols(), 397);
  ASSERT_EQ(bun4.cols(), 361);
  ASSERT_EQ(ours.bun0.cols(), bun0.cols());
  ASSERT_EQ(ours.bun4.cols(), bun4.cols());
  // PCL parses into float, we into double: equal to float rounding (|coordinates| < 0.2, so half an ulp of
  // 0.2 bounds the difference).
  const double half_ulp = 0.5 * 0.2 * std::numeric_limits<float>::epsilon();
  EXPECT_LE((bun0 - ours.bun0).cwiseAbs().maxCoeff(), half_ulp);
  EXPECT_LE((bun4 - ours.bun4).cwiseAbs().maxCoeff(), half_ulp);
  EXPECT_THROW(ReadPcdPointsWithPcl(test::SharedData("pcl_bunny_small/missing.pcd")), std::runtime_error);
}

TEST(PclRegistration, PclIcpReproducesPclsOwnBun0Bun4Test) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  const PclPair pair = ReadPclPair();
  const auto start = std::chrono::steady_clock::now();
  const PclIcpResult r =
      PclIterativeClosestPoint(pair.bun0, pair.bun4);  // PCL's test's settings are the defaults
  const double seconds = Seconds(start);
  const Eigen::Matrix4d m = r.target_T_source.matrix();
  // PCL's expected matrix, from its test (the checks are commented out there; PCL 1.13 still meets them).
  Eigen::Matrix<double, 3, 4> expected;
  expected << 0.8806, 0.036481287330389023, -0.4724, 0.03453,  //
      -0.02354, 0.9992, 0.03326, -0.001519,                    //
      0.4732, -0.01817, 0.8808, 0.04116;
  std::printf("PCL ICP: %d iterations (stopped by %s), fitness %.3e, %.4f s; max |PCL - expected| = %.2e\n",
              r.iterations, r.stop_reason.c_str(), r.fitness_score, seconds,
              (m.topRows<3>() - expected).cwiseAbs().maxCoeff());
  for (int i = 0; i < 3; ++i) std::printf("  %9.5f %9.5f %9.5f %9.5f\n", m(i, 0), m(i, 1), m(i, 2), m(i, 3));
  EXPECT_TRUE(r.converged);
  // PCL's tolerance is 1e-3 (1e-2 for entry (0,1)); 1e-3 throughout here.
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 4; ++j)
      EXPECT_NEAR(m(i, j), expected(i, j), 1e-3) << "entry (" << i << "," << j << ")";
  EXPECT_EQ(m.row(3), Eigen::RowVector4d(0, 0, 0, 1));
}

// Point-to-point ICP (Besl & McKay 1992) from our pieces: nearest neighbours from NearestIndex, the
// linearized rigid step with M = I (rigid_step.h, PDM), exact helical updates, in double precision. Same
// pairing rule as PCL's test; runs until the step vanishes.
RigidMotion OurPointToPointIcp(const Eigen::Matrix3Xd& source, const Eigen::Matrix3Xd& target,
                               double max_distance, RigidMotion pose, int* iterations) {
  const NearestIndex index(target);
  *iterations = 0;
  for (int it = 0; it < 1000; ++it) {
    RigidNormalEquations eq;
    for (Eigen::Index i = 0; i < source.cols(); ++i) {
      const Eigen::Vector3d x = pose * Eigen::Vector3d(source.col(i));
      const Eigen::Vector3d t = target.col(index.Nearest(x));
      if ((x - t).norm() > max_distance) continue;
      eq.Add({x, t, Eigen::Matrix3d::Identity(), 1.0});
    }
    const Eigen::Matrix<double, 6, 1> v = SolveRigidVelocity(eq);
    const RigidMotion step = RigidMotion::FromHelicalVelocity(v.head<3>(), v.tail<3>());
    pose = step * pose;
    pose.normalize();
    *iterations = it + 1;
    if (step.angle() < 1e-12 && step.translation().norm() < 1e-12) break;
  }
  return pose;
}

TEST(PclRegistration, OurPointToPointIcpReachesPclsFixedPoint) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  const PclPair pair = ReadPclPair();
  // PCL run to its own end (no transformation epsilon): a fixed point of its iteration.
  PclIcpOptions to_the_end;
  to_the_end.max_iterations = 1000;
  to_the_end.transformation_epsilon = 0.0;
  const PclIcpResult pcl = PclIterativeClosestPoint(pair.bun0, pair.bun4, to_the_end);
  const Eigen::Vector3d centroid = pcl.target_T_source * Eigen::Vector3d(pair.bun0.rowwise().mean());

  // Started there, our double-precision ICP stays put to PCL's single precision: the same fixed point.
  int iterations = 0;
  const RigidMotion from_pcl =
      OurPointToPointIcp(pair.bun0, pair.bun4, 0.05, pcl.target_T_source, &iterations);
  const PoseDifference stay = Compare(from_pcl, pcl.target_T_source, centroid);
  std::printf(
      "PCL to its end: %d iterations (%s); ours started there moves %.2e deg, %.2e mm in %d iterations\n",
      pcl.iterations, pcl.stop_reason.c_str(), stay.angle / kDeg, stay.shift * 1e3, iterations);
  // 1 micrometre is about a hundred float ulps of these coordinates (< 0.2), and the angle that moves a point
  // at 0.1 (the cloud's size) by as much.
  EXPECT_LT(stay.shift, 1e-6);
  EXPECT_LT(stay.angle, 1e-5);

  // From the identity, as PCL's test starts, the two iterations take different paths (SVD versus linearized
  // steps) and end on neighbouring fixed points: the pairings differ by a few points, so the poses differ by
  // a small fraction of the point spacing.
  const RigidMotion ours =
      OurPointToPointIcp(pair.bun0, pair.bun4, 0.05, RigidMotion::Identity(), &iterations);
  const PoseDifference apart = Compare(ours, pcl.target_T_source, centroid);
  const double spacing = MedianSpacing(pair.bun4);
  const double radius =
      std::sqrt((pair.bun0.colwise() - pair.bun0.rowwise().mean()).colwise().squaredNorm().mean());
  std::printf(
      "from the identity: ours %d iterations, %.4f deg and %.4f mm from PCL's (point spacing %.2f mm)\n",
      iterations, apart.angle / kDeg, apart.shift * 1e3, spacing * 1e3);
  EXPECT_LT(apart.shift, 0.1 * spacing);
  EXPECT_LT(apart.angle, 0.1 * spacing / radius);
}

TEST(PclRegistration, OurPointToPlaneOnBun0Bun4IsCloserToTheStanfordReferenceThanPclsIcp) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  const PclPair pair = ReadPclPair();
  // bun0 and bun4 are resamplings of the Stanford range scans bun000 and bun045 in those scans' own
  // coordinates (checked here), so bun.conf gives an independent reference for the motion bun4_T_bun0.
  const ScanSet set = ReadScanSet(test::SharedData("stanford_bunny_scans/bun.conf"));
  ASSERT_GE(set.scans.size(), 2u);
  ASSERT_EQ(set.scans[0].metadata.source.rfind("bun000", 0), 0u);
  ASSERT_EQ(set.scans[1].metadata.source.rfind("bun045", 0), 0u);
  const double off0 = MedianNearestDistance(pair.bun0, set.scans[0].points);
  const double off4 = MedianNearestDistance(pair.bun4, set.scans[1].points);
  std::printf("median distance bun0 -> bun000 %.2f mm, bun4 -> bun045 %.2f mm\n", off0 * 1e3, off4 * 1e3);
  ASSERT_LT(off0, 0.001);
  ASSERT_LT(off4, 0.001);
  const RigidMotion reference = set.scans[1].world_T_scan.inverse() * set.scans[0].world_T_scan;
  const Eigen::Vector3d centroid = reference * Eigen::Vector3d(pair.bun0.rowwise().mean());

  const PclIcpResult pcl = PclIterativeClosestPoint(pair.bun0, pair.bun4);
  const auto start = std::chrono::steady_clock::now();
  // Our point-to-plane registration (scan_to_scan.h) from the same identity start, bun4 held fixed.
  const ScanToScanResult ours =
      RegisterScansToEachOther({pair.bun4, pair.bun0}, {RigidMotion::Identity(), RigidMotion::Identity()});
  const double seconds = Seconds(start);
  const PoseDifference d_pcl = Compare(pcl.target_T_source, reference, centroid);
  const PoseDifference d_ours = Compare(ours.world_T_scan[1], reference, centroid);
  const PoseDifference d_between = Compare(ours.world_T_scan[1], pcl.target_T_source, centroid);
  std::printf(
      "reference motion %.2f deg; PCL point-to-point ICP %.3f deg, %.3f mm from it; our point-to-plane %.3f "
      "deg, "
      "%.3f mm from it (%d sweeps, RMS %.3f mm, %.3f s); ours vs PCL %.3f deg, %.3f mm\n",
      reference.angle() / kDeg, d_pcl.angle / kDeg, d_pcl.shift * 1e3, d_ours.angle / kDeg,
      d_ours.shift * 1e3, ours.sweeps, ours.rms_per_sweep.back() * 1e3, seconds, d_between.angle / kDeg,
      d_between.shift * 1e3);
  EXPECT_TRUE(ours.converged);
  EXPECT_LT(d_ours.angle, 0.5 * kDeg);
  EXPECT_LT(d_ours.shift, 0.001);
  EXPECT_LT(d_ours.angle, d_pcl.angle);
  EXPECT_LT(d_ours.shift, d_pcl.shift);
}

// ---------------------------------------------------------------------------------------------------------
// 2. Coarse alignment without poses.

TEST(PclRegistration, RejectsEmptyAndNonFiniteInput) {
  // A wavy sheet: enough structure for normals and features, so every throw below is about the bad input.
  Eigen::Matrix3Xd good(3, 900);
  for (int i = 0; i < 30; ++i)
    for (int j = 0; j < 30; ++j) {
      const double x = i / 29.0, y = j / 29.0;
      good.col(30 * i + j) << x, y, 0.1 * std::sin(3 * x) * std::cos(2 * y);
    }
  EXPECT_NO_THROW(CoarseAlign(good, good));
  Eigen::Matrix3Xd bad = good;
  bad(1, 7) = std::numeric_limits<double>::quiet_NaN();
  const Eigen::Matrix3Xd empty(3, 0);
  EXPECT_THROW(CoarseAlign(empty, good), std::invalid_argument);
  EXPECT_THROW(CoarseAlign(good, bad), std::invalid_argument);
  EXPECT_THROW(CoarseAlign(good, good.leftCols(3)), std::invalid_argument);  // too few points for features
  EXPECT_THROW(CoarseAlignViews({good}), std::invalid_argument);
  EXPECT_THROW(CoarseAlignViews({good, good, bad}), std::invalid_argument);
  CoarseAlignOptions negative;
  negative.voxel_size = -1.0;
  EXPECT_THROW(CoarseAlign(good, good, negative), std::invalid_argument);
  EXPECT_THROW(PclIterativeClosestPoint(good, empty), std::invalid_argument);
  EXPECT_THROW(PclIterativeClosestPoint(bad, good), std::invalid_argument);
}

struct Bunny {
  std::vector<Eigen::Matrix3Xd> views;
  std::vector<RigidMotion> world_T_view;  // bun.conf
  std::vector<std::string> names;
};
Bunny ReadBunny() {
  const ScanSet set = ReadScanSet(test::SharedData("stanford_bunny_scans/bun.conf"));
  Bunny b;
  for (const Scan& s : set.scans) {
    b.views.push_back(s.points);
    b.world_T_view.push_back(s.world_T_scan);
    b.names.push_back(s.metadata.source);  // "bun000.ply (bun.conf)"
  }
  return b;
}
std::size_t Find(const Bunny& b, const std::string& prefix) {
  for (std::size_t k = 0; k < b.names.size(); ++k)
    if (b.names[k].rfind(prefix, 0) == 0) return k;
  throw std::runtime_error("the bunny has no view " + prefix);
}

// A large motion: 30 to 60 degrees about a random axis through the view's centroid, then 30 mm in a random
// direction.
RigidMotion LargeMotion(const Eigen::Matrix3Xd& view, std::mt19937_64& rng) {
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> angle(30.0 * kDeg, 60.0 * kDeg);
  const Eigen::Vector3d axis = Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
  const Eigen::Vector3d shift = Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized() * 0.030;
  const Eigen::Vector3d c = view.rowwise().mean();
  const Eigen::Matrix3d r = RotationAboutAxis(axis, angle(rng));
  return {r, c - r * c + shift};
}

TEST(PclRegistration, BunnyPairsMovedByLargeMotionsAreCoarseAlignedThenRefined) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  const Bunny bunny = ReadBunny();
  std::mt19937_64 rng(7);
  // Neighbouring turntable views (45 degrees apart); each source is moved on top of that.
  const std::pair<const char*, const char*> pairs[] = {
      {"bun000", "bun045"}, {"bun045", "bun090"}, {"bun000", "bun315"}, {"bun315", "bun270"}};
  int fine_alone_misses = 0;
  for (const auto& [target_name, source_name] : pairs) {
    const std::size_t t = Find(bunny, target_name), s = Find(bunny, source_name);
    const RigidMotion moved = LargeMotion(bunny.views[s], rng);
    const Eigen::Matrix3Xd source = moved.apply(bunny.views[s]);
    const Eigen::Matrix3Xd& target = bunny.views[t];
    const RigidMotion truth = bunny.world_T_view[t].inverse() * bunny.world_T_view[s] * moved.inverse();
    const Eigen::Vector3d centroid = truth * Eigen::Vector3d(source.rowwise().mean());

    auto start = std::chrono::steady_clock::now();
    const CoarseAlignment coarse = CoarseAlign(source, target);
    const double coarse_seconds = Seconds(start);
    const PoseDifference c = Compare(coarse.target_T_source, truth, centroid);
    start = std::chrono::steady_clock::now();
    const ScanToScanResult fine =
        RegisterScansToEachOther({target, source}, {RigidMotion::Identity(), coarse.target_T_source});
    const double fine_seconds = Seconds(start);
    const PoseDifference f = Compare(fine.world_T_scan[1], truth, centroid);
    // Control: the fine registration alone, from the views as given (no usable pose).
    const ScanToScanResult alone = RegisterScansToEachOther({target, source}, {RigidMotion(), RigidMotion()});
    const PoseDifference a = Compare(alone.world_T_scan[1], truth, centroid);
    const bool alone_ok = a.angle < 0.5 * kDeg && a.shift < 0.001;
    fine_alone_misses += alone_ok ? 0 : 1;
    std::printf(
        "%s -> %s (start %.0f deg off): coarse %.2f deg %.2f mm (inliers %.2f of %ld, voxel %.1f mm, %.1f "
        "s); "
        "refined %.3f deg %.3f mm (%d sweeps, %.2f s); fine alone %.1f deg %.1f mm\n",
        source_name, target_name, truth.angle() / kDeg, c.angle / kDeg, c.shift * 1e3, coarse.inlier_fraction,
        static_cast<long>(coarse.source_samples), coarse.voxel_size * 1e3, coarse_seconds, f.angle / kDeg,
        f.shift * 1e3, fine.sweeps, fine_seconds, a.angle / kDeg, a.shift * 1e3);
    EXPECT_TRUE(coarse.found) << source_name << " -> " << target_name;
    EXPECT_LT(f.angle, 0.5 * kDeg) << source_name << " -> " << target_name;
    EXPECT_LT(f.shift, 0.001) << source_name << " -> " << target_name;
  }
  // The set is not one the fine registration solves by itself.
  EXPECT_GE(fine_alone_misses, 1);
}

TEST(PclRegistration, BunnyViewsMovedByLargeMotionsAreCoarseAlignedTogetherThenRefined) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  const Bunny bunny = ReadBunny();
  std::mt19937_64 rng(11);
  std::vector<Eigen::Matrix3Xd> views;
  std::vector<RigidMotion> truth;  // world_T_view of the moved views
  const char* names[] = {"bun000", "bun045", "bun090", "bun315"};
  for (const char* name : names) {
    const std::size_t k = Find(bunny, name);
    const RigidMotion moved = LargeMotion(bunny.views[k], rng);
    views.push_back(moved.apply(bunny.views[k]));
    truth.push_back(bunny.world_T_view[k] * moved.inverse());
  }
  auto start = std::chrono::steady_clock::now();
  const MultiViewCoarseAlignment coarse = CoarseAlignViews(views);
  const double coarse_seconds = Seconds(start);
  start = std::chrono::steady_clock::now();
  const ScanToScanResult fine = RegisterScansToEachOther(views, coarse.world_T_view);
  const double fine_seconds = Seconds(start);
  std::printf("4 views: coarse %.1f s (6 pairs), refined in %d sweeps, %.2f s; tree:", coarse_seconds,
              fine.sweeps, fine_seconds);
  for (const auto& [parent, child] : coarse.tree) std::printf(" %s-%s", names[parent], names[child]);
  std::printf("\n");
  ASSERT_EQ(coarse.tree.size(), views.size() - 1);
  // Relative to view 0 (the views are determined only relative to each other), at each view's centroid.
  for (std::size_t k = 1; k < views.size(); ++k) {
    const RigidMotion ref = truth[0].inverse() * truth[k];
    const Eigen::Vector3d centroid = ref * Eigen::Vector3d(views[k].rowwise().mean());
    const PoseDifference c =
        Compare(coarse.world_T_view[0].inverse() * coarse.world_T_view[k], ref, centroid);
    const PoseDifference f = Compare(fine.world_T_scan[0].inverse() * fine.world_T_scan[k], ref, centroid);
    std::printf("  %s: start %.0f deg off, coarse %.2f deg %.2f mm, refined %.3f deg %.3f mm\n", names[k],
                ref.angle() / kDeg, c.angle / kDeg, c.shift * 1e3, f.angle / kDeg, f.shift * 1e3);
    EXPECT_TRUE(coarse.placed[k]) << names[k];
    EXPECT_LT(f.angle, 0.5 * kDeg) << names[k];
    EXPECT_LT(f.shift, 0.001) << names[k];
  }
}

}  // namespace
}  // namespace s2m
