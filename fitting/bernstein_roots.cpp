#include "fitting/bernstein_roots.h"

#include <algorithm>
#include <cmath>

namespace s2m {
namespace {

double Binomial(int n, int k) {
  double r = 1.0;
  for (int i = 1; i <= k; ++i) r = r * (n - k + i) / i;
  return r;
}

int SignChanges(const Eigen::VectorXd& b, double zero) {
  int changes = 0, last = 0;
  for (Eigen::Index i = 0; i < b.size(); ++i) {
    const int s = b[i] > zero ? 1 : (b[i] < -zero ? -1 : 0);
    if (s == 0) continue;
    if (last != 0 && s != last) ++changes;
    last = s;
  }
  return changes;
}

// de Casteljau: the coefficients of the left and right halves of [0, 1].
void Split(const Eigen::VectorXd& b, Eigen::VectorXd& left, Eigen::VectorXd& right) {
  const Eigen::Index n = b.size();
  Eigen::VectorXd work = b;
  left.resize(n);
  right.resize(n);
  for (Eigen::Index r = 0; r < n; ++r) {
    left[r] = work[0];
    right[n - 1 - r] = work[n - 1 - r];
    for (Eigen::Index i = 0; i + 1 < n - r; ++i) work[i] = 0.5 * (work[i] + work[i + 1]);
  }
}

// Value and derivative at t of the Bernstein polynomial, by de Casteljau.
void EvaluateBernstein(const Eigen::VectorXd& b, double t, double& value, double& slope) {
  const Eigen::Index n = b.size();
  Eigen::VectorXd work = b;
  for (Eigen::Index r = 1; r < n; ++r) {
    if (r == n - 1) slope = static_cast<double>(n - 1) * (work[1] - work[0]);
    for (Eigen::Index i = 0; i + r < n; ++i) work[i] = (1.0 - t) * work[i] + t * work[i + 1];
  }
  if (n == 1) slope = 0.0;
  value = work[0];
}

// The one root in [0, 1] of b (b[0] and b[n-1] of opposite signs): Newton kept inside a shrinking bracket.
double BracketedRoot(const Eigen::VectorXd& b) {
  double lo = 0.0, hi = 1.0;
  const double f_lo = b[0];
  double t = b[0] / (b[0] - b[b.size() - 1]);  // the chord's zero
  for (int it = 0; it < 100; ++it) {
    double f = 0.0, df = 0.0;
    EvaluateBernstein(b, t, f, df);
    if (f == 0.0) return t;
    if ((f < 0) == (f_lo < 0))
      lo = t;
    else
      hi = t;
    double next = df != 0.0 ? t - f / df : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (std::abs(next - t) < 1e-15 || hi - lo < 1e-15) return next;
    t = next;
  }
  return t;
}

void Isolate(const Eigen::VectorXd& b, double a, double width, double zero, double resolution, int depth,
             std::vector<double>& roots) {
  const int changes = SignChanges(b, zero);
  const Eigen::Index last = b.size() - 1;
  if (changes == 0) {
    // An end value at (numerical) zero is a root at that end (e.g. exactly at a split point).
    if (std::abs(b[0]) <= zero) roots.push_back(a);
    if (std::abs(b[last]) <= zero) roots.push_back(a + width);
    return;
  }
  if (changes == 1 && std::abs(b[0]) > zero && std::abs(b[last]) > zero && (b[0] < 0) != (b[last] < 0)) {
    roots.push_back(a + width * BracketedRoot(b));
    return;
  }
  if (width <= resolution || depth > 60) {
    roots.push_back(a + 0.5 * width);
    return;
  }
  Eigen::VectorXd left, right;
  Split(b, left, right);
  Isolate(left, a, 0.5 * width, zero, resolution, depth + 1, roots);
  Isolate(right, a + 0.5 * width, 0.5 * width, zero, resolution, depth + 1, roots);
}

}  // namespace

Eigen::VectorXd PowerToBernstein(const Eigen::VectorXd& power) {
  const int m = static_cast<int>(power.size()) - 1;
  Eigen::VectorXd b = Eigen::VectorXd::Zero(power.size());
  for (int i = 0; i <= m; ++i)
    for (int k = 0; k <= i; ++k) b[i] += Binomial(i, k) / Binomial(m, k) * power[k];
  return b;
}

void BernsteinRoots(const Eigen::VectorXd& bernstein, std::vector<double>& roots, double resolution) {
  if (bernstein.size() < 2) return;
  // Coefficients below this are zero: rounding of the conversion, relative to the largest.
  const double zero = 1e-14 * bernstein.cwiseAbs().maxCoeff();
  if (zero == 0.0) return;
  const std::size_t first = roots.size();
  Isolate(bernstein, 0.0, 1.0, zero, resolution, 0, roots);
  std::sort(roots.begin() + static_cast<std::ptrdiff_t>(first), roots.end());
}

}  // namespace s2m
