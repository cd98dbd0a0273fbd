// Disk and device faults injected under the command (docs/reliability.md, "Fault injection"): the
// `scan2model` process runs with tests/io_fault_shim.c preloaded, which fails every write to a chosen file
// once a byte budget is spent, with ENOSPC (a full disk) or EIO (a device error), and optionally its fsyncs.
// The file-size-limit versions of the same promises are in recording_test.cpp and batch_test.cpp; these reach
// the errno a real disk gives, and the fsync path.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <regex>
#include <string>

#include "acquisition/point_cloud_io.h"
#include "acquisition/recording.h"
#include "test_support.h"

#ifndef S2M_IO_FAULT_SHIM
#error "the build gives the shim's path"
#endif

namespace s2m {
namespace {

namespace fs = std::filesystem;

struct Fault {
  const char* name;
  const char* errno_name;  // S2M_FAULT_ERRNO
  bool fsync;              // S2M_FAULT_FSYNC
  // What the recording's message must say: SQLite keeps no reliable errno for a failed write, so its own
  // words plus the likely causes (recording.cpp, SqliteProblem).
  const char* recording_reason;
  const char* batch_reason;  // the system's words (strerror), which the result writer has
};

const Fault kFaults[] = {
    {"disk_full", "ENOSPC", false, "database or disk is full", "No space left on device"},
    {"io_error", "EIO", false, "disk I/O error", "Input/output error"},
    {"fsync_error", "EIO", true, "disk I/O error", "Input/output error"},
};

// `env` with the shim preloaded. Under AddressSanitizer (gcc's, whose runtime is a shared library) the shim
// comes after ASan's runtime in the preload order, which ASan accepts only when told; the run's own
// ASAN_OPTIONS are kept.
std::string WithShim() {
  return std::string("env LD_PRELOAD=") + S2M_IO_FAULT_SHIM +
         " ASAN_OPTIONS=\"${ASAN_OPTIONS:+$ASAN_OPTIONS:}verify_asan_link_order=0\" ";
}

// `scan2model ARGS` with the shim failing writes to files whose path contains `path_part` after `budget`
// bytes.
test::ShellResult RunWithFault(const Fault& fault, const std::string& path_part, long long budget,
                               const std::string& args) {
  const std::string env = WithShim() + "S2M_FAULT_PATH=" + test::Quote({path_part}) +
                          " S2M_FAULT_AFTER_BYTES=" + std::to_string(budget) +
                          " S2M_FAULT_ERRNO=" + fault.errno_name +
                          " S2M_FAULT_FSYNC=" + (fault.fsync ? "1" : "0") + " ";
  return test::Shell(env + S2M_CLI_PATH + " " + args);
}

// Opens the recording as a reader does (checks included) and decodes every frame's payload; returns the
// frames.
std::size_t ReadEveryFrame(const fs::path& file) {
  const RecordingReader reader = RecordingReader::Open(file);
  std::size_t frames = 0;
  for (const RecordingStream& stream : reader.Streams()) {
    for (const RecordingFrame& frame : reader.Frames(stream.id)) {
      EXPECT_FALSE(FramePayload(frame, file.string(), "frame").empty());
      ++frames;
    }
  }
  return frames;
}

// The recordings come from the virtual scanner, which the command has only when Open3D was found.
#ifdef S2M_HAVE_VIRTUAL_SCANNER
#define S2M_NEEDS_VIRTUAL_SCANNER()
#else
#define S2M_NEEDS_VIRTUAL_SCANNER() GTEST_SKIP() << "this build has no virtual scanner (Open3D was not found)"
#endif

// Without a fault path the shim is idle: the command runs as it does without it.
TEST(IoFault, ShimIsIdleUnlessAsked) {
  S2M_NEEDS_VIRTUAL_SCANNER();
  const fs::path dir = test::FreshTempDir("io_fault_idle");
  const test::ShellResult r =
      test::Shell(WithShim() + S2M_CLI_PATH + " record --device virtual:vase,steps=2 -q -o " +
                  (dir / "idle.s2mrec").string());
  EXPECT_EQ(r.exit_code, 0) << r.out;
  EXPECT_EQ(ReadEveryFrame(dir / "idle.s2mrec"), 2u);
  fs::remove_all(dir);
}

// A recording whose disk fills (or whose device fails) after 3 MB (a few 600 KB depth images): `record` exits
// with code 3 and a message naming the file, the reason and how many frames are kept; exactly those frames
// are in the recording, every one readable (after a failed fsync, the frame in flight may be there too).
TEST(IoFault, RecordingKeepsEveryCommittedFrameAndSaysWhy) {
  S2M_NEEDS_VIRTUAL_SCANNER();
  for (const Fault& fault : kFaults) {
    SCOPED_TRACE(fault.name);
    const fs::path dir = test::FreshTempDir(std::string("io_fault_record_") + fault.name);
    const fs::path file = dir / "scan.s2mrec";
    const test::ShellResult r = RunWithFault(fault, "scan.s2mrec", 3000000,
                                             "record --device virtual:vase,steps=40 -q -o " + file.string());
    std::cout << "[ " << fault.name << " ] " << r.out.substr(0, r.out.find('\n')) << "\n";
    EXPECT_EQ(r.exit_code, 3) << r.out;
    EXPECT_NE(r.out.find(file.string()), std::string::npos) << r.out;
    EXPECT_NE(r.out.find(fault.recording_reason), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("the disk is full, a file-size limit was reached or the device is gone"),
              std::string::npos)
        << r.out;
    std::smatch kept;
    ASSERT_TRUE(
        std::regex_search(r.out, kept, std::regex("the ([0-9]+) frame\\(s\\) before it are committed")))
        << r.out;
    const std::size_t committed = std::stoul(kept[1].str());
    EXPECT_GT(committed, 0u) << "the budget holds a few frames";
    EXPECT_LT(committed, 40u) << "the fault came before the end";
    // Opened without the shim: the committed frames, all of them, each decoded and checked.
    std::size_t frames = 0;
    ASSERT_NO_THROW(frames = ReadEveryFrame(file)) << r.out;
    if (fault.fsync) {
      // The failed fsync came after the frame's pages and its commit record reached the log: SQLite reports
      // the commit failed, and the reader may still find that frame, whole (the log's checksums cover it).
      EXPECT_GE(frames, committed);
      EXPECT_LE(frames, committed + 1);
    } else {
      EXPECT_EQ(frames, committed);
    }
    fs::remove_all(dir);
  }
}

// A batch whose result folder's disk fills (or fails) in the middle of its second record: exit code non-zero
// with the file and the reason; the first record complete, no `.partial` and no half-written JSON left; the
// rerun without the fault finishes every object.
TEST(IoFault, BatchLeavesNoCorruptResultAndResumes) {
  const fs::path dir = test::FreshTempDir("io_fault_batch");
  std::mt19937_64 rng(3);
  std::normal_distribution<double> gauss(0.0, 1.0);
  Scan sphere;
  sphere.points.resize(3, 1000);
  for (Eigen::Index j = 0; j < sphere.points.cols(); ++j) {
    const Eigen::Vector3d u(gauss(rng), gauss(rng), gauss(rng));
    sphere.points.col(j) = (20.0 + 0.01 * gauss(rng)) * u.normalized();
  }
  WritePly(dir / "sphere.ply", sphere);
  std::ofstream(dir / "batch.csv") << "id,input,model\ns0,sphere.ply,sphere\ns1,sphere.ply,sphere\n"
                                   << "s2,sphere.ply,sphere\n";
  const auto batch = [&](const fs::path& out) {
    return "batch " + (dir / "batch.csv").string() + " -o " + out.string() + " -j 1 -q";
  };
  // The size of one record, from a batch that never fails.
  const test::ShellResult clean = test::Shell(std::string(S2M_CLI_PATH) + " " + batch(dir / "clean"));
  ASSERT_EQ(clean.exit_code, 0) << clean.out;
  const auto record_bytes = static_cast<long long>(fs::file_size(dir / "clean" / "objects" / "s0.json"));

  for (const Fault& fault : kFaults) {
    SCOPED_TRACE(fault.name);
    const fs::path out = dir / (std::string("results_") + fault.name);
    // Every write into the results folder counts: the disk fills half-way through the second record.
    const test::ShellResult failed =
        RunWithFault(fault, out.filename().string() + "/", record_bytes * 3 / 2, batch(out));
    std::cout << "[ " << fault.name << " ] " << failed.out.substr(0, failed.out.find('\n')) << "\n";
    EXPECT_NE(failed.exit_code, 0) << failed.out;
    EXPECT_NE(failed.out.find(fault.batch_reason), std::string::npos) << failed.out;
    EXPECT_NE(failed.out.find((out / "objects" / "s1.json").string()), std::string::npos) << failed.out;
    EXPECT_TRUE(fs::exists(out / "objects" / "s0.json")) << "the record written before the fault stays";
    for (const auto& e : fs::recursive_directory_iterator(out)) {
      EXPECT_EQ(e.path().string().find(".partial"), std::string::npos) << e.path();
      if (e.path().extension() == ".json") {
        std::ifstream in(e.path());
        nlohmann::json parsed;
        EXPECT_NO_THROW(parsed = nlohmann::json::parse(in)) << e.path() << " is not complete JSON";
      }
    }
    const test::ShellResult resumed = test::Shell(std::string(S2M_CLI_PATH) + " " + batch(out));
    EXPECT_EQ(resumed.exit_code, 0) << resumed.out;
    std::ifstream summary_file(out / "summary.json");
    nlohmann::json summary;
    ASSERT_NO_THROW(summary = nlohmann::json::parse(summary_file));
    ASSERT_EQ(summary["objects"].size(), 3u);
    for (const auto& o : summary["objects"]) EXPECT_EQ(o["status"], "ok") << o.dump();
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace s2m
