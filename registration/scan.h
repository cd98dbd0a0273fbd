#pragma once
// A scan: one view of a part, in the scanner's own coordinates, with the pose that places it in the world.

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "registration/rigid_motion.h"

namespace s2m {

struct ScanMetadata {
  std::string device;                         // e.g. "virtual:kinect", "horus", "file"
  std::optional<double> timestamp_s;          // acquisition time, seconds since the Unix epoch
  std::optional<double> turntable_angle_rad;  // nominal turntable angle of this view
  std::string source;                         // where the scan came from (file path, recording and frame)
  std::vector<std::string> notes;             // what the source did to the data (e.g. invalid points dropped)
};

struct Scan {
  Eigen::Matrix3Xd points;   // double precision, scan coordinates, one point per column
  Eigen::Matrix3Xd normals;  // empty, or one unit normal per point
  Eigen::VectorXd weights;   // empty, or one non-negative weight per point
  // Empty, or one integer label per point (PCD's `label` field, e.g. a ground-truth segmentation).
  std::vector<std::int64_t> labels;
  RigidMotion world_T_scan;       // maps scan coordinates to world coordinates
  std::string units = "unknown";  // "mm", "m", ... as declared by the source; never guessed
  ScanMetadata metadata;

  Eigen::Index size() const { return points.cols(); }
  bool empty() const { return points.cols() == 0; }
  bool has_normals() const { return normals.cols() == points.cols() && points.cols() > 0; }
  bool has_weights() const { return weights.size() == points.cols() && points.cols() > 0; }

  // Points (and normals) mapped into the world frame by world_T_scan.
  Eigen::Matrix3Xd WorldPoints() const { return world_T_scan.apply(points); }
  Eigen::Matrix3Xd WorldNormals() const { return world_T_scan.rotation() * normals; }
};

// Several views of one part (multi-view); views share units.
struct ScanSet {
  std::string name;
  std::vector<Scan> scans;

  Eigen::Index TotalPoints() const;
  // All views merged in the world frame (the initially registered cloud).
  Eigen::Matrix3Xd MergedWorldPoints() const;
};

struct Bounds {
  Eigen::Vector3d min = Eigen::Vector3d::Zero();
  Eigen::Vector3d max = Eigen::Vector3d::Zero();
  Eigen::Vector3d extent() const { return max - min; }
  double diagonal() const { return extent().norm(); }
};
Bounds ComputeBounds(const Eigen::Matrix3Xd& points);

}  // namespace s2m
