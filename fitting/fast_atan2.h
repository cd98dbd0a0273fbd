#pragma once
// FastAtan2(y, x): std::atan2 to double precision (measured within 1 ulp of glibc's result over 9M random
// pairs; the test asserts 2: tests/fast_atan2_test.cpp), for the closed-form foot points of the primitives
// and part faces, where glibc's atan2 (about 22 ns a call on a quiet machine) was most of the per-point cost.
// About two thirds of glibc's instructions (callgrind), no branch on the data (the octant of a foot point is
// random) and no division after z's, so its dependency chain is no longer than glibc's.
//
// Method (table-driven, e.g. Tang, "Table-lookup algorithms for elementary functions", ACM TOMS 15(2), 1989;
// Muller, "Elementary Functions", 3rd ed., chapter 6):
//   1. Octant reduction: with a = |x|, b = |y|, z = min(a, b) / max(a, b) in [0, 1],
//        atan2(y, x) = sign(y) * B,  B = atan z (b <= a, x >= 0),  pi/2 - atan z (b > a, x >= 0),
//                                      pi - atan z (b <= a, x < 0),  pi/2 + atan z (b > a, x < 0).
//   2. Centres c_k = k / 64, k = round(64 z), and k = 0 when z < 3.5/64; d = z - c_k is exact (Sterbenz:
//      c_k/2 <= z <= 2 c_k for k >= 1), |d| <= 1/128 for k >= 4 and d = z < 3.5/64 for k = 0.
//   3. atan z = atan c_k + sum_{n=1..13} a_n(c_k) d^n + remainder, the Taylor series of atan about c_k. From
//      atan'(x) = 1 / (1 + x^2) = Im (x - i)^-1: atan^(n)(c) = (-1)^(n-1) (n-1)! Im (c - i)^-n, so
//      a_n(c) = (-1)^(n-1) Im((c - i)^-n) / n and |a_n| <= (1 + c^2)^(-n/2) / n <= 1 / n. Remainder: for
//      k >= 4 at most sum_{n>=14} |d|^n / n < 2^-98; for k = 0 (c = 0: the odd series z - z^3/3 + ...,
//      alternating with decreasing terms) below the first omitted term z^15 / 15 < 2^-62 z. Both far below
//      the rounding.
//   The offsets B_k = offset +- atan c_k and the coefficients a_n(c_k) are computed once in long double
//   (64-bit significand on x86-64); B_k is stored as an unevaluated sum hi + lo of two doubles, so it adds no
//   error at double precision: the result is hi + (lo +- Q), Q the polynomial. The rounding errors: z = b / a
//   (half an ulp, propagated by z atan'(z) / atan z <= 1), Q (about 2 units of 2^-53 of |Q| <= |d|, with |d|
//   <= 0.143 |result| for k >= 4; for k = 0, a_1 = 1 and the leading term d is exact), and the final addition
//   (half an ulp): about 1.2 ulp from the exact value at worst.
//
// Special values follow std::atan2 (C99 Annex F.9.1.4): +-0 for y = +-0 and x > 0 or x = +0, +-pi for y = +-0
// and x < 0 or x = -0, +-pi/2 for x = +-0 and y != 0, +-pi/4 and +-3pi/4 for infinite x and y, NaN for a NaN
// argument. Arguments of any magnitude (subnormal to DBL_MAX) are rescaled before the reduction so that no
// intermediate overflows or loses precision to underflow.

#include <cmath>
#include <cstdint>
#include <cstring>

// Rare paths out of line: inlined at every call they multiplied the callers' code several times over.
#if defined(__GNUC__)
#define S2M_FAST_ATAN2_COLD __attribute__((noinline, cold))
#else
#define S2M_FAST_ATAN2_COLD
#endif

