#include "registration/principal_curvatures.h"

#include <cmath>
#include <utility>

namespace s2m {

bool SolvePrincipalCurvatures(const Eigen::Matrix2d& second, const Eigen::Matrix2d& first,
                              Eigen::Matrix2d& directions, Eigen::Vector2d& curvatures) {
  // The metric's Cholesky factor first = L L^T (closed form for 2 x 2); a metric that is not positive
  // definite (a singular parametrization) has no principal directions.
  const double e = first(0, 0), g = first(1, 1);
  if (!(e > 0)) return false;
  const double l11 = std::sqrt(e), l21 = first(1, 0) / l11, l22_squared = g - l21 * l21;
  if (!(l22_squared > 0)) return false;
  const double l22 = std::sqrt(l22_squared);
  // A = L^-1 II L^-T (symmetric), with L^-1 = [1/l11 0; -l21/(l11 l22) 1/l22].
  Eigen::Matrix2d l_inverse;
  l_inverse << 1.0 / l11, 0.0, -l21 / (l11 * l22), 1.0 / l22;
  const Eigen::Matrix2d a = l_inverse * second * l_inverse.transpose();
  // One Jacobi rotation diagonalizes a symmetric 2 x 2 matrix exactly (Golub & Van Loan, Matrix Computations,
  // 4th ed., algorithm 8.5.1 sym.schur2): J^T A J = diag(a00 - t a01, a11 + t a01) with J = [c s; -s c].
  const double a00 = a(0, 0), a11 = a(1, 1), a01 = 0.5 * (a(0, 1) + a(1, 0));
  double c = 1.0, s = 0.0, t = 0.0;
  if (a01 != 0.0) {
    const double tau = (a11 - a00) / (2.0 * a01);
    t = tau >= 0 ? 1.0 / (tau + std::sqrt(1.0 + tau * tau)) : -1.0 / (-tau + std::sqrt(1.0 + tau * tau));
    c = 1.0 / std::sqrt(1.0 + t * t);
    s = t * c;
  }
  Eigen::Matrix2d q;
  q << c, s, -s, c;
  Eigen::Vector2d kappa(a00 - t * a01, a11 + t * a01);
  // Ascending order, as Eigen's solvers return them.
  if (kappa[0] > kappa[1]) {
    std::swap(kappa[0], kappa[1]);
    q.col(0).swap(q.col(1));
  }
  if (!kappa.allFinite()) return false;
  // Eigenvectors of II v = kappa I v: v = L^-T q, I-orthonormal.
  directions = l_inverse.transpose() * q;
  curvatures = kappa;
  return true;
}

}  // namespace s2m
