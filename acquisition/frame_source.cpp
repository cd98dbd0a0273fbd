#include "acquisition/frame_source.h"

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <map>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <thread>

#include "acquisition/e57_io.h"
#include "acquisition/format_error.h"
#include "acquisition/point_cloud_io.h"
#include "acquisition/recording.h"
#include "acquisition/scan_set_io.h"
#include "fitting/enum_names.h"

namespace s2m {

namespace fs = std::filesystem;

static_assert(std::endian::native == std::endian::little, "the payload codec assumes a little-endian host");

namespace {

constexpr std::array<EnumName<FrameKind>, 3> kFrameKindNames = {{
    {FrameKind::kPoints, "points"},
    {FrameKind::kDepth, "depth"},
    {FrameKind::kProfile, "profile"},
}};

}  // namespace

const char* ToString(FrameKind kind) {
  return NameOf(kFrameKindNames, kind, "points");
}

FrameKind FrameKindFromString(const std::string& kind) {
  return ValueOf(kFrameKindNames, kind, "frame kind");
}

namespace {

class SteadyClock final : public ReplayClock {
 public:
  std::int64_t NowNs() override {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::steady_clock::now().time_since_epoch())
        .count();
  }
  void SleepUntilNs(std::int64_t t) override {
    std::this_thread::sleep_until(std::chrono::steady_clock::time_point(std::chrono::nanoseconds(t)));
  }
};

nlohmann::json IntrinsicsJson(const DepthIntrinsics& k) {
  return {{"fx", k.fx}, {"fy", k.fy}, {"cx", k.cx}, {"cy", k.cy}, {"depth_scale", k.depth_scale}};
}

// The intrinsics of calibration.streams.<name>.intrinsics; FormatError naming what is missing.
DepthIntrinsics IntrinsicsFromJson(const nlohmann::json& calibration, const std::string& stream,
                                   const std::string& file) {
  const std::string where = "stream '" + stream + "'";
  const nlohmann::json* k = nullptr;
  if (calibration.is_object() && calibration.contains("streams") && calibration["streams"].is_object() &&
      calibration["streams"].contains(stream) && calibration["streams"][stream].is_object() &&
      calibration["streams"][stream].contains("intrinsics")) {
    k = &calibration["streams"][stream]["intrinsics"];
  }
  if (k == nullptr || !k->is_object()) {
    throw FormatError(
        file, where,
        "a depth stream needs its intrinsics, but the calibration has no streams." + stream + ".intrinsics");
  }
  DepthIntrinsics out;
  auto get = [&](const char* name, double& value) {
    if (!k->contains(name) || !(*k)[name].is_number()) {
      throw FormatError(file, where, std::string("intrinsics: '") + name + "' missing or not a number");
    }
    value = (*k)[name].get<double>();
    if (!std::isfinite(value))
      throw FormatError(file, where, std::string("intrinsics: '") + name + "' not finite");
  };
  get("fx", out.fx);
  get("fy", out.fy);
  get("cx", out.cx);
  get("cy", out.cy);
  get("depth_scale", out.depth_scale);
  out.depth_scale_from_file = true;
  if (out.fx <= 0 || out.fy <= 0 || out.depth_scale <= 0)
    throw FormatError(file, where, "intrinsics: focal lengths and depth_scale must be positive");
  return out;
}

// The views of a frame sequence (RecordingFrame or Frame), in order of first appearance.
template <typename FrameT>
std::vector<std::int64_t> DistinctViews(const std::vector<FrameT>& frames) {
  std::vector<std::int64_t> views;
  for (const FrameT& f : frames) {
    if (std::find(views.begin(), views.end(), f.view) == views.end()) views.push_back(f.view);
  }
  return views;
}

// Index of the first frame of `view`; std::out_of_range (prefixed by `source`) when there is none.
template <typename FrameT>
std::size_t FirstFrameOfView(const std::vector<FrameT>& frames, std::int64_t view,
                             const std::string& source) {
  for (std::size_t k = 0; k < frames.size(); ++k) {
    if (frames[k].view == view) return k;
  }
  throw std::out_of_range(source + "no view " + std::to_string(view));
}

// -------------------------------------------------------------------------------------------- recording

class RecordingSource final : public FrameSource {
 public:
  RecordingSource(const fs::path& path, const ReplayOptions& options)
      : reader_(RecordingReader::Open(path)), options_(options) {
    if (!options_.clock) options_.clock = SteadyReplayClock();
    if (!(options_.max_gap_s > 0.0) || !std::isfinite(options_.max_gap_s)) {
      throw std::invalid_argument(
          "replay: the largest gap between frames must be a positive number of seconds");
    }
    const std::string file = path.string();
    const RecordingSummary summary = reader_.Summary();
    description_.origin = file;
    description_.name = reader_.Meta("name").value_or("");
    description_.device_json = summary.device;
    for (const auto& [key, value] : summary.meta) {
      if (key != "format" && key != "name") description_.meta.emplace_back(key, value);
    }
    nlohmann::json calibration = nlohmann::json::parse(summary.calibration, nullptr, false);
    if (calibration.is_discarded()) throw FormatError(file, "device", "the calibration is not JSON");
    for (const RecordingStream& s : summary.streams) {
      StreamInfo info;
      info.name = s.name;
      const std::string where = "stream '" + s.name + "'";
      try {
        info.kind = FrameKindFromString(s.kind);
      } catch (const std::invalid_argument& e) {
        throw FormatError(file, where, e.what());
      }
      const std::string expected = info.kind == FrameKind::kDepth ? kDepthEncoding : kPointsEncoding;
      if (s.encoding != expected) {
        throw FormatError(file, where,
                          "encoding '" + s.encoding + "' of a " + s.kind +
                              " stream is not supported (expected " + expected + ")");
      }
      info.units = s.units;
      if (info.kind == FrameKind::kDepth) info.intrinsics = IntrinsicsFromJson(calibration, s.name, file);
      stream_index_[s.id] = static_cast<int>(description_.streams.size());
      description_.streams.push_back(info);
    }
    // The streams' intrinsics are returned in StreamInfo; the rest of the calibration stays as it was.
    if (calibration.is_object()) calibration.erase("streams");
    description_.calibration_json = calibration.dump();
    for (const RecordingStream& s : summary.streams) {
      for (RecordingFrame& f : reader_.Frames(s.id)) frames_.push_back(std::move(f));
    }
    std::sort(frames_.begin(), frames_.end(),
              [](const RecordingFrame& a, const RecordingFrame& b) { return a.id < b.id; });
  }

