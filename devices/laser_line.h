#pragma once
// Laser-line scanning (issue 6): the lit line's sub-pixel position in each image row, and its triangulation
// with a calibrated camera and laser plane into the camera, platform and object (turntable angle 0) frames.
// OpenCV appears only in devices/laser_line.cpp (cv::undistortPoints).

#include <Eigen/Core>
#include <vector>

#include "devices/horus_interfaces.h"

namespace s2m {

// Per image row: the difference d(c) = max(0, on(c) - off(c)) of one channel between the laser-on and the
// laser-off frame removes the ambient light and the object's own texture (Horus does the same). The row's
// peak is its maximum; where it is at least `threshold`, its sub-pixel column comes from the samples within
// `half_window` of it (Fisher and Naidu, "A comparison of algorithms for subpixel peak detection", 1996):
//   kCenterOfMass: sum c (d(c) - t) / sum (d(c) - t) over the contiguous samples above t = threshold,
//   kGaussian:     the 3-point Gaussian fit  c0 + (ln d- - ln d+) / (2 (ln d- - 2 ln d0 + ln d+)),
//   kParabola:     the 3-point parabola fit  c0 + (d- - d+) / (2 (d- - 2 d0 + d+)).
// Fisher and Naidu found the Gaussian fit and the centre of mass the least biased for Gaussian-like profiles.
struct LaserExtractionOptions {
  enum class Method { kCenterOfMass, kGaussian, kParabola };
  Method method = Method::kCenterOfMass;
  int channel = 2;      // of a 3-channel BGR image: 2 = red (ignored for grey images)
  int threshold = 20;   // minimum peak of the difference, grey levels
  int half_window = 6;  // pixels either side of the maximum that may contribute
  int max_width = 40;   // rows whose contiguous lit run is wider than this are rejected (reflections)
  int min_row = 0, max_row = -1;  // rows searched (max_row < 0: to the last)
  // Optional region: only columns in [column_min[row], column_max[row]] (both per row, empty: all columns).
  std::vector<int> column_min, column_max;
};

// The sub-pixel laser line: x = column, y = row (pixel centres at integer coordinates, OpenCV's convention),
// at most one point per row. Throws std::invalid_argument when the two images differ in size or channels.
std::vector<Eigen::Vector2d> ExtractLaserLine(const Image8& laser_on, const Image8& laser_off,
                                              const LaserExtractionOptions& options = {});

// Pixels to 3D points in the camera frame (mm): each pixel is undistorted (cv::undistortPoints with the
// intrinsics' Brown-Conrady model), its ray r = (x_n, y_n, 1) meets the laser plane n . x = d at
//   x = r d / (n . r)
// (Hartley and Zisserman, Multiple View Geometry, 2nd ed., section 8.1: a ray meeting a plane). Rays nearly
// parallel to the plane (|n . r| < 1e-9 |r|) or meeting it behind the camera are dropped. Throws
// std::out_of_range for a laser the calibration does not have.
Eigen::Matrix3Xd TriangulateLaserLine(const std::vector<Eigen::Vector2d>& pixels,
                                      const HorusCalibration& calibration, int laser);

// Camera-frame points to the object's frame (the platform frame at turntable angle 0) for a frame taken at
// turntable angle `angle_rad`: p = Rz(-angle) platform_T_camera x (the convention of HorusCalibration).
Eigen::Matrix3Xd CameraToObject(const Eigen::Matrix3Xd& camera_points, const HorusCalibration& calibration,
                                double angle_rad);

// Convenience: extraction, triangulation and CameraToObject. Points below the table (z < min_z) or farther
// than max_radius from the axis are dropped (the platform itself and the background; max_radius <= 0: none).
Eigen::Matrix3Xd ScanLaserLine(const Image8& laser_on, const Image8& laser_off,
                               const HorusCalibration& calibration, int laser, double angle_rad,
                               const LaserExtractionOptions& options = {}, double min_z = 0.5,
                               double max_radius = 0.0);

// Pixel projection with the intrinsics' distortion (OpenCV's model, without OpenCV): camera-frame point to
// pixel. And the inverse ray of a pixel (x_n, y_n, 1) by fixed-point iteration as cv::undistortPoints does.
Eigen::Vector2d ProjectToPixel(const CameraIntrinsics& camera, const Eigen::Vector3d& camera_point);
Eigen::Vector3d PixelRay(const CameraIntrinsics& camera, const Eigen::Vector2d& pixel);

}  // namespace s2m
