#pragma once
// Calibration of a Horus/Ciclop-style laser-line turntable scanner (issue 6) with a chessboard pattern, and
// the calibration's JSON form (stored in a recording's calibration JSON under the key "horus"). Three
// procedures, each returning its estimate with residuals so the user sees its quality
// (docs/laser-scanning.md):
//   1. camera intrinsics: Zhang's method (cv::calibrateCamera) over pattern images in varied poses;
//   2. laser planes: the pattern on the platform at several turntable angles; the lit line's pixels on the
//      pattern are triangulated onto the pattern's plane (its pose from cv::solvePnP), and one plane is
//      fitted through all these points per laser;
//   3. the turntable axis: every pattern corner traces a circle about the axis as the table turns; the
//   circles'
//      planes give the axis direction and their centres a point on it -> platform_T_camera.
// The capture functions drive a TurntableBoard and an ImageCamera, so the same code calibrates the real board
// and camera or the virtual rig (devices/virtual_horus.h). OpenCV appears only in horus_calibration.cpp.

#include <Eigen/Core>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "devices/horus_interfaces.h"

namespace s2m {

// ------------------------------------------------------------------------------------------------ JSON

// {"camera": {"width", "height", "fx", "fy", "cx", "cy", "distortion": [k1, k2, p1, p2, k3]},
//  "lasers": [{"normal": [x, y, z], "distance": d}, ...], "platform_T_camera": 4x4 row-major rows}, mm.
nlohmann::json HorusCalibrationToJson(const HorusCalibration& calibration);
// Throws std::invalid_argument naming the missing or malformed field (and `what`, e.g. the file name).
HorusCalibration HorusCalibrationFromJson(const nlohmann::json& json,
                                          const std::string& what = "calibration");
// A calibration document (a recording's calibration JSON, or the file `scan2model calibrate` writes): the
// calibration under its "horus" key. ReadHorusCalibrationFile throws std::runtime_error naming the file when
// it is missing, not JSON, has no "horus" key or a malformed calibration.
HorusCalibration HorusCalibrationFromDocument(const nlohmann::json& document,
                                              const std::string& what = "calibration");
HorusCalibration ReadHorusCalibrationFile(const std::filesystem::path& path);

// --------------------------------------------------------------------------------------------- pattern

// A chessboard: `columns` x `rows` inner corners, squares `square` mm. Its frame (OpenCV's object points):
// the first inner corner (top left as the camera sees the board standing on the platform) at the origin, x
// along a row of corners to the right, y down the board, z into the board. Ciclop's pattern: 11 x 6 corners,
// 13 mm.
struct ChessboardPattern {
  int columns = 11, rows = 6;
  double square = 13.0;
  // Height of the lowest row of corners above the platform's surface when the pattern stands on the platform
  // (Horus calls it the pattern's origin distance); places the platform frame's origin on the table surface.
  double bottom_row_height = 30.0;
  std::vector<Eigen::Vector3d> ObjectPoints() const;  // row-major: index = row * columns + column
};

// The inner corners, sub-pixel (cv::findChessboardCorners, then cv::cornerSubPix), ordered like ObjectPoints
// (the first one top left in the image). nullopt when the pattern is not found.
std::optional<std::vector<Eigen::Vector2d>> DetectChessboard(const Image8& image,
                                                             const ChessboardPattern& pattern);

// ------------------------------------------------------------------------------------------ procedures

struct IntrinsicsEstimate {
  CameraIntrinsics camera;
  double rms_px = 0.0;        // reprojection RMS over all corners used
  int images_used = 0;        // images in which the pattern was found
  std::vector<int> rejected;  // indices of images without a detected pattern
};
// Throws std::runtime_error when fewer than 3 images show the pattern.
IntrinsicsEstimate CalibrateIntrinsics(const std::vector<Image8>& images, const ChessboardPattern& pattern);

// One turntable stop of a calibration sweep: the pattern with all lasers off, then with each laser on alone.
struct PatternCapture {
  double angle_rad = 0.0;
  Image8 off;
  std::vector<Image8> lasers;  // one per laser
};
using CalibrationProgress = std::function<void(const std::string& message)>;

// Drives the board through `angles_rad` (absolute turntable angles), capturing at each stop; leaves lasers
// off and the table at the last angle. Throws DeviceError from the board or camera.
std::vector<PatternCapture> CapturePatternSweep(TurntableBoard& board, ImageCamera& camera,
                                                const std::vector<double>& angles_rad, int lasers,
                                                const CalibrationProgress& progress = {});

// Captures `count` images for intrinsics calibration: before each, `present_pose(k)` puts the pattern in its
// k-th pose (the virtual rig places it; with a real camera, ask the user to move it and wait). Lasers off.
std::vector<Image8> CaptureIntrinsicsImages(TurntableBoard& board, ImageCamera& camera, int count,
                                            const std::function<void(int)>& present_pose,
                                            const CalibrationProgress& progress = {});

// A captured calibration set on disk: <dir>/calibration_images.json (format "scan2model.horus_images/1": the
// pattern, the intrinsics images' and the sweep's file names and angles) beside the PNG images, so a set
// taken on a real device can be calibrated again later (`scan2model calibrate --images <dir>`). Write throws
// std::runtime_error naming the file; Read throws std::runtime_error naming the missing or bad file or field.
void WriteCalibrationImages(const std::filesystem::path& directory,
                            const std::vector<Image8>& intrinsics_images,
                            const std::vector<PatternCapture>& sweep, const ChessboardPattern& pattern);
struct CalibrationImages {
  ChessboardPattern pattern;
  std::vector<Image8> intrinsics_images;
  std::vector<PatternCapture> sweep;
};
CalibrationImages ReadCalibrationImages(const std::filesystem::path& directory);

struct LaserPlanesEstimate {
  std::vector<LaserPlane> planes;  // camera frame
  std::vector<double> rms_mm;      // RMS distance of the triangulated points from each fitted plane
  std::vector<int> points;         // points per plane
  int poses_used = 0;              // captures in which the pattern was found
};
// Throws std::runtime_error when a laser has too few points on the pattern or they are (nearly) collinear.
LaserPlanesEstimate CalibrateLaserPlanes(const std::vector<PatternCapture>& captures,
                                         const CameraIntrinsics& camera, const ChessboardPattern& pattern);

struct TurntableAxisEstimate {
  RigidMotion platform_T_camera;  // z up the axis, origin on it at the table surface, x = camera x projected
  Eigen::Vector3d axis_direction_camera = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d axis_point_camera = Eigen::Vector3d::Zero();
  double circle_rms_mm = 0.0;  // RMS distance of the corners' positions from their fitted circles
  double centre_rms_mm = 0.0;  // RMS distance of the circles' centres from the axis
  int poses_used = 0;
};
// Needs the pattern found at >= 3 angles spanning a few tens of degrees; throws std::runtime_error otherwise.
TurntableAxisEstimate CalibrateTurntableAxis(const std::vector<PatternCapture>& captures,
                                             const CameraIntrinsics& camera,
                                             const ChessboardPattern& pattern);

// The pattern's pose in the camera frame from its corners (cv::solvePnP, iterative), with the reprojection
// RMS.
std::optional<RigidMotion> PatternPose(const Image8& image, const CameraIntrinsics& camera,
                                       const ChessboardPattern& pattern, double* rms_px = nullptr);

// All three in a row for a rig: `intrinsics_images` (pattern in varied poses, captured by the caller: a real
// pattern is moved by hand), then a sweep over `angles_rad` with the pattern standing on the platform.
struct HorusCalibrationReport {
  HorusCalibration calibration;
  IntrinsicsEstimate intrinsics;
  LaserPlanesEstimate lasers;
  TurntableAxisEstimate axis;
  nlohmann::json Summary() const;  // the residuals, for printing and for the calibration file
};
HorusCalibrationReport CalibrateHorus(const std::vector<Image8>& intrinsics_images,
                                      const std::vector<PatternCapture>& sweep,
                                      const ChessboardPattern& pattern);

}  // namespace s2m
