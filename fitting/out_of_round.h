#pragma once
// Out-of-roundness of a part around an axis, band by band along it (docs/archaeology.md section 4): how far a
// pot's wall departs from the fitted surface of revolution around each height (warping in the kiln, an oval
// mouth, a leaning neck), separated from the scanner's noise by a truncated Fourier series.

#include <Eigen/Core>
#include <vector>

namespace s2m {

struct RoundnessBand {
  double z_lo = 0.0, z_hi = 0.0;  // the band along the frame's z
  Eigen::Index points = 0;
  double largest_gap = 0.0;  // radians: the widest angle around the axis without a point
  // Whether the harmonics were estimated: at least kMinPoints points and no gap wider than kMaxGap (a sherd's
  // band is not: a partial arc cannot tell an oval from a shifted circle). Otherwise the figures are NaN.
  bool resolved = false;
  // First harmonic: the band's centre off the axis (eq. A6), with its standard uncertainty.
  double centre_offset = 0.0, centre_offset_uncertainty = 0.0;
  // Second harmonic: the largest minus the smallest diameter, 4 c2 (eq. A7), with its standard uncertainty.
  double ovality = 0.0, ovality_uncertainty = 0.0;
  // Peak-to-valley of the harmonics 2 to 4 around the band (eq. A8): the out-of-round shape without the
  // offset.
  double out_of_round = 0.0;
  // RMS of what the series leaves: the noise (and finer form) the figures are not made of.
  double residual_rms = 0.0;

  static constexpr int kMinPoints = 40;
  static constexpr double kMaxGap = 1.0471975511965976;  // 60 degrees
};

// `points` in a frame whose z axis is the axis, `deviations` their signed distances to the fitted surface
// (positive away from the axis), `bands` equal bands between z_lo and z_hi. In each band the deviations are
// fitted by least squares with d(theta) = a0 + sum_{k=1..4} (a_k cos k theta + b_k sin k theta) (eq. A5);
// the uncertainties follow from the fit's covariance s^2 (A^T A)^-1 (s^2 the residual variance) through the
// amplitude's gradient. Amplitudes near their uncertainty are biased upwards (a Rayleigh amplitude): read
// them against it. Throws std::invalid_argument for mismatched sizes, bands < 1 or z_hi <= z_lo.
std::vector<RoundnessBand> MeasureRoundnessBands(const Eigen::Matrix3Xd& points,
                                                 const Eigen::VectorXd& deviations, double z_lo, double z_hi,
                                                 int bands);

// The signed deviations of points from a surface around the frame's z axis turned into deviations across the
// axis at the point's height (eq. A9): a point at distance d along the surface normal n from its foot is
// d / n_rho off the surface's radius at its height, n_rho the normal's radial component, here (rho_p - rho_f)
// / d from the point and its foot (rho the distance to the axis). NaN where the surface there is within 60
// degrees of horizontal (|n_rho| < 0.5: a base, a flat shoulder, whose radius a deviation hardly changes);
// deviations within 1e-6 of the point's distance to the axis are returned as they are. Throws
// std::invalid_argument for mismatched sizes.
Eigen::VectorXd RadialDeviations(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& feet,
                                 const Eigen::VectorXd& deviations);

}  // namespace s2m