  const SourceDescription& description() const override { return description_; }

  std::optional<Frame> Next() override {
    if (next_ >= frames_.size()) return std::nullopt;
    const RecordingFrame& f = frames_[next_++];
    const std::string file = reader_.path().string();
    const std::string where = "frame " + std::to_string(f.id);
    const std::vector<std::uint8_t> payload = FramePayload(f, file, where);
    Frame out;
    out.stream = stream_index_.at(f.stream);
    const StreamInfo& stream = description_.streams[static_cast<std::size_t>(out.stream)];
    out.kind = stream.kind;
    out.view = f.view;
    out.timestamp_ns = f.timestamp_ns;
    out.world_T_scan = f.world_T_scan;
    out.turntable_angle_rad = f.turntable_angle_rad;
    if (out.kind == FrameKind::kDepth) {
      out.depth = DecodeDepth(payload, file, where);
    } else {
      out.points = DecodePoints(payload, file, where);
    }
    out.source = file + ": stream '" + stream.name + "', view " + std::to_string(f.view) + ", " + where;
    if (options_.original_timing && f.timestamp_ns) WaitForDueTime(*f.timestamp_ns);
    return out;
  }

  std::vector<std::int64_t> Views() const override { return DistinctViews(frames_); }

  void SeekView(std::int64_t view) override {
    next_ = FirstFrameOfView(frames_, view, reader_.path().string() + ": ");
    anchor_.reset();  // timing restarts at the seek
  }

  std::optional<std::int64_t> FrameCount() const override {
    return static_cast<std::int64_t>(frames_.size());
  }

