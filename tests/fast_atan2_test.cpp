// FastAtan2 (fitting/fast_atan2.h) against std::atan2: within 2 ulp over random arguments of every magnitude,
// near the octant boundaries and the table's switch points, and exactly std::atan2's special values (signed
// zeros, zeros, infinities, NaN, extreme ratios, subnormals).

#include "fitting/fast_atan2.h"

#include <gtest/gtest.h>

#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

namespace s2m {
namespace {

// Distance in units in the last place: the doubles ordered as integers (negative ones mirrored), so that
// adjacent doubles are 1 apart, across zero and binades, subnormals included.
std::int64_t Ordered(double d) {
  std::int64_t i = 0;
  std::memcpy(&i, &d, sizeof d);
  return i < 0 ? std::numeric_limits<std::int64_t>::min() - i : i;
}

std::int64_t UlpDistance(double a, double b) {
  const std::int64_t d = Ordered(a) - Ordered(b);
  return d < 0 ? -d : d;
}

constexpr std::int64_t kMaxUlp = 2;

// The largest ulp distance over the pairs, and the first pair that reaches it.
struct Worst {
  std::int64_t ulp = 0;
  double y = 0.0, x = 0.0;
  void Add(double yy, double xx) {
    const std::int64_t d = UlpDistance(FastAtan2(yy, xx), std::atan2(yy, xx));
    if (d > ulp) {
      ulp = d;
      y = yy;
      x = xx;
    }
  }
};

double RandomSign(std::mt19937_64& rng, double v) {
  return (rng() & 1) != 0 ? -v : v;
}

TEST(FastAtan2, WithinTwoUlpOverRandomArgumentsOfEveryMagnitude) {
  std::mt19937_64 rng(20261201);
  std::uniform_real_distribution<double> mantissa(1.0, 2.0);
  // Exponent ranges: similar magnitudes (the common case), a wide band, and the whole double range (ratios
  // from underflow to overflow, subnormal and huge arguments).
  const int ranges[3][2] = {{-3, 3}, {-60, 60}, {-1074, 1023}};
  long count = 0;
  for (const auto& range : ranges) {
    std::uniform_int_distribution<int> exponent(range[0], range[1]);
    Worst worst;
    for (int i = 0; i < 400000; ++i, ++count) {
      const double x = RandomSign(rng, std::ldexp(mantissa(rng), exponent(rng)));
      const double y = RandomSign(rng, std::ldexp(mantissa(rng), exponent(rng)));
      worst.Add(y, x);
    }
    EXPECT_LE(worst.ulp, kMaxUlp) << "exponents " << range[0] << ".." << range[1] << ": atan2(" << worst.y
                                  << ", " << worst.x << ")";
  }
  EXPECT_GE(count, 1000000);
}

TEST(FastAtan2, WithinTwoUlpOnTheUnitCircleAndNearTableSwitchPoints) {
  // Uniform angles (what foot points see), and ratios z = min/max right at and around the points where the
  // reduction changes its centre ((k + 1/2) / 64) or leaves the series on z itself (3.5 / 64), and at the
  // octant boundaries (|y| = |x|, and y or x nearly 0).
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> angle(-M_PI, M_PI), scale(1e-3, 1e3);
  Worst worst;
  for (int i = 0; i < 200000; ++i) {
    const double a = angle(rng), s = scale(rng);
    worst.Add(s * std::sin(a), s * std::cos(a));
  }
  auto add_all_octants = [&worst](double z) {
    for (const double sx : {1.0, -1.0}) {
      for (const double sy : {1.0, -1.0}) {
        worst.Add(sy * z, sx * 1.0);  // |y| <= |x|
        worst.Add(sy * 1.0, sx * z);  // |y| >= |x|
        worst.Add(sy * z * 3.7, sx * 3.7);
      }
    }
  };
  for (int k = 0; k <= 128; ++k) {
    // 64 neighbouring doubles on either side of k / 128.
    for (const double direction : {0.0, 2.0}) {
      double z = k / 128.0;
      for (int step = 0; step < 64 && z <= 1.0; ++step, z = std::nextafter(z, direction)) add_all_octants(z);
    }
  }
  EXPECT_LE(worst.ulp, kMaxUlp) << "atan2(" << worst.y << ", " << worst.x << ")";
}

TEST(FastAtan2, SpecialValuesAsStdAtan2) {
  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double denorm = std::numeric_limits<double>::denorm_min();
  const std::vector<double> values = {0.0,     -0.0,     1.0,      -1.0,       2.5,
                                      -2.5,    inf,      -inf,     DBL_MAX,    -DBL_MAX,
                                      DBL_MIN, -DBL_MIN, denorm,   -denorm,    1e-310,
                                      -1e-310, 0x1p-900, 0x1p1000, 0x1p1001,   0x1p-901,
                                      1e300,   -1e300,   1e-300,   3 * denorm, 0x1p-1022 * 0.75};
  for (const double y : values) {
    for (const double x : values) {
      const double fast = FastAtan2(y, x), ref = std::atan2(y, x);
      ASSERT_FALSE(std::isnan(fast)) << "atan2(" << y << ", " << x << ")";
      // Exact where the reference is a special value (zeros with their sign, multiples of pi/4), else 2 ulp.
      EXPECT_LE(UlpDistance(fast, ref), kMaxUlp)
          << "atan2(" << y << ", " << x << ") = " << ref << ", got " << fast;
      EXPECT_EQ(std::signbit(fast), std::signbit(ref)) << "atan2(" << y << ", " << x << ")";
    }
    EXPECT_TRUE(std::isnan(FastAtan2(y, nan)));
    EXPECT_TRUE(std::isnan(FastAtan2(nan, y)));
  }
  EXPECT_TRUE(std::isnan(FastAtan2(nan, nan)));
  // The values C99 Annex F.9.1.4 fixes, bit for bit.
  EXPECT_EQ(Ordered(FastAtan2(0.0, 0.0)), Ordered(0.0));
  EXPECT_EQ(Ordered(FastAtan2(-0.0, 0.0)), Ordered(-0.0));
  EXPECT_EQ(FastAtan2(0.0, -0.0), std::atan2(0.0, -0.0));
  EXPECT_EQ(FastAtan2(-0.0, -0.0), std::atan2(-0.0, -0.0));
  EXPECT_EQ(FastAtan2(0.0, -1.0), std::atan2(0.0, -1.0));
  EXPECT_EQ(FastAtan2(-0.0, -1.0), std::atan2(-0.0, -1.0));
  EXPECT_EQ(Ordered(FastAtan2(-0.0, 1.0)), Ordered(-0.0));
  EXPECT_EQ(FastAtan2(1.0, 0.0), std::atan2(1.0, 0.0));
  EXPECT_EQ(FastAtan2(-1.0, -0.0), std::atan2(-1.0, -0.0));
  EXPECT_EQ(FastAtan2(inf, inf), std::atan2(inf, inf));
  EXPECT_EQ(FastAtan2(-inf, -inf), std::atan2(-inf, -inf));
  EXPECT_EQ(FastAtan2(inf, -3.0), std::atan2(inf, -3.0));
  EXPECT_EQ(FastAtan2(3.0, -inf), std::atan2(3.0, -inf));
  EXPECT_EQ(Ordered(FastAtan2(-3.0, inf)), Ordered(-0.0));
  EXPECT_EQ(FastAtan2(1.0, 1.0), std::atan2(1.0, 1.0));
  EXPECT_EQ(FastAtan2(-7.0, -7.0), std::atan2(-7.0, -7.0));
}

TEST(FastAtan2, ExtremeRatiosUnderflowAndSaturateAsStdAtan2) {
  // y / x below the smallest subnormal, and x / y so small that the angle is pi/2 to the last bit.
  const double pairs[][2] = {{1e-300, 1e300},  {-1e-300, 1e300},  {1e-300, -1e300},  {1e300, 1e-300},
                             {1e-320, 1.0},    {1.0, 1e-320},     {1e-320, 1e-320},  {DBL_MAX, DBL_MAX},
                             {DBL_MAX, -1e-3}, {5e-324, DBL_MAX}, {-DBL_MAX, 5e-324}};
  for (const auto& p : pairs) {
    EXPECT_LE(UlpDistance(FastAtan2(p[0], p[1]), std::atan2(p[0], p[1])), kMaxUlp)
        << "atan2(" << p[0] << ", " << p[1] << ")";
  }
}

}  // namespace
}  // namespace s2m
