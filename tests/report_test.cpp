// `scan2model report` (docs/batch.md): a self-contained HTML report whose SVG plots are well-formed XML and
// which headless Chromium opens without console errors, with a screenshot that is not blank.

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "test_support.h"

namespace s2m {
namespace {

namespace fs = std::filesystem;

using Result = test::ShellResult;
using test::Shell;

bool Have(const std::string& program) {
  return Shell("command -v " + program + " >/dev/null").exit_code == 0;
}

std::string ReadText(const fs::path& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

class Report : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("s2m_report_test_" + std::to_string(getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    // The demo vase: 4 views, joint fit, vessel outputs (about 0.5 s).
    const std::string views = std::string(S2M_SOURCE_DIR) + "/recordings/demo_vase/views.json";
    const Result fit = Shell(std::string(S2M_CLI_PATH) + " fit --model revolution " + views + " -o " +
                             (dir_ / "vase").string());
    ASSERT_EQ(fit.exit_code, 0) << fit.out;
    const Result report = Shell(std::string(S2M_CLI_PATH) + " report " + (dir_ / "vase.json").string() +
                                " -o " + (dir_ / "vase.html").string());
    ASSERT_EQ(report.exit_code, 0) << report.out;
    html_ = ReadText(dir_ / "vase.html");
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_;
  std::string html_;
};

TEST_F(Report, IsSelfContainedWithEverySection) {
  // No scripts, no external resources (the only URL is the SVG namespace, which is a name, not a fetch).
  EXPECT_EQ(html_.find("<script"), std::string::npos);
  // Images only as inline PNG data (the surface interrogation, docs/interrogation.md).
  for (std::size_t at = html_.find("src="); at != std::string::npos; at = html_.find("src=", at + 1))
    EXPECT_EQ(html_.compare(at, 27, "src=\"data:image/png;base64,"), 0) << html_.substr(at, 60);
  EXPECT_EQ(html_.find("href="), std::string::npos);
  std::string without_namespace = html_;
  for (std::size_t at; (at = without_namespace.find("http://www.w3.org/2000/svg")) != std::string::npos;)
    without_namespace.erase(at, 26);
  EXPECT_EQ(without_namespace.find("http"), std::string::npos);
  for (const char* section :
       {"<h2>Parameters</h2>", "rim_diameter", "<h2>Model adequacy</h2>", "<h2>Vessel profile</h2>",
        "Residuals per iteration", "Residual histogram", "<h2>Deviation from the model</h2>",
        "<h2>Views and pose corrections</h2>", "distance (log scale)",
        "<h2>Surface interrogation: surface of revolution</h2>", "Gaussian curvature</b>", "Isophotes</b>"}) {
    EXPECT_NE(html_.find(section), std::string::npos) << section;
  }
  // A primitive fit: its parameters with their uncertainties, its deviations; no views.
  const std::string sphere = std::string(S2M_TEST_DATA_DIR) + "/nist/sph1.ds";
  ASSERT_EQ(Shell(std::string(S2M_CLI_PATH) + " fit --model sphere " + sphere + " --json > " +
                  (dir_ / "sphere.json").string())
                .exit_code,
            0);
  ASSERT_EQ(Shell(std::string(S2M_CLI_PATH) + " report " + (dir_ / "sphere.json").string() + " -o " +
                  (dir_ / "sphere.html").string())
                .exit_code,
            0);
  const std::string primitive = ReadText(dir_ / "sphere.html");
  EXPECT_NE(primitive.find("<td class=\"name\">radius</td>"), std::string::npos);
  EXPECT_NE(primitive.find("Residual histogram"), std::string::npos);
  EXPECT_EQ(primitive.find("Views and pose corrections"), std::string::npos);
  // A document that is no fit result is bad input.
  std::ofstream(dir_ / "other.json") << "{\"schema\": \"scan2model.info/1\"}";
  const Result bad = Shell(std::string(S2M_CLI_PATH) + " report " + (dir_ / "other.json").string() + " -o " +
                           (dir_ / "other.html").string());
  EXPECT_EQ(bad.exit_code, 3) << bad.out;
  EXPECT_NE(bad.out.find("other.json"), std::string::npos) << bad.out;
}

TEST_F(Report, SvgPlotsAreWellFormedXml) {
  std::vector<fs::path> files = {dir_ / "vase_profile.svg"};  // written by fit -o
  int count = 0;  // (std::regex recurses per character: a stack overflow on 150 kB)
  for (std::size_t at = html_.find("<svg"); at != std::string::npos; at = html_.find("<svg", at + 1)) {
    const std::size_t end = html_.find("</svg>", at);
    ASSERT_NE(end, std::string::npos);
    files.push_back(dir_ / ("plot_" + std::to_string(count++) + ".svg"));
    std::ofstream(files.back()) << html_.substr(at, end + 6 - at);
  }
  EXPECT_GE(count, 6);  // profile, convergence, histogram, deviations, two pose charts
  std::string list;
  for (const fs::path& f : files) list += " " + f.string();
  if (Have("python3")) {
    const Result r = Shell(
        "python3 -c 'import sys, xml.etree.ElementTree as E; [E.parse(f) for f in sys.argv[1:]]; "
        "print(\"ok\")'" +
        list);
    EXPECT_EQ(r.exit_code, 0) << r.out;
  } else if (Have("xmllint")) {
    const Result r = Shell("xmllint --noout" + list);
    EXPECT_EQ(r.exit_code, 0) << r.out;
  } else {
    GTEST_SKIP() << "neither python3 nor xmllint to check the XML";
  }
}

TEST_F(Report, OpensInHeadlessChromiumWithoutConsoleErrors) {
  std::string chromium;
  for (const char* candidate : {"chromium", "chromium-browser"}) {
    if (Have(candidate)) {
      chromium = candidate;
      break;
    }
  }
  if (chromium.empty())
    GTEST_SKIP() << "chromium not installed (Debian package chromium, a test-only dependency)";
  if (!Have("python3")) GTEST_SKIP() << "python3 is needed to decode the screenshot";
  auto open = [&](const fs::path& html, const fs::path& png) {
    return Shell(chromium + " --headless --disable-gpu --no-sandbox --user-data-dir=" +
                 (dir_ / "profile").string() + " --window-size=1000,2400 --screenshot=" + png.string() +
                 " --enable-logging=stderr --v=0 file://" + html.string());
  };
  // The check sees console errors: a page with a failing script is caught.
  std::ofstream(dir_ / "broken.html")
      << "<!DOCTYPE html><html><body><script>console.error('x'); nothing();</script>"
         "</body></html>";
  const Result broken = open(dir_ / "broken.html", dir_ / "broken.png");
  ASSERT_NE(broken.out.find(":CONSOLE"), std::string::npos) << broken.out;

  const Result r = open(dir_ / "vase.html", dir_ / "vase.png");
  EXPECT_EQ(r.out.find(":CONSOLE"), std::string::npos) << r.out;
  ASSERT_TRUE(fs::exists(dir_ / "vase.png")) << r.out;
  // Non-blank: decode the PNG (8-bit RGB or RGBA, what Chromium writes) and count pixels that are not white.
  const char* decode = R"(
import struct, sys, zlib
data = open(sys.argv[1], 'rb').read()
assert data[:8] == b'\x89PNG\r\n\x1a\n'
pos, idat, w, h, ctype = 8, b'', 0, 0, 0
while pos < len(data):
    n, kind = struct.unpack('>I4s', data[pos:pos + 8]); body = data[pos + 8:pos + 8 + n]; pos += 12 + n
    if kind == b'IHDR': w, h, depth, ctype = struct.unpack('>IIBB', body[:10])
    elif kind == b'IDAT': idat += body
bpp = {2: 3, 6: 4}[ctype]; raw = zlib.decompress(idat); stride = w * bpp; prev = bytearray(stride); dark = 0; i = 0
for y in range(h):
    f = raw[i]; line = bytearray(raw[i + 1:i + 1 + stride]); i += 1 + stride
    for x in range(stride):
        a = line[x - bpp] if x >= bpp else 0; b = prev[x]; c = prev[x - bpp] if x >= bpp else 0
        if f == 1: line[x] = (line[x] + a) & 255
        elif f == 2: line[x] = (line[x] + b) & 255
        elif f == 3: line[x] = (line[x] + (a + b) // 2) & 255
        elif f == 4:
            p = a + b - c; pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
            line[x] = (line[x] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
    dark += sum(1 for x in range(0, stride, bpp) if min(line[x:x + 3]) < 200)
    prev = line
print(w, h, dark)
)";
  std::ofstream(dir_ / "decode.py") << decode;
  const Result pixels =
      Shell("python3 " + (dir_ / "decode.py").string() + " " + (dir_ / "vase.png").string());
  ASSERT_EQ(pixels.exit_code, 0) << pixels.out;
  long long width = 0, height = 0, dark = 0;
  ASSERT_EQ(std::sscanf(pixels.out.c_str(), "%lld %lld %lld", &width, &height, &dark), 3) << pixels.out;
  EXPECT_EQ(width, 1000);
  // Text, tables, plot lines and points: well above 1 % of the page (measured on the demo vase: about 4 %).
  EXPECT_GT(dark, width * height / 100) << pixels.out;
}

TEST_F(Report, BatchWritesOneReportPerObjectAndReportsFailures) {
  std::ofstream(dir_ / "batch.csv")
      << "id,input,model\nvase," << S2M_SOURCE_DIR
      << "/recordings/demo_vase/views.json,revolution\nbroken,nowhere.ply,sphere\n";
  const Result r = Shell(std::string(S2M_CLI_PATH) + " batch " + (dir_ / "batch.csv").string() +
                         " --report -q -o " + (dir_ / "out").string());
  EXPECT_EQ(r.exit_code, 4) << r.out;
  const std::string vase = ReadText(dir_ / "out" / "objects" / "vase.html");
  EXPECT_NE(vase.find("<h2>Vessel profile</h2>"), std::string::npos);
  const std::string broken = ReadText(dir_ / "out" / "objects" / "broken.html");
  EXPECT_NE(broken.find("<h2>Failed</h2>"), std::string::npos) << broken;
  EXPECT_NE(broken.find("nowhere.ply"), std::string::npos) << broken;
  // The report command reads batch records too.
  const Result again =
      Shell(std::string(S2M_CLI_PATH) + " report " + (dir_ / "out" / "objects" / "vase.json").string() +
            " -o " + (dir_ / "again.html").string());
  EXPECT_EQ(again.exit_code, 0) << again.out;
}

}  // namespace
}  // namespace s2m
