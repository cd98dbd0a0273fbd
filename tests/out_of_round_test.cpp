// MeasureRoundnessBands and RadialDeviations (fitting/out_of_round.h, docs/archaeology.md eqs. A5-A9): an
// oval, leaning and three-lobed band recovered from noisy deviations within 3 standard uncertainties, the
// uncertainties checked by simulation, partial arcs (sherds) and sparse bands left unresolved, normal
// deviations turned radial on cones, bad arguments refused.

#include "fitting/out_of_round.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

namespace s2m {
namespace {

struct Band {
  Eigen::Matrix3Xd points;
  Eigen::VectorXd deviations;
};

// Points on z in [0, 10) at radius 50, angles uniform in [0, arc), deviations e2 cos 2(t - 0.3) + shift cos
// (t - 1) + e3 cos 3t plus Gaussian noise sigma.
Band MakeBand(int count, double arc, double e2, double shift, double e3, double sigma, std::mt19937& rng) {
  std::uniform_real_distribution<double> angle(0.0, arc), height(0.0, 10.0);
  std::normal_distribution<double> noise(0.0, sigma);
  Band b;
  b.points.resize(3, count);
  b.deviations.resize(count);
  for (int i = 0; i < count; ++i) {
    const double t = angle(rng);
    b.points.col(i) << 50 * std::cos(t), 50 * std::sin(t), height(rng);
    b.deviations[i] =
        e2 * std::cos(2 * (t - 0.3)) + shift * std::cos(t - 1.0) + e3 * std::cos(3 * t) + noise(rng);
  }
  return b;
}

TEST(OutOfRound, RecoversOvalityOffsetAndLobesWithinTheirUncertainties) {
  std::mt19937 rng(11u);
  // Oval by 0.5 mm (diameters differ by 2 mm), centre 0.2 mm off, lobes of 0.1 mm, noise 0.05 mm.
  const Band b = MakeBand(2000, 2 * M_PI, 0.5, 0.2, 0.1, 0.05, rng);
  const std::vector<RoundnessBand> bands = MeasureRoundnessBands(b.points, b.deviations, 0.0, 10.0, 1);
  ASSERT_EQ(bands.size(), 1u);
  const RoundnessBand& r = bands[0];
  ASSERT_TRUE(r.resolved);
  EXPECT_EQ(r.points, 2000);
  EXPECT_NEAR(r.ovality, 2.0, 3 * r.ovality_uncertainty);
  EXPECT_NEAR(r.centre_offset, 0.2, 3 * r.centre_offset_uncertainty);
  EXPECT_LT(r.ovality_uncertainty, 0.02);
  // Harmonics 2 and 3 together: the peak-to-valley of 0.5 cos 2(t - 0.3) + 0.1 cos 3t on a fine grid.
  double lo = 1e9, hi = -1e9;
  for (int s = 0; s < 100000; ++s) {
    const double t = 2 * M_PI * s / 100000, v = 0.5 * std::cos(2 * (t - 0.3)) + 0.1 * std::cos(3 * t);
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  EXPECT_NEAR(r.out_of_round, hi - lo, 0.02);
  EXPECT_NEAR(r.residual_rms, 0.05, 0.005);
}

TEST(OutOfRound, OvalityUncertaintyMatchesItsSpreadOverTrials) {
  // A clearly oval band (amplitude 40 times its uncertainty, so the amplitude is near-linear in (a2, b2)):
  // the standardized errors of the ovality over 200 trials have a standard deviation near 1.
  std::mt19937 rng(5u);
  std::vector<double> e;
  for (int trial = 0; trial < 200; ++trial) {
    const Band b = MakeBand(400, 2 * M_PI, 0.1, 0.0, 0.0, 0.05, rng);
    const RoundnessBand r = MeasureRoundnessBands(b.points, b.deviations, 0.0, 10.0, 1)[0];
    e.push_back((r.ovality - 0.4) / r.ovality_uncertainty);
  }
  const double n = static_cast<double>(e.size());
  double mean = 0, sd = 0;
  for (const double x : e) mean += x / n;
  for (const double x : e) sd += (x - mean) * (x - mean) / (n - 1);
  sd = std::sqrt(sd);
  EXPECT_GE(sd, 0.8);
  EXPECT_LE(sd, 1.25);
  EXPECT_LT(std::abs(mean), 0.3);
}

TEST(OutOfRound, PartialArcsAndSparseBandsAreNotResolved) {
  std::mt19937 rng(2u);
  // A sherd's 40 % of the circumference: a gap of 216 degrees.
  const Band sherd = MakeBand(2000, 0.4 * 2 * M_PI, 0.5, 0.0, 0.0, 0.05, rng);
  const RoundnessBand r = MeasureRoundnessBands(sherd.points, sherd.deviations, 0.0, 10.0, 1)[0];
  EXPECT_FALSE(r.resolved);
  EXPECT_NEAR(r.largest_gap, 0.6 * 2 * M_PI, 0.01);
  EXPECT_TRUE(std::isnan(r.ovality));
  // Two bands, the upper one empty; and a band of 20 points.
  const Band full = MakeBand(2000, 2 * M_PI, 0.5, 0.0, 0.0, 0.05, rng);
  const std::vector<RoundnessBand> two = MeasureRoundnessBands(full.points, full.deviations, 0.0, 20.0, 2);
  EXPECT_TRUE(two[0].resolved);
  EXPECT_FALSE(two[1].resolved);
  EXPECT_EQ(two[1].points, 0);
  const Band sparse = MakeBand(20, 2 * M_PI, 0.5, 0.0, 0.0, 0.05, rng);
  EXPECT_FALSE(MeasureRoundnessBands(sparse.points, sparse.deviations, 0.0, 10.0, 1)[0].resolved);
}

TEST(OutOfRound, RadialDeviationsFromNormalOnes) {
  // A cone rho = 10 + s z (slope s): a point d along the normal (1, -s) / sqrt(1 + s^2) from its foot is
  // d sqrt(1 + s^2) off the radius at its own height (eq. A9). Slope 3 (within 60 degrees of horizontal):
  // NaN. A zero deviation stays zero.
  for (const double slope : {0.0, 0.5, -0.7, 3.0}) {
    Eigen::Matrix3Xd points(3, 3), feet(3, 3);
    Eigen::VectorXd d(3);
    const double norm = std::sqrt(1 + slope * slope);
    for (int i = 0; i < 3; ++i) {
      const double z = 2.0 * i, t = 0.7 * i, rho = 10 + slope * z;
      d[i] = i == 2 ? 0.0 : (i == 0 ? 0.3 : -0.2);
      feet.col(i) << rho * std::cos(t), rho * std::sin(t), z;
      points.col(i) << (rho + d[i] / norm) * std::cos(t), (rho + d[i] / norm) * std::sin(t),
          z - slope * d[i] / norm;
    }
    const Eigen::VectorXd radial = RadialDeviations(points, feet, d);
    for (int i = 0; i < 2; ++i) {
      if (std::abs(slope) > std::sqrt(3.0)) {
        EXPECT_TRUE(std::isnan(radial[i])) << slope;
      } else {
        EXPECT_NEAR(radial[i], d[i] * norm, 1e-12) << slope;
      }
    }
    EXPECT_EQ(radial[2], 0.0);
  }
  EXPECT_THROW(
      RadialDeviations(Eigen::Matrix3Xd::Zero(3, 2), Eigen::Matrix3Xd::Zero(3, 1), Eigen::VectorXd::Zero(2)),
      std::invalid_argument);
}

TEST(OutOfRound, RefusesBadArguments) {
  const Eigen::Matrix3Xd points = Eigen::Matrix3Xd::Zero(3, 4);
  EXPECT_THROW(MeasureRoundnessBands(points, Eigen::VectorXd::Zero(3), 0, 1, 1), std::invalid_argument);
  EXPECT_THROW(MeasureRoundnessBands(points, Eigen::VectorXd::Zero(4), 0, 1, 0), std::invalid_argument);
  EXPECT_THROW(MeasureRoundnessBands(points, Eigen::VectorXd::Zero(4), 1, 1, 1), std::invalid_argument);
}

}  // namespace
}  // namespace s2m
