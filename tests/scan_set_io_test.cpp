#include "acquisition/scan_set_io.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "acquisition/format_error.h"
#include "registration/nearest_index.h"
#include "test_paths.h"
#include "test_support.h"

namespace s2m {
namespace {

namespace fs = std::filesystem;

fs::path TempDir(const std::string& name) {
  return test::FreshTempDir("views_" + name);
}

TEST(ScanSetIo, ManifestRoundTrip) {
  const fs::path dir = TempDir("roundtrip");
  ScanSet set;
  set.name = "pot";
  for (int k = 0; k < 3; ++k) {
    Scan s;
    s.points = Eigen::Matrix3Xd::Random(3, 20 + k);
    s.units = "mm";
    s.world_T_scan =
        RigidMotion::FromHelicalVelocity({0.1 * k, 0.2, -0.3}, {static_cast<double>(k), 2.0, 3.0});
    s.metadata.turntable_angle_rad = 0.5 * k;
    set.scans.push_back(s);
  }
  WriteScanSet(dir / "views.json", set);
  const ScanSet back = ReadScanSet(dir / "views.json");
  ASSERT_EQ(back.scans.size(), 3u);
  EXPECT_EQ(back.name, "pot");
  for (std::size_t k = 0; k < 3; ++k) {
    EXPECT_EQ(back.scans[k].points, set.scans[k].points);
    EXPECT_LT((back.scans[k].world_T_scan.matrix() - set.scans[k].world_T_scan.matrix()).norm(), 1e-15);
    EXPECT_EQ(back.scans[k].units, "mm");
    EXPECT_DOUBLE_EQ(*back.scans[k].metadata.turntable_angle_rad, 0.5 * static_cast<double>(k));
  }
  fs::remove_all(dir);
}

TEST(ScanSetIo, BrokenManifestsNameTheFileAndTheView) {
  const fs::path dir = TempDir("broken");
  auto expect_error = [&](const std::string& text, const std::string& fragment) {
    std::ofstream(dir / "m.json") << text;
    try {
      ReadScanSet(dir / "m.json");
      ADD_FAILURE() << "no error for " << text;
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find((dir / "m.json").string()), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
  };
  expect_error("{", "invalid JSON");
  expect_error(R"({"schema": "other"})", "not a scan2model.views/1");
  expect_error(R"({"schema": "scan2model.views/1", "views": []})", "no views");
  expect_error(R"({"schema": "scan2model.views/1", "views": [{"file": "missing.ply"}]})",
               "view 0: view file");
  std::ofstream(dir / "a.xyz") << "1 2 3\n4 5 6\n7 8 9\n";
  expect_error(
      R"({"schema": "scan2model.views/1", "views": [{"file": "a.xyz", "world_T_scan": [[2,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]})",
      "not a rigid motion");
  expect_error(R"({"schema": "scan2model.views/1", "views": [{"file": "a.xyz", "world_T_scan": [[1,0,0]]}]})",
               "4x4");
  std::ofstream(dir / "bad.conf") << "camera 0 0 0 0 0 0 1\nbmesh a.xyz 0 0 0 0 0\n";
  try {
    ReadScanSet(dir / "bad.conf");
    ADD_FAILURE();
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("line 2"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ReadScanSet(dir / "views.txt"), FormatError);
  fs::remove_all(dir);
}

TEST(ScanSetIo, StanfordConfAlignsTheBunnyViews) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  const ScanSet set = ReadScanSet(test::SharedData("stanford_bunny_scans/bun.conf"));
  ASSERT_EQ(set.scans.size(), 10u);  // bun090.ply etc. resolve to the shipped .ply.gz files
  // With the data README's convention the views overlap: median nearest-neighbour distance well below 1 mm.
  const Eigen::Matrix3Xd a = set.scans[0].WorldPoints(), b = set.scans[1].WorldPoints();
  const NearestIndex index(a);
  std::vector<double> d;
  for (Eigen::Index j = 0; j < b.cols(); j += 10)
    d.push_back((a.col(index.Nearest(b.col(j))) - b.col(j)).norm());
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  EXPECT_LT(d[d.size() / 2], 0.001);  // metres
}

}  // namespace
}  // namespace s2m
