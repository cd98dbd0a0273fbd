#include "acquisition/recording.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sqlite3.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>

#include "acquisition/format_error.h"
#include "acquisition/scan_set_io.h"
#include "raw_sql.h"
#include "synthetic/synthetic_cases.h"
#include "test_support.h"

namespace s2m {
namespace {

namespace fs = std::filesystem;

fs::path TempDir(const std::string& name) {
  return test::FreshTempDir("recording_" + name);
}

using test::RawExec;

// The FormatError of opening and reading `file` as views; fails the test when there is none.
std::string ReadError(const fs::path& file) {
  try {
    ReadRecording(file);
  } catch (const FormatError& e) {
    EXPECT_EQ(e.file(), file.string());
    EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
    return e.what();
  }
  ADD_FAILURE() << "no FormatError for " << file;
  return "";
}

ScanSet Vase() {
  return RecordedViews(MakeSyntheticCase("vase"));
}

TEST(Recording, ScanSetRoundTripIsBitIdentical) {
  const fs::path dir = TempDir("roundtrip");
  ScanSet set = Vase();
  ASSERT_EQ(set.scans.size(), 8u);
  for (std::size_t k = 0; k < set.scans.size(); ++k) {
    set.scans[k].metadata.turntable_angle_rad = 0.25 * static_cast<double>(k);
    set.scans[k].metadata.timestamp_s = 1.7e9 + static_cast<double>(k);
  }
  const fs::path file = dir / "vase.s2mrec";
  WriteRecording(file, set);
  // A closed recording is a single file: the write-ahead log was checkpointed and removed.
  EXPECT_FALSE(fs::exists(file.string() + "-wal"));
  const ScanSet back = ReadRecording(file);
  EXPECT_EQ(back.name, set.name);
  ASSERT_EQ(back.scans.size(), set.scans.size());
  for (std::size_t k = 0; k < set.scans.size(); ++k) {
    const Scan& a = set.scans[k];
    const Scan& b = back.scans[k];
    ASSERT_EQ(a.points.cols(), b.points.cols());
    EXPECT_EQ(std::memcmp(a.points.data(), b.points.data(),
                          sizeof(double) * 3 * static_cast<std::size_t>(a.size())),
              0);
    const Eigen::Matrix4d ma = a.world_T_scan.matrix(), mb = b.world_T_scan.matrix();
    EXPECT_EQ(std::memcmp(ma.data(), mb.data(), sizeof(double) * 16), 0) << k;
    EXPECT_EQ(b.units, "mm");
    EXPECT_EQ(b.metadata.turntable_angle_rad, a.metadata.turntable_angle_rad);
    ASSERT_TRUE(b.metadata.timestamp_s.has_value());
    EXPECT_NEAR(*b.metadata.timestamp_s, *a.metadata.timestamp_s, 1e-6);
    EXPECT_NE(b.metadata.source.find("view " + std::to_string(k)), std::string::npos) << b.metadata.source;
  }

  const RecordingReader reader = RecordingReader::Open(file);
  const RecordingSummary summary = reader.Summary();
  EXPECT_EQ(summary.format, kRecordingFormat);
  ASSERT_EQ(summary.streams.size(), 1u);
  EXPECT_EQ(summary.streams[0].kind, "points");
  EXPECT_EQ(summary.streams[0].encoding, kPointsEncoding);
  EXPECT_EQ(summary.frames_per_stream[0], 8);
  EXPECT_EQ(summary.posed_frames, 8);
  const std::vector<RecordingFrame> view3 = reader.FramesOfView(summary.streams[0].id, 3);
  ASSERT_EQ(view3.size(), 1u);
  EXPECT_EQ(DecodePoints(view3[0].payload, "x", "y"), set.scans[3].points);
  fs::remove_all(dir);
}

TEST(Recording, WriterApiDeviceStreamsAndRefusals) {
  const fs::path dir = TempDir("writer");
  const fs::path file = dir / "r.s2mrec";
  {
    RecordingWriter w = RecordingWriter::Create(file);
    w.SetDevice(R"({"name": "virtual:horus", "serial": "42"})", R"({"fx": 525.0, "fy": 525.0})");
    w.SetMeta("operator", "test");
    const std::int64_t points = w.AddStream("cloud", "points", kPointsEncoding, "mm");
    const std::int64_t depth = w.AddStream("depth", "depth", "u16le_mm");
    EXPECT_THROW(w.AddStream("x", "video", "raw"), std::invalid_argument);
    EXPECT_THROW(w.SetMeta("format", "other"), std::invalid_argument);
    EXPECT_THROW(w.SetDevice("{not json"), std::invalid_argument);
    Eigen::Matrix4d nan_pose = Eigen::Matrix4d::Identity();
    nan_pose(0, 3) = std::numeric_limits<double>::quiet_NaN();
    EXPECT_THROW(w.AppendFrame(points, 0, EncodePoints(Eigen::Matrix3Xd::Random(3, 4)),
                               RigidMotion::FromMatrix(nan_pose)),
                 std::invalid_argument);
    Eigen::Matrix4d scaled = 2.0 * Eigen::Matrix4d::Identity();
    scaled(3, 3) = 1.0;
    EXPECT_THROW(w.AppendFrame(points, 0, EncodePoints(Eigen::Matrix3Xd::Random(3, 4)),
                               RigidMotion::FromMatrix(scaled)),
                 std::invalid_argument);
    w.AppendFrame(points, 0, EncodePoints(Eigen::Matrix3Xd::Random(3, 4)));
    w.AppendFrame(depth, 0, std::vector<std::uint8_t>(640 * 2, 7), std::nullopt, 123);
    w.Close();
  }
  EXPECT_THROW(RecordingWriter::Create(file), FormatError);  // never overwritten
  const RecordingReader r = RecordingReader::Open(file);
  const RecordingSummary s = r.Summary();
  EXPECT_NE(s.device.find("virtual:horus"), std::string::npos);
  EXPECT_NE(s.calibration.find("525"), std::string::npos);
  EXPECT_EQ(r.Meta("operator"), "test");
  ASSERT_EQ(s.streams.size(), 2u);
  EXPECT_EQ(s.frames_per_stream, (std::vector<std::int64_t>{1, 1}));
  EXPECT_EQ(s.posed_frames, 0);
  const std::vector<RecordingFrame> depth = r.Frames(s.streams[1].id);
  ASSERT_EQ(depth.size(), 1u);
  EXPECT_EQ(depth[0].payload.size(), 1280u);
  EXPECT_EQ(depth[0].timestamp_ns, 123);
  EXPECT_FALSE(depth[0].world_T_scan.has_value());
  const ScanSet set = ReadRecording(file);  // the only points stream
  ASSERT_EQ(set.scans.size(), 1u);
  EXPECT_TRUE(set.scans[0].world_T_scan.matrix().isIdentity(0.0));
  EXPECT_EQ(set.scans[0].units, "mm");
  EXPECT_EQ(set.scans[0].metadata.device, "virtual:horus");  // the device description's "name"
  fs::remove_all(dir);
}

// Kills the child on every path out of the test, so that a failed assertion never leaves a writer running.
struct ChildGuard {
  pid_t pid = -1;
  ~ChildGuard() {
    if (pid > 0) {
      kill(pid, SIGKILL);
      waitpid(pid, nullptr, 0);
    }
  }
};

// Records the vase views one frame per transaction in a child, kills it with SIGKILL after it reported
// `committed` commits, and checks the file. Returns the frames reported and recovered.
std::pair<int, int> KillAfter(const fs::path& file, const ScanSet& vase, int committed) {
  int fds[2];
  if (pipe(fds) != 0) {
    ADD_FAILURE() << "pipe";
    return {0, 0};
  }
  ChildGuard child{fork()};
  if (child.pid < 0) {
    ADD_FAILURE() << "fork";
    return {0, 0};
  }
  if (child.pid == 0) {
    close(fds[0]);
    try {
      RecordingWriter w = RecordingWriter::Create(file);
      const std::int64_t stream = w.AddStream("points", "points", kPointsEncoding, "mm");
      for (int i = 0;; ++i) {  // records until killed (or the parent goes away: write fails, SIGPIPE)
        const Scan& scan = vase.scans[static_cast<std::size_t>(i) % vase.scans.size()];
        w.AppendFrame(stream, i, EncodePoints(scan.points), scan.world_T_scan, i);
        const char c = 'f';
        if (write(fds[1], &c, 1) != 1) _exit(3);  // one byte per committed frame
      }
    } catch (...) {
      _exit(2);
    }
  }
  close(fds[1]);
  int seen = 0;
  char c = 0;
  while (seen < committed && read(fds[0], &c, 1) == 1) ++seen;
  EXPECT_EQ(seen, committed);
  EXPECT_EQ(kill(child.pid, SIGKILL), 0);
  int status = 0;
  EXPECT_EQ(waitpid(child.pid, &status, 0), child.pid);
  child.pid = -1;
  EXPECT_TRUE(WIFSIGNALED(status)) << "the writer ended on its own, status " << status;
  // Frames the child committed between our count and the kill: drain the pipe.
  while (read(fds[0], &c, 1) == 1) ++seen;
  close(fds[0]);
  EXPECT_TRUE(fs::exists(file.string() + "-wal"));  // killed mid-recording: the log was never checkpointed

  const ScanSet back = ReadRecording(file);  // integrity check included
  const auto recovered = static_cast<int>(back.scans.size());
  EXPECT_GE(recovered, seen);
  EXPECT_LE(recovered, seen + 1);  // at most the frame in flight committed without being reported
  for (int i = 0; i < recovered; ++i) {
    const Scan& expected = vase.scans[static_cast<std::size_t>(i) % vase.scans.size()];
    EXPECT_EQ(back.scans[static_cast<std::size_t>(i)].points, expected.points) << i;
    EXPECT_EQ(back.scans[static_cast<std::size_t>(i)].world_T_scan.matrix(), expected.world_T_scan.matrix())
        << i;
  }
  return {seen, recovered};
}

// A writer killed with SIGKILL in the middle of a recording: every frame it reported committed is in the
// file, which passes the integrity check.
TEST(Recording, KilledWriterKeepsEveryCommittedFrame) {
  const fs::path dir = TempDir("kill");
  const ScanSet vase = Vase();
  for (int committed : {1, 7, 20, 50}) {
    const auto [seen, recovered] =
        KillAfter(dir / ("killed_" + std::to_string(committed) + ".s2mrec"), vase, committed);
    std::cout << "[ kill     ] after " << committed << " commits: frames reported committed " << seen
              << ", recovered " << recovered << "\n";
  }
  fs::remove_all(dir);
}

// A disk that fills up in the middle of a recording (docs/reliability.md), emulated without root by the
// child's file-size limit (RLIMIT_FSIZE: a write beyond it fails with EFBIG, as on a full disk; SIGXFSZ is
// ignored so that the write returns the error). The writer's error names the file and says the write failed;
// every frame it reported committed before is in the file, which passes the integrity check.
TEST(Recording, FullDiskKeepsEveryCommittedFrameAndSaysSo) {
  const fs::path dir = TempDir("full_disk");
  const fs::path file = dir / "full.s2mrec";
  const ScanSet vase = Vase();
  int fds[2];
  ASSERT_EQ(pipe(fds), 0);
  ChildGuard child{fork()};
  ASSERT_GE(child.pid, 0);
  if (child.pid == 0) {
    close(fds[0]);
    signal(SIGXFSZ, SIG_IGN);
    const rlimit limit{1u << 20, 1u << 20};  // 1 MiB: a few dozen frames of the vase
    if (setrlimit(RLIMIT_FSIZE, &limit) != 0) _exit(10);
    try {
      RecordingWriter w = RecordingWriter::Create(file);
      const std::int64_t stream = w.AddStream("points", "points", kPointsEncoding, "mm");
      for (int i = 0; i < 100000; ++i) {
        const Scan& scan = vase.scans[static_cast<std::size_t>(i) % vase.scans.size()];
        w.AppendFrame(stream, i, EncodePoints(scan.points), scan.world_T_scan, i);
        const char c = 'f';
        if (write(fds[1], &c, 1) != 1) _exit(11);
      }
      _exit(12);  // never filled the disk
    } catch (const FormatError& e) {
      const std::string message = e.what();
      if (write(fds[1], message.data(), message.size()) < 0) _exit(13);
      _exit(0);
    } catch (...) {
      _exit(14);
    }
  }
  close(fds[1]);
  std::string from_child;
  char buffer[256];
  for (ssize_t n; (n = read(fds[0], buffer, sizeof buffer)) > 0;)
    from_child.append(buffer, static_cast<std::size_t>(n));
  close(fds[0]);
  int status = 0;
  ASSERT_EQ(waitpid(child.pid, &status, 0), child.pid);
  child.pid = -1;
  ASSERT_TRUE(WIFEXITED(status));
  ASSERT_EQ(WEXITSTATUS(status), 0) << "the writer did not end with a FormatError: " << from_child;
  const std::size_t committed = from_child.find_first_not_of('f');
  ASSERT_NE(committed, std::string::npos);
  const std::string message = from_child.substr(committed);
  std::cout << "[ full     ] " << committed << " frames committed, then: " << message << "\n";
  EXPECT_GT(committed, 0u);
  EXPECT_NE(message.find(file.string()), std::string::npos) << message;
  EXPECT_NE(message.find("disk is full"), std::string::npos) << message;  // says what to look at

  const ScanSet back = ReadRecording(file);  // integrity check included
  ASSERT_GE(back.scans.size(), committed);
  EXPECT_LE(back.scans.size(), committed + 1);  // the frame in flight may have reached the log
  for (std::size_t i = 0; i < committed; ++i)
    EXPECT_EQ(back.scans[i].points, vase.scans[i % vase.scans.size()].points) << i;
  fs::remove_all(dir);
}

// WAL lets a reader open a recording while it is being written (a live preview): it sees the frames committed
// when it opened.
TEST(Recording, ReadableWhileBeingWritten) {
  const fs::path dir = TempDir("live");
  const fs::path file = dir / "live.s2mrec";
  const ScanSet vase = Vase();
  RecordingWriter w = RecordingWriter::Create(file);
  const std::int64_t stream = w.AddStream("points", "points", kPointsEncoding, "mm");
  for (int i = 0; i < 3; ++i)
    w.AppendFrame(stream, i, EncodePoints(vase.scans[static_cast<std::size_t>(i)].points));
  EXPECT_EQ(ReadRecording(file).scans.size(), 3u);
  w.AppendFrame(stream, 3, EncodePoints(vase.scans[3].points));
  const ScanSet four = ReadRecording(file);
  ASSERT_EQ(four.scans.size(), 4u);
  EXPECT_EQ(four.scans[3].points, vase.scans[3].points);
  {
    // Closing while a reader has the file open: nothing is lost, the recording stays file + -wal, and says
    // so.
    const RecordingReader reader = RecordingReader::Open(file);
    try {
      w.Close();
      ADD_FAILURE() << "no error closing under a reader";
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find("still in WAL mode"), std::string::npos) << e.what();
    }
    EXPECT_EQ(reader.Frames(stream).size(), 4u);
  }
  EXPECT_EQ(ReadRecording(file).scans.size(), 4u);
  fs::remove_all(dir);
}

TEST(Recording, TruncatedAndOverwrittenFilesNameTheFile) {
  const fs::path dir = TempDir("damaged");
  const fs::path good = dir / "good.s2mrec";
  WriteRecording(good, Vase());
  const auto size = fs::file_size(good);

  const fs::path truncated = dir / "truncated.s2mrec";
  fs::copy_file(good, truncated);
  fs::resize_file(truncated, size / 2);
  EXPECT_NE(ReadError(truncated).find("truncated"), std::string::npos);

  const fs::path header = dir / "header.s2mrec";
  fs::copy_file(good, header);
  {
    std::fstream f(header, std::ios::in | std::ios::out | std::ios::binary);
    f.write("garbage garbage garbage!", 24);
  }
  EXPECT_NE(ReadError(header).find("not a SQLite database"), std::string::npos);

  // A page in the middle overwritten: only the integrity check can see it.
  const fs::path middle = dir / "middle.s2mrec";
  fs::copy_file(good, middle);
  {
    std::fstream f(middle, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(4096);  // the second page: a b-tree page of the schema's tables
    const std::string junk(4096, '\x5a');
    f.write(junk.data(), static_cast<std::streamsize>(junk.size()));
  }
  EXPECT_NE(ReadError(middle).find("corrupted"), std::string::npos);

  const fs::path text = dir / "text.s2mrec";
  std::ofstream(text) << "x y z\n1 2 3\n";
  EXPECT_NE(ReadError(text).find("not a SQLite database"), std::string::npos);
  EXPECT_NE(ReadError(dir / "missing.s2mrec").find("no such recording"), std::string::npos);
  fs::remove_all(dir);
}

TEST(Recording, WrongVersionMissingTablesAndBadContentAreClearErrors) {
  const fs::path dir = TempDir("content");
  const fs::path base = dir / "base.s2mrec";
  WriteRecording(base, Vase());
  auto variant = [&](const std::string& name, const std::string& sql) {
    const fs::path f = dir / (name + ".s2mrec");
    fs::copy_file(base, f);
    RawExec(f, sql);
    return f;
  };
  EXPECT_NE(ReadError(variant("v2", "UPDATE meta SET value = 'scan2model.recording/2' WHERE key = 'format'"))
                .find("unsupported recording format 'scan2model.recording/2'"),
            std::string::npos);
  EXPECT_NE(
      ReadError(variant("noformat", "DELETE FROM meta WHERE key = 'format'")).find("meta has no 'format'"),
      std::string::npos);
  EXPECT_NE(ReadError(variant("noposes", "DROP TABLE poses")).find("no table 'poses'"), std::string::npos);
  // SQLite stores a bound NaN as NULL (refused by NOT NULL); text is what a hand-edited NaN becomes.
  EXPECT_NE(ReadError(variant("nanpose", "UPDATE poses SET m03 = 'NaN' WHERE frame = 2"))
                .find("frame 2: pose element m03 is not a number"),
            std::string::npos);
  EXPECT_NE(ReadError(variant("shear", "UPDATE poses SET m01 = 0.5 WHERE frame = 3"))
                .find("frame 3: world_T_scan is not a rigid"),
            std::string::npos);
  // A NaN coordinate inside a payload: x of point 1 of frame 1 (bytes 8 + 24 of the blob, 1-based offset 33).
  EXPECT_NE(ReadError(variant("nanpoint",
                              "UPDATE frames SET payload = substr(payload, 1, 32) || x'000000000000F87F' || "
                              "substr(payload, 41) WHERE id = 1"))
                .find("frame 1: point 1: x is not finite"),
            std::string::npos);
  EXPECT_NE(ReadError(variant("short", "UPDATE frames SET payload = substr(payload, 1, 100) WHERE id = 4"))
                .find("frame 4: point payload declares"),
            std::string::npos);
  EXPECT_NE(ReadError(variant("nopoints", "UPDATE streams SET kind = 'depth'")).find("no points stream"),
            std::string::npos);
  fs::remove_all(dir);
}

// The command's output (stdout only) and exit code.
std::pair<int, std::string> RunCli(const std::string& args) {
  const test::ShellResult r = test::Shell(std::string(S2M_CLI_PATH) + " " + args, /*merge_stderr=*/false);
  return {r.exit_code, r.out};
}

// `info` and `fit --model revolution` on the demo vase as a recording: the fit reads the same views as from
// the manifest, so the results are identical.
TEST(Recording, CliInfoAndFitReadARecording) {
  const fs::path dir = TempDir("cli");
  const std::string manifest = std::string(S2M_SOURCE_DIR) + "/recordings/demo_vase/views.json";
  const fs::path file = dir / "demo_vase.s2mrec";
  WriteRecording(file, ReadScanSet(manifest));

  const auto [info_code, info_out] = RunCli("info --json " + file.string());
  ASSERT_EQ(info_code, 0) << info_out;
  const auto info = nlohmann::json::parse(info_out);
  EXPECT_EQ(info["schema"], "scan2model.info/1");
  EXPECT_EQ(info["format"], kRecordingFormat);
  ASSERT_EQ(info["streams"].size(), 1u);
  EXPECT_EQ(info["streams"][0]["frames"], 4);
  EXPECT_EQ(info["views"], 4);
  EXPECT_EQ(info["posed_frames"], 4);
  EXPECT_EQ(info["points"].get<long long>(), ReadScanSet(manifest).TotalPoints());
  EXPECT_EQ(RunCli("info " + file.string()).first, 0);

  // The same loss for both (a recording's default is robust, a manifest's plain: docs/cli.md "--loss").
  const auto [fit_code, fit_out] = RunCli("fit --model revolution --loss none --json " + file.string());
  ASSERT_EQ(fit_code, 0) << fit_out;
  const auto fit = nlohmann::json::parse(fit_out);
  const auto [ref_code, ref_out] = RunCli("fit --model revolution --loss none --json " + manifest);
  ASSERT_EQ(ref_code, 0);
  const auto ref = nlohmann::json::parse(ref_out);
  ASSERT_EQ(fit["views"].size(), 4u);
  EXPECT_EQ(fit["residuals"]["rms"].get<double>(), ref["residuals"]["rms"].get<double>());
  EXPECT_EQ(fit["axis"], ref["axis"]);
  EXPECT_NE(fit["views"][0]["source"].get<std::string>().find("demo_vase.s2mrec"), std::string::npos);

  // A damaged recording is bad input (exit code 3), with the file named.
  const fs::path broken = dir / "broken.s2mrec";
  fs::copy_file(file, broken);
  fs::resize_file(broken, fs::file_size(file) / 2);
  EXPECT_EQ(RunCli("info " + broken.string()).first, 3);
  EXPECT_EQ(RunCli("fit --model revolution " + broken.string()).first, 3);
  fs::remove_all(dir);
}

TEST(Recording, WriteThroughputOneTransactionPerFrame) {
  const fs::path dir = TempDir("throughput");
  const ScanSet vase = Vase();
  RecordingWriter w = RecordingWriter::Create(dir / "t.s2mrec");
  const std::int64_t stream = w.AddStream("points", "points", kPointsEncoding, "mm");
  constexpr int kFrames = 64;
  std::size_t bytes = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < kFrames; ++i) {
    const Scan& scan = vase.scans[static_cast<std::size_t>(i) % vase.scans.size()];
    const std::vector<std::uint8_t> payload = EncodePoints(scan.points);
    bytes += payload.size();
    w.AppendFrame(stream, i, payload, scan.world_T_scan, i);
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  w.Close();
  std::cout << "[ write    ] " << kFrames << " frames, " << bytes / kFrames << " bytes each, "
            << kFrames / seconds << " frames/s, " << static_cast<double>(bytes) / seconds / 1e6 << " MB/s\n";
  EXPECT_EQ(RecordingReader::Open(dir / "t.s2mrec").Summary().frames_per_stream[0], kFrames);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace s2m
