// The statistics of residual structure (fitting/residual_structure.h, docs/method.md section 17): the runs
// test and Moran's I against exact values (all permutations of small samples), against sequences of known
// structure, and their z-scores under the null over seeds.
#include "fitting/residual_structure.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <set>

#include "fitting/noise_estimate.h"

namespace s2m {
namespace {

TEST(RunsTest, CountsRunsAndIgnoresZeros) {
  Eigen::VectorXd v(9);
  v << 1, 2, 0, -1, -3, 4, 0, 5, -1;  // + + | - - | + + | -  -> 4 runs of 4 positives and 3 negatives
  const RunsTest t = SignRunsTest(v);
  EXPECT_EQ(t.positives, 4);
  EXPECT_EQ(t.negatives, 3);
  EXPECT_EQ(t.runs, 4);
  EXPECT_DOUBLE_EQ(t.expected_runs, 1 + 2.0 * 4 * 3 / 7);
}

// Eqs. 49-50 are the exact mean and variance over all orders: check them by enumerating every arrangement of
// 5 positives and 5 negatives.
TEST(RunsTest, MeanAndVarianceAreExactOverAllArrangements) {
  std::vector<double> signs = {-1, -1, -1, -1, -1, 1, 1, 1, 1, 1};
  double sum = 0, sum_squares = 0, count = 0;
  RunsTest any;
  do {
    const RunsTest t = SignRunsTest(Eigen::Map<const Eigen::VectorXd>(signs.data(), 10));
    sum += static_cast<double>(t.runs);
    sum_squares += static_cast<double>(t.runs * t.runs);
    count += 1;
    any = t;
  } while (std::next_permutation(signs.begin(), signs.end()));
  EXPECT_EQ(count, 252);  // 10 choose 5
  const double mean = sum / count;
  EXPECT_NEAR(any.expected_runs, mean, 1e-12);
  EXPECT_NEAR(any.variance, sum_squares / count - mean * mean, 1e-12);
}

TEST(RunsTest, BlocksAndAlternationAreTheExtremes) {
  Eigen::VectorXd blocks(200), alternating(200);
  for (int i = 0; i < 200; ++i) {
    blocks[i] = i < 100 ? 1.0 : -1.0;
    alternating[i] = i % 2 == 0 ? 1.0 : -1.0;
  }
  const RunsTest b = SignRunsTest(blocks), a = SignRunsTest(alternating);
  EXPECT_EQ(b.runs, 2);
  EXPECT_LT(b.z, -13);  // (2 - 101) / sqrt(49.75)
  EXPECT_NEAR(b.sign_correlation, 1 - 1.0 / 100, 1e-12);
  EXPECT_EQ(a.runs, 200);
  EXPECT_GT(a.z, 13);
  EXPECT_NEAR(a.sign_correlation, 1 - 199.0 / 100, 1e-12);  // -0.99
}

TEST(RunsTest, TooFewSignsGiveNoStatistic) {
  Eigen::VectorXd v(5);
  v << 1, 1, 1, -1, 1;
  EXPECT_TRUE(std::isnan(SignRunsTest(v).z));
}

// Under the null (iid noise) z is approximately standard normal: over 400 seeds of 500 values the mean of z
// is within 4 standard errors (4 / sqrt(400) = 0.2) of 0 and its standard deviation within 0.15 of 1 (the
// standard error of a sample standard deviation of 400 is about 0.035; the normal approximation of a
// discrete count adds a little).
TEST(RunsTest, ZIsStandardNormalForIidNoise) {
  std::vector<double> z;
  for (int seed = 0; seed < 400; ++seed) {
    std::mt19937 rng(static_cast<unsigned>(seed));
    std::normal_distribution<double> noise(0.0, 1.0);
    Eigen::VectorXd v(500);
    for (Eigen::Index i = 0; i < v.size(); ++i) v[i] = noise(rng);
    z.push_back(SignRunsTest(v).z);
  }
  const double mean = std::accumulate(z.begin(), z.end(), 0.0) / static_cast<double>(z.size());
  double var = 0;
  for (double x : z) var += (x - mean) * (x - mean) / static_cast<double>(z.size() - 1);
  EXPECT_NEAR(mean, 0.0, 0.2);
  EXPECT_NEAR(std::sqrt(var), 1.0, 0.15);
}

// E[I] and Var[I] under randomization (eqs. 64-65) are the exact first two moments of I over all
// permutations of the values on a fixed neighbour graph: check on 7 values (5040 permutations) with a graph
// that has one-way and mutual pairs and unequal degrees, and skewed, heavy-tailed values (b2 matters).
TEST(MoransI, ExpectationAndVarianceAreExactOverAllPermutations) {
  const std::vector<std::vector<Eigen::Index>> graph = {{1, 2}, {0}, {3, 4, 5}, {2}, {6}, {0, 6}, {5, 1}};
  std::vector<double> values = {-3.0, -0.5, 0.1, 0.4, 0.7, 1.0, 9.0};
  std::sort(values.begin(), values.end());
  double sum = 0, sum_squares = 0, count = 0;
  MoranTest any;
  do {
    const MoranTest t = MoransI(graph, Eigen::Map<const Eigen::VectorXd>(values.data(), 7));
    sum += t.statistic;
    sum_squares += t.statistic * t.statistic;
    count += 1;
    any = t;
  } while (std::next_permutation(values.begin(), values.end()));
  EXPECT_EQ(count, 5040);
  const double mean = sum / count;
  EXPECT_NEAR(any.expected, mean, 1e-12);
  EXPECT_NEAR(any.variance, sum_squares / count - mean * mean, 1e-12);
}

// Points on a line, each with its two nearest neighbours: alternating values give I = -1 (every neighbour
// has the opposite value) up to the ends, two blocks give I close to +1.
TEST(MoransI, AlternationAndBlocksOnALine) {
  const int n = 200;
  Eigen::Matrix3Xd points = Eigen::Matrix3Xd::Zero(3, n);
  Eigen::VectorXd alternating(n), blocks(n);
  for (int i = 0; i < n; ++i) {
    points(0, i) = i + 0.001 * i * i / n;  // unequal spacing: no ties among neighbours
    alternating[i] = i % 2 == 0 ? 1.0 : -1.0;
    blocks[i] = i < n / 2 ? 1.0 : -1.0;
  }
  const MoranTest a = MoransI(points, alternating, 2), b = MoransI(points, blocks, 2);
  EXPECT_NEAR(a.statistic, -1.0, 0.02);
  EXPECT_LT(a.z, -10);
  EXPECT_GT(b.statistic, 0.95);
  EXPECT_GT(b.z, 10);
  EXPECT_EQ(b.neighbours, 2);
}

// A smooth field over a surface plus noise: I grows with the share of the smooth part in the variance (the
// effect size of docs/method.md section 17) and its z-score flags it.
TEST(MoransI, SmoothFieldIsClustered) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 1.0);
  const int n = 2000;
  Eigen::Matrix3Xd points(3, n);
  Eigen::VectorXd smooth(n), white(n);
  for (int i = 0; i < n; ++i) {
    points.col(i) << uniform(rng), uniform(rng), 0.0;
    smooth[i] = std::sqrt(2.0) * std::sin(2 * M_PI * points(0, i));  // variance 1
    white[i] = noise(rng);
  }
  const MoranTest only_noise = MoransI(points, white), mixed = MoransI(points, smooth + white);
  EXPECT_LT(std::abs(only_noise.z), 4);
  EXPECT_LT(std::abs(only_noise.statistic), 0.05);
  // Half the variance is smooth on the neighbours' scale: I close to 0.5.
  EXPECT_NEAR(mixed.statistic, 0.5, 0.08);
  EXPECT_GT(mixed.z, 20);
}

