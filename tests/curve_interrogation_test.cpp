// Curve interrogation (fitting/curve_interrogation.h) against closed forms: circles, a sine, a helix, and the
// one-sided jumps of a C1 curve at its junctions.

#include "fitting/curve_interrogation.h"

#include <gtest/gtest.h>

#include <cmath>

namespace s2m {
namespace {

// A quintic Hermite curve through an analytic curve's position and first two derivatives at the nodes.
template <typename F>
HermiteCurve Sampled(int elements, bool closed, int dimension, F&& jet) {
  const int nodes = closed ? elements : elements + 1;
  Eigen::MatrixXd dofs(dimension, 3 * nodes);
  for (int i = 0; i < nodes; ++i) {
    const Eigen::MatrixXd j = jet(static_cast<double>(i) / elements);
    dofs.middleCols(3 * i, 3) = j;
  }
  return HermiteCurve::Uniform(5, elements, dofs, closed);
}

TEST(CurveInterrogation, CircleHasConstantCurvatureAndNoVariation) {
  const double r = 2.5;
  const HermiteCurve circle = Sampled(16, true, 2, [&](double u) {
    const double a = 2 * M_PI * u, c = 2 * M_PI;
    Eigen::MatrixXd j(2, 3);
    j << r * std::cos(a), -r * c * std::sin(a), -r * c * c * std::cos(a), r * std::sin(a),
        r * c * std::cos(a), -r * c * c * std::sin(a);
    return j;
  });
  const CurveInterrogation q = InterrogateCurve(ToInterrogated(circle));
  // A quintic Hermite interpolant of the circle with 16 elements: position error ~ (h / r)^6, curvature ~
  // (h / r)^4 relative: 1e-5 is a generous bound for both.
  EXPECT_NEAR(q.length, 2 * M_PI * r, 1e-5 * r);
  for (const CurvatureSample& c : q.samples) {
    EXPECT_NEAR(c.kappa, 1.0 / r, 1e-4 / r) << "s " << c.s;  // counter-clockwise: positive
    EXPECT_NEAR(c.dkappa_ds, 0.0, 1e-2 / (r * r)) << "s " << c.s;
  }
  EXPECT_TRUE(q.inflections.empty());
  EXPECT_NEAR(q.comb_scale, 0.5 * q.length / q.max_abs_kappa, 1e-12);
  // The comb's teeth point away from the centre by comb_scale kappa.
  const CurvatureSample& c = q.samples[10];
  EXPECT_NEAR(c.comb_tip.head<2>().norm(), r + q.comb_scale * c.kappa, 1e-3);
  // The geometric fairness integral(dkappa/ds)^2 ds vanishes on the circle (to interpolation error).
  EXPECT_LT(q.dkappa_ds_squared, 1e-6);
  // The closed curve's seam is a junction like the others: C2, so no G1/G2 break.
  ASSERT_EQ(q.junctions.size(), 16u);
  EXPECT_LT(q.max_g1, 1e-12);
  EXPECT_LT(q.max_g2, 1e-9);
}

TEST(CurveInterrogation, SineMatchesClosedFormCurvatureAndInflection) {
  // y = sin x on [0, 2 pi], as w(u) = (2 pi u, sin 2 pi u); kappa(x) = -sin x / (1 + cos^2 x)^(3/2).
  const HermiteCurve sine = Sampled(24, false, 2, [](double u) {
    const double c = 2 * M_PI, x = c * u;
    Eigen::MatrixXd j(2, 3);
    j << x, c, 0, std::sin(x), c * std::cos(x), -c * c * std::sin(x);
    return j;
  });
  const CurveInterrogation q = InterrogateCurve(ToInterrogated(sine));
  double dmax = 0.0;
  for (const CurvatureSample& c : q.samples) {
    const double x = c.point.x();
    const double expected = -std::sin(x) / std::pow(1 + std::cos(x) * std::cos(x), 1.5);
    dmax = std::max(dmax, std::abs(c.kappa - expected));
  }
  EXPECT_LT(dmax, 1e-4);
  // One inflection at x = pi, the middle of the arc length by symmetry.
  ASSERT_EQ(q.inflections.size(), 1u);
  EXPECT_NEAR(q.inflections[0], 0.5, 1.0 / 511);  // within one sample spacing
  // dkappa/ds against the difference quotient of kappa over neighbouring samples (spacing ds = L / 511).
  for (std::size_t i = 1; i + 1 < q.samples.size(); i += 37) {
    const double ds = (q.samples[i + 1].s - q.samples[i - 1].s) * q.length;
    const double numeric = (q.samples[i + 1].kappa - q.samples[i - 1].kappa) / ds;
    EXPECT_NEAR(q.samples[i].dkappa_ds, numeric, 2e-3) << i;
  }
}

TEST(CurveInterrogation, HelixCurvatureAndTorsion) {
  const double r = 1.5, pitch = 0.4, turns = 2.0;  // (r cos a, r sin a, pitch a)
  const HermiteCurve helix = Sampled(32, false, 3, [&](double u) {
    const double c = 2 * M_PI * turns, a = c * u;
    Eigen::MatrixXd j(3, 3);
    j << r * std::cos(a), -r * c * std::sin(a), -r * c * c * std::cos(a),  //
        r * std::sin(a), r * c * std::cos(a), -r * c * c * std::sin(a),    //
        pitch * a, pitch * c, 0.0;
    return j;
  });
  const CurveInterrogation q = InterrogateCurve(ToInterrogated(helix));
  const double kappa = r / (r * r + pitch * pitch), tau = pitch / (r * r + pitch * pitch);
  for (const CurvatureSample& c : q.samples) {
    EXPECT_NEAR(c.kappa, kappa, 1e-4 * kappa);
    EXPECT_NEAR(c.torsion, tau, 1e-3 * tau);
  }
  EXPECT_NEAR(q.length, 2 * M_PI * turns * std::sqrt(r * r + pitch * pitch), 1e-6);
}

TEST(CurveInterrogation, JunctionJumpsOfACubicAreItsOneSidedDifferences) {
  // A C1 cubic Hermite curve through a quarter circle with perturbed slopes: its curvature jumps at nodes.
  Eigen::MatrixXd dofs(2, 8);
  dofs << 1, 0, 0.7, -1.1, 0.0, -1.9, -0.8, -1.4,  //
      0, 1.8, 0.7, 1.0, 1.0, 0.1, 0.4, -1.2;
  const HermiteCurve curve = HermiteCurve::Uniform(3, 3, dofs, false);
  const CurveInterrogation q = InterrogateCurve(ToInterrogated(curve));
  ASSERT_EQ(q.junctions.size(), 2u);
  double zeta = 0.0;
  for (int node = 1; node <= 2; ++node) {
    Eigen::MatrixXd left, right;
    curve.EvaluateOnElement(node - 1, 1.0, 3, left);
    curve.EvaluateOnElement(node, 0.0, 3, right);
    double kl, dl, tl, kr, dr, tr;
    CurvatureOf(left.col(1), left.col(2), left.col(3), kl, dl, tl);
    CurvatureOf(right.col(1), right.col(2), right.col(3), kr, dr, tr);
    const JunctionJump& j = q.junctions[static_cast<std::size_t>(node - 1)];
    EXPECT_NEAR(j.u, node / 3.0, 1e-15);
    EXPECT_LT(j.g1, 1e-12);  // shared tangent: G1
    EXPECT_NEAR(j.g2, std::abs(kr - kl), 1e-12);
    EXPECT_GT(j.g2, 1e-3);  // the slopes were perturbed: a visible G2 break
    EXPECT_NEAR(j.g3, std::abs(dr - dl), 1e-10);
    zeta += std::abs(dr - dl);
  }
  EXPECT_NEAR(q.zeta, zeta, 1e-10);
}

TEST(CurveInterrogation, BSplineJetsMatchEvaluate) {
  const BSplineBasis basis = BSplineBasis::PeriodicUniform(4, 7);
  Eigen::MatrixXd control(2, 7);
  control << 0, 2, 3, 2.5, 1, -1, -0.5,  //
      0, -0.5, 1, 2.5, 3, 2, 1;
  const BSplineCurve curve(basis, control);
  const InterrogatedCurve ic = ToInterrogated(curve);
  Eigen::Matrix<double, Eigen::Dynamic, 4> jet, ahead, behind;
  LocalGeometry g;
  for (double u = ic.lo + 0.013; u < ic.hi; u += 0.37) {
    ic.jet(u, 0, jet);
    curve.Evaluate({u, 0, 0}, 2, g);
    EXPECT_LT((jet.col(0) - Eigen::VectorXd(g.point)).norm(), 1e-12);
    EXPECT_LT((jet.col(1) - Eigen::VectorXd(g.d1.col(0))).norm(), 1e-11);
    EXPECT_LT((jet.col(2) - Eigen::VectorXd(g.d2.col(0))).norm(), 1e-10);
    // The third derivative: central difference of the second (exact within a span for a cubic: w'' is
    // linear).
    const double h = 1e-4;
    ic.jet(u + h, 0, ahead);
    ic.jet(u - h, 0, behind);
    EXPECT_LT((jet.col(3) - (ahead.col(2) - behind.col(2)) / (2 * h)).norm(), 1e-6 * (1 + jet.col(3).norm()));
  }
  const CurveInterrogation q = InterrogateCurve(ic);
  EXPECT_EQ(q.junctions.size(), 7u);  // 7 spans, the seam included
  EXPECT_LT(q.max_g2, 1e-9);          // a cubic B-spline is C2
  EXPECT_GT(q.zeta, 0.0);             // and not C3
}

}  // namespace
}  // namespace s2m
