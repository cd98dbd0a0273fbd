#pragma once
// Structure in a fit's residuals: tests of whether the signed residuals of neighbouring points are related,
// which a model that describes the data up to independent noise does not produce (docs/method.md section 17,
// eqs. 60-66). Pure statistics; the verdict that combines them with the RMS lives in the pipeline
// (pipeline/domain_measures.h).
// - The Wald-Wolfowitz runs test of the residuals' signs in an order (along a curve's parameter, or along a
//   space-filling curve through the points): too few runs mean neighbours share their sign (Wald &
//   Wolfowitz 1940, Ann. Math. Statist. 11(2)).
// - Moran's I of the residuals over k-nearest-neighbour pairs, with its expectation and variance under the
//   randomization null (Moran 1950, Biometrika 37; Cliff & Ord 1981, "Spatial Processes", eqs. 1.35-1.38).

#include <Eigen/Core>
#include <cstdint>
#include <limits>
#include <vector>

namespace s2m {

// The runs test of the signs of `values` in the order given (zeros are left out: they have no sign).
struct RunsTest {
  Eigen::Index positives = 0;
  Eigen::Index negatives = 0;
  Eigen::Index runs = 0;  // maximal blocks of equal sign
  // Under the null (the signs in random order, given the counts), eqs. 60-61.
  double expected_runs = std::numeric_limits<double>::quiet_NaN();
  double variance = std::numeric_limits<double>::quiet_NaN();
  // (runs - expected) / sqrt(variance): negative when neighbours share their sign (structure), positive when
  // signs alternate; NaN with fewer than two signs of either kind.
  double z = std::numeric_limits<double>::quiet_NaN();
  // Effect size, eq. 62: 1 - (runs - 1) / (expected - 1), the correlation of the signs of successive values
  // (0 for a random order, 1 for two blocks, -1 for alternation).
  double sign_correlation = std::numeric_limits<double>::quiet_NaN();
};
RunsTest SignRunsTest(const Eigen::Ref<const Eigen::VectorXd>& values);

// Moran's I of `values` (one per point) over the directed pairs (i, j), j one of the k nearest neighbours of
// i (binary weights), eq. 63, with E[I] and Var[I] under randomization (eqs. 64-65), which hold for any
// distribution of the values (the kurtosis enters), unlike the normality variance.
struct MoranTest {
  Eigen::Index count = 0;
  int neighbours = 0;
  double statistic = std::numeric_limits<double>::quiet_NaN();  // I
  double expected = std::numeric_limits<double>::quiet_NaN();   // -1 / (n - 1)
  double variance = std::numeric_limits<double>::quiet_NaN();
  double z = std::numeric_limits<double>::quiet_NaN();  // (I - E[I]) / sqrt(Var[I]); positive: clustered
};
// `points` (3 x n) and `values` (n). NaN statistics for fewer than neighbours + 4 points or constant values.
MoranTest MoransI(const Eigen::Ref<const Eigen::Matrix3Xd>& points,
                  const Eigen::Ref<const Eigen::VectorXd>& values, int neighbours = 8);
// The same over explicit neighbour lists: `neighbours_of[i]` the indices j != i with w_ij = 1 (each list
// without repeats). For tests and for neighbourhoods other than k-nearest.
MoranTest MoransI(const std::vector<std::vector<Eigen::Index>>& neighbours_of,
                  const Eigen::Ref<const Eigen::VectorXd>& values);

// The index of each point (the columns of `coordinates`, 1 to 3 rows) along a Hilbert curve through their
// bounding box (Skilling 2004, "Programming the Hilbert curve", AIP Conf. Proc. 707), `bits` per coordinate:
// points near each other along the curve are near each other in space, so the runs test in this order sees
// spatially coherent residuals (eq. 66).
std::vector<std::uint64_t> HilbertKeys(const Eigen::Ref<const Eigen::MatrixXd>& coordinates, int bits = 16);
// The permutation that sorts the points along that curve (ties by index).
std::vector<Eigen::Index> HilbertOrder(const Eigen::Ref<const Eigen::MatrixXd>& coordinates);
// The permutation that sorts by a scalar parameter (a curve's foot parameters; ties by index).
std::vector<Eigen::Index> OrderByParameter(const Eigen::Ref<const Eigen::VectorXd>& parameter);

}  // namespace s2m
