#pragma once
// Recordings: one SQLite file per acquisition session (format "scan2model.recording/1", schema in
// docs/recordings.md), in the spirit of rosbag2's SQLite storage. A recording holds the device's description
// and calibration, one or more streams (points, depth images, laser profiles) and their frames, each frame
// with an optional world_T_scan pose and turntable angle. The writer commits one transaction per frame in WAL
// mode with synchronous=FULL, so a crash or a pulled cable loses at most the frame in flight. SQLite stays
// behind this header: nothing here includes sqlite3.h.

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "registration/rigid_motion.h"
#include "registration/scan.h"

namespace s2m {

inline constexpr const char* kRecordingFormat = "scan2model.recording/1";
inline constexpr const char* kRecordingExtension = ".s2mrec";
// The point-set payload: a little-endian uint64 point count, then count x y z triplets of little-endian IEEE
// float64 (docs/recordings.md).
inline constexpr const char* kPointsEncoding = "xyz_f64le";
// Frame compression: "none", or "zlib" = a little-endian uint64 uncompressed size, then the payload as one
// zlib stream (RFC 1950). Depth images, mostly "no return" zeros, shrink several-fold.
inline constexpr const char* kNoCompression = "none";
inline constexpr const char* kZlibCompression = "zlib";
// Meta key "status" of an acquisition recorded as it goes (docs/recordings.md): kStatusInProgress while
// frames arrive, kStatusComplete when the acquisition finished, "interrupted: <reason>" when it stopped early
// (the frames so far are kept; the acquisition may be resumed with RecordingWriter::OpenForAppend).
inline constexpr const char* kStatusMeta = "status";
inline constexpr const char* kStatusInProgress = "in_progress";
inline constexpr const char* kStatusComplete = "complete";

struct RecordingStream {
  std::int64_t id = 0;
  std::string name;
  std::string kind;      // "points", "depth" or "profile"
  std::string encoding;  // e.g. kPointsEncoding
  std::string units;     // "mm", "m", ... or "unknown"
};

struct RecordingFrame {
  std::int64_t id = 0;
  std::int64_t stream = 0;
  std::optional<std::int64_t> timestamp_ns;  // since the Unix epoch; absent when the source had no clock
  std::int64_t view = 0;
  std::string compression = "none";
  std::vector<std::uint8_t> payload;
  std::optional<RigidMotion> world_T_scan;
  std::optional<double> turntable_angle_rad;
};

// What a recording holds, without the payloads.
struct RecordingSummary {
  std::string format;
  std::vector<std::pair<std::string, std::string>> meta;  // every meta row, format included
  std::string device;                                     // JSON text
  std::string calibration;                                // JSON text
  std::vector<RecordingStream> streams;
  std::vector<std::int64_t> frames_per_stream;  // parallel to streams
  std::vector<std::int64_t> payload_bytes_per_stream;
  std::int64_t posed_frames = 0;
};

class RecordingWriter {
 public:
  // Creates a new recording; throws FormatError naming the file when it exists already (a recording is never
  // overwritten) or cannot be created.
  static RecordingWriter Create(const std::filesystem::path& path);
  // Reopens an existing recording to append frames (an interrupted acquisition resumed):
  // RecordingReader::Open's checks first, then read-write in WAL mode as Create. Refuses, with FormatError
  // naming the file, a recording whose meta "status" is kStatusComplete (a finished acquisition is never
  // extended). Streams are found with RecordingReader::Streams (their ids stay valid).
  static RecordingWriter OpenForAppend(const std::filesystem::path& path);
  RecordingWriter(RecordingWriter&&) noexcept;
  RecordingWriter& operator=(RecordingWriter&&) noexcept;
  ~RecordingWriter();  // closes (see Close) and swallows errors; call Close to see them

