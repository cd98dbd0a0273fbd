// Frame sources without the virtual scanner: depth frames and profiles through a recording and back, replay
// timing on an injected clock, bad recordings, the real Kinect frames as a recording.

#include "acquisition/frame_source.h"

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>

#include "acquisition/format_error.h"
#include "acquisition/recording.h"
#include "raw_sql.h"
#include "test_paths.h"
#include "test_support.h"

namespace s2m {
namespace {

namespace fs = std::filesystem;

fs::path TempDir(const std::string& name) {
  return test::FreshTempDir("frames_" + name);
}

using test::RawExec;

// A source of prepared frames (what a device driver would hand over).
class ListSource final : public FrameSource {
 public:
  ListSource(SourceDescription d, std::vector<Frame> frames) : d_(std::move(d)), frames_(std::move(frames)) {}
  const SourceDescription& description() const override { return d_; }
  std::optional<Frame> Next() override {
    if (next_ >= frames_.size()) return std::nullopt;
    return frames_[next_++];
  }
  std::vector<std::int64_t> Views() const override { return {}; }
  void SeekView(std::int64_t) override { next_ = 0; }
  std::optional<std::int64_t> FrameCount() const override {
    return static_cast<std::int64_t>(frames_.size());
  }

 private:
  SourceDescription d_;
  std::vector<Frame> frames_;
  std::size_t next_ = 0;
};

DepthIntrinsics Intrinsics() {
  DepthIntrinsics k;
  k.fx = 520.5;
  k.fy = 519.25;
  k.cx = 3.5;
  k.cy = 2.75;
  k.depth_scale = 0.001;
  k.depth_scale_from_file = true;
  return k;
}

// Three depth frames of a 8 x 6 image (some pixels without return) at 1 s, 2 s and 4 s, turntable poses.
ListSource DepthSource() {
  SourceDescription d;
  d.name = "depth test";
  d.device_json = R"({"name": "test-kinect"})";
  d.calibration_json = R"({"turntable": {"axis": [0, 0, 1]}})";
  d.meta = {{"operator", "test"}};
  d.streams.push_back({"depth", FrameKind::kDepth, "m", Intrinsics()});
  std::vector<Frame> frames;
  for (int k = 0; k < 3; ++k) {
    Frame f;
    f.kind = FrameKind::kDepth;
    f.view = k;
    f.timestamp_ns = 1'000'000'000LL * (k == 2 ? 4 : k + 1);
    f.turntable_angle_rad = 0.7 * k;
    f.world_T_scan = RigidMotion(RotationAboutAxis(Eigen::Vector3d::UnitZ(), -0.7 * k),
                                 Eigen::Vector3d(0.1, -0.2, 0.3 * k));
    f.depth.width = 8;
    f.depth.height = 6;
    for (int i = 0; i < 48; ++i)
      f.depth.values.push_back(static_cast<std::uint16_t>(i % 7 == 0 ? 0 : 900 + 13 * i + k));
    frames.push_back(f);
  }
  return ListSource(d, frames);
}

void ExpectSameFrames(const Frame& a, const Frame& b) {
  EXPECT_EQ(a.kind, b.kind);
  EXPECT_EQ(a.view, b.view);
  EXPECT_EQ(a.timestamp_ns, b.timestamp_ns);
  EXPECT_EQ(a.turntable_angle_rad, b.turntable_angle_rad);
  ASSERT_EQ(a.world_T_scan.has_value(), b.world_T_scan.has_value());
  if (a.world_T_scan) {
    EXPECT_EQ(a.world_T_scan->matrix(), b.world_T_scan->matrix());  // bit for bit
  }
  EXPECT_EQ(a.depth.width, b.depth.width);
  EXPECT_EQ(a.depth.height, b.depth.height);
  EXPECT_EQ(a.depth.values, b.depth.values);
  ASSERT_EQ(a.points.cols(), b.points.cols());
  EXPECT_EQ(a.points, b.points);
}

void ExpectSameViews(const ScanSet& a, const ScanSet& b) {
  ASSERT_EQ(a.scans.size(), b.scans.size());
  for (std::size_t k = 0; k < a.scans.size(); ++k) {
    EXPECT_EQ(a.scans[k].points, b.scans[k].points) << "view " << k;
    EXPECT_EQ(a.scans[k].world_T_scan.matrix(), b.scans[k].world_T_scan.matrix());
    EXPECT_EQ(a.scans[k].units, b.scans[k].units);
    EXPECT_EQ(a.scans[k].metadata.turntable_angle_rad, b.scans[k].metadata.turntable_angle_rad);
  }
}

TEST(FrameSource, DepthFramesRoundTripThroughARecordingBitForBit) {
  const fs::path dir = TempDir("depth");
  ListSource original = DepthSource();
  std::vector<std::int64_t> progress;
  EXPECT_EQ(RecordSource(original, dir / "d.s2mrec",
                         [&](std::int64_t done, std::optional<std::int64_t> total) {
                           progress.push_back(done);
                           EXPECT_EQ(total, 3);
                         }),
            3);
  EXPECT_EQ(progress, (std::vector<std::int64_t>{1, 2, 3}));

  const auto replay = OpenRecordingSource(dir / "d.s2mrec");
  const SourceDescription& d = replay->description();
  ASSERT_EQ(d.streams.size(), 1u);
  EXPECT_EQ(d.streams[0].kind, FrameKind::kDepth);
  EXPECT_EQ(d.streams[0].units, "m");
  ASSERT_TRUE(d.streams[0].intrinsics);
  EXPECT_EQ(d.streams[0].intrinsics->fx, 520.5);
  EXPECT_EQ(d.streams[0].intrinsics->cy, 2.75);
  EXPECT_EQ(d.name, "depth test");
  EXPECT_EQ(nlohmann::json::parse(d.device_json)["name"], "test-kinect");
  EXPECT_EQ(nlohmann::json::parse(d.calibration_json)["turntable"]["axis"][2], 1);
  EXPECT_EQ(d.meta, (std::vector<std::pair<std::string, std::string>>{{"operator", "test"}}));
  EXPECT_EQ(replay->Views(), (std::vector<std::int64_t>{0, 1, 2}));

  ListSource again = DepthSource();
  for (int k = 0; k < 3; ++k) {
    const std::optional<Frame> a = again.Next(), b = replay->Next();
    ASSERT_TRUE(a && b);
    ExpectSameFrames(*a, *b);
  }
  EXPECT_FALSE(replay->Next());

  // Views: back-projected with the stream's intrinsics, identical from the device and from the replay.
  ListSource device = DepthSource();
  const ScanSet live = FramesToScanSet(device);
  const auto replay2 = OpenRecordingSource(dir / "d.s2mrec");
  ExpectSameViews(live, FramesToScanSet(*replay2));
  ASSERT_EQ(live.scans.size(), 3u);
  EXPECT_EQ(live.scans[0].size(), 48 - 7);  // the zero pixels (every 7th) have no return
  const DepthCloud direct = BackProject(DepthSource().Next()->depth, Intrinsics());
  EXPECT_EQ(live.scans[0].points, direct.points);
  EXPECT_EQ(live.scans[0].metadata.device, "test-kinect");
  fs::remove_all(dir);
}

// zlib-compressed frames replay bit for bit; a damaged compressed payload is a clear error.
TEST(FrameSource, CompressedFramesRoundTripAndDamageIsReported) {
  const fs::path dir = TempDir("zlib");
  ListSource plain = DepthSource(), packed = DepthSource();
  RecordSource(plain, dir / "plain.s2mrec");
  RecordSource(packed, dir / "zlib.s2mrec", {}, kZlibCompression);
  const auto a = OpenRecordingSource(dir / "plain.s2mrec"), b = OpenRecordingSource(dir / "zlib.s2mrec");
  for (int k = 0; k < 3; ++k) ExpectSameFrames(*a->Next(), *b->Next());
  EXPECT_FALSE(b->Next());
  // Stored compressed (this tiny image does not shrink; the shipped depth recordings do,
  // recordings/README.md).
  EXPECT_EQ(RecordingReader::Open(dir / "zlib.s2mrec").Frames(1)[0].compression, kZlibCompression);

  const fs::path damaged = dir / "damaged.s2mrec";
  fs::copy_file(dir / "zlib.s2mrec", damaged);
  RawExec(damaged,
          "UPDATE frames SET payload = substr(payload, 1, 12) || x'00000000' || substr(payload, 17) WHERE id "
          "= 2");
  const auto c = OpenRecordingSource(damaged);
  ASSERT_TRUE(c->Next());
  try {
    c->Next();
    ADD_FAILURE() << "no error for a damaged zlib payload";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("frame 2: damaged zlib payload"), std::string::npos) << e.what();
  }
  const fs::path unknown = dir / "lz4.s2mrec";
  fs::copy_file(dir / "zlib.s2mrec", unknown);
  RawExec(unknown, "UPDATE frames SET compression = 'lz4' WHERE id = 1");
  try {
    OpenRecordingSource(unknown)->Next();
    ADD_FAILURE() << "no error for an unknown compression";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("frame 1: unsupported compression 'lz4'"), std::string::npos)
        << e.what();
  }
  fs::remove_all(dir);
}

