// `scan2model interrogate` end to end (docs/interrogation.md, docs/cli.md): the demo's vase fitted jointly
// with its views, then its curvature map and isophotes as PNG files and in the HTML report; clear errors for
// a missing file, a curve's document, unusable members and NaN parameters.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>

#include "acquisition/scan_set_io.h"
#include "synthetic/synthetic_cases.h"
#include "test_support.h"

namespace s2m {
namespace {

namespace fs = std::filesystem;

test::ShellResult RunCli(const std::string& args) {
  return test::Shell(std::string(S2M_CLI_PATH) + " " + args);
}

std::string Read(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// A point off the fitted vase's axis point by (dx, dy, dz), as "x,y,z".
std::string Eye(const nlohmann::json& fit, double dx, double dy, double dz) {
  const auto p = fit["axis"]["point"].get<std::vector<double>>();
  return std::to_string(p[0] + dx) + "," + std::to_string(p[1] + dy) + "," + std::to_string(p[2] + dz);
}

class InterrogateCommand : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(test::FreshTempDir("interrogate"));
    const test::ShellResult fit = RunCli("fit --model revolution " + std::string(S2M_SOURCE_DIR) +
                                         "/recordings/demo_vase/views.json -o " + (*dir_ / "vase").string());
    ASSERT_EQ(fit.exit_code, 0) << fit.out;
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
  }
  static fs::path* dir_;
};
fs::path* InterrogateCommand::dir_ = nullptr;

TEST_F(InterrogateCommand, WritesTheVasesMapsAndIsophotes) {
  const std::string fit = (*dir_ / "vase.json").string();
  const nlohmann::json doc = nlohmann::json::parse(Read(fit));
  ASSERT_TRUE(doc.contains("surface"));
  EXPECT_EQ(doc["surface"]["kind"], "revolution");
  for (const std::string& args :
       {std::string("--map mean --range -0.05,0.05"), std::string("--isophotes 6"),
        std::string("--reflection-lines 10 --light 0,0.3,1"), std::string("--zebra 8"),
        std::string("--contours 12 --view 1,0,0 --size 300x200"),
        "--isophotes 8 --eye " + Eye(doc, 0, 280, 60), std::string("")}) {
    const fs::path png = *dir_ / "out.png";
    fs::remove(png);
    const test::ShellResult r = RunCli("interrogate " + fit + " " + args + " -o " + png.string());
    EXPECT_EQ(r.exit_code, 0) << args << ": " << r.out;
    EXPECT_NE(r.out.find("surface of revolution"), std::string::npos) << r.out;
    const std::string bytes = Read(png);
    ASSERT_GT(bytes.size(), 8u) << args;
    EXPECT_EQ(bytes.substr(0, 8), std::string("\x89PNG\r\n\x1a\n")) << args;
  }
  // The report shows the curvature maps, isophotes, reflection lines, zebra stripes and contours as embedded
  // images with their parameters.
  const fs::path html = *dir_ / "vase.html";
  ASSERT_EQ(RunCli("report " + fit + " -o " + html.string()).exit_code, 0);
  const std::string report = Read(html);
  EXPECT_NE(report.find("Surface interrogation: surface of revolution"), std::string::npos);
  for (const char* title : {"Gaussian curvature</b>", "Mean curvature</b>", "Maximum principal curvature</b>",
                            "Minimum principal curvature</b>", "Isophotes</b>", "Reflection lines</b>",
                            "Zebra stripes</b>", "Contours</b>"})
    EXPECT_NE(report.find(title), std::string::npos) << title;
  std::size_t images = 0;
  for (std::size_t at = report.find("data:image/png;base64,"); at != std::string::npos;
       at = report.find("data:image/png;base64,", at + 1))
    ++images;
  EXPECT_EQ(images, 8u);
  EXPECT_NE(report.find("light towards"), std::string::npos);
}

TEST_F(InterrogateCommand, BSplineSurfaceFitsAreInterrogatedToo) {
  // A saddle z = 0.3 (x^2 - y^2) sampled on a grid, fitted by a 5 x 5 B-spline surface.
  const fs::path points = *dir_ / "saddle.xyz";
  {
    std::ofstream out(points);
    for (int i = 0; i < 20; ++i) {
      for (int j = 0; j < 20; ++j) {
        const double x = -1 + 2.0 * i / 19, y = -1 + 2.0 * j / 19;
        out << x << " " << y << " " << 0.3 * (x * x - y * y) << "\n";
      }
    }
  }
  const std::string prefix = (*dir_ / "saddle").string();
  const test::ShellResult fit =
      RunCli("fit --model bspline-surface --control-points 5x5 " + points.string() + " -o " + prefix);
  ASSERT_EQ(fit.exit_code, 0) << fit.out;
  const fs::path png = *dir_ / "saddle.png";
  const test::ShellResult r = RunCli("interrogate " + prefix + ".json --map gaussian -o " + png.string());
  EXPECT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("B-spline surface"), std::string::npos) << r.out;
  EXPECT_EQ(Read(png).substr(0, 8), std::string("\x89PNG\r\n\x1a\n"));
  ASSERT_EQ(RunCli("report " + prefix + ".json -o " + prefix + ".html").exit_code, 0);
  EXPECT_NE(Read(prefix + ".html").find("Surface interrogation: B-spline surface"), std::string::npos);
}

