// Laser-line extraction and triangulation: devices/laser_line.h.

#include "devices/laser_line.h"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <stdexcept>
#include <string>

namespace s2m {

std::vector<Eigen::Vector2d> ExtractLaserLine(const Image8& on, const Image8& off,
                                              const LaserExtractionOptions& o) {
  if (on.width != off.width || on.height != off.height || on.channels != off.channels)
    throw std::invalid_argument("laser line: the laser-on image (" + std::to_string(on.width) + "x" +
                                std::to_string(on.height) + "x" + std::to_string(on.channels) +
                                ") and the laser-off image (" + std::to_string(off.width) + "x" +
                                std::to_string(off.height) + "x" + std::to_string(off.channels) + ") differ");
  if (on.pixels.size() != static_cast<std::size_t>(on.width) * on.height * on.channels)
    throw std::invalid_argument("laser line: the image's pixel buffer does not match its size");
  const int channel = on.channels == 1 ? 0 : std::clamp(o.channel, 0, on.channels - 1);
  const int last_row = o.max_row < 0 ? on.height - 1 : std::min(o.max_row, on.height - 1);
  std::vector<Eigen::Vector2d> line;
  std::vector<int> d(static_cast<std::size_t>(on.width));
  for (int row = std::max(0, o.min_row); row <= last_row; ++row) {
    int c_lo = 0, c_hi = on.width - 1;
    if (static_cast<std::size_t>(row) < o.column_min.size()) c_lo = std::max(c_lo, o.column_min[row]);
    if (static_cast<std::size_t>(row) < o.column_max.size()) c_hi = std::min(c_hi, o.column_max[row]);
    if (c_lo > c_hi) continue;
    int best = -1, peak = 0;
    for (int c = c_lo; c <= c_hi; ++c) {
      d[c] =
          std::max(0, static_cast<int>(on.at(row, c, channel)) - static_cast<int>(off.at(row, c, channel)));
      if (d[c] > peak) peak = d[c], best = c;
    }
    if (best < 0 || peak < o.threshold) continue;
    // The contiguous run above the threshold around the maximum, clipped to the window.
    int lo = best, hi = best;
    while (lo > c_lo && d[lo - 1] >= o.threshold) --lo;
    while (hi < c_hi && d[hi + 1] >= o.threshold) ++hi;
    if (hi - lo + 1 > o.max_width) continue;
    lo = std::max(lo, best - o.half_window);
    hi = std::min(hi, best + o.half_window);
    double column = best;
    const bool inside = best > c_lo && best < c_hi;
    switch (o.method) {
      case LaserExtractionOptions::Method::kCenterOfMass: {
        double sw = 0, swc = 0;
        for (int c = lo; c <= hi; ++c) {
          const double w = d[c] - o.threshold + 1.0;  // > 0 on the run
          sw += w;
          swc += w * c;
        }
        column = swc / sw;
        break;
      }
      case LaserExtractionOptions::Method::kGaussian:
        if (inside && d[best - 1] > 0 && d[best + 1] > 0) {
          const double a = std::log(d[best - 1]), b = std::log(d[best]), c = std::log(d[best + 1]);
          const double den = a - 2 * b + c;
          if (den < 0) column = best + 0.5 * (a - c) / den;
        }
        break;
      case LaserExtractionOptions::Method::kParabola:
        if (inside) {
          const double a = d[best - 1], b = d[best], c = d[best + 1];
          const double den = a - 2 * b + c;
          if (den < 0) column = best + 0.5 * (a - c) / den;
        }
        break;
    }
    line.emplace_back(column, row);
  }
  return line;
}

Eigen::Matrix3Xd TriangulateLaserLine(const std::vector<Eigen::Vector2d>& pixels,
                                      const HorusCalibration& calibration, int laser) {
  if (laser < 0 || static_cast<std::size_t>(laser) >= calibration.lasers.size())
    throw std::out_of_range("laser " + std::to_string(laser) + ": the calibration has " +
                            std::to_string(calibration.lasers.size()) + " laser plane(s)");
  if (pixels.empty()) return Eigen::Matrix3Xd(3, 0);
  const CameraIntrinsics& k = calibration.camera;
  std::vector<cv::Point2d> in, out;
  in.reserve(pixels.size());
  for (const auto& p : pixels) in.emplace_back(p.x(), p.y());
  const cv::Matx33d camera_matrix(k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
  const std::vector<double> distortion(k.distortion.begin(), k.distortion.end());
  // Default criteria are 5 fixed-point iterations; more for cameras with strong distortion.
  cv::undistortPoints(in, out, camera_matrix, distortion, cv::noArray(), cv::noArray(),
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 20, 1e-12));
  const LaserPlane& plane = calibration.lasers[static_cast<std::size_t>(laser)];
  Eigen::Matrix3Xd points(3, static_cast<Eigen::Index>(out.size()));
  Eigen::Index n = 0;
  for (const auto& q : out) {
    const Eigen::Vector3d r(q.x, q.y, 1.0);
    const double nr = plane.normal.dot(r);
    if (std::abs(nr) < 1e-9 * r.norm()) continue;
    const double s = plane.distance / nr;
    if (s <= 0) continue;
    points.col(n++) = s * r;
  }
  points.conservativeResize(3, n);
  return points;
}

Eigen::Matrix3Xd CameraToObject(const Eigen::Matrix3Xd& camera_points, const HorusCalibration& calibration,
                                double angle_rad) {
  const Eigen::Matrix3d rz = RotationAboutAxis(Eigen::Vector3d::UnitZ(), -angle_rad);
  return (RigidMotion(rz, Eigen::Vector3d::Zero()) * calibration.platform_T_camera).apply(camera_points);
}

Eigen::Matrix3Xd ScanLaserLine(const Image8& on, const Image8& off, const HorusCalibration& calibration,
                               int laser, double angle_rad, const LaserExtractionOptions& options,
                               double min_z, double max_radius) {
  const Eigen::Matrix3Xd camera =
      TriangulateLaserLine(ExtractLaserLine(on, off, options), calibration, laser);
  const Eigen::Matrix3Xd object = CameraToObject(camera, calibration, angle_rad);
  Eigen::Matrix3Xd kept(3, object.cols());
  Eigen::Index n = 0;
  for (Eigen::Index i = 0; i < object.cols(); ++i) {
    const Eigen::Vector3d p = object.col(i);
    if (p.z() < min_z) continue;
    if (max_radius > 0 && p.head<2>().norm() > max_radius) continue;
    kept.col(n++) = p;
  }
  kept.conservativeResize(3, n);
  return kept;
}

Eigen::Vector2d ProjectToPixel(const CameraIntrinsics& k, const Eigen::Vector3d& x) {
  // OpenCV's projection (docs of calib3d): x' = x/z, y' = y/z, r^2 = x'^2 + y'^2,
  // x'' = x' (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x' y' + p2 (r^2 + 2 x'^2), y'' likewise; u = fx x'' + cx.
  const double xp = x.x() / x.z(), yp = x.y() / x.z();
  const auto& d = k.distortion;
  const double r2 = xp * xp + yp * yp;
  const double radial = 1 + r2 * (d[0] + r2 * (d[1] + r2 * d[4]));
  const double xpp = xp * radial + 2 * d[2] * xp * yp + d[3] * (r2 + 2 * xp * xp);
  const double ypp = yp * radial + d[2] * (r2 + 2 * yp * yp) + 2 * d[3] * xp * yp;
  return {k.fx * xpp + k.cx, k.fy * ypp + k.cy};
}

Eigen::Vector3d PixelRay(const CameraIntrinsics& k, const Eigen::Vector2d& pixel) {
  const double x0 = (pixel.x() - k.cx) / k.fx, y0 = (pixel.y() - k.cy) / k.fy;
  const auto& d = k.distortion;
  double x = x0, y = y0;
  if (d[0] != 0 || d[1] != 0 || d[2] != 0 || d[3] != 0 || d[4] != 0) {
    for (int i = 0; i < 20; ++i) {  // the fixed point of cv::undistortPoints
      const double r2 = x * x + y * y;
      const double radial = 1 + r2 * (d[0] + r2 * (d[1] + r2 * d[4]));
      const double dx = 2 * d[2] * x * y + d[3] * (r2 + 2 * x * x);
      const double dy = d[2] * (r2 + 2 * y * y) + 2 * d[3] * x * y;
      x = (x0 - dx) / radial;
      y = (y0 - dy) / radial;
    }
  }
  return {x, y, 1.0};
}

}  // namespace s2m
