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
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "fitting/parametric_model.h"
#include "fitting/part_model.h"
#include "registration/scan.h"

namespace s2m::app {

// The columns of all matrices side by side.
Eigen::Matrix3Xd Concatenate(const std::vector<Eigen::Matrix3Xd>& parts);

// Signed orthogonal distances of points (model frame) to a model around the z axis (surface of revolution,
// helical, spiral): positive on the side away from the axis (outside a pot's wall, the convention of
// SampleAroundAxis).
Eigen::VectorXd SignedDistancesAroundAxis(const ParametricModel& model, const Eigen::Matrix3Xd& points);
// Signed distances of points (part frame) to their nearest faces: positive along the face's normal C_u x C_v
// at the foot point (planes: their normal; cylinders: away from the axis).
Eigen::VectorXd SignedDistancesToFaces(const PartModel& part, const Eigen::Matrix3Xd& points);

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

// The scanner noise of the views, without a model: per view, local quadrics (registration/local_quadric.h)
// over the 8 nearest neighbours of up to 500 points spread over the view; each gives SS / dof scaled to have
// the noise variance as its median; the square root of the median over all of them (docs/batch.md). NaN when
// fewer than 10 neighbourhoods could be fitted.
double EstimateNoise(const ScanSet& set);
// Adequacy of a model: ratio = fit RMS / noise estimate; adequate when the ratio is at most
// kAdequacyThreshold (null when the noise is unknown).
constexpr double kAdequacyThreshold = 1.5;
nlohmann::json AdequacyJson(double fit_rms, double noise_estimate);
std::string AdequacyText(const nlohmann::json& adequacy);

// Vessel measures from a scan2model.multiview/1 document of a surface of revolution: the axis oriented
// towards the world's +z (the base is the end lower in the world, the rim the upper one), base centre,
// height, base, rim and largest diameters with standard uncertainties, and the profile from base to rim.
nlohmann::json VesselJson(const nlohmann::json& multiview, const std::string& units);
std::string VesselText(const nlohmann::json& vessel, const std::string& units);
// The profile as CSV: height_above_base,radius,radius_uncertainty.
std::string ProfileCsv(const nlohmann::json& vessel);
// The profile drawing (SVG, standalone): axis vertical, the profile (section) left of the axis, the vessel's
// outline mirrored right of it as a thin line, rim and base marked by horizontal lines with their diameters,
// a scale bar.
std::string ProfileSvg(const nlohmann::json& vessel, const std::string& units);
// Writes PREFIX_profile.csv and PREFIX_profile.svg (atomically).
void WriteProfileFiles(const std::string& prefix, const nlohmann::json& vessel, const std::string& units);

}  // namespace s2m::app
