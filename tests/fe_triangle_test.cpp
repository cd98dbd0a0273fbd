// Fang's 12-dof conforming triangle (fitting/fe_triangle.h, docs/fe-surfaces.md section 2): nodal
// interpolation, C1 conformity across a shared edge, the mid-edge dof, the energies of linear and quadratic
// fields, and the quadrature.
#include "fitting/fe_triangle.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <random>

namespace s2m {
namespace {

// A random counter-clockwise triangle with angles not too small (so that the checks test the element, not
// rounding on slivers).
ConformingTriangle RandomTriangle(std::mt19937& rng) {
  std::uniform_real_distribution<double> coordinate(-3.0, 3.0);
  for (;;) {
    const Eigen::Vector2d a(coordinate(rng), coordinate(rng)), b(coordinate(rng), coordinate(rng)),
        c(coordinate(rng), coordinate(rng));
    const double twice_area = (b - a).x() * (c - a).y() - (c - a).x() * (b - a).y();
    const double longest = std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
    if (std::abs(twice_area) < 0.2 * longest) continue;
    return twice_area > 0 ? ConformingTriangle(a, b, c) : ConformingTriangle(a, c, b);
  }
}

Eigen::Vector3d VertexBarycentric(int i) {
  return Eigen::Vector3d::Unit(i);
}
Eigen::Vector3d MidEdgeBarycentric(int k) {
  Eigen::Vector3d L = Eigen::Vector3d::Zero();
  L(k) = L((k + 1) % 3) = 0.5;
  return L;
}

// The 12 dofs of a scalar field given by its value and gradient at a point of the plane.
template <typename Field>
Eigen::Matrix<double, 12, 1> DofsOf(const ConformingTriangle& t, const Field& field) {
  Eigen::Matrix<double, 12, 1> a;
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d g = field(t.vertex(i));  // value, w_u, w_v
    a.segment<3>(3 * i) = g;
  }
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d g = field(0.5 * (t.vertex(k) + t.vertex((k + 1) % 3)));
    a(9 + k) = t.edge_frame(k).normal.dot(g.tail<2>());
  }
  return a;
}

TEST(ConformingTriangle, NodalInterpolationMatrixIsTheIdentity) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 50; ++trial) {
    const ConformingTriangle t = RandomTriangle(rng);
    Eigen::Matrix<double, 12, 12> m;
    for (int i = 0; i < 3; ++i) {
      const TriangleShape s = t.Evaluate(VertexBarycentric(i));
      m.row(3 * i) = s.value;
      m.row(3 * i + 1) = s.du;
      m.row(3 * i + 2) = s.dv;
    }
    for (int k = 0; k < 3; ++k) {
      const TriangleShape s = t.Evaluate(MidEdgeBarycentric(k));
      const Eigen::Vector2d n = t.edge_frame(k).normal;
      m.row(9 + k) = n.x() * s.du + n.y() * s.dv;
    }
    EXPECT_LT((m - Eigen::Matrix<double, 12, 12>::Identity()).cwiseAbs().maxCoeff(), 1e-12)
        << "trial " << trial;
  }
}

TEST(ConformingTriangle, NineDofBlockInterpolatesItsNodalData) {
  // Zienkiewicz's element on its own: the 9 x 9 matrix of value and slopes at the vertices is the identity
  // with no extra factor.
  std::mt19937 rng(8);
  for (int trial = 0; trial < 20; ++trial) {
    const ConformingTriangle t = RandomTriangle(rng);
    Eigen::Matrix<double, 9, 9> m;
    for (int i = 0; i < 3; ++i) {
      const TriangleShape s = t.EvaluateNineDof(VertexBarycentric(i));
      m.row(3 * i) = s.value.head<9>();
      m.row(3 * i + 1) = s.du.head<9>();
      m.row(3 * i + 2) = s.dv.head<9>();
    }
    EXPECT_LT((m - Eigen::Matrix<double, 9, 9>::Identity()).cwiseAbs().maxCoeff(), 1e-12);
  }
}

