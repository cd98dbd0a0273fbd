// Adequacy on every fit (docs/method.md section 17, docs/cli.md "adequacy"): the RMS against the model-free
// noise estimate AND no significant residual structure, through ComputeFit as `fit` and `batch` run it. An
// inadequate fit is reported so, with its uncertainties flagged and a suggestion; an adequate one is not
// flagged over seeds.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <random>
#include <string>

#include "pipeline/domain_measures.h"
#include "pipeline/fit_option_table.h"
#include "pipeline/fit_options.h"
#include "pipeline/report.h"
#include "test_paths.h"
#include "test_support.h"

namespace s2m::pipeline {
namespace {

std::string WriteXyz(const std::filesystem::path& path, const Eigen::MatrixXd& points) {
  std::ofstream out(path);
  out.precision(12);
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    for (Eigen::Index r = 0; r < points.rows(); ++r) out << (r ? " " : "") << points(r, i);
    if (points.rows() == 2) out << " 0";
    out << "\n";
  }
  return path.string();
}

// Points on a surface of revolution about z with radius r(h) for h in [0, height], uniform over the
// lateral area (approximately: uniform in angle and height), Gaussian noise along x, y and z.
Eigen::Matrix3Xd RevolutionPoints(int n, double height, const std::function<double(double)>& radius,
                                  double noise, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, noise);
  Eigen::Matrix3Xd p(3, n);
  for (int i = 0; i < n; ++i) {
    const double a = 2 * M_PI * uniform(rng), h = height * uniform(rng), r = radius(h);
    p.col(i) << r * std::cos(a) + gauss(rng), r * std::sin(a) + gauss(rng), h + gauss(rng);
  }
  return p;
}

FitOptions Options(const std::string& file, const std::string& model) {
  FitOptions o;
  o.file = file;
  o.model = model;
  o.interactive = false;
  return o;
}

// A cylinder fitted to a cone's points (radius 10 to 13 over 40 mm, noise 0.02 mm): the residuals follow the
// taper (a smooth pattern along the axis), the RMS is far above the noise; the fit is NOT adequate, its
// uncertainties are marked as not trustworthy, and the report says to try a cone.
TEST(Adequacy, CylinderOnAConeIsInadequateWithUntrustedUncertainties) {
  const auto dir = test::FreshTempDir("adequacy_cone");
  const std::string file =
      WriteXyz(dir / "cone.xyz", RevolutionPoints(
                                     3000, 40, [](double h) { return 10 + 0.075 * h; }, 0.02, 1));
  const FitOutcome outcome = ComputeFit(Options(file, "cylinder"));
  const nlohmann::json& a = outcome.document["adequacy"];
  EXPECT_FALSE(a["adequate"].get<bool>());
  EXPECT_FALSE(a["rms_within_band"].get<bool>());
  EXPECT_TRUE(a["structure"]["significant"].get<bool>());
  EXPECT_GT(a["structure"]["moran"]["statistic"].get<double>(), 0.5);
  EXPECT_FALSE(a["uncertainty_trusted"].get<bool>());
  EXPECT_FALSE(outcome.document["uncertainty_trusted"].get<bool>());
  ASSERT_FALSE(a["suggestions"].empty());
  EXPECT_NE(a["suggestions"][0].get<std::string>().find("cone"), std::string::npos);
  EXPECT_NE(outcome.text.find("uncertainties are NOT trustworthy: the model is inadequate"),
            std::string::npos);
  EXPECT_NE(outcome.text.find("NOT adequate"), std::string::npos);
  EXPECT_NE(outcome.text.find("radius            ["), std::string::npos) << outcome.text;
  // The HTML report shows the verdict, the structure tests, the untrusted uncertainties and the suggestion.
  const std::string html = ReportHtml(outcome.document);
  EXPECT_NE(html.find("The model is NOT adequate"), std::string::npos);
  EXPECT_NE(html.find("Moran's I over 8 nearest neighbours"), std::string::npos);
  EXPECT_NE(html.find("Uncertainties are NOT trustworthy"), std::string::npos);
  EXPECT_NE(html.find("try another model: cone"), std::string::npos);
  // The right model on the same points is adequate, and its uncertainties are trusted.
  const FitOutcome cone = ComputeFit(Options(file, "cone"));
  EXPECT_TRUE(cone.document["adequacy"]["adequate"].get<bool>()) << cone.text;
  EXPECT_TRUE(cone.document["uncertainty_trusted"].get<bool>());
  EXPECT_EQ(cone.text.find("NOT trustworthy"), std::string::npos);
}

