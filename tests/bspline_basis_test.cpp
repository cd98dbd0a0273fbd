// The fast B-spline evaluation (per-span Taylor tables, bucket span search; fitting/bspline_basis.h) against
// the generic reference (A2.1 + A2.3 of Piegl & Tiller) and against finite differences, and the curve and
// surface models' tensor products against plain sums over the reference basis.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "fitting/bspline_models.h"

namespace s2m {
namespace {

// Non-uniform clamped knots on [lo, hi]: random interior knots, some of them repeated (multiplicity < order).
BSplineBasis RandomClamped(int order, int num_control, double lo, double hi, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(lo, hi);
  std::vector<double> interior;
  const int count = num_control - order;
  while (static_cast<int>(interior.size()) < count) {
    const double k = u(rng);
    interior.push_back(k);
    // A double knot now and then (allowed for order >= 3).
    if (order >= 3 && static_cast<int>(interior.size()) < count && rng() % 4 == 0) interior.push_back(k);
  }
  std::sort(interior.begin(), interior.end());
  std::vector<double> knots(static_cast<std::size_t>(order), lo);
  knots.insert(knots.end(), interior.begin(), interior.end());
  knots.insert(knots.end(), static_cast<std::size_t>(order), hi);
  return BSplineBasis::Clamped(order, std::move(knots));
}

BSplineBasis RandomPeriodic(int order, int num_control, double lo, double hi, std::mt19937_64& rng) {
  // Spacings between 0.2 and 5 (ratio 25 between neighbours at worst), scaled onto [lo, hi].
  std::uniform_real_distribution<double> gap(0.2, 5.0);
  std::vector<double> b{0.0};
  for (int i = 0; i < num_control; ++i) b.push_back(b.back() + gap(rng));
  const double total = b.back();
  for (double& x : b) x = lo + (hi - lo) * x / total;
  b.back() = hi;
  return BSplineBasis::Periodic(order, std::move(b));
}

// Twelve knots within 0.011 of 3 on [0, 10] (span lengths 1e-3 next to 3: the bucket search's binary-search
// branch, and Taylor tables on very unequal spans).
BSplineBasis Clustered(int order) {
  std::vector<double> knots(static_cast<std::size_t>(order), 0.0);
  for (int i = 0; i < 12; ++i) knots.push_back(3.0 + 1e-3 * i);
  knots.push_back(6.0);
  knots.push_back(8.0);
  knots.insert(knots.end(), static_cast<std::size_t>(order), 10.0);
  return BSplineBasis::Clamped(order, std::move(knots));
}

std::vector<BSplineBasis> TestBases(int order, std::mt19937_64& rng) {
  const int n = order + 5;
  return {BSplineBasis::ClampedUniform(order, n, -1.5, 2.0), RandomClamped(order, n + 3, 0.0, 7.0, rng),
          BSplineBasis::PeriodicUniform(order, n, 0.0, 2.0 * M_PI),
          RandomPeriodic(order, n + 2, -3.0, 4.0, rng),
          // Unit-spaced, far from the origin (larger absolute t, as in UnitSpacedClamped fits).
          BSplineBasis::ClampedUniform(order, n + 20, 100.0, 100.0 + n + 21 - order), Clustered(order)};
}

std::string Describe(const BSplineBasis& b) {
  return std::string(b.periodic() ? "periodic" : "clamped") + " order " + std::to_string(b.order()) +
         " on [" + std::to_string(b.lo()) + ", " + std::to_string(b.hi()) + "] with " +
         std::to_string(b.num_control()) + " functions";
}

// The size of derivative d of the basis functions on t's span: the largest coefficient of the span's
// polynomials (~ 1 / length^d). Rounding of any evaluation at t is relative to it; the values at t may be
// far smaller (near a zero of a steep piece, e.g. at a knot next to a span 3000 times shorter).
double SpanScale(const BSplineBasis& b, double t, int d) {
  double y = 0.0, inv_length = 0.0;
  const int s = b.LocateSpan(t, y, inv_length);
  double scale = d == 0 ? 1.0 : 0.0;
  for (int j = 0; j < b.order(); ++j)
    for (int i = 0; i < b.order(); ++i) scale = std::max(scale, std::abs(b.TaylorCoefficient(s, d, j, i)));
  return scale;
}

// Parameters to test: random ones, every knot exactly and its neighbouring doubles, the ends, and (to test
// wrapping and clamping) some outside the domain.
std::vector<double> TestParameters(const BSplineBasis& b, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(b.lo(), b.hi());
  std::vector<double> ts;
  for (int i = 0; i < 400; ++i) ts.push_back(u(rng));
  for (double k : b.Breakpoints()) {
    ts.push_back(k);
    ts.push_back(std::nextafter(k, -INFINITY));
    ts.push_back(std::nextafter(k, INFINITY));
  }
  const double w = b.hi() - b.lo();
  for (double f : {-2.3, -1.0, -0.01, 1.0, 1.37, 3.5}) ts.push_back(b.lo() + f * w);
  return ts;
}

TEST(BSplineBasisFastPath, MatchesReferenceA23ForOrders2To8) {
  std::mt19937_64 rng(20261201);
  double worst[BSplineBasis::kMaxOrder + 1][3] = {};
  for (int order = 2; order <= BSplineBasis::kMaxOrder; ++order) {
    for (const BSplineBasis& b : TestBases(order, rng)) {
      SCOPED_TRACE(Describe(b));
      for (double t : TestParameters(b, rng)) {
        for (int derivatives = 0; derivatives <= 2; ++derivatives) {
          BSplineBasis::Values fast, ref;
          b.Evaluate(t, derivatives, fast);
          b.EvaluateReference(t, derivatives, ref);
          ASSERT_EQ(fast.first, ref.first) << "t = " << t;
          for (int d = 0; d <= derivatives; ++d) {
            const auto ud = static_cast<std::size_t>(d);
            // Relative to the size of this derivative on t's span (1 for d = 0; ~ 1 / length^d otherwise).
            const double scale = SpanScale(b, t, d);
            for (int i = 0; i < order; ++i) {
              const auto ui = static_cast<std::size_t>(i);
              const double err = std::abs(fast.values[ud][ui] - ref.values[ud][ui]);
              if (scale > 0.0) worst[order][d] = std::max(worst[order][d], err / scale);
              const double tol = 1e-14 * scale;  // measured: < 1e-15 (printed below)
              ASSERT_LE(err, tol) << "t = " << t << ", derivative " << d << ", function " << i << ": fast "
                                  << fast.values[ud][ui] << ", reference " << ref.values[ud][ui];
            }
          }
        }
      }
    }
  }
  for (int order = 2; order <= BSplineBasis::kMaxOrder; ++order) {
    std::printf("order %d: worst |fast - reference| / span scale: %.2e (values) %.2e (d1) %.2e (d2)\n", order,
                worst[order][0], worst[order][1], worst[order][2]);
  }
}

TEST(BSplineBasisFastPath, DerivativesMatchFiniteDifferences) {
  std::mt19937_64 rng(7);
  int checked = 0;
  for (int order = 2; order <= 6; ++order) {
    for (const BSplineBasis& b : TestBases(order, rng)) {
      SCOPED_TRACE(Describe(b));
      std::uniform_real_distribution<double> u(b.lo(), b.hi());
      const double w = b.hi() - b.lo(), h = 1e-6 * w;
      for (int k = 0; k < 200; ++k) {
        const double t = u(rng);
        BSplineBasis::Values v, vp, vm;
        b.Evaluate(t, 2, v);
        b.Evaluate(t + h, 2, vp);
        b.Evaluate(t - h, 2, vm);
        if (vp.first != v.first || vm.first != v.first) continue;  // a knot within h: one-sided pieces
        ++checked;
        double s1 = 0.0, s2 = 0.0;  // scales of the first and second derivatives
        for (int i = 0; i < order; ++i) {
          s1 = std::max(s1, std::abs(v.values[1][std::size_t(i)]));
          s2 = std::max(s2, std::abs(v.values[2][std::size_t(i)]));
        }
        for (int i = 0; i < order; ++i) {
          const auto ui = static_cast<std::size_t>(i);
          // Central differences: error ~ h^2 f''' / 6 plus rounding ~ 1e-16 / h.
          EXPECT_NEAR(v.values[1][ui], (vp.values[0][ui] - vm.values[0][ui]) / (2 * h), 1e-6 * (1.0 + s1));
          EXPECT_NEAR(v.values[2][ui], (vp.values[1][ui] - vm.values[1][ui]) / (2 * h), 1e-6 * (1.0 + s2));
        }
        if (order == 2) {
          for (int i = 0; i < order; ++i) EXPECT_EQ(v.values[2][std::size_t(i)], 0.0);  // above the degree
        }
      }
    }
  }
  EXPECT_GT(checked, 5000);  // of 6000 parameters (5 orders x 6 bases x 200), few within h of a knot
}

TEST(BSplineBasisFastPath, PartitionOfUnityAtKnotsAndEnds) {
  std::mt19937_64 rng(11);
  for (int order = 2; order <= BSplineBasis::kMaxOrder; ++order) {
    for (const BSplineBasis& b : TestBases(order, rng)) {
      SCOPED_TRACE(Describe(b));
      for (double t : TestParameters(b, rng)) {
        BSplineBasis::Values v;
        b.Evaluate(t, 2, v);
        double sum = 0.0, d1 = 0.0;
        const double s1 = std::max(1.0, SpanScale(b, t, 1));
        for (int i = 0; i < order; ++i) {
          sum += v.values[0][std::size_t(i)];
          d1 += v.values[1][std::size_t(i)];
          EXPECT_GE(v.values[0][std::size_t(i)], -1e-14);  // non-negative (to rounding)
        }
        EXPECT_NEAR(sum, 1.0, 1e-13);
        EXPECT_NEAR(d1, 0.0, 1e-13 * s1);
      }
    }
  }
}

// The models' tensor products (fixed cubic and generic orders, periodic u) against plain sums of the
// reference basis times the control points.
TEST(BSplineBasisFastPath, SurfaceAndCurveMatchPlainSumsOfReferenceBasis) {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> gauss(0.0, 10.0);
  struct Case {
    BSplineBasis u, v;
  };
  const std::vector<Case> cases = {
      {BSplineBasis::ClampedUniform(4, 7), BSplineBasis::ClampedUniform(4, 9, -2.0, 5.0)},
      {RandomClamped(3, 8, 0.0, 1.0, rng), RandomClamped(5, 9, 0.0, 2.0, rng)},
      {BSplineBasis::PeriodicUniform(4, 8, 0.0, 2 * M_PI), BSplineBasis::ClampedUniform(4, 6)},
      {RandomPeriodic(3, 7, 0.0, 1.0, rng), BSplineBasis::ClampedUniform(2, 4)}};
  for (const Case& c : cases) {
    SCOPED_TRACE(Describe(c.u) + " x " + Describe(c.v));
    const int nu = c.u.num_control(), nv = c.v.num_control();
    Eigen::Matrix3Xd control(3, nu * nv);
    for (Eigen::Index k = 0; k < control.cols(); ++k) control.col(k) << gauss(rng), gauss(rng), gauss(rng);
    const BSplineSurface surface(c.u, c.v, control);
    std::uniform_real_distribution<double> uu(c.u.lo() - 0.2, c.u.hi() + 0.2), vv(c.v.lo(), c.v.hi());
    for (int k = 0; k < 300; ++k) {
      const ParamT t{uu(rng), vv(rng), 0.0};
      for (int derivatives = 0; derivatives <= 2; ++derivatives) {
        LocalGeometry g;
        surface.Evaluate(t, derivatives, g);
        BSplineBasis::Values bu, bv;
        c.u.EvaluateReference(t[0], 2, bu);
        c.v.EvaluateReference(t[1], 2, bv);
        // (a, b) per output: S, S_u, S_v, S_uu, S_uv, S_vv.
        const int a[6] = {0, 1, 0, 2, 1, 0}, bb[6] = {0, 0, 1, 0, 1, 2};
        Eigen::Vector3d expected[6];
        double scale = 1.0;
        for (int m = 0; m < 6; ++m) {
          expected[m].setZero();
          if (a[m] + bb[m] > derivatives) continue;
          for (int i = 0; i < c.u.order(); ++i)
            for (int j = 0; j < c.v.order(); ++j) {
              const int index = c.u.ControlIndex(bu.first, i) * nv + c.v.ControlIndex(bv.first, j);
              expected[m] += bu.values[std::size_t(a[m])][std::size_t(i)] *
                             bv.values[std::size_t(bb[m])][std::size_t(j)] * control.col(index);
            }
          scale = std::max(scale, expected[m].norm());
        }
        const double tol = 1e-13 * scale;
        EXPECT_LE((To3(g.point) - expected[0]).norm(), tol);
        ASSERT_EQ(g.d1.cols(), 2);
        ASSERT_EQ(g.d2.cols(), 3);
        for (int m = 1; m < 3; ++m) EXPECT_LE((Eigen::Vector3d(g.d1.col(m - 1)) - expected[m]).norm(), tol);
        for (int m = 3; m < 6; ++m) EXPECT_LE((Eigen::Vector3d(g.d2.col(m - 3)) - expected[m]).norm(), tol);
      }
    }
  }
  for (int s = 2; s <= 3; ++s) {
    for (const BSplineBasis& b :
         {BSplineBasis::PeriodicUniform(4, 9), RandomClamped(5, 11, -1.0, 1.0, rng)}) {
      SCOPED_TRACE(Describe(b) + ", " + std::to_string(s) + "D curve");
      Eigen::MatrixXd control(s, b.num_control());
      for (Eigen::Index k = 0; k < control.size(); ++k) control.data()[k] = gauss(rng);
      const BSplineCurve curve(b, control);
      std::uniform_real_distribution<double> tt(b.lo() - 0.3, b.hi() + 0.3);
      for (int k = 0; k < 300; ++k) {
        const ParamT t{tt(rng), 0.0, 0.0};
        LocalGeometry g;
        curve.Evaluate(t, 2, g);
        BSplineBasis::Values v;
        b.EvaluateReference(t[0], 2, v);
        Eigen::VectorXd expected[3] = {Eigen::VectorXd::Zero(s), Eigen::VectorXd::Zero(s),
                                       Eigen::VectorXd::Zero(s)};
        for (int d = 0; d < 3; ++d)
          for (int i = 0; i < b.order(); ++i)
            expected[d] += v.values[std::size_t(d)][std::size_t(i)] * control.col(b.ControlIndex(v.first, i));
        const double scale = std::max({1.0, expected[0].norm(), expected[1].norm(), expected[2].norm()});
        ASSERT_EQ(g.point.size(), s);
        EXPECT_LE((Eigen::VectorXd(g.point) - expected[0]).norm(), 1e-13 * scale);
        EXPECT_LE((Eigen::VectorXd(g.d1.col(0)) - expected[1]).norm(), 1e-13 * scale);
        EXPECT_LE((Eigen::VectorXd(g.d2.col(0)) - expected[2]).norm(), 1e-13 * scale);
      }
    }
  }
}

// The bicubic patch tables follow the control points: after set_parameters and ApplySimilarity the surface
// evaluates like a freshly built one.
TEST(BSplineBasisFastPath, SurfacePatchTablesFollowParameterChanges) {
  std::mt19937_64 rng(5);
  std::normal_distribution<double> gauss(0.0, 5.0);
  const BSplineBasis u = BSplineBasis::PeriodicUniform(4, 7, 0.0, 2 * M_PI),
                     v = RandomClamped(4, 8, 0, 3, rng);
  Eigen::Matrix3Xd control(3, u.num_control() * v.num_control());
  for (Eigen::Index k = 0; k < control.size(); ++k) control.data()[k] = gauss(rng);
  BSplineSurface surface(u, v, control);
  Eigen::VectorXd p = surface.parameters();
  for (Eigen::Index k = 0; k < p.size(); ++k) p[k] += gauss(rng);
  surface.set_parameters(p);
  surface.ApplySimilarity(1.7, Eigen::Vector3d(0.3, -2.0, 5.0));
  Eigen::Matrix3Xd moved = Eigen::Map<const Eigen::Matrix3Xd>(p.data(), 3, control.cols());
  moved = (1.7 * moved).colwise() + Eigen::Vector3d(0.3, -2.0, 5.0);
  const BSplineSurface fresh(u, v, moved);
  std::uniform_real_distribution<double> uu(u.lo(), u.hi()), vv(v.lo(), v.hi());
  for (int k = 0; k < 200; ++k) {
    const ParamT t{uu(rng), vv(rng), 0.0};
    LocalGeometry a, b;
    surface.Evaluate(t, 2, a);
    fresh.Evaluate(t, 2, b);
    const double scale = std::max(1.0, b.point.norm());
    EXPECT_LE((a.point - b.point).norm(), 1e-13 * scale);
    EXPECT_LE((a.d1 - b.d1).norm(), 1e-13 * std::max(1.0, b.d1.norm()));
    EXPECT_LE((a.d2 - b.d2).norm(), 1e-13 * std::max(1.0, b.d2.norm()));
  }
}

// Likewise the curve's span tables.
TEST(BSplineBasisFastPath, CurveSpanTablesFollowParameterChanges) {
  std::mt19937_64 rng(8);
  std::normal_distribution<double> gauss(0.0, 5.0);
  const BSplineBasis b = RandomPeriodic(4, 9, 0.0, 1.0, rng);
  Eigen::MatrixXd control(2, b.num_control());
  for (Eigen::Index k = 0; k < control.size(); ++k) control.data()[k] = gauss(rng);
  BSplineCurve curve(b, control);
  Eigen::VectorXd p = curve.parameters();
  for (Eigen::Index k = 0; k < p.size(); ++k) p[k] += gauss(rng);
  curve.set_parameters(p);
  VecS offset(2);
  offset << 0.5, -1.5;
  curve.ApplySimilarity(0.8, offset);
  Eigen::MatrixXd moved = Eigen::Map<const Eigen::MatrixXd>(p.data(), 2, control.cols());
  moved = (0.8 * moved).colwise() + Eigen::Vector2d(0.5, -1.5);
  const BSplineCurve fresh(b, moved);
  std::uniform_real_distribution<double> tt(-1.0, 2.0);
  for (int k = 0; k < 200; ++k) {
    const ParamT t{tt(rng), 0.0, 0.0};
    LocalGeometry g1, g2;
    curve.Evaluate(t, 2, g1);
    fresh.Evaluate(t, 2, g2);
    EXPECT_LE((g1.point - g2.point).norm(), 1e-13 * std::max(1.0, g2.point.norm()));
    EXPECT_LE((g1.d1 - g2.d1).norm(), 1e-13 * std::max(1.0, g2.d1.norm()));
    EXPECT_LE((g1.d2 - g2.d2).norm(), 1e-13 * std::max(1.0, g2.d2.norm()));
  }
}

}  // namespace
}  // namespace s2m
