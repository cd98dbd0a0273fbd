#include "devices/horus_scan.h"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <stdexcept>
#include <thread>

#include "acquisition/format_error.h"
#include "acquisition/recording.h"

namespace s2m {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr const char* kStreamName = "profile";
constexpr const char* kOptionsMeta = "horus.scan_options";
// Pairs (step, laser) acquired so far, empty profiles included: a resume starts after the larger of this and
// the last recorded frame (the frame commit and this update are two transactions; either may be the newer).
constexpr const char* kAcquiredMeta = "horus.acquired";

constexpr double kPi = 3.14159265358979323846;

std::int64_t NowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

const char* GroupingName(HorusScanOptions::ViewGrouping g) {
  return g == HorusScanOptions::ViewGrouping::kLaserSweep ? "laser_sweep" : "step_and_laser";
}

void CheckOptions(const HorusScanOptions& o, const HorusCalibration& calibration) {
  if (o.steps < 1)
    throw std::invalid_argument("scan: steps must be at least 1, not " + std::to_string(o.steps));
  if (o.lasers.empty()) throw std::invalid_argument("scan: no laser to use");
  std::set<int> seen;
  for (const int laser : o.lasers) {
    if (laser < 0 || laser >= static_cast<int>(calibration.lasers.size())) {
      throw std::invalid_argument("scan: laser " + std::to_string(laser) +
                                  " is not calibrated (the calibration has " +
                                  std::to_string(calibration.lasers.size()) + " laser planes)");
    }
    if (!seen.insert(laser).second)
      throw std::invalid_argument("scan: laser " + std::to_string(laser) + " given twice");
  }
  if (!(o.feed_rate_deg_s > 0) || !(o.acceleration_deg_s2 > 0))
    throw std::invalid_argument("scan: feed rate and acceleration must be positive");
  if (!(o.settle_s >= 0) || !std::isfinite(o.settle_s))
    throw std::invalid_argument("scan: settle time must be finite and >= 0");
  if (!std::isfinite(o.start_angle_deg)) throw std::invalid_argument("scan: start angle is not finite");
}

// The keys that differ between two option objects, "steps 400 (recorded) vs 200".
std::string Differences(const json& recorded, const json& given) {
  std::string out;
  std::set<std::string> keys;
  for (auto it = recorded.begin(); it != recorded.end(); ++it) keys.insert(it.key());
  for (auto it = given.begin(); it != given.end(); ++it) keys.insert(it.key());
  for (const std::string& k : keys) {
    const json a = recorded.contains(k) ? recorded[k] : json();
    const json b = given.contains(k) ? given[k] : json();
    if (a != b)
      out += (out.empty() ? "" : ", ") + k + " " + a.dump() + " (recorded) vs " + b.dump() + " (given)";
  }
  return out;
}

void WriteImage(const fs::path& path, const Image8& image) {
  if (image.channels != 1 && image.channels != 3) return;
  std::ofstream out(path, std::ios::binary);
  // Netpbm: P5 grey, P6 RGB (our images are B, G, R like OpenCV's).
  out << (image.channels == 1 ? "P5" : "P6") << "\n" << image.width << " " << image.height << "\n255\n";
  if (image.channels == 1) {
    out.write(reinterpret_cast<const char*>(image.pixels.data()),
              static_cast<std::streamsize>(image.pixels.size()));
  } else {
    std::vector<std::uint8_t> rgb(image.pixels.size());
    for (std::size_t i = 0; i + 2 < rgb.size(); i += 3) {
      rgb[i] = image.pixels[i + 2];
      rgb[i + 1] = image.pixels[i + 1];
      rgb[i + 2] = image.pixels[i];
    }
    out.write(reinterpret_cast<const char*>(rgb.data()), static_cast<std::streamsize>(rgb.size()));
  }
  if (!out) throw FormatError(path.string(), "", "cannot write the image");
}

std::string StepName(int step) {
  std::string s = std::to_string(step);
  return "step_" + std::string(s.size() < 4 ? 4 - s.size() : 0, '0') + s;
}

// Only finite points are recorded (a triangulation at infinity would make the recording unreadable).
Eigen::Matrix3Xd FinitePoints(const Eigen::Matrix3Xd& points) {
  Eigen::Index n = 0;
  for (Eigen::Index i = 0; i < points.cols(); ++i) n += points.col(i).allFinite() ? 1 : 0;
  if (n == points.cols()) return points;
  Eigen::Matrix3Xd out(3, n);
  Eigen::Index at = 0;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    if (points.col(i).allFinite()) out.col(at++) = points.col(i);
  }
  return out;
}

