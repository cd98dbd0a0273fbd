#pragma once
// B-spline basis functions of one parameter: clamped (open) or periodic (closed) knot vectors of any order.
// Reference evaluation follows Piegl & Tiller, The NURBS Book (2nd ed.), algorithms A2.1 (span) and A2.3
// (basis and derivatives). The fast path (Evaluate) uses tables built once from A2.3: per knot span, the
// Taylor coefficients of the order() non-zero basis functions about the span's midpoint (each function is a
// polynomial of degree order() - 1 there, de Boor, A Practical Guide to Splines, ch. IX), evaluated by
// Horner's rule; and a bucket table that finds the span in O(1) (exactly so for uniform knots).

#include <algorithm>
#include <array>
#include <vector>

namespace s2m {

class BSplineBasis {
 public:
  static constexpr int kMaxOrder = 8;
  static constexpr int kMaxDerivative = 2;

  // Clamped: `knots` has num_control + order entries, non-decreasing, the first and last `order` equal,
  // interior multiplicities below `order`. Throws std::invalid_argument naming the violated rule.
  static BSplineBasis Clamped(int order, std::vector<double> knots);
  static BSplineBasis ClampedUniform(int order, int num_control, double lo = 0.0, double hi = 1.0);
  // Periodic (closed): num_control + 1 strictly increasing breakpoints; the last closes the period.
  static BSplineBasis Periodic(int order, std::vector<double> breakpoints);
  static BSplineBasis PeriodicUniform(int order, int num_control, double lo = 0.0, double hi = 1.0);

  int order() const { return order_; }
  int degree() const { return order_ - 1; }
  int num_control() const { return num_control_; }
  bool periodic() const { return periodic_; }
  double lo() const { return lo_; }
  double hi() const { return hi_; }
  double period() const { return hi_ - lo_; }
  // The knot vector as given (clamped: full vector; periodic: breakpoints).
  const std::vector<double>& knots() const { return knots_; }
  // Distinct knot values inside the domain, lo and hi included (integration and sampling spans).
  std::vector<double> Breakpoints() const;

  // Wraps periodic parameters into [lo, hi); clamps open ones to [lo, hi].
  double Normalize(double t) const;

  // Non-zero basis functions at t: derivative d (0..derivatives) of function `first + i` is values[d][i],
  // i < order(). For periodic bases the control index is (first + i) mod num_control(). Entries with i >=
  // order() or d > derivatives are not written (no zero fill on the hot path); derivatives above the degree
  // are written as 0.
  struct Values {
    int first = 0;
    std::array<std::array<double, kMaxOrder>, kMaxDerivative + 1> values;
  };
  // Fast path: span by bucket table, values by the per-span Taylor tables. Agrees with EvaluateReference to
  // rounding: within a few ulp of each derivative's size on the span (its largest Taylor coefficient, ~ 1 /
  // length^d; measured < 1e-15 relative to it, tests/bspline_basis_test.cpp). Near a zero of a
  // steep piece (at a knot next to a much shorter span) that is more than a few ulp of the value itself.
  void Evaluate(double t, int derivatives, Values& out) const;
  // The generic reference: binary-search span (A2.1) and A2.3 at t, any order. Slower; for tests and for
  // building the tables.
  void EvaluateReference(double t, int derivatives, Values& out) const;
  int ControlIndex(int first, int i) const { return periodic_ ? (first + i) % num_control_ : first + i; }

