#pragma once
// FastAtan2(y, x): std::atan2 to double precision (measured within 2 ulp of glibc's result, typically 0 or 1;
// tests/fast_atan2_test.cpp) at a fraction of its cost, for the closed-form foot points of the primitives and
// part faces, where glibc's atan2 (about 22 ns a call here) was most of the per-point cost.
//
// Method (the classical table-driven reduction, e.g. Tang, "Table-lookup algorithms for elementary
// functions", ACM TOMS 1990; Muller, "Elementary Functions", 3rd ed., section 6.2):
//   1. Octant reduction: with a = |x|, b = |y|, z = min(a, b) / max(a, b) in [0, 1], and
//        atan2(y, x) = sign(y) * B,  B = atan z (b <= a, x >= 0),  pi/2 - atan z (b > a, x >= 0),
//                                      pi - atan z (b <= a, x < 0),  pi/2 + atan z (b > a, x < 0).
//   2. Argument reduction about tabulated centres c_k = k / 64 (k = round(64 z); k = 0 when z < 3.5/64):
//        atan z = atan c_k + atan r,  r = (z - c_k) / (1 + z c_k)
//      (the addition theorem tan(p - q) = (tan p - tan q) / (1 + tan p tan q) with tan p = z, tan q = c_k),
//      so |r| <= 1/128 for k >= 4 and |r| = z < 3.5/64 for k = 0. z - c_k is exact (Sterbenz: c_k/2 <= z <= 2
//      c_k for k >= 1).
//   3. atan r by its odd Taylor series to r^13: an alternating series with decreasing terms for |r| < 1, so
//      the truncation error is below the first omitted term, |r|^15 / 15 <= 0.0547^14 / 15 |r| < 2^-62 |r|:
//      far below the rounding of the result.
//   The constants B_k = offset +- atan c_k are tabulated once in long double (64-bit significand on x86-64)
//   and stored as an unevaluated sum hi + lo of two doubles, so the table adds no error at double precision;
//   the result is hi + (lo +- atan r). The rounding errors: z = b / a (half an ulp, propagated by
//   z atan'(z) / atan z <= 1), r (a few units of 2^-53 of |r|, and |r| <= 0.143 |result| for k >= 4; r = z
//   exactly for k = 0), and the final addition (half an ulp): about 1.2 ulp from the exact value at worst.
//
// Special values follow std::atan2 (C99 Annex F.9.1.4): +-0 for y = +-0 and x > 0 or x = +0, +-pi for y = +-0
// and x < 0 or x = -0, +-pi/2 for x = +-0 and y != 0, +-pi/4 and +-3pi/4 for infinite x and y, NaN for a NaN
// argument. Arguments of any magnitude (subnormal to DBL_MAX) are rescaled before the reduction so that no
// intermediate overflows or loses precision to underflow.

#include <cmath>

namespace s2m {
namespace fast_atan2_detail {

constexpr int kCentres = 64;  // c_k = k / kCentres, k = 0..kCentres

struct Entry {
  double hi, lo;  // B = hi + lo, |lo| <= ulp(hi) / 2
  double sign;    // how atan r enters: B +- atan r
};

// B for the four octant cases (index case * (kCentres + 1) + k; case = 2 * (x < 0) + (b > a)).
struct Table {
  Entry b[4 * (kCentres + 1)];
  Table() {
    const long double pi = 3.14159265358979323846264338327950288L;
    for (int k = 0; k <= kCentres; ++k) {
      const long double t = std::atan(static_cast<long double>(k) / kCentres);
      const long double values[4] = {t, pi / 2 - t, pi - t, pi / 2 + t};
      for (int c = 0; c < 4; ++c) {
        const double hi = static_cast<double>(values[c]);
        b[c * (kCentres + 1) + k] = {hi, static_cast<double>(values[c] - static_cast<long double>(hi)),
                                     c == 0 || c == 3 ? 1.0 : -1.0};
      }
    }
  }
};

inline const Table& GetTable() {
  static const Table table;  // built once, thread-safe (function-local static)
  return table;
}

// The general reduction, for a = |x|, b = |y| not NaN with max(a, b) in [2^-901, 2^1000]: no overflow or
// division by zero, and no intermediate that matters is subnormal (which would cost relative precision).
inline double Reduced(double y, double x, double a, double b) {
  // Branch-free (minsd, maxsd, a mask): which octant a foot point lies in is random, a branch on it would be
  // mispredicted half the time.
  const bool swap = b > a;
  const double lo = b < a ? b : a, hi = a < b ? b : a;
  const double z = lo / hi;
  int k = static_cast<int>(z * kCentres + 0.5);
  k &= -static_cast<int>(k >= 4);  // k < 4: k = 0, the series on z itself (|r| small relative to the result)
  const double c = static_cast<double>(k) * (1.0 / kCentres);
  const double r = (z - c) / (1.0 + z * c);
  const double w = r * r, w2 = w * w;
  // Odd Taylor series r - r^3/3 + ... + r^13/13, inner part in Estrin's form (shorter dependency chains).
  const double q =
      (-1.0 / 3 + w * (1.0 / 5)) + w2 * ((-1.0 / 7 + w * (1.0 / 9)) + w2 * (-1.0 / 11 + w * (1.0 / 13)));
  const double p = r + r * (w * q);
  const Entry& e =
      GetTable().b[(2 * static_cast<int>(std::signbit(x)) + static_cast<int>(swap)) * (kCentres + 1) + k];
  return std::copysign(e.hi + (e.lo + e.sign * p), y);
}

// The rare cases: NaN, infinities, zeros, and arguments outside [2^-900, 2^1000] (rescaled by a power of two,
// exact, or exact enough: a lost bit of min(a, b) only matters when the result underflows anyway).
inline double Special(double y, double x, double a, double b) {
  constexpr double kPi = 3.141592653589793238462643383279502884;
  if (std::isnan(x) || std::isnan(y)) return x + y;
  const bool x_negative = std::signbit(x);
  if (std::isinf(a) || std::isinf(b)) {
    if (std::isinf(a) && std::isinf(b)) return std::copysign(x_negative ? 3 * kPi / 4 : kPi / 4, y);
    if (std::isinf(b)) return std::copysign(kPi / 2, y);
    return std::copysign(x_negative ? kPi : 0.0, y);
  }
  const double sum = a + b;
  if (sum == 0.0) return std::copysign(x_negative ? kPi : 0.0, y);
  const double scale = sum < 0x1p-900 ? 0x1p200 : 0x1p-200;  // max(a, b) into [2^-875, 2^825]
  return Reduced(y * scale, x * scale, a * scale, b * scale);
}

}  // namespace fast_atan2_detail

// atan2(y, x) in (-pi, pi], as std::atan2 to within 2 ulp (see above), with its special values.
inline double FastAtan2(double y, double x) {
  const double a = std::abs(x), b = std::abs(y);
  // a + b is NaN if either is, infinite if either is, and within a factor 2 of max(a, b): one test sends NaN,
  // zeros, infinities and extreme magnitudes to the slow path.
  const double sum = a + b;
  if (sum >= 0x1p-900 && sum <= 0x1p1000) return fast_atan2_detail::Reduced(y, x, a, b);
  return fast_atan2_detail::Special(y, x, a, b);
}

}  // namespace s2m
