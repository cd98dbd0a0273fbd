#pragma once
// Preprocessing of one view with PCL (issue 5): crop box, statistical outlier removal, voxel-grid
// down-sampling and normal estimation oriented towards the sensor. Each step is optional; they run in that
// order. Only Eigen appears here; PCL stays inside pcl_preprocess.cpp (target s2m_pcl, built only when
// PCL 1.13 is found).
//
// Why this order: cropping first makes everything after it cheaper and keeps the background out of the
// statistics; outlier removal runs on the sensor's own samples, before voxel centroids could blend a flying
// pixel into a surface; normals come last, from the points that are returned.

#include <Eigen/Core>

namespace s2m {

struct PreprocessOptions {
  // Crop box, axis-aligned in the input's coordinates, bounds inclusive. Done in double precision by us (not
  // PCL's single-precision CropBox), so what is kept is exactly what the box says.
  bool crop = false;
  Eigen::Vector3d crop_min = Eigen::Vector3d::Constant(-1.0);
  Eigen::Vector3d crop_max = Eigen::Vector3d::Constant(1.0);

  // pcl::VoxelGrid: each occupied cube of this edge length becomes the centroid of its points. 0: off.
  // Units of the data (for a depth frame in metres, 0.005 is a good start for a Kinect at about 1 m).
  double voxel_size = 0.0;

  // pcl::StatisticalOutlierRemoval: a point goes when its mean distance to its `outlier_neighbours` nearest
  // neighbours exceeds the mean of that quantity over the cloud by `outlier_stddev` standard deviations.
  // Defaults are PCL's tutorial values (50, 1.0).
  bool remove_outliers = false;
  int outlier_neighbours = 50;
  double outlier_stddev = 1.0;

  // pcl::NormalEstimationOMP: plane fit to the `normal_neighbours` nearest points, flipped to face the sensor
  // position. Points whose neighbourhood gives no normal (too few or collinear neighbours) are dropped and
  // counted, so that points and normals stay one to one.
  bool estimate_normals = false;
  int normal_neighbours = 20;
};

struct PreprocessResult {
  Eigen::Matrix3Xd points;   // same units and frame as the input
  Eigen::Matrix3Xd normals;  // unit normals facing the sensor, one per point; empty unless estimated
  Eigen::Index input = 0;
  Eigen::Index removed_by_crop = 0;
  Eigen::Index removed_by_voxel = 0;  // points merged away (input to the grid minus occupied voxels)
  Eigen::Index removed_as_outliers = 0;
  Eigen::Index removed_without_normal = 0;
};

// `sensor_position` in the points' coordinates (the origin for a depth frame's camera frame); used only to
// orient normals. Throws std::invalid_argument for empty or non-finite input, an inverted crop box, a voxel
// size so small that PCL's grid index would overflow, or non-positive step settings of an enabled step.
PreprocessResult Preprocess(const Eigen::Matrix3Xd& points, const Eigen::Vector3d& sensor_position,
                            const PreprocessOptions& options);

}  // namespace s2m
