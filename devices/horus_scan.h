#pragma once
// The scan loop of a Horus/Ciclop-style laser-line turntable scanner (issue 6, docs/horus-scan.md): turn the
// table step by step, take a laser-off frame and one laser-on frame per laser, turn each pair into the laser
// line's points in the camera frame, and record every profile the moment it is acquired (acquisition/
// recording.h: one committed transaction per frame), so that a scan stopped by a pulled cable keeps
// everything acquired so far and can be resumed where it stopped.
//
// The loop only knows the interfaces of devices/horus_interfaces.h and a profile function, so it runs the
// same against the real board and camera (libusb, OpenCV), the virtual rig, or the fakes of the tests.
// Nothing here includes OpenCV or libusb.

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "devices/horus_interfaces.h"

namespace s2m {

// The laser line of one (laser-on, laser-off) image pair as points in the camera frame, millimetres (the
// CLI passes ExtractLaserLine + TriangulateLaserLine of devices/laser_line.h). May return no points (the
// line missed the object).
using LaserProfileFunction =
    std::function<Eigen::Matrix3Xd(const Image8& laser_on, const Image8& laser_off, int laser)>;

struct HorusScanOptions {
  // Turntable steps per full turn: 400 -> 0.9 degrees per step (Horus's default resolution is 0.45-1.8 deg).
  int steps = 400;
  // The lasers to use, in acquisition order (0: left = firmware T1, 1: right = T2).
  std::vector<int> lasers = {0, 1};
  double feed_rate_deg_s = 200.0;      // G1 F<n>; Horus's default motor speed
  double acceleration_deg_s2 = 200.0;  // $120=<n>; Horus's default motor acceleration
  double settle_s = 0.1;               // wait after each move before capturing (table vibration, exposure)
  double start_angle_deg = 0.0;        // the angle of step 0; step k is at start + k * 360 / steps
  // How frames are grouped into views. kStepAndLaser (default, issue 6): one view per (step, laser), view =
  // step * lasers.size() + laser index -- every profile is its own view, as the hardware acquires it.
  // kLaserSweep: one view per laser (view = laser index), every profile of a turn in it, which is what the
  // multi-view fit wants (a single laser line cannot be registered on its own; a full sweep can).
  enum class ViewGrouping { kStepAndLaser, kLaserSweep };
  ViewGrouping views = ViewGrouping::kStepAndLaser;
  // Store the raw images too: PGM/PPM files in the folder "<recording>.images" beside the recording
  // (step_SSSS_off.pgm, step_SSSS_laserL.pgm), not in the recording: its stream kinds are points, depth and
  // profile only.
  bool store_images = false;
  // true: `out` exists and holds an interrupted scan with the same options and calibration; acquire the
  // (step, laser) pairs after the last one recorded. false: `out` must not exist.
  bool resume = false;
  // The device's description (JSON object text) recorded in the recording; empty: {"name": "horus"} with the
  // board's banner and the camera's name.
  std::string device_json;
  // How the loop waits `settle_s` (tests pass a no-op); empty: std::this_thread::sleep_for.
  std::function<void(double seconds)> sleep;
};

// After each (step, laser) pair: pairs done so far (the resumed ones included) of the total, and the
// estimated time left from the pace of this run.
struct HorusScanProgress {
  std::int64_t done = 0, total = 0;
  int step = 0, laser = 0;  // the pair just acquired
  double elapsed_s = 0.0;   // this run
  std::optional<double> eta_s;
};
using HorusScanProgressFunction = std::function<void(const HorusScanProgress&)>;

struct HorusScanResult {
  std::filesystem::path recording;
  std::int64_t done = 0;          // (step, laser) pairs acquired, all runs
  std::int64_t total = 0;         // steps * lasers
  std::int64_t resumed_from = 0;  // pairs already in the recording when this run started
  std::int64_t frames = 0;  // profile frames in the recording (pairs with an empty profile are not recorded)
  std::int64_t empty_profiles = 0;  // this run
  std::string status;               // the recording's meta status: complete or "interrupted: <reason>"
  bool complete = false;
  std::optional<DeviceError::Kind> error_kind;  // why it stopped early
  std::string error;                            // the device's message
};

// Runs (or resumes) a scan into the recording `out`. Sequence: Reset (handshake), feed rate, acceleration,
// motor on, lasers off; per step: move, settle, laser-off frame, per laser: laser on, capture, laser off,
// profile, record; finally lasers off and motor off -- also when anything fails. Device errors (DeviceError
// of any kind: disconnected, timeout, stall...) stop the scan and are returned in the result with the
// recording kept (status "interrupted: <message>"); bad options, a refused resume or a recording that cannot
// be written throw (std::invalid_argument, FormatError naming the file). Frame poses: world_T_scan =
// Rz(-theta) * platform_T_camera (devices/horus_interfaces.h), the nominal turntable angle theta recorded
// with each frame.
HorusScanResult RunHorusScan(TurntableBoard& board, ImageCamera& camera, const HorusCalibration& calibration,
                             const LaserProfileFunction& profile, const std::filesystem::path& out,
                             const HorusScanOptions& options, const HorusScanProgressFunction& progress = {});

// The recorded scan options (meta "horus.scan_options", JSON): everything that shapes the frames (steps,
// lasers, start angle, view grouping, feed rate, acceleration, settle time); a resume must match them.
std::string HorusScanOptionsToJson(const HorusScanOptions& options);

// The "horus" member of the recording's calibration JSON: exactly HorusCalibrationToJson's form
// (devices/horus_calibration.h; tested equal), written here so that the scan loop needs no OpenCV library:
// {"camera": {...}, "lasers": [...], "platform_T_camera": 4 rows of 4, "units": "mm"}.
std::string HorusCalibrationJson(const HorusCalibration& calibration);

// Where a scan's images go when HorusScanOptions::store_images is set.
std::filesystem::path HorusImageFolder(const std::filesystem::path& recording);

}  // namespace s2m
