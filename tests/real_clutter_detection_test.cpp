// Robust extraction on real cluttered depth scenes (../shared/data/real_clutter_scenes, skipped when absent):
// the labelled mOSD scenes test36 (three cylindrical objects on a table) and test45 (seven mixed objects),
// scored point by point against the per-point ground-truth labels (1-2 table, 20, 30, ... one object each),
// and the mug on PCL's stereo table scene. Issue 22's bar: inlier precision at least 0.9 for the table plane
// and every cylinder; recall is printed (the tops of cylinders are planes, not cylinder inliers). Metres,
// Kinect noise.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <string>

#include "acquisition/point_cloud_io.h"
#include "fitting/primitive_detection.h"
#include "test_paths.h"

namespace s2m {
namespace {

// The table's labels are 1 and 2 (two parts of one table).
std::int64_t Object(std::int64_t label) {
  return label == 2 ? 1 : label;
}

struct Scored {
  std::int64_t object = 0;   // the majority label of the instance's inliers
  double precision = 0.0;    // the fraction of its inliers with that label
  Eigen::Index correct = 0;  // inliers with that label
};

Scored Score(const DetectedPrimitive& instance, const std::vector<std::int64_t>& labels) {
  std::map<std::int64_t, Eigen::Index> votes;
  for (Eigen::Index i : instance.inliers) ++votes[Object(labels[static_cast<std::size_t>(i)])];
  Scored s;
  Eigen::Index best = 0;
  for (const auto& [object, count] : votes) {
    if (count > best) {
      best = count;
      s.object = object;
    }
  }
  s.correct = best;
  s.precision = static_cast<double>(best) / static_cast<double>(instance.support());
  return s;
}

// Detects planes and cylinders; every cylinder and the largest plane (the table) must reach precision 0.9
// (issue 22); returns the objects that a cylinder was matched to.
std::set<std::int64_t> CheckScene(const std::string& name, int max_instances) {
  const Scan scan = ReadPointCloud(test::SharedData("real_clutter_scenes/" + name));
  EXPECT_EQ(scan.labels.size(), static_cast<std::size_t>(scan.size()));
  std::map<std::int64_t, Eigen::Index> object_points;
  for (std::int64_t l : scan.labels) ++object_points[Object(l)];
  DetectionOptions options;
  options.kinds = {PrimitiveKind::kPlane, PrimitiveKind::kCylinder};
  options.max_instances = max_instances;
  const DetectionResult result = DetectPrimitives(scan.points, options);
  EXPECT_FALSE(result.instances.empty());
  std::set<std::int64_t> cylinders;
  std::map<std::int64_t, Eigen::Index> recalled;
  bool table_seen = false;
  for (const DetectedPrimitive& instance : result.instances) {
    const Scored s = Score(instance, scan.labels);
    recalled[s.object] += s.correct;
    std::printf("[ %s ] %s: %ld inliers, object %ld, precision %.4f\n", name.c_str(), ToString(instance.kind),
                static_cast<long>(instance.support()), static_cast<long>(s.object), s.precision);
    if (instance.kind == PrimitiveKind::kCylinder) {
      EXPECT_GE(s.precision, 0.9) << name << ": a cylinder matched to object " << s.object;
      cylinders.insert(s.object);
    }
    if (instance.kind == PrimitiveKind::kPlane && !table_seen) {  // the first plane found is the largest
      table_seen = true;
      EXPECT_EQ(s.object, 1) << name << ": the largest plane is not the table";
      EXPECT_GE(s.precision, 0.9) << name << ": the table plane";
    }
  }
  EXPECT_TRUE(table_seen);
  for (const auto& [object, count] : object_points) {
    if (object == 0) continue;
    std::printf("[ %s ] object %ld: %ld points, recall %.3f\n", name.c_str(), static_cast<long>(object),
                static_cast<long>(count), static_cast<double>(recalled[object]) / static_cast<double>(count));
  }
  return cylinders;
}

TEST(RealClutterDetection, Test36ThreeCylindersAndTheTable) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  const std::set<std::int64_t> cylinders = CheckScene("test36.pcd", 9);
  // The README's three cylindrical objects, each found as a cylinder.
  EXPECT_EQ(cylinders, (std::set<std::int64_t>{20, 30, 40}));
}

TEST(RealClutterDetection, Test45MixedObjects) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  const std::set<std::int64_t> cylinders = CheckScene("test45.pcd", 8);
  EXPECT_GE(cylinders.size(), 2u);
}

// PCL's cylinder-segmentation tutorial scene: the mug stands on the table, so its axis is the table's normal
// (within 5 degrees: the mug's own tilt and the fits' uncertainty, both far below it).
TEST(RealClutterDetection, TheMugOnTheTableStandsUpright) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  const Scan scan =
      ReadPointCloud(test::SharedData("real_clutter_scenes/table_scene_mug_stereo_textured.pcd"));
  DetectionOptions options;
  options.kinds = {PrimitiveKind::kPlane, PrimitiveKind::kCylinder};
  options.max_instances = 2;
  const DetectionResult result = DetectPrimitives(scan.points, options);
  ASSERT_EQ(result.instances.size(), 2u);
  ASSERT_EQ(result.instances[0].kind, PrimitiveKind::kPlane);
  ASSERT_EQ(result.instances[1].kind, PrimitiveKind::kCylinder);
  const Plane& table = std::get<Plane>(result.instances[0].shape);
  const Cylinder& mug = std::get<Cylinder>(result.instances[1].shape);
  const double tilt = std::acos(std::min(1.0, std::abs(table.normal.dot(mug.axis_direction))));
  std::printf(
      "[ mug ] table %ld inliers; mug %ld inliers, radius %.5f m, RMS %.5f m, axis %.2f deg off the "
      "table normal\n",
      static_cast<long>(result.instances[0].support()), static_cast<long>(result.instances[1].support()),
      mug.radius, result.instances[1].rms, tilt * 180 / M_PI);
  EXPECT_LT(tilt, 5 * M_PI / 180);
  EXPECT_GT(mug.radius, 0.02);  // a mug, not a ring of the table: PCL's tutorial bounds it by 0.1 m
  EXPECT_LT(mug.radius, 0.1);
}

}  // namespace
}  // namespace s2m
