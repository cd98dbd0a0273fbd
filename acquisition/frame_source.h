#pragma once
// Frame sources (issue 5): ONE interface that every input implements -- a recording replayed, plain files (a
// scan2model.views/1 manifest, a Stanford .conf, a single cloud, Kinect depth TIFFs) and the virtual scanner
// (devices/virtual_scanner.h); a live device driver would be one more. A source yields frames of the kinds a
// real device gives:
//   - a depth image with the stream's pinhole intrinsics (structured-light / Kinect-class cameras),
//   - a laser profile: the points of one laser line in the scanner's frame, with the turntable's angle,
//   - a ready point set (a file, a scanner that triangulates itself),
// each with its timestamp and the device's nominal pose (world_T_scan). FramesToScanSet turns any source's
// frames into per-view point sets with world_T_scan, so a replayed recording goes through exactly the code
// path of the device that made it.

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "acquisition/depth_frame.h"
#include "registration/rigid_motion.h"
#include "registration/scan.h"

namespace s2m {

enum class FrameKind { kPoints, kDepth, kProfile };
// "points", "depth", "profile": the recording's stream kinds (docs/recordings.md).
const char* ToString(FrameKind kind);
FrameKind FrameKindFromString(const std::string& kind);  // throws std::invalid_argument

// The depth-image payload of a recording (kind "depth"): little-endian uint32 width, uint32 height, then
// width * height uint16 raw values, row-major (docs/recordings.md).
inline constexpr const char* kDepthEncoding = "depth_u16le";

struct StreamInfo {
  std::string name;
  FrameKind kind = FrameKind::kPoints;
  // Units of the stream's coordinates ("mm", "m", ... or "unknown"); a depth stream's points are in metres
  // when depth_scale is metres per raw unit (the OpenNI convention), which is what "m" declares.
  std::string units = "unknown";
  std::optional<DepthIntrinsics> intrinsics;  // required for a depth stream
};

struct SourceDescription {
  std::string origin;                   // the file or device the frames come from (named in errors)
  std::string name;                     // the set's name (a recording's meta "name")
  std::string device_json = "{}";       // the device's description; its "name" names the device
  std::string calibration_json = "{}";  // everything but the streams' intrinsics (turntable axis, ...)
  std::vector<std::pair<std::string, std::string>> meta;  // free metadata to record
  std::vector<StreamInfo> streams;
};

struct Frame {
  int stream = 0;  // index into SourceDescription::streams
  FrameKind kind = FrameKind::kPoints;
  std::int64_t view = 0;                      // frames of one view (a turntable stop, a sweep) share it
  std::optional<std::int64_t> timestamp_ns;   // since the Unix epoch; absent when the source has no clock
  std::optional<RigidMotion> world_T_scan;    // the device's nominal pose of this frame
  std::optional<double> turntable_angle_rad;  // nominal turntable angle, when there is a turntable
  Eigen::Matrix3Xd points;                    // kPoints, kProfile: scanner coordinates, stream units
  DepthImage depth;                           // kDepth: raw values, see the stream's intrinsics
  std::string source;                         // where the frame came from (file, recording frame, device)
};

// What replay waits on. Injectable so that tests check the timing without sleeping.
class ReplayClock {
 public:
  virtual ~ReplayClock() = default;
  virtual std::int64_t NowNs() = 0;               // a monotonic clock
  virtual void SleepUntilNs(std::int64_t t) = 0;  // returns at or after t on NowNs's scale
};
// std::chrono::steady_clock and std::this_thread::sleep_until.
std::shared_ptr<ReplayClock> SteadyReplayClock();

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  virtual const SourceDescription& description() const = 0;
  // The next frame, or nullopt at the end. Throws FormatError (recordings, files) naming the file and frame.
  virtual std::optional<Frame> Next() = 0;
  // The views in delivery order, when known in advance (recordings, files, the virtual scanner).
  virtual std::vector<std::int64_t> Views() const = 0;
  // The next frame is the first of `view`. Throws std::out_of_range when the source has no such view.
  virtual void SeekView(std::int64_t view) = 0;
  virtual std::optional<std::int64_t> FrameCount() const { return std::nullopt; }
  // What the replay did with the recording's timing (recordings replayed with their original timing; all zero
  // otherwise).
  struct TimingReport {
    int recording_clock_jumps = 0;  // timestamps that went back, or forward by more than max_gap_s
    int replay_late_restarts = 0;   // frames due more than max_gap_s in the past (the replay clock jumped)
  };
  virtual TimingReport timing_report() const { return {}; }
};

