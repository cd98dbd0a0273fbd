// `scan2model inspect` end to end (docs/cli.md, docs/metrology.md sections 5-9): a box's nominal as an ASCII
// STL with one solid per face, a scan of it placed off by a small motion, a checks file; the report's JSON
// and HTML, the decisions, the traceability block; corrupt inputs rejected with the file named.

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>

#include "acquisition/file_hash.h"
#include "acquisition/mesh_io.h"
#include "acquisition/point_cloud_io.h"
#include "test_meshes.h"
#include "test_support.h"

namespace s2m {
namespace {

namespace fs = std::filesystem;

// The box [-30, 30] x [-20, 20] x [0, 20], one group per face, named as the checks files below name them.
TriangleMesh Box() {
  TriangleMesh m = test::BoxMesh(30, 20, 20);
  m.group_names = {"px", "mx", "py", "my", "top", "bottom"};
  return m;
}

// Points on the box's faces (noise 0.002 along the normal), moved by a small rigid motion.
Scan BoxScan() {
  std::mt19937_64 random(9);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> noise(0, 0.002);
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < 6000; ++i) {
    const int f = i % 6;
    const double p = u(random), q = u(random), e = noise(random);
    switch (f) {
      case 0:
        pts.emplace_back(30 + e, -20 + 40 * p, 20 * q);
        break;
      case 1:
        pts.emplace_back(-30 - e, -20 + 40 * p, 20 * q);
        break;
      case 2:
        pts.emplace_back(-30 + 60 * p, 20 + e, 20 * q);
        break;
      case 3:
        pts.emplace_back(-30 + 60 * p, -20 - e, 20 * q);
        break;
      case 4:
        pts.emplace_back(-30 + 60 * p, -20 + 40 * q, 20 + e);
        break;
      default:
        pts.emplace_back(-30 + 60 * p, -20 + 40 * q, -e);
    }
  }
  const RigidMotion off(RotationAboutAxis(Eigen::Vector3d(0, 0, 1), 0.01), Eigen::Vector3d(0.3, -0.2, 0.1));
  Scan s;
  s.points.resize(3, static_cast<Eigen::Index>(pts.size()));
  for (std::size_t i = 0; i < pts.size(); ++i) s.points.col(static_cast<Eigen::Index>(i)) = off * pts[i];
  s.units = "mm";
  return s;
}

TEST(InspectCommand, ReportWithDecisionsAndTraceability) {
  const fs::path dir = test::FreshTempDir("inspect");
  WriteStl(dir / "box.stl", Box(), true);
  WritePly(dir / "scan.ply", BoxScan());
  std::ofstream(dir / "checks.json") << R"({"schema": "scan2model.checks/1", "part": "test box", "checks": [
             {"name": "top flatness", "type": "flatness", "group": "top", "tolerance": 0.05},
             {"name": "top profile", "type": "profile", "group": "top", "tolerance": 0.001}]})";
  const test::ShellResult r =
      test::Shell(test::Quote({S2M_CLI_PATH, "inspect", "--nominal", (dir / "box.stl").string(),
                               (dir / "scan.ply").string(), "--part", (dir / "checks.json").string(), "-o",
                               (dir / "report").string(), "--operator", "A. Tester", "--json"}),
                  false);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["schema"], "scan2model.inspection/1");
  ASSERT_EQ(j["regions"].size(), 6u);
  for (const auto& g : j["regions"]) EXPECT_LT(std::abs(g["mean"].get<double>()), 0.002) << g["name"];
  ASSERT_EQ(j["characteristics"].size(), 2u);
  const auto& flat = j["characteristics"][0];
  // Flatness of noise 0.002: a zone of several sigma, far inside 0.05 with a small U.
  EXPECT_GT(flat["actual"].get<double>(), 0.004);
  EXPECT_LT(flat["actual"].get<double>(), 0.03);
  EXPECT_GT(flat["expanded_uncertainty"].get<double>(), 0.0);
  EXPECT_EQ(flat["coverage_factor"].get<double>(), 2.0);
  EXPECT_EQ(flat["decision"], "conforms");
  // A profile tolerance of 1 um is below the noise: proven out of tolerance.
  EXPECT_EQ(j["characteristics"][1]["decision"], "does not conform");
  EXPECT_EQ(j["characteristics"][1]["verdict"], "fail");
  const auto& t = j["traceability"];
  EXPECT_EQ(t["operator"], "A. Tester");
  ASSERT_EQ(t["files"].size(), 3u);
  EXPECT_EQ(t["files"][0]["sha256"], Sha256OfFile(dir / "box.stl"));
  EXPECT_EQ(Sha256Hex("abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");  // FIPS 180-4
  std::ifstream html(dir / "report.html");
  const std::string text((std::istreambuf_iterator<char>(html)), {});
  EXPECT_NE(text.find("Traceability"), std::string::npos);
  EXPECT_NE(text.find("does not conform"), std::string::npos);
  EXPECT_NE(text.find("<svg"), std::string::npos);
  EXPECT_TRUE(fs::exists(dir / "report.json"));
  EXPECT_TRUE(fs::exists(dir / "report_deviations.csv"));
  fs::remove_all(dir);
}

TEST(InspectCommand, RejectsCorruptInputsNamingTheFile) {
  const fs::path dir = test::FreshTempDir("inspect_bad");
  WriteStl(dir / "box.stl", Box(), false);
  WritePly(dir / "scan.ply", BoxScan());
  {
    std::ifstream in(dir / "box.stl", std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), {});
    std::ofstream(dir / "cut.stl", std::ios::binary) << bytes.substr(0, 300);
  }
  test::ShellResult r = test::Shell(test::Quote(
      {S2M_CLI_PATH, "inspect", "--nominal", (dir / "cut.stl").string(), (dir / "scan.ply").string()}));
  EXPECT_EQ(r.exit_code, 3) << r.out;
  EXPECT_NE(r.out.find("cut.stl"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("truncated"), std::string::npos) << r.out;
  std::ofstream(dir / "checks.json")
      << R"({"schema": "scan2model.checks/1", "checks": [{"type": "roundness"}]})";
  r = test::Shell(test::Quote({S2M_CLI_PATH, "inspect", "--nominal", (dir / "box.stl").string(),
                               (dir / "scan.ply").string(), "--part", (dir / "checks.json").string()}));
  EXPECT_EQ(r.exit_code, 3) << r.out;
  EXPECT_NE(r.out.find("checks.json"), std::string::npos) << r.out;
  r = test::Shell(test::Quote({S2M_CLI_PATH, "inspect", "--nominal", (dir / "box.stl").string(),
                               (dir / "scan.ply").string(), "--datum", "nope"}));
  EXPECT_EQ(r.exit_code, 2) << r.out;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace s2m
