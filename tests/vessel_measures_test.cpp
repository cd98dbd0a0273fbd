// The vessel's volume and out-of-roundness through the command's own path (ComputeFit, `fit --model
// revolution`): a pot with a known analytic profile, scanned all round as one cloud. Noise-free, the volume
// to the rim and up to a fill height are within 0.1 % of the analytic integrals; with noise, within 3 of the
// reported standard uncertainties (docs/archaeology.md eqs. A1-A4) on every seed; a fill height above the rim
// is said, not fitted. The same pot made oval has its ovality measured in every band (eqs. A5-A8), a third of
// it (a sherd) in none; the text and the report carry both.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <random>
#include <vector>

#include "acquisition/point_cloud_io.h"
#include "pipeline/batch.h"
#include "pipeline/fit_option_table.h"
#include "pipeline/fit_options.h"
#include "pipeline/report.h"

namespace s2m {
namespace {

namespace fs = std::filesystem;

// The pot: r(z) = 40 + 8 sin(pi z / 100) - 0.1 z (mm) for z in [0, 100], axis the world's z.
double PotRadius(double z) {
  return 40.0 + 8.0 * std::sin(M_PI * z / 100.0) - 0.1 * z;
}
double PotSlope(double z) {
  return 8.0 * M_PI / 100.0 * std::cos(M_PI * z / 100.0) - 0.1;
}

// pi integral r(z)^2 dz from a to b by composite Simpson on 20000 intervals (the integrand is smooth: error
// far below 1e-9 relative).
double PotVolume(double a, double b) {
  const int n = 20000;
  const double h = (b - a) / n;
  double sum = 0.0;
  for (int i = 0; i <= n; ++i) {
    const double r = PotRadius(a + i * h);
    sum += (i == 0 || i == n ? 1.0 : i % 2 ? 4.0 : 2.0) * r * r;
  }
  return M_PI * sum * h / 3.0;
}

// `count` points uniform in (z, angle) with Gaussian noise `sigma` along the surface normal, the exact
// ends z = 0 and z = 100 included as rings so that the data's extent is the pot's.
fs::path WritePot(const std::string& name, int count, double sigma, unsigned seed) {
  const fs::path dir = fs::temp_directory_path() / "s2m_vessel_measures_test";
  fs::create_directories(dir);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> height(0.0, 100.0), angle(0.0, 2 * M_PI);
  std::normal_distribution<double> noise(0.0, sigma);
  Scan scan;
  scan.units = "mm";
  scan.points.resize(3, count);
  scan.normals.resize(3, count);
  for (int i = 0; i < count; ++i) {
    const double z = i < 100 ? 0.0 : i < 200 ? 100.0 : height(rng);
    const double a = i < 200 ? 2 * M_PI * (i % 100) / 100.0 : angle(rng);
    const Eigen::Vector3d n = Eigen::Vector3d(std::cos(a), std::sin(a), -PotSlope(z)).normalized();
    scan.points.col(i) = Eigen::Vector3d(PotRadius(z) * std::cos(a), PotRadius(z) * std::sin(a), z) +
                         (sigma > 0 ? noise(rng) : 0.0) * n;
    scan.normals.col(i) = n;
  }
  const fs::path path = dir / (name + ".ply");
  WritePly(path, scan);
  return path;
}

pipeline::FitOutcome FitPot(const fs::path& file, const std::string& fill_height = "") {
  pipeline::FitOptions o;
  o.file = file.string();
  o.model = "revolution";
  o.interactive = false;
  if (!fill_height.empty())
    pipeline::ApplyFitOption(*pipeline::FindManifestOption("fill_height"), fill_height, o);
  return pipeline::ComputeFit(o);
}

TEST(VesselVolume, NoiseFreePotMatchesTheAnalyticVolume) {
  const pipeline::FitOutcome outcome = FitPot(WritePot("exact", 6000, 0.0, 1u), "40");
  const nlohmann::json& v = outcome.document.at("vessel");
  EXPECT_NEAR(v.at("height").get<double>(), 100.0, 0.01);
  const double volume = v.at("volume").get<double>(), truth = PotVolume(0.0, 100.0);
  EXPECT_NEAR(volume, truth, 1e-3 * truth);
  EXPECT_NEAR(v.at("fill_volume").get<double>(), PotVolume(0.0, 40.0), 1e-3 * PotVolume(0.0, 40.0));
  EXPECT_EQ(v.at("fill_height").get<double>(), 40.0);
  EXPECT_NE(outcome.text.find("volume            "), std::string::npos) << outcome.text;
  EXPECT_NE(outcome.text.find("filled volume"), std::string::npos) << outcome.text;
  EXPECT_NE(pipeline::ReportHtml(outcome.document).find("volume up to 40"), std::string::npos);
  // A fill height above the rim: a note, the volume to the rim, no filled volume.
  const pipeline::FitOutcome above = FitPot(WritePot("exact", 6000, 0.0, 1u), "150");
  EXPECT_TRUE(above.document.at("vessel").at("fill_volume").is_null());
  ASSERT_FALSE(above.notes.empty());
  EXPECT_NE(above.notes.back().find("above the rim"), std::string::npos) << above.notes.back();
}

TEST(VesselVolume, NoisyPotIsWithinThreeStandardUncertainties) {
  // 0.05 mm noise: the uncertainty is propagated from the fit's shape covariance (eq. A4). The truth is the
  // pot's volume between the fitted profile's ends (the data reach z = 0 and 100 exactly; the fitted ends
  // are where the feet end, within the noise of them).
  for (unsigned seed = 1; seed <= 4; ++seed) {
    const nlohmann::json v = FitPot(WritePot("noisy", 6000, 0.05, seed)).document.at("vessel");
    const double u = v.at("volume_uncertainty").get<double>();
    const double base = v.at("base_centre").at(2).get<double>(), height = v.at("height").get<double>();
    const double truth = PotVolume(base, base + height);
    EXPECT_GT(u, 0.0);
    EXPECT_LT(u, 1e-3 * truth) << "seed " << seed;
    EXPECT_LT(std::abs(v.at("volume").get<double>() - truth), 3 * u)
        << "seed " << seed << ": volume " << v.at("volume") << " truth " << truth << " u " << u;
  }
}

TEST(VesselVolume, StandardizedErrorsOverTwoHundredPotsHaveUnitSpread) {
  // The GUM's law of propagation (eq. A4) checked by simulation through the command's path: 200 data sets of
  // the pot, 1000 points each with 0.05 mm noise; (V - V_true) / u(V), V_true the pot's volume between the
  // fitted ends, should have a standard deviation near 1 and no bias beyond chance.
  const int trials = 200;
  std::vector<double> standardized;
  for (int trial = 0; trial < trials; ++trial) {
    const nlohmann::json v =
        FitPot(WritePot("trial", 1000, 0.05, 1000u + static_cast<unsigned>(trial))).document.at("vessel");
    const double base = v.at("base_centre").at(2).get<double>(), height = v.at("height").get<double>();
    const double u = v.at("volume_uncertainty").get<double>();
    ASSERT_GT(u, 0.0) << "trial " << trial;
    standardized.push_back((v.at("volume").get<double>() - PotVolume(base, base + height)) / u);
  }
  double mean = 0.0, sd = 0.0;
  for (const double e : standardized) mean += e / trials;
  for (const double e : standardized) sd += (e - mean) * (e - mean) / (trials - 1);
  sd = std::sqrt(sd);
  std::cout << "standardized volume errors over " << trials << " pots: mean " << mean << ", SD " << sd
            << "\n";
  EXPECT_GE(sd, 0.8);
  EXPECT_LE(sd, 1.25);
  EXPECT_LT(std::abs(mean), 4.0 * sd / std::sqrt(static_cast<double>(trials)));
}

TEST(VesselVolume, MonteCarloAgreesWithTheLinearUncertaintiesOfTheDerivedQuantities) {
  // --uncertainty monte-carlo:N refits the whole joint fit N times to perturbed feet (docs/metrology.md
  // section 7a). On the noisy pot the volume is near-linear in the data: the two standard uncertainties agree
  // within 10 % plus the Monte Carlo estimate's own sampling error (1 / sqrt(2 N), 5 % at N = 200), the bound
  // of docs/metrology.md section 7's primitive test.
  const fs::path pot = WritePot("mc", 6000, 0.05, 7u);
  auto fit = [&](const std::string& method) {
    pipeline::FitOptions o;
    o.file = pot.string();
    o.model = "revolution";
    o.interactive = false;
    pipeline::ApplyFitOption(*pipeline::FindManifestOption("uncertainty"), method, o);
    return pipeline::ComputeFit(o);
  };
  const pipeline::FitOutcome linear = fit("linear"), mc = fit("monte-carlo:200");
  const nlohmann::json &l = linear.document.at("measurands"), &m = mc.document.at("measurands");
  ASSERT_EQ(l.size(), 3u);
  ASSERT_EQ(m.size(), 3u);
  const char* names[3] = {"rim diameter", "base diameter", "volume"};
  const char* keys[3] = {"rim_diameter", "base_diameter", "volume"};
  for (int k = 0; k < 3; ++k) {
    SCOPED_TRACE(names[k]);
    EXPECT_EQ(l[k].at("name"), names[k]);
    EXPECT_EQ(m[k].at("name"), names[k]);
    // The values are the vessel's, the linear u its reported one (k = 2).
    EXPECT_EQ(l[k].at("value").get<double>(), linear.document.at("vessel").at(keys[k]).get<double>());
    EXPECT_EQ(l[k].at("standard_uncertainty").get<double>(),
              linear.document.at("vessel").at(std::string(keys[k]) + "_uncertainty").get<double>());
    EXPECT_EQ(l[k].at("coverage_factor").get<double>(), 2.0);
    EXPECT_EQ(m[k].at("monte_carlo").at("trials").get<int>() +
                  m[k].at("monte_carlo").at("failed_trials").get<int>(),
              200);
    EXPECT_GT(m[k].at("standard_uncertainty").get<double>(), 0.0);
    std::cout << names[k] << ": linear u " << l[k].at("standard_uncertainty") << ", Monte Carlo u "
              << m[k].at("standard_uncertainty") << "\n";
  }
  const double ratio =
      m[2].at("standard_uncertainty").get<double>() / l[2].at("standard_uncertainty").get<double>();
  EXPECT_GT(ratio, 1.0 - 0.1 - 2 * 0.05);
  EXPECT_LT(ratio, 1.0 + 0.1 + 2 * 0.05);
  EXPECT_NE(mc.text.find("derived quantities"), std::string::npos);
  EXPECT_NE(mc.text.find("monte-carlo:200"), std::string::npos);
}

TEST(VesselOutline, EllipticFourierDescriptorsOfTheMirroredProfile) {
  // --efd 8: the outline (profile and mirror) as 8 normalized harmonics. The outline is symmetric about the
  // axis, so every b_n and c_n vanishes; the first harmonic is (1, 0, 0, d1) with |d1| < 1. Another model
  // refuses the option.
  pipeline::FitOptions o;
  o.file = WritePot("efd", 3000, 0.05, 3u).string();
  o.model = "revolution";
  o.interactive = false;
  pipeline::ApplyFitOption(*pipeline::FindManifestOption("efd"), "8", o);
  const nlohmann::json document = pipeline::ComputeFit(o).document;
  const nlohmann::json& efd = document.at("vessel").at("outline_efd");
  EXPECT_EQ(efd.at("harmonics").get<int>(), 8);
  const nlohmann::json& rows = efd.at("coefficients");
  ASSERT_EQ(rows.size(), 8u);
  EXPECT_NEAR(rows[0][0].get<double>(), 1.0, 1e-12);
  EXPECT_LT(std::abs(rows[0][3].get<double>()), 1.0);
  EXPECT_GT(std::abs(rows[0][3].get<double>()), 0.1);
  for (const auto& row : rows) {
    EXPECT_LT(std::abs(row[1].get<double>()), 1e-9);
    EXPECT_LT(std::abs(row[2].get<double>()), 1e-9);
  }
  // A batch's summary has them as the columns efd_1_a .. efd_8_d.
  int columns = 0;
  for (const nlohmann::json& p : pipeline::FlatParameters(document))
    if (p.at("name").get<std::string>().rfind("efd_", 0) == 0) ++columns;
  EXPECT_EQ(columns, 32);
  o.model = "cylinder";
  EXPECT_THROW(pipeline::ComputeFit(o), pipeline::FitFailure);
}

TEST(VesselVolume, OtherModelsRefuseTheFillHeight) {
  pipeline::FitOptions o;
  o.file = WritePot("exact", 600, 0.0, 1u).string();
  o.model = "cylinder";
  pipeline::ApplyFitOption(*pipeline::FindManifestOption("fill_height"), "10", o);
  try {
    pipeline::ComputeFit(o);
    ADD_FAILURE() << "no error";
  } catch (const pipeline::FitFailure& e) {
    EXPECT_EQ(e.exit_code(), pipeline::kUsage);
    EXPECT_NE(std::string(e.what()).find("--fill-height"), std::string::npos) << e.what();
  }
}

TEST(VesselRoundness, OvalPotIsMeasuredBandByBandAndASherdIsNotResolved) {
  // The pot made oval: every radius gains 0.4 cos 2 t (mm), so each band's diameters differ by 1.6 mm.
  // The fitted surface of revolution takes the mean radius; the deviations keep the oval, which every
  // resolved band measures within 3 of its standard uncertainties.
  const fs::path dir = fs::temp_directory_path() / "s2m_vessel_measures_test";
  fs::create_directories(dir);
  std::mt19937 rng(3u);
  std::uniform_real_distribution<double> height(0.0, 100.0), angle(0.0, 2 * M_PI);
  std::normal_distribution<double> noise(0.0, 0.05);
  Scan scan;
  scan.units = "mm";
  const int count = 6000;
  scan.points.resize(3, count);
  scan.normals.resize(3, count);
  for (int i = 0; i < count; ++i) {
    const double z = height(rng), a = angle(rng);
    const double r = PotRadius(z) + 0.4 * std::cos(2 * a) + noise(rng);
    scan.points.col(i) << r * std::cos(a), r * std::sin(a), z;
    scan.normals.col(i) = Eigen::Vector3d(std::cos(a), std::sin(a), -PotSlope(z)).normalized();
  }
  WritePly(dir / "oval.ply", scan);
  const pipeline::FitOutcome outcome = FitPot(dir / "oval.ply");
  const nlohmann::json& bands = outcome.document.at("vessel").at("roundness").at("bands");
  ASSERT_EQ(bands.size(), 10u);
  for (const nlohmann::json& b : bands) {
    ASSERT_TRUE(b[6].is_number()) << b;
    EXPECT_NEAR(b[6].get<double>(), 1.6, 3 * b[7].get<double>()) << b;
  }
  EXPECT_NE(outcome.text.find("ovality up to"), std::string::npos) << outcome.text;
  EXPECT_NE(pipeline::ReportHtml(outcome.document).find("Out of round"), std::string::npos);
  // A third of the pot (a sherd's arc): no band is resolved, and the text says why.
  Scan sherd;
  sherd.units = "mm";
  for (int i = 0; i < count; ++i)
    if (std::atan2(scan.points(1, i), scan.points(0, i)) > 0 &&
        std::atan2(scan.points(1, i), scan.points(0, i)) < 2 * M_PI / 3) {
      sherd.points.conservativeResize(3, sherd.points.cols() + 1);
      sherd.normals.conservativeResize(3, sherd.normals.cols() + 1);
      sherd.points.col(sherd.points.cols() - 1) = scan.points.col(i);
      sherd.normals.col(sherd.normals.cols() - 1) = scan.normals.col(i);
    }
  WritePly(dir / "sherd.ply", sherd);
  const pipeline::FitOutcome part = FitPot(dir / "sherd.ply");
  for (const nlohmann::json& b : part.document.at("vessel").at("roundness").at("bands"))
    EXPECT_TRUE(b[6].is_null()) << b;
  EXPECT_NE(part.text.find("not resolved"), std::string::npos) << part.text;
}

}  // namespace
}  // namespace s2m
