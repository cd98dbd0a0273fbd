#pragma once
// A small dense linear program: minimize c^T x subject to A x <= b, x free, for the Chebyshev (minimum-zone)
// fits (minimum_zone.h): few unknowns (up to about ten) and many inequality rows (two per data point).
//
// Solved by the revised simplex method on the dual, min b^T y subject to A^T y = -c, y >= 0 (n equations,
// m unknowns), two phases (artificial variables first), Dantzig pricing with Bland's rule after a run of
// degenerate pivots (no cycling), the basis factorized afresh at every pivot (n x n: no drift). The
// primal solution is the dual problem's simplex multipliers and the dual solution y are the Lagrange
// multipliers of the rows: c + A^T y = 0, y >= 0, y_i (b - A x)_i = 0 (docs/metrology.md section 3,
// eqs. 9-10). Written here because the maths core depends on Eigen alone (GLPK, lp_solve and CLP are
// general sparse solvers whose licences and dependencies the core does not take; docs/metrology.md).

#include <Eigen/Core>
#include <string>

namespace s2m {

struct LinearProgramOptions {
  // Iterations of both phases together at most.
  int max_iterations = 5000;
  // Reduced costs above -optimality_tolerance count as non-negative (relative to the largest |b| and 1);
  // pivots below pivot_tolerance (relative to the column's largest entry) are refused.
  double optimality_tolerance = 1e-12;
  double pivot_tolerance = 1e-10;
  // Consecutive degenerate pivots after which Bland's rule replaces Dantzig's.
  int degenerate_pivots_before_bland = 50;

  bool IsValid(std::string* why = nullptr) const;
};

enum class LinearProgramStatus { kOptimal, kInfeasible, kUnbounded, kIterationLimit };
const char* ToString(LinearProgramStatus status);

struct LinearProgramResult {
  LinearProgramStatus status = LinearProgramStatus::kIterationLimit;
  Eigen::VectorXd x;      // the minimizer (kOptimal)
  Eigen::VectorXd duals;  // y >= 0, one per row of A; positive only on active rows (kOptimal)
  double objective = 0.0;
  int iterations = 0;
};

// Throws std::invalid_argument for mismatched sizes, non-finite entries or invalid options. kInfeasible:
// no x satisfies A x <= b; kUnbounded: c^T x has no lower bound on the feasible set.
LinearProgramResult SolveLinearProgram(const Eigen::MatrixXd& A, const Eigen::VectorXd& b,
                                       const Eigen::VectorXd& c, const LinearProgramOptions& options = {});

}  // namespace s2m