  TimingReport timing_report() const override { return timing_; }

 private:
  // Original timing (ReplayOptions): a frame is due as long after the anchor's clock reading as its timestamp
  // is after the anchor's timestamp; clock jumps on either side restart the timing at the frame.
  void WaitForDueTime(std::int64_t timestamp_ns) {
    const auto max_gap_ns = static_cast<std::int64_t>(options_.max_gap_s * 1e9);
    const std::int64_t now = options_.clock->NowNs();
    if (!anchor_) {
      anchor_ = std::make_pair(now, timestamp_ns);
    } else if (const std::int64_t gap = timestamp_ns - last_timestamp_ns_; gap < 0 || gap > max_gap_ns) {
      ++timing_.recording_clock_jumps;
      anchor_ = std::make_pair(now, timestamp_ns);
    } else if (const std::int64_t due = anchor_->first + (timestamp_ns - anchor_->second);
               now - due > max_gap_ns) {
      ++timing_.replay_late_restarts;
      anchor_ = std::make_pair(now, timestamp_ns);
    } else {
      options_.clock->SleepUntilNs(due);
    }
    last_timestamp_ns_ = timestamp_ns;
  }

  RecordingReader reader_;
  ReplayOptions options_;
  SourceDescription description_;
  std::map<std::int64_t, int> stream_index_;
  std::vector<RecordingFrame> frames_;
  std::size_t next_ = 0;
  std::optional<std::pair<std::int64_t, std::int64_t>> anchor_;  // (clock, timestamp) of the first frame
  std::int64_t last_timestamp_ns_ = 0;  // of the previous frame delivered with its timing
  TimingReport timing_;
};

// ------------------------------------------------------------------------------------------------ files

// Frames prepared in memory (files are small enough to read at once; reading them is what can fail, and it
// fails at open, before anything is recorded).
class VectorSource final : public FrameSource {
 public:
  VectorSource(SourceDescription description, std::vector<Frame> frames)
      : description_(std::move(description)), frames_(std::move(frames)) {}
  const SourceDescription& description() const override { return description_; }
  std::optional<Frame> Next() override {
    if (next_ >= frames_.size()) return std::nullopt;
    return frames_[next_++];
  }
  std::vector<std::int64_t> Views() const override { return DistinctViews(frames_); }
  void SeekView(std::int64_t view) override { next_ = FirstFrameOfView(frames_, view, ""); }
  std::optional<std::int64_t> FrameCount() const override {
    return static_cast<std::int64_t>(frames_.size());
  }

