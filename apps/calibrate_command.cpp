// `scan2model calibrate`: calibrates a Horus-style laser-line turntable scanner (camera intrinsics, laser
// planes, turntable axis; devices/horus_calibration.h, docs/laser-scanning.md) by driving its board and
// camera -- a real scanner (horus,...: the user presents the pattern when asked) or the virtual rig
// (horus-virtual:<scene>,...) -- or from a captured image set (--images <dir>), and writes the calibration
// JSON ({"horus": ..., "residuals": ...}) with a summary of the residuals.

#include <cmath>
#include <filesystem>
#include <functional>
#include <iostream>
#include <memory>
#include <optional>
#include <string>

#include "apps/commands.h"
#include "devices/horus_calibration.h"
#include "devices/horus_rig.h"
#include "pipeline/output.h"
#ifdef S2M_HAVE_VIRTUAL_HORUS
#include "devices/virtual_horus.h"
#endif

namespace s2m::app {
namespace {

constexpr double kDegree = M_PI / 180.0;

// What a rig gives the calibration: the board and camera to drive, and how to present the pattern (the
// virtual rig places it; with a real scanner the user does, prompted on the terminal).
struct CalibrationRig {
  std::unique_ptr<TurntableBoard> board;
  std::unique_ptr<ImageCamera> camera;
  std::function<void(int)> present_hand_held;  // intrinsics pose k
  std::function<void()> present_standing;      // the pattern upright on the platform
  std::optional<HorusCalibration> truth;       // virtual rigs only
};

CalibrationRig OpenRig(const std::string& device, const ChessboardPattern& pattern, int poses) {
#ifdef S2M_HAVE_VIRTUAL_HORUS
  if (device.rfind("horus-virtual:", 0) == 0) {
    VirtualHorus v = MakeVirtualHorus(device);
    CalibrationRig rig;
    rig.board = std::move(v.board);
    rig.camera = std::move(v.camera);
    rig.truth = v.truth;
    std::shared_ptr<VirtualHorusRig> shared = v.rig;
    const std::vector<RigidMotion> hand = shared->HandHeldPatternPoses(pattern, poses);
    rig.present_hand_held = [shared, hand, pattern](int k) {
      shared->PlacePattern(pattern, hand[static_cast<std::size_t>(k)]);
    };
    rig.present_standing = [shared, pattern]() {
      shared->PlacePattern(pattern, VirtualHorusRig::StandingPatternPose(pattern));
    };
    return rig;
  }
#endif
  if (IsHorusDeviceSpec(device)) {
    // A real scanner (devices/horus_rig.h): the user moves the pattern; each capture waits for Enter, so the
    // pattern is still when the image is taken. A closed stdin (a script) stops the calibration cleanly.
    HorusRig opened = OpenHorusRig(device);
    CalibrationRig rig;
    rig.board = std::move(opened.board);
    rig.camera = std::move(opened.camera);
    rig.truth = opened.truth;
    auto keep_alive = opened.keep_alive;
    auto wait_for_enter = [keep_alive](const std::string& instruction) {
      std::cerr << instruction << " -- press Enter when it is still" << std::endl;
      std::string line;
      if (!std::getline(std::cin, line))
        throw std::runtime_error("calibration stopped: standard input closed while waiting for the pattern");
    };
    rig.present_hand_held = [wait_for_enter, pattern, poses](int k) {
      wait_for_enter("pose " + std::to_string(k + 1) + "/" + std::to_string(poses) + ": hold the " +
                     std::to_string(pattern.columns) + "x" + std::to_string(pattern.rows) +
                     " chessboard (inner corners) in view, tilted differently from the last pose");
    };
    rig.present_standing = [wait_for_enter]() {
      wait_for_enter("stand the chessboard upright on the platform, facing the camera");
    };
    return rig;
  }
  throw std::invalid_argument(
      "device '" + device +
      "': calibrate drives horus[,key=value...] or horus-virtual:<scene>[,key=value...] (this build: " +
#ifdef S2M_HAVE_VIRTUAL_HORUS
      "virtual rig available"
#else
      "no virtual rig: OpenCV or Open3D missing"
#endif
      "); or give --images <dir>");
}

double AngleBetween(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

// Estimate against the truth of a virtual rig.
nlohmann::json TruthErrors(const HorusCalibration& e, const HorusCalibration& t) {
  nlohmann::json j;
  j["fx_px"] = e.camera.fx - t.camera.fx;
  j["fy_px"] = e.camera.fy - t.camera.fy;
  j["cx_px"] = e.camera.cx - t.camera.cx;
  j["cy_px"] = e.camera.cy - t.camera.cy;
  j["lasers"] = nlohmann::json::array();
  for (std::size_t l = 0; l < e.lasers.size() && l < t.lasers.size(); ++l)
    j["lasers"].push_back({{"normal_deg", AngleBetween(e.lasers[l].normal, t.lasers[l].normal) / kDegree},
                           {"distance_mm", e.lasers[l].distance - t.lasers[l].distance}});
  const RigidMotion ce = e.platform_T_camera.inverse(), ct = t.platform_T_camera.inverse();
  j["axis_direction_deg"] = AngleBetween(ce.rotation().col(2), ct.rotation().col(2)) / kDegree;
  j["platform_origin_mm"] = (ce.translation() - ct.translation()).norm();
  return j;
}

void PrintSummary(const HorusCalibrationReport& r, std::ostream& out) {
  const CameraIntrinsics& k = r.calibration.camera;
  out << "camera: " << k.width << "x" << k.height << ", fx " << Format(k.fx, 6) << ", fy " << Format(k.fy, 6)
      << ", cx " << Format(k.cx, 6) << ", cy " << Format(k.cy, 6) << ", k1 " << Format(k.distortion[0], 4)
      << "; reprojection RMS " << Format(r.intrinsics.rms_px, 3) << " px over " << r.intrinsics.images_used
      << " images\n";
  for (std::size_t l = 0; l < r.lasers.planes.size(); ++l)
    out << "laser " << l << ": normal " << Format(r.lasers.planes[l].normal, 5) << ", distance "
        << Format(r.lasers.planes[l].distance, 6) << " mm; plane RMS " << Format(r.lasers.rms_mm[l], 3)
        << " mm over " << r.lasers.points[l] << " points\n";
  out << "turntable: axis " << Format(r.axis.axis_direction_camera, 5) << " through "
      << Format(r.axis.axis_point_camera, 5) << " (camera frame, mm); circle RMS "
      << Format(r.axis.circle_rms_mm, 3) << " mm over " << r.axis.poses_used << " poses\n";
}

}  // namespace

Runner AddCalibrateCommand(CLI::App& app) {
  struct Options {
    std::string device, images, out, save_images;
    int poses = 12, angles = 9;
    double range_deg = 45.0;
    ChessboardPattern pattern;
    bool quiet = false;
  };
  auto options = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand("calibrate",
                                     "Calibrate a Horus laser-line turntable scanner (camera, laser planes, "
                                     "turntable axis) with a chessboard");
  cmd->add_option(
      "--device", options->device,
      "horus-virtual:<vase|helical|spiral|part|mesh.ply>[,key=value...] (docs/laser-scanning.md)");
  cmd->add_option("--images", options->images,
                  "Instead of --device: a captured image set (calibration_images.json and its PNGs)");
  cmd->add_option("-o,--output,--out", options->out,
                  "The calibration JSON to write (--out: the old spelling, an alias for one release)")
      ->required();
  cmd->add_option("--save-images", options->save_images,
                  "Also write the captured images as an image set to this folder (for --images later)");
  cmd->add_option("--poses", options->poses, "Pattern poses for the camera intrinsics (12)")
      ->check(CLI::Range(3, 100));
  cmd->add_option("--angles", options->angles, "Turntable stops of the pattern sweep (9)")
      ->check(CLI::Range(3, 360));
  cmd->add_option("--range-deg", options->range_deg, "The sweep turns the table over +-this (45)")
      ->check(CLI::Range(5.0, 80.0));
  cmd->add_option("--pattern-columns", options->pattern.columns, "Inner corners per row (11)")
      ->check(CLI::Range(3, 50));
  cmd->add_option("--pattern-rows", options->pattern.rows, "Inner corners per column (6)")
      ->check(CLI::Range(3, 50));
  cmd->add_option("--square", options->pattern.square, "Square size, mm (13)")->check(CLI::PositiveNumber);
  cmd->add_option("--bottom-row-height", options->pattern.bottom_row_height,
                  "Height of the pattern's lowest corner row above the platform, mm (30)");
  cmd->add_flag("-q,--quiet", options->quiet, "No progress on standard error");
  return [options]() {
    try {
      if (options->device.empty() == options->images.empty())
        throw std::invalid_argument("give either --device horus-virtual:... or --images <dir>");
      std::vector<Image8> intrinsics;
      std::vector<PatternCapture> sweep;
      ChessboardPattern pattern = options->pattern;
      std::optional<HorusCalibration> truth;
      const CalibrationProgress progress = [options](const std::string& m) {
        if (!options->quiet) std::cerr << "calibrate: " << m << "\n";
      };
      if (!options->device.empty()) {
        CalibrationRig rig = OpenRig(options->device, pattern, options->poses);
        truth = rig.truth;
        intrinsics =
            CaptureIntrinsicsImages(*rig.board, *rig.camera, options->poses, rig.present_hand_held, progress);
        rig.present_standing();
        std::vector<double> angles;
        for (int k = 0; k < options->angles; ++k)
          angles.push_back((-options->range_deg + 2 * options->range_deg * k / (options->angles - 1)) *
                           kDegree);
        sweep = CapturePatternSweep(*rig.board, *rig.camera, angles, 2, progress);
        rig.board->MoveTo(0.0);
        if (!options->save_images.empty())
          WriteCalibrationImages(options->save_images, intrinsics, sweep, pattern);
      } else {
        CalibrationImages set = ReadCalibrationImages(options->images);
        pattern = set.pattern;
        intrinsics = std::move(set.intrinsics_images);
        sweep = std::move(set.sweep);
      }
      progress("estimating intrinsics, laser planes and turntable axis");
      const HorusCalibrationReport report = CalibrateHorus(intrinsics, sweep, pattern);
      nlohmann::json doc;
      doc["horus"] = HorusCalibrationToJson(report.calibration);
      doc["residuals"] = report.Summary();
      PrintSummary(report, std::cout);
      if (truth) {
        doc["errors_vs_truth"] = TruthErrors(report.calibration, *truth);
        std::cout << "against the virtual rig's truth: " << doc["errors_vs_truth"].dump() << "\n";
      }
      WriteTextAtomically(options->out, doc.dump(2) + "\n");
      std::cout << options->out << ": calibration written\n";
      return int{kOk};
    } catch (const std::invalid_argument& e) {
      return ReportError("calibrate", e.what(), kUsage, false);
    } catch (const DeviceError& e) {  // as `scan` reports it: the board or camera, not the input
      return ReportError("calibrate", e.what(), kDeviceError, false);
    } catch (const std::runtime_error& e) {  // a pattern not found, unreadable images, a file not written
      return ReportError("calibrate", e.what(), kInputError, false);
    }
  };
}

}  // namespace s2m::app