  // The fast path's pieces, for models that tabulate their own per-span polynomials (BSplineSurface). Spans
  // are numbered 0 .. num_spans() - 1 over the domain (clamped: zero-length spans of repeated knots included,
  // never located).
  int num_spans() const { return num_spans_; }
  // The span s of t (wrapped/clamped like Evaluate) and t's local coordinate y = (t - mid_s) / length_s in
  // [-1/2, 1/2]; inv_length = 1 / length_s.
  int LocateSpan(double t, double& y, double& inv_length) const {
    const double u = Normalize(t);
    const int s = FindSpan(u) - span_base_;
    const auto us = static_cast<std::size_t>(s);
    inv_length = inv_length_[us];
    y = (u - mid_[us]) * inv_length;
    return s;
  }
  // Values::first of span s.
  int FirstFunction(int s) const {
    return periodic_ ? (s < order_ - 1 ? s - order_ + 1 + num_control_ : s - order_ + 1) : s;
  }
  // The coefficient of y^j (j < order) in derivative d (<= kMaxDerivative) of function first + i (i < order)
  // on span s: derivative d of the function is sum_j coefficient y^j (Taylor about the span's midpoint).
  double TaylorCoefficient(int s, int d, int j, int i) const {
    return coeffs_[static_cast<std::size_t>(((s * 3 + d) * order_ + j) * order_ + i)];
  }

  // Gram matrix G_ij = integral of B_i^(d) B_j^(d) over the domain (exact, from each span's power form:
  // fitting/spline_energy.h).
  std::vector<double> GramMatrix(int derivative) const;  // row-major num_control x num_control

 private:
  BSplineBasis(int order, int num_control, bool periodic, std::vector<double> knots);
  void BuildTables();
  // Index into ext_ with ext_[span] <= t < ext_[span + 1] for a normalized t (the last span takes t == hi).
  int FindSpanReference(double t) const;  // binary search (A2.1)
  int FindSpan(double t) const;           // bucket table, then at most a few steps

  int order_ = 4, num_control_ = 0;
  bool periodic_ = false;
  double lo_ = 0.0, hi_ = 1.0;
  std::vector<double> knots_;
  std::vector<double>
      ext_;             // clamped: knots_; periodic: breakpoints extended by order-1 periods' worth each side
  int ext_offset_ = 0;  // periodic: ext_[ext_offset_] == lo
  // Spans of the domain: ext_ indices span_base_ .. span_base_ + num_spans_ - 1 (clamped: order - 1 ..
  // num_control - 1, zero-length spans included but never found; periodic: one per breakpoint interval).
  int span_base_ = 0, num_spans_ = 0;
  // Per span s: midpoint, 1 / length, and coeffs_[((s * 3 + d) * order + j) * order + i] = the coefficient of
  // y^j in derivative d of function i, y = (t - mid) / length in [-1/2, 1/2].
  std::vector<double> mid_, inv_length_, coeffs_;
  // bucket_[b] = FindSpanReference(lo + b (hi - lo) / buckets), b = 0..buckets (the last one: hi).
  std::vector<int> bucket_;
  double bucket_scale_ = 0.0;  // buckets / (hi - lo)
};

inline int BSplineBasis::FindSpan(double t) const {
  // Bucket b covers [lo + b w, lo + (b + 1) w): its spans run from bucket_[b] to bucket_[b + 1]. The steps
  // below also absorb the rounding of x (one bucket either way); they compare with the knots themselves, so
  // the span is exactly FindSpanReference's.
  const int buckets = static_cast<int>(bucket_.size()) - 1;
  const double x = (t - lo_) * bucket_scale_;
  const int b = x > 0.0 ? (x < buckets ? static_cast<int>(x) : buckets - 1) : 0;  // NaN -> bucket 0
  int span = bucket_[static_cast<std::size_t>(b)];
  const int last = span_base_ + num_spans_ - 1;
  const double* U = ext_.data();
  const int end = bucket_[static_cast<std::size_t>(b) + 1];
  if (end - span > 8) {  // clustered knots: binary search within the bucket (A2.1)
    span = static_cast<int>(std::upper_bound(U + span, U + std::min(end, last) + 1, t) - U) - 1;
    span = std::max(span, span_base_);
  }
  while (span > span_base_ && U[span] > t) --span;
  while (span < last && U[span + 1] <= t) ++span;
  return span;
}

}  // namespace s2m
