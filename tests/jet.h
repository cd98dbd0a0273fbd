#pragma once
// Forward-mode automatic differentiation for tests: a value and its gradient with respect to up to kMax
// parameters (the dual-number "jets" of Ceres Solver, written small). Enough operations for the NIST StRD
// models.

#include <array>
#include <cmath>

namespace s2m::test {

struct Jet {
  static constexpr int kMax = 9;
  double a = 0.0;
  std::array<double, kMax> v{};

  Jet() = default;
  Jet(double value) : a(value) {}  // NOLINT: constants promote implicitly, as in Ceres
  static Jet Variable(double value, int index) {
    Jet j(value);
    j.v[static_cast<std::size_t>(index)] = 1.0;
    return j;
  }
};

inline Jet operator+(const Jet& x, const Jet& y) {
  Jet o(x.a + y.a);
  for (int i = 0; i < Jet::kMax; ++i) o.v[i] = x.v[i] + y.v[i];
  return o;
}
inline Jet operator-(const Jet& x, const Jet& y) {
  Jet o(x.a - y.a);
  for (int i = 0; i < Jet::kMax; ++i) o.v[i] = x.v[i] - y.v[i];
  return o;
}
inline Jet operator-(const Jet& x) {
  return Jet(0.0) - x;
}
inline Jet operator*(const Jet& x, const Jet& y) {
  Jet o(x.a * y.a);
  for (int i = 0; i < Jet::kMax; ++i) o.v[i] = x.v[i] * y.a + x.a * y.v[i];
  return o;
}
inline Jet operator/(const Jet& x, const Jet& y) {
  Jet o(x.a / y.a);
  for (int i = 0; i < Jet::kMax; ++i) o.v[i] = (x.v[i] - o.a * y.v[i]) / y.a;
  return o;
}
inline Jet Scale(const Jet& x, double value, double derivative) {
  Jet o(value);
  for (int i = 0; i < Jet::kMax; ++i) o.v[i] = derivative * x.v[i];
  return o;
}
inline Jet exp(const Jet& x) {
  const double e = std::exp(x.a);
  return Scale(x, e, e);
}
inline Jet log(const Jet& x) {
  return Scale(x, std::log(x.a), 1.0 / x.a);
}
inline Jet sin(const Jet& x) {
  return Scale(x, std::sin(x.a), std::cos(x.a));
}
inline Jet cos(const Jet& x) {
  return Scale(x, std::cos(x.a), -std::sin(x.a));
}
inline Jet atan(const Jet& x) {
  return Scale(x, std::atan(x.a), 1.0 / (1.0 + x.a * x.a));
}
inline Jet pow(const Jet& x, double p) {
  return Scale(x, std::pow(x.a, p), p * std::pow(x.a, p - 1.0));
}
inline Jet pow(double base, const Jet& p) {
  const double v = std::pow(base, p.a);
  return Scale(p, v, v * std::log(base));
}
inline Jet pow(const Jet& x, const Jet& p) {
  return exp(p * log(x));
}

}  // namespace s2m::test
