// SolvePrincipalCurvatures (registration/principal_curvatures.h): the closed-form generalized 2 x 2
// eigenproblem II v = kappa I v against Eigen's iterative solver and against surfaces with known curvatures.

#include "registration/principal_curvatures.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <random>

namespace s2m {
namespace {

// Checks the defining properties: II v_k = kappa_k I v_k, v_i^T I v_j = delta_ij, ascending kappa.
void ExpectEigenpairs(const Eigen::Matrix2d& second, const Eigen::Matrix2d& first, const Eigen::Matrix2d& v,
                      const Eigen::Vector2d& kappa, double tolerance) {
  EXPECT_LE(kappa[0], kappa[1]);
  const double scale = second.norm() + first.norm() * kappa.cwiseAbs().maxCoeff();
  for (int k = 0; k < 2; ++k) {
    const Eigen::Vector2d residual = second * v.col(k) - kappa[k] * first * v.col(k);
    EXPECT_LE(residual.norm(), tolerance * scale * v.col(k).norm()) << "eigenpair " << k;
  }
  const Eigen::Matrix2d gram = v.transpose() * first * v;
  EXPECT_LE((gram - Eigen::Matrix2d::Identity()).norm(), tolerance);
}

TEST(PrincipalCurvatures, AgreeWithEigensIterativeSolverOnRandomForms) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int checked = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    // A metric of random size and anisotropy (condition numbers up to about 1e6), a random second form.
    const double size = std::pow(10.0, 3 * u(rng));
    Eigen::Matrix2d basis;
    basis << u(rng), u(rng), u(rng), u(rng);
    basis *= size;
    if (trial % 4 == 0) basis.col(1) = basis.col(0) + 1e-3 * size * Eigen::Vector2d(u(rng), u(rng));
    const Eigen::Matrix2d first = basis.transpose() * basis;
    Eigen::Matrix2d second;
    second << u(rng), u(rng), 0.0, u(rng);
    second(1, 0) = second(0, 1);
    second *= size;
    if (trial % 5 == 0) second = 0.3 * first;  // umbilic: every direction is principal
    Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::Matrix2d> reference(second, first);
    if (reference.info() != Eigen::Success) continue;
    Eigen::Matrix2d v;
    Eigen::Vector2d kappa;
    ASSERT_TRUE(SolvePrincipalCurvatures(second, first, v, kappa));
    // Both solvers lose accuracy with the metric's condition number (up to about 1e8 here): the tolerance
    // follows it.
    const Eigen::Vector2d metric = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(first).eigenvalues();
    const double tolerance = 1e-14 * metric[1] / metric[0];
    const double kappa_scale = reference.eigenvalues().cwiseAbs().maxCoeff() + 1e-300;
    const Eigen::Vector2d difference = kappa - reference.eigenvalues();
    EXPECT_LE(difference.cwiseAbs().maxCoeff(), tolerance * kappa_scale) << "trial " << trial;
    ExpectEigenpairs(second, first, v, kappa, tolerance);
    ++checked;
  }
  EXPECT_GE(checked, 19000);
}

TEST(PrincipalCurvatures, KnownSurfaces) {
  // Sphere of radius 2 at the equator, parametrized by (longitude, latitude): I = diag(4, 4), and with the
  // normal pointing outwards II = -I / 2, so both curvatures are -1/2.
  Eigen::Matrix2d v;
  Eigen::Vector2d kappa;
  const Eigen::Matrix2d sphere_first = 4.0 * Eigen::Matrix2d::Identity();
  ASSERT_TRUE(SolvePrincipalCurvatures(-0.5 * sphere_first, sphere_first, v, kappa));
  EXPECT_NEAR(kappa[0], -0.5, 1e-15);
  EXPECT_NEAR(kappa[1], -0.5, 1e-15);
  ExpectEigenpairs(-0.5 * sphere_first, sphere_first, v, kappa, 1e-14);
  // Cylinder of radius 3 by (angle, height): I = diag(9, 1), II = diag(-3, 0): curvatures -1/3 and 0, the
  // first along the angle.
  Eigen::Matrix2d first = Eigen::Vector2d(9.0, 1.0).asDiagonal(),
                  second = Eigen::Vector2d(-3.0, 0.0).asDiagonal();
  ASSERT_TRUE(SolvePrincipalCurvatures(second, first, v, kappa));
  EXPECT_NEAR(kappa[0], -1.0 / 3.0, 1e-15);
  EXPECT_NEAR(kappa[1], 0.0, 1e-15);
  EXPECT_NEAR(std::abs(v(0, 0)), 1.0 / 3.0, 1e-15);  // unit length in the metric: 1/3 of the angle's speed
  EXPECT_NEAR(v(1, 0), 0.0, 1e-15);
  // Off-diagonal metric (a sheared parametrization of the same cylinder): the curvatures do not change.
  Eigen::Matrix2d shear;
  shear << 1.0, 0.7, 0.0, 1.0;
  ASSERT_TRUE(SolvePrincipalCurvatures(shear.transpose() * second * shear, shear.transpose() * first * shear,
                                       v, kappa));
  EXPECT_NEAR(kappa[0], -1.0 / 3.0, 1e-14);
  EXPECT_NEAR(kappa[1], 0.0, 1e-14);
}

TEST(PrincipalCurvatures, SingularMetricsHaveNoPrincipalDirections) {
  Eigen::Matrix2d v;
  Eigen::Vector2d kappa;
  Eigen::Matrix2d first;
  first << 1.0, 1.0, 1.0, 1.0;  // both tangents parallel
  EXPECT_FALSE(SolvePrincipalCurvatures(Eigen::Matrix2d::Identity(), first, v, kappa));
  EXPECT_FALSE(SolvePrincipalCurvatures(Eigen::Matrix2d::Identity(), Eigen::Matrix2d::Zero(), v, kappa));
  first << std::nan(""), 0.0, 0.0, 1.0;
  EXPECT_FALSE(SolvePrincipalCurvatures(Eigen::Matrix2d::Identity(), first, v, kappa));
}

}  // namespace
}  // namespace s2m