TEST(ConformingTriangle, ValueAndNormalSlopeAgreeAlongASharedEdge) {
  // Two triangles on opposite sides of an edge p-q, each with random dofs except those of the edge's own
  // nodes (the two vertices and the mid-edge slope), which they share: value and normal slope must agree at
  // every point of the edge. The same check with the 9-dof element fails (its normal slope depends on the
  // opposite vertex), which shows the test can fail.
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  double worst_12 = 0.0, worst_9 = 0.0;
  for (int trial = 0; trial < 50; ++trial) {
    const Eigen::Vector2d p(unit(rng), unit(rng)), q(2.0 + unit(rng), 0.5 * unit(rng));
    const Eigen::Vector2d along = (q - p).normalized(), left(-along.y(), along.x());
    const Eigen::Vector2d r =
        0.5 * (p + q) + (0.6 + 0.5 * std::abs(unit(rng))) * left + 0.4 * unit(rng) * along;
    const Eigen::Vector2d s =
        0.5 * (p + q) - (0.6 + 0.5 * std::abs(unit(rng))) * left + 0.4 * unit(rng) * along;
    const ConformingTriangle a(p, q, r);  // edge 0 of a is p-q
    const ConformingTriangle b(q, p, s);  // edge 0 of b is q-p
    Eigen::Matrix<double, 12, 1> da, db;
    for (int i = 0; i < 12; ++i) da(i) = unit(rng), db(i) = unit(rng);
    db.segment<3>(0) = da.segment<3>(3);  // b's vertex 1 is a's vertex 2 (q)
    db.segment<3>(3) = da.segment<3>(0);  // b's vertex 2 is a's vertex 1 (p)
    db(9) = da(9);                        // the shared mid-edge node
    const Eigen::Vector2d n = a.edge_frame(0).normal;
    ASSERT_EQ(n, b.edge_frame(0).normal);
    for (int k = 0; k <= 20; ++k) {
      const double x = k / 20.0;
      const Eigen::Vector2d point = p + x * (q - p);
      for (bool twelve : {true, false}) {
        const TriangleShape sa =
            twelve ? a.Evaluate(a.Barycentric(point)) : a.EvaluateNineDof(a.Barycentric(point));
        const TriangleShape sb =
            twelve ? b.Evaluate(b.Barycentric(point)) : b.EvaluateNineDof(b.Barycentric(point));
        const double value_gap = std::abs(sa.value.dot(da) - sb.value.dot(db));
        const double slope_gap =
            std::abs(n.x() * (sa.du.dot(da) - sb.du.dot(db)) + n.y() * (sa.dv.dot(da) - sb.dv.dot(db)));
        double& worst = twelve ? worst_12 : worst_9;
        worst = std::max({worst, value_gap, slope_gap});
      }
    }
  }
  EXPECT_LT(worst_12, 1e-11);
  EXPECT_GT(worst_9, 1e-2);
}

TEST(ConformingTriangle, MidEdgeDofIsAParabolicNormalSlopeOnItsOwnEdgeOnly) {
  std::mt19937 rng(10);
  for (int trial = 0; trial < 20; ++trial) {
    const ConformingTriangle t = RandomTriangle(rng);
    for (int k = 0; k < 3; ++k)  // the dof w_nk
      for (int edge = 0; edge < 3; ++edge)
        for (int step = 1; step < 10; ++step) {
          const double x = step / 10.0;
          Eigen::Vector3d L = Eigen::Vector3d::Zero();
          L(edge) = 1.0 - x;
          L((edge + 1) % 3) = x;
          const TriangleShape s = t.Evaluate(L);
          const Eigen::Vector2d n = t.edge_frame(edge).normal, tangent = t.edge_frame(edge).tangent;
          const double normal_slope = n.x() * s.du(9 + k) + n.y() * s.dv(9 + k);
          const double tangent_slope = tangent.x() * s.du(9 + k) + tangent.y() * s.dv(9 + k);
          EXPECT_NEAR(s.value(9 + k), 0.0, 1e-13);
          EXPECT_NEAR(tangent_slope, 0.0, 1e-12);
          EXPECT_NEAR(normal_slope, edge == k ? 4.0 * x * (1.0 - x) : 0.0, 1e-12)
              << "dof " << k << " edge " << edge << " at " << x;
        }
  }
}

