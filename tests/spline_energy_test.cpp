// Fang's fairness terms for B-spline bases (fitting/spline_energy.h, docs/fair-curves.md section 8): the
// energy matrices against Gauss quadrature of the basis' own evaluation, the third-derivative energy and the
// junction jumps against a curve's one-sided jets, and the models' fairness matrices built from them.

#include "fitting/spline_energy.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>

#include "fitting/bspline_models.h"
#include "fitting/curve_interrogation.h"
#include "fitting/kinematic_surfaces.h"

namespace s2m {
namespace {

BSplineBasis NonUniformCubic() {
  return BSplineBasis::Clamped(4, {0, 0, 0, 0, 0.7, 1.1, 2.6, 3.0, 4.2, 4.2, 4.2, 4.2});
}

TEST(SplineEnergy, MatchesGaussQuadratureOfTheBasis) {
  for (const BSplineBasis& b : {NonUniformCubic(), BSplineBasis::PeriodicUniform(5, 9, 0.0, 2.0)}) {
    const std::vector<double> breaks = b.Breakpoints();
    // 8-point Gauss-Legendre per span: exact for the degree <= 2 (order - 1) products.
    const double x[8] = {-0.9602898564975363, -0.7966664774136267, -0.5255324099163290, -0.1834346424956498,
                         0.1834346424956498,  0.5255324099163290,  0.7966664774136267,  0.9602898564975363};
    const double w[8] = {0.1012285362903763, 0.2223810344533745, 0.3137066458778873, 0.3626837833783620,
                         0.3626837833783620, 0.3137066458778873, 0.2223810344533745, 0.1012285362903763};
    for (int p = 0; p <= 2; ++p) {
      Eigen::MatrixXd q = Eigen::MatrixXd::Zero(b.num_control(), b.num_control());
      BSplineBasis::Values v;
      for (std::size_t s = 0; s + 1 < breaks.size(); ++s)
        for (int g = 0; g < 8; ++g) {
          const double half = 0.5 * (breaks[s + 1] - breaks[s]);
          b.EvaluateReference(breaks[s] + half * (1 + x[g]), p, v);
          for (int i = 0; i < b.order(); ++i)
            for (int j = 0; j < b.order(); ++j)
              q(b.ControlIndex(v.first, i), b.ControlIndex(v.first, j)) +=
                  half * w[g] * v.values[p][static_cast<std::size_t>(i)] *
                  v.values[p][static_cast<std::size_t>(j)];
        }
      const Eigen::MatrixXd exact = SplineEnergyMatrix(b, p);
      EXPECT_LT((exact - q).norm(), 1e-12 * q.norm()) << "order " << b.order() << " p " << p;
    }
  }
}

TEST(SplineEnergy, ThirdDerivativeEnergyAndJumpsMatchTheCurvesJets) {
  const BSplineBasis b = NonUniformCubic();
  Eigen::MatrixXd control(2, 8);
  control << 0, 1, 2.5, 3, 4.1, 5, 6.2, 7,  //
      0, 1.5, -0.5, 2, 0.7, -1, 1.2, 0.3;
  const BSplineCurve curve(b, control);
  const InterrogatedCurve ic = ToInterrogated(curve);
  const std::vector<double> breaks = b.Breakpoints();
  // integral |C'''|^2: C''' is constant on each span of a cubic.
  double energy = 0.0, jumps2 = 0.0, jumps3 = 0.0;
  Eigen::Matrix<double, Eigen::Dynamic, 4> jet, left, right;
  for (std::size_t s = 0; s + 1 < breaks.size(); ++s) {
    ic.jet(0.5 * (breaks[s] + breaks[s + 1]), 0, jet);
    energy += (breaks[s + 1] - breaks[s]) * jet.col(3).squaredNorm();
  }
  for (std::size_t s = 1; s + 1 < breaks.size(); ++s) {
    ic.jet(breaks[s], -1, left);
    ic.jet(breaks[s], 1, right);
    jumps2 += (right.col(2) - left.col(2)).squaredNorm();
    jumps3 += (right.col(3) - left.col(3)).squaredNorm();
  }
  auto form = [&](const Eigen::MatrixXd& k) {
    double e = 0.0;
    for (int c = 0; c < 2; ++c) e += control.row(c) * k * control.row(c).transpose();
    return e;
  };
  EXPECT_NEAR(form(SplineEnergyMatrix(b, 3)), energy, 1e-9 * energy);
  EXPECT_NEAR(form(SplineJumpMatrix(b, 3)), jumps3, 1e-8 * jumps3);
  // A cubic B-spline is C2 at simple knots: no second-derivative jumps (the one-sided jets step off the knot
  // by 1e-13 of the domain, hence the small floor).
  EXPECT_LT(form(SplineJumpMatrix(b, 2)), 1e-12 * jumps3);
  EXPECT_LT(jumps2, 1e-12 * jumps3);
  // The curve model's fairness matrix is the sum of the terms, per coordinate.
  FairnessWeights w;
  w.variation = 2.0;
  w.jump3 = 0.5;
  const Eigen::MatrixXd k = curve.FairnessMatrix(w);
  const Eigen::VectorXd p = curve.parameters();
  EXPECT_NEAR(p.dot(k * p), 2.0 * energy + 0.5 * jumps3, 1e-8 * energy);
}

TEST(SplineEnergy, GeneratricesTakeTheSameTerms) {
  const BSplineBasis b = NonUniformCubic();
  Eigen::Matrix2Xd profile(2, 8);
  profile << 3, 3.5, 4, 3.2, 2.8, 3.6, 4.4, 4.0,  //
      0, 1, 2, 3, 4, 5, 6, 7;
  const KinematicSurface surface = KinematicSurface::Revolution(b, profile);
  const BSplineCurve generatrix(b, profile);
  FairnessWeights w;
  w.variation = 1.0;
  w.jump3 = 3.0;
  w.bending = 0.1;
  const Eigen::MatrixXd ks = surface.FairnessMatrix(w), kc = generatrix.FairnessMatrix(w);
  const Eigen::VectorXd ps = surface.parameters(), pc = generatrix.parameters();
  // The surface's first 2 n parameters are the profile's, interleaved like the curve's.
  EXPECT_NEAR(ps.head(pc.size()).dot(ks.topLeftCorner(pc.size(), pc.size()) * ps.head(pc.size())),
              pc.dot(kc * pc), 1e-9 * pc.dot(kc * pc));
}

TEST(SplineEnergy, SurfaceVariationVanishesOnQuadraticPatches) {
  // S(u, v) = (u, v, u^2 + u v - v^2) on a bicubic basis: every third derivative is zero. A cubic term adds
  // S_uuu = 6 over the unit square: integral 36.
  const BSplineBasis bu = BSplineBasis::ClampedUniform(4, 6), bv = BSplineBasis::ClampedUniform(4, 5);
  const int nu = bu.num_control(), nv = bv.num_control();
  // Control points of a polynomial by least squares on a dense grid (exact: the polynomial is in the space).
  auto fit = [&](auto&& f) {
    const int g = 25;
    Eigen::MatrixXd a(g * g, nu * nv);
    Eigen::MatrixXd rhs(g * g, 3);
    a.setZero();
    BSplineBasis::Values x, y;
    for (int i = 0; i < g; ++i)
      for (int j = 0; j < g; ++j) {
        const double u = i / (g - 1.0), v = j / (g - 1.0);
        bu.EvaluateReference(u, 0, x);
        bv.EvaluateReference(v, 0, y);
        for (int k = 0; k < 4; ++k)
          for (int l = 0; l < 4; ++l)
            a(i * g + j, bu.ControlIndex(x.first, k) * nv + bv.ControlIndex(y.first, l)) =
                x.values[0][static_cast<std::size_t>(k)] * y.values[0][static_cast<std::size_t>(l)];
        rhs.row(i * g + j) = f(u, v).transpose();
      }
    const Eigen::MatrixXd p = a.colPivHouseholderQr().solve(rhs);
    return BSplineSurface(bu, bv, p.transpose());
  };
  FairnessWeights w;
  w.variation = 1.0;
  const BSplineSurface quadratic =
      fit([](double u, double v) { return Eigen::Vector3d(u, v, u * u + u * v - v * v); });
  const BSplineSurface cubic =
      fit([](double u, double v) { return Eigen::Vector3d(u, v, u * u + u * v - v * v + u * u * u); });
  const Eigen::VectorXd pq = quadratic.parameters(), pc = cubic.parameters();
  EXPECT_LT(std::abs(pq.dot(quadratic.FairnessMatrix(w) * pq)), 1e-9);
  EXPECT_NEAR(pc.dot(cubic.FairnessMatrix(w) * pc), 36.0, 1e-8);
}

}  // namespace
}  // namespace s2m
