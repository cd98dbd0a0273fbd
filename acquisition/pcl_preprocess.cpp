#include "acquisition/pcl_preprocess.h"

#include <pcl/common/common.h>
#include <pcl/features/normal_3d_omp.h>
#include <pcl/filters/statistical_outlier_removal.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

namespace s2m {
namespace {

using Cloud = pcl::PointCloud<pcl::PointXYZ>;

void Check(const Eigen::Matrix3Xd& points, const Eigen::Vector3d& sensor, const PreprocessOptions& o) {
  if (points.cols() == 0) throw std::invalid_argument("Preprocess: the point set is empty");
  if (!points.allFinite())
    throw std::invalid_argument("Preprocess: the point set contains NaN or inf coordinates");
  if (!sensor.allFinite()) throw std::invalid_argument("Preprocess: the sensor position is not finite");
  if (o.crop &&
      (!o.crop_min.allFinite() || !o.crop_max.allFinite() || (o.crop_min.array() > o.crop_max.array()).any()))
    throw std::invalid_argument("Preprocess: the crop box needs finite bounds with crop_min <= crop_max");
  if (!(o.voxel_size >= 0) || !std::isfinite(o.voxel_size))
    throw std::invalid_argument("Preprocess: voxel_size must be >= 0 (0: off)");
  if (o.remove_outliers &&
      (o.outlier_neighbours < 1 || !(o.outlier_stddev > 0) || !std::isfinite(o.outlier_stddev)))
    throw std::invalid_argument(
        "Preprocess: outlier removal needs outlier_neighbours >= 1 and outlier_stddev > 0");
  if (o.estimate_normals && o.normal_neighbours < 3)
    throw std::invalid_argument("Preprocess: a normal needs normal_neighbours >= 3");
}

// PCL works in single precision: coordinates are shifted by `origin` (the points' mean) so that data far from
// the origin keep their resolution.
Cloud::Ptr ToCloud(const Eigen::Matrix3Xd& points, const Eigen::Vector3d& origin) {
  Cloud::Ptr cloud(new Cloud);
  cloud->resize(static_cast<std::size_t>(points.cols()));
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const Eigen::Vector3f p = (points.col(i) - origin).cast<float>();
    (*cloud)[static_cast<std::size_t>(i)] = pcl::PointXYZ(p.x(), p.y(), p.z());
  }
  return cloud;
}

Eigen::Index Size(const Cloud& cloud) {
  return static_cast<Eigen::Index>(cloud.size());
}

}  // namespace

PreprocessResult Preprocess(const Eigen::Matrix3Xd& points, const Eigen::Vector3d& sensor_position,
                            const PreprocessOptions& options) {
  Check(points, sensor_position, options);
  PreprocessResult result;
  result.input = points.cols();

  Eigen::Matrix3Xd kept = points;
  if (options.crop) {
    Eigen::Index n = 0;
    for (Eigen::Index i = 0; i < points.cols(); ++i) {
      const auto p = points.col(i);
      if ((p.array() >= options.crop_min.array()).all() && (p.array() <= options.crop_max.array()).all())
        kept.col(n++) = p;
    }
    kept.conservativeResize(3, n);
    result.removed_by_crop = points.cols() - n;
  }
  // Without a PCL step the points never pass through single precision: a crop alone is exact.
  if (kept.cols() == 0 || !(options.remove_outliers || options.voxel_size > 0 || options.estimate_normals)) {
    result.points = std::move(kept);
    return result;
  }

  const Eigen::Vector3d origin = kept.rowwise().mean();
  Cloud::Ptr cloud = ToCloud(kept, origin);

  if (options.remove_outliers) {
    pcl::StatisticalOutlierRemoval<pcl::PointXYZ> sor;
    sor.setInputCloud(cloud);
    sor.setMeanK(options.outlier_neighbours);
    sor.setStddevMulThresh(options.outlier_stddev);
    Cloud::Ptr out(new Cloud);
    sor.filter(*out);
    result.removed_as_outliers = Size(*cloud) - Size(*out);
    cloud = out;
  }

  if (options.voxel_size > 0 && !cloud->empty()) {
    // pcl::VoxelGrid indexes voxels with 32-bit integers and, when they would overflow, only warns and
    // returns the input unfiltered; refuse that case instead of silently not down-sampling.
    Eigen::Vector4f lo, hi;
    pcl::getMinMax3D(*cloud, lo, hi);
    double cells = 1;
    for (int k = 0; k < 3; ++k) cells *= std::floor((hi[k] - lo[k]) / options.voxel_size) + 1;
    if (cells > static_cast<double>(std::numeric_limits<std::int32_t>::max()))
      throw std::invalid_argument("Preprocess: voxel_size " + std::to_string(options.voxel_size) +
                                  " is too small for the data's extent (PCL's voxel index would overflow)");
    pcl::VoxelGrid<pcl::PointXYZ> grid;
    grid.setInputCloud(cloud);
    const auto leaf = static_cast<float>(options.voxel_size);
    grid.setLeafSize(leaf, leaf, leaf);
    Cloud::Ptr out(new Cloud);
    grid.filter(*out);
    result.removed_by_voxel = Size(*cloud) - Size(*out);
    cloud = out;
  }

  pcl::PointCloud<pcl::Normal> normals;
  if (options.estimate_normals && !cloud->empty()) {
    pcl::NormalEstimationOMP<pcl::PointXYZ, pcl::Normal> estimate(2);
    estimate.setInputCloud(cloud);
    estimate.setKSearch(options.normal_neighbours);
    const Eigen::Vector3f view = (sensor_position - origin).cast<float>();
    estimate.setViewPoint(view.x(), view.y(), view.z());
    estimate.compute(normals);
  }

  result.points.resize(3, Size(*cloud));
  if (options.estimate_normals) result.normals.resize(3, Size(*cloud));
  Eigen::Index n = 0;
  for (std::size_t i = 0; i < cloud->size(); ++i) {
    const Eigen::Vector3d p = (*cloud)[i].getVector3fMap().cast<double>() + origin;
    if (options.estimate_normals) {
      const Eigen::Vector3d normal = normals[i].getNormalVector3fMap().cast<double>();
      if (!normal.allFinite() || normal.norm() < 0.5) {
        ++result.removed_without_normal;
        continue;
      }
      result.normals.col(n) = normal.normalized();
    }
    result.points.col(n++) = p;
  }
  result.points.conservativeResize(3, n);
  if (options.estimate_normals) result.normals.conservativeResize(3, n);
  return result;
}

}  // namespace s2m