 private:
  SourceDescription description_;
  std::vector<Frame> frames_;
  std::size_t next_ = 0;
};

bool IsDepthTiff(const fs::path& p) {
  const std::string name = p.filename().string();
  auto ends = [&](const std::string& s) {
    return name.size() >= s.size() && name.compare(name.size() - s.size(), s.size(), s) == 0;
  };
  return ends("_depth.tiff") || ends("_depth.tif");
}

// frame_20121214T142255.814212_depth.tiff: the OpenNI grabber's local time stamp, read as UTC (the files
// do not say their zone) with microseconds; nullopt when the name does not follow the pattern.
std::optional<std::int64_t> GrabberTimestampNs(const fs::path& p) {
  const std::string name = p.filename().string();
  int year, month, day, hour, minute, second, micro;
  if (std::sscanf(name.c_str(), "frame_%4d%2d%2dT%2d%2d%2d.%6d_depth", &year, &month, &day, &hour, &minute,
                  &second, &micro) != 7) {
    return std::nullopt;
  }
  std::tm tm{};
  tm.tm_year = year - 1900;
  tm.tm_mon = month - 1;
  tm.tm_mday = day;
  tm.tm_hour = hour;
  tm.tm_min = minute;
  tm.tm_sec = second;
  const std::time_t seconds = timegm(&tm);
  if (seconds == static_cast<std::time_t>(-1)) return std::nullopt;
  return static_cast<std::int64_t>(seconds) * 1000000000 + static_cast<std::int64_t>(micro) * 1000;
}

std::unique_ptr<FrameSource> DepthFileSource(const std::vector<fs::path>& files) {
  SourceDescription d;
  d.origin = files.front().string();
  d.name = files.front().parent_path().filename().string();
  d.device_json = nlohmann::json{{"name", "openni-files"}}.dump();
  StreamInfo stream{"depth", FrameKind::kDepth, "m", std::nullopt};
  std::vector<Frame> frames;
  for (std::size_t k = 0; k < files.size(); ++k) {
    const fs::path& file = files[k];
    if (!IsDepthTiff(file)) {
      throw FormatError(file.string(), "",
                        "not a depth frame (frame_<time>_depth.tiff); depth frames cannot be "
                        "mixed with other inputs");
    }
    const DepthIntrinsics k_file = ReadDepthIntrinsicsXml(DepthIntrinsicsPathFor(file));
    if (!stream.intrinsics) {
      stream.intrinsics = k_file;
    } else if (k_file.fx != stream.intrinsics->fx || k_file.fy != stream.intrinsics->fy ||
               k_file.cx != stream.intrinsics->cx || k_file.cy != stream.intrinsics->cy ||
               k_file.depth_scale != stream.intrinsics->depth_scale) {
      throw FormatError(file.string(), "",
                        "intrinsics differ from those of " + files.front().string() +
                            " (one depth stream has one calibration)");
    }
    Frame f;
    f.kind = FrameKind::kDepth;
    f.view = static_cast<std::int64_t>(k);
    f.timestamp_ns = GrabberTimestampNs(file);
    f.depth = ReadDepthTiff(file);
    f.source = file.string();
    frames.push_back(std::move(f));
  }
  d.streams.push_back(stream);
  return std::make_unique<VectorSource>(std::move(d), std::move(frames));
}

}  // namespace

std::shared_ptr<ReplayClock> SteadyReplayClock() {
  return std::make_shared<SteadyClock>();
}

std::unique_ptr<FrameSource> OpenRecordingSource(const fs::path& path, const ReplayOptions& options) {
  return std::make_unique<RecordingSource>(path, options);
}

std::unique_ptr<FrameSource> ScanSetSource(ScanSet set, const std::string& device_name,
                                           const std::string& origin) {
  SourceDescription d;
  d.origin = origin.empty() ? set.name : origin;
  d.name = set.name;
  const std::string device = set.scans.empty() || set.scans.front().metadata.device.empty()
                                 ? device_name
                                 : set.scans.front().metadata.device;
  d.device_json = nlohmann::json{{"name", device}}.dump();
  d.streams.push_back(
      {"points", FrameKind::kPoints, set.scans.empty() ? "unknown" : set.scans.front().units, std::nullopt});
  std::vector<Frame> frames;
  for (std::size_t k = 0; k < set.scans.size(); ++k) {
    Scan& scan = set.scans[k];
    Frame f;
    f.kind = FrameKind::kPoints;
    f.view = static_cast<std::int64_t>(k);
    if (scan.metadata.timestamp_s) f.timestamp_ns = std::llround(*scan.metadata.timestamp_s * 1e9);
    f.world_T_scan = scan.world_T_scan;
    f.turntable_angle_rad = scan.metadata.turntable_angle_rad;
    f.points = std::move(scan.points);
    f.source = scan.metadata.source;
    frames.push_back(std::move(f));
  }
  return std::make_unique<VectorSource>(std::move(d), std::move(frames));
}

std::unique_ptr<FrameSource> OpenFileSource(const std::vector<fs::path>& files) {
  if (files.empty()) throw std::invalid_argument("no input files");
  if (IsDepthTiff(files.front())) return DepthFileSource(files);
  if (files.size() != 1) {
    throw FormatError(files[1].string(), "",
                      "only depth frames come as several files; give one manifest, .conf or cloud");
  }
  const fs::path& file = files.front();
  const std::string ext = file.extension().string();
  ScanSet set;
  if (ext == ".json" || ext == ".conf") {
    set = ReadScanSet(file);
  } else if (IsE57File(file)) {
    set = ReadE57ScanSet(file);  // each data3D scan a view, with its pose
  } else {
    set.scans.push_back(ReadPointCloud(file));  // one view in world coordinates
    set.name = file.stem().string();
  }
  return ScanSetSource(std::move(set), "file", file.string());
}

