#pragma once
// One linearized rigid-registration step (docs/method.md section 5; Liu, Pottmann, Wang, CAD 38(6) 2006,
// section 3): a small motion of a point about its current position x is x' = x + cbar + c x x. With each
// point's quadratic error term (x' - s)^T M (x' - s) frozen at its model point s, the motion (c, cbar) solves
// a 6x6 linear system. PDM (M = I) is classic ICP, TDM (M = n n^T) point-to-plane ICP (Chen-Medioni), SDM
// adds curvature-weighted tangents.

#include <Eigen/Core>
#include <vector>

#include "registration/rigid_motion.h"

namespace s2m {

struct PointConstraint {
  Eigen::Vector3d x;       // current position of the data point
  Eigen::Vector3d target;  // its model point s
  Eigen::Matrix3d M;       // the error term's matrix
  double weight = 1.0;
};

// The linearized motion of a point x (Liu, Pottmann, Wang 2006, section 3): x' = x + cbar + c x x = x + A(x)
// [c; cbar] with A(x) = [-[x]x  I], since d/dc (c x x) = -[x]x. Fixed size and inline: it is built for every
// point of every iteration.
inline Eigen::Matrix<double, 3, 6> MotionJacobian(const Eigen::Vector3d& x) {
  Eigen::Matrix<double, 3, 6> a;
  a << 0.0, x.z(), -x.y(), 1.0, 0.0, 0.0,  //
      -x.z(), 0.0, x.x(), 0.0, 1.0, 0.0,   //
      x.y(), -x.x(), 0.0, 0.0, 0.0, 1.0;
  return a;
}

// The normal equations sum w A^T M A [c; cbar] = -sum w A^T M (x - s), A = [-[x]x  I], accumulated point by
// point.
struct RigidNormalEquations {
  Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();  // sum w A^T M (x - s)
  // One point's term w (x' - s)^T M (x' - s) with a symmetric M (AddSymmetric).
  void Add(const PointConstraint& p);
  // The term weight * (x' - s)^T M (x' - s) of a symmetric M (its upper triangle is read), with
  // residual = x - s, by the blocks of A^T W A, W = weight * M (docs/method.md eq. 16a): fewer operations
  // than the general product, and faster than three AddDirection calls (bench/micro_benchmarks.cpp:
  // RigidAssembly against RigidAssemblyByDirections).
  void AddSymmetric(const Eigen::Vector3d& x, const Eigen::Matrix3d& M, double weight,
                    const Eigen::Vector3d& residual);
  // One rank-one term weight * (v . (x' - s))^2 of an error matrix M = sum_k w_k v_k v_k^T: its row
  // A^T v = [x x v; v], right-hand side v . (x - s). Cheaper than Add when M's eigen-decomposition is known.
  void AddDirection(const Eigen::Vector3d& x, const Eigen::Vector3d& v, double weight, double v_dot_residual);
  void Add(const RigidNormalEquations& other);
};

// The velocity (c, cbar) minimizing the linearized error, with Levenberg-Marquardt damping lambda * diag(H).
Eigen::Matrix<double, 6, 1> SolveRigidVelocity(const RigidNormalEquations& eq, double damping = 0.0);

}  // namespace s2m
