#include "fitting/residual_structure.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "registration/nearest_index.h"

namespace s2m {

RunsTest SignRunsTest(const Eigen::Ref<const Eigen::VectorXd>& values) {
  RunsTest t;
  int previous = 0;
  for (Eigen::Index i = 0; i < values.size(); ++i) {
    const int sign = values[i] > 0 ? 1 : values[i] < 0 ? -1 : 0;
    if (sign == 0) continue;
    (sign > 0 ? t.positives : t.negatives) += 1;
    if (sign != previous) t.runs += 1;
    previous = sign;
  }
  if (t.positives < 2 || t.negatives < 2) return t;
  // Eqs. 49-50 (Wald & Wolfowitz 1940): mean and variance of the number of runs of n1 and n2 signs in random
  // order, n = n1 + n2.
  const double n1 = static_cast<double>(t.positives), n2 = static_cast<double>(t.negatives), n = n1 + n2;
  t.expected_runs = 1 + 2 * n1 * n2 / n;
  t.variance = 2 * n1 * n2 * (2 * n1 * n2 - n) / (n * n * (n - 1));
  t.z = (static_cast<double>(t.runs) - t.expected_runs) / std::sqrt(t.variance);
  // Eq. 51: of the n - 1 successive pairs, the fraction that change sign is (R - 1) / (n - 1); under the null
  // it is (E[R] - 1) / (n - 1). Their ratio's complement is the correlation of successive signs (for
  // balanced signs exactly the lag-1 correlation of the +-1 indicators).
  t.sign_correlation = 1 - (static_cast<double>(t.runs) - 1) / (t.expected_runs - 1);
  return t;
}

MoranTest MoransI(const std::vector<std::vector<Eigen::Index>>& neighbours_of,
                  const Eigen::Ref<const Eigen::VectorXd>& values) {
  MoranTest t;
  const Eigen::Index n = values.size();
  t.count = n;
  if (n < 4 || static_cast<Eigen::Index>(neighbours_of.size()) != n) return t;
  const Eigen::VectorXd z = values.array() - values.mean();
  const double m2 = z.squaredNorm();
  if (!(m2 > 0)) return t;
  // Sorted copies to find mutual pairs (w_ij = w_ji = 1) by binary search.
  std::vector<std::vector<Eigen::Index>> sorted = neighbours_of;
  for (auto& list : sorted) std::sort(list.begin(), list.end());
  std::vector<double> in_degree(static_cast<std::size_t>(n), 0.0);
  double W = 0, cross = 0, S1 = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    for (const Eigen::Index j : sorted[static_cast<std::size_t>(i)]) {
      W += 1;
      cross += z[i] * z[j];
      in_degree[static_cast<std::size_t>(j)] += 1;
      const auto& back = sorted[static_cast<std::size_t>(j)];
      const bool mutual = std::binary_search(back.begin(), back.end(), i);
      // S1 = 1/2 sum over ordered pairs of (w_ij + w_ji)^2: a mutual pair gives 4 to (i, j) and 4 to (j, i),
      // counted from both of its directed edges; a one-way edge gives 1 to each of the two ordered pairs.
      S1 += mutual ? 4.0 : 2.0;
    }
  }
  S1 /= 2;
  if (!(W > 0)) return t;
  double S2 = 0;  // sum over i of (out-degree + in-degree)^2
  for (Eigen::Index i = 0; i < n; ++i) {
    const double d = static_cast<double>(sorted[static_cast<std::size_t>(i)].size()) +
                     in_degree[static_cast<std::size_t>(i)];
    S2 += d * d;
  }
  const double nn = static_cast<double>(n);
  // Eq. 52.
  t.statistic = nn / W * cross / m2;
  // Eq. 53-54 (Cliff & Ord 1981, randomization): b2 is the sample kurtosis of the values.
  t.expected = -1.0 / (nn - 1);
  const double b2 = nn * z.array().pow(4).sum() / (m2 * m2);
  const double second_moment = (nn * ((nn * nn - 3 * nn + 3) * S1 - nn * S2 + 3 * W * W) -
                                b2 * ((nn * nn - nn) * S1 - 2 * nn * S2 + 6 * W * W)) /
                               ((nn - 1) * (nn - 2) * (nn - 3) * W * W);
  t.variance = second_moment - t.expected * t.expected;
  if (t.variance > 0) t.z = (t.statistic - t.expected) / std::sqrt(t.variance);
  return t;
}