std::unique_ptr<FrameSource> OpenFrameSource(const std::vector<fs::path>& inputs,
                                             const ReplayOptions& replay) {
  if (inputs.size() == 1 && inputs.front().extension() == kRecordingExtension)
    return OpenRecordingSource(inputs.front(), replay);
  return OpenFileSource(inputs);
}

// ---------------------------------------------------------------------------------------- frames to views

ScanSet FramesToScanSet(FrameSource& source, const FrameProgress& progress) {
  const SourceDescription& d = source.description();
  const nlohmann::json device = nlohmann::json::parse(d.device_json, nullptr, false);
  const std::string device_name = device.is_object() && device.contains("name") && device["name"].is_string()
                                      ? device["name"].get<std::string>()
                                      : "";
  ScanSet set;
  set.name = d.name;
  std::map<std::pair<int, std::int64_t>, std::size_t> scan_of;  // (stream, view) -> scan index
  std::vector<std::vector<Eigen::Matrix3Xd>> parts;             // per scan: each frame's points, scan frame
  std::int64_t done = 0;
  const std::optional<std::int64_t> total = source.FrameCount();
  while (std::optional<Frame> f = source.Next()) {
    if (f->stream < 0 || f->stream >= static_cast<int>(d.streams.size()))
      throw std::logic_error("frame of an unknown stream");
    const StreamInfo& stream = d.streams[static_cast<std::size_t>(f->stream)];
    Eigen::Matrix3Xd points;
    if (f->kind == FrameKind::kDepth) {
      if (!stream.intrinsics) throw FormatError(f->source, "stream '" + stream.name + "'", "no intrinsics");
      points = BackProject(f->depth, *stream.intrinsics).points;
    } else {
      points = std::move(f->points);
    }
    const RigidMotion world_T_frame = f->world_T_scan.value_or(RigidMotion::Identity());
    const auto key = std::make_pair(f->stream, f->view);
    auto it = scan_of.find(key);
    if (it == scan_of.end()) {
      it = scan_of.emplace(key, set.scans.size()).first;
      Scan scan;
      scan.world_T_scan = world_T_frame;
      scan.units = stream.units;
      scan.metadata.device = device_name;
      if (f->timestamp_ns) scan.metadata.timestamp_s = static_cast<double>(*f->timestamp_ns) * 1e-9;
      scan.metadata.turntable_angle_rad = f->turntable_angle_rad;
      scan.metadata.source = f->source;
      set.scans.push_back(std::move(scan));
      parts.emplace_back();
      parts.back().push_back(std::move(points));
    } else {
      // Another frame of the view (a sweep's next profile): into the view's frame, that of its first frame.
      Scan& scan = set.scans[it->second];
      parts[it->second].push_back((scan.world_T_scan.inverse() * world_T_frame).apply(points));
      scan.metadata.turntable_angle_rad.reset();  // the view spans several angles
    }
    ++done;
    if (progress) progress(done, total);
  }
  if (set.scans.empty())
    throw FormatError(d.origin.empty() ? d.name : d.origin, "", "no frames to read as views");
  for (std::size_t k = 0; k < set.scans.size(); ++k) {
    Eigen::Index count = 0;
    for (const auto& p : parts[k]) count += p.cols();
    if (parts[k].size() == 1) {
      set.scans[k].points = std::move(parts[k].front());
    } else {
      set.scans[k].points.resize(3, count);
      Eigen::Index at = 0;
      for (const auto& p : parts[k]) {
        set.scans[k].points.middleCols(at, p.cols()) = p;
        at += p.cols();
      }
      set.scans[k].metadata.source += " (+" + std::to_string(parts[k].size() - 1) + " frames of the view)";
    }
    if (count == 0) throw FormatError(set.scans[k].metadata.source, "", "the view has no points");
  }
  return set;
}

// ---------------------------------------------------------------------------------------------- recording