// ---------------------------------------------------------------------------------------------- recordings

struct ReplayOptions {
  // false (default): frames as fast as they are read. true: the original timing -- each frame is delivered
  // when as much time has passed since the first delivered frame (or the last seek) as between their
  // timestamps. Frames without a timestamp are delivered at once.
  bool original_timing = false;
  // A clock jump is not a pause. When the recording's timestamps go back, or forward by more than
  // `max_gap_s` (the recording machine's clock was set while it recorded), the frame is delivered at once and
  // the timing restarts from it, instead of replaying everything after a backward jump at once or waiting out
  // a forward one. When the replay clock is more than `max_gap_s` past a frame's due time (the replaying
  // machine slept, or the reader stalled), the timing restarts at that frame too, instead of delivering the
  // frames after it in a burst. Both are counted in FrameSource::timing_report().
  double max_gap_s = 60.0;
  std::shared_ptr<ReplayClock> clock;  // null: SteadyReplayClock()
};

// Opens a recording (RecordingReader::Open's checks) and replays every stream's frames in recording order
// (frame id, i.e. the order they were written). Checked at open, FormatError naming the file: a stream kind
// or encoding this build does not decode, a depth stream without intrinsics in the calibration, a
// calibration that is not JSON; each frame's payload is checked when it is delivered.
std::unique_ptr<FrameSource> OpenRecordingSource(const std::filesystem::path& path,
                                                 const ReplayOptions& options = {});

// ------------------------------------------------------------------------------------------------ files

// A multi-view file (scan2model.views/1 .json, Stanford .conf) or one point cloud: one points frame per view
// with its world_T_scan. Depth TIFFs (frame_<time>_depth.tiff beside frame_<time>.xml): one depth frame per
// file, one view each, timestamps from the grabber's file name; all must share their intrinsics.
// FormatError naming the file.
std::unique_ptr<FrameSource> OpenFileSource(const std::vector<std::filesystem::path>& files);

// A ScanSet (already read) as a source of points frames; `origin` names it in errors.
std::unique_ptr<FrameSource> ScanSetSource(ScanSet set, const std::string& device_name = "file",
                                           const std::string& origin = "");

// .s2mrec: OpenRecordingSource; anything else: OpenFileSource.
std::unique_ptr<FrameSource> OpenFrameSource(const std::vector<std::filesystem::path>& inputs,
                                             const ReplayOptions& replay = {});

// ---------------------------------------------------------------------------------------- frames to views

// Called after each frame with the frames done so far and the total when known.
using FrameProgress = std::function<void(std::int64_t done, std::optional<std::int64_t> total)>;

// Every frame from the source's current position to its end, as views: one scan per (stream, view), in
// order of first appearance. Depth frames are back-projected with the stream's intrinsics (BackProject of
// depth_frame.h: metres, camera frame); points and profiles are taken as they are. A view with one frame
// keeps the frame's points and pose bit for bit; a view of several frames (a sweep of laser profiles) is
// expressed in the frame of its first frame: each frame's points are mapped by first_T_frame =
// world_T_first^-1 * world_T_frame. Frames without a pose get the identity. Throws FormatError for a source
// with no frames or a view with no points.
ScanSet FramesToScanSet(FrameSource& source, const FrameProgress& progress = {});

// ---------------------------------------------------------------------------------------------- recording

// Records every frame of the source into a new recording (RecordingWriter: one transaction per frame): the
// description's device, calibration (with each depth stream's intrinsics under
// calibration.streams.<name>.intrinsics), meta and streams, then the frames, each stored with `compression`
// ("none" or "zlib", recording.h). Returns the number of frames.
std::int64_t RecordSource(FrameSource& source, const std::filesystem::path& out,
                          const FrameProgress& progress = {}, const std::string& compression = "none");

// Payload codecs of the depth stream. DecodeDepth throws FormatError (file, where) for a size that does not
// match the declared image.
std::vector<std::uint8_t> EncodeDepth(const DepthImage& image);
DepthImage DecodeDepth(const std::vector<std::uint8_t>& payload, const std::string& file,
                       const std::string& where);

}  // namespace s2m
