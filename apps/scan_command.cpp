// `scan2model scan`: a Horus/Ciclop-style laser-line turntable scan (devices/horus_scan.h) from the real
// scanner or the virtual rig into a recording, with progress, resumable (docs/horus-scan.md).

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "acquisition/format_error.h"
#include "apps/commands.h"
#include "apps/stop_signal.h"
#include "devices/horus_interfaces.h"
#include "devices/horus_rig.h"
#include "devices/horus_scan.h"
#include "pipeline/output.h"
#ifdef S2M_HAVE_HORUS_OPENCV
#include "devices/horus_calibration.h"
#include "devices/laser_line.h"
#endif

namespace s2m::app {
namespace {

namespace fs = std::filesystem;

// Ctrl-C or SIGTERM during a scan (apps/stop_signal.h): the loop stops after the pair in progress, switches
// lasers and motor off and marks the recording interrupted (resumable), instead of dying with the lasers on.
[[maybe_unused]] std::string StopReason() {
  const std::string signal = StopOnSignals::SignalName();
  return signal == "SIGTERM" ? "stopped by SIGTERM" : "interrupted by the user (Ctrl-C)";
}

[[maybe_unused]] std::string Duration(double seconds) {
  const auto s = static_cast<long>(std::lround(seconds));
  std::ostringstream out;
  if (s >= 3600) out << s / 3600 << "h";
  if (s >= 60) out << (s % 3600) / 60 << "m";
  out << s % 60 << "s";
  return out.str();
}

// A bar redrawn in place on a terminal, one line per tenth otherwise (logs), as `record` does.
[[maybe_unused]] HorusScanProgressFunction ScanProgressBar(bool quiet) {
  const bool tty = isatty(STDERR_FILENO) != 0;
  auto last_tenth = std::make_shared<std::int64_t>(-1);
  return [quiet, tty, last_tenth](const HorusScanProgress& p) {
    if (StopOnSignals::Requested()) throw std::runtime_error(StopReason());
    if (quiet || p.total <= 0) return;
    const std::string eta = p.eta_s ? ", " + Duration(*p.eta_s) + " left" : "";
    if (tty) {
      constexpr int kWidth = 30;
      const auto filled = static_cast<int>(kWidth * p.done / p.total);
      std::cerr << "\rscanning [" << std::string(static_cast<std::size_t>(filled), '#')
                << std::string(static_cast<std::size_t>(kWidth - filled), ' ') << "] " << p.done << "/"
                << p.total << " (step " << p.step << ", laser " << p.laser << ")" << eta << "   "
                << (p.done == p.total ? "\n" : "") << std::flush;
    } else if (const std::int64_t tenth = 10 * p.done / p.total; tenth != *last_tenth) {
      *last_tenth = tenth;
      std::cerr << "scanning: " << p.done << "/" << p.total << " (step, laser) pairs" << eta << "\n";
    }
  };
}

#ifdef S2M_HAVE_HORUS_OPENCV
HorusCalibration ReadCalibration(const std::string& file) {
  std::ifstream in(file);
  if (!in) throw FormatError(file, "", "cannot open the calibration");
  const nlohmann::json j = nlohmann::json::parse(in, nullptr, false);
  if (j.is_discarded()) throw FormatError(file, "", "not JSON");
  // A calibration file, or a recording's calibration JSON (the calibration under "horus").
  try {
    return HorusCalibrationFromJson(j.is_object() && j.contains("horus") ? j["horus"] : j, file);
  } catch (const std::invalid_argument& e) {
    throw FormatError(file, "", e.what());
  }
}
#endif

}  // namespace

Runner AddScanCommand(CLI::App& app) {
  struct Options {
    std::string device, calibration, out, views = "step";
    int steps = 400;
    std::vector<int> lasers = {0, 1};
    bool resume = false, images = false, quiet = false;
    double feed_rate = 200.0, acceleration = 200.0, settle = 0.1, start_angle = 0.0;
    double min_z = 0.5, max_radius = 0.0;
    int threshold = 20;
  };
  auto o = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand(
      "scan", "Scan with a Horus/Ciclop laser-line turntable scanner into a recording (docs/horus-scan.md)");
  cmd->add_option("--device", o->device,
                  "horus[,camera=/dev/video0,vid=0x2341,pid=0x0043,serial=...] or "
                  "horus-virtual:<scene>[,key=value...]")
      ->required();
  cmd->add_option(
      "--calibration", o->calibration,
      "Calibration JSON (scan2model calibrate); horus-virtual without it: the rig's true calibration");
  cmd->add_option("-o,--output,--out", o->out,
                  "The recording (.s2mrec); never overwritten, see --resume (--out: the old spelling, an "
                  "alias for one release)")
      ->required();
  cmd->add_option("--steps", o->steps, "Turntable steps per turn (400: 0.9 degrees)");
  cmd->add_option("--lasers", o->lasers, "Lasers to use, in order (0,1)")->delimiter(',');
  cmd->add_flag(
      "--resume", o->resume,
      "Continue the interrupted scan in --out (same options and calibration) from its first missing "
      "(step, laser)");
  cmd->add_flag("--images", o->images, "Also store the raw images (PGM/PPM) in <out>.images/");
  cmd->add_option("--views", o->views,
                  "step: one view per (step, laser), as acquired (default); sweep: one view per laser's full "
                  "turn, what `fit` wants")
      ->check(CLI::IsMember({"step", "sweep"}));
  cmd->add_option("--feed-rate", o->feed_rate, "Turntable speed, degrees/s (200)");
  cmd->add_option("--acceleration", o->acceleration, "Turntable acceleration, degrees/s^2 (200)");
  CLI::Option* settle =
      cmd->add_option("--settle", o->settle, "Wait after each move, seconds (0.1; the virtual rig: 0)");
  cmd->add_option("--start-angle", o->start_angle, "Angle of the first step, degrees (0)");
  cmd->add_option("--min-z", o->min_z,
                  "Drop points below this height over the table, mm (0.5: the platform itself)");
  cmd->add_option("--max-radius", o->max_radius,
                  "Drop points farther from the axis, mm (0: keep all; the background)");
  cmd->add_option("--threshold", o->threshold,
                  "Laser line: minimum brightness over the laser-off frame (20)");
  cmd->add_flag("-q,--quiet", o->quiet, "No progress on standard error");
  return [o, settle]() {
    std::string resume_hint;
    try {
#ifndef S2M_HAVE_HORUS_OPENCV
      throw DeviceError(DeviceError::Kind::kOther,
                        "laser-line scanning is not built (OpenCV was not found when scan2model was built)");
#else
      const bool is_virtual = o->device.rfind("horus-virtual:", 0) == 0;
      if (!IsHorusDeviceSpec(o->device)) throw std::invalid_argument("unknown --device '" + o->device + "'");
      if (o->calibration.empty() && !is_virtual)
        throw std::invalid_argument(
            "--calibration is required for a real scanner (scan2model calibrate makes one)");
      std::optional<HorusCalibration> calibration;
      if (!o->calibration.empty()) calibration = ReadCalibration(o->calibration);
      HorusRig rig = OpenHorusRig(o->device);
      if (!calibration) {
        if (!rig.truth) throw std::invalid_argument("--calibration is required for this device");
        calibration = rig.truth;
        // Said even with --quiet: a scan with a perfect calibration is not a real one.
        std::cerr << "scan: no --calibration: using the virtual rig's true calibration\n";
      }
      HorusScanOptions options;
      options.steps = o->steps;
      options.lasers = o->lasers;
      options.feed_rate_deg_s = o->feed_rate;
      options.acceleration_deg_s2 = o->acceleration;
      // The virtual table does not shake: no settling unless asked for.
      options.settle_s = is_virtual && settle->count() == 0 ? 0.0 : o->settle;
      options.start_angle_deg = o->start_angle;
      options.views = o->views == "sweep" ? HorusScanOptions::ViewGrouping::kLaserSweep
                                          : HorusScanOptions::ViewGrouping::kStepAndLaser;
      options.store_images = o->images;
      options.resume = o->resume;
      options.device_json = rig.description_json;

      LaserExtractionOptions extraction;
      extraction.threshold = o->threshold;
      const HorusCalibration c = *calibration;
      const double min_z = o->min_z, max_radius = o->max_radius;
      // Pixels -> camera-frame points; the platform and the background are dropped by their height and their
      // distance from the axis in the platform frame, both independent of the turntable's angle.
      const LaserProfileFunction profile = [c, extraction, min_z, max_radius](const Image8& on,
                                                                              const Image8& off, int laser) {
        const Eigen::Matrix3Xd camera = TriangulateLaserLine(ExtractLaserLine(on, off, extraction), c, laser);
        const Eigen::Matrix3Xd platform = c.platform_T_camera.apply(camera);
        Eigen::Matrix3Xd kept(3, camera.cols());
        Eigen::Index n = 0;
        for (Eigen::Index i = 0; i < camera.cols(); ++i) {
          if (platform(2, i) < min_z) continue;
          if (max_radius > 0 && platform.col(i).head<2>().norm() > max_radius) continue;
          kept.col(n++) = camera.col(i);
        }
        return Eigen::Matrix3Xd(kept.leftCols(n));
      };

      resume_hint = "scan2model scan --device " + o->device +
                    (o->calibration.empty() ? "" : " --calibration " + o->calibration) + " --out " + o->out +
                    " --steps " + std::to_string(o->steps) + (o->views == "sweep" ? " --views sweep" : "");
      // The options recorded in horus.scan_options that differ from their defaults must be given again.
      if (o->lasers != std::vector<int>{0, 1}) {
        resume_hint += " --lasers ";
        for (std::size_t k = 0; k < o->lasers.size(); ++k)
          resume_hint += (k ? "," : "") + std::to_string(o->lasers[k]);
      }
      const auto number = [](double v) {
        std::ostringstream s;
        s << v;
        return s.str();
      };
      if (o->feed_rate != 200.0) resume_hint += " --feed-rate " + number(o->feed_rate);
      if (o->acceleration != 200.0) resume_hint += " --acceleration " + number(o->acceleration);
      if (settle->count() > 0) resume_hint += " --settle " + number(o->settle);
      if (o->start_angle != 0.0) resume_hint += " --start-angle " + number(o->start_angle);
      resume_hint += " --resume";
      HorusScanResult r;
      {
        StopOnSignals stop_on_signals;
        r = RunHorusScan(*rig.board, *rig.camera, c, profile, o->out, options, ScanProgressBar(o->quiet));
      }
      if (!r.complete) {
        std::cerr << "\n";
        return ReportError("scan",
                           "the scan stopped after " + std::to_string(r.done) + " of " +
                               std::to_string(r.total) + " (step, laser) pairs: " + r.error +
                               "\n  every profile acquired so far is in " + o->out + " (" +
                               std::to_string(r.frames) +
                               " frames, status 'interrupted'); continue it with:\n  " + resume_hint,
                           StopOnSignals::Requested() ? kInterrupted : kDeviceError, false);
      }
      std::cout << o->out << ": complete, " << r.total << " (step, laser) pairs"
                << (r.resumed_from > 0 ? " (resumed at " + std::to_string(r.resumed_from) + ")" : "") << ", "
                << r.frames << " profile frames, " << r.empty_profiles << " empty profiles in this run\n";
      return int{kOk};
#endif
    } catch (const DeviceError& e) {
      return ReportError("scan", e.what(), kDeviceError, false);
    } catch (const FormatError& e) {
      return ReportError("scan", e.what(), kInputError, false);
    } catch (const std::invalid_argument& e) {
      return ReportError("scan", e.what(), kUsage, false);
    } catch (const std::runtime_error& e) {
      // Ctrl-C or a failing image pipeline: the recording is marked interrupted and can be resumed.
      std::cerr << "\n";
      return ReportError("scan",
                         std::string(e.what()) + "; the lasers and the motor are off" +
                             (resume_hint.empty() ? "" : "; continue with:\n  " + resume_hint),
                         StopOnSignals::Requested() ? kInterrupted : kDeviceError, false);
    }
  };
}

}  // namespace s2m::app