namespace s2m {
namespace fast_atan2_detail {

constexpr int kCentres = 64;  // c_k = k / kCentres, k = 0..kCentres
constexpr int kDegree = 13;   // of the Taylor polynomial of atan about c_k

struct Offset {
  double hi, lo;  // B = hi + lo, |lo| <= ulp(hi) / 2
};

struct Table {
  // B for the four octant cases (index case * (kCentres + 1) + k; case = 2 * (x < 0) + (b > a)).
  Offset offset[4 * (kCentres + 1)];
  // Taylor coefficients a_n(c_k), n = 1..kDegree, of atan(c_k + d) - atan(c_k) (a_n at [k][n - 1]).
  double coefficient[kCentres + 1][kDegree];
  S2M_FAST_ATAN2_COLD Table() {
    const long double pi = 3.14159265358979323846264338327950288L;
    for (int k = 0; k <= kCentres; ++k) {
      const long double c = static_cast<long double>(k) / kCentres;
      const long double t = std::atan(c);
      const long double values[4] = {t, pi / 2 - t, pi - t, pi / 2 + t};
      for (int o = 0; o < 4; ++o) {
        const double hi = static_cast<double>(values[o]);
        offset[o * (kCentres + 1) + k] = {hi, static_cast<double>(values[o] - static_cast<long double>(hi))};
      }
      // atan'(x) = 1 / (1 + x^2) = Im (x - i)^-1, so atan^(n)(c) = (-1)^(n-1) (n-1)! Im (c - i)^-n and
      // a_n = atan^(n)(c) / n! = (-1)^(n-1) Im((c - i)^-n) / n.
      const long double norm = 1 + c * c;
      const long double wr = c / norm, wi = 1 / norm;  // (c - i)^-1 = (c + i) / (1 + c^2)
      long double pr = 1, pi_n = 0;
      for (int n = 1; n <= kDegree; ++n) {
        const long double r = pr * wr - pi_n * wi, i = pr * wi + pi_n * wr;
        pr = r;
        pi_n = i;
        coefficient[k][n - 1] = static_cast<double>((n % 2 == 1 ? 1 : -1) * pi_n / n);
      }
    }
  }
};

inline const Table& GetTable() {
  static const Table table;  // built once, thread-safe (function-local static)
  return table;
}

constexpr double kSign[4] = {1.0, -1.0, -1.0, 1.0};  // how atan z enters B, per octant case

// The general reduction, for a = |x|, b = |y| not NaN with max(a, b) in [2^-901, 2^1000]: no overflow or
// division by zero, and no intermediate that matters is subnormal (which would cost relative precision).
inline double Reduced(double y, double x, double a, double b) {
  // Branch-free (minsd, maxsd, masks): which octant a foot point lies in is random, a branch on it would be
  // mispredicted half the time.
  const bool swap = b > a;
  const double lo = b < a ? b : a, hi = a < b ? b : a;
  const double z = lo / hi;
  // k = round(64 z) without the float-int-float round trip (the critical path): adding 1.5 2^52 leaves k in
  // the low bits of the significand, and c_k after subtracting it again.
  constexpr double kShift = 0x1.8p52;
  const double shifted = z * kCentres + kShift;
  std::uint64_t bits = 0;
  std::memcpy(&bits, &shifted, sizeof bits);
  // (Another rounding mode than the default would give floor or ceiling: |d| <= 1/64, still far inside the
  // series' accuracy.) k < 4: k = 0, the series on z itself, so that |d| stays small against the result.
  const bool near_zero = z < 3.5 / kCentres;
  const std::uint64_t keep = near_zero ? 0 : ~std::uint64_t{0};
  const int k = static_cast<int>(bits & 0x7f & keep);
  // c_k, or 0 for k < 4 (a product rather than a select, which the compiler would make a branch).
  const double c = ((shifted - kShift) * (1.0 / kCentres)) * static_cast<double>(!near_zero);
  const double d = z - c;  // exact (see above)
  const Table& table = GetTable();
  const double* a_n = table.coefficient[k];
  const int octant = 2 * static_cast<int>(std::signbit(x)) + static_cast<int>(swap);
  const Offset& e = table.offset[octant * (kCentres + 1) + k];
  // Q = sign (a_1 d + d^2 R(d)), R in Estrin's form (short dependency chains). For k = 0, a_1 = 1 and the
  // leading term is exact.
  const double sd = kSign[octant] * d, d2 = d * d, d4 = d2 * d2, d8 = d4 * d4;
  const double r = ((a_n[1] + d * a_n[2]) + d2 * (a_n[3] + d * a_n[4])) +
                   d4 * ((a_n[5] + d * a_n[6]) + d2 * (a_n[7] + d * a_n[8])) +
                   d8 * ((a_n[9] + d * a_n[10]) + d2 * (a_n[11] + d * a_n[12]));
  const double q = sd * a_n[0] + (sd * d) * r;
  return std::copysign(e.hi + (e.lo + q), y);
}

// The rare cases: NaN, infinities, zeros, and arguments outside [2^-900, 2^1000] (rescaled by a power of two,
// exact, or exact enough: a lost bit of min(a, b) only matters when the result underflows anyway).
S2M_FAST_ATAN2_COLD inline double Special(double y, double x, double a, double b) {
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
