#pragma once
// Domain outputs of the fits (docs/batch.md): what archaeologists, biologists and metrologists read off a
// result.
// - Signed deviations of the data from the fitted model: a histogram over all points and a subsample with
//   world coordinates (the report's pictures).
// - The model's adequacy: the fit's RMS relative to the views' own noise, estimated without the model from
//   local quadrics (a spiral model that does not describe a shell leaves an RMS well above the noise).
// - Vessels (surfaces of revolution): axis, base and rim diameters, height, the profile curve as CSV and as
// an
//   SVG drawing in the archaeological convention.

#include <Eigen/Core>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "fitting/noise_estimate.h"
#include "fitting/out_of_round.h"
#include "fitting/residual_structure.h"
#include "fitting/robust_loss.h"
#include "fitting/sherd_measures.h"
#include "fitting/signed_distance.h"
#include "registration/scan.h"

namespace s2m::pipeline {

// The columns of all matrices side by side.
Eigen::Matrix3Xd Concatenate(const std::vector<Eigen::Matrix3Xd>& parts);

// Options of the deviations summary.
struct DeviationOptions {
  int max_sample = 2000;  // points kept with their coordinates (every k-th point, deterministic)
  int bins = 41;          // histogram bins, symmetric about 0
  // Histogram range: +- min(largest |deviation|, range_in_rms x RMS); values beyond count as below/above.
  double range_in_rms = 5.0;
};
// {count, rms, mean, min, max, histogram: {edges, counts, below, above}, sample: {stride, columns,
// points: [[x, y, z, deviation], ...]}}; `world_points` are the points the distances belong to, in the
// result's world. With robust `weights` (one per point) the sample has a fifth column, `weight` (the IRLS
// weight: below 0.5 down-weighted, 0 rejected), and the document `down_weighted` and `rejected` counts.
nlohmann::json DeviationsJson(const Eigen::Matrix3Xd& world_points, const Eigen::VectorXd& signed_distances,
                              const DeviationOptions& options = {},
                              const Eigen::VectorXd& weights = Eigen::VectorXd());

// A measured quantity with its standard uncertainty (GUM, type A; NaN when unknown) and its unit, carried
// explicitly: the unit string comes from the input (the views' or the part file's), never from a name.
struct Measure {
  double value = 0.0;
  double uncertainty = std::numeric_limits<double>::quiet_NaN();
  std::string unit;
};

// Adequacy of a model (docs/method.md section 17): the fit's RMS against the data's noise estimated without
// the model (ratio at most kAdequacyThreshold), AND no significant structure in the signed residuals (the
// runs test along an order and Moran's I over nearest neighbours, fitting/residual_structure.h): structure
// is significant when a test's z-score passes kStructureZ in the direction of clustering AND its effect size
// (sign correlation, Moran's I) passes kStructureEffect.
constexpr double kAdequacyThreshold = 1.5;
// One-sided z > 3: a false alarm rate of 1.35e-3 per test, 2.7e-3 per fit with both tests (Bonferroni).
constexpr double kStructureZ = 3.0;
// Effect size: Moran's I is about the share of the residual variance that is smooth over neighbours; 0.1
// means an RMS at least 5 % above the noise from the misfit. Without it, a large cloud (n = 1e5: standard
// error of I about 0.001) flags irrelevant structure.
constexpr double kStructureEffect = 0.1;
// Heavy tails: more than 1 % of the points beyond 3 MAD sigmas (a normal sample has 0.27 %).
constexpr double kHeavyTailFraction = 0.01;
// Clutter: more than 20 % of the points down-weighted by a robust loss.
constexpr double kManyDownWeighted = 0.2;

enum class ModelFamily { kPrimitive, kSpline, kMultiView, kPart };

// What AssessAdequacy needs from a fit.
struct AdequacyEvidence {
  ModelFamily family = ModelFamily::kPrimitive;
  std::string model;           // e.g. "cylinder", "bspline-curve", "revolution", "part:block.json"
  std::string control_points;  // splines and generatrices: the count used, e.g. "12", "8x8" (suggestions)
  double fit_rms = 0.0;        // over all points
  double noise_estimate = std::numeric_limits<double>::quiet_NaN();
  std::string noise_method;
  // One residual per point, signed (outside positive); for a space curve, where an orthogonal distance has
  // no sign, the distances (`signed_residuals` false: the tests use them about their median).
  Eigen::VectorXd residuals;
  bool signed_residuals = true;
  Eigen::Matrix3Xd points;  // the points the residuals belong to (neighbours for Moran's I)
  // The order of the runs test (a permutation of the points) and what it follows; empty: a Hilbert curve
  // through the points.
  std::vector<Eigen::Index> order;
  std::string order_description;
  // Robust fits: each point's final IRLS weight (empty: plain least squares).
  Eigen::VectorXd weights;
  bool reports_uncertainties = true;  // the fit reports uncertainties (not the splines)
  double extent = 0.0;  // the data's bounding-box diagonal: RMS below 1e-9 x extent is exact data
};

struct Adequacy {
  double fit_rms = 0.0;
  // What is compared with the noise: the RMS, or for a robust fit the RMS of the points with weight >= 0.5.
  double fit_scale = 0.0;
  std::string fit_scale_kind = "rms";
  double noise_estimate =
      std::numeric_limits<double>::quiet_NaN();  // EstimateNoise (fitting/noise_estimate.h)
  double rms_to_noise = std::numeric_limits<double>::quiet_NaN();
  double threshold = kAdequacyThreshold;
  std::optional<bool> rms_within_band;  // empty when the noise is unknown
  bool exact = false;                   // the residuals are at rounding level (exact data)
  // The noise estimate is at rounding level on inexact data (quantized depth, resampled points): unusable.
  bool noise_at_rounding_level = false;
  // Residual structure; absent when not assessed (the old RMS-only form, or too few points).
  std::optional<RunsTest> runs;
  std::string runs_order;
  std::optional<MoranTest> moran;
  bool runs_significant = false, moran_significant = false;
  bool structure = false;  // either is significant
  // Tails of the residuals: sigma = 1.4826 MAD and the fraction beyond 3 sigma.
  double mad_sigma = std::numeric_limits<double>::quiet_NaN();
  double beyond_3_sigma = std::numeric_limits<double>::quiet_NaN();
  bool heavy_tails = false;
  double down_weighted_fraction = std::numeric_limits<double>::quiet_NaN();  // robust fits
  std::optional<bool> adequate;  // RMS within the band and no structure; empty when the noise is unknown
  std::vector<std::string> suggestions;  // what to try when not adequate
  std::string noise_method;
  bool reports_uncertainties = true;  // false for fits without uncertainties (splines): no warning line