TEST_F(InterrogateCommand, FiniteElementSurfacesAreInterrogatedOverTheirPolygon) {
  // A saddle z = 0.3 (x^2 - y^2) over a disk (a domain no rectangle covers), fitted by `--model fe-surface`:
  // the command draws its Gaussian map and the report shows its interrogation.
  const fs::path points = *dir_ / "disk_saddle.xyz";
  {
    std::ofstream out(points);
    for (int i = 0; i < 40; ++i)
      for (int j = 0; j < 40; ++j) {
        const double x = -1 + 2.0 * i / 39, y = -1 + 2.0 * j / 39;
        if (x * x + y * y <= 1.0) out << x << " " << y << " " << 0.3 * (x * x - y * y) << "\n";
      }
  }
  const std::string prefix = (*dir_ / "disk_saddle").string();
  const test::ShellResult fit = RunCli("fit --model fe-surface " + points.string() + " -o " + prefix);
  ASSERT_EQ(fit.exit_code, 0) << fit.out;
  const fs::path png = *dir_ / "disk_saddle.png";
  const test::ShellResult r = RunCli("interrogate " + prefix + ".json --map gaussian -o " + png.string());
  EXPECT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("finite-element surface"), std::string::npos) << r.out;
  EXPECT_EQ(Read(png).substr(0, 8), std::string("\x89PNG\r\n\x1a\n"));
  ASSERT_EQ(RunCli("report " + prefix + ".json -o " + prefix + ".html").exit_code, 0);
  EXPECT_NE(Read(prefix + ".html").find("Surface interrogation: finite-element surface"), std::string::npos);
}

TEST_F(InterrogateCommand, APartsSplinePatchIsInterrogated) {
  // The free-form plate (docs/examples/freeform_plate.part.json) fitted to the relief plate's views with the
  // file's 4 x 4 net: its top patch is in the document exactly and is drawn; the analytic faces are not.
  SyntheticCase c;
  c.name = "relief plate";
  c.views = ReliefPlateViews();
  const fs::path manifest = *dir_ / "plate_views.json";
  WriteScanSet(manifest, RecordedViews(c));
  const std::string prefix = (*dir_ / "plate").string();
  const test::ShellResult fit =
      RunCli("fit --model part:" + std::string(S2M_SOURCE_DIR) + "/docs/examples/freeform_plate.part.json " +
             manifest.string() + " --control-points file -o " + prefix);
  ASSERT_EQ(fit.exit_code, 0) << fit.out;
  const nlohmann::json doc = nlohmann::json::parse(Read(prefix + ".json"));
  int patches = 0;
  for (const nlohmann::json& face : doc["faces"]) {
    EXPECT_EQ(face.contains("surface"), face["type"] == "spline_patch") << face.dump();
    if (face.contains("surface")) {
      ++patches;
      EXPECT_EQ(face["surface"]["control_points"].size(), 16u);  // the file's 4 x 4 net
    }
  }
  EXPECT_EQ(patches, 1);
  const fs::path png = *dir_ / "plate.png";
  const test::ShellResult r = RunCli("interrogate " + prefix + ".json --map mean -o " + png.string());
  EXPECT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("spline patch 'top' of the part"), std::string::npos) << r.out;
  EXPECT_EQ(Read(png).substr(0, 8), std::string("\x89PNG\r\n\x1a\n"));
  // The part's report interrogates the same patch.
  ASSERT_EQ(RunCli("report " + prefix + ".json -o " + prefix + ".html").exit_code, 0);
  const std::string report = Read(prefix + ".html");
  EXPECT_NE(report.find("Surface interrogation: spline patch"), std::string::npos);
  EXPECT_EQ(report.find("not rendered"), std::string::npos);
}

