#include <cmath>
#include <filesystem>
#include <iostream>

#include "acquisition/e57_io.h"
#include "acquisition/format_error.h"
#include "acquisition/frame_source.h"
#include "acquisition/point_cloud_io.h"
#include "acquisition/recording.h"
#include "apps/commands.h"
#include "pipeline/output.h"

namespace s2m::app {
namespace {

// JSON text from the recording, parsed for the document; kept as a string if it does not parse (the writer
// validates it, a hand-edited file may not).
nlohmann::json JsonOrText(const std::string& text) {
  nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  return j.is_discarded() ? nlohmann::json(text) : j;
}

// `info` on a recording: its meta, device, streams and, when it has exactly one points stream, the views that
// `fit` would read.
int DescribeRecording(const std::string& file, bool json) {
  const RecordingReader reader = RecordingReader::Open(file);
  const RecordingSummary s = reader.Summary();
  nlohmann::json j = {{"file", file}, {"format", s.format}};
  j["meta"] = nlohmann::json::object();
  for (const auto& [key, value] : s.meta) j["meta"][key] = value;
  j["device"] = JsonOrText(s.device);
  j["calibration"] = JsonOrText(s.calibration);
  j["streams"] = nlohmann::json::array();
  for (std::size_t k = 0; k < s.streams.size(); ++k) {
    const RecordingStream& st = s.streams[k];
    j["streams"].push_back({{"id", st.id},
                            {"name", st.name},
                            {"kind", st.kind},
                            {"encoding", st.encoding},
                            {"units", st.units},
                            {"frames", s.frames_per_stream[k]},
                            {"payload_bytes", s.payload_bytes_per_stream[k]}});
  }
  j["posed_frames"] = s.posed_frames;
  std::optional<ScanSet> views;
  std::int64_t frames = 0;
  for (const std::int64_t n : s.frames_per_stream) frames += n;
  if (frames > 0) {
    // The views `fit` and `export` would read: every stream through the frame path (depth images
    // back-projected, laser sweeps gathered); decodes and validates every payload.
    const std::unique_ptr<FrameSource> source = OpenRecordingSource(file);
    views = FramesToScanSet(*source);
    j["views"] = views->scans.size();
    j["points"] = views->TotalPoints();
    const Bounds b = ComputeBounds(views->MergedWorldPoints());
    j["world_bounds"] = {{"min", ToJson(b.min)}, {"max", ToJson(b.max)}};
  }
  if (json) {
    j["schema"] = "scan2model.info/1";
    std::cout << j.dump(2) << "\n";
    return kOk;
  }
  std::cout << file << "\n"
            << "  format    " << s.format << " (recording)\n";
  for (const auto& [key, value] : s.meta) {
    if (key != "format") std::cout << "  meta      " << key << " = " << value << "\n";
  }
  std::cout << "  device    " << s.device << "\n"
            << "  calib     " << s.calibration << "\n";
  for (std::size_t k = 0; k < s.streams.size(); ++k) {
    const RecordingStream& st = s.streams[k];
    std::cout << "  stream    " << st.id << " '" << st.name << "': " << st.kind << ", " << st.encoding << ", "
              << st.units << ", " << s.frames_per_stream[k] << " frames, " << s.payload_bytes_per_stream[k]
              << " bytes\n";
  }
  std::cout << "  posed     " << s.posed_frames << " frames\n";
  if (views) {
    const Bounds b = ComputeBounds(views->MergedWorldPoints());
    std::cout << "  views     " << views->scans.size() << " (" << views->TotalPoints() << " points)\n"
              << "  min       " << Format(b.min, 8) << "  (world)\n"
              << "  max       " << Format(b.max, 8) << "  (world)\n";
  }
  return kOk;
}

// `info` on an E57 file: the merged cloud as for any point-cloud file (what `fit` of a primitive reads), plus
// each data3D scan: its name, points, pose, fields and encodings (what multi-view `fit` reads as views).
int DescribeE57(const std::string& file, bool json) {
  const E57Data data = ReadE57(file);
  const Scan cloud = ToOneCloud(data, file);
  nlohmann::json j = DescribeScan(cloud, file, ToString(PointCloudFormat::kE57));
  nlohmann::json scans = nlohmann::json::array();
  for (const E57Scan& s : data.scans) {
    scans.push_back({{"name", s.name},
                     {"guid", s.guid},
                     {"points", s.scan.size()},
                     {"records", s.records},
                     {"invalid", s.invalid},
                     {"coordinates", s.coordinates},
                     {"intensity", s.intensity.size() > 0},
                     {"colour", s.colour.cols() > 0},
                     {"row_column", !s.row_index.empty()},
                     {"world_T_scan", ToJson(s.scan.world_T_scan.matrix())},
                     {"fields", s.fields}});
  }
  j["e57"] = {{"guid", data.guid},
              {"library_version", data.library_version},
              {"images", data.images},
              {"scans", scans}};
  if (json) {
    j["schema"] = "scan2model.info/1";
    std::cout << j.dump(2) << "\n";
    return kOk;
  }
  const Bounds b = ComputeBounds(cloud.points);
  std::cout << file << "\n"
            << "  format    e57 (" << data.scans.size() << (data.scans.size() == 1 ? " scan, " : " scans, ")
            << data.images << (data.images == 1 ? " image" : " images")
            << (data.library_version.empty() ? "" : ", written by " + data.library_version) << ")\n"
            << "  points    " << cloud.size() << " (all scans in the file's world frame)\n"
            << "  units     " << cloud.units << "\n"
            << "  min       " << Format(b.min, 8) << "  (world)\n"
            << "  max       " << Format(b.max, 8) << "  (world)\n";
  for (std::size_t k = 0; k < data.scans.size(); ++k) {
    const E57Scan& s = data.scans[k];
    const Eigen::Vector3d t = s.scan.world_T_scan.translation();
    std::cout << "  scan " << k << "    '" << s.name << "': " << s.scan.size() << " points of " << s.records
              << " records (" << s.coordinates << (s.intensity.size() > 0 ? ", intensity" : "")
              << (s.colour.cols() > 0 ? ", colour" : "") << (!s.row_index.empty() ? ", rows/columns" : "")
              << "), pose rotation " << Format(s.scan.world_T_scan.angle() * 180.0 / M_PI, 6)
              << " deg, translation " << Format(t, 8) << "\n";
    for (const std::string& f : s.fields) std::cout << "            " << f << "\n";
  }
  for (const std::string& note : cloud.metadata.notes) std::cout << "  note      " << note << "\n";
  return kOk;
}

}  // namespace

Runner AddInfoCommand(CLI::App& app) {
  struct Options {
    std::string file;
    bool json = false;
  };
  auto options = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand("info", "Describe a point-cloud file: points, bounds, units, normals");
  cmd->add_option("file", options->file,
                  "Input: .ply, .ply.gz, .pcd, .xyz/.txt/.csv/.pts, .ds, .e57, .s2mrec")
      ->required();
  cmd->add_flag("--json", options->json, "Machine-readable output (schema scan2model.info/1, docs/cli.md)");
  return [options]() {
    try {
      if (std::filesystem::path(options->file).extension() == kRecordingExtension) {
        return DescribeRecording(options->file, options->json);
      }
      if (IsE57File(options->file)) return DescribeE57(options->file, options->json);
      const PointCloudFormat format = DetectFormat(options->file);
      const Scan scan = ReadPointCloud(options->file, format);
      nlohmann::json j = DescribeScan(scan, options->file, ToString(format));
      if (options->json) {
        j["schema"] = "scan2model.info/1";
        std::cout << j.dump(2) << "\n";
        return int{kOk};
      }
      const Bounds b = ComputeBounds(scan.points);
      std::cout << options->file << "\n"
                << "  format    " << ToString(format) << "\n"
                << "  points    " << scan.size() << "\n"
                << "  normals   " << (scan.has_normals() ? "yes" : "no") << "\n"
                << "  weights   " << (scan.has_weights() ? "yes" : "no") << "\n"
                << "  units     " << scan.units << "\n"
                << "  min       " << Format(b.min, 8) << "\n"
                << "  max       " << Format(b.max, 8) << "\n"
                << "  extent    " << Format(b.extent(), 8) << "  (diagonal " << Format(b.diagonal(), 8)
                << ")\n";
      if (!scan.world_T_scan.matrix().isIdentity(0.0)) {
        std::cout << "  world_T_scan\n" << scan.world_T_scan.matrix() << "\n";
      }
      for (const std::string& note : scan.metadata.notes) std::cout << "  note      " << note << "\n";
      return int{kOk};
    } catch (const FormatError& e) {
      return ReportError("info", e.what(), kInputError, options->json);
    }
  };
}

}  // namespace s2m::app
