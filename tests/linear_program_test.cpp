// The dense linear program (fitting/linear_program.h) against an exhaustive solution: on small random
// problems every vertex (n active rows of A x <= b, solved as equations) is enumerated and the best feasible
// one is the optimum; the simplex's objective must equal it, its x must be feasible, and its multipliers
// must satisfy the optimality conditions c + A^T y = 0, y >= 0, y_i (b - A x)_i = 0.

#include "fitting/linear_program.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace s2m {
namespace {

// The best vertex of {A x <= b} for c^T x by enumerating every n-subset of the rows (infinity when none is
// feasible).
double ExhaustiveMinimum(const Eigen::MatrixXd& A, const Eigen::VectorXd& b, const Eigen::VectorXd& c) {
  const int m = static_cast<int>(A.rows()), n = static_cast<int>(A.cols());
  double best = std::numeric_limits<double>::infinity();
  std::vector<int> pick(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) pick[static_cast<std::size_t>(k)] = k;
  while (true) {
    Eigen::MatrixXd M(n, n);
    Eigen::VectorXd r(n);
    for (int k = 0; k < n; ++k) {
      M.row(k) = A.row(pick[static_cast<std::size_t>(k)]);
      r[k] = b[pick[static_cast<std::size_t>(k)]];
    }
    Eigen::FullPivLU<Eigen::MatrixXd> lu(M);
    if (lu.rank() == n) {
      const Eigen::VectorXd x = lu.solve(r);
      if (((A * x - b).array() <= 1e-9).all()) best = std::min(best, c.dot(x));
    }
    int k = n - 1;
    while (k >= 0 && pick[static_cast<std::size_t>(k)] == m - n + k) --k;
    if (k < 0) break;
    ++pick[static_cast<std::size_t>(k)];
    for (int j = k + 1; j < n; ++j)
      pick[static_cast<std::size_t>(j)] = pick[static_cast<std::size_t>(j - 1)] + 1;
  }
  return best;
}

TEST(LinearProgram, MatchesExhaustiveVertexEnumeration) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> g(0.0, 1.0);
  int checked = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const int n = 2 + trial % 4, m = n + 4 + trial % 7;
    // Random rows plus a box |x_k| <= 1 + |g|: always feasible (x = 0 when b > 0) and bounded.
    Eigen::MatrixXd A(m + 2 * n, n);
    Eigen::VectorXd b(m + 2 * n), c(n);
    for (int i = 0; i < m; ++i) {
      for (int k = 0; k < n; ++k) A(i, k) = g(rng);
      b[i] = std::abs(g(rng)) + (trial % 3 == 0 ? 0.0 : 0.1);  // every third problem degenerate at x = 0
    }
    for (int k = 0; k < n; ++k) {
      A.row(m + 2 * k).setZero();
      A.row(m + 2 * k + 1).setZero();
      A(m + 2 * k, k) = 1.0;
      A(m + 2 * k + 1, k) = -1.0;
      b[m + 2 * k] = b[m + 2 * k + 1] = 1.0 + std::abs(g(rng));
    }
    for (int k = 0; k < n; ++k) c[k] = g(rng);
    const LinearProgramResult lp = SolveLinearProgram(A, b, c);
    ASSERT_EQ(lp.status, LinearProgramStatus::kOptimal) << "trial " << trial;
    const double exhaustive = ExhaustiveMinimum(A, b, c);
    EXPECT_NEAR(lp.objective, exhaustive, 1e-9 * (1 + std::abs(exhaustive))) << "trial " << trial;
    EXPECT_NEAR(c.dot(lp.x), lp.objective, 1e-9 * (1 + std::abs(exhaustive)));
    EXPECT_LE((A * lp.x - b).maxCoeff(), 1e-9) << "infeasible x, trial " << trial;
    // Optimality conditions (docs/metrology.md eq. 10).
    EXPECT_GE(lp.duals.minCoeff(), 0.0);
    EXPECT_LT((c + A.transpose() * lp.duals).cwiseAbs().maxCoeff(), 1e-9) << "trial " << trial;
    EXPECT_LT(lp.duals.cwiseProduct(b - A * lp.x).cwiseAbs().maxCoeff(), 1e-9) << "trial " << trial;
    ++checked;
  }
  EXPECT_EQ(checked, 200);
}

// min t s.t. |x_i - t_i| style Chebyshev problem with many rows and few unknowns, as minimum_zone.cpp builds:
// the best constant approximation of values v_i in the max norm is their mid-range, with error half the
// range.
TEST(LinearProgram, SolvesAChebyshevMidRange) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-5.0, 7.0);
  const int m = 2000;
  Eigen::VectorXd v(m);
  for (int i = 0; i < m; ++i) v[i] = u(rng);
  // Unknowns (a, h): |v_i - a| <= h, minimize h.
  Eigen::MatrixXd A(2 * m, 2);
  Eigen::VectorXd b(2 * m);
  for (int i = 0; i < m; ++i) {
    A.row(2 * i) << -1.0, -1.0;  // v_i - a <= h
    b[2 * i] = -v[i];
    A.row(2 * i + 1) << 1.0, -1.0;  // a - v_i <= h
    b[2 * i + 1] = v[i];
  }
  const LinearProgramResult lp = SolveLinearProgram(A, b, Eigen::Vector2d(0.0, 1.0));
  ASSERT_EQ(lp.status, LinearProgramStatus::kOptimal);
  EXPECT_NEAR(lp.x[0], 0.5 * (v.maxCoeff() + v.minCoeff()), 1e-12);
  EXPECT_NEAR(lp.x[1], 0.5 * (v.maxCoeff() - v.minCoeff()), 1e-12);
  EXPECT_EQ((lp.duals.array() > 0).count(), 2);  // the two extreme values define the solution
}

TEST(LinearProgram, ReportsInfeasibleAndUnboundedProblems) {
  Eigen::MatrixXd A(2, 1);
  A << 1.0, -1.0;
  // x <= -1 and -x <= -1 (x >= 1): no x.
  EXPECT_EQ(SolveLinearProgram(A, Eigen::Vector2d(-1.0, -1.0), Eigen::VectorXd::Ones(1)).status,
            LinearProgramStatus::kInfeasible);
  // min -x s.t. -x <= 0: unbounded.
  Eigen::MatrixXd B(1, 1);
  B << -1.0;
  EXPECT_EQ(SolveLinearProgram(B, Eigen::VectorXd::Zero(1), -Eigen::VectorXd::Ones(1)).status,
            LinearProgramStatus::kUnbounded);
}

TEST(LinearProgram, RejectsBadInput) {
  EXPECT_THROW(SolveLinearProgram(Eigen::MatrixXd(3, 2), Eigen::VectorXd(2), Eigen::VectorXd(2)),
               std::invalid_argument);
  Eigen::MatrixXd A = Eigen::MatrixXd::Ones(2, 2);
  A(0, 1) = std::nan("");
  EXPECT_THROW(SolveLinearProgram(A, Eigen::VectorXd::Ones(2), Eigen::VectorXd::Ones(2)),
               std::invalid_argument);
  LinearProgramOptions o;
  o.max_iterations = 0;
  EXPECT_THROW(SolveLinearProgram(Eigen::MatrixXd::Identity(2, 2), Eigen::VectorXd::Ones(2),
                                  Eigen::VectorXd::Ones(2), o),
               std::invalid_argument);
}

}  // namespace
}  // namespace s2m
