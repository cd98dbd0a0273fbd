// Hermite finite-element curves (fitting/hermite_curve.h), their exact element and junction matrices
// (fitting/element_energy.h) and the Bernstein root isolation of their foot points
// (fitting/bernstein_roots.h), checked against L. Fang's printed tables (Tables 3.1 and 3.2, the junction
// vectors of eqs. 3.2.5-3.2.7), Gauss quadrature, one-sided finite differences, and brute-force sampling.

#include "fitting/hermite_curve.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>

#include "fitting/bernstein_roots.h"
#include "fitting/element_energy.h"

namespace s2m {
namespace {

// Fang's Table 3.1, written out: the shape functions at t = u / h.
Eigen::VectorXd TableShapeFunctions(int degree, double h, double t) {
  if (degree == 3) {
    Eigen::VectorXd v(4);
    v << 1 - 3 * t * t + 2 * t * t * t, h * (t - 2 * t * t + t * t * t), 3 * t * t - 2 * t * t * t,
        h * (-t * t + t * t * t);
    return v;
  }
  const double t2 = t * t, t3 = t2 * t, t4 = t3 * t, t5 = t4 * t;
  Eigen::VectorXd v(6);
  v << 1 - 10 * t3 + 15 * t4 - 6 * t5, h * (t - 6 * t3 + 8 * t4 - 3 * t5),
      h * h * (0.5 * t2 - 1.5 * t3 + 1.5 * t4 - 0.5 * t5), 10 * t3 - 15 * t4 + 6 * t5,
      h * (-4 * t3 + 7 * t4 - 3 * t5), h * h * (0.5 * t3 - t4 + 0.5 * t5);
  return v;
}

// Fang's Table 3.2 (every entry; the printed upper triangles written out in full).
Eigen::MatrixXd TableElementMatrix(int degree, int p, double h) {
  Eigen::MatrixXd k;
  if (degree == 3) {
    k.resize(4, 4);
    if (p == 1) {
      k << 36, 3 * h, -36, 3 * h, 3 * h, 4 * h * h, -3 * h, -h * h, -36, -3 * h, 36, -3 * h, 3 * h, -h * h,
          -3 * h, 4 * h * h;
      return k / (30 * h);
    }
    if (p == 2) {
      k << 12, 6 * h, -12, 6 * h, 6 * h, 4 * h * h, -6 * h, 2 * h * h, -12, -6 * h, 12, -6 * h, 6 * h,
          2 * h * h, -6 * h, 4 * h * h;
      return k / std::pow(h, 3);
    }
    k << 4, 2 * h, -4, 2 * h, 2 * h, h * h, -2 * h, h * h, -4, -2 * h, 4, -2 * h, 2 * h, h * h, -2 * h, h * h;
    return 36 * k / std::pow(h, 5);
  }
  const double h2 = h * h, h3 = h2 * h, h4 = h3 * h;
  k.resize(6, 6);
  if (p == 1) {
    k << 1800, 270 * h, 15 * h2, -1800, 270 * h, -15 * h2,         //
        270 * h, 288 * h2, 21 * h3, -270 * h, -18 * h2, 6 * h3,    //
        15 * h2, 21 * h3, 2 * h4, -15 * h2, -6 * h3, h4,           //
        -1800, -270 * h, -15 * h2, 1800, -270 * h, 15 * h2,        //
        270 * h, -18 * h2, -6 * h3, -270 * h, 288 * h2, -21 * h3,  //
        -15 * h2, 6 * h3, h4, 15 * h2, -21 * h3, 2 * h4;
    return k / (1260 * h);
  }
  if (p == 2) {
    k << 1200, 600 * h, 30 * h2, -1200, 600 * h, -30 * h2,        //
        600 * h, 384 * h2, 22 * h3, -600 * h, 216 * h2, -8 * h3,  //
        30 * h2, 22 * h3, 6 * h4, -30 * h2, 8 * h3, h4,           //
        -1200, -600 * h, -30 * h2, 1200, -600 * h, 30 * h2,       //
        600 * h, 216 * h2, 8 * h3, -600 * h, 384 * h2, -22 * h3,  //
        -30 * h2, -8 * h3, h4, 30 * h2, -22 * h3, 6 * h4;
    return k / (70 * h3);
  }
  k << 240, 120 * h, 20 * h2, -240, 120 * h, -20 * h2,        //
      120 * h, 64 * h2, 12 * h3, -120 * h, 56 * h2, -8 * h3,  //
      20 * h2, 12 * h3, 3 * h4, -20 * h2, 8 * h3, -h4,        //
      -240, -120 * h, -20 * h2, 240, -120 * h, 20 * h2,       //
      120 * h, 56 * h2, 8 * h3, -120 * h, 64 * h2, -12 * h3,  //
      -20 * h2, -8 * h3, -h4, 20 * h2, -12 * h3, 3 * h4;
  return 3 * k / std::pow(h, 5);
}

// Relative comparison of two matrices: |a - b| / |b|, rounding of a few hundred operations.
double RelativeError(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return (a - b).norm() / b.norm();
}

TEST(HermiteShapeFunctions, MatchFangTable31AndInterpolateTheNodalData) {
  for (const int degree : {3, 5}) {
    const double h = 0.37;
    const ElementBasis basis = HermiteElementBasis(degree, h);
    for (const double t : {0.0, 0.13, 0.5, 0.77, 1.0}) {
      EXPECT_LT((ElementDerivativeRow(basis, 0, t) - TableShapeFunctions(degree, h, t)).norm(), 1e-13)
          << "degree " << degree << " t " << t;
    }
    // phi_i^(j) at the ends is 1 exactly for the dof it belongs to and 0 for the others (eq. 3.2.2).
    const int per_node = (degree + 1) / 2;
    for (int j = 0; j < per_node; ++j) {
      const Eigen::VectorXd at0 = ElementDerivativeRow(basis, j, 0.0),
                            at1 = ElementDerivativeRow(basis, j, 1.0);
      for (int i = 0; i < degree + 1; ++i) {
        EXPECT_NEAR(at0[i], i == j ? 1.0 : 0.0, 1e-12)
            << "degree " << degree << " function " << i << " d" << j;
        EXPECT_NEAR(at1[i], i == per_node + j ? 1.0 : 0.0, 1e-12) << "degree " << degree << " function " << i;
      }
    }
  }
}

TEST(HermiteElementMatrices, MatchFangTable32AndGaussQuadrature) {
  for (const int degree : {3, 5}) {
    for (const double h : {1.0, 0.2, 0.037}) {
      const ElementBasis basis = HermiteElementBasis(degree, h);
      for (int p = 1; p <= 3; ++p) {
        const Eigen::MatrixXd exact = ElementEnergyMatrix(basis, p);
        // The table's entries are exact rationals times powers of h; ours come from an inverted Hermite
        // matrix and moments: agreement to rounding (1e-12 relative) on all scales of h.
        EXPECT_LT(RelativeError(exact, TableElementMatrix(degree, p, h)), 1e-12)
            << "degree " << degree << " p " << p << " h " << h;
        // Gauss-Legendre with 6 nodes integrates degree 11 exactly: (phi^(p))^2 has degree <= 2 (5 - p).
        const double x[6] = {-0.9324695142031521, -0.6612093864662645, -0.2386191860831969,
                             0.2386191860831969,  0.6612093864662645,  0.9324695142031521};
        const double w[6] = {0.1713244923791704, 0.3607615730481386, 0.4679139345726910,
                             0.4679139345726910, 0.3607615730481386, 0.1713244923791704};
        Eigen::MatrixXd quadrature = Eigen::MatrixXd::Zero(degree + 1, degree + 1);
        for (int q = 0; q < 6; ++q) {
          const Eigen::VectorXd row = ElementDerivativeRow(basis, p, 0.5 * (1 + x[q]));
          quadrature += 0.5 * h * w[q] * row * row.transpose();
        }
        EXPECT_LT(RelativeError(exact, quadrature), 1e-12) << "degree " << degree << " p " << p;
      }
    }
  }
}

// The p-th derivative at t = end of a polynomial of degree <= d from d + 1 positions inside the element, by
// the one-sided finite-difference stencil of the interpolating polynomial (exact for degree <= d).
Eigen::VectorXd OneSidedDerivative(const HermiteCurve& curve, int element, bool at_end, int p) {
  const int d = curve.degree();
  Eigen::MatrixXd v(d + 1, d + 1);
  Eigen::MatrixXd positions(curve.ambient_dimension(), d + 1), jet;
  const double h = curve.knots()[element + 1] - curve.knots()[element];
  for (int i = 0; i <= d; ++i) {
    const double t = at_end ? 1.0 - 0.15 * i : 0.15 * i;  // points inside the element
    curve.EvaluateOnElement(element, t, 0, jet);
    positions.col(i) = jet.col(0);
    for (int k = 0; k <= d; ++k) v(i, k) = std::pow((t - (at_end ? 1.0 : 0.0)) * h, k);
  }
  // positions = coefficients * V^T, the p-th derivative at the end is p! coefficient_p.
  const Eigen::MatrixXd coefficients = v.fullPivLu().solve(positions.transpose()).transpose();
  return std::tgamma(p + 1.0) * coefficients.col(p);
}

HermiteCurve RandomCurve(int degree, bool closed, int dimension, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> knots = {0.0, 0.22, 0.3, 0.61, 1.0};
  const int nodes = closed ? 4 : 5, per_node = (degree + 1) / 2;
  Eigen::MatrixXd dofs(dimension, nodes * per_node);
  for (Eigen::Index i = 0; i < dofs.size(); ++i) dofs.data()[i] = u(rng);
  return HermiteCurve(degree, knots, dofs, closed);
}

TEST(HermiteJunctionMatrices, MatchFangsVectorsAndFiniteDifferencesOfTheJump) {
  // Fang's printed cubic vectors (eqs. 3.2.5-3.2.6) and the quintic one restated in docs/fair-curves.md
  // eq. F9.
  const double h0 = 0.3, h1 = 0.45;
  Eigen::VectorXd kd2(6), kd3(6), kq3(9);
  kd2 << -6 / (h0 * h0), -2 / h0, 6 / (h0 * h0) - 6 / (h1 * h1), -4 / h0 - 4 / h1, 6 / (h1 * h1), -2 / h1;
  kd3 << -12 / std::pow(h0, 3), -6 / (h0 * h0), 12 / std::pow(h0, 3) + 12 / std::pow(h1, 3),
      6 / (h1 * h1) - 6 / (h0 * h0), -12 / std::pow(h1, 3), 6 / (h1 * h1);
  kq3 << 60 / std::pow(h0, 3), 24 / (h0 * h0), 3 / h0, -60 / std::pow(h0, 3) - 60 / std::pow(h1, 3),
      36 / (h0 * h0) - 36 / (h1 * h1), -9 / h0 - 9 / h1, 60 / std::pow(h1, 3), -24 / (h1 * h1), 3 / h1;
  auto jump = [&](int degree, int p) {
    const int n = degree + 1, per = n / 2;
    Eigen::VectorXd v = Eigen::VectorXd::Zero(3 * per);
    const Eigen::VectorXd right = ElementDerivativeRow(HermiteElementBasis(degree, h1), p, 0.0);
    const Eigen::VectorXd left = ElementDerivativeRow(HermiteElementBasis(degree, h0), p, 1.0);
    v.segment(per, n) += right;
    v.head(n) -= left;
    return v;
  };
  EXPECT_LT((jump(3, 2) - kd2).norm(), 1e-12 * kd2.norm());
  EXPECT_LT((jump(3, 3) - kd3).norm(), 1e-12 * kd3.norm());
  EXPECT_LT((jump(5, 3) - kq3).norm(), 1e-12 * kq3.norm());

  // The assembled junction energy Q^T K Q of a random curve against the jumps of its one-sided derivatives,
  // each from positions by an exact one-sided stencil (open and closed: the closed curve's seam is a
  // junction).
  for (const int degree : {3, 5})
    for (const bool closed : {false, true})
      for (const int p : {2, 3}) {
        if (degree == 5 && p == 2) continue;  // a quintic is C2: no beta2 term
        const HermiteCurve curve = RandomCurve(degree, closed, 2, 7u + static_cast<std::uint32_t>(p));
        HermiteFairness f;
        (p == 2 ? f.beta2 : f.beta3) = 1.0;
        const Eigen::VectorXd q = curve.parameters();
        const double energy = q.dot(curve.FairnessMatrixOf(f) * q);
        double expected = 0.0;
        const int e_count = curve.num_elements();
        for (int node = closed ? 0 : 1; node < (closed ? e_count : e_count); ++node) {
          const int left = (node + e_count - 1) % e_count;
          expected += (OneSidedDerivative(curve, node, false, p) - OneSidedDerivative(curve, left, true, p))
                          .squaredNorm();
        }
        // The stencils solve a 6 x 6 Vandermonde system: about 1e-9 relative.
        EXPECT_NEAR(energy, expected, 1e-7 * expected)
            << "degree " << degree << " closed " << closed << " p " << p;
      }
}

// Nodal values of w(u) (and its derivatives) at the knots.
template <typename F>
HermiteCurve Sampled(int degree, int elements, bool closed, F&& jet) {
  const int per = (degree + 1) / 2, nodes = closed ? elements : elements + 1;
  Eigen::MatrixXd dofs(2, nodes * per);
  for (int i = 0; i < nodes; ++i) {
    const Eigen::Matrix<double, 2, 3> j = jet(static_cast<double>(i) / elements);
    for (int k = 0; k < per; ++k) dofs.col(i * per + k) = j.col(k);
  }
  return HermiteCurve::Uniform(degree, elements, dofs, closed);
}

TEST(HermiteFairnessEnergy, Alpha3IsZeroOnLinesAndTheKappaFourthTermOnCircles) {
  // A line a + b u: w''' = 0 and w'' = 0, so the alpha2 and alpha3 energies vanish exactly (to rounding).
  for (const int degree : {3, 5}) {
    const HermiteCurve line = Sampled(degree, 4, false, [](double u) {
      Eigen::Matrix<double, 2, 3> j;
      j << 1 + 3 * u, 3, 0, -2 + 1.5 * u, 1.5, 0;
      return j;
    });
    const Eigen::VectorXd q = line.parameters();
    const HermiteFairness e = line.EnergyBreakdown({1.0, 1.0, 1.0, 1.0, 1.0});
    EXPECT_NEAR(e.alpha1, 3 * 3 + 1.5 * 1.5, 1e-12);  // integral |w'|^2 over [0, 1]
    // Zero up to the rounding of the quadratic form Q^T K Q: a few ulps of |K| |Q|^2.
    auto rounding = [&](HermiteFairness one) {
      return 1e-14 * line.FairnessMatrixOf(one).norm() * q.squaredNorm();
    };
    EXPECT_LT(std::abs(e.alpha2), rounding({0, 1, 0, 0, 0}));
    EXPECT_LT(std::abs(e.alpha3), rounding({0, 0, 1, 0, 0}));
    EXPECT_LT(std::abs(e.beta3), rounding({0, 0, 0, 0, 1}));
  }
  // A circle of radius r at constant speed L = 2 pi r over [0, 1] (w' . w'' = 0): w''' = -(L / r)^2 w', so
  // |w'''|^2 = L^6 / r^4, constant. The parametric alpha3 energy is therefore NOT zero on a circle: it is
  // the kappa^4 part of |w'''|^2 = (s')^6 (kappa_s^2 + kappa^4 + kappa^2 tau^2) + (terms of s'', s''') of a
  // curve at speed s'; what vanishes on a circle (and a line) is its curvature-variation part kappa_s, the
  // geometric fairness measure integral (dkappa/ds)^2 ds (curve_interrogation_test). Here: the quintic
  // Hermite circle's alpha3 energy equals L^6 / r^4 to its interpolation error (8 elements: ~1e-4).
  const double r = 1.7, length = 2 * M_PI * r;
  const HermiteCurve circle = Sampled(5, 8, true, [&](double u) {
    const double a = 2 * M_PI * u, c = 2 * M_PI;
    Eigen::Matrix<double, 2, 3> j;
    j << r * std::cos(a), -r * c * std::sin(a), -r * c * c * std::cos(a), r * std::sin(a),
        r * c * std::cos(a), -r * c * c * std::sin(a);
    return j;
  });
  const HermiteFairness e = circle.EnergyBreakdown({0.0, 0.0, 1.0, 0.0, 0.0});
  EXPECT_NEAR(e.alpha3, std::pow(length, 6) / std::pow(r, 4), 1e-3 * std::pow(length, 6) / std::pow(r, 4));
}

TEST(HermiteCurve, C2ReductionHasNoSecondDerivativeJumps) {
  for (const bool closed : {false, true}) {
    HermiteCurve curve = RandomCurve(3, closed, 3, 11u);
    const HermiteCurve c2(3, curve.knots(), curve.nodal_values(), closed, true);
    // Positions kept, interior slopes replaced: w'' continuous at every junction.
    const int e_count = c2.num_elements();
    for (int node = closed ? 0 : 1; node < e_count; ++node) {
      Eigen::MatrixXd right, left;
      c2.EvaluateOnElement(node, 0.0, 2, right);
      c2.EvaluateOnElement((node + e_count - 1) % e_count, 1.0, 2, left);
      EXPECT_LT((right.col(2) - left.col(2)).norm(), 1e-10 * right.col(2).norm()) << "closed " << closed;
      EXPECT_LT((right.col(0) - curve.nodal_values().col(2 * node)).norm(), 1e-14);
    }
    HermiteFairness f;
    f.beta2 = 1.0;
    const Eigen::VectorXd q = c2.parameters();
    // Zero up to rounding: against the jump energy of the C1 curve it came from.
    const Eigen::VectorXd q1 = curve.parameters();
    EXPECT_LT(q.dot(c2.FairnessMatrixOf(f) * q), 1e-12 * q1.dot(curve.FairnessMatrixOf(f) * q1));
    EXPECT_EQ(c2.num_parameters(), 3 * (closed ? 4 : 5 + 2));
  }
}

TEST(HermiteCurve, RefinementKeepsTheCurve) {
  const HermiteCurve curve = RandomCurve(5, true, 2, 3u);
  const HermiteCurve fine = curve.Refined({1, 3});
  EXPECT_EQ(fine.num_elements(), curve.num_elements() + 2);
  Eigen::MatrixXd a, b;
  for (int i = 0; i <= 100; ++i) {
    curve.EvaluateJet(i / 100.0, 3, a);
    fine.EvaluateJet(i / 100.0, 3, b);
    EXPECT_LT((a.leftCols(3) - b.leftCols(3)).norm(), 1e-10 * (1 + a.norm())) << i;
  }
}

TEST(HermiteCurve, BadInputIsRejected) {
  Eigen::MatrixXd dofs = Eigen::MatrixXd::Zero(2, 4);
  EXPECT_THROW(HermiteCurve(4, {0.0, 1.0}, dofs, false), std::invalid_argument);
  EXPECT_THROW(HermiteCurve(3, {0.0, 0.5}, dofs, false), std::invalid_argument);
  EXPECT_THROW(HermiteCurve(3, {0.0, 1.0}, Eigen::MatrixXd::Zero(2, 6), false), std::invalid_argument);
  EXPECT_THROW(HermiteCurve(5, {0.0, 1.0}, Eigen::MatrixXd::Zero(2, 6), false, true), std::invalid_argument);
  dofs(0, 1) = std::nan("");
  EXPECT_THROW(HermiteCurve(3, {0.0, 1.0}, dofs, false), std::invalid_argument);
  EXPECT_THROW(HermiteCurve(3, {0.0, 0.5, 0.5, 1.0}, Eigen::MatrixXd::Zero(2, 8), false),
               std::invalid_argument);
}

TEST(BernsteinRoots, FindsSimpleCloseAndEndRoots) {
  // (t - 0.2)(t - 0.5)(t - 0.5001)(t - 0.9)(t - 1) in power form.
  Eigen::VectorXd power = Eigen::VectorXd::Ones(1);
  for (const double root : {0.2, 0.5, 0.5001, 0.9, 1.0}) {
    Eigen::VectorXd next = Eigen::VectorXd::Zero(power.size() + 1);
    next.head(power.size()) -= root * power;
    next.tail(power.size()) += power;
    power = next;
  }
  std::vector<double> roots;
  BernsteinRoots(PowerToBernstein(power), roots);
  const std::vector<double> expected = {0.2, 0.5, 0.5001, 0.9, 1.0};
  std::vector<double> found;
  for (double r : roots)
    if (found.empty() || r - found.back() > 1e-9) found.push_back(r);
  ASSERT_EQ(found.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) EXPECT_NEAR(found[i], expected[i], 1e-9);
  // No sign change, no root: 1 + t^2.
  roots.clear();
  Eigen::VectorXd positive(3);
  positive << 1, 0, 1;
  BernsteinRoots(PowerToBernstein(positive), roots);
  EXPECT_TRUE(roots.empty());
}

// Brute force: the smallest distance over dense samples, each local minimum polished by golden sections.
double BruteForceDistance(const HermiteCurve& curve, const Eigen::VectorXd& x, int samples) {
  LocalGeometry g;
  auto dist = [&](double u) {
    curve.Evaluate({u, 0.0, 0.0}, 0, g);
    return (Eigen::VectorXd(g.point) - x).norm();
  };
  std::vector<double> d(static_cast<std::size_t>(samples) + 1);
  for (int i = 0; i <= samples; ++i) d[static_cast<std::size_t>(i)] = dist(static_cast<double>(i) / samples);
  double best = *std::min_element(d.begin(), d.end());
  for (int i = 0; i <= samples; ++i) {
    const auto k = static_cast<std::size_t>(i);
    if ((i > 0 && d[k] > d[k - 1]) || (i < samples && d[k] > d[k + 1])) continue;
    double a = std::max(0.0, (i - 1.0) / samples), b = std::min(1.0, (i + 1.0) / samples);
    for (int it = 0; it < 100; ++it) {
      const double m1 = a + 0.382 * (b - a), m2 = a + 0.618 * (b - a);
      (dist(m1) < dist(m2) ? b : a) = dist(m1) < dist(m2) ? m2 : m1;
    }
    best = std::min(best, dist(0.5 * (a + b)));
  }
  return best;
}

TEST(HermiteFootPoints, AgreeWithBruteForceSamplingOnOpenAndClosedCurves) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  for (const int degree : {3, 5})
    for (const bool closed : {false, true}) {
      const HermiteCurve curve = RandomCurve(degree, closed, 2, 21u + static_cast<std::uint32_t>(degree));
      for (int i = 0; i < 60; ++i) {
        const Eigen::Vector2d x(u(rng), u(rng));
        ParamT t;
        double distance = 0.0;
        bool boundary = false, ambiguous = false;
        ASSERT_TRUE(curve.ClosedFormFoot(x, t, distance, boundary, ambiguous));
        LocalGeometry g;
        curve.Evaluate(t, 1, g);
        EXPECT_NEAR((Eigen::VectorXd(g.point) - Eigen::VectorXd(x)).norm(), distance, 1e-12);
        // The exact foot is never farther than brute force, and brute force's polished minima find it.
        const double brute = BruteForceDistance(curve, x, 4000);
        EXPECT_LE(distance, brute + 1e-10) << "degree " << degree << " closed " << closed << " point " << i;
        EXPECT_NEAR(distance, brute, 1e-7) << "degree " << degree << " closed " << closed << " point " << i;
        if (boundary) {
          EXPECT_FALSE(closed);
          EXPECT_TRUE(t[0] == 0.0 || t[0] == 1.0);
        }
      }
    }
}

}  // namespace
}  // namespace s2m
