#include "fitting/out_of_round.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace s2m {
namespace {

constexpr int kOrder = 4;                 // harmonics 1..4 (eq. A5)
constexpr int kColumns = 1 + 2 * kOrder;  // a0, (a_k, b_k)
constexpr int kProfileSamples = 720;      // for the peak-to-valley of eq. A8 (half a degree)

// The standard uncertainty of the amplitude sqrt(a^2 + b^2) from the covariance of (a, b): the gradient (a,
// b) / c through the 2 x 2 block; at c = 0, the larger standard deviation.
double AmplitudeUncertainty(double a, double b, const Eigen::Matrix2d& covariance) {
  const double c = std::hypot(a, b);
  if (!(c > 0)) return std::sqrt(std::max(covariance(0, 0), covariance(1, 1)));
  const Eigen::Vector2d g(a / c, b / c);
  return std::sqrt(std::max(0.0, g.dot(covariance * g)));
}

}  // namespace

std::vector<RoundnessBand> MeasureRoundnessBands(const Eigen::Matrix3Xd& points,
                                                 const Eigen::VectorXd& deviations, double z_lo, double z_hi,
                                                 int bands) {
  if (deviations.size() != points.cols())
    throw std::invalid_argument("out-of-round: one deviation per point is needed");
  if (bands < 1) throw std::invalid_argument("out-of-round: at least one band");
  if (!(z_hi > z_lo)) throw std::invalid_argument("out-of-round: the bands' height range is empty");
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double width = (z_hi - z_lo) / bands;
  std::vector<std::vector<Eigen::Index>> members(static_cast<std::size_t>(bands));
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const double z = points(2, i);
    if (!(z >= z_lo && z <= z_hi) || !std::isfinite(deviations[i])) continue;
    const int b = std::min(bands - 1, static_cast<int>((z - z_lo) / width));
    members[static_cast<std::size_t>(b)].push_back(i);
  }
  std::vector<RoundnessBand> out;
  for (int b = 0; b < bands; ++b) {
    const std::vector<Eigen::Index>& in = members[static_cast<std::size_t>(b)];
    RoundnessBand band;
    band.z_lo = z_lo + b * width;
    band.z_hi = z_lo + (b + 1) * width;
    band.points = static_cast<Eigen::Index>(in.size());
    std::vector<double> angles;
    for (const Eigen::Index i : in) angles.push_back(std::atan2(points(1, i), points(0, i)));
    std::sort(angles.begin(), angles.end());
    band.largest_gap = 2 * M_PI;
    if (!angles.empty()) {
      band.largest_gap = angles.front() + 2 * M_PI - angles.back();  // across +-pi
      for (std::size_t k = 1; k < angles.size(); ++k)
        band.largest_gap = std::max(band.largest_gap, angles[k] - angles[k - 1]);
    }
    band.resolved = band.points >= RoundnessBand::kMinPoints && band.largest_gap <= RoundnessBand::kMaxGap;
    if (!band.resolved) {
      band.centre_offset = band.centre_offset_uncertainty = band.ovality = band.ovality_uncertainty = nan;
      band.out_of_round = band.residual_rms = nan;
      out.push_back(band);
      continue;
    }
    // Least squares for eq. A5 by QR (the columns are near-orthogonal on a well-covered band).
    Eigen::MatrixXd a(band.points, kColumns);
    Eigen::VectorXd d(band.points);
    for (Eigen::Index r = 0; r < band.points; ++r) {
      const Eigen::Index i = in[static_cast<std::size_t>(r)];
      const double t = std::atan2(points(1, i), points(0, i));
      a(r, 0) = 1.0;
      for (int k = 1; k <= kOrder; ++k) {
        a(r, 2 * k - 1) = std::cos(k * t);
        a(r, 2 * k) = std::sin(k * t);
      }
      d[r] = deviations[i];
    }
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(a);
    const Eigen::VectorXd c = qr.solve(d);
    const Eigen::VectorXd residual = d - a * c;
    const double variance = residual.squaredNorm() / static_cast<double>(band.points - kColumns);
    band.residual_rms = std::sqrt(residual.squaredNorm() / static_cast<double>(band.points));
    const Eigen::MatrixXd covariance = variance * (a.transpose() * a).inverse();
    // Eq. A6: the first harmonic a1 cos t + b1 sin t is a shift of the band's centre by (a1, b1).
    band.centre_offset = std::hypot(c[1], c[2]);
    band.centre_offset_uncertainty = AmplitudeUncertainty(c[1], c[2], covariance.block<2, 2>(1, 1));
    // Eq. A7: r(t) = R + c2 cos(2 (t - t2)) has diameters 2R + 2 c2 and 2R - 2 c2 at right angles.
    band.ovality = 4.0 * std::hypot(c[3], c[4]);
    band.ovality_uncertainty = 4.0 * AmplitudeUncertainty(c[3], c[4], covariance.block<2, 2>(3, 3));
    // Eq. A8: peak-to-valley of harmonics 2..4 on a half-degree grid.
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (int s = 0; s < kProfileSamples; ++s) {
      const double t = 2 * M_PI * s / kProfileSamples;
      double v = 0.0;
      for (int k = 2; k <= kOrder; ++k) v += c[2 * k - 1] * std::cos(k * t) + c[2 * k] * std::sin(k * t);
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
    band.out_of_round = hi - lo;
    out.push_back(band);
  }
  return out;
}

Eigen::VectorXd RadialDeviations(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& feet,
                                 const Eigen::VectorXd& deviations) {
  if (feet.cols() != points.cols() || deviations.size() != points.cols())
    throw std::invalid_argument("radial deviations: one foot and one deviation per point are needed");
  Eigen::VectorXd radial(deviations.size());
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const double d = deviations[i];
    const double rho_p = points.col(i).head<2>().norm(), rho_f = feet.col(i).head<2>().norm();
    // Below a micrometre in a metre the foot's direction is rounding: the deviation is kept as it is (the
    // factor 1 / n_rho is at most 2 where it is used).
    if (!(std::abs(d) > 1e-6 * std::max(1.0, rho_p))) {
      radial[i] = d;
      continue;
    }
    const double n_rho = (rho_p - rho_f) / d;  // eq. A9
    radial[i] = std::abs(n_rho) >= 0.5 ? d / n_rho : std::numeric_limits<double>::quiet_NaN();
  }
  return radial;
}

}  // namespace s2m
