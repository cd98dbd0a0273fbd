// `scan2model record` and `scan2model export`: frame sources (acquisition/frame_source.h) into a recording,
// and any source into one PLY per view plus a scan2model.views/1 manifest.

#include <unistd.h>

#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "acquisition/e57_io.h"
#include "acquisition/format_error.h"
#include "acquisition/frame_source.h"
#include "acquisition/recording.h"
#include "acquisition/scan_set_io.h"
#include "apps/commands.h"
#include "pipeline/output.h"
#ifdef S2M_HAVE_VIRTUAL_SCANNER
#include "devices/virtual_scanner.h"
#endif
#ifdef S2M_HAVE_PCL
#include "acquisition/pcl_preprocess.h"
#endif
#ifdef S2M_HAVE_PCL
#include "acquisition/pcl_preprocess.h"
#endif

namespace s2m::app {
namespace {

namespace fs = std::filesystem;

// Progress on standard error: a bar redrawn in place on a terminal, one line per tenth otherwise (logs).
FrameProgress ProgressBar(const std::string& what, bool quiet) {
  if (quiet) return {};
  const bool tty = isatty(STDERR_FILENO) != 0;
  auto last_tenth = std::make_shared<std::int64_t>(-1);
  return [what, tty, last_tenth](std::int64_t done, std::optional<std::int64_t> total) {
    if (!total || *total <= 0) {
      if (tty) std::cerr << "\r" << what << ": " << done << " frames" << std::flush;
      return;
    }
    const std::int64_t tenth = 10 * done / *total;
    if (tty) {
      constexpr int kWidth = 30;
      const auto filled = static_cast<int>(kWidth * done / *total);
      std::cerr << "\r" << what << " [" << std::string(static_cast<std::size_t>(filled), '#')
                << std::string(static_cast<std::size_t>(kWidth - filled), ' ') << "] " << done << "/"
                << *total << " frames" << (done == *total ? "\n" : "") << std::flush;
    } else if (tenth != *last_tenth) {
      *last_tenth = tenth;
      std::cerr << what << ": " << done << "/" << *total << " frames\n";
    }
  };
}

std::unique_ptr<FrameSource> OpenSource(const std::string& device, const std::vector<std::string>& inputs,
                                        bool original_timing, double max_gap_s = 60.0) {
  if (!device.empty()) {
    if (!inputs.empty()) throw std::invalid_argument("give either --device or input files, not both");
#ifdef S2M_HAVE_VIRTUAL_SCANNER
    std::string scene, units;
    const VirtualScannerOptions options = ParseVirtualDevice(device, scene, units);
    return MakeVirtualScanner(SceneByName(scene, units), options);
#else
    throw std::invalid_argument("this build has no virtual scanner (Open3D was not found when it was built)");
#endif
  }
  if (inputs.empty()) throw std::invalid_argument("no input: give --device virtual:... or input files");
  std::vector<fs::path> paths(inputs.begin(), inputs.end());
  ReplayOptions replay;
  replay.original_timing = original_timing;
  replay.max_gap_s = max_gap_s;
  return OpenFrameSource(paths, replay);
}

}  // namespace

Runner AddRecordCommand(CLI::App& app) {
  struct Options {
    std::string device, out;
    std::vector<std::string> inputs;
    bool original_timing = false, quiet = false, compress = false;
    double max_gap_s = 60.0;
  };
  auto options = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand(
      "record", "Record a device's frames (the virtual scanner) or input files into a recording (.s2mrec)");
  cmd->add_option("inputs", options->inputs,
                  "Instead of --device: a views manifest (.json), Stanford .conf, E57 file, point cloud, "
                  "recording, or Kinect depth frames (frame_<time>_depth.tiff beside frame_<time>.xml)");
  cmd->add_option("--device", options->device,
                  "virtual:<vase|helical|spiral|part|mesh.ply>[,key=value...] (docs/acquisition.md)");
  cmd->add_option("-o,--output,--out", options->out,
                  "The new recording (never overwritten) (--out: the old spelling, an alias for one release)")
      ->required();
  cmd->add_flag("--original-timing", options->original_timing,
                "Replaying a recording: deliver its frames with their original timing");
  cmd->add_option("--max-gap", options->max_gap_s,
                  "With --original-timing: a gap between frames' timestamps longer than this (seconds), or a "
                  "timestamp going back, is a clock jump: that frame comes at once and the timing restarts")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_flag("--compress", options->compress,
                "Store each frame zlib-compressed (depth images shrink several-fold)");
  cmd->add_flag("-q,--quiet", options->quiet, "No progress on standard error");
  return [options]() {
    try {
      std::unique_ptr<FrameSource> source =
          OpenSource(options->device, options->inputs, options->original_timing, options->max_gap_s);
      const std::int64_t frames =
          RecordSource(*source, options->out, ProgressBar("recording", options->quiet),
                       options->compress ? kZlibCompression : kNoCompression);
      const RecordingSummary s = RecordingReader::Open(options->out).Summary();
      std::cout << options->out << ": " << frames << " frames\n";
      const FrameSource::TimingReport timing = source->timing_report();
      if (timing.recording_clock_jumps > 0) {
        std::cout << "  replay: " << timing.recording_clock_jumps
                  << " clock jump(s) in the input's timestamps (back, or forward by more than --max-gap "
                  << options->max_gap_s << " s): those frames came at once and the timing restarted there\n";
      }
      if (timing.replay_late_restarts > 0) {
        std::cout << "  replay: fell behind the original timing by more than --max-gap "
                  << timing.replay_late_restarts << " time(s) (the clock jumped or reading stalled): the "
                  << "timing restarted there instead of delivering the frames after it in a burst\n";
      }
      for (std::size_t k = 0; k < s.streams.size(); ++k) {
        std::cout << "  stream '" << s.streams[k].name << "' (" << s.streams[k].kind << ", "
                  << s.streams[k].units << "): " << s.frames_per_stream[k] << " frames, "
                  << s.payload_bytes_per_stream[k] << " bytes\n";
      }
      return int{kOk};
    } catch (const FormatError& e) {
      return ReportError("record", e.what(), kInputError, false);
    } catch (const std::invalid_argument& e) {
      return ReportError("record", e.what(), kUsage, false);
    }
  };
}

Runner AddExportCommand(CLI::App& app) {
  struct Options {
    std::vector<std::string> inputs;
    std::string out;
    std::vector<std::int64_t> views;
    bool quiet = false;
    // Preprocessing (acquisition/pcl_preprocess.h), each step optional, per view in its scanner's
    // coordinates.
    std::vector<double> crop_min, crop_max;
    double voxel = 0.0;
    bool remove_outliers = false, normals = false;
    int outlier_neighbours = 50, normal_neighbours = 20;
    double outlier_stddev = 1.0;
  };
  auto options = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand(
      "export",
      "Write a recording's (or any input's) views as one PLY per view plus a scan2model.views/1 manifest, or "
      "as one E57 file");
  cmd->add_option(
         "inputs", options->inputs,
         "A recording (.s2mrec), views manifest (.json), Stanford .conf, E57 file, point cloud, or Kinect "
         "depth frames")
      ->required();
  cmd->add_option(
         "-o,--output,--out", options->out,
         "Output folder (created; views.json and view_NNN.ply inside), or an .e57 file (every view a "
         "scan with its pose, in metres) (--out: the old spelling, an alias for one release)")
      ->required();
  cmd->add_option("--view", options->views, "Only these views (the recording's view numbers); repeatable");
  cmd->add_flag("-q,--quiet", options->quiet, "No progress on standard error");
  const std::string group =
      "Preprocessing (PCL; each view in its scanner's coordinates, sensor at the origin)";
  cmd->add_option("--crop-min", options->crop_min, "Crop box corner x y z (with --crop-max), inclusive")
      ->expected(3)
      ->group(group);
  cmd->add_option("--crop-max", options->crop_max, "Crop box corner x y z (with --crop-min)")
      ->expected(3)
      ->group(group);
  cmd->add_flag("--remove-outliers", options->remove_outliers, "Statistical outlier removal")->group(group);
  cmd->add_option("--outlier-neighbours", options->outlier_neighbours,
                  "Neighbours of the outlier statistic (50)")
      ->group(group);
  cmd->add_option("--outlier-stddev", options->outlier_stddev,
                  "Standard deviations beyond which a point goes (1.0)")
      ->group(group);
  cmd->add_option("--voxel", options->voxel,
                  "Voxel-grid down-sampling, edge length in the data's units (0: off)")
      ->group(group);
  cmd->add_flag("--normals", options->normals, "Estimate normals, oriented towards the sensor")->group(group);
  cmd->add_option("--normal-neighbours", options->normal_neighbours,
                  "Neighbours of each normal's plane fit (20)")
      ->group(group);
  return [options]() {
    try {
      const bool crop = !options->crop_min.empty() || !options->crop_max.empty();
      const bool preprocess = crop || options->voxel > 0 || options->remove_outliers || options->normals;
      if (crop && (options->crop_min.size() != 3 || options->crop_max.size() != 3))
        throw std::invalid_argument("--crop-min and --crop-max go together, three numbers each");
#ifndef S2M_HAVE_PCL
      if (preprocess)
        throw std::invalid_argument("this build has no preprocessing (PCL was not found when it was built)");
#endif
      std::unique_ptr<FrameSource> source = OpenSource("", options->inputs, false);
      ScanSet set;
      const FrameProgress progress = ProgressBar("converting", options->quiet);
      if (options->views.empty()) {
        set = FramesToScanSet(*source, progress);
      } else {
        for (const std::int64_t view : options->views) {
          try {
            source->SeekView(view);
          } catch (const std::out_of_range&) {
            throw FormatError(options->inputs.front(), "", "no view " + std::to_string(view));
          }
          // One view: the frames from its first up to the next view's.
          std::vector<Frame> frames;
          while (std::optional<Frame> f = source->Next()) {
            if (f->view != view) break;
            frames.push_back(std::move(*f));
          }
          // Converted through the same function as a whole source.
          struct OneView final : FrameSource {
            const SourceDescription& d;
            std::vector<Frame> frames;
            std::size_t next = 0;
            OneView(const SourceDescription& description, std::vector<Frame> f)
                : d(description), frames(std::move(f)) {}
            const SourceDescription& description() const override { return d; }
            std::optional<Frame> Next() override {
              if (next >= frames.size()) return std::nullopt;
              return std::move(frames[next++]);
            }
            std::vector<std::int64_t> Views() const override { return {}; }
            void SeekView(std::int64_t) override {}
          } one(source->description(), std::move(frames));
          ScanSet part = FramesToScanSet(one);
          if (set.name.empty()) set.name = part.name;
          for (Scan& s : part.scans) set.scans.push_back(std::move(s));
        }
      }
#ifdef S2M_HAVE_PCL
      if (preprocess) {
        PreprocessOptions p;
        p.crop = crop;
        if (crop) {
          p.crop_min = Eigen::Vector3d(options->crop_min[0], options->crop_min[1], options->crop_min[2]);
          p.crop_max = Eigen::Vector3d(options->crop_max[0], options->crop_max[1], options->crop_max[2]);
        }
        p.voxel_size = options->voxel;
        p.remove_outliers = options->remove_outliers;
        p.outlier_neighbours = options->outlier_neighbours;
        p.outlier_stddev = options->outlier_stddev;
        p.estimate_normals = options->normals;
        p.normal_neighbours = options->normal_neighbours;
        for (std::size_t k = 0; k < set.scans.size(); ++k) {
          Scan& scan = set.scans[k];
          // Every frame source delivers views in the scanner's coordinates: the sensor is at the origin.
          const PreprocessResult r = Preprocess(scan.points, Eigen::Vector3d::Zero(), p);
          if (r.points.cols() == 0)
            throw FormatError(scan.metadata.source, "", "preprocessing left no points in the view");
          scan.points = r.points;
          scan.normals = r.normals;
          scan.metadata.notes.push_back("preprocessed: " + std::to_string(r.input) + " points, " +
                                        std::to_string(r.removed_by_crop) + " cropped, " +
                                        std::to_string(r.removed_as_outliers) + " outliers, " +
                                        std::to_string(r.removed_by_voxel) + " merged by the voxel grid, " +
                                        std::to_string(r.removed_without_normal) + " without a normal");
          if (!options->quiet) std::cerr << "view " << k << ": " << scan.metadata.notes.back() << "\n";
        }
      }
#endif
      if (IsE57File(options->out)) {
        // One E57 file: every view a data3D scan with its pose, coordinates as float64 in metres.
        if (fs::path(options->out).has_parent_path())
          fs::create_directories(fs::path(options->out).parent_path());
        WriteE57(options->out, set);
        std::cout << options->out << ": " << set.scans.size() << " views, " << set.TotalPoints()
                  << " points (E57, metres)\n";
        return int{kOk};
      }
      fs::create_directories(options->out);
      const fs::path manifest = fs::path(options->out) / "views.json";
      WriteScanSet(manifest, set);
      std::cout << manifest.string() << ": " << set.scans.size() << " views, " << set.TotalPoints()
                << " points (" << (set.scans.empty() ? "" : set.scans.front().units) << ")\n";
      return int{kOk};
    } catch (const FormatError& e) {
      return ReportError("export", e.what(), kInputError, false);
    } catch (const std::invalid_argument& e) {
      return ReportError("export", e.what(), kUsage, false);
    } catch (const fs::filesystem_error& e) {
      return ReportError("export", e.what(), kInputError, false);
    }
  };
}

}  // namespace s2m::app
