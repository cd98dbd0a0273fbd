// A long recording at a depth camera's rate (docs/reliability.md, "Bounded resources"): 30 frames/s of
// Kinect-class depth images (640 x 480, 16 bits) from the virtual scanner, written as `scan2model record`
// writes them by default: one fsynced transaction per frame, uncompressed (600 KB each: the virtual scene has
// no background, so its images compress far better than a real room's would; the raw size is the worst case).
// The writer runs as fast as it can, faster than real time, and each frame's write time is measured; a camera
// delivering every 1/30 s into a queue of one second of frames is then replayed on those measured times (a
// single writer serving a FIFO: exact for the times measured) to count what a live recording would have
// dropped. The default records one minute of frames; set S2M_ENDURANCE_SECONDS=600 for ten minutes
// (docs/reliability.md gives both runs' figures).

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <deque>
#include <filesystem>
#include <iostream>
#include <vector>

#include "acquisition/frame_source.h"
#include "acquisition/recording.h"
#include "devices/virtual_scanner.h"
#include "test_support.h"

namespace s2m {
namespace {

namespace fs = std::filesystem;

constexpr double kFramesPerSecond = 30.0;
constexpr std::size_t kQueueFrames = 30;  // one second of frames waiting to be written

struct QueueReplay {
  std::size_t dropped = 0;
  std::size_t deepest = 0;  // frames in the system (waiting or being written) at an arrival, at most
};

// Frames arriving every 1/rate s into a FIFO of `capacity` waiting places in front of one writer that takes
// `write_s[i]` for frame i: which arrivals find the queue full.
QueueReplay ReplayQueue(const std::vector<double>& write_s, double rate, std::size_t capacity) {
  QueueReplay r;
  std::deque<double> finish;  // finish times of the accepted frames still in the system
  std::size_t next_written = 0;
  for (std::size_t i = 0; i < write_s.size(); ++i) {
    const double arrival = static_cast<double>(i) / rate;
    while (!finish.empty() && finish.front() <= arrival) finish.pop_front();
    r.deepest = std::max(r.deepest, finish.size());
    if (finish.size() > capacity) {  // one being written plus `capacity` waiting
      ++r.dropped;
      continue;
    }
    const double start = finish.empty() ? arrival : std::max(arrival, finish.back());
    finish.push_back(start + write_s[next_written++]);
  }
  return r;
}

TEST(RecordingEndurance, QueueReplayCountsDrops) {
  // A writer at exactly the rate never queues; one twice as slow drops once the queue is full.
  EXPECT_EQ(ReplayQueue(std::vector<double>(100, 1.0 / 30), 30, 2).dropped, 0u);
  const QueueReplay slow = ReplayQueue(std::vector<double>(100, 2.0 / 30), 30, 2);
  EXPECT_GT(slow.dropped, 40u);
  EXPECT_EQ(slow.deepest, 3u);
  // One stall of 0.49 s (frame 10, from t = 10/30 s): frames 11 to 24 arrive during it (14 of them). A
  // one-second queue takes them all; a queue of 5 takes 5 and drops 9.
  std::vector<double> stall(100, 0.01);
  stall[10] = 0.49;
  EXPECT_EQ(ReplayQueue(stall, 30, 30).dropped, 0u);
  EXPECT_EQ(ReplayQueue(stall, 30, 5).dropped, 9u);
}

TEST(RecordingEndurance, ThirtyFramesPerSecondKeepUp) {
  const char* seconds_env = std::getenv("S2M_ENDURANCE_SECONDS");
  const double seconds = seconds_env != nullptr ? std::atof(seconds_env) : 60.0;
  ASSERT_GT(seconds, 0.0) << "S2M_ENDURANCE_SECONDS must be a positive number of seconds";
  const auto frames = static_cast<std::size_t>(seconds * kFramesPerSecond);

  // Eight real-looking depth images (noise, dropouts, quantization) of the vase, recorded over and over.
  VirtualScannerOptions options;
  options.turntable.steps = 8;
  std::unique_ptr<FrameSource> camera = MakeVirtualScanner(SceneByName("vase"), options);
  std::vector<Frame> images;
  while (std::optional<Frame> f = camera->Next()) images.push_back(std::move(*f));
  ASSERT_EQ(images.size(), 8u);
  ASSERT_EQ(images[0].kind, FrameKind::kDepth);
  std::vector<std::vector<std::uint8_t>> payloads;
  for (const Frame& f : images) payloads.push_back(EncodeDepth(f.depth));

  const fs::path dir = test::FreshTempDir("endurance");
  const fs::path file = dir / "thirty_fps.s2mrec";
  // The test needs the disk for the whole recording.
  const double needed = static_cast<double>(frames * payloads[0].size());
  if (static_cast<double>(fs::space(dir).available) < 2 * needed) {
    GTEST_SKIP() << "needs " << needed / 1e9 << " GB free under " << dir;
  }
  std::vector<double> write_s;
  write_s.reserve(frames);
  {
    RecordingWriter writer = RecordingWriter::Create(file);
    const std::int64_t stream = writer.AddStream("depth", "depth", kDepthEncoding, "m");
    const std::int64_t start_ns = 1700000000000000000;
    for (std::size_t i = 0; i < frames; ++i) {
      const auto t0 = std::chrono::steady_clock::now();
      writer.AppendFrame(
          stream, static_cast<std::int64_t>(i), payloads[i % payloads.size()],
          images[i % images.size()].world_T_scan,
          start_ns + static_cast<std::int64_t>(static_cast<double>(i) * 1e9 / kFramesPerSecond), std::nullopt,
          kNoCompression);
      write_s.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    const auto wal = dir / "thirty_fps.s2mrec-wal";
    std::cout << "[ endurance ] write-ahead log before closing: "
              << (fs::exists(wal) ? static_cast<double>(fs::file_size(wal)) / 1e6 : 0.0) << " MB\n";
    writer.Close();
  }
  std::vector<double> sorted = write_s;
  std::sort(sorted.begin(), sorted.end());
  double total = 0;
  for (const double s : write_s) total += s;
  const QueueReplay live = ReplayQueue(write_s, kFramesPerSecond, kQueueFrames);
  const double file_mb = static_cast<double>(fs::file_size(file)) / 1e6;
  std::cout << "[ endurance ] " << frames << " frames (" << seconds << " s at 30 frames/s) written in "
            << total << " s: " << static_cast<double>(frames) / total << " frames/s; per frame median "
            << 1e3 * sorted[sorted.size() / 2] << " ms, 99th percentile "
            << 1e3 * sorted[sorted.size() * 99 / 100] << " ms, slowest " << 1e3 * sorted.back() << " ms; "
            << file_mb << " MB\n";
  std::cout << "[ endurance ] live at 30 frames/s with a queue of " << kQueueFrames
            << " frames: " << live.dropped << " dropped, at most " << live.deepest << " frames queued\n";
  EXPECT_EQ(live.dropped, 0u);
  // Every frame is in the file.
  const RecordingSummary summary = RecordingReader::Open(file).Summary();
  ASSERT_EQ(summary.frames_per_stream.size(), 1u);
  EXPECT_EQ(summary.frames_per_stream[0], static_cast<std::int64_t>(frames));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace s2m