TEST(MoransI, ZIsStandardNormalForIidNoise) {
  std::vector<double> z;
  for (int seed = 0; seed < 200; ++seed) {
    std::mt19937 rng(static_cast<unsigned>(seed + 1000));
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    std::normal_distribution<double> noise(0.0, 1.0);
    Eigen::Matrix3Xd points(3, 400);
    Eigen::VectorXd v(400);
    for (Eigen::Index i = 0; i < 400; ++i) {
      points.col(i) << uniform(rng), uniform(rng), uniform(rng);
      v[i] = noise(rng);
    }
    z.push_back(MoransI(points, v).z);
  }
  const double mean = std::accumulate(z.begin(), z.end(), 0.0) / static_cast<double>(z.size());
  double var = 0;
  for (double x : z) var += (x - mean) * (x - mean) / static_cast<double>(z.size() - 1);
  // 200 seeds: standard error of the mean 0.07 (4 of them: 0.28), of the standard deviation 0.05.
  EXPECT_NEAR(mean, 0.0, 0.28);
  EXPECT_NEAR(std::sqrt(var), 1.0, 0.2);
}

TEST(MoransI, ConstantValuesOrTooFewPointsGiveNoStatistic) {
  const Eigen::Matrix3Xd points = Eigen::Matrix3Xd::Random(3, 50);
  EXPECT_TRUE(std::isnan(MoransI(points, Eigen::VectorXd::Constant(50, 2.0)).z));
  EXPECT_TRUE(std::isnan(MoransI(points.leftCols(5), Eigen::VectorXd::Random(5)).z));
}