struct Resume {
  std::int64_t next = 0;    // first pair to acquire
  std::int64_t frames = 0;  // profile frames already recorded
  std::int64_t stream = 0;
};

// Checks that `out` holds an interrupted scan with these options and calibration; where to go on.
Resume PrepareResume(const fs::path& out, const std::string& options_json,
                     const std::string& calibration_json, const HorusScanOptions& o) {
  const std::string file = out.string();
  if (!fs::exists(out)) throw std::invalid_argument(file + ": no such recording to resume");
  const RecordingReader reader = RecordingReader::Open(out);
  const std::string status = reader.Meta(kStatusMeta).value_or("");
  if (status == kStatusComplete)
    throw FormatError(file, "", "the scan is complete (meta status 'complete'); there is nothing to resume");
  const std::optional<std::string> recorded = reader.Meta(kOptionsMeta);
  if (!recorded)
    throw FormatError(file, "", "not a Horus scan (no meta '" + std::string(kOptionsMeta) + "')");
  const json recorded_options = json::parse(*recorded, nullptr, false);
  const json given_options = json::parse(options_json);
  if (recorded_options != given_options) {
    throw std::invalid_argument(file + ": cannot resume with different scan options: " +
                                Differences(recorded_options, given_options));
  }
  const json calibration = json::parse(reader.Summary().calibration, nullptr, false);
  if (!calibration.is_object() || !calibration.contains("horus") ||
      calibration["horus"] != json::parse(calibration_json)) {
    throw std::invalid_argument(file +
                                ": cannot resume with a different calibration (the recorded one is in the "
                                "recording's calibration under \"horus\")");
  }
  Resume r;
  bool found = false;
  for (const RecordingStream& s : reader.Streams()) {
    if (s.name == kStreamName && s.kind == "profile") {
      r.stream = s.id;
      found = true;
    }
  }
  if (!found)
    throw FormatError(file, "", "not a Horus scan (no profile stream '" + std::string(kStreamName) + "')");
  const auto lasers = static_cast<std::int64_t>(o.lasers.size());
  const double step_rad = 2 * kPi / o.steps;
  const double start_rad = o.start_angle_deg * kPi / 180.0;
  for (const RecordingFrame& f : reader.Frames(r.stream)) {
    std::int64_t index = f.view;  // kStepAndLaser: view = step * lasers + laser index
    if (o.views == HorusScanOptions::ViewGrouping::kLaserSweep) {
      if (!f.turntable_angle_rad)
        throw FormatError(file, "frame " + std::to_string(f.id), "a profile without its turntable angle");
      const std::int64_t step = std::llround((*f.turntable_angle_rad - start_rad) / step_rad);
      index = step * lasers + f.view;
    }
    r.next = std::max(r.next, index + 1);
    ++r.frames;
  }
  if (const std::optional<std::string> acquired = reader.Meta(kAcquiredMeta)) {
    try {
      r.next = std::max<std::int64_t>(r.next, std::stoll(*acquired));
    } catch (const std::exception&) {
      throw FormatError(file, "", "meta " + std::string(kAcquiredMeta) + " is not a number: " + *acquired);
    }
  }
  return r;
}

}  // namespace

std::string HorusScanOptionsToJson(const HorusScanOptions& o) {
  return json{{"steps", o.steps},
              {"lasers", o.lasers},
              {"feed_rate_deg_s", o.feed_rate_deg_s},
              {"acceleration_deg_s2", o.acceleration_deg_s2},
              {"settle_s", o.settle_s},
              {"start_angle_deg", o.start_angle_deg},
              {"views", GroupingName(o.views)}}
      .dump();
}

