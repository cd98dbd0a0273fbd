#include "registration/rigid_motion.h"

#include <gtest/gtest.h>

#include <random>

namespace s2m {
namespace {

// docs/method.md section 5, literally: x -> a0 + R(a, phi)(x - a0) + p phi a.
Eigen::Vector3d HelicalLiteral(const Eigen::Vector3d& c, const Eigen::Vector3d& cbar,
                               const Eigen::Vector3d& x) {
  const double phi = c.norm();
  const Eigen::Vector3d a = c / phi;
  const double p = c.dot(cbar) / (phi * phi);
  const Eigen::Vector3d a0 = c.cross(cbar) / (phi * phi);
  return a0 + RotationAboutAxis(a, phi) * (x - a0) + p * phi * a;
}

TEST(RigidMotion, HelicalUpdateMatchesTheLiteralFormula) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    const Eigen::Vector3d c(u(rng), u(rng), u(rng)), cbar(u(rng), u(rng), u(rng)), x(u(rng), u(rng), u(rng));
    const RigidMotion m = RigidMotion::FromHelicalVelocity(c, cbar);
    EXPECT_LT((m * x - HelicalLiteral(c, cbar, x)).norm(), 1e-13) << "trial " << trial;
    EXPECT_LT((m.rotation().transpose() * m.rotation() - Eigen::Matrix3d::Identity()).norm(), 1e-14);
    EXPECT_NEAR(m.rotation().determinant(), 1.0, 1e-14);
  }
}

TEST(RigidMotion, HelicalUpdateIsFirstOrderTheLinearizedMotion) {
  // x' = x + cbar + c x x + O(|c|(|c| + |cbar|)): the error shrinks quadratically with the step.
  const Eigen::Vector3d c0(0.3, -0.2, 0.5), cbar0(0.1, 0.4, -0.3), x(1.0, 2.0, -0.5);
  double previous = 0.0;
  for (double s : {1e-2, 1e-3, 1e-4}) {
    const Eigen::Vector3d c = s * c0, cbar = s * cbar0;
    const double error = (RigidMotion::FromHelicalVelocity(c, cbar) * x - (x + cbar + c.cross(x))).norm();
    if (previous > 0) {
      EXPECT_NEAR(previous / error, 100.0, 5.0);
    }
    previous = error;
  }
}

TEST(RigidMotion, TinyAndZeroRotationsAreTranslations) {
  const Eigen::Vector3d cbar(0.5, -1.0, 2.0), x(3.0, 1.0, -2.0);
  EXPECT_EQ(RigidMotion::FromHelicalVelocity(Eigen::Vector3d::Zero(), cbar) * x, x + cbar);
  // No 1/phi^2 blow-up just above zero: the result matches the second-order expansion of the helical motion,
  // x + cbar + c x x + (c x (c x x) + c x cbar) / 2, up to third-order terms (~1e-24 here).
  const Eigen::Vector3d c(1e-12, -2e-12, 0.5e-12);
  const Eigen::Vector3d second_order = x + cbar + c.cross(x) + 0.5 * (c.cross(c.cross(x)) + c.cross(cbar));
  EXPECT_LT((RigidMotion::FromHelicalVelocity(c, cbar) * x - second_order).norm(), 1e-15);
}

TEST(RigidMotion, PureRotationKeepsTheAxisAndScrewTranslatesAlongIt) {
  const Eigen::Vector3d axis = Eigen::Vector3d(1, 2, 2).normalized();
  // c parallel to cbar: a screw about the line through the origin; a point on the axis moves by cbar.
  const RigidMotion screw = RigidMotion::FromHelicalVelocity(0.7 * axis, 0.25 * axis);
  EXPECT_LT((screw * (3.0 * axis) - (3.0 * axis + 0.25 * axis)).norm(), 1e-14);
  EXPECT_NEAR(screw.angle(), 0.7, 1e-14);
}

TEST(RigidMotion, CompositionAndInverse) {
  const RigidMotion a = RigidMotion::FromHelicalVelocity({0.1, 0.2, -0.3}, {1, 2, 3});
  const RigidMotion b = RigidMotion::FromHelicalVelocity({-0.4, 0.0, 0.2}, {0, -1, 0.5});
  const Eigen::Vector3d x(0.3, -0.7, 1.1);
  EXPECT_LT(((a * b) * x - a * (b * x)).norm(), 1e-14);
  EXPECT_LT(((a * a.inverse()) * x - x).norm(), 1e-14);
  EXPECT_LT((RigidMotion::FromMatrix(a.matrix()) * x - a * x).norm(), 0.0 + 1e-15);
  Eigen::Matrix3Xd points(3, 2);
  points << x, -x;
  EXPECT_LT((a.apply(points).col(1) - a * Eigen::Vector3d(-x)).norm(), 1e-15);
}

TEST(RigidMotion, NormalizeRestoresAnOrthonormalRotation) {
  Eigen::Matrix3d r = RotationAboutAxis(Eigen::Vector3d(0, 0, 1), 0.3);
  r(0, 1) += 1e-6;
  RigidMotion m(r, Eigen::Vector3d::Zero());
  m.normalize();
  EXPECT_LT((m.rotation().transpose() * m.rotation() - Eigen::Matrix3d::Identity()).norm(), 1e-15);
  EXPECT_NEAR(m.angle(), 0.3, 1e-6);
}

}  // namespace
}  // namespace s2m
