#pragma once
// A fitted shell's growth beyond Raup's three numbers (docs/shells.md): the measures of each whorl the scan
// covers, and whether the logarithmic spiral holds at all, tested against the allometric spiral of eq. S1
// (the growth rate changing along the coil, the axial scale outgrowing the radial one).

#include <Eigen/Core>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "fitting/joint_fit.h"
#include "fitting/kinematic_surfaces.h"
#include "pipeline/domain_measures.h"

namespace s2m::pipeline {

// One whorl (docs/shells.md section 2): the generating curve at coiling angle `angle` (radians, the fit's
// frame), `whorls_from_last` whole turns before the last angle the data reach. Height, width, umbilical
// width and diameter as SpiralSurface::WhorlAt defines them, with standard uncertainties from the shape
// covariance (eq. 18 of docs/metrology.md) and the last angle's own uncertainty. The umbilical width and the
// diameter need the data to reach the opposite side of the axis half a turn earlier: NaN when they do not.
struct WhorlMeasures {
  int whorls_from_last = 0;
  double angle = 0.0;
  Measure height, width, umbilical_width, diameter;
  // The shares of where the data end in each uncertainty (rows height, width, umbilical width, diameter;
  // columns the coil's end, eq. S7a, and the generating curve's lower and upper ends, eq. S7b), standard
  // uncertainties (NaN where the measure has none). Each is a gap between the last point and an end, whose
  // distribution is exponential, not normal (docs/shells.md section 2): what a calibration needs to know.
  Eigen::Matrix<double, 4, 3> end_shares =
      Eigen::Matrix<double, 4, 3>::Constant(std::numeric_limits<double>::quiet_NaN());
};

// Where the data lie on a shell (docs/shells.md section 2), from the feet of its kept points (a foot on the
// surface's boundary counts at its clamped parameters: the end rule trimmed the generating curve where the
// data end, eq. 70 of docs/method.md, and the angle range reaches a margin beyond them, so such a foot is a
// point at the curve's end): the coiling angles they cover, the last one's own standard uncertainty (eq.
// S7a), and the part of the generating curve they cover, u in [curve_lo, curve_hi], with the standard
// uncertainties of both ends in u (eq. S7b). NaN where there are no feet.
struct ShellCoverage {
  double angle_lo = std::numeric_limits<double>::quiet_NaN(), angle_hi = angle_lo,
         angle_uncertainty = angle_lo;
  double curve_lo = angle_lo, curve_hi = angle_lo;
  double curve_lo_uncertainty = angle_lo, curve_hi_uncertainty = angle_lo;
  bool covered() const { return angle_lo <= angle_hi && curve_lo <= curve_hi; }
};
ShellCoverage MeasureCoverage(const std::vector<FootPoint>& feet);

// Where the shell itself ends, estimated from where its data end (docs/shells.md eq. S7c): the last point
// falls short of an end by one spacing of the feet there on average, so each end is put one spacing (its
// standard uncertainty, eqs. S7a and S7b) beyond the last foot, along the coil and along the generating curve
// (on the curve's tangent line). Without a finite spacing an end stays at the last foot.
struct ShellEnds {
  double angle = 0.0;                                                       // the last whorl's coiling angle
  Eigen::Vector2d curve_lo = Eigen::Vector2d::Zero(), curve_hi = curve_lo;  // (r, z) on the curve's tangent
};
ShellEnds EstimateEnds(const SpiralSurface& shell, const ShellCoverage& coverage);

// The whorls at the shell's estimated end (EstimateEnds), a turn before it, and so on while inside the
// coiling angles the data cover, each measured on the part of the generating curve between its estimated ends
// (SpiralSurface::ExtentsBetween; eq. S5a). Standard uncertainties: the shape covariance's share (eq. 18 of
// docs/metrology.md) with the ends following the data, and in quadrature the shares of where the data end,
// along the coil (eq. S7a: the rows move with angle_hi) and along the generating curve (eq. S7b).
std::vector<WhorlMeasures> MeasureWhorls(const SpiralSurface& shell, const Eigen::MatrixXd& shape_covariance,
                                         const ShellCoverage& coverage, const std::string& units);

// Raup's D and T and the growing tube's E, C and T of a shell (docs/archaeology.md section 7), written into
// `out`, on the part of its generating curve between its estimated ends (EstimateEnds; eq. S5a), or on the
// whole curve when `coverage` is not covered. Standard uncertainties: the shape covariance's share with the
// ends held and, in quadrature, each end's own (eq. S7b).
void MeasureRaup(const SpiralSurface& shell, const Eigen::MatrixXd& shape_covariance,
                 const ShellCoverage& coverage, ShellMeasures& out);

// The standard uncertainty of the last coiling angle the data reach, from the angles of the points' feet
// (docs/shells.md eq. S7a): the points sample the coil at random, so the last one falls short of the coil's
// end by about the local spacing of the angles, the width of the last tenth of a turn over the feet in it.
double LastAngleUncertainty(const std::vector<double>& foot_angles, double angle_hi);

// The same for an end of the generating curve's covered part (eq. S7b): the width of the tenth of the covered
// range [lo, hi] next to `end` (lo or hi) over the feet in it; NaN without any.
double CurveEndUncertainty(const std::vector<double>& foot_parameters, double lo, double hi, bool at_hi);

// The test of the logarithmic spiral against the allometric one (docs/shells.md section 3): the nested
// model refitted jointly from the logarithmic fit, its q and a with their standard uncertainties, and the
// Wald statistic chi2 = theta^T V^-1 theta of theta = (q, a) (eq. S8) with 2 degrees of freedom.
struct AllometryTest {
  Measure growth_change;  // q, 1/rad^2
  Measure axial_excess;   // a, 1/rad
  // What they mean per whorl: the whorl expansion rate a turn later over now, e^{4 pi^2 q} (eq. S9), and the
  // height-to-width ratio of the generating curve a turn later over now, e^{2 pi a} (eq. S10).
  Measure expansion_rate_change_per_whorl, shape_change_per_whorl;
  double chi2 = 0.0;
  double p_value = 1.0;  // exp(-chi2 / 2), the chi-square tail with 2 degrees of freedom
  double rms_logarithmic = 0.0, rms_allometric = 0.0;
  // "holds": the data do not show allometric growth (p at least kAllometryAlpha); "does not hold": they do;
  // "inconclusive": the logarithmic fit is not adequate and the allometric one does not explain why;
  // "not tested": the nested fit had no uncertainties (too few points, q and a unobservable).
  std::string verdict = "not tested";
  std::string reason;
  nlohmann::json ToJson() const;
};

// The false-alarm rate of the allometry test: the one-sided z > 3 of the residual-structure tests
// (kStructureZ), 1.35e-3, so that a logarithmic shell is called allometric as rarely as an adequate model
// is called structured.
constexpr double kAllometryAlpha = 1.349898031630095e-3;

// The nested model the test fits (docs/shells.md section 3): `fitted` with q = a = 0 freed and its angle
// range widened by half a turn at either end (the allometric surface's data may reach past the logarithmic
// one's range).
SpiralSurface AllometricStart(const SpiralSurface& fitted);

// Tests q = a = 0 on the allometric spiral `nested`, fitted jointly (shape covariance `shape_covariance`,
// RMS `rms_allometric`) with the same loss, weights and left-out points as the logarithmic fit of RMS
// `rms_logarithmic`. `logarithmic_trusted` is the logarithmic fit's adequacy verdict (its
// uncertainty_trusted()), `noise` the data's noise estimate (NaN: unknown): a logarithmic fit that is not
// adequate gives "inconclusive" unless the test is significant and the allometric fit's RMS is within
// kAdequacyThreshold x the noise.
AllometryTest TestAllometry(const SpiralSurface& nested, const Eigen::MatrixXd& shape_covariance,
                            double rms_allometric, double rms_logarithmic,
                            std::optional<bool> logarithmic_trusted, double noise);

nlohmann::json WhorlsJson(const std::vector<WhorlMeasures>& whorls);

// The shell's section through its axis as an SVG drawing (the archaeological and malacological convention,
// axis vertical, the model's z up): the half-plane at coiling angle angle_hi right of the axis, the one at
// angle_hi - pi left of it, each cutting the coil once a turn, at v = angle_hi - 2 pi k and angle_hi - pi
// - 2 pi k. Each cut is the generating curve at that v, scaled as the surface scales it there; solid where
// v lies in [angle_lo, angle_hi] (the coiling angles the data cover), dashed for the inner whorls the model
// extrapolates below angle_lo, while a whorl's size (the larger of its height and width) stays above
// kSectionSmallestWhorl of the last one's and keeps shrinking towards the apex. Annotated with the last
// whorl's height and width (SpiralSurface::WhorlAt(angle_hi)), its umbilical width when positive, a scale
// bar of a round length in `units` and a one-line caption. Throws std::invalid_argument unless angle_lo <=
// angle_hi, both finite.
std::string ShellSectionSvg(const SpiralSurface& shell, double angle_lo, double angle_hi,
                            const std::string& units);
constexpr double kSectionSmallestWhorl = 0.02;

}  // namespace s2m::pipeline
