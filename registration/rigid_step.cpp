#include "registration/rigid_step.h"

#include <Eigen/Cholesky>

namespace s2m {

void RigidNormalEquations::Add(const PointConstraint& p) {
  // A = [-[x]x  I]: d/dc (c x x) = -[x]x.
  Eigen::Matrix<double, 3, 6> A;
  A << 0.0, p.x.z(), -p.x.y(), 1.0, 0.0, 0.0,  //
      -p.x.z(), 0.0, p.x.x(), 0.0, 1.0, 0.0,   //
      p.x.y(), -p.x.x(), 0.0, 0.0, 0.0, 1.0;
  const Eigen::Matrix<double, 6, 3> AtM = p.weight * A.transpose() * p.M;
  H.noalias() += AtM * A;
  g.noalias() += AtM * (p.x - p.target);
}

void RigidNormalEquations::AddDirection(const Eigen::Vector3d& x, const Eigen::Vector3d& v, double weight,
                                        double v_dot_residual) {
  // (-[x]x)^T v = x x v.
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
