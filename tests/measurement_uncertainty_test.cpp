// GUM propagation (docs/metrology.md sections 6-8): the law of propagation against a closed form, the Monte
// Carlo summary's interval, the ISO 14253-1 decisions, and on cone fits the standardized errors of a derived
// quantity over 200 data sets and the agreement of linear and Monte Carlo uncertainties.

#include "fitting/measurement_uncertainty.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "fitting/primitive_fit.h"
#include "fitting/primitive_measurands.h"

namespace s2m {
namespace {

TEST(MeasurementUncertainty, LinearPropagationOfAProduct) {
  // y = p0 p1: u^2 = p1^2 V00 + p0^2 V11 + 2 p0 p1 V01 (JCGM 100:2008 eq. 13).
  Eigen::Vector2d p(3.0, -2.0);
  Eigen::Matrix2d v;
  v << 0.04, 0.01, 0.01, 0.09;
  const LinearPropagation r = PropagateLinear([](const Eigen::VectorXd& q) { return q[0] * q[1]; }, p, v);
  EXPECT_DOUBLE_EQ(r.value, -6.0);
  EXPECT_NEAR(r.standard_uncertainty, std::sqrt(4 * 0.04 + 9 * 0.09 + 2 * 3 * -2 * 0.01), 1e-9);
  EXPECT_NEAR(r.sensitivities[0], -2.0, 1e-9);
  EXPECT_NEAR(r.sensitivities[1], 3.0, 1e-9);
}

TEST(MeasurementUncertainty, MonteCarloSummaryAndInterval) {
  std::vector<double> values;
  for (int i = 1; i <= 1000; ++i) values.push_back(i);
  const MonteCarloSummary s = SummarizeMonteCarlo(values);
  EXPECT_DOUBLE_EQ(s.mean, 500.5);
  EXPECT_EQ(s.trials, 1000);
  // JCGM 101 7.7.2: the 25th and the 975th of 1000 sorted values.
  EXPECT_DOUBLE_EQ(s.interval_low, 25.0);
  EXPECT_DOUBLE_EQ(s.interval_high, 975.0);
  const ExpandedUncertainty e = ExpandMonteCarlo(s);
  EXPECT_DOUBLE_EQ(e.expanded, 475.0);
  EXPECT_NEAR(e.coverage_factor, 475.0 / s.standard_uncertainty, 1e-12);
  EXPECT_THROW(UncertaintyMethod::FromString("monte-carlo:5"), std::invalid_argument);
  EXPECT_THROW(UncertaintyMethod::FromString("bootstrap"), std::invalid_argument);
  EXPECT_EQ(UncertaintyMethod::FromString("monte-carlo:200").trials, 200);
}

TEST(MeasurementUncertainty, Iso14253Decisions) {
  const Specification two_sided{9.9, 10.1};
  EXPECT_EQ(DecideConformity(10.0, 0.05, two_sided), ConformityDecision::kConforms);
  EXPECT_EQ(DecideConformity(10.07, 0.05, two_sided), ConformityDecision::kNotDecidable);  // 10.07 > 10.05
  EXPECT_EQ(DecideConformity(10.13, 0.05, two_sided), ConformityDecision::kNotDecidable);  // 10.13 < 10.15
  EXPECT_EQ(DecideConformity(10.16, 0.05, two_sided), ConformityDecision::kDoesNotConform);
  EXPECT_EQ(DecideConformity(9.84, 0.05, two_sided), ConformityDecision::kDoesNotConform);
  EXPECT_STREQ(PlainVerdict(10.07, two_sided), "pass");
  EXPECT_STREQ(PlainVerdict(10.13, two_sided), "fail");
  // One-sided (a form error): only the upper limit.
  const Specification form{std::nullopt, 0.05};
  EXPECT_EQ(DecideConformity(0.01, 0.02, form), ConformityDecision::kConforms);
  EXPECT_EQ(DecideConformity(0.04, 0.02, form), ConformityDecision::kNotDecidable);
  EXPECT_EQ(DecideConformity(0.08, 0.02, form), ConformityDecision::kDoesNotConform);
  // An unknown U proves nothing; a zone narrower than 2U has no conformance zone.
  EXPECT_EQ(DecideConformity(10.0, std::nan(""), two_sided), ConformityDecision::kNotDecidable);
  EXPECT_EQ(DecideConformity(10.0, 0.2, two_sided), ConformityDecision::kNotDecidable);
  EXPECT_THROW(DecideConformity(1.0, 0.1, Specification{}), std::invalid_argument);
}

// Points on a cone (axis z through the origin, half-angle 0.3, section radius 20 at z = 0) between z = 0 and
// 30 over the full turn, with normal noise sigma along the surface normal.
Eigen::Matrix3Xd ConePoints(const Cone& cone, int n, double sigma, std::mt19937_64& random) {
  std::uniform_real_distribution<double> unit(0, 1);
  std::normal_distribution<double> noise(0, sigma);
  Eigen::Matrix3Xd x(3, n);
  const double t = std::tan(cone.half_angle);
  for (int i = 0; i < n; ++i) {
    const double z = 30 * unit(random), phi = 2 * 3.14159265358979 * unit(random);
    const double r = cone.radius + t * z;
    const Eigen::Vector3d radial(std::cos(phi), std::sin(phi), 0);
    const Eigen::Vector3d normal =
        (radial * std::cos(cone.half_angle) - Eigen::Vector3d::UnitZ() * std::sin(cone.half_angle));
    x.col(i) = r * radial + z * Eigen::Vector3d::UnitZ() + noise(random) * normal;
  }
  return x;
}

// The diameter at a fixed station (z = 15) of fitted cones: over 200 data sets its standardized errors
// (fit - truth) / u_linear have a standard deviation within [0.8, 1.25] (an unbiased, correctly scaled
// uncertainty; the SD's own sampling error is about 0.05 at 200 trials).
TEST(MeasurementUncertainty, StandardizedErrorsOfAConeDiameterOver200DataSets) {
  Cone truth;
  truth.half_angle = 0.3;
  truth.radius = 20;
  MeasurandContext context;
  context.station = Eigen::Vector3d(0, 0, 15);
  const double true_diameter = Measurands(truth, context)[0];
  std::mt19937_64 random(42);
  std::vector<double> z;
  for (int trial = 0; trial < 200; ++trial) {
    const Eigen::Matrix3Xd x = ConePoints(truth, 300, 0.02, random);
    PrimitiveFitOptions options;
    options.record_history = false;
    const PrimitiveFit<Cone> fit = RefineCone(x, truth, options);
    const LinearPropagation d = PropagateMeasurands(fit.shape, x, context)[0];
    ASSERT_GT(d.standard_uncertainty, 0);
    z.push_back((d.value - true_diameter) / d.standard_uncertainty);
  }
  double mean = 0, ss = 0;
  for (double v : z) mean += v / 200;
  for (double v : z) ss += (v - mean) * (v - mean);
  const double sd = std::sqrt(ss / 199);
  std::printf("standardized errors of the cone diameter: mean %.3f, sd %.3f over 200 data sets\n", mean, sd);
  EXPECT_GE(sd, 0.8);
  EXPECT_LE(sd, 1.25);
  EXPECT_LT(std::abs(mean), 4 * sd / std::sqrt(200.0));
}

// Linear and Monte Carlo (GUM-S1, refitting 400 perturbed data sets) standard uncertainties of the cone's
// diameter agree within 10 % (the MC estimate's own relative sampling error is 1/sqrt(2 x 400) = 3.5 %).
TEST(MeasurementUncertainty, LinearAndMonteCarloAgreeForANearLinearMeasurand) {
  Cone truth;
  truth.half_angle = 0.3;
  truth.radius = 20;
  std::mt19937_64 random(7);
  const Eigen::Matrix3Xd x = ConePoints(truth, 400, 0.02, random);
  PrimitiveFitOptions options;
  options.record_history = false;
  const Cone fit = RefineCone(x, truth, options).shape;
  MeasurandContext context;
  context.station = Eigen::Vector3d(0, 0, 15);
  const LinearPropagation linear = PropagateMeasurands(fit, x, context)[0];
  const double sigma = ResidualStandardDeviation(fit, x);
  EXPECT_NEAR(sigma, 0.02, 0.003);
  const std::vector<MonteCarloSummary> mc = MonteCarloByRefitting<Cone>(
      fit, x, sigma, 400, 1,
      [&](const Cone& refit, const Eigen::Matrix3Xd&) { return Measurands(refit, context); });
  ASSERT_EQ(mc.size(), 1u);
  std::printf("cone diameter: linear u %.6g, Monte Carlo u %.6g (ratio %.4f), 95 %% interval [%.6g, %.6g]\n",
              linear.standard_uncertainty, mc[0].standard_uncertainty,
              mc[0].standard_uncertainty / linear.standard_uncertainty, mc[0].interval_low,
              mc[0].interval_high);
  EXPECT_EQ(mc[0].failed_trials, 0);
  EXPECT_NEAR(mc[0].standard_uncertainty / linear.standard_uncertainty, 1.0, 0.10)
      << "linear " << linear.standard_uncertainty << ", Monte Carlo " << mc[0].standard_uncertainty;
  EXPECT_NEAR(mc[0].mean, linear.value, 4 * linear.standard_uncertainty / std::sqrt(400.0));
}

}  // namespace
}  // namespace s2m