// A cylinder on cylinder points with Gaussian noise, 20 seeds: adequate every time, no structure flagged.
// Each test's z-score is approximately standard normal under the null; at the one-sided level z > 3
// (1.35e-3) the 40 z-scores are expected to pass it 0.05 times, and 2 or more would happen with probability
// about 1e-3: at most one is allowed. The effect thresholds (I and sign correlation > 0.1) are 30 standard
// errors away at 2000 points, so the verdict itself never flags.
TEST(Adequacy, CylinderOnCylinderPointsIsAdequateOverSeeds) {
  const auto dir = test::FreshTempDir("adequacy_cylinder");
  int beyond = 0;
  for (unsigned seed = 0; seed < 20; ++seed) {
    const std::string file = WriteXyz(dir / ("cylinder_" + std::to_string(seed) + ".xyz"),
                                      RevolutionPoints(
                                          2000, 40, [](double) { return 10.0; }, 0.02, 100 + seed));
    const FitOutcome outcome = ComputeFit(Options(file, "cylinder"));
    const nlohmann::json& a = outcome.document["adequacy"];
    EXPECT_TRUE(a["adequate"].get<bool>()) << "seed " << seed << "\n" << outcome.text;
    EXPECT_FALSE(a["structure"]["significant"].get<bool>()) << "seed " << seed;
    EXPECT_TRUE(a["suggestions"].empty());
    EXPECT_TRUE(outcome.document["uncertainty_trusted"].get<bool>());
    EXPECT_NEAR(a["rms_to_noise"].get<double>(), 1.0, 0.25) << "seed " << seed;
    beyond += -a["structure"]["runs"]["z"].get<double>() > kStructureZ;
    beyond += a["structure"]["moran"]["z"].get<double>() > kStructureZ;
  }
  EXPECT_LE(beyond, 1);
}

// A plane curve y = sin(x) over four periods (400 points, noise 0.01) fitted with 6 control points: the
// curve cannot follow the waves, the residuals keep their sign over long stretches of the curve parameter
// and the runs test flags it; the suggestion is more control points. With 40 control points the same data
// are fitted to the noise and adequate.
TEST(Adequacy, SplineCurveWithTooFewControlPointsShowsStructureAlongTheParameter) {
  const auto dir = test::FreshTempDir("adequacy_curve");
  std::mt19937 rng(5);
  std::normal_distribution<double> gauss(0.0, 0.01);
  Eigen::MatrixXd points(2, 400);
  for (int i = 0; i < 400; ++i) {
    const double x = 8 * M_PI * i / 399.0;
    points.col(i) << x + gauss(rng), std::sin(x) + gauss(rng);
  }
  const std::string file = WriteXyz(dir / "wave.xyz", points);
  FitOptions coarse = Options(file, "bspline-curve");
  coarse.control_points = "6";
  const FitOutcome few = ComputeFit(coarse);
  const nlohmann::json& a = few.document["adequacy"];
  EXPECT_FALSE(a["adequate"].get<bool>()) << few.text;
  EXPECT_TRUE(a["structure"]["runs"]["significant"].get<bool>());
  EXPECT_EQ(a["structure"]["runs"]["order"], "the curve parameter");
  EXPECT_LT(a["structure"]["runs"]["z"].get<double>(), -kStructureZ);
  ASSERT_FALSE(a["suggestions"].empty());
  EXPECT_NE(a["suggestions"][0].get<std::string>().find("more control points"), std::string::npos);
  EXPECT_NE(few.text.find("NOT adequate"), std::string::npos);

  FitOptions fine = Options(file, "bspline-curve");
  fine.control_points = "40";
  const FitOutcome many = ComputeFit(fine);
  EXPECT_TRUE(many.document["adequacy"]["adequate"].get<bool>()) << many.text;
}