  // Whether the reported uncertainties (type A, from the residuals under an adequate model) can be trusted:
  // `adequate` (empty: unknown).
  std::optional<bool> uncertainty_trusted() const { return adequate; }
  // {fit_rms, fit_scale, fit_scale_kind, noise_estimate, rms_to_noise, threshold, rms_within_band, exact,
  // structure: {...}, tails: {...}, down_weighted_fraction, adequate, uncertainty_trusted, suggestions,
  // noise_method} (docs/cli.md); unknown values as null.
  nlohmann::json ToJson() const;
  // The "model adequacy" block of the text output.
  std::string Text() const;
};
// The RMS against the noise only (no residual structure): what fits without per-point residuals use.
Adequacy AssessAdequacy(double fit_rms, double noise_estimate);
// The full verdict: RMS band, structure, tails, suggestions.
Adequacy AssessAdequacy(const AdequacyEvidence& evidence);

// Each point's IRLS weight rho'(d^2) at the fit's final loss scale (input units), for the fits that report
// only the scale; empty for plain least squares.
Eigen::VectorXd RobustWeightsAt(const RobustLoss& loss, double scale, const Eigen::VectorXd& distances);

// Marks every uncertainty block of a result document with `uncertainty_trusted` (true, false or null):
// the document itself (beside `uncertainties`), `pitch`, `growth`, `vessel`, `profile`, each view with a
// `pose_uncertainty`, and each entry of an array `parameters` (parts).
void MarkUncertainties(nlohmann::json& document, std::optional<bool> trusted);
// An uncertainty for the text output: "-" when unknown, in brackets when not trustworthy.
std::string UncertaintyText(double uncertainty, std::optional<bool> trusted, int digits = 3);
// The line every text output prints above untrustworthy uncertainties ("" when they are trusted).
std::string UntrustedUncertaintiesLine(std::optional<bool> trusted);

// One sample of a vessel's profile: height above the base and radius, in the vessel's units.
struct ProfileSample {
  double height_above_base = 0.0;
  double radius = 0.0;
  double radius_uncertainty = std::numeric_limits<double>::quiet_NaN();
};

// Below this covered fraction of the turn a surface of revolution is a fragment (a sherd): drawn as one and
// measured as one (docs/archaeology.md sections 6 and 9).
constexpr double kFragmentTurn = 0.9;
// Below this preserved fraction of the circumference a single-surface sherd's stated uncertainties of the
// axis, the diameters and the preserved fraction are not known to hold, and the output says so
// (docs/archaeology.md section 9: over 50 synthetic rim sherds per size, at 40, 20 and 10 % of the
// circumference, the root mean squares of the standardized errors were 0.80-0.88 (rim diameter) and
// 0.83-0.98 (preserved fraction), with at most 1 axis component in 96 beyond 3 u; the 10 % sherds preserve
// about 0.09 at the rim, and nothing smaller was measured).
constexpr double kCalibratedSherdFraction = 0.08;

// What a sherd adds to its vessel's measures (docs/archaeology.md section 9): how its way up was decided
// and the preserved fraction of the circumference.
struct SherdSummary {
  // "rim": the edge level across the axis is the rim, drawn up; "world": the end higher in the world is
  // drawn up (the edges do not tell the rim). `up_reason` says why.
  std::string up_from = "world";
  std::string up_reason;
  // The fraction of the circumference preserved (eq. A14) with its standard uncertainty (A16) and the two
  // parts of it (A15: the axis; the sampling of the breaks), in the band below the rim ("rim") or in the
  // widest of ten bands of a body sherd ("widest band"); band heights above the base.
  Measure preserved_fraction{std::numeric_limits<double>::quiet_NaN(),
                             std::numeric_limits<double>::quiet_NaN(), ""};
  double preserved_axis_uncertainty = std::numeric_limits<double>::quiet_NaN();
  double preserved_sampling_uncertainty = std::numeric_limits<double>::quiet_NaN();
  std::string preserved_where;
  double band_lo = 0, band_hi = 0;
  long long band_points = 0;
  // The edges' evidence in the drawing's orientation (eqs. A12-A13a): robust spread of the edge's height over
  // the sectors of the arc, what a level edge would show, and the spread a level edge stays under.
  double top_spread = std::numeric_limits<double>::quiet_NaN(), top_expected = top_spread,
         top_limit = top_spread;
  double bottom_spread = top_spread, bottom_expected = top_spread, bottom_limit = top_spread;
  bool top_level = false, bottom_level = false;
  // False below kCalibratedSherdFraction: the fit's uncertainties of the axis, the diameters and the
  // preserved fraction are then lower bounds, and a note says so.
  bool uncertainties_calibrated = true;
};

// Vessel measures of a surface of revolution: the axis oriented up (`up`: the rim is the upper end; by
// default the end higher in the world, for a sherd whose rim its edges tell, that rim), base centre,
// height, base, rim and largest diameters with standard uncertainties, and the profile from base to rim.
struct VesselMeasures {
  std::string units;
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d base_centre = Eigen::Vector3d::Zero();
  Measure height, base_diameter, rim_diameter, max_diameter;
  double max_diameter_height = 0.0;  // above the base
  std::vector<ProfileSample> profile;
  // A wall fit's inner surface (docs/archaeology.md section 10), sampled as `profile` (heights above the same
  // base, from its lower end to its upper end); empty when only one surface was fitted. The drawing fills
  // the section between the two.
  std::vector<ProfileSample> inner_profile;
  // The volume enclosed by the fitted surface between the base plane and the rim plane (units^3), with its
  // standard uncertainty propagated from the shape covariance (docs/archaeology.md eqs. A1-A4): the capacity
  // when the fitted surface is the vessel's inner one. NaN when not computed.
  Measure volume{std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN(), ""};
  // The same up to a fill height above the base (`--fill-height`; NaN: not asked).
  double fill_height = std::numeric_limits<double>::quiet_NaN();
  Measure fill_volume{std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN(), ""};
  // Out-of-roundness band by band from base to rim (docs/archaeology.md eqs. A5-A8), heights above the base;
  // empty when not measured.
  std::vector<RoundnessBand> roundness;
  // The fraction of the circumference the points cover about the axis (5-degree sectors holding at least a
  // tenth of the mean count); NaN: not measured. Below 0.9 the object is drawn as a fragment (IsFragment).
  double covered_turn = std::numeric_limits<double>::quiet_NaN();
  bool IsFragment() const { return covered_turn < kFragmentTurn; }
  // Fragments: the sherd's stance and preserved fraction (empty for whole vessels or when not measured).
  std::optional<SherdSummary> sherd;

