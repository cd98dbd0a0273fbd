// Robust extraction on real cluttered depth scenes (../shared/data/real_clutter_scenes, skipped when absent):
// the labelled mOSD scenes test36 (three cylindrical objects on a table) and test45 (seven mixed objects),
// scored point by point against the per-point ground-truth labels (1-2 table, 20, 30, ... one object each),
// the mug on PCL's stereo table scene, and three raw Kinect depth frames. Issue 22's bar: inlier precision at
// least 0.9 for the table plane and every cylinder; recall is printed (the tops of cylinders are planes, not
// cylinder inliers). Metres, Kinect noise.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "acquisition/depth_frame.h"
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

// What a scene's detection found: per object a cylinder was matched to, its largest cylinder's support; the
// objects any instance was matched to.
using CylinderSupport = std::map<std::int64_t, Eigen::Index>;
struct SceneDetection {
  CylinderSupport cylinders;
  std::set<std::int64_t> objects;
};

// Detects planes and cylinders; every instance (the cylinders and the table plane, which issue 22 names,
// and every other plane) must reach precision 0.9: no instance mixes objects.
SceneDetection CheckScene(const std::string& name, int max_instances) {
  const Scan scan = ReadPointCloud(test::SharedData("real_clutter_scenes/" + name));
  EXPECT_EQ(scan.labels.size(), static_cast<std::size_t>(scan.size()));
  std::map<std::int64_t, Eigen::Index> object_points;
  for (std::int64_t l : scan.labels) ++object_points[Object(l)];
  DetectionOptions options;
  options.kinds = {PrimitiveKind::kPlane, PrimitiveKind::kCylinder};
  options.max_instances = max_instances;
  const DetectionResult result = DetectPrimitives(scan.points, options);
  EXPECT_FALSE(result.instances.empty());
  SceneDetection found;
  CylinderSupport& cylinders = found.cylinders;
  std::map<std::int64_t, Eigen::Index> recalled;
  bool table_seen = false;
  for (const DetectedPrimitive& instance : result.instances) {
    const Scored s = Score(instance, scan.labels);
    recalled[s.object] += s.correct;
    // The image row of the inliers' centroid by the Kinect's nominal intrinsics (fy 525, cy 239.5).
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (Eigen::Index i : instance.inliers) centroid += scan.points.col(i);
    centroid /= static_cast<double>(instance.support());
    std::printf("[ %s ] %s: %ld inliers, object %ld, precision %.4f, image row %.0f\n", name.c_str(),
                ToString(instance.kind), static_cast<long>(instance.support()), static_cast<long>(s.object),
                s.precision, 525.0 * centroid.y() / centroid.z() + 239.5);
    EXPECT_GE(s.precision, 0.9) << name << ": a " << ToString(instance.kind) << " matched to object "
                                << s.object;
    found.objects.insert(s.object);
    if (instance.kind == PrimitiveKind::kCylinder)
      cylinders[s.object] = std::max(cylinders[s.object], instance.support());
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
  return found;
}

TEST(RealClutterDetection, Test36ThreeCylindersAndTheTable) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  const CylinderSupport cylinders = CheckScene("test36.pcd", 10).cylinders;
  // The README's three cylindrical objects, each found as a cylinder. The table is one plane of 113793
  // points; what is left of it bends at the depth image's lower border, where a Kinect's depth distortion is
  // largest (measured: the two cylinders matched to the table there have 230 and 259 inliers, centred on
  // image rows 464-472 of 480). They are real shapes of the data, not of the table; they must rank below
  // every object's cylinder.
  Eigen::Index smallest_object_cylinder = std::numeric_limits<Eigen::Index>::max();
  for (std::int64_t object : {20, 30, 40}) {
    ASSERT_TRUE(cylinders.count(object)) << "object " << object << " not found as a cylinder";
    smallest_object_cylinder = std::min(smallest_object_cylinder, cylinders.at(object));
  }
  if (cylinders.count(1)) {
    EXPECT_LT(cylinders.at(1), smallest_object_cylinder);
  }
}

