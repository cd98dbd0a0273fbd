// EstimateCovariance (fitting/covariance.h): the gauge-aware covariance of a least-squares estimate against
// closed forms (straight-line regression), on a rank-deficient information matrix and in its weighted form.

#include "fitting/covariance.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>

namespace s2m {
namespace {

struct Line {
  Eigen::VectorXd x, y;
};

// y = 2 + 0.5 x + noise at x = 0 .. n-1.
Line NoisyLine(int n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.1);
  Line line{Eigen::VectorXd(n), Eigen::VectorXd(n)};
  for (int i = 0; i < n; ++i) {
    line.x[i] = i;
    line.y[i] = 2.0 + 0.5 * i + noise(rng);
  }
  return line;
}

// The design matrix [1 x] of y = a + b x.
Eigen::MatrixXd Design(const Eigen::VectorXd& x) {
  Eigen::MatrixXd j(x.size(), 2);
  j.col(0).setOnes();
  j.col(1) = x;
  return j;
}

TEST(Covariance, StraightLineRegressionMatchesTheClosedForm) {
  const Line line = NoisyLine(25, 3);
  const Eigen::MatrixXd j = Design(line.x);
  const Eigen::MatrixXd information = j.transpose() * j;
  const Eigen::Vector2d ab = information.ldlt().solve(j.transpose() * line.y);
  const double sum_of_squares = (line.y - j * ab).squaredNorm();
  const CovarianceEstimate estimate = EstimateCovariance(information, sum_of_squares, 25.0);

  // Textbook closed form of the straight line: s^2 = SSR / (n - 2), var b = s^2 / Sxx, var a = s^2 (1/n +
  // xbar^2 / Sxx), cov(a, b) = -xbar s^2 / Sxx with Sxx = sum (x - xbar)^2.
  const double n = 25.0, xbar = line.x.mean();
  const double sxx = (line.x.array() - xbar).square().sum();
  const double s2 = sum_of_squares / (n - 2.0);
  EXPECT_EQ(estimate.degrees_of_freedom, 23);
  EXPECT_NEAR(estimate.variance, s2, 1e-15 * s2);
  ASSERT_EQ(estimate.covariance.rows(), 2);
  EXPECT_NEAR(estimate.covariance(1, 1), s2 / sxx, 1e-12 * s2 / sxx);
  EXPECT_NEAR(estimate.covariance(0, 0), s2 * (1.0 / n + xbar * xbar / sxx), 1e-12 * s2);
  EXPECT_NEAR(estimate.covariance(0, 1), -xbar * s2 / sxx, 1e-12 * s2);
  EXPECT_NEAR(estimate.covariance(1, 0), estimate.covariance(0, 1), 1e-15 * s2);
  EXPECT_NEAR(estimate.standard_uncertainty[1], std::sqrt(s2 / sxx), 1e-12 * std::sqrt(s2 / sxx));
  EXPECT_TRUE(estimate.null_directions.empty());
  EXPECT_EQ(estimate.null_share.size(), 2);
  EXPECT_EQ(estimate.null_share.norm(), 0.0);
  // The same as the plain inverse (the primitive fits' former FullPivLU) to rounding.
  const Eigen::MatrixXd plain = s2 * information.fullPivLu().inverse();
  EXPECT_LE((estimate.covariance - plain).norm(), 1e-12 * plain.norm());
}

TEST(Covariance, RankDeficientInformationGivesNanExactlyOnTheTouchedParameters) {
  // y = a + b + c x: a and b only ever appear as their sum, so (1, -1, 0) is a null direction; c stays
  // determined with the straight line's variance s^2 / Sxx.
  const Line line = NoisyLine(30, 5);
  Eigen::MatrixXd j(30, 3);
  j.col(0).setOnes();
  j.col(1).setOnes();
  j.col(2) = line.x;
  const Eigen::MatrixXd information = j.transpose() * j;
  const Eigen::MatrixXd line_design = Design(line.x);
  const Eigen::Vector2d ab =
      (line_design.transpose() * line_design).ldlt().solve(line_design.transpose() * line.y);
  const double sum_of_squares = (line.y - line_design * ab).squaredNorm();
  const CovarianceEstimate estimate = EstimateCovariance(information, sum_of_squares, 30.0);

  ASSERT_EQ(estimate.null_directions.size(), 1u);
  const Eigen::Vector3d expected = Eigen::Vector3d(1.0, -1.0, 0.0) / std::sqrt(2.0);
  EXPECT_NEAR(std::abs(estimate.null_directions[0].dot(expected)), 1.0, 1e-12);
  EXPECT_NEAR(estimate.null_share[0], 0.5, 1e-12);
  EXPECT_NEAR(estimate.null_share[1], 0.5, 1e-12);
  EXPECT_NEAR(estimate.null_share[2], 0.0, 1e-12);
  // Three unknowns count against the degrees of freedom, the null direction included.
  EXPECT_EQ(estimate.degrees_of_freedom, 27);
  const double s2 = sum_of_squares / 27.0;
  EXPECT_NEAR(estimate.variance, s2, 1e-15 * s2);
  ASSERT_EQ(estimate.standard_uncertainty.size(), 3);
  EXPECT_TRUE(std::isnan(estimate.standard_uncertainty[0]));
  EXPECT_TRUE(std::isnan(estimate.standard_uncertainty[1]));
  ASSERT_TRUE(std::isfinite(estimate.standard_uncertainty[2]));
  const double sxx = (line.x.array() - line.x.mean()).square().sum();
  EXPECT_NEAR(estimate.standard_uncertainty[2], std::sqrt(s2 / sxx), 1e-9 * std::sqrt(s2 / sxx));
  // The pseudo-inverse: no variance along the null direction; the sum a + b keeps the line's intercept
  // variance s^2 (1/n + xbar^2 / Sxx).
  EXPECT_LE((estimate.covariance * expected).norm(), 1e-12 * estimate.covariance.norm());
  const Eigen::Vector3d sum(1.0, 1.0, 0.0);
  const double xbar = line.x.mean();
  EXPECT_NEAR(sum.dot(estimate.covariance * sum), s2 * (1.0 / 30.0 + xbar * xbar / sxx), 1e-9 * s2);
}

TEST(Covariance, IntegerWeightsEqualRepeatedObservations) {
  // The weighted form (W = weights, n_eff = sum w) with weights 1, 2, 3 must equal the unweighted estimate
  // of the data with every observation repeated w times.
  const Line line = NoisyLine(12, 7);
  Eigen::VectorXd w(12);
  for (int i = 0; i < 12; ++i) w[i] = 1 + i % 3;
  const Eigen::MatrixXd j = Design(line.x);
  const Eigen::MatrixXd information = j.transpose() * w.asDiagonal() * j;
  const Eigen::Vector2d ab = information.ldlt().solve(j.transpose() * w.asDiagonal() * line.y);
  const Eigen::VectorXd d = line.y - j * ab;
  const double weighted = (w.array() * d.array().square()).sum();
  const CovarianceEstimate estimate = EstimateCovariance(information, weighted, w.sum());

  const int repeated = static_cast<int>(w.sum());
  Eigen::VectorXd x(repeated), y(repeated);
  int k = 0;
  for (int i = 0; i < 12; ++i) {
    for (int c = 0; c < static_cast<int>(w[i]); ++c, ++k) {
      x[k] = line.x[i];
      y[k] = line.y[i];
    }
  }
  const Eigen::MatrixXd jr = Design(x);
  const Eigen::MatrixXd information_r = jr.transpose() * jr;
  const Eigen::Vector2d ab_r = information_r.ldlt().solve(jr.transpose() * y);
  const CovarianceEstimate plain =
      EstimateCovariance(information_r, (y - jr * ab_r).squaredNorm(), static_cast<double>(repeated));

  EXPECT_EQ(estimate.degrees_of_freedom, repeated - 2);
  EXPECT_NEAR(estimate.variance, plain.variance, 1e-12 * plain.variance);
  EXPECT_LE((estimate.covariance - plain.covariance).norm(), 1e-12 * plain.covariance.norm());
  // Fractional weights: n_eff - p need not be an integer; the variance uses it as it is.
  const CovarianceEstimate fractional = EstimateCovariance(information, weighted, 10.5);
  EXPECT_EQ(fractional.degrees_of_freedom, 8);
  EXPECT_NEAR(fractional.variance, weighted / 8.5, 1e-15 * weighted);
}

TEST(Covariance, NoDegreesOfFreedomGiveNoCovarianceButStillTheNullDirections) {
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
  information(0, 0) = 2.0;
  information(1, 1) = 1.0;  // the third parameter is not observed at all
  const CovarianceEstimate estimate = EstimateCovariance(information, 1.0, 3.0);
  EXPECT_EQ(estimate.degrees_of_freedom, 0);
  EXPECT_TRUE(std::isnan(estimate.variance));
  EXPECT_EQ(estimate.covariance.size(), 0);
  EXPECT_EQ(estimate.standard_uncertainty.size(), 0);
  ASSERT_EQ(estimate.null_directions.size(), 1u);
  EXPECT_NEAR(std::abs(estimate.null_directions[0][2]), 1.0, 1e-15);
  EXPECT_NEAR(estimate.null_share[2], 1.0, 1e-15);
}

}  // namespace
}  // namespace s2m
