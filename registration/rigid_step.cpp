#include "registration/rigid_step.h"

#include <Eigen/Cholesky>

namespace s2m {

void RigidNormalEquations::Add(const PointConstraint& p) {
  const Eigen::Matrix<double, 3, 6> A = MotionJacobian(p.x);
  const Eigen::Matrix<double, 6, 3> AtM = p.weight * A.transpose() * p.M;
  H.noalias() += AtM * A;
  g.noalias() += AtM * (p.x - p.target);
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
