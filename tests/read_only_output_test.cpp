// Read-only output folders (docs/reliability.md): every command that writes refuses with exit code 3 and a
// message naming the file or folder and the system's reason, writes nothing, and does not crash. Permissions
// do not stop root, and CI runs as root: there the commands run as the unprivileged user `nobody`
// (setpriv), which the folders deny writing.

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "acquisition/point_cloud_io.h"
#include "test_support.h"

namespace s2m {
namespace {

namespace fs = std::filesystem;

class ReadOnlyOutput : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = test::FreshTempDir("read_only");
    fs::permissions(dir_, fs::perms::all, fs::perm_options::replace);  // inputs reachable for `nobody`
    std::mt19937_64 rng(1);
    std::normal_distribution<double> gauss(0.0, 1.0);
    Scan sphere;
    sphere.points.resize(3, 500);
    for (Eigen::Index j = 0; j < sphere.points.cols(); ++j) {
      const Eigen::Vector3d u(gauss(rng), gauss(rng), gauss(rng));
      sphere.points.col(j) = (10.0 + 0.01 * gauss(rng)) * u.normalized();
    }
    input_ = (dir_ / "sphere.ply").string();
    WritePly(input_, sphere);
    std::ofstream(dir_ / "batch.csv") << "id,input,model\nball,sphere.ply,sphere\n";
    locked_ = dir_ / "locked";
    fs::create_directory(locked_);
    // Readable and searchable by everyone, writable by no one but root.
    fs::permissions(locked_,
                    fs::perms::owner_read | fs::perms::owner_exec | fs::perms::group_read |
                        fs::perms::group_exec | fs::perms::others_read | fs::perms::others_exec,
                    fs::perm_options::replace);
    if (geteuid() == 0) {
      prefix_ = "setpriv --reuid=nobody --regid=nogroup --clear-groups ";
      const test::ShellResult can_run = test::Shell(prefix_ + "test -x " + std::string(S2M_CLI_PATH));
      if (can_run.exit_code != 0) {
        GTEST_SKIP() << "running as root and the user nobody cannot run " << S2M_CLI_PATH
                     << " (setpriv missing, or a folder on the way is closed): permissions cannot be tested";
      }
    }
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Runs `scan2model ARGS` as a user the locked folder denies; checks the refusal.
  void ExpectRefused(const std::string& args, const std::string& named) {
    const test::ShellResult r = test::Shell(prefix_ + S2M_CLI_PATH + " " + args);
    EXPECT_EQ(r.exit_code, 3) << args << "\n" << r.out;
    EXPECT_NE(r.out.find(named), std::string::npos) << args << "\n" << r.out;
    EXPECT_NE(r.out.find("Permission denied"), std::string::npos) << args << "\n" << r.out;
    EXPECT_TRUE(fs::is_empty(locked_)) << args;
  }

  fs::path dir_, locked_;
  std::string input_, prefix_;
};

TEST_F(ReadOnlyOutput, FitReportBatchRecordAndExportRefuseClearly) {
  const std::string locked = locked_.string();
  ExpectRefused("fit --model sphere " + input_ + " -o " + locked + "/ball", locked + "/ball");
  ExpectRefused("batch " + (dir_ / "batch.csv").string() + " -q -o " + locked + "/results",
                locked + "/results");
  ExpectRefused("record " + input_ + " -q -o " + locked + "/ball.s2mrec", locked + "/ball.s2mrec");
  ExpectRefused("export " + input_ + " -q -o " + locked + "/views", locked + "/views");
  // report needs a result to render: written where it may be, then refused where it may not.
  const fs::path open_dir = dir_ / "open";
  fs::create_directory(open_dir);
  fs::permissions(open_dir, fs::perms::all, fs::perm_options::replace);
  const test::ShellResult fit = test::Shell(prefix_ + S2M_CLI_PATH + " fit --model sphere " + input_ +
                                            " -o " + (open_dir / "ball").string());
  ASSERT_EQ(fit.exit_code, 0) << fit.out;
  ExpectRefused("report " + (open_dir / "ball.json").string() + " -o " + locked + "/ball.html",
                locked + "/ball.html");
}

}  // namespace
}  // namespace s2m