  // Free metadata (key "format" is reserved). Replaces an earlier value of the key.
  void SetMeta(const std::string& key, const std::string& value);
  // The device's description and calibration/intrinsics, JSON text each (validated as JSON).
  void SetDevice(const std::string& description_json, const std::string& calibration_json = "{}");
  // Returns the stream's id. kind: "points", "depth" or "profile".
  std::int64_t AddStream(const std::string& name, const std::string& kind, const std::string& encoding,
                         const std::string& units = "unknown");
  // One committed transaction per frame; returns the frame's id. `compression`: kNoCompression or
  // kZlibCompression (the payload is compressed here). Throws std::invalid_argument for a pose that is not
  // finite or not rigid or an unknown compression, FormatError naming the file when SQLite fails.
  std::int64_t AppendFrame(std::int64_t stream, std::int64_t view, const std::vector<std::uint8_t>& payload,
                           const std::optional<RigidMotion>& world_T_scan = std::nullopt,
                           std::optional<std::int64_t> timestamp_ns = std::nullopt,
                           std::optional<double> turntable_angle_rad = std::nullopt,
                           const std::string& compression = kNoCompression);
  // Checkpoints the write-ahead log into the file and leaves WAL mode, so that a finished recording is one
  // self-contained file. Idempotent.
  void Close();

  const std::filesystem::path& path() const { return path_; }

 private:
  struct Db;
  RecordingWriter(std::filesystem::path path, std::unique_ptr<Db> db);
  std::filesystem::path path_;
  std::unique_ptr<Db> db_;
};

class RecordingReader {
 public:
  // Opens read-only and checks: a SQLite database (not truncated: header size against the file's), PRAGMA
  // quick_check, the tables of docs/recordings.md, meta format == kRecordingFormat. Throws FormatError naming
  // the file and the problem.
  static RecordingReader Open(const std::filesystem::path& path);
  RecordingReader(RecordingReader&&) noexcept;
  RecordingReader& operator=(RecordingReader&&) noexcept;
  ~RecordingReader();

  RecordingSummary Summary() const;
  std::vector<RecordingStream> Streams() const;
  // Frames of a stream ordered by view, then id; with payloads. Poses validated (finite, rigid): FormatError.
  std::vector<RecordingFrame> Frames(std::int64_t stream) const;
  std::vector<RecordingFrame> FramesOfView(std::int64_t stream, std::int64_t view) const;
  std::optional<std::string> Meta(const std::string& key) const;

  const std::filesystem::path& path() const { return path_; }

 private:
  struct Db;
  RecordingReader(std::filesystem::path path, std::unique_ptr<Db> db);
  std::vector<RecordingFrame> Query(std::int64_t stream, std::optional<std::int64_t> view) const;
  std::filesystem::path path_;
  std::unique_ptr<Db> db_;
};

// A frame's payload as the sensor gave it: decompressed when the frame is compressed. Throws FormatError
// (file and `where` given by the caller) for an unknown compression or a damaged compressed payload.
std::vector<std::uint8_t> FramePayload(const RecordingFrame& frame, const std::string& file,
                                       const std::string& where);

// The point-set payload (kPointsEncoding) of a 3xN matrix, and back. DecodePoints throws FormatError (file
// and `where` given by the caller) for a size that does not match the count, or a coordinate that is not
// finite.
std::vector<std::uint8_t> EncodePoints(const Eigen::Matrix3Xd& points);
Eigen::Matrix3Xd DecodePoints(const std::vector<std::uint8_t>& payload, const std::string& file,
                              const std::string& where);

// A ScanSet as a recording: one "points" stream (named `stream`), one frame per scan (view = its index) with
// its world_T_scan, turntable angle and timestamp; name, units and device in meta. Normals and weights are
// not recorded (the payload holds points only).
void WriteRecording(const std::filesystem::path& path, const ScanSet& set,
                    const std::string& stream = "points");
// A recording's points stream as a ScanSet, one scan per frame in (view, id) order. `stream` empty: the
// recording's only points stream (FormatError when there are none or several). Frames without a pose get the
// identity; each scan's metadata.device is the device description's "name" member, when it has one.
ScanSet ReadRecording(const std::filesystem::path& path, const std::string& stream = "");

}  // namespace s2m