// A plane with 10 % of its points far off it (flying pixels 5-50 mm away, noise 0.05 mm): fitted by plain
// least squares the residuals are heavy-tailed and the suggestion is a robust loss; with --loss cauchy the
// verdict uses the inliers' RMS and the deviations' sample carries the weights the report colours.
TEST(Adequacy, HeavyTailsSuggestARobustLoss) {
  const auto dir = test::FreshTempDir("adequacy_tails");
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 0.05);
  Eigen::Matrix3Xd p(3, 3000);
  for (int i = 0; i < 3000; ++i) {
    const double off = i % 10 == 0 ? 5 + 45 * uniform(rng) : 0.0;
    p.col(i) << 100 * uniform(rng), 100 * uniform(rng), gauss(rng) + off;
  }
  const std::string file = WriteXyz(dir / "plane.xyz", p);
  FitOptions plain = Options(file, "plane");
  plain.loss = ParseRobustLoss("none");
  plain.loss_given = true;
  const FitOutcome ls = ComputeFit(plain);
  const nlohmann::json& a = ls.document["adequacy"];
  EXPECT_FALSE(a["adequate"].get<bool>());
  EXPECT_TRUE(a["tails"]["heavy"].get<bool>());
  ASSERT_FALSE(a["suggestions"].empty());
  EXPECT_NE(a["suggestions"][0].get<std::string>().find("robust loss"), std::string::npos);

  FitOptions robust = Options(file, "plane");
  robust.loss = ParseRobustLoss("cauchy");
  robust.loss_given = true;
  const nlohmann::json r = ComputeFit(robust).document;
  EXPECT_EQ(r["adequacy"]["fit_scale_kind"], "rms of the points with robust weight >= 0.5");
  EXPECT_NEAR(r["adequacy"]["down_weighted_fraction"].get<double>(), 0.1, 0.02);
  EXPECT_TRUE(r["adequacy"]["rms_within_band"].get<bool>());
  EXPECT_EQ(r["deviations"]["sample"]["columns"].back(), "weight");
  EXPECT_NEAR(r["deviations"]["down_weighted"].get<double>(), 300, 30);
  // The report's deviation map draws the down-weighted points as crosses, with their legend.
  EXPECT_NE(ReportHtml(r).find("down-weighted (robust weight &lt; 0.5)"), std::string::npos);
}

// Certified data are exact to rounding: the verdict says so instead of dividing by a zero noise.
TEST(Adequacy, ExactDataAreAdequate) {
  const FitOutcome outcome = ComputeFit(Options(test::TestData("nist/sph9.ds").string(), "sphere"));
  EXPECT_TRUE(outcome.document["adequacy"]["exact"].get<bool>());
  EXPECT_TRUE(outcome.document["adequacy"]["adequate"].get<bool>());
}

}  // namespace
}  // namespace s2m::pipeline

namespace s2m::pipeline {
namespace {

// The default loss per input kind (docs/cli.md "--loss"): robust for recordings, device frames and organized
// clouds, none for certified NIST data and other point files; a given loss always wins.
TEST(DefaultLoss, ClassifiesInputsByKind) {
  EXPECT_EQ(ClassifyInput("sph1.ds", "file"), InputKind::kCertified);
  EXPECT_EQ(ClassifyInput("pot.s2mrec", "virtual:kinect"), InputKind::kRecording);
  EXPECT_EQ(ClassifyInput("scene.pcd", "file:organized"), InputKind::kOrganizedCloud);
  EXPECT_EQ(ClassifyInput("frame.tiff", "file:depth-frame"), InputKind::kDeviceFrame);
  EXPECT_EQ(ClassifyInput("views.json", "virtual:kinect"), InputKind::kDeviceFrame);
  EXPECT_EQ(ClassifyInput("bore.ply", "file"), InputKind::kPointFile);
  EXPECT_EQ(ClassifyInput("bore.ply", ""), InputKind::kPointFile);
  FitOptions o;
  ResolveDefaultLoss(o, InputKind::kRecording);
  EXPECT_EQ(o.loss.kind, LossKind::kCauchy);
  EXPECT_TRUE(o.loss.scale_from_data());
  EXPECT_EQ(o.loss_reason, "default for recordings (flying pixels and mixed edges)");
  ResolveDefaultLoss(o, InputKind::kCertified);
  EXPECT_EQ(o.loss.kind, LossKind::kNone);
  FitOptions given;
  ApplyFitOption(*FindManifestOption("loss"), "none", given);
  ResolveDefaultLoss(given, InputKind::kRecording);
  EXPECT_EQ(given.loss.kind, LossKind::kNone);
  EXPECT_EQ(given.loss_reason, "given");
  FitOptions automatic;
  ApplyFitOption(*FindManifestOption("loss"), "auto", automatic);
  EXPECT_FALSE(automatic.loss_given);
}

// Through ComputeFit: a recording gets the robust default and says so; NIST data get plain least squares
// (their certification stays exact: tests/nist_reference_test.cpp).
TEST(DefaultLoss, RecordingGetsTheRobustDefaultAndNistGetsNone) {
  const FitOutcome recording =
      ComputeFit(Options(std::string(S2M_SOURCE_DIR) + "/recordings/pot.s2mrec", "cylinder"));
  EXPECT_EQ(recording.document["loss"]["kind"], "cauchy");
  EXPECT_EQ(recording.document["loss"]["reason"], "default for recordings (flying pixels and mixed edges)");
  EXPECT_NE(recording.text.find("default for recordings"), std::string::npos);
  const FitOutcome nist = ComputeFit(Options(test::TestData("nist/cyl1.ds").string(), "cylinder"));
  EXPECT_EQ(nist.document["loss"]["kind"], "none");
  EXPECT_EQ(nist.document["loss"]["reason"],
            "default for certified reference data (plain least squares, as certified)");
}

}  // namespace
}  // namespace s2m::pipeline