MoranTest MoransI(const Eigen::Ref<const Eigen::Matrix3Xd>& points,
                  const Eigen::Ref<const Eigen::VectorXd>& values, int neighbours) {
  const Eigen::Index n = points.cols();
  if (n < neighbours + 4 || values.size() != n) {
    MoranTest t;
    t.count = n;
    t.neighbours = neighbours;
    return t;
  }
  const NearestIndex index{Eigen::Matrix3Xd(points)};
  std::vector<std::vector<Eigen::Index>> lists(static_cast<std::size_t>(n));
  for (Eigen::Index i = 0; i < n; ++i) {
    // The point itself comes back first (distance 0), and coincident points may too: drop i only.
    std::vector<Eigen::Index> near = index.KNearest(points.col(i), neighbours + 1);
    near.erase(std::remove(near.begin(), near.end(), i), near.end());
    if (static_cast<int>(near.size()) > neighbours) near.resize(static_cast<std::size_t>(neighbours));
    lists[static_cast<std::size_t>(i)] = std::move(near);
  }
  MoranTest t = MoransI(lists, values);
  t.neighbours = neighbours;
  return t;
}

namespace {

// Skilling's transform of axes to the "transposed" Hilbert index, in place (n coordinates of b bits).
void AxesToTranspose(std::uint32_t* x, int bits, int n) {
  const std::uint32_t top = 1u << (bits - 1);
  for (std::uint32_t q = top; q > 1; q >>= 1) {  // inverse undo
    const std::uint32_t p = q - 1;
    for (int i = 0; i < n; ++i) {
      if (x[i] & q) {
        x[0] ^= p;  // invert
      } else {      // exchange
        const std::uint32_t t = (x[0] ^ x[i]) & p;
        x[0] ^= t;
        x[i] ^= t;
      }
    }
  }
  for (int i = 1; i < n; ++i) x[i] ^= x[i - 1];  // Gray encode
  std::uint32_t t = 0;
  for (std::uint32_t q = top; q > 1; q >>= 1) {
    if (x[n - 1] & q) t ^= q - 1;
  }
  for (int i = 0; i < n; ++i) x[i] ^= t;
}

}  // namespace

std::vector<std::uint64_t> HilbertKeys(const Eigen::Ref<const Eigen::MatrixXd>& c, int bits) {
  const int dims = static_cast<int>(c.rows());
  const Eigen::Index n = c.cols();
  std::vector<std::uint64_t> keys(static_cast<std::size_t>(n), 0);
  if (n == 0 || dims < 1 || dims > 3) return keys;
  bits = std::clamp(bits, 1, 63 / dims);
  bits = std::min(bits, 31);
  const Eigen::VectorXd lo = c.rowwise().minCoeff(), hi = c.rowwise().maxCoeff();
  // One scale for all axes, so that the curve's cells are cubes (distances keep their meaning).
  const double extent = (hi - lo).maxCoeff();
  const double cells = std::ldexp(1.0, bits) - 1;
  for (Eigen::Index i = 0; i < n; ++i) {
    std::uint32_t x[3] = {0, 0, 0};
    for (int d = 0; d < dims; ++d) {
      const double unit = extent > 0 ? (c(d, i) - lo[d]) / extent : 0.0;
      x[d] = static_cast<std::uint32_t>(std::clamp(std::lround(unit * cells), 0L, static_cast<long>(cells)));
    }
    AxesToTranspose(x, bits, dims);
    std::uint64_t key = 0;
    for (int b = bits - 1; b >= 0; --b) {
      for (int d = 0; d < dims; ++d) key = (key << 1) | ((x[d] >> b) & 1u);
    }
    keys[static_cast<std::size_t>(i)] = key;
  }
  return keys;
}

std::vector<Eigen::Index> HilbertOrder(const Eigen::Ref<const Eigen::MatrixXd>& coordinates) {
  const std::vector<std::uint64_t> keys = HilbertKeys(coordinates, coordinates.rows() == 3 ? 20 : 30);
  std::vector<Eigen::Index> order(keys.size());
  std::iota(order.begin(), order.end(), Eigen::Index{0});
  std::stable_sort(order.begin(), order.end(), [&](Eigen::Index a, Eigen::Index b) {
    return keys[static_cast<std::size_t>(a)] < keys[static_cast<std::size_t>(b)];
  });
  return order;
}

std::vector<Eigen::Index> OrderByParameter(const Eigen::Ref<const Eigen::VectorXd>& parameter) {
  std::vector<Eigen::Index> order(static_cast<std::size_t>(parameter.size()));
  std::iota(order.begin(), order.end(), Eigen::Index{0});
  std::stable_sort(order.begin(), order.end(),
                   [&](Eigen::Index a, Eigen::Index b) { return parameter[a] < parameter[b]; });
  return order;
}

}  // namespace s2m
