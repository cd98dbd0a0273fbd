#include "fitting/bspline_basis.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "fitting/spline_energy.h"

namespace s2m {
namespace {

void CheckOrder(int order, int num_control) {
  if (order < 2 || order > BSplineBasis::kMaxOrder) {
    throw std::invalid_argument("B-spline order must be in [2, " + std::to_string(BSplineBasis::kMaxOrder) +
                                "], got " + std::to_string(order));
  }
  if (num_control < order) {
    throw std::invalid_argument("a B-spline of order " + std::to_string(order) + " needs at least " +
                                std::to_string(order) + " control points, got " +
                                std::to_string(num_control));
  }
}

}  // namespace

BSplineBasis::BSplineBasis(int order, int num_control, bool periodic, std::vector<double> knots)
    : order_(order), num_control_(num_control), periodic_(periodic), knots_(std::move(knots)) {
  if (!periodic_) {
    ext_ = knots_;
    lo_ = knots_[static_cast<std::size_t>(order_ - 1)];
    hi_ = knots_[static_cast<std::size_t>(num_control_)];
  } else {
    lo_ = knots_.front();
    hi_ = knots_.back();
    const int n = num_control_;
    const double period = hi_ - lo_;
    ext_offset_ = order_ - 1;
    for (int i = -(order_ - 1); i <= n + order_ - 1; ++i) {
      const int wrapped = ((i % n) + n) % n;
      const int shift = (i - wrapped) / n;
      ext_.push_back(knots_[static_cast<std::size_t>(wrapped)] + shift * period);
    }
  }
  BuildTables();
}

BSplineBasis BSplineBasis::Clamped(int order, std::vector<double> knots) {
  const int n = static_cast<int>(knots.size()) - order;
  CheckOrder(order, n);
  for (std::size_t i = 0; i < knots.size(); ++i) {
    if (!std::isfinite(knots[i])) throw std::invalid_argument("knot " + std::to_string(i) + " is not finite");
    if (i > 0 && knots[i] < knots[i - 1]) {
      throw std::invalid_argument("knots must be non-decreasing: knot " + std::to_string(i) + " (" +
                                  std::to_string(knots[i]) + ") < knot " + std::to_string(i - 1));
    }
  }
  for (int i = 1; i < order; ++i) {
    if (knots[static_cast<std::size_t>(i)] != knots[0] ||
        knots[knots.size() - 1 - static_cast<std::size_t>(i)] != knots.back()) {
      throw std::invalid_argument("a clamped knot vector repeats its first and last knots `order` (" +
                                  std::to_string(order) + ") times");
    }
  }
  if (!(knots.back() > knots.front())) throw std::invalid_argument("the knot vector spans an empty domain");
  for (std::size_t i = static_cast<std::size_t>(order); i + static_cast<std::size_t>(order) < knots.size();
       ++i) {
    std::size_t m = 1;
    while (i + m < knots.size() - static_cast<std::size_t>(order) && knots[i + m] == knots[i]) ++m;
    if (m >= static_cast<std::size_t>(order)) {
      throw std::invalid_argument("interior knot " + std::to_string(knots[i]) + " has multiplicity " +
                                  std::to_string(m) + " >= order " + std::to_string(order) +
                                  " (the curve would break apart)");
    }
  }
  return BSplineBasis(order, n, false, std::move(knots));
}

BSplineBasis BSplineBasis::ClampedUniform(int order, int num_control, double lo, double hi) {
  CheckOrder(order, num_control);
  std::vector<double> knots;
  const int spans = num_control - order + 1;
  for (int i = 0; i < order; ++i) knots.push_back(lo);
  for (int i = 1; i < spans; ++i) knots.push_back(lo + (hi - lo) * i / spans);
  for (int i = 0; i < order; ++i) knots.push_back(hi);
  return Clamped(order, std::move(knots));
}

BSplineBasis BSplineBasis::Periodic(int order, std::vector<double> breakpoints) {
  const int n = static_cast<int>(breakpoints.size()) - 1;
  CheckOrder(order, n);
  for (std::size_t i = 1; i < breakpoints.size(); ++i) {
    if (!std::isfinite(breakpoints[i]) || !(breakpoints[i] > breakpoints[i - 1])) {
      throw std::invalid_argument("periodic breakpoints must be finite and strictly increasing (breakpoint " +
                                  std::to_string(i) + ")");
    }
  }
  return BSplineBasis(order, n, true, std::move(breakpoints));
}

BSplineBasis BSplineBasis::PeriodicUniform(int order, int num_control, double lo, double hi) {
  CheckOrder(order, num_control);
  std::vector<double> b;
  for (int i = 0; i <= num_control; ++i) b.push_back(lo + (hi - lo) * i / num_control);
  return Periodic(order, std::move(b));
}

std::vector<double> BSplineBasis::Breakpoints() const {
  std::vector<double> out;
  for (double k : knots_) {
    if (k >= lo_ && k <= hi_ && (out.empty() || k > out.back())) out.push_back(k);
  }
  return out;
}

double BSplineBasis::Normalize(double t) const {
  if (periodic_) {
    if (t >= lo_ && t < hi_) return t;  // the common case: no fmod
    double u = std::fmod(t - lo_, hi_ - lo_);
    if (u < 0) u += hi_ - lo_;
    const double w = lo_ + u;
    return w >= hi_ ? lo_ : w;
  }
  return std::clamp(t, lo_, hi_);
}

int BSplineBasis::FindSpanReference(double t) const {
  if (!periodic_) {
    if (t >= hi_) return num_control_ - 1;
    if (t <= lo_) return order_ - 1;
    // ext_[span] <= t < ext_[span + 1] with span in [order - 1, n - 1]
    const auto it = std::upper_bound(ext_.begin() + order_ - 1, ext_.begin() + num_control_ + 1, t);
    return static_cast<int>(it - ext_.begin()) - 1;
  }
  const auto it =
      std::upper_bound(ext_.begin() + ext_offset_, ext_.begin() + ext_offset_ + num_control_ + 1, t);
  return std::min(static_cast<int>(it - ext_.begin()) - 1, ext_offset_ + num_control_ - 1);
}

namespace {

// Piegl & Tiller A2.3: all non-zero basis functions of degree p at t in knot span `span` of U and their
// derivatives up to `n_der` (<= p): ders[k][j] is derivative k of function span - p + j. The knot differences
// are inverted once and multiplied thereafter (A2.3 divides by each of them again for every derivative).
void BasisAndDerivatives(int p, double t, int span, const std::vector<double>& U, int n_der,
                         double (&ders)[BSplineBasis::kMaxOrder][BSplineBasis::kMaxOrder]) {
  constexpr int kMaxOrder = BSplineBasis::kMaxOrder;
  // ndu holds basis functions (upper triangle); inv_diff[j][r] = 1 / (knot difference of the lower triangle).
  double ndu[kMaxOrder][kMaxOrder];
  double inv_diff[kMaxOrder][kMaxOrder];
  double left[kMaxOrder], right[kMaxOrder];
  ndu[0][0] = 1.0;
  for (int j = 1; j <= p; ++j) {
    left[j] = t - U[static_cast<std::size_t>(span + 1 - j)];
    right[j] = U[static_cast<std::size_t>(span + j)] - t;
    double saved = 0.0;
    for (int r = 0; r < j; ++r) {
      inv_diff[j][r] = 1.0 / (right[r + 1] + left[j - r]);
      const double temp = ndu[r][j - 1] * inv_diff[j][r];
      ndu[r][j] = saved + right[r + 1] * temp;
      saved = left[j - r] * temp;
    }
    ndu[j][j] = saved;
  }
  for (int j = 0; j <= p; ++j) ders[0][j] = ndu[j][p];
  double a[2][kMaxOrder];
  for (int r = 0; r <= p; ++r) {
    int s1 = 0, s2 = 1;
    a[0][0] = 1.0;
    for (int k = 1; k <= n_der; ++k) {
      double d = 0.0;
      const int rk = r - k, pk = p - k;
      if (r >= k) {
        a[s2][0] = a[s1][0] * inv_diff[pk + 1][rk];
        d = a[s2][0] * ndu[rk][pk];
      }
      const int j1 = rk >= -1 ? 1 : -rk;
      const int j2 = (r - 1 <= pk) ? k - 1 : p - r;
      for (int j = j1; j <= j2; ++j) {
        a[s2][j] = (a[s1][j] - a[s1][j - 1]) * inv_diff[pk + 1][rk + j];
        d += a[s2][j] * ndu[rk + j][pk];
      }
      if (r <= pk) {
        a[s2][k] = -a[s1][k - 1] * inv_diff[pk + 1][r];
        d += a[s2][k] * ndu[r][pk];
      }
      ders[k][r] = d;
      std::swap(s1, s2);
    }
  }
  double factor = p;  // A2.3's closing loop: multiply by p! / (p - k)!
  for (int k = 1; k <= n_der; ++k) {
    for (int j = 0; j <= p; ++j) ders[k][j] *= factor;
    factor *= (p - k);
  }
}

// The fast path for order K: derivative d of the K functions at y, by Horner's rule on the span's Taylor
// coefficients (the rows j = 0 .. K - 1 - d; derivatives above the degree are 0).
template <int K>
void HornerAll(const double* coeffs, double y, int derivatives, BSplineBasis::Values& out) {
  for (int d = 0; d <= derivatives; ++d) {
    auto& row = out.values[static_cast<std::size_t>(d)];
    const double* c = coeffs + d * K * K;
    const int top = K - 1 - d;
    if (top < 0) {
      for (int i = 0; i < K; ++i) row[static_cast<std::size_t>(i)] = 0.0;
      continue;
    }
    double v[K];
    for (int i = 0; i < K; ++i) v[i] = c[top * K + i];
    for (int j = top - 1; j >= 0; --j)
      for (int i = 0; i < K; ++i) v[i] = v[i] * y + c[j * K + i];
    for (int i = 0; i < K; ++i) row[static_cast<std::size_t>(i)] = v[i];
  }
}

}  // namespace

void BSplineBasis::BuildTables() {
  const int p = order_ - 1, k = order_;
  span_base_ = periodic_ ? ext_offset_ : order_ - 1;
  num_spans_ = periodic_ ? num_control_ : num_control_ - order_ + 1;
  mid_.assign(static_cast<std::size_t>(num_spans_), 0.0);
  inv_length_.assign(static_cast<std::size_t>(num_spans_), 0.0);
  coeffs_.assign(static_cast<std::size_t>(num_spans_ * 3 * k * k), 0.0);
  double ders[kMaxOrder][kMaxOrder];
  for (int s = 0; s < num_spans_; ++s) {
    const int span = span_base_ + s;
    const double a = ext_[static_cast<std::size_t>(span)], b = ext_[static_cast<std::size_t>(span) + 1];
    if (!(b > a)) continue;  // a repeated interior knot: FindSpan never returns it
    const double length = b - a, mid = a + 0.5 * length;
    mid_[static_cast<std::size_t>(s)] = mid;
    inv_length_[static_cast<std::size_t>(s)] = 1.0 / length;
    // Taylor's theorem about mid (exact for the degree-p pieces): with y = (t - mid) / length,
    // N_i^(d)(t) = sum_j N_i^(d + j)(mid) length^j / j! y^j. A2.3 with all p derivatives supplies N^(k)(mid).
    BasisAndDerivatives(p, mid, span, ext_, p, ders);
    for (int d = 0; d <= kMaxDerivative; ++d) {
      double scale = 1.0;  // length^j / j!
      for (int j = 0; j + d <= p; ++j) {
        for (int i = 0; i < k; ++i)
          coeffs_[static_cast<std::size_t>(((s * 3 + d) * k + j) * k + i)] = ders[j + d][i] * scale;
        scale *= length / (j + 1);
      }
    }
  }
  // About two buckets per span; their first spans by the reference search.
  const int buckets = 2 * num_spans_;
  bucket_scale_ = buckets / (hi_ - lo_);
  bucket_.assign(static_cast<std::size_t>(buckets) + 1, 0);
  for (int b = 0; b <= buckets; ++b) {
    const double t = b == buckets ? hi_ : lo_ + (hi_ - lo_) * b / buckets;
    bucket_[static_cast<std::size_t>(b)] =
        FindSpanReference(periodic_ && b == buckets ? std::nextafter(hi_, lo_) : t);
  }
}

void BSplineBasis::EvaluateReference(double t_in, int derivatives, Values& out) const {
  const double t = Normalize(t_in);
  const int p = order_ - 1;
  const int span = FindSpanReference(t);
  const int nd = std::clamp(derivatives, 0, kMaxDerivative);
  double ders[kMaxOrder][kMaxOrder];
  BasisAndDerivatives(p, t, span, ext_, std::min(nd, p), ders);
  for (int d = 0; d <= nd; ++d)
    for (int i = 0; i < order_; ++i)
      out.values[static_cast<std::size_t>(d)][static_cast<std::size_t>(i)] = d <= p ? ders[d][i] : 0.0;
  out.first = periodic_ ? ((span - ext_offset_ - p) % num_control_ + num_control_) % num_control_ : span - p;
}

void BSplineBasis::Evaluate(double t_in, int derivatives, Values& out) const {
  double y = 0.0, inv_length = 0.0;
  const int s = LocateSpan(t_in, y, inv_length);
  out.first = FirstFunction(s);
  const auto us = static_cast<std::size_t>(s);
  const int nd = std::clamp(derivatives, 0, kMaxDerivative);
  const double* c = coeffs_.data() + us * 3 * static_cast<std::size_t>(order_ * order_);
  switch (order_) {
    case 2:
      HornerAll<2>(c, y, nd, out);
      break;
    case 3:
      HornerAll<3>(c, y, nd, out);
      break;
    case 4:
      HornerAll<4>(c, y, nd, out);
      break;
    case 5:
      HornerAll<5>(c, y, nd, out);
      break;
    case 6:
      HornerAll<6>(c, y, nd, out);
      break;
    case 7:
      HornerAll<7>(c, y, nd, out);
      break;
    default:
      HornerAll<8>(c, y, nd, out);
      break;
  }
}

std::vector<double> BSplineBasis::GramMatrix(int derivative) const {
  // Exact, from each span's power form (fitting/spline_energy.h, docs/fair-curves.md eq. F5).
  const Eigen::MatrixXd g = SplineEnergyMatrix(*this, derivative);
  std::vector<double> out(static_cast<std::size_t>(g.size()));
  Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(out.data(), g.rows(),
                                                                                     g.cols()) = g;
  return out;
}

}  // namespace s2m
