// Elliptic Fourier descriptors (fitting/elliptic_fourier.h; Kuhl and Giardina 1982): a circle is one harmonic
// about its centre; normalization removes position, size, rotation and starting point; bad contours are
// refused.

#include "fitting/elliptic_fourier.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

namespace s2m {
namespace {

Eigen::Matrix2Xd Polygon(int n, double a, double b, double start) {
  Eigen::Matrix2Xd p(2, n);
  for (int i = 0; i < n; ++i) {
    const double s = start + 2 * M_PI * i / n;
    p.col(i) << a * std::cos(s), b * std::sin(s) + 0.3 * std::sin(2 * s);  // an egg-like, not an ellipse
  }
  return p;
}

TEST(EllipticFourier, CircleIsOneHarmonicAboutItsCentre) {
  Eigen::Matrix2Xd circle(2, 4000);
  for (int i = 0; i < 4000; ++i)
    circle.col(i) << 5 + 2 * std::cos(2 * M_PI * i / 4000), -2 + 2 * std::sin(2 * M_PI * i / 4000);
  const EllipticFourierDescriptors e = EllipticFourier(circle, 6);
  EXPECT_NEAR(e.a0, 5.0, 1e-9);
  EXPECT_NEAR(e.c0, -2.0, 1e-9);
  // x = 2 cos(2 pi t / T), y = 2 sin(...): a1 = 2, d1 = 2 (to the polygon's 4000-gon approximation).
  EXPECT_NEAR(e.coefficients(0, 0), 2.0, 1e-5);
  EXPECT_NEAR(e.coefficients(0, 3), 2.0, 1e-5);
  EXPECT_NEAR(e.coefficients(0, 1), 0.0, 1e-9);
  EXPECT_NEAR(e.coefficients(0, 2), 0.0, 1e-9);
  EXPECT_LT(e.coefficients.bottomRows(5).cwiseAbs().maxCoeff(), 1e-6);
  const EllipticFourierDescriptors n = NormalizeEllipticFourier(e);
  EXPECT_NEAR(n.coefficients(0, 0), 1.0, 1e-9);
  EXPECT_NEAR(std::abs(n.coefficients(0, 3)), 1.0, 1e-5);
}

TEST(EllipticFourier, NormalizationRemovesPositionSizeRotationAndStart) {
  const int harmonics = 8;
  const Eigen::Matrix2Xd shape = Polygon(720, 3.0, 1.2, 0.0);
  const EllipticFourierDescriptors reference = NormalizeEllipticFourier(EllipticFourier(shape, harmonics));
  EXPECT_NEAR(reference.coefficients(0, 0), 1.0, 1e-12);
  EXPECT_NEAR(reference.coefficients(0, 1), 0.0, 1e-12);
  EXPECT_NEAR(reference.coefficients(0, 2), 0.0, 1e-12);
  EXPECT_LT(std::abs(reference.coefficients(0, 3)), 1.0);
  // The same polygon started 97 vertices later, turned by 0.4 rad, scaled by 2.5 and moved.
  Eigen::Matrix2Xd moved(2, shape.cols());
  const Eigen::Matrix2d turn =
      (Eigen::Matrix2d() << std::cos(0.4), -std::sin(0.4), std::sin(0.4), std::cos(0.4)).finished();
  for (Eigen::Index i = 0; i < shape.cols(); ++i)
    moved.col(i) = 2.5 * turn * shape.col((i + 97) % shape.cols()) + Eigen::Vector2d(10, -4);
  const EllipticFourierDescriptors other = NormalizeEllipticFourier(EllipticFourier(moved, harmonics));
  // Kuhl and Giardina's normalization leaves one choice: the start at either end of the major axis, which
  // flips the sign of every even harmonic.
  double same = 0, flipped = 0;
  for (int n = 0; n < harmonics; ++n) {
    const double sign = n % 2 == 1 ? -1.0 : 1.0;
    same = std::max(same, (other.coefficients.row(n) - reference.coefficients.row(n)).cwiseAbs().maxCoeff());
    flipped = std::max(
        flipped, (other.coefficients.row(n) - sign * reference.coefficients.row(n)).cwiseAbs().maxCoeff());
  }
  EXPECT_LT(std::min(same, flipped), 1e-10) << "same " << same << ", flipped " << flipped;
}

TEST(EllipticFourier, BadContoursAreRefused) {
  EXPECT_THROW(EllipticFourier((Eigen::Matrix2Xd(2, 2) << 0, 1, 0, 1).finished(), 3), std::invalid_argument);
  EXPECT_THROW(EllipticFourier((Eigen::Matrix2Xd(2, 4) << 0, 0, 0, 0, 1, 1, 1, 1).finished(), 3),
               std::invalid_argument);
  EXPECT_THROW(EllipticFourier(Polygon(10, 1, 1, 0), 0), std::invalid_argument);
  Eigen::Matrix2Xd bad = Polygon(10, 1, 1, 0);
  bad(0, 3) = std::nan("");
  EXPECT_THROW(EllipticFourier(bad, 3), std::invalid_argument);
}

}  // namespace
}  // namespace s2m
