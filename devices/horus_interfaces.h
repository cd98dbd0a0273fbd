#pragma once
// The parts of a Horus/Ciclop-style laser-line turntable scanner (issue 6), as interfaces, so that the scan
// loop (devices/horus_scan.h) runs the same against the real board (libusb, devices/horus_board.h), an
// emulated one (umockdev in the tests), a real camera (OpenCV/V4L2, devices/opencv_camera.h) or rendered
// images (the virtual scanner). Nothing here includes libusb or OpenCV headers: images are plain byte
// buffers.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "registration/rigid_motion.h"

namespace s2m {

// What a device does wrong, with the action a user can take. `kind` lets callers react (a scan keeps what it
// acquired when the device is disconnected; a stall or timeout may be retried).
class DeviceError : public std::runtime_error {
 public:
  enum class Kind { kNotFound, kPermission, kBusy, kDisconnected, kTimeout, kStall, kProtocol, kOther };
  DeviceError(Kind kind, const std::string& message) : std::runtime_error(message), kind_(kind) {}
  Kind kind() const { return kind_; }

 private:
  Kind kind_;
};

// An 8-bit image, row-major, `channels` interleaved bytes per pixel (1: grey; 3: B, G, R as OpenCV stores
// them).
struct Image8 {
  int width = 0, height = 0, channels = 1;
  std::vector<std::uint8_t> pixels;  // width * height * channels
  std::uint8_t at(int row, int col, int channel = 0) const {
    return pixels[(static_cast<std::size_t>(row) * width + col) * channels + channel];
  }
};

// The turntable board: an Arduino-class board speaking G-code over USB CDC-ACM (Horus firmware). Every call
// blocks until the board acknowledges and throws DeviceError on failure.
class TurntableBoard {
 public:
  virtual ~TurntableBoard() = default;
  virtual std::string Banner() const = 0;                        // "Horus 0.1 ['$' for help]"
  virtual void EnableMotor(bool on) = 0;                         // M17 / M18
  virtual void SetFeedRate(double degrees_per_second) = 0;       // G1 F<n>
  virtual void SetAcceleration(double degrees_per_second2) = 0;  // $120=<n>
  virtual void MoveTo(double absolute_degrees) = 0;              // G1 X<deg>: absolute turntable angle
  virtual void SetLaser(int laser, bool on) = 0;                 // M71 T<n> / M70 T<n>; laser 0 is T1
  virtual int ReadLightSensor(int sensor) = 0;                   // M50 T<n>
  virtual void Reset() = 0;                                      // Ctrl-X, waits for the banner again
};

// A camera delivering frames on request (the latest frame after the call, not one buffered before it).
class ImageCamera {
 public:
  virtual ~ImageCamera() = default;
  virtual std::string Name() const = 0;
  virtual Image8 Capture() = 0;  // throws DeviceError (kDisconnected when the camera is gone)
};

// ------------------------------------------------------------------------------------------ calibration

// Pinhole camera with Brown-Conrady distortion (OpenCV's model: k1, k2, p1, p2, k3), pixels.
struct CameraIntrinsics {
  int width = 0, height = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  std::array<double, 5> distortion = {0, 0, 0, 0, 0};
};

// A laser plane in the camera frame: points x with normal . x = distance (normal unit, distance > 0).
struct LaserPlane {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitX();
  double distance = 0.0;
};

// Everything a Horus scan needs to turn pixels into turntable coordinates. The platform frame: origin on the
// turntable's axis at the table's surface, z up the axis, at turntable angle 0 (the world of a scan, as in
// devices/virtual_scanner.h). Lengths in millimetres.
struct HorusCalibration {
  CameraIntrinsics camera;
  std::vector<LaserPlane> lasers;  // laser 0, 1 in the camera frame
  RigidMotion platform_T_camera;   // camera coordinates to platform coordinates
  // Angle convention: a point p fixed on the table at angle theta is at Rz(theta) p in the platform frame at
  // 0, so a frame at angle theta has world_T_scan = Rz(-theta) * platform_T_camera.
};

}  // namespace s2m