std::int64_t RecordSource(FrameSource& source, const fs::path& out, const FrameProgress& progress,
                          const std::string& compression) {
  const SourceDescription& d = source.description();
  nlohmann::json calibration = nlohmann::json::parse(d.calibration_json, nullptr, false);
  if (!calibration.is_object()) throw std::invalid_argument("the source's calibration is not a JSON object");
  for (const StreamInfo& s : d.streams) {
    if (s.kind == FrameKind::kDepth) {
      if (!s.intrinsics) throw std::invalid_argument("depth stream '" + s.name + "' has no intrinsics");
      calibration["streams"][s.name]["intrinsics"] = IntrinsicsJson(*s.intrinsics);
    }
  }
  RecordingWriter writer = RecordingWriter::Create(out);
  writer.SetMeta("name", d.name);
  for (const auto& [key, value] : d.meta) writer.SetMeta(key, value);
  writer.SetDevice(d.device_json, calibration.dump());
  std::vector<std::int64_t> stream_ids;
  for (const StreamInfo& s : d.streams) {
    stream_ids.push_back(writer.AddStream(
        s.name, ToString(s.kind), s.kind == FrameKind::kDepth ? kDepthEncoding : kPointsEncoding, s.units));
  }
  std::int64_t done = 0;
  const std::optional<std::int64_t> total = source.FrameCount();
  while (std::optional<Frame> f = source.Next()) {
    const std::vector<std::uint8_t> payload =
        f->kind == FrameKind::kDepth ? EncodeDepth(f->depth) : EncodePoints(f->points);
    // A turntable angle needs a pose row to live in (docs/recordings.md): frames with an angle have a pose.
    try {
      writer.AppendFrame(stream_ids.at(static_cast<std::size_t>(f->stream)), f->view, payload,
                         f->world_T_scan, f->timestamp_ns, f->turntable_angle_rad, compression);
    } catch (const FormatError& e) {
      // Each frame is its own transaction (docs/recordings.md): the ones before this are on disk. Saying how
      // many tells the user what the recording holds without opening it.
      throw FormatError(e.file(), e.location(),
                        e.problem() + "; the " + std::to_string(done) +
                            " frame(s) before it are committed and stay readable");
    }
    ++done;
    if (progress) progress(done, total);
  }
  writer.Close();
  return done;
}

std::vector<std::uint8_t> EncodeDepth(const DepthImage& image) {
  if (image.width < 0 || image.height < 0 ||
      image.values.size() != static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height)) {
    throw std::invalid_argument("depth image: value count does not match its size");
  }
  std::vector<std::uint8_t> out(8 + 2 * image.values.size());
  const auto w = static_cast<std::uint32_t>(image.width), h = static_cast<std::uint32_t>(image.height);
  std::memcpy(out.data(), &w, 4);
  std::memcpy(out.data() + 4, &h, 4);
  if (!image.values.empty()) std::memcpy(out.data() + 8, image.values.data(), 2 * image.values.size());
  return out;
}

DepthImage DecodeDepth(const std::vector<std::uint8_t>& payload, const std::string& file,
                       const std::string& where) {
  if (payload.size() < 8) {
    throw FormatError(file, where,
                      "depth payload of " + std::to_string(payload.size()) + " bytes has no size");
  }
  std::uint32_t w = 0, h = 0;
  std::memcpy(&w, payload.data(), 4);
  std::memcpy(&h, payload.data() + 4, 4);
  const std::uint64_t count = std::uint64_t{w} * h;
  if (w > (1u << 16) || h > (1u << 16) || payload.size() - 8 != 2 * count) {
    throw FormatError(file, where,
                      "depth payload declares " + std::to_string(w) + " x " + std::to_string(h) +
                          " pixels (8 + 2 per pixel bytes) but has " + std::to_string(payload.size()) +
                          " bytes");
  }
  DepthImage image;
  image.width = static_cast<int>(w);
  image.height = static_cast<int>(h);
  image.values.resize(count);
  if (count > 0) std::memcpy(image.values.data(), payload.data() + 8, 2 * count);
  return image;
}

}  // namespace s2m