TEST(ConformingTriangle, LinearFieldHasNoBendingAndQuadraticFieldsAreExact) {
  // Patch tests: a linear field is reproduced exactly with zero bending energy; a quadratic field
  // w = A u^2 + B u v + C v^2 + ... is reproduced exactly inside the triangle, and its thin-plate energy is
  // area * (4 A^2 + 2 B^2 + 4 C^2) (w_uu = 2A, w_uv = B, w_vv = 2C).
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const TriangleQuadrature rule = CollapsedGaussRule(8);
  for (int trial = 0; trial < 20; ++trial) {
    const ConformingTriangle t = RandomTriangle(rng);
    const double A = unit(rng), B = unit(rng), C = unit(rng), D = unit(rng), E = unit(rng), F = unit(rng);
    const auto linear = [&](const Eigen::Vector2d& x) {
      return Eigen::Vector3d(D + E * x.x() + F * x.y(), E, F);
    };
    const auto quadratic = [&](const Eigen::Vector2d& x) {
      return Eigen::Vector3d(
          A * x.x() * x.x() + B * x.x() * x.y() + C * x.y() * x.y() + D + E * x.x() + F * x.y(),
          2 * A * x.x() + B * x.y() + E, B * x.x() + 2 * C * x.y() + F);
    };
    const Eigen::Matrix<double, 12, 12> bending = t.Stiffness(0.0, 1.0, rule);
    const Eigen::Matrix<double, 12, 1> dl = DofsOf(t, linear), dq = DofsOf(t, quadratic);
    EXPECT_NEAR(dl.dot(bending * dl), 0.0, 1e-11 * dl.squaredNorm());
    const double expected = t.area() * (4 * A * A + 2 * B * B + 4 * C * C);
    EXPECT_NEAR(dq.dot(bending * dq), expected, 1e-10 * expected);
    for (int k = 0; k < 10; ++k) {
      Eigen::Vector3d L(std::abs(unit(rng)), std::abs(unit(rng)), std::abs(unit(rng)));
      L /= L.sum();
      const Eigen::Vector2d x = L(0) * t.vertex(0) + L(1) * t.vertex(1) + L(2) * t.vertex(2);
      const TriangleShape s = t.Evaluate(L);
      EXPECT_NEAR(s.value.dot(dq), quadratic(x)(0), 1e-12);
      EXPECT_NEAR(s.duu.dot(dq), 2 * A, 1e-10);
      EXPECT_NEAR(s.duv.dot(dq), B, 1e-10);
      EXPECT_NEAR(s.dvv.dot(dq), 2 * C, 1e-10);
    }
  }
}

TEST(ConformingTriangle, StiffnessIsSymmetricPositiveSemidefiniteWithTheLinearFieldsAsBendingNullSpace) {
  std::mt19937 rng(12);
  const ConformingTriangle t = RandomTriangle(rng);
  const Eigen::Matrix<double, 12, 12> k = t.Stiffness(0.0, 1.0, CollapsedGaussRule(8));
  EXPECT_LT((k - k.transpose()).cwiseAbs().maxCoeff(), 1e-12 * k.cwiseAbs().maxCoeff());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>> eig(k);
  const Eigen::VectorXd values = eig.eigenvalues();
  // Exactly three zero eigenvalues (constant, u and v fields), the rest clearly positive.
  EXPECT_GT(values(0), -1e-10 * values(11));
  EXPECT_LT(values(2), 1e-10 * values(11));
  EXPECT_GT(values(3), 1e-6 * values(11));
  // With the membrane term only constants are free.
  const Eigen::Matrix<double, 12, 12> m = t.Stiffness(1.0, 0.0, CollapsedGaussRule(8));
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 12, 12>> eig_m(m);
  EXPECT_LT(eig_m.eigenvalues()(0), 1e-10 * eig_m.eigenvalues()(11));
  EXPECT_GT(eig_m.eigenvalues()(1), 1e-6 * eig_m.eigenvalues()(11));
}

