#pragma once
// Elliptic Fourier descriptors of a closed plane contour (F. P. Kuhl and C. R. Giardina, "Elliptic Fourier
// features of a closed contour", Computer Graphics and Image Processing 18, 1982), the outline descriptors
// of morphometrics (Momocs' efourier): each harmonic n is an ellipse x_n(t) = a_n cos(2 pi n t / T) +
// b_n sin(...), y_n(t) = c_n cos(...) + d_n sin(...), t the arc length along the contour of perimeter T.
// docs/archaeology.md section 8 restates the formulas.

#include <Eigen/Core>
#include <vector>

namespace s2m {

struct EllipticFourierDescriptors {
  double a0 = 0.0, c0 = 0.0;  // the contour's centre (the series' constant terms)
  // One row per harmonic n = 1..N: (a_n, b_n, c_n, d_n).
  Eigen::MatrixX4d coefficients;
};

// The first `harmonics` harmonics of the closed polygon through `contour`'s columns (the last point joins the
// first; consecutive coincident points are skipped), exactly for that polygon (Kuhl and Giardina eqs. 6-7,
// 13-14). Throws std::invalid_argument for fewer than 3 distinct points, a zero perimeter or harmonics < 1.
EllipticFourierDescriptors EllipticFourier(const Eigen::Matrix2Xd& contour, int harmonics);

// Normalized for size, rotation and starting point (Kuhl and Giardina section 4): the first harmonic's
// ellipse turned to start at its major axis' end and to lie along x, every coefficient divided by its
// semi-major axis, so the first harmonic is (1, 0, 0, d1) with |d1| <= 1 the minor-to-major ratio (negative:
// the contour runs clockwise). The constant terms are set to 0.
EllipticFourierDescriptors NormalizeEllipticFourier(const EllipticFourierDescriptors& efd);

}  // namespace s2m