  // The "vessel" member of scan2model.multiview/1 (docs/cli.md).
  nlohmann::json ToJson() const;
  // Reads that member back (a batch record, a report's input). Throws nlohmann::json::exception when members
  // are missing or of the wrong type.
  static VesselMeasures FromJson(const nlohmann::json& vessel);
  // The "vessel" block of the text output; untrusted uncertainties in brackets (MarkUncertainties).
  std::string Text(std::optional<bool> uncertainty_trusted = std::nullopt) const;
};
// The sherd measures (fitting/sherd_measures.h) of the registered points (model frame, all views one after
// the other, `view_sizes` points each) that `take` selects, each with its view's 6x6 pose covariance; `noise`
// the data's noise. Nullopt, with a note appended to `notes`, when they cannot be taken (too few points).
std::optional<SherdMeasures> MeasureSherdOfPoints(
    const Eigen::Matrix3Xd& registered, const std::vector<Eigen::Index>& view_sizes,
    const std::vector<bool>& take, const std::vector<Eigen::Matrix<double, 6, 6>>& pose_covariance,
    double noise, std::vector<std::string>& notes);

// A sherd's measures (fitting/sherd_measures.h, in the fitted model frame) in the drawing's orientation:
// `up_sign` +1 when the model's z is drawn up, -1 when it is drawn down; heights above `base`, the base's
// height along the drawn-up direction (up_sign times the model's z).
SherdSummary SummarizeSherd(const SherdMeasures& sherd, double up_sign, double base);

// From the fitted axis (a point on it and the direction drawn up, world frame) and the profile sampled as
// (height along `up_direction` from the axis point, radius) with the radius' standard uncertainty per sample
// (NaN: unknown): the rim is the highest end. Throws std::invalid_argument for fewer than two samples.
VesselMeasures MeasureVessel(const Eigen::Vector3d& axis_point, const Eigen::Vector3d& up_direction,
                             const std::vector<Eigen::Vector2d>& height_radius,
                             const std::vector<double>& radius_uncertainty, const std::string& units);

// A helical surface's pitch (length per radian of turn) and its lead (length per turn, 2 pi pitch).
struct HelixMeasures {
  Measure pitch;  // units/rad
  double lead_per_turn = 0.0;
  nlohmann::json ToJson() const;  // {value, uncertainty, lead_per_turn}
};
HelixMeasures MeasureHelix(double pitch, double pitch_uncertainty, const std::string& units);

// A shell's (spiral surface's) growth: the logarithmic spiral r = r0 exp(growth theta) (Moseley 1838; Raup
// 1966, J. Paleontology 40(5)), and the whorl expansion rate W = exp(2 pi growth), Raup's W, with its
// uncertainty propagated to first order: u(W) = 2 pi W u(growth).
struct ShellMeasures {
  Measure growth;                // 1/rad
  Measure whorl_expansion_rate;  // dimensionless
  // Raup's D and T (docs/archaeology.md section 7; W is the whorl expansion rate); NaN: not measured.
  Measure raup_d{std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN(), ""};
  Measure raup_t{std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN(), ""};
  // The growing-tube parameters E, C, T (docs/archaeology.md eqs. A18-A20; Noshita 2014's convention); NaN:
  // not measured.
  Measure tube_expansion{std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN(),
                         ""};
  Measure tube_curvature = tube_expansion, tube_torsion = tube_expansion;
  // {value, uncertainty, whorl_expansion_rate, whorl_expansion_rate_uncertainty, raup {w, d, d_uncertainty,
  // t, t_uncertainty, growing_tube {e, c, t and their uncertainties, convention} when known} when D or T is
  // known}
  nlohmann::json ToJson() const;
};
ShellMeasures MeasureShell(double growth, double growth_uncertainty, double whorl_expansion_rate);

// A parameter against its tolerance (nominal +- tolerance): the plain verdict, and the decision of ISO
// 14253-1 with the expanded uncertainty U = 2 u (conformance or non-conformance proven, or neither).
struct ToleranceCheck {
  double deviation = 0.0;  // measured - nominal
  double tolerance = 0.0;
  double uncertainty = std::numeric_limits<double>::quiet_NaN();  // standard; NaN: unknown (never proven)
  std::string verdict;   // "pass" when |deviation| <= tolerance, else "fail"
  std::string decision;  // "conforms", "does not conform", "ambiguous"
};
ToleranceCheck CheckTolerance(double deviation, double tolerance, double uncertainty);

// What a parameter of scan2model.fit/1 measures, hence its unit: lengths take the input's units.
enum class ParameterKind { kLength, kDirection, kAngleRadians, kAngleDegrees };
// The explicit table of the primitives' parameters (pipeline/fit_dispatch.cpp writes them). Throws
// std::out_of_range naming a parameter not in the table.
ParameterKind PrimitiveParameterKind(const std::string& name);
// The unit of a parameter of that kind: `length_units` for lengths, "" for directions, "rad", "deg".
std::string UnitOf(ParameterKind kind, const std::string& length_units);

// The profile as CSV: height_above_base,radius,radius_uncertainty.
std::string ProfileCsv(const VesselMeasures& vessel);
// The section of a wall fit as a closed outline, (radius, height above base) points: the outer profile from
// the base up to the rim, then the inner one from its upper end down to its lower end (the outline closes
// from there to the outer's base). Empty without an inner profile.
std::vector<Eigen::Vector2d> WallSection(const VesselMeasures& vessel);
// The profile drawing (SVG, standalone) in the vessel's units: axis vertical, the profile (section) left of
// the axis, the vessel's outline mirrored right of it as a thin line, rim and base marked by horizontal lines
// with their diameters, a scale bar. With a wall fit's inner profile, the section between the two surfaces is
// filled (the archaeological convention: the cut through the wall drawn solid).
std::string ProfileSvg(const VesselMeasures& vessel);
// The same drawing as DXF (AutoCAD R12, ASCII; docs/archaeology.md section 6), in the vessel's units (1
// drawing unit = 1 unit): x across the axis, y the height above the base; layers AXIS, SECTION (the profile,
// x <= 0; with a wall fit's inner profile, also the wall's section as one closed polyline, for the CAD tool's
// hatch: R12 has no hatch entity), EXTERIOR (its mirror), RIM, BASE, SCALE and TEXT.
std::string ProfileDxf(const VesselMeasures& vessel);
// The profile in the rim-first, base-at-origin convention of Kotyle (docs/archaeology.md section 6): points
// from the rim down to the base, x the radius, y the height above the base (the base's centre at the origin),
// as CSV (x,y) and as a GeoJSON Feature (a LineString in the vessel's units, not geographic coordinates, with
// the measures as properties).
std::string ProfileKotyleCsv(const VesselMeasures& vessel);
std::string ProfileGeoJson(const VesselMeasures& vessel);
// Writes PREFIX_profile.csv, PREFIX_profile.svg, PREFIX_profile.dxf, PREFIX_profile_kotyle.csv and
// PREFIX_profile.geojson (each atomically).
void WriteProfileFiles(const std::string& prefix, const VesselMeasures& vessel);

}  // namespace s2m::pipeline