// The mean change of depth between two frames over the pixels valid in both (millimetres, raw units).
double MeanDepthChange(const std::string& first, const std::string& second) {
  const DepthImage a = ReadDepthTiff(test::SharedData("pcl_kinect_frames/" + first + "_depth.tiff"));
  const DepthImage b = ReadDepthTiff(test::SharedData("pcl_kinect_frames/" + second + "_depth.tiff"));
  double sum = 0.0;
  long count = 0;
  for (std::size_t i = 0; i < a.values.size() && i < b.values.size(); ++i) {
    if (a.values[i] == 0 || b.values[i] == 0) continue;
    sum += static_cast<double>(b.values[i]) - static_cast<double>(a.values[i]);
    ++count;
  }
  return count > 0 ? sum / static_cast<double>(count) : 0.0;
}

TEST(RealClutterDetection, Test45MixedObjects) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  // 25 instances: the objects 60, 70 and 80 are small (2633-3252 points) and not one primitive each (alone,
  // their largest primitive covers 517 of 3252, 314 of 2798 and 852 of 2633 points, measured with `detect`),
  // so the first 10 instances, all of the table and the larger objects, do not reach them (measured).
  const SceneDetection found = CheckScene("test45.pcd", 25);
  // The two cans (objects 30 and 40) as cylinders; every object found by some instance.
  EXPECT_TRUE(found.cylinders.count(30));
  EXPECT_TRUE(found.cylinders.count(40));
  for (std::int64_t object : {1, 20, 30, 40, 50, 60, 70, 80})
    EXPECT_TRUE(found.objects.count(object)) << "object " << object << " not found";
}

// Three consecutive real Kinect frames (a floor and two boxes, 0.25 s apart, raw depth in millimetres; the
// camera moves between them: frame 2's depths differ from frame 0's by 11 mm on average, printed below). Read
// as depth frames, the noise is recognized as layered (it was 1e-18 m before, and nothing was detected). In
// every frame the two largest planes are the large surface behind the boxes and the large box's face towards
// the camera; the angle between them does not depend on where the camera is, so the three frames must agree
// on it. Within 1 degree: a Kinect's depth distortion bends planes by millimetres near the image border
// (test36's table above), and 3 mm over the box face's 0.3 m is 0.6 degree.
TEST(RealClutterDetection, KinectFramesAgreeOnTheAngleOfTheBox) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  std::vector<double> angles;
  for (const char* frame :
       {"frame_20121214T142255.814212", "frame_20121214T142256.068683", "frame_20121214T142256.332395"}) {
    const Scan scan =
        ReadPointCloud(test::SharedData(std::string("pcl_kinect_frames/") + frame + "_depth.tiff"));
    DetectionOptions options;
    options.kinds = {PrimitiveKind::kPlane};
    options.max_instances = 2;
    const DetectionResult result = DetectPrimitives(scan.points, options);
    ASSERT_EQ(result.instances.size(), 2u) << frame << ": " << result.stop_reason;
    const DetectedPrimitive& floor = result.instances[0];
    const DetectedPrimitive& face = result.instances[1];
    const double angle = std::acos(
        std::min(1.0, std::abs(std::get<Plane>(floor.shape).normal.dot(std::get<Plane>(face.shape).normal))));
    std::printf(
        "[ kinect ] %s: noise %.5f m, epsilon %.5f m; surface %ld of %ld points (RMS %.5f m), box face "
        "%ld (RMS %.5f m), %.2f deg between them\n",
        frame, result.noise_sigma, result.epsilon, static_cast<long>(floor.support()),
        static_cast<long>(scan.size()), floor.rms, static_cast<long>(face.support()), face.rms,
        angle * 180 / M_PI);
    EXPECT_GT(result.noise_sigma, 0.3e-3) << frame;  // Kinect depth steps here are millimetres
    EXPECT_GT(floor.support(), scan.size() / 3) << frame;
    EXPECT_GT(face.support(), scan.size() / 20) << frame;
    angles.push_back(angle);
  }
  const auto [smallest, largest] = std::minmax_element(angles.begin(), angles.end());
  std::printf("[ kinect ] angles %.2f-%.2f deg; mean depth change from the first frame to the last %.1f mm\n",
              *smallest * 180 / M_PI, *largest * 180 / M_PI,
              MeanDepthChange("frame_20121214T142255.814212", "frame_20121214T142256.332395"));
  EXPECT_LT(*largest - *smallest, M_PI / 180);
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
