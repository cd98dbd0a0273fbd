#include "fitting/elliptic_fourier.h"

#include <cmath>
#include <stdexcept>

namespace s2m {

EllipticFourierDescriptors EllipticFourier(const Eigen::Matrix2Xd& contour, int harmonics) {
  if (harmonics < 1) throw std::invalid_argument("elliptic Fourier descriptors need at least one harmonic");
  // The polygon's vertices without consecutive repeats (a zero-length segment has no direction).
  std::vector<Eigen::Vector2d> p;
  for (Eigen::Index i = 0; i < contour.cols(); ++i) {
    const Eigen::Vector2d v = contour.col(i);
    if (!v.allFinite()) throw std::invalid_argument("the contour has a non-finite point");
    if (p.empty() || (v - p.back()).norm() > 0) p.push_back(v);
  }
  while (p.size() > 1 && (p.back() - p.front()).norm() == 0) p.pop_back();
  if (p.size() < 3) throw std::invalid_argument("a closed contour needs at least 3 distinct points");
  const std::size_t m = p.size();
  // Segment p -> p+1 (closing back to the start): its increments and the arc length at its end.
  std::vector<Eigen::Vector2d> delta(m);
  std::vector<double> dt(m), t(m + 1, 0.0);
  for (std::size_t i = 0; i < m; ++i) {
    delta[i] = p[(i + 1) % m] - p[i];
    dt[i] = delta[i].norm();
    t[i + 1] = t[i] + dt[i];
  }
  const double perimeter = t[m];
  if (!(perimeter > 0)) throw std::invalid_argument("the contour has zero perimeter");
  EllipticFourierDescriptors out;
  out.coefficients.resize(harmonics, 4);
  for (int n = 1; n <= harmonics; ++n) {
    // Kuhl and Giardina eq. 6-7: a_n = T / (2 n^2 pi^2) sum_p (dx_p / dt_p) (cos phi_p - cos phi_(p-1)),
    // phi_p = 2 n pi t_p / T; b_n the same with sines; c_n, d_n with dy.
    const double k = 2.0 * n * M_PI / perimeter, factor = perimeter / (2.0 * n * n * M_PI * M_PI);
    double a = 0, b = 0, c = 0, d = 0;
    for (std::size_t i = 0; i < m; ++i) {
      if (dt[i] == 0) continue;
      const double dcos = std::cos(k * t[i + 1]) - std::cos(k * t[i]);
      const double dsin = std::sin(k * t[i + 1]) - std::sin(k * t[i]);
      a += delta[i].x() / dt[i] * dcos;
      b += delta[i].x() / dt[i] * dsin;
      c += delta[i].y() / dt[i] * dcos;
      d += delta[i].y() / dt[i] * dsin;
    }
    out.coefficients.row(n - 1) << factor * a, factor * b, factor * c, factor * d;
  }
  // Constant terms (eqs. 13-14): the mean of the polygon over its arc length, the start point included.
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  for (std::size_t i = 0; i < m; ++i) centre += 0.5 * (p[i] + p[(i + 1) % m]) * dt[i];
  centre /= perimeter;
  out.a0 = centre.x();
  out.c0 = centre.y();
  return out;
}

EllipticFourierDescriptors NormalizeEllipticFourier(const EllipticFourierDescriptors& efd) {
  if (efd.coefficients.rows() < 1) throw std::invalid_argument("no harmonics to normalize");
  const double a1 = efd.coefficients(0, 0), b1 = efd.coefficients(0, 1), c1 = efd.coefficients(0, 2),
               d1 = efd.coefficients(0, 3);
  // The start-point phase theta that puts the first harmonic at its major axis' end (eq. 41).
  const double theta = 0.5 * std::atan2(2.0 * (a1 * b1 + c1 * d1), a1 * a1 + c1 * c1 - b1 * b1 - d1 * d1);
  EllipticFourierDescriptors out;
  out.coefficients.resize(efd.coefficients.rows(), 4);
  // Shift the start by theta (harmonic n by n theta), then rotate by -psi so the major axis lies along x and
  // divide by its length (eqs. 44-48).
  Eigen::Matrix2d shifted1;
  {
    const Eigen::Matrix2d h = (Eigen::Matrix2d() << a1, b1, c1, d1).finished();
    const Eigen::Matrix2d s =
        (Eigen::Matrix2d() << std::cos(theta), -std::sin(theta), std::sin(theta), std::cos(theta)).finished();
    shifted1 = h * s;
  }
  const double psi = std::atan2(shifted1(1, 0), shifted1(0, 0));
  const double scale = std::hypot(shifted1(0, 0), shifted1(1, 0));
  if (!(scale > 0)) throw std::invalid_argument("the first harmonic is degenerate: nothing to normalize by");
  const Eigen::Matrix2d rotation =
      (Eigen::Matrix2d() << std::cos(psi), std::sin(psi), -std::sin(psi), std::cos(psi)).finished();
  for (Eigen::Index n = 1; n <= efd.coefficients.rows(); ++n) {
    const Eigen::RowVector4d r = efd.coefficients.row(n - 1);
    const Eigen::Matrix2d h = (Eigen::Matrix2d() << r[0], r[1], r[2], r[3]).finished();
    const double phase = static_cast<double>(n) * theta;
    const Eigen::Matrix2d s =
        (Eigen::Matrix2d() << std::cos(phase), -std::sin(phase), std::sin(phase), std::cos(phase)).finished();
    const Eigen::Matrix2d normalized = rotation * h * s / scale;
    out.coefficients.row(n - 1) << normalized(0, 0), normalized(0, 1), normalized(1, 0), normalized(1, 1);
  }
  return out;
}

}  // namespace s2m
