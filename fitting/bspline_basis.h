#pragma once
// B-spline basis functions of one parameter: clamped (open) or periodic (closed) knot vectors of any order.
// Evaluation follows Piegl & Tiller, The NURBS Book, algorithms A2.1 (span) and A2.3 (basis and derivatives).

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
  // i < order(). For periodic bases the control index is (first + i) mod num_control().
  struct Values {
    int first = 0;
    std::array<std::array<double, kMaxOrder>, kMaxDerivative + 1> values{};
  };
  void Evaluate(double t, int derivatives, Values& out) const;
  int ControlIndex(int first, int i) const { return periodic_ ? (first + i) % num_control_ : first + i; }

  // Gram matrix G_ij = integral of B_i^(d) B_j^(d) over the domain (exact, Gauss-Legendre per span).
  std::vector<double> GramMatrix(int derivative) const;  // row-major num_control x num_control

 private:
  BSplineBasis(int order, int num_control, bool periodic, std::vector<double> knots);
  int FindSpan(double t) const;  // index into ext_ with ext_[span] <= t < ext_[span + 1]

  int order_ = 4, num_control_ = 0;
  bool periodic_ = false;
  double lo_ = 0.0, hi_ = 1.0;
  std::vector<double> knots_;
  std::vector<double>
      ext_;             // clamped: knots_; periodic: breakpoints extended by order-1 periods' worth each side
  int ext_offset_ = 0;  // periodic: ext_[ext_offset_] == lo
};

}  // namespace s2m