std::string HorusCalibrationJson(const HorusCalibration& c) {
  json lasers = json::array();
  for (const LaserPlane& p : c.lasers)
    lasers.push_back({{"normal", {p.normal.x(), p.normal.y(), p.normal.z()}}, {"distance", p.distance}});
  json m = json::array();
  const Eigen::Matrix4d t = c.platform_T_camera.matrix();
  for (int r = 0; r < 4; ++r) m.push_back({t(r, 0), t(r, 1), t(r, 2), t(r, 3)});
  return json{{"camera",
               {{"width", c.camera.width},
                {"height", c.camera.height},
                {"fx", c.camera.fx},
                {"fy", c.camera.fy},
                {"cx", c.camera.cx},
                {"cy", c.camera.cy},
                {"distortion", c.camera.distortion}}},
              {"lasers", lasers},
              {"platform_T_camera", m},
              {"units", "mm"}}
      .dump();
}

fs::path HorusImageFolder(const fs::path& recording) {
  return fs::path(recording.string() + ".images");
}

HorusScanResult RunHorusScan(TurntableBoard& board, ImageCamera& camera, const HorusCalibration& calibration,
                             const LaserProfileFunction& profile, const fs::path& out,
                             const HorusScanOptions& options, const HorusScanProgressFunction& progress) {
  CheckOptions(options, calibration);
  if (!profile) throw std::invalid_argument("scan: no laser profile function");
  const std::string file = out.string();
  const std::string options_json = HorusScanOptionsToJson(options);
  const std::string calibration_json = HorusCalibrationJson(calibration);
  const auto lasers = static_cast<std::int64_t>(options.lasers.size());

  HorusScanResult result;
  result.recording = out;
  result.total = options.steps * lasers;

  // The recording first: a refused resume or an unwritable file must not move the hardware.
  std::optional<RecordingWriter> writer;
  std::int64_t stream = 0;
  if (options.resume) {
    const Resume r = PrepareResume(out, options_json, calibration_json, options);
    writer.emplace(RecordingWriter::OpenForAppend(out));
    stream = r.stream;
    result.resumed_from = std::min(r.next, result.total);
    result.frames = r.frames;
  } else {
    if (fs::exists(out)) {
      throw std::invalid_argument(
          file +
          ": exists already (a recording is never overwritten; resume it if it holds an "
          "interrupted scan)");
    }
    // The header (device, calibration, options, stream) is written to a staging file that is renamed into
    // place: a scan killed at any moment leaves either no recording or one that --resume accepts, never a
    // recording without its options. A staging file left by an earlier kill holds no frame and is replaced.
    const fs::path staging = fs::path(file + ".creating");
    std::error_code ignored;
    fs::remove(staging, ignored);
    writer.emplace(RecordingWriter::Create(staging));
    json device = json::object();
    if (!options.device_json.empty()) {
      device = json::parse(options.device_json, nullptr, false);
      if (!device.is_object())
        throw std::invalid_argument("scan: the device description is not a JSON object");
    }
    if (!device.contains("name")) device["name"] = "horus";
    if (!device.contains("board")) device["board"] = board.Banner();
    if (!device.contains("camera")) device["camera"] = camera.Name();
    writer->SetDevice(device.dump(), json{{"horus", json::parse(calibration_json)}}.dump());
    writer->SetMeta("name", out.stem().string());
    writer->SetMeta(kOptionsMeta, options_json);
    stream = writer->AddStream(kStreamName, "profile", kPointsEncoding, "mm");
    writer->Close();
    writer.reset();
    // link(2), not rename: it refuses to replace a file that appeared at `out` meanwhile. File systems
    // without hard links (FAT and exFAT memory sticks) refuse link itself: there the rename follows a check,
    // whose window only another writer racing for the same name could use.
    if (::link(staging.c_str(), out.c_str()) != 0) {
      const int error = errno;
      if (error == EEXIST || fs::exists(out))
        throw FormatError(file, "", "exists already (a recording is never overwritten)");
      std::error_code renamed;
      fs::rename(staging, out, renamed);
      if (renamed) {
        throw FormatError(
            file, "",
            std::string("cannot create the recording: ") + std::strerror(error) + "; " + renamed.message());
      }
    }
    fs::remove(staging, ignored);
    writer.emplace(RecordingWriter::OpenForAppend(out));
  }
  writer->SetMeta(kStatusMeta, kStatusInProgress);
  if (options.store_images) fs::create_directories(HorusImageFolder(out));

  const auto sleep = [&](double seconds) {
    if (seconds <= 0) return;
    if (options.sleep) {
      options.sleep(seconds);
    } else {
      std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
    }
  };
  // Lasers off and motor off, whatever happened; a board that is gone is not asked again and again (each
  // call would wait for its timeout).
  const auto shut_down = [&]() {
    for (const int laser : options.lasers) {
      try {
        board.SetLaser(laser, false);
      } catch (const DeviceError& e) {
        if (e.kind() == DeviceError::Kind::kDisconnected) return;
      }
    }
    try {
      board.EnableMotor(false);
    } catch (const DeviceError&) {
    }
  };

  const auto start = std::chrono::steady_clock::now();
  const double step_deg = 360.0 / options.steps;
  std::int64_t index = result.resumed_from;
  try {
    board.Reset();  // Ctrl-X: a known state, the banner as handshake
    board.SetFeedRate(options.feed_rate_deg_s);
    board.SetAcceleration(options.acceleration_deg_s2);
    board.EnableMotor(true);
    for (const int laser : options.lasers) board.SetLaser(laser, false);
    Image8 off;
    int off_step = -1;
    for (; index < result.total; ++index) {
      const int step = static_cast<int>(index / lasers);
      const auto laser_index = static_cast<int>(index % lasers);
      const int laser = options.lasers[static_cast<std::size_t>(laser_index)];
      const double theta_deg = options.start_angle_deg + step * step_deg;
      const double theta_rad = theta_deg * kPi / 180.0;
      if (off_step != step) {
        board.MoveTo(theta_deg);
        sleep(options.settle_s);
        off = camera.Capture();
        off_step = step;
        if (options.store_images) WriteImage(HorusImageFolder(out) / (StepName(step) + "_off.pgm"), off);
      }
      board.SetLaser(laser, true);
      const Image8 on = camera.Capture();
      board.SetLaser(laser, false);
      if (options.store_images) {
        WriteImage(HorusImageFolder(out) / (StepName(step) + "_laser" + std::to_string(laser) +
                                            (on.channels == 3 ? ".ppm" : ".pgm")),
                   on);
      }
      const Eigen::Matrix3Xd points = FinitePoints(profile(on, off, laser));
      if (points.cols() > 0) {
        // devices/horus_interfaces.h: a frame at angle theta has world_T_scan = Rz(-theta) *
        // platform_T_camera.
        const RigidMotion world_T_scan =
            RigidMotion(RotationAboutAxis(Eigen::Vector3d::UnitZ(), -theta_rad), Eigen::Vector3d::Zero()) *
            calibration.platform_T_camera;
        const std::int64_t view =
            options.views == HorusScanOptions::ViewGrouping::kLaserSweep ? laser_index : index;
        writer->AppendFrame(stream, view, EncodePoints(points), world_T_scan, NowNs(), theta_rad);
        ++result.frames;
      } else {
        ++result.empty_profiles;
      }
      writer->SetMeta(kAcquiredMeta, std::to_string(index + 1));
      if (progress) {
        HorusScanProgress p;
        p.done = index + 1;
        p.total = result.total;
        p.step = step;
        p.laser = laser;
        p.elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        const std::int64_t this_run = index + 1 - result.resumed_from;
        if (this_run > 0)
          p.eta_s =
              p.elapsed_s / static_cast<double>(this_run) * static_cast<double>(result.total - index - 1);
        progress(p);
      }
    }
    result.complete = true;
    result.status = kStatusComplete;
  } catch (const DeviceError& e) {
    result.error_kind = e.kind();
    result.error = e.what();
    result.status = std::string("interrupted: ") + e.what();
  } catch (const std::exception& e) {
    // Not a device problem (the profile function, the disk): still leave the hardware safe and the
    // recording marked, then let the caller see the error.
    shut_down();
    try {
      writer->SetMeta(kStatusMeta, std::string("interrupted: ") + e.what());
      writer->Close();
    } catch (const std::exception&) {
    }
    throw;
  }
  shut_down();
  result.done = index;
  writer->SetMeta(kStatusMeta, result.status);
  writer->Close();
  return result;
}

}  // namespace s2m