TEST_F(InterrogateCommand, BadInputIsRefusedClearly) {
  const std::string fit = (*dir_ / "vase.json").string(), png = (*dir_ / "bad.png").string();
  // A missing file: input error, the file named.
  test::ShellResult r = RunCli("interrogate " + (*dir_ / "missing.json").string() + " -o " + png);
  EXPECT_EQ(r.exit_code, 3) << r.out;
  EXPECT_NE(r.out.find("missing.json"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("cannot open"), std::string::npos) << r.out;
  // A curve's document: no surface to interrogate.
  const fs::path curve = *dir_ / "curve.json";
  std::ofstream(curve)
      << nlohmann::json{{"schema", "scan2model.bspline/1"},
                        {"model", "bspline-curve"},
                        {"basis", {{"order", 4}, {"periodic", false}, {"knots", {0, 0, 0, 0, 1, 1, 1, 1}}}},
                        {"control_points", {{0, 0}, {1, 1}, {2, 0}, {3, 1}}}}
             .dump();
  r = RunCli("interrogate " + curve.string() + " -o " + png);
  EXPECT_EQ(r.exit_code, 3) << r.out;
  EXPECT_NE(r.out.find("no surface"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("bspline-curve"), std::string::npos) << r.out;
  // Unusable members of a surface (a null where a radius belongs; JSON has no NaN).
  nlohmann::json doc = nlohmann::json::parse(Read(fit));
  doc["surface"]["profile"][1][0] = nullptr;
  const fs::path broken = *dir_ / "broken.json";
  std::ofstream(broken) << doc.dump();
  r = RunCli("interrogate " + broken.string() + " -o " + png);
  EXPECT_EQ(r.exit_code, 3) << r.out;
  EXPECT_NE(r.out.find("unusable"), std::string::npos) << r.out;
  // Not JSON at all.
  const fs::path text = *dir_ / "text.json";
  std::ofstream(text) << "not json";
  EXPECT_EQ(RunCli("interrogate " + text.string() + " -o " + png).exit_code, 3);
  // NaN and malformed parameters: usage errors naming the option.
  for (const std::string& args :
       {std::string("--light nan,0,1"), std::string("--view 0,0,0"), std::string("--range 1,nan"),
        std::string("--range 2,1"), std::string("--map gauss"), std::string("--size 10x"),
        std::string("--isophotes 4 --zebra 3"), std::string("--isophotes -2"), std::string("--eye 1,nan,2"),
        "--eye " + Eye(nlohmann::json::parse(Read(fit)), 0, 0, 0)}) {  // an eye inside the vase
    r = RunCli("interrogate " + fit + " " + args + " -o " + png);
    EXPECT_EQ(r.exit_code, 2) << args << ": " << r.out;
    const std::string option = args.substr(0, args.find(' '));
    EXPECT_NE(r.out.find(option), std::string::npos) << args << ": " << r.out;
  }
  EXPECT_FALSE(fs::exists(png));
}

}  // namespace
}  // namespace s2m
