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
// result's world.
nlohmann::json DeviationsJson(const Eigen::Matrix3Xd& world_points, const Eigen::VectorXd& signed_distances,
                              const DeviationOptions& options = {});

// A measured quantity with its standard uncertainty (GUM, type A; NaN when unknown) and its unit, carried
// explicitly: the unit string comes from the input (the views' or the part file's), never from a name.
struct Measure {
  double value = 0.0;
  double uncertainty = std::numeric_limits<double>::quiet_NaN();
  std::string unit;
};

// Adequacy of a model: ratio = fit RMS / noise estimate; adequate when the ratio is at most
// kAdequacyThreshold (unknown when the noise is).
constexpr double kAdequacyThreshold = 1.5;
struct Adequacy {
  double fit_rms = 0.0;
  double noise_estimate =
      std::numeric_limits<double>::quiet_NaN();  // EstimateNoise (fitting/noise_estimate.h)
  double rms_to_noise = std::numeric_limits<double>::quiet_NaN();
  double threshold = kAdequacyThreshold;
  std::optional<bool> adequate;  // empty when the noise is unknown
  std::string noise_method;

  // {fit_rms, noise_estimate, rms_to_noise, threshold, adequate, noise_method}; unknown values as null.
  nlohmann::json ToJson() const;
  // The "model adequacy" line of the text output.
  std::string Text() const;
};
Adequacy AssessAdequacy(double fit_rms, double noise_estimate);

// One sample of a vessel's profile: height above the base and radius, in the vessel's units.
struct ProfileSample {
  double height_above_base = 0.0;
  double radius = 0.0;
  double radius_uncertainty = std::numeric_limits<double>::quiet_NaN();
};

// Vessel measures of a surface of revolution: the axis oriented towards the world's +z (the base is the end
// lower in the world, the rim the upper one), base centre, height, base, rim and largest diameters with
// standard uncertainties, and the profile from base to rim.
struct VesselMeasures {
  std::string units;
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d base_centre = Eigen::Vector3d::Zero();
  Measure height, base_diameter, rim_diameter, max_diameter;
  double max_diameter_height = 0.0;  // above the base
  std::vector<ProfileSample> profile;

  // The "vessel" member of scan2model.multiview/1 (docs/cli.md).
  nlohmann::json ToJson() const;
  // Reads that member back (a batch record, a report's input). Throws nlohmann::json::exception when members
  // are missing or of the wrong type.
  static VesselMeasures FromJson(const nlohmann::json& vessel);
  // The "vessel" block of the text output.
  std::string Text() const;
};
// From the fitted axis (a point and a direction, world frame) and the profile sampled as (height along the
// axis from the axis point, radius) with the radius' standard uncertainty per sample (NaN: unknown). Throws
// std::invalid_argument for fewer than two samples.
VesselMeasures MeasureVessel(const Eigen::Vector3d& axis_point, const Eigen::Vector3d& axis_direction,
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
  // {value, uncertainty, whorl_expansion_rate, whorl_expansion_rate_uncertainty}
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
// The profile drawing (SVG, standalone) in the vessel's units: axis vertical, the profile (section) left of
// the axis, the vessel's outline mirrored right of it as a thin line, rim and base marked by horizontal lines
// with their diameters, a scale bar.
std::string ProfileSvg(const VesselMeasures& vessel);
// Writes PREFIX_profile.csv and PREFIX_profile.svg (atomically).
void WriteProfileFiles(const std::string& prefix, const VesselMeasures& vessel);

}  // namespace s2m::pipeline