// Successive cells of the Hilbert curve are face neighbours: on the full 2D grid of 16 x 16 cells (4 bits)
// every step of the order moves by exactly one cell, and the keys are a permutation of 0..255.
TEST(HilbertOrder, VisitsGridCellsAsNeighbours) {
  for (int dims : {2, 3}) {
    const int side = dims == 2 ? 16 : 8, bits = dims == 2 ? 4 : 3;
    const int n = dims == 2 ? side * side : side * side * side;
    Eigen::MatrixXd grid(dims, n);
    for (int i = 0; i < n; ++i) {
      grid(0, i) = i % side;
      grid(1, i) = (i / side) % side;
      if (dims == 3) grid(2, i) = i / (side * side);
    }
    const std::vector<std::uint64_t> keys = HilbertKeys(grid, bits);
    EXPECT_EQ(std::set<std::uint64_t>(keys.begin(), keys.end()).size(), static_cast<std::size_t>(n));
    std::vector<Eigen::Index> order(static_cast<std::size_t>(n));
    std::iota(order.begin(), order.end(), Eigen::Index{0});
    std::sort(order.begin(), order.end(), [&](Eigen::Index a, Eigen::Index b) {
      return keys[static_cast<std::size_t>(a)] < keys[static_cast<std::size_t>(b)];
    });
    for (int k = 1; k < n; ++k) {
      const double step =
          (grid.col(order[static_cast<std::size_t>(k)]) - grid.col(order[static_cast<std::size_t>(k - 1)]))
              .lpNorm<1>();
      ASSERT_DOUBLE_EQ(step, 1.0) << dims << "D, step " << k;
    }
  }
}

TEST(OrderByParameter, SortsStably) {
  Eigen::VectorXd t(5);
  t << 0.3, 0.1, 0.3, -2, 5;
  EXPECT_EQ(OrderByParameter(t), (std::vector<Eigen::Index>{3, 1, 0, 2, 4}));
}

// The curve noise estimate on a circle of radius 10 with Gaussian noise 0.05 in the plane (codim 1) and a
// helix with isotropic noise 0.05 in space (codim 2: the orthogonal distance's RMS is sqrt(2) x 0.05), both
// sampled about every 0.15 (the estimator needs a spacing well above the noise to find the tangent). The
// median of 420 (circle) and 1000 (helix) neighbourhoods scatters by a few per cent; 7 neighbours on these
// curvatures add a small bias: within 10 %.
TEST(EstimateCurveNoise, CircleAndHelix) {
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.05);
  const int n = 420, m = 1260;
  Eigen::MatrixXd circle(2, n), helix(3, m);
  for (int i = 0; i < n; ++i) {
    const double a = 2 * M_PI * i / n;
    circle.col(i) << 10 * std::cos(a) + noise(rng), 10 * std::sin(a) + noise(rng);
  }
  for (int i = 0; i < m; ++i) {
    const double a = 2 * M_PI * i / m;
    helix.col(i) << 10 * std::cos(3 * a) + noise(rng), 10 * std::sin(3 * a) + noise(rng), 5 * a + noise(rng);
  }
  EXPECT_NEAR(EstimateCurveNoise(circle).sigma, 0.05, 0.005);
  EXPECT_NEAR(EstimateCurveNoise(helix).sigma, std::sqrt(2.0) * 0.05, std::sqrt(2.0) * 0.005);
  EXPECT_TRUE(std::isnan(EstimateCurveNoise(circle.leftCols(10)).sigma));
}

}  // namespace
}  // namespace s2m
