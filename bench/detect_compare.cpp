// Robust extraction against PCL's sample consensus (issue 22, docs/benchmarks.md "Robust extraction"): on the
// synthetic terrestrial scan of a 50 mm sphere on a stand with a floor and a wall, and on the real mug scene
// of PCL's cylinder-segmentation tutorial, our DetectPrimitives and PCL's SACSegmentation(FromNormals) with
// RANSAC and MSAC, side by side: parameter error and time. Prints a markdown table.
//
//   build/bench/detect_compare [path to table_scene_mug_stereo_textured.pcd]

#include <pcl/ModelCoefficients.h>
#include <pcl/features/normal_3d.h>
#include <pcl/filters/extract_indices.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/method_types.h>
#include <pcl/sample_consensus/model_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/sac_segmentation.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include "acquisition/point_cloud_io.h"
#include "fitting/primitive_detection.h"
#include "synthetic/clutter_scenes.h"

namespace {

using namespace s2m;
using Clock = std::chrono::steady_clock;
using Cloud = pcl::PointCloud<pcl::PointXYZ>;
using Normals = pcl::PointCloud<pcl::Normal>;

double Seconds(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// PCL works in floats: the points are shifted by their centroid first.
Cloud::Ptr ToCloud(const Eigen::Matrix3Xd& points, const Eigen::Vector3d& origin) {
  Cloud::Ptr cloud(new Cloud);
  cloud->resize(static_cast<std::size_t>(points.cols()));
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const Eigen::Vector3f x = (points.col(i) - origin).cast<float>();
    (*cloud)[static_cast<std::size_t>(i)] = pcl::PointXYZ(x.x(), x.y(), x.z());
  }
  return cloud;
}

Normals::Ptr PclNormals(const Cloud::Ptr& cloud, int k) {
  pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> ne;
  ne.setSearchMethod(pcl::make_shared<pcl::search::KdTree<pcl::PointXYZ>>());
  ne.setInputCloud(cloud);
  ne.setKSearch(k);
  Normals::Ptr normals(new Normals);
  ne.compute(*normals);
  return normals;
}

struct PclResult {
  pcl::ModelCoefficients coefficients;
  pcl::PointIndices inliers;
  double seconds = 0;
};

// One SACSegmentationFromNormals run (normal distance weight 0.1, 10000 iterations, as PCL's tutorial).
PclResult PclSegment(const Cloud::Ptr& cloud, const Normals::Ptr& normals, int model, int method,
                     double distance, double max_radius) {
  PclResult r;
  const auto start = Clock::now();
  pcl::SACSegmentationFromNormals<pcl::PointXYZ, pcl::Normal> seg;
  seg.setOptimizeCoefficients(true);
  seg.setModelType(model);
  seg.setMethodType(method);
  seg.setNormalDistanceWeight(0.1);
  seg.setMaxIterations(10000);
  seg.setDistanceThreshold(distance);
  seg.setRadiusLimits(0, max_radius);
  seg.setInputCloud(cloud);
  seg.setInputNormals(normals);
  seg.segment(r.inliers, r.coefficients);
  r.seconds = Seconds(start);
  return r;
}

// `flying_pixels`: the probability that a ray straddling two objects returns a mixed range
// (synthetic/clutter_scenes.h); 1: every such ray, a halo of points between the sphere and what is behind it.
void SphereScene(double flying_pixels) {
  std::printf("\n### Synthetic: 50 mm sphere on a stand, floor and wall (7 m, 0.2 mm noise)%s, 5 seeds\n\n",
              flying_pixels > 0 ? ", flying pixels at every silhouette" : "");
  std::printf(
      "| method | worst radius error (mm) | worst centre error (mm) | mean time (s) |\n|---|---|---|---|\n");
  struct Row {
    std::string name;
    double radius = 0, centre = 0, seconds = 0;
  };
  Row ours{"scan2model detect (sphere, 1 instance)"}, ransac{"PCL SACSegmentationFromNormals SPHERE RANSAC"},
      msac{"PCL SACSegmentationFromNormals SPHERE MSAC"},
      plain{"plain least squares (FitSphere, all points)"};
  const int seeds = 5;
  for (int seed = 1; seed <= seeds; ++seed) {
    const SphereOnStandScene scene =
        MakeSphereOnStandScene(7000, 0.2, static_cast<std::uint64_t>(seed), flying_pixels);
    const Eigen::Matrix3Xd& p = scene.cloud.points;
    auto start = Clock::now();
    DetectionOptions o;
    o.kinds = {PrimitiveKind::kSphere};
    o.max_instances = 1;
    o.seed = static_cast<std::uint64_t>(seed);
    const DetectionResult result = DetectPrimitives(p, o);
    ours.seconds += Seconds(start) / seeds;
    const Sphere s = std::get<Sphere>(result.instances.at(0).shape);
    ours.radius = std::max(ours.radius, std::abs(s.radius - 25));
    ours.centre = std::max(ours.centre, s.center.norm());
    start = Clock::now();
    const PrimitiveFit<Sphere> ls = FitSphere(p);
    plain.seconds += Seconds(start) / seeds;
    plain.radius = std::max(plain.radius, std::abs(ls.shape.radius - 25));
    plain.centre = std::max(plain.centre, ls.shape.center.norm());
    // PCL with the same epsilon as ours, its normals from the same 40 neighbours.
    const Eigen::Vector3d origin = p.rowwise().mean();
    const Cloud::Ptr cloud = ToCloud(p, origin);
    for (Row* row : {&ransac, &msac}) {
      const auto t0 = Clock::now();
      const Normals::Ptr normals = PclNormals(cloud, 40);
      PclResult r = PclSegment(cloud, normals, pcl::SACMODEL_NORMAL_SPHERE,
                               row == &ransac ? pcl::SAC_RANSAC : pcl::SAC_MSAC, result.epsilon, 100.0);
      row->seconds += Seconds(t0) / seeds;
      if (r.coefficients.values.size() < 4) {
        row->radius = row->centre = std::numeric_limits<double>::infinity();
        continue;
      }
      const Eigen::Vector3d c =
          Eigen::Vector3d(r.coefficients.values[0], r.coefficients.values[1], r.coefficients.values[2]) +
          origin;
      row->radius = std::max(row->radius, std::abs(r.coefficients.values[3] - 25.0));
      row->centre = std::max(row->centre, c.norm());
    }
  }
  for (const Row* r : {&ours, &ransac, &msac, &plain})
    std::printf("| %s | %.4f | %.4f | %.3f |\n", r->name.c_str(), r->radius, r->centre, r->seconds);
}

void MugScene(const std::string& file) {
  if (!std::filesystem::exists(file)) {
    std::printf("\n(mug scene %s absent: skipped)\n", file.c_str());
    return;
  }
  const Scan scan = ReadPointCloud(file);
  std::printf("\n### Real: the mug on PCL's stereo table scene (%ld valid points, metres)\n\n",
              static_cast<long>(scan.size()));
  std::printf(
      "| method | mug radius (m) | axis tilt from the table normal (deg) | mug inliers | time (s) |\n"
      "|---|---|---|---|---|\n");
  auto start = Clock::now();
  DetectionOptions o;
  o.kinds = {PrimitiveKind::kPlane, PrimitiveKind::kCylinder};
  o.max_instances = 2;
  const DetectionResult result = DetectPrimitives(scan.points, o);
  const double ours_seconds = Seconds(start);
  const Plane table = std::get<Plane>(result.instances.at(0).shape);
  const Cylinder mug = std::get<Cylinder>(result.instances.at(1).shape);
  std::printf("| scan2model detect (plane + cylinder, 2 instances) | %.5f | %.2f | %ld | %.2f |\n",
              mug.radius,
              std::acos(std::min(1.0, std::abs(table.normal.dot(mug.axis_direction)))) * 180 / M_PI,
              static_cast<long>(result.instances[1].support()), ours_seconds);
  // PCL's tutorial: normals of 50 neighbours, the plane (NORMAL_PLANE, 0.03 m) removed, then the cylinder
  // (0.05 m, radius 0-0.1 m).
  const Eigen::Vector3d origin = scan.points.rowwise().mean();
  const Cloud::Ptr cloud = ToCloud(scan.points, origin);
  for (int method : {pcl::SAC_RANSAC, pcl::SAC_MSAC}) {
    const auto t0 = Clock::now();
    const Normals::Ptr normals = PclNormals(cloud, 50);
    PclResult plane = PclSegment(cloud, normals, pcl::SACMODEL_NORMAL_PLANE, method, 0.03, 0.1);
    pcl::ExtractIndices<pcl::PointXYZ> extract;
    extract.setInputCloud(cloud);
    extract.setIndices(pcl::make_shared<pcl::PointIndices>(plane.inliers));
    extract.setNegative(true);
    Cloud::Ptr rest(new Cloud);
    extract.filter(*rest);
    pcl::ExtractIndices<pcl::Normal> extract_normals;
    extract_normals.setInputCloud(normals);
    extract_normals.setIndices(pcl::make_shared<pcl::PointIndices>(plane.inliers));
    extract_normals.setNegative(true);
    Normals::Ptr rest_normals(new Normals);
    extract_normals.filter(*rest_normals);
    PclResult cylinder = PclSegment(rest, rest_normals, pcl::SACMODEL_CYLINDER, method, 0.05, 0.1);
    const double seconds = Seconds(t0);
    if (plane.coefficients.values.size() < 4 || cylinder.coefficients.values.size() < 7) {
      std::printf("| PCL tutorial pipeline %s | failed | | | %.2f |\n",
                  method == pcl::SAC_RANSAC ? "RANSAC" : "MSAC", seconds);
      continue;
    }
    const Eigen::Vector3d n(plane.coefficients.values[0], plane.coefficients.values[1],
                            plane.coefficients.values[2]);
    const Eigen::Vector3d a(cylinder.coefficients.values[3], cylinder.coefficients.values[4],
                            cylinder.coefficients.values[5]);
    std::printf("| PCL tutorial pipeline (NORMAL_PLANE then CYLINDER) %s | %.5f | %.2f | %zu | %.2f |\n",
                method == pcl::SAC_RANSAC ? "RANSAC" : "MSAC", cylinder.coefficients.values[6],
                std::acos(std::min(1.0, std::abs(n.normalized().dot(a.normalized())))) * 180 / M_PI,
                cylinder.inliers.indices.size(), seconds);
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::printf("## Robust extraction: scan2model detect against PCL's sample consensus\n");
  SphereScene(0.0);
  SphereScene(1.0);
  MugScene(argc > 1 ? argv[1]
                    : std::string(S2M_SOURCE_DIR) +
                          "/../shared/data/real_clutter_scenes/table_scene_mug_stereo_textured.pcd");
  return 0;
}