// A clock that never sleeps: it records the instants it was asked to wait for and jumps there.
class FakeClock final : public ReplayClock {
 public:
  std::int64_t now = 5'000;
  std::vector<std::int64_t> waits;
  std::int64_t NowNs() override { return now; }
  void SleepUntilNs(std::int64_t t) override {
    waits.push_back(t);
    now = std::max(now, t);
  }
};

TEST(FrameSource, ReplayTimingOriginalOrAsFastAsPossible) {
  const fs::path dir = TempDir("timing");
  ListSource original = DepthSource();
  RecordSource(original, dir / "t.s2mrec");

  auto clock = std::make_shared<FakeClock>();
  ReplayOptions fast;
  fast.clock = clock;
  const auto quick = OpenRecordingSource(dir / "t.s2mrec", fast);
  while (quick->Next()) {
  }
  EXPECT_TRUE(clock->waits.empty());

  ReplayOptions timed;
  timed.original_timing = true;
  timed.clock = clock;
  const auto replay = OpenRecordingSource(dir / "t.s2mrec", timed);
  while (replay->Next()) {
  }
  // Frames at 1 s, 2 s, 4 s: the first at once, then 1 s and 3 s after it.
  EXPECT_EQ(clock->waits, (std::vector<std::int64_t>{5'000 + 1'000'000'000, 5'000 + 3'000'000'000LL}));

  // A seek restarts the timing at the frame sought.
  clock->waits.clear();
  const std::int64_t before = clock->now;
  replay->SeekView(1);
  ASSERT_TRUE(replay->Next());
  EXPECT_TRUE(clock->waits.empty());
  const std::optional<Frame> last = replay->Next();
  ASSERT_TRUE(last);
  EXPECT_EQ(last->view, 2);
  EXPECT_EQ(clock->waits, (std::vector<std::int64_t>{before + 2'000'000'000LL}));
  EXPECT_THROW(replay->SeekView(7), std::out_of_range);
  fs::remove_all(dir);
}

// Clock jumps during a replay with the original timing (docs/reliability.md): the recording machine's clock
// set back and forward while it recorded, and the replaying machine's clock jumping ahead (a suspend). Every
// frame comes, in order; no jump is waited out, none makes the frames after it come in a burst; each is
// counted.
TEST(FrameSource, ReplayWithOriginalTimingSurvivesClockJumps) {
  const fs::path dir = TempDir("clock_jump");
  ListSource base = DepthSource();
  SourceDescription d = base.description();
  std::vector<Frame> frames;
  // Frames every second, with the recorder's clock set back an hour before frame 3 and forward two hours
  // before frame 6.
  const std::int64_t s = 1'000'000'000LL;
  const std::vector<std::int64_t> stamps = {10 * s,
                                            11 * s,
                                            12 * s,
                                            13 * s - 3600 * s,
                                            14 * s - 3600 * s,
                                            15 * s - 3600 * s,
                                            16 * s + 3600 * s,
                                            17 * s + 3600 * s};
  for (std::size_t k = 0; k < stamps.size(); ++k) {
    std::optional<Frame> f = base.Next();
    if (!f) {
      base.SeekView(0);
      f = base.Next();
    }
    f->view = static_cast<std::int64_t>(k);
    f->timestamp_ns = stamps[k];
    frames.push_back(*f);
  }
  ListSource jumpy(d, frames);
  RecordSource(jumpy, dir / "jumpy.s2mrec");

  auto clock = std::make_shared<FakeClock>();
  ReplayOptions timed;
  timed.original_timing = true;
  timed.clock = clock;
  const auto replay = OpenRecordingSource(dir / "jumpy.s2mrec", timed);
  std::vector<std::int64_t> views, delivered_at;
  while (const std::optional<Frame> f = replay->Next()) {
    views.push_back(f->view);
    delivered_at.push_back(clock->now);
    if (f->view == 4) clock->now += 7200 * s;  // the replaying machine sleeps two hours after frame 4
  }
  EXPECT_EQ(views, (std::vector<std::int64_t>{0, 1, 2, 3, 4, 5, 6, 7}));
  // Seconds between deliveries: 1, 1, then the backward jump comes at once, 1, then frame 5 is two hours late
  // and comes at once (the timing restarts: no burst), then the forward jump comes at once, 1.
  std::vector<std::int64_t> spacing;
  for (std::size_t k = 1; k < delivered_at.size(); ++k)
    spacing.push_back(delivered_at[k] - delivered_at[k - 1]);
  EXPECT_EQ(spacing, (std::vector<std::int64_t>{s, s, 0, s, 7200 * s, 0, s}));
  EXPECT_EQ(replay->timing_report().recording_clock_jumps, 2);
  EXPECT_EQ(replay->timing_report().replay_late_restarts, 1);

  // The command says what it did (and refuses a gap that is not a positive number of seconds).
  const test::ShellResult r =
      test::Shell(std::string(S2M_CLI_PATH) + " record --original-timing --max-gap 5 " +
                  (dir / "jumpy.s2mrec").string() + " -q -o " + (dir / "again.s2mrec").string());
  EXPECT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("2 clock jump(s)"), std::string::npos) << r.out;
  EXPECT_EQ(test::Shell(std::string(S2M_CLI_PATH) + " record --original-timing --max-gap 0 " +
                        (dir / "jumpy.s2mrec").string() + " -q -o " + (dir / "never.s2mrec").string())
                .exit_code,
            2);
  ReplayOptions bad;
  bad.max_gap_s = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(OpenRecordingSource(dir / "jumpy.s2mrec", bad), std::invalid_argument);
  fs::remove_all(dir);
}

// Laser profiles of one sweep become one view, in the frame of its first profile.
TEST(FrameSource, ProfilesOfASweepBecomeOneView) {
  SourceDescription d;
  d.streams.push_back({"profile", FrameKind::kProfile, "mm", std::nullopt});
  std::vector<Frame> frames;
  Eigen::Matrix3Xd world(3, 0);
  for (int k = 0; k < 4; ++k) {
    Frame f;
    f.kind = FrameKind::kProfile;
    f.view = 0;
    f.turntable_angle_rad = 0.5 * k;
    f.world_T_scan =
        RigidMotion(RotationAboutAxis(Eigen::Vector3d::UnitZ(), -0.5 * k), Eigen::Vector3d(200, 0, 50));
    f.points = Eigen::Matrix3Xd::Random(3, 5 + k) * 30.0;
    const Eigen::Matrix3Xd w = f.world_T_scan->apply(f.points);
    world.conservativeResize(3, world.cols() + w.cols());
    world.rightCols(w.cols()) = w;
    frames.push_back(f);
  }
  ListSource source(d, frames);
  const ScanSet set = FramesToScanSet(source);
  ASSERT_EQ(set.scans.size(), 1u);
  EXPECT_EQ(set.scans[0].size(), 5 + 6 + 7 + 8);
  EXPECT_EQ(set.scans[0].world_T_scan.matrix(), frames[0].world_T_scan->matrix());
  EXPECT_LT((set.scans[0].WorldPoints() - world).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_FALSE(set.scans[0].metadata.turntable_angle_rad);  // a sweep spans many angles
}

TEST(FrameSource, BadRecordingsAreClearErrors) {
  const fs::path dir = TempDir("bad");
  ListSource original = DepthSource();
  const fs::path base = dir / "base.s2mrec";
  RecordSource(original, base);
  auto variant = [&](const std::string& name, const std::string& sql) {
    const fs::path f = dir / (name + ".s2mrec");
    fs::copy_file(base, f);
    RawExec(f, sql);
    return f;
  };
  // The message of opening and converting the recording, with the file named.
  auto error = [](const fs::path& file) -> std::string {
    try {
      const auto source = OpenRecordingSource(file);
      FramesToScanSet(*source);
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
      return e.what();
    }
    ADD_FAILURE() << "no FormatError for " << file;
    return "";
  };
  EXPECT_NE(
      error(variant("nointrinsics", "UPDATE device SET calibration = '{}'")).find("needs its intrinsics"),
      std::string::npos);
  EXPECT_NE(error(variant("badfx",
                          "UPDATE device SET calibration = json_remove(calibration, "
                          "'$.streams.depth.intrinsics.fx')"))
                .find("intrinsics: 'fx' missing"),
            std::string::npos);
  EXPECT_NE(error(variant("version", "UPDATE meta SET value = 'scan2model.recording/9' WHERE key = 'format'"))
                .find("unsupported recording format"),
            std::string::npos);
  EXPECT_NE(error(variant("empty", "DELETE FROM poses; DELETE FROM frames")).find("no frames"),
            std::string::npos);
  EXPECT_NE(error(variant("short", "UPDATE frames SET payload = substr(payload, 1, 50) WHERE id = 2"))
                .find("frame 2: depth payload declares 8 x 6 pixels"),
            std::string::npos);
  EXPECT_NE(
      error(variant("encoding", "UPDATE streams SET encoding = 'depth_f32'")).find("encoding 'depth_f32'"),
      std::string::npos);
  EXPECT_NE(error(variant("nanpose", "UPDATE poses SET m13 = 'NaN' WHERE frame = 3"))
                .find("frame 3: pose element m13 is not a number"),
            std::string::npos);
  // A view whose only frame has no returns at all.
  EXPECT_NE(error(variant("noreturn",
                          "UPDATE frames SET payload = substr(payload, 1, 8) || zeroblob(96) WHERE id = 1"))
                .find("the view has no points"),
            std::string::npos);
  // The writer refuses a NaN pose before anything of that frame is written.
  SourceDescription d = DepthSource().description();
  Frame nan = *DepthSource().Next();
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m(0, 3) = std::nan("");
  nan.world_T_scan = RigidMotion::FromMatrix(m);
  ListSource bad(d, {nan});
  EXPECT_THROW(RecordSource(bad, dir / "nan.s2mrec"), std::invalid_argument);
  fs::remove_all(dir);
}

// The three real Kinect frames (PCL, BSD-3) as a recording: the replayed views are exactly what the
// depth-frame reader gives for each file, and the timestamps come from the grabber's file names.
TEST(FrameSource, KinectFilesRecordAndReplayExactly) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data absent";
  const fs::path folder = test::SharedData("pcl_kinect_frames");
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(folder)) {
    if (e.path().string().ends_with("_depth.tiff")) files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  ASSERT_EQ(files.size(), 3u);
  const fs::path dir = TempDir("kinect");
  const auto files_source = OpenFrameSource(files);
  EXPECT_EQ(RecordSource(*files_source, dir / "k.s2mrec"), 3);
  const auto replay = OpenFrameSource({dir / "k.s2mrec"});
  const ScanSet set = FramesToScanSet(*replay);
  ASSERT_EQ(set.scans.size(), 3u);
  for (std::size_t k = 0; k < 3; ++k) {
    const Scan direct = ReadDepthFrame(files[k]);
    EXPECT_EQ(set.scans[k].points, direct.points) << files[k];
    EXPECT_EQ(set.scans[k].units, "m");
  }
  EXPECT_EQ(set.scans[0].size(), 271575);
  // frame_20121214T142255.814212 read as UTC.
  ASSERT_TRUE(set.scans[0].metadata.timestamp_s);
  EXPECT_NEAR(*set.scans[0].metadata.timestamp_s, 1355494975.814212, 1e-6);
  EXPECT_NEAR(*set.scans[2].metadata.timestamp_s - *set.scans[0].metadata.timestamp_s, 0.518183, 1e-6);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace s2m
