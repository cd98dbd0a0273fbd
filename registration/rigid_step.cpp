#include "registration/rigid_step.h"

#include <Eigen/Cholesky>

namespace s2m {

void RigidNormalEquations::Add(const PointConstraint& p) {
  AddSymmetric(p.x, p.M, p.weight, p.x - p.target);
}

void RigidNormalEquations::AddSymmetric(const Eigen::Vector3d& x, const Eigen::Matrix3d& M, double weight,
                                        const Eigen::Vector3d& residual) {
  // docs/method.md eq. 16a. A = [-[x]x  I] (MotionJacobian), so A^T = [[x]x; I] ([x]x^T = -[x]x) and,
  // with W = weight * M,
  //   A^T W A = [ -[x]x W [x]x   [x]x W ]      A^T W r = [ x x (W r) ]
  //             [ -W [x]x        W      ],               [ W r       ].
  // Q = [x]x W row by row, R = Q [x]x column by column (symmetric, as -R = [x]x W [x]x^T is).
  // M's upper triangle only: H stays exactly symmetric whatever rounding left in M's lower one.
  Eigen::Matrix3d w = M.selfadjointView<Eigen::Upper>();
  w *= weight;
  const double px = x.x(), py = x.y(), pz = x.z();
  Eigen::Matrix3d q;
  q.row(0) = py * w.row(2) - pz * w.row(1);
  q.row(1) = pz * w.row(0) - px * w.row(2);
  q.row(2) = px * w.row(1) - py * w.row(0);
  const double r00 = pz * q(0, 1) - py * q(0, 2), r11 = px * q(1, 2) - pz * q(1, 0);
  const double r22 = py * q(2, 0) - px * q(2, 1), r01 = px * q(0, 2) - pz * q(0, 0);
  const double r02 = py * q(0, 0) - px * q(0, 1), r12 = py * q(1, 0) - px * q(1, 1);
  H(0, 0) -= r00;
  H(1, 1) -= r11;
  H(2, 2) -= r22;
  H(0, 1) -= r01;
  H(1, 0) -= r01;
  H(0, 2) -= r02;
  H(2, 0) -= r02;
  H(1, 2) -= r12;
  H(2, 1) -= r12;
  H.topRightCorner<3, 3>() += q;
  H.bottomLeftCorner<3, 3>() += q.transpose();
  H.bottomRightCorner<3, 3>() += w;
  const Eigen::Vector3d wr = w * residual;
  g.head<3>() += x.cross(wr);
  g.tail<3>() += wr;
}

void RigidNormalEquations::AddDirection(const Eigen::Vector3d& x, const Eigen::Vector3d& v, double weight,
                                        double v_dot_residual) {
  // A^T v = [(-[x]x)^T v; v] = [x x v; v] (MotionJacobian), without forming A.
  Eigen::Matrix<double, 6, 1> row;
  row << x.cross(v), v;
  H.noalias() += (weight * row) * row.transpose();
  g.noalias() += (weight * v_dot_residual) * row;
}

void RigidNormalEquations::Add(const RigidNormalEquations& other) {
  H += other.H;
  g += other.g;
}

Eigen::Matrix<double, 6, 1> SolveRigidVelocity(const RigidNormalEquations& eq, double damping) {
  Eigen::Matrix<double, 6, 6> A = eq.H;
  A.diagonal() += damping * eq.H.diagonal();
  return A.ldlt().solve(-eq.g);
}

}  // namespace s2m