TEST(CollapsedGaussRule, IntegratesBarycentricMonomialsExactlyUpToItsDegree) {
  // integral over the reference triangle of L1^a L2^b L3^c = a! b! c! / (a + b + c + 2)!.
  const auto factorial = [](int n) { return std::tgamma(n + 1.0); };
  for (int order = 1; order <= 8; ++order) {
    const TriangleQuadrature rule = CollapsedGaussRule(order);
    for (int a = 0; a <= 2 * order - 2; ++a)
      for (int b = 0; a + b <= 2 * order - 2; ++b)
        for (int c = 0; a + b + c <= 2 * order - 2; ++c) {
          double sum = 0.0;
          for (std::size_t q = 0; q < rule.weights.size(); ++q) {
            const Eigen::Vector3d& L = rule.barycentric[q];
            EXPECT_GT(L.minCoeff(), 0.0);  // strictly inside
            sum += rule.weights[q] * std::pow(L(0), a) * std::pow(L(1), b) * std::pow(L(2), c);
          }
          const double exact = factorial(a) * factorial(b) * factorial(c) / factorial(a + b + c + 2);
          EXPECT_NEAR(sum, exact, 1e-14) << "order " << order << " monomial " << a << b << c;
        }
  }
}

TEST(ConformingTriangle, StiffnessConvergesWithTheQuadratureOrder) {
  // The correction functions are rational, so no rule is exact; the element matrix settles as the order
  // grows (the documentation's choice of order rests on this measurement).
  std::mt19937 rng(13);
  const ConformingTriangle t = RandomTriangle(rng);
  const Eigen::Matrix<double, 12, 12> reference = t.Stiffness(1.0, 1.0, CollapsedGaussRule(24));
  double previous = 1.0;
  for (int order : {4, 6, 8, 12}) {
    const double error =
        (t.Stiffness(1.0, 1.0, CollapsedGaussRule(order)) - reference).norm() / reference.norm();
    std::printf("quadrature order %2d (%3d points): relative stiffness error %.2e\n", order,
                4 * order * order, error);
    EXPECT_LT(error, previous);
    previous = error;
  }
  EXPECT_LT(previous, 1e-12);
}

TEST(ConformingTriangle, RefusesClockwiseDegenerateAndNonFiniteTriangles) {
  const Eigen::Vector2d a(0, 0), b(1, 0), c(0, 1);
  EXPECT_THROW(ConformingTriangle(a, c, b), std::invalid_argument);
  EXPECT_THROW(ConformingTriangle(a, b, Eigen::Vector2d(2, 0)), std::invalid_argument);
  EXPECT_THROW(ConformingTriangle(a, b, Eigen::Vector2d(NAN, 1)), std::invalid_argument);
}

TEST(GlobalEdgeFrame, IsTheSameFromEitherEndAndPointsTheNormalUp) {
  std::mt19937 rng(14);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  for (int trial = 0; trial < 100; ++trial) {
    const Eigen::Vector2d a(unit(rng), unit(rng)), b(unit(rng), unit(rng));
    const EdgeFrame f = GlobalEdgeFrame(a, b), g = GlobalEdgeFrame(b, a);
    EXPECT_EQ(f.normal, g.normal);
    EXPECT_GT(f.normal.y(), 0.0);
    EXPECT_NEAR(f.tangent.x() * f.normal.y() - f.tangent.y() * f.normal.x(), 1.0, 1e-15);
  }
  EXPECT_EQ(GlobalEdgeFrame({0, 0}, {0, 1}).normal, Eigen::Vector2d(1, 0));
  EXPECT_EQ(GlobalEdgeFrame({0, 1}, {0, 0}).normal, Eigen::Vector2d(1, 0));
  EXPECT_EQ(GlobalEdgeFrame({1, 0}, {0, 0}).normal, Eigen::Vector2d(0, 1));
}

}  // namespace
}  // namespace s2m
