// A shell's whorls and the test of the logarithmic spiral against the allometric one (pipeline/
// shell_growth.h, docs/shells.md sections 2-3), through the command's own path (ComputeFit): logarithmic
// shells are called logarithmic and their whorls measured; allometric shells are called allometric, with
// q and a recovered.

#include "pipeline/shell_growth.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "fitting/kinematic_surfaces.h"
#include "pipeline/batch.h"
#include "pipeline/fit_options.h"
#include "registration/scan.h"
#include "synthetic/synthetic_cases.h"

namespace s2m {
namespace {

constexpr int kPoints = 12000;
constexpr double kNoise = 0.02;

pipeline::FitOutcome FitShell(const Eigen::Matrix3Xd& points) {
  auto set = std::make_shared<ScanSet>();
  Scan scan;
  scan.units = "mm";
  scan.points = points;
  set->scans.push_back(scan);
  pipeline::FitOptions o;
  o.file = "shell";
  o.views = set;
  o.model = "spiral";
  o.interactive = false;
  return pipeline::ComputeFit(o);
}

int Seeds() {
  const char* env = std::getenv("S2M_SHELL_SEEDS");
  return env ? std::max(1, std::atoi(env)) : 2;
}

// The last whorl's height, width, umbilical width and diameter against the truth's at the data's last angle
// (3 pi), within 3 standard uncertainties plus what the data's end can tell: the points sample the coil at
// random, so the last angle is found to within about 4 pi / kPoints radians, a relative g' 4 pi / kPoints of
// a whorl's size (g' the local growth rate; 1.3e-4 here).
void ExpectLastWhorl(const nlohmann::json& row, const SpiralSurface& truth) {
  const SpiralSurface::Whorl last = truth.WhorlAt(3 * M_PI);
  const double rate = truth.growth() + truth.growth_change() * (3 * M_PI - truth.allometry_reference()) +
                      std::abs(truth.axial_excess());
  const double end_error = rate * 4 * M_PI / kPoints;
  for (const auto& [key, expected] : {std::pair<const char*, double>{"height", last.height},
                                      {"width", last.width},
                                      {"umbilical_width", last.umbilical_width},
                                      {"diameter", last.diameter}}) {
    const double value = row[key]["value"].get<double>(), u = row[key]["uncertainty"].get<double>();
    std::printf("  last whorl %s %.4f +- %.2g (truth %.4f)\n", key, value, u, expected);
    EXPECT_LT(std::abs(value - expected), 3 * u + end_error * expected) << key;
  }
}

// Logarithmic shells (q = a = 0), two whorls, 0.02 mm noise: the test says the model holds, and the last
// whorl's height, width, umbilical width and diameter agree with the truth's (ExpectLastWhorl).
TEST(ShellGrowth, LogarithmicShellHoldsAndItsWhorlsAreMeasured) {
  for (int seed = 1; seed <= Seeds(); ++seed) {
    const KinematicCloud cloud =
        AllometricShellCloud(0.0, 0.0, kNoise, kPoints, static_cast<std::uint64_t>(seed));
    const pipeline::FitOutcome outcome = FitShell(cloud.points);
    const nlohmann::json& growth = outcome.document["growth"];
    const nlohmann::json& allometry = growth["allometry"];
    std::printf("seed %d: growth %.6f +- %.2g, q %.3g +- %.2g, a %.3g +- %.2g, chi2 %.2f, %s\n", seed,
                growth["value"].get<double>(), growth["uncertainty"].get<double>(),
                allometry["growth_change"]["value"].get<double>(),
                allometry["growth_change"]["uncertainty"].get<double>(),
                allometry["axial_excess"]["value"].get<double>(),
                allometry["axial_excess"]["uncertainty"].get<double>(), allometry["chi2"].get<double>(),
                allometry["verdict"].get<std::string>().c_str());
    EXPECT_EQ(allometry["verdict"], "holds") << allometry["reason"];
    EXPECT_EQ(outcome.document["adequacy"]["adequate"], true);
    // About two whorls of data: rows at the last angle and a turn before it.
    const nlohmann::json& whorls = growth["whorls"];
    ASSERT_GE(whorls.size(), 2u);
    EXPECT_NEAR(growth["coiled_angle"].get<double>(), 4 * M_PI, 0.01);
    EXPECT_EQ(growth["whorls_surface"], "logarithmic");
    ExpectLastWhorl(whorls[0], dynamic_cast<const SpiralSurface&>(*cloud.truth));
    // A turn before, the whorl is smaller by the whorl expansion rate.
    EXPECT_NEAR(whorls[0]["width"]["value"].get<double>() / whorls[1]["width"]["value"].get<double>(),
                growth["whorl_expansion_rate"].get<double>(), 1e-6);
  }
}

// Allometric shells: the whorl expansion rate grows by e^{4 pi^2 q} = 1.17 per whorl and the whorl's
// height-to-width ratio by e^{2 pi a} = 1.10: the test says the logarithmic spiral does not hold, the fit
// is not adequate, q and a come back within 3 standard uncertainties, and the whorls are measured on the
// allometric surface, the last one as the truth's (ExpectLastWhorl).
TEST(ShellGrowth, AllometricShellIsToldAndItsAllometryRecovered) {
  const double q = 0.004, a = 0.015;
  for (int seed = 1; seed <= Seeds(); ++seed) {
    const KinematicCloud cloud =
        AllometricShellCloud(q, a, kNoise, kPoints, static_cast<std::uint64_t>(seed));
    const pipeline::FitOutcome outcome = FitShell(cloud.points);
    const nlohmann::json& allometry = outcome.document["growth"]["allometry"];
    const double q_fit = allometry["growth_change"]["value"].get<double>(),
                 q_u = allometry["growth_change"]["uncertainty"].get<double>(),
                 a_fit = allometry["axial_excess"]["value"].get<double>(),
                 a_u = allometry["axial_excess"]["uncertainty"].get<double>();
    std::printf(
        "seed %d: q %.5f +- %.2g (truth %g), a %.5f +- %.2g (truth %g), chi2 %.1f, RMS %.4f -> %.4f: %s\n",
        seed, q_fit, q_u, q, a_fit, a_u, a, allometry["chi2"].get<double>(),
        allometry["rms_logarithmic"].get<double>(), allometry["rms_allometric"].get<double>(),
        allometry["verdict"].get<std::string>().c_str());
    EXPECT_EQ(allometry["verdict"], "does not hold") << allometry["reason"];
    EXPECT_EQ(outcome.document["adequacy"]["adequate"], false);
    EXPECT_LT(std::abs(q_fit - q), 3 * q_u);
    EXPECT_LT(std::abs(a_fit - a), 3 * a_u);
    EXPECT_NEAR(allometry["expansion_rate_change_per_whorl"]["value"].get<double>(),
                std::exp(4 * M_PI * M_PI * q_fit), 1e-12);
    const nlohmann::json& growth = outcome.document["growth"];
    EXPECT_EQ(growth["whorls_surface"], "allometric");
    EXPECT_NEAR(growth["coiled_angle"].get<double>(), 4 * M_PI, 0.01);
    ASSERT_GE(growth["whorls"].size(), 2u);
    ExpectLastWhorl(growth["whorls"][0], dynamic_cast<const SpiralSurface&>(*cloud.truth));
  }
}

}  // namespace
}  // namespace s2m
