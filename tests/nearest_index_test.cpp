// The k-d tree of registration/nearest_index.h against brute force: nearest, bounded (warm-started) and
// k-nearest queries for queries inside the cloud, on its points, and far outside it.

#include "registration/nearest_index.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <random>

namespace s2m {
namespace {

Eigen::Index BruteNearest(const Eigen::Matrix3Xd& p, const Eigen::Vector3d& q) {
  Eigen::Index best = 0;
  (p.colwise() - q).colwise().squaredNorm().minCoeff(&best);
  return best;
}

// A sheet (a scan-like surface) and a ball of points, with duplicates.
Eigen::Matrix3Xd Cloud(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  Eigen::Matrix3Xd p(3, 3000);
  for (Eigen::Index i = 0; i < 2000; ++i) p.col(i) << u(rng), u(rng), 0.1 * std::sin(3 * u(rng));
  for (Eigen::Index i = 2000; i < 2900; ++i) p.col(i) << 2 + 0.3 * u(rng), 0.3 * u(rng), 0.3 * u(rng);
  for (Eigen::Index i = 2900; i < 3000; ++i) p.col(i) = p.col(i - 2900);
  return p;
}

std::vector<Eigen::Vector3d> Queries(std::mt19937_64& rng, const Eigen::Matrix3Xd& p) {
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Eigen::Vector3d> q;
  for (int i = 0; i < 300; ++i) q.emplace_back(1.5 * u(rng), 1.5 * u(rng), 1.5 * u(rng));  // near
  for (int i = 0; i < 100; ++i) q.emplace_back(p.col(i * 29));                             // on points
  for (int i = 0; i < 100; ++i)
    q.push_back(Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized() * 50.0);  // far
  return q;
}

TEST(NearestIndex, NearestEqualsBruteForce) {
  std::mt19937_64 rng(3);
  const Eigen::Matrix3Xd p = Cloud(rng);
  const NearestIndex index(p);
  for (const Eigen::Vector3d& q : Queries(rng, p)) {
    // Among equally near points (the duplicates) the lowest index, as the brute force's first minimum.
    EXPECT_EQ(index.Nearest(q), BruteNearest(p, q));
  }
}

TEST(NearestIndex, BoundedSearchFindsOnlyCloserPointsAndKeepsTheBoundOtherwise) {
  std::mt19937_64 rng(5);
  const Eigen::Matrix3Xd p = Cloud(rng);
  const NearestIndex index(p);
  for (const Eigen::Vector3d& q : Queries(rng, p)) {
    const double d2 = (p.col(BruteNearest(p, q)) - q).squaredNorm();
    // A bound above the nearest distance: found, and it is the nearest.
    Eigen::Index best = -1;
    double bound = 1.5 * d2 + 1e-12;
    ASSERT_TRUE(index.NearestWithin(q, best, bound));
    EXPECT_EQ(bound, d2);
    EXPECT_EQ((p.col(best) - q).squaredNorm(), d2);
    // A bound at or below it: nothing, and the caller's best is untouched.
    best = -7;
    bound = d2;
    EXPECT_FALSE(index.NearestWithin(q, best, bound));
    EXPECT_EQ(best, -7);
    EXPECT_EQ(bound, d2);
  }
  // The nearest over two trees by passing the best of the first to the second.
  const NearestIndex left(p.leftCols(1500)), right(p.rightCols(1500));
  for (const Eigen::Vector3d& q : Queries(rng, p)) {
    Eigen::Index best = -1;
    double bound = std::numeric_limits<double>::infinity();
    left.NearestWithin(q, best, bound);
    const bool in_right = right.NearestWithin(q, best, bound);
    const Eigen::Index global = in_right ? best + 1500 : best;
    EXPECT_EQ((p.col(global) - q).squaredNorm(), (p.col(BruteNearest(p, q)) - q).squaredNorm());
  }
}

TEST(NearestIndex, KNearestEqualsBruteForceInOrder) {
  std::mt19937_64 rng(7);
  const Eigen::Matrix3Xd p = Cloud(rng);
  const NearestIndex index(p);
  for (const Eigen::Vector3d& q : Queries(rng, p)) {
    const std::vector<Eigen::Index> nn = index.KNearest(q, 20);
    ASSERT_EQ(nn.size(), 20u);
    std::vector<double> brute(static_cast<std::size_t>(p.cols()));
    for (Eigen::Index i = 0; i < p.cols(); ++i)
      brute[static_cast<std::size_t>(i)] = (p.col(i) - q).squaredNorm();
    std::sort(brute.begin(), brute.end());
    for (std::size_t m = 0; m < nn.size(); ++m) EXPECT_EQ((p.col(nn[m]) - q).squaredNorm(), brute[m]) << m;
  }
  EXPECT_EQ(NearestIndex(p.leftCols(5)).KNearest(Eigen::Vector3d::Zero(), 8).size(), 5u);
}

TEST(NearestIndex, EmptyAndTinyTrees) {
  const NearestIndex empty{Eigen::Matrix3Xd(3, 0)};
  Eigen::Index best = -1;
  double bound = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(empty.NearestWithin(Eigen::Vector3d::Zero(), best, bound));
  EXPECT_TRUE(empty.KNearest(Eigen::Vector3d::Zero(), 3).empty());
  Eigen::Matrix3Xd one(3, 1);
  one << 1, 2, 3;
  EXPECT_EQ(NearestIndex(one).Nearest(Eigen::Vector3d(100, -4, 0)), 0);
}

}  // namespace
}  // namespace s2m
