#include "pipeline/domain_measures.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>

#include "fitting/robust_loss.h"
#include "pipeline/output.h"
#include "pipeline/svg.h"

namespace s2m::pipeline {
namespace {

double NumberOr(const nlohmann::json& j, double fallback) {
  return j.is_number() ? j.get<double>() : fallback;
}

}  // namespace

Eigen::Matrix3Xd Concatenate(const std::vector<Eigen::Matrix3Xd>& parts) {
  Eigen::Index total = 0;
  for (const auto& p : parts) total += p.cols();
  Eigen::Matrix3Xd out(3, total);
  Eigen::Index at = 0;
  for (const auto& p : parts) {
    out.middleCols(at, p.cols()) = p;
    at += p.cols();
  }
  return out;
}

nlohmann::json DeviationsJson(const Eigen::Matrix3Xd& world_points, const Eigen::VectorXd& d,
                              const DeviationOptions& o, const Eigen::VectorXd& weights) {
  nlohmann::json j;
  const Eigen::Index n = d.size();
  j["count"] = n;
  if (n == 0) return j;
  const double rms = std::sqrt(d.squaredNorm() / static_cast<double>(n));
  j["rms"] = rms;
  j["mean"] = d.mean();
  j["min"] = d.minCoeff();
  j["max"] = d.maxCoeff();
  const double largest = d.cwiseAbs().maxCoeff();
  double range = std::min(largest, o.range_in_rms * rms);
  if (!(range > 0)) range = 1.0;
  const int bins = std::max(o.bins, 1);
  std::vector<double> edges;
  std::vector<long long> counts(static_cast<std::size_t>(bins), 0);  // integers in the JSON
  for (int b = 0; b <= bins; ++b) edges.push_back(-range + 2 * range * b / bins);
  long long below = 0, above = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (d[i] < -range) {
      ++below;
    } else if (d[i] > range) {
      ++above;
    } else {
      const int b = std::min(bins - 1, static_cast<int>((d[i] + range) / (2 * range) * bins));
      counts[static_cast<std::size_t>(std::max(b, 0))] += 1;
    }
  }
  j["histogram"] = {{"edges", edges}, {"counts", counts}, {"below", below}, {"above", above}};
  const Eigen::Index stride = std::max<Eigen::Index>(1, (n + o.max_sample - 1) / std::max(o.max_sample, 1));
  nlohmann::json sample = nlohmann::json::array();
  const bool weighted = weights.size() == n;
  for (Eigen::Index i = 0; i < n; i += stride) {
    nlohmann::json row = {world_points(0, i), world_points(1, i), world_points(2, i), d[i]};
    if (weighted) row.push_back(weights[i]);
    sample.push_back(std::move(row));
  }
  nlohmann::json columns = {"x", "y", "z", "deviation"};
  if (weighted) {
    columns.push_back("weight");
    j["down_weighted"] = (weights.array() < 0.5).count();
    j["rejected"] = (weights.array() == 0.0).count();
  }
  j["sample"] = {{"stride", stride}, {"columns", columns}, {"points", sample}};
  return j;
}

namespace {

constexpr const char* kNoiseMethod =
    "median over local quadrics of 8 neighbours within each view (docs/batch.md)";
// Moran's I on at most this many points (every k-th): the k-d tree's neighbours of 2e4 points take tens of
// milliseconds; its standard error there (about 0.003) is far below the effect threshold.
constexpr Eigen::Index kMoranMaxPoints = 20000;
constexpr int kMoranNeighbours = 8;

std::string Percent(double fraction) {
  return Format(100 * fraction, 2) + " %";
}

std::string SplineCountHint(const std::string& control_points) {
  return control_points.empty() ? "" : " than the " + control_points + " used";
}

// What to try, from the evidence (docs/cli.md, "adequacy").
std::vector<std::string> Suggestions(const AdequacyEvidence& e, const Adequacy& a) {
  std::vector<std::string> out;
  if (a.adequate.value_or(true)) return out;
  const bool robust = e.weights.size() > 0;
  if (a.heavy_tails && !robust) {
    out.push_back("heavy-tailed residuals (" + Percent(a.beyond_3_sigma) +
                  " of the points beyond 3 sigma): a robust loss (--loss cauchy), or fit --robust when other "
                  "objects, a stand or a floor are in the data");
  }
  if (robust && a.down_weighted_fraction > kManyDownWeighted) {
    out.push_back(Percent(a.down_weighted_fraction) +
                  " of the points are down-weighted: the data hold more than this model (clutter, a second "
                  "object, a stand): fit --robust (the dominant instance) or detect");
  }
  if (a.structure) {
    std::string where = a.runs_significant ? "along " + a.runs_order : "between neighbouring points";
    switch (e.family) {
      case ModelFamily::kSpline:
        out.push_back("residuals structured " + where +
                      ": more control points (--control-points auto, or a " + "larger count" +
                      SplineCountHint(e.control_points) + ")");
        break;
      case ModelFamily::kPrimitive: {
        std::string other = "bspline-surface";
        if (e.model == "cylinder")
          other = "cone (a taper), revolution (a varying profile) or bspline-surface";
        if (e.model == "cone") other = "revolution (a curved profile) or bspline-surface";
        if (e.model == "sphere") other = "revolution or bspline-surface";
        if (e.model == "plane") other = "bspline-surface (the surface is not flat)";
        out.push_back("residuals structured " + where + ": the surface is not a " + e.model +
                      "; try another model: " + other +
                      "; or, when the scan also holds other objects or a background, fit --robust (the "
                      "dominant instance) or detect");
        break;
      }
      case ModelFamily::kMultiView:
        out.push_back("residuals structured " + where + ": more control points for the generatrix " +
                      "(--control-points auto, or a larger count" + SplineCountHint(e.control_points) +
                      "), or another model (revolution, helical, spiral)");
        break;
      case ModelFamily::kPart:
        out.push_back("residuals structured " + where +
                      ": the part differs from its file (free a fixed parameter, add a missing face) or a " +
                      "view is mis-registered");
        break;
    }
  }
  if (out.empty() && a.rms_within_band == false) {
    const bool spline = e.family == ModelFamily::kSpline || e.family == ModelFamily::kMultiView;
    out.push_back(std::string("RMS above the noise estimate without a structure the tests detect: ") +
                  (spline ? "more control points (--control-points auto), or " : "") +
                  "the misfit is finer than the neighbourhoods, or the noise estimate is low (quantized or "
                  "resampled data)");
  }
  return out;
}

nlohmann::json RunsJson(const RunsTest& t, const std::string& order, bool significant) {
  return {{"order", order},
          {"positives", t.positives},
          {"negatives", t.negatives},
          {"runs", t.runs},
          {"expected_runs", NumberOrNull(t.expected_runs)},
          {"z", NumberOrNull(t.z)},
          {"sign_correlation", NumberOrNull(t.sign_correlation)},
          {"significant", significant}};
}

nlohmann::json MoranJson(const MoranTest& t, bool significant) {
  return {{"points", t.count},
          {"neighbours", t.neighbours},
          {"statistic", NumberOrNull(t.statistic)},
          {"expected", NumberOrNull(t.expected)},
          {"z", NumberOrNull(t.z)},
          {"significant", significant}};
}

}  // namespace

Adequacy AssessAdequacy(double fit_rms, double noise) {
  Adequacy a;
  a.fit_rms = fit_rms;
  a.fit_scale = fit_rms;
  a.noise_estimate = noise;
  if (std::isfinite(noise) && noise > 0) a.rms_to_noise = fit_rms / noise;
  if (std::isfinite(a.rms_to_noise)) a.rms_within_band = a.rms_to_noise <= a.threshold;
  a.adequate = a.rms_within_band;
  a.noise_method = kNoiseMethod;
  return a;
}

Adequacy AssessAdequacy(const AdequacyEvidence& e) {
  Adequacy a;
  a.fit_rms = e.fit_rms;
  a.noise_estimate = e.noise_estimate;
  a.noise_method = e.noise_method.empty() ? kNoiseMethod : e.noise_method;
  const Eigen::Index n = e.residuals.size();
  const bool robust = e.weights.size() == n && n > 0;
  // The points the structure tests and the scale use: all, or a robust fit's inliers (weight >= 0.5).
  std::vector<Eigen::Index> kept;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!robust || e.weights[i] >= 0.5) kept.push_back(i);
  }
  a.fit_scale = e.fit_rms;
  if (robust) {
    double sum = 0;
    for (const Eigen::Index i : kept) sum += e.residuals[i] * e.residuals[i];
    a.fit_scale = kept.empty() ? e.fit_rms : std::sqrt(sum / static_cast<double>(kept.size()));
    a.fit_scale_kind = "rms of the points with robust weight >= 0.5";
    a.down_weighted_fraction = 1.0 - static_cast<double>(kept.size()) / static_cast<double>(n);
  }
  // Exact data: residuals at rounding level (certified reference sets, synthetic exact points).
  a.exact = e.extent > 0 && a.fit_scale <= 1e-9 * e.extent;
  // A noise estimate at rounding level on data that are not exact means the neighbourhoods fit exactly: depth
  // quantized into steps (the real Kinect frames: 4e-19 m, on 1 mm raw units), or resampled points. It
  // says nothing about the noise: unknown, and the verdict rests on the structure.
  a.noise_at_rounding_level =
      !a.exact && e.extent > 0 && std::isfinite(e.noise_estimate) && e.noise_estimate <= 1e-9 * e.extent;
  if (std::isfinite(e.noise_estimate) && e.noise_estimate > 0 && !a.noise_at_rounding_level)
    a.rms_to_noise = a.fit_scale / e.noise_estimate;
  if (a.exact) {
    a.rms_within_band = true;
  } else if (std::isfinite(a.rms_to_noise)) {
    a.rms_within_band = a.rms_to_noise <= a.threshold;
  }

  // Tails (all points): a normal sample has 0.27 % beyond 3 sigma.
  if (n > 0) {
    a.mad_sigma = MadSigma(e.residuals);
    if (a.mad_sigma > 0) {
      a.beyond_3_sigma =
          static_cast<double>((e.residuals.array().abs() > 3 * a.mad_sigma).count()) / static_cast<double>(n);
      a.heavy_tails = e.signed_residuals && a.beyond_3_sigma > kHeavyTailFraction;
    }
  }

  // Structure, on the kept points: values signed, or (space curves) distances about their median.
  if (!a.exact && kept.size() >= 20 && e.points.cols() == n) {
    Eigen::VectorXd values(static_cast<Eigen::Index>(kept.size()));
    Eigen::Matrix3Xd where(3, values.size());
    for (Eigen::Index k = 0; k < values.size(); ++k) {
      values[k] = e.residuals[kept[static_cast<std::size_t>(k)]];
      where.col(k) = e.points.col(kept[static_cast<std::size_t>(k)]);
    }
    if (!e.signed_residuals) {
      Eigen::VectorXd sorted = values;
      std::nth_element(sorted.data(), sorted.data() + sorted.size() / 2, sorted.data() + sorted.size());
      values.array() -= sorted[sorted.size() / 2];
    }
    // The runs order restricted to the kept points.
    std::vector<Eigen::Index> position(static_cast<std::size_t>(n), -1);
    for (std::size_t k = 0; k < kept.size(); ++k)
      position[static_cast<std::size_t>(kept[k])] = static_cast<Eigen::Index>(k);
    std::vector<Eigen::Index> order;
    if (static_cast<Eigen::Index>(e.order.size()) == n) {
      for (const Eigen::Index i : e.order) {
        if (position[static_cast<std::size_t>(i)] >= 0)
          order.push_back(position[static_cast<std::size_t>(i)]);
      }
      a.runs_order = e.order_description;
    } else {
      order = HilbertOrder(where);
      a.runs_order = "a Hilbert curve through the points";
    }
    Eigen::VectorXd ordered(values.size());
    for (Eigen::Index k = 0; k < values.size(); ++k) ordered[k] = values[order[static_cast<std::size_t>(k)]];
    a.runs = SignRunsTest(ordered);
    const Eigen::Index stride =
        std::max<Eigen::Index>(1, (values.size() + kMoranMaxPoints - 1) / kMoranMaxPoints);
    const Eigen::Index m = (values.size() + stride - 1) / stride;
    Eigen::Matrix3Xd sample_points(3, m);
    Eigen::VectorXd sample_values(m);
    for (Eigen::Index k = 0; k < m; ++k) {
      sample_points.col(k) = where.col(k * stride);
      sample_values[k] = values[k * stride];
    }
    a.moran = MoransI(sample_points, sample_values, kMoranNeighbours);
    // One-sided: a model's misfit makes neighbours alike (fewer runs, positive I); alternation is no misfit.
    a.runs_significant =
        std::isfinite(a.runs->z) && -a.runs->z > kStructureZ && a.runs->sign_correlation > kStructureEffect;
    a.moran_significant =
        std::isfinite(a.moran->z) && a.moran->z > kStructureZ && a.moran->statistic > kStructureEffect;
    a.structure = a.runs_significant || a.moran_significant;
  }
  if (a.rms_within_band) a.adequate = *a.rms_within_band && !a.structure;
  if (!a.rms_within_band && a.structure) a.adequate = false;  // unknown noise, but structure is enough
  a.suggestions = Suggestions(e, a);
  a.reports_uncertainties = e.reports_uncertainties;
  return a;
}

nlohmann::json Adequacy::ToJson() const {
  const auto optional_bool = [](const std::optional<bool>& b) {
    return b ? nlohmann::json(*b) : nlohmann::json(nullptr);
  };
  nlohmann::json j = {{"fit_rms", fit_rms},
                      {"fit_scale", fit_scale},
                      {"fit_scale_kind", fit_scale_kind},
                      {"noise_estimate", NumberOrNull(noise_estimate)},
                      {"rms_to_noise", NumberOrNull(rms_to_noise)},
                      {"threshold", threshold},
                      {"rms_within_band", optional_bool(rms_within_band)},
                      {"exact", exact},
                      {"noise_at_rounding_level", noise_at_rounding_level},
                      {"adequate", optional_bool(adequate)},
                      {"uncertainty_trusted", optional_bool(uncertainty_trusted())},
                      {"suggestions", suggestions},
                      {"noise_method", noise_method}};
  if (runs || moran) {
    nlohmann::json& s = j["structure"];
    s = {{"significant", structure}, {"z_threshold", kStructureZ}, {"effect_threshold", kStructureEffect}};
    s["runs"] = runs ? RunsJson(*runs, runs_order, runs_significant) : nlohmann::json(nullptr);
    s["moran"] = moran ? MoranJson(*moran, moran_significant) : nlohmann::json(nullptr);
  } else {
    j["structure"] = nullptr;
  }
  j["tails"] = {{"mad_sigma", NumberOrNull(mad_sigma)},
                {"beyond_3_sigma", NumberOrNull(beyond_3_sigma)},
                {"heavy", heavy_tails}};
  j["down_weighted_fraction"] = NumberOrNull(down_weighted_fraction);
  return j;
}

std::string Adequacy::Text() const {
  std::ostringstream t;
  t << "\n  model adequacy    " << (!adequate ? "unknown" : *adequate ? "adequate" : "NOT adequate") << "\n";
  t << "  RMS / noise       ";
  if (exact) {
    t << "exact data (RMS " << Format(fit_scale, 3) << " at rounding level)\n";
  } else if (noise_at_rounding_level) {
    t << "unknown (the noise estimate " << Format(noise_estimate, 2)
      << " is at rounding level: quantized depth or resampled points)\n";
  } else if (!std::isfinite(rms_to_noise)) {
    t << "unknown (too few points to estimate their noise)\n";
  } else {
    t << Format(rms_to_noise, 3) << " (" << (fit_scale_kind == "rms" ? "RMS " : "inlier RMS ")
      << Format(fit_scale, 3) << ", noise estimate " << Format(noise_estimate, 3)
      << "): " << (*rms_within_band ? "within" : "above") << " the band (<= " << threshold << ")\n";
  }
  if (runs || moran) {
    t << "  structure         ";
    if (runs && std::isfinite(runs->z)) {
      t << "runs along " << runs_order << " z " << Format(runs->z, 3) << " (sign correlation "
        << Format(runs->sign_correlation, 2) << ")";
    } else {
      t << "runs test: too few signs";
    }
    if (moran && std::isfinite(moran->z)) {
      t << ", Moran's I " << Format(moran->statistic, 2) << " (z " << Format(moran->z, 3) << ", "
        << moran->neighbours << " neighbours)";
    }
    t << ": " << (structure ? "significant" : "none") << " (z beyond " << kStructureZ << " and effect above "
      << kStructureEffect << ")\n";
  }
  if (heavy_tails)
    t << "  tails             " << Format(100 * beyond_3_sigma, 2)
      << " % of the points beyond 3 sigma (heavy)\n";
  if (std::isfinite(down_weighted_fraction)) {
    t << "  down-weighted     " << Format(100 * down_weighted_fraction, 3)
      << " % of the points (robust weight < 0.5)\n";
  }
  if (reports_uncertainties) t << UntrustedUncertaintiesLine(uncertainty_trusted());
  for (std::size_t i = 0; i < suggestions.size(); ++i)
    t << (i == 0 ? "  try               " : "                    ") << suggestions[i] << "\n";
  return t.str();
}

Eigen::VectorXd RobustWeightsAt(const RobustLoss& loss, double scale, const Eigen::VectorXd& distances) {
  if (!loss.is_robust()) return {};
  RobustLoss at = loss;
  at.scale = scale > 0 ? scale : loss.scale;
  if (!(at.scale > 0)) return {};
  return RobustWeighting(at).Weights(distances);
}

void MarkUncertainties(nlohmann::json& d, std::optional<bool> trusted) {
  const nlohmann::json flag = trusted ? nlohmann::json(*trusted) : nlohmann::json(nullptr);
  d["uncertainty_trusted"] = flag;
  for (const char* block : {"pitch", "growth", "vessel", "profile"}) {
    if (d.contains(block) && d[block].is_object()) d[block]["uncertainty_trusted"] = flag;
  }
  if (d.contains("views") && d["views"].is_array()) {
    for (nlohmann::json& v : d["views"]) {
      if (v.contains("pose_uncertainty")) v["uncertainty_trusted"] = flag;
    }
  }
  for (const char* list : {"parameters", "measurands"}) {
    if (d.contains(list) && d[list].is_array()) {
      for (nlohmann::json& p : d[list]) {
        if (p.is_object()) p["uncertainty_trusted"] = flag;
      }
    }
  }
}

std::string UncertaintyText(double u, std::optional<bool> trusted, int digits) {
  if (!std::isfinite(u)) return "-";
  return trusted == false ? "[" + Format(u, digits) + "]" : Format(u, digits);
}

std::string UntrustedUncertaintiesLine(std::optional<bool> trusted) {
  return trusted == false ? "  uncertainties are NOT trustworthy: the model is inadequate (uncertainties "
                            "shown in brackets)\n"
                          : "";
}

std::optional<SherdMeasures> MeasureSherdOfPoints(
    const Eigen::Matrix3Xd& registered, const std::vector<Eigen::Index>& view_sizes,
    const std::vector<bool>& take, const std::vector<Eigen::Matrix<double, 6, 6>>& pose_covariance,
    double noise, std::vector<std::string>& notes) {
  std::vector<Eigen::Index> kept;
  std::vector<int> view_of_point;
  Eigen::Index at = 0;
  for (std::size_t k = 0; k < view_sizes.size(); ++k)
    for (Eigen::Index p = 0; p < view_sizes[k]; ++p, ++at)
      if (take[static_cast<std::size_t>(at)]) {
        kept.push_back(at);
        view_of_point.push_back(static_cast<int>(k));
      }
  const Eigen::Matrix3Xd surface = registered(Eigen::all, kept);
  try {
    return MeasureSherd(surface, view_of_point, pose_covariance, noise);
  } catch (const std::invalid_argument& e) {
    notes.push_back(std::string("sherd measures not taken: ") + e.what());
    return std::nullopt;
  }
}

SherdSummary SummarizeSherd(const SherdMeasures& sherd, double up_sign, double base) {
  SherdSummary s;
  s.up_from = sherd.rim_side != 0 ? "rim" : "world";
  s.up_reason = sherd.rim_reason;
  const PreservedArc& a = sherd.preserved;
  s.preserved_fraction = {a.fraction, a.uncertainty, ""};
  s.preserved_axis_uncertainty = a.axis_uncertainty;
  s.preserved_sampling_uncertainty = a.sampling_uncertainty;
  s.preserved_where = sherd.preserved_at_rim ? "rim" : "widest band";
  const double lo = up_sign * a.height_lo - base, hi = up_sign * a.height_hi - base;
  s.band_lo = std::min(lo, hi);
  s.band_hi = std::max(lo, hi);
  s.band_points = static_cast<long long>(a.points);
  // The top edge is the one drawn up.
  const EdgeLevelness& top = up_sign > 0 ? sherd.upper : sherd.lower;
  const EdgeLevelness& bottom = up_sign > 0 ? sherd.lower : sherd.upper;
  s.top_spread = top.spread;
  s.top_expected = top.expected;
  s.top_limit = top.limit;
  s.top_level = top.level;
  s.bottom_spread = bottom.spread;
  s.bottom_expected = bottom.expected;
  s.bottom_limit = bottom.limit;
  s.bottom_level = bottom.level;
  return s;
}

VesselMeasures MeasureVessel(const Eigen::Vector3d& axis_point, const Eigen::Vector3d& up_direction,
                             const std::vector<Eigen::Vector2d>& height_radius,
                             const std::vector<double>& radius_uncertainty, const std::string& units) {
  VesselMeasures v;
  v.units = units;
  v.up = up_direction.normalized();
  struct Sample {
    double height, radius, uncertainty;
  };
  std::vector<Sample> profile;
  for (std::size_t i = 0; i < height_radius.size(); ++i) {
    profile.push_back({height_radius[i].x(), height_radius[i].y(),
                       i < radius_uncertainty.size() ? radius_uncertainty[i] : std::nan("")});
  }
  if (profile.size() < 2) throw std::invalid_argument("the profile has fewer than two samples");
  if (profile.front().height > profile.back().height) std::reverse(profile.begin(), profile.end());
  const double base_height = profile.front().height;
  double lowest = base_height, highest = base_height;
  std::size_t widest = 0;
  for (std::size_t i = 0; i < profile.size(); ++i) {
    lowest = std::min(lowest, profile[i].height);
    highest = std::max(highest, profile[i].height);
    if (profile[i].radius > profile[widest].radius) widest = i;
  }
  for (const Sample& s : profile) v.profile.push_back({s.height - base_height, s.radius, s.uncertainty});
  const Sample& base = profile.front();
  const Sample& rim = profile.back();
  v.base_centre = axis_point + base_height * v.up;
  v.height = {highest - lowest, std::nan(""), units};
  // A diameter is twice a radius: u(2r) = 2 u(r) (GUM 5.1.2, sensitivity coefficient 2).
  v.base_diameter = {2 * base.radius, 2 * base.uncertainty, units};
  v.rim_diameter = {2 * rim.radius, 2 * rim.uncertainty, units};
  v.max_diameter = {2 * profile[widest].radius, std::nan(""), units};
  v.max_diameter_height = profile[widest].height - base_height;
  return v;
}

namespace {

// The "roundness" member of "vessel": a row per band (heights above the base; null where not resolved).
nlohmann::json RoundnessJson(const std::vector<RoundnessBand>& bands) {
  nlohmann::json rows = nlohmann::json::array();
  for (const RoundnessBand& b : bands) {
    rows.push_back({b.z_lo, b.z_hi, b.points, b.largest_gap * 180.0 / M_PI, NumberOrNull(b.centre_offset),
                    NumberOrNull(b.centre_offset_uncertainty), NumberOrNull(b.ovality),
                    NumberOrNull(b.ovality_uncertainty), NumberOrNull(b.out_of_round),
                    NumberOrNull(b.residual_rms)});
  }
  return {{"columns",
           {"height_lo", "height_hi", "points", "largest_gap_deg", "centre_offset",
            "centre_offset_uncertainty", "ovality", "ovality_uncertainty", "out_of_round", "residual_rms"}},
          {"bands", rows},
          {"method",
           "per band, the deviations across the axis (d / n_rho, eq. A9) fitted by a0 + sum_{k=1..4} a_k "
           "cos k t + b_k sin k t; "
           "centre_offset = |(a1, b1)|, ovality = 4 |(a2, b2)| (largest minus smallest diameter), "
           "out_of_round = peak-to-valley of harmonics 2-4; a band with a gap over 60 degrees or "
           "under 40 points is not resolved (docs/archaeology.md section 4)"}};
}

// The "sherd" member of "vessel" (docs/archaeology.md section 9) and back.
nlohmann::json SherdJson(const SherdSummary& s) {
  auto edge = [](double spread, double expected, double limit, bool level) {
    return nlohmann::json{{"spread", NumberOrNull(spread)},
                          {"expected_if_level", NumberOrNull(expected)},
                          {"limit_if_level", NumberOrNull(limit)},
                          {"level", level}};
  };
  return {{"up_from", s.up_from},
          {"up_reason", s.up_reason},
          {"preserved_fraction", NumberOrNull(s.preserved_fraction.value)},
          {"preserved_fraction_uncertainty", NumberOrNull(s.preserved_fraction.uncertainty)},
          {"preserved_fraction_axis_uncertainty", NumberOrNull(s.preserved_axis_uncertainty)},
          {"preserved_fraction_sampling_uncertainty", NumberOrNull(s.preserved_sampling_uncertainty)},
          {"preserved_where", s.preserved_where},
          {"band_height_lo", s.band_lo},
          {"band_height_hi", s.band_hi},
          {"band_points", s.band_points},
          {"edges",
           {{"top", edge(s.top_spread, s.top_expected, s.top_limit, s.top_level)},
            {"bottom", edge(s.bottom_spread, s.bottom_expected, s.bottom_limit, s.bottom_level)}}},
          {"uncertainties_calibrated", s.uncertainties_calibrated}};
}

SherdSummary SherdFromJson(const nlohmann::json& j) {
  SherdSummary s;
  const auto number = [&](const nlohmann::json& o, const char* key) {
    return NumberOr(o.value(key, nlohmann::json()), std::nan(""));
  };
  s.up_from = j.at("up_from").get<std::string>();
  s.up_reason = j.value("up_reason", "");
  s.preserved_fraction = {number(j, "preserved_fraction"), number(j, "preserved_fraction_uncertainty"), ""};
  s.preserved_axis_uncertainty = number(j, "preserved_fraction_axis_uncertainty");
  s.preserved_sampling_uncertainty = number(j, "preserved_fraction_sampling_uncertainty");
  s.preserved_where = j.value("preserved_where", "");
  s.band_lo = number(j, "band_height_lo");
  s.band_hi = number(j, "band_height_hi");
  s.band_points = j.value("band_points", 0LL);
  s.uncertainties_calibrated = j.value("uncertainties_calibrated", true);
  if (j.contains("edges")) {
    const nlohmann::json& top = j.at("edges").at("top");
    const nlohmann::json& bottom = j.at("edges").at("bottom");
    s.top_spread = number(top, "spread");
    s.top_expected = number(top, "expected_if_level");
    s.top_limit = number(top, "limit_if_level");
    s.top_level = top.value("level", false);
    s.bottom_spread = number(bottom, "spread");
    s.bottom_expected = number(bottom, "expected_if_level");
    s.bottom_limit = number(bottom, "limit_if_level");
    s.bottom_level = bottom.value("level", false);
  }
  return s;
}

}  // namespace

nlohmann::json VesselMeasures::ToJson() const {
  nlohmann::json rows = nlohmann::json::array();
  for (const ProfileSample& s : profile)
    rows.push_back({s.height_above_base, s.radius, NumberOrNull(s.radius_uncertainty)});
  nlohmann::json inner_rows = nlohmann::json::array();  // the same columns; empty for one surface
  for (const ProfileSample& s : inner_profile)
    inner_rows.push_back({s.height_above_base, s.radius, NumberOrNull(s.radius_uncertainty)});
  nlohmann::json j = {
      {"units", units},
      {"up", pipeline::ToJson(up)},
      {"base_centre", pipeline::ToJson(base_centre)},
      {"height", height.value},
      {"base_diameter", base_diameter.value},
      {"base_diameter_uncertainty", NumberOrNull(base_diameter.uncertainty)},
      {"rim_diameter", rim_diameter.value},
      {"rim_diameter_uncertainty", NumberOrNull(rim_diameter.uncertainty)},
      {"max_diameter", max_diameter.value},
      {"max_diameter_height", max_diameter_height},
      {"volume", NumberOrNull(volume.value)},
      {"volume_uncertainty", NumberOrNull(volume.uncertainty)},
      {"fill_height", NumberOrNull(fill_height)},
      {"fill_volume", NumberOrNull(fill_volume.value)},
      {"fill_volume_uncertainty", NumberOrNull(fill_volume.uncertainty)},
      {"roundness", RoundnessJson(roundness)},
      {"covered_turn_fraction", NumberOrNull(covered_turn)},
      {"profile_columns", {"height_above_base", "radius", "radius_uncertainty"}},
      {"profile", rows},
      {"inner_profile", inner_rows},
      {"convention",
       sherd && sherd->up_from == "rim"
           ? "up from the base to the rim the sherd's level edge shows; base = lower end of the profile"
           : "axis towards the world's +z; base = lower end of the profile, rim = upper end"}};
  if (sherd) j["sherd"] = SherdJson(*sherd);
  return j;
}

VesselMeasures VesselMeasures::FromJson(const nlohmann::json& j) {
  VesselMeasures v;
  v.units = j.value("units", "unknown");
  for (int i = 0; i < 3; ++i) {
    v.up[i] = j.at("up").at(static_cast<std::size_t>(i)).get<double>();
    v.base_centre[i] = j.at("base_centre").at(static_cast<std::size_t>(i)).get<double>();
  }
  const auto uncertainty = [&](const char* key) {
    return NumberOr(j.value(key, nlohmann::json()), std::nan(""));
  };
  v.height = {j.at("height").get<double>(), std::nan(""), v.units};
  v.base_diameter = {j.at("base_diameter").get<double>(), uncertainty("base_diameter_uncertainty"), v.units};
  v.rim_diameter = {j.at("rim_diameter").get<double>(), uncertainty("rim_diameter_uncertainty"), v.units};
  v.max_diameter = {j.at("max_diameter").get<double>(), std::nan(""), v.units};
  v.max_diameter_height = j.at("max_diameter_height").get<double>();
  const std::string cubic = v.units + "^3";
  v.volume = {uncertainty("volume"), uncertainty("volume_uncertainty"), cubic};
  v.fill_height = uncertainty("fill_height");
  v.fill_volume = {uncertainty("fill_volume"), uncertainty("fill_volume_uncertainty"), cubic};
  v.covered_turn = uncertainty("covered_turn_fraction");
  if (j.contains("sherd") && j.at("sherd").is_object()) v.sherd = SherdFromJson(j.at("sherd"));
  if (j.contains("roundness") && j.at("roundness").is_object()) {
    for (const nlohmann::json& row : j.at("roundness").at("bands")) {
      RoundnessBand b;
      b.z_lo = row.at(0).get<double>();
      b.z_hi = row.at(1).get<double>();
      b.points = row.at(2).get<Eigen::Index>();
      b.largest_gap = row.at(3).get<double>() * M_PI / 180.0;
      b.resolved = row.at(4).is_number();
      b.centre_offset = NumberOr(row.at(4), std::nan(""));
      b.centre_offset_uncertainty = NumberOr(row.at(5), std::nan(""));
      b.ovality = NumberOr(row.at(6), std::nan(""));
      b.ovality_uncertainty = NumberOr(row.at(7), std::nan(""));
      b.out_of_round = NumberOr(row.at(8), std::nan(""));
      b.residual_rms = NumberOr(row.at(9), std::nan(""));
      v.roundness.push_back(b);
    }
  }
  for (const nlohmann::json& row : j.at("profile")) {
    v.profile.push_back(
        {row.at(0).get<double>(), row.at(1).get<double>(), NumberOr(row.at(2), std::nan(""))});
  }
  if (j.contains("inner_profile")) {  // absent in records written before wall sections were drawn
    for (const nlohmann::json& row : j.at("inner_profile")) {
      v.inner_profile.push_back(
          {row.at(0).get<double>(), row.at(1).get<double>(), NumberOr(row.at(2), std::nan(""))});
    }
  }
  return v;
}

std::string VesselMeasures::Text(std::optional<bool> trusted) const {
  auto with_u = [&](const Measure& m) {
    return Format(m.value, 6) + (std::isfinite(m.uncertainty)
                                     ? " +- " + UncertaintyText(m.uncertainty, trusted, 2)
                                     : std::string());
  };
  std::ostringstream t;
  t << (sherd && sherd->up_from == "rim"
            ? "\n  vessel (up towards the sherd's rim: base below, rim above)\n"
            : "\n  vessel (axis towards the world's +z: base below, rim above)\n")
    << "  height            " << Format(height.value, 6) << " " << units << "\n"
    << "  rim diameter      " << with_u(rim_diameter) << " " << units << "\n"
    << "  base diameter     " << with_u(base_diameter) << " " << units << "\n"
    << (sherd && sherd->up_from != "rim"
            ? "                    (a fragment whose edges do not show its rim: \"rim\" and \"base\" are its "
              "upper and lower ends, which may be breaks)\n"
            : "")
    << "  largest diameter  " << Format(max_diameter.value, 6) << " " << units << " at "
    << Format(max_diameter_height, 4) << " above the base\n";
  if (std::isfinite(volume.value))
    t << "  volume            " << with_u(volume) << " " << volume.unit
      << " (inside the fitted surface, base plane to rim plane)\n";
  if (std::isfinite(fill_volume.value))
    t << "  filled volume     " << with_u(fill_volume) << " " << fill_volume.unit << " up to "
      << Format(fill_height, 6) << " " << units << " above the base\n";
  if (!roundness.empty()) {
    const RoundnessBand* worst = nullptr;
    int resolved = 0;
    for (const RoundnessBand& b : roundness) {
      if (!b.resolved) continue;
      ++resolved;
      if (!worst || b.ovality > worst->ovality) worst = &b;
    }
    t << "  out of round      ";
    if (worst) {
      t << "ovality up to " << with_u({worst->ovality, worst->ovality_uncertainty, units}) << " " << units
        << " (largest minus smallest diameter) at " << Format(worst->z_lo, 4) << "-" << Format(worst->z_hi, 4)
        << " above the base; " << resolved << " of " << roundness.size() << " bands resolved\n";
    } else {
      t << "not resolved: no band is seen all round (a sherd) or has enough points\n";
    }
  }
  if (sherd) {
    t << "  sherd             "
      << (sherd->up_from == "rim" ? "rim up (" + sherd->up_reason + ")"
                                  : "way up not told by its edges (" + sherd->up_reason +
                                        "): the end higher in the world is drawn up")
      << "\n";
    if (std::isfinite(sherd->preserved_fraction.value))
      t << "  preserved         " << with_u(sherd->preserved_fraction) << " of the circumference ("
        << (sherd->preserved_where == "rim" ? "at the rim" : "the widest band") << ", "
        << Format(sherd->band_lo, 4) << "-" << Format(sherd->band_hi, 4) << " above the base)\n";
    if (!sherd->uncertainties_calibrated)
      t << "                    (under " << Format(100 * kCalibratedSherdFraction, 2)
        << " % of the circumference: the uncertainties of the axis, the diameters and the preserved "
           "fraction are lower bounds)\n";
  }
  return t.str();
}

HelixMeasures MeasureHelix(double pitch, double pitch_uncertainty, const std::string& units) {
  // The lead is the advance over one full turn, 2 pi radians.
  return {{pitch, pitch_uncertainty, units + "/rad"}, 2 * M_PI * pitch};
}

nlohmann::json HelixMeasures::ToJson() const {
  return {{"value", pitch.value},
          {"uncertainty", NumberOrNull(pitch.uncertainty)},
          {"lead_per_turn", lead_per_turn}};
}

ShellMeasures MeasureShell(double growth, double growth_uncertainty, double whorl_expansion_rate) {
  return {{growth, growth_uncertainty, "1/rad"},
          {whorl_expansion_rate, 2 * M_PI * whorl_expansion_rate * growth_uncertainty, ""}};
}

nlohmann::json ShellMeasures::ToJson() const {
  nlohmann::json j = {{"value", growth.value},
                      {"uncertainty", NumberOrNull(growth.uncertainty)},
                      {"whorl_expansion_rate", whorl_expansion_rate.value},
                      {"whorl_expansion_rate_uncertainty", NumberOrNull(whorl_expansion_rate.uncertainty)}};
  if (std::isfinite(raup_d.value) || std::isfinite(raup_t.value))
    j["raup"] = {
        {"w", whorl_expansion_rate.value}, {"w_uncertainty", NumberOrNull(whorl_expansion_rate.uncertainty)},
        {"d", NumberOrNull(raup_d.value)}, {"d_uncertainty", NumberOrNull(raup_d.uncertainty)},
        {"t", NumberOrNull(raup_t.value)}, {"t_uncertainty", NumberOrNull(raup_t.uncertainty)}};
  if (j.contains("raup") && std::isfinite(tube_expansion.value))
    j["raup"]["growing_tube"] = {
        {"e", tube_expansion.value},
        {"e_uncertainty", NumberOrNull(tube_expansion.uncertainty)},
        {"c", NumberOrNull(tube_curvature.value)},
        {"c_uncertainty", NumberOrNull(tube_curvature.uncertainty)},
        {"t", NumberOrNull(tube_torsion.value)},
        {"t_uncertainty", NumberOrNull(tube_torsion.uncertainty)},
        {"convention",
         "Okamoto's growing tube in Noshita (2014)'s convention: E = dr/ds, C = kappa r, T = tau r of the "
         "generating curve's centre (docs/archaeology.md eqs. A18-A20)"}};
  return j;
}

ToleranceCheck CheckTolerance(double deviation, double tolerance, double uncertainty) {
  const double d = std::abs(deviation);
  // ISO 14253-1: the expanded uncertainty U = k u with k = 2 narrows the conformance zone and widens the
  // non-conformance zone; an unknown uncertainty proves neither.
  const double expanded =
      std::isfinite(uncertainty) ? 2 * uncertainty : std::numeric_limits<double>::infinity();
  ToleranceCheck c;
  c.deviation = deviation;
  c.tolerance = tolerance;
  c.uncertainty = uncertainty;
  c.verdict = d <= tolerance ? "pass" : "fail";
  c.decision = d + expanded <= tolerance  ? "conforms"
               : d - expanded > tolerance ? "does not conform"
                                          : "ambiguous";
  return c;
}

ParameterKind PrimitiveParameterKind(const std::string& name) {
  static const std::map<std::string, ParameterKind> kKinds = {
      {"point", ParameterKind::kLength},
      {"normal", ParameterKind::kDirection},
      {"center", ParameterKind::kLength},
      {"radius", ParameterKind::kLength},
      {"diameter", ParameterKind::kLength},
      {"axis_point", ParameterKind::kLength},
      {"axis_direction", ParameterKind::kDirection},
      {"surface_distance", ParameterKind::kLength},
      {"half_angle", ParameterKind::kAngleRadians},
      {"apex_angle_deg", ParameterKind::kAngleDegrees},
      {"apex", ParameterKind::kLength}};
  const auto it = kKinds.find(name);
  if (it == kKinds.end()) throw std::out_of_range("no unit known for the parameter '" + name + "'");
  return it->second;
}

std::string UnitOf(ParameterKind kind, const std::string& length_units) {
  switch (kind) {
    case ParameterKind::kLength:
      return length_units;
    case ParameterKind::kDirection:
      return "";
    case ParameterKind::kAngleRadians:
      return "rad";
    case ParameterKind::kAngleDegrees:
      return "deg";
  }
  return "";
}

std::string ProfileCsv(const VesselMeasures& vessel) {
  std::ostringstream csv;
  csv.precision(12);
  csv << "height_above_base,radius,radius_uncertainty\n";
  for (const ProfileSample& row : vessel.profile) {
    csv << row.height_above_base << ',' << row.radius << ',';
    if (std::isfinite(row.radius_uncertainty)) csv << row.radius_uncertainty;
    csv << '\n';
  }
  return csv.str();
}

std::vector<Eigen::Vector2d> WallSection(const VesselMeasures& v) {
  std::vector<Eigen::Vector2d> outline;
  if (v.inner_profile.empty() || v.profile.empty()) return outline;
  for (const ProfileSample& row : v.profile) outline.emplace_back(row.radius, row.height_above_base);
  for (auto row = v.inner_profile.rbegin(); row != v.inner_profile.rend(); ++row)
    outline.emplace_back(row->radius, row->height_above_base);
  return outline;
}

std::string ProfileSvg(const VesselMeasures& v) {
  using svg::Num;
  const std::string& units = v.units;
  std::vector<Eigen::Vector2d> profile;  // (radius, height above base)
  double max_r = 0, min_h = 0, max_h = 0;
  for (const ProfileSample& row : v.profile) {
    profile.emplace_back(row.radius, row.height_above_base);
    max_r = std::max(max_r, profile.back().x());
    min_h = std::min(min_h, profile.back().y());
    max_h = std::max(max_h, profile.back().y());
  }
  for (const ProfileSample& row : v.inner_profile) {  // a wall's inner surface may reach above the outer
    min_h = std::min(min_h, row.height_above_base);
    max_h = std::max(max_h, row.height_above_base);
  }
  constexpr double kWidth = 520, kHeight = 520, kMargin = 60;
  const double scale = std::min((kWidth - 2 * kMargin) / std::max(2 * max_r, 1e-9),
                                (kHeight - 2 * kMargin - 30) / std::max(max_h - min_h, 1e-9));
  const double axis_x = kWidth / 2, base_y = kHeight - kMargin - 30 + scale * min_h;
  auto X = [&](double r) { return axis_x + scale * r; };
  auto Y = [&](double h) { return base_y - scale * h; };
  std::ostringstream s;
  s << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << kWidth << "\" height=\"" << kHeight
    << "\" viewBox=\"0 0 " << kWidth << " " << kHeight << "\" font-family=\"sans-serif\" font-size=\"12\">\n"
    << "<title>Vessel profile</title>\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  // Axis (dash-dot), the section left of it, the outline mirrored right of it.
  s << "<line x1=\"" << Num(axis_x) << "\" y1=\"" << Num(Y(max_h) - 3) << "\" x2=\"" << Num(axis_x)
    << "\" y2=\"" << Num(Y(min_h) + 20)
    << "\" stroke=\"#000\" stroke-width=\"0.8\" stroke-dasharray=\"12 3 2 3\"/>\n";
  // A wall: the section between the two surfaces filled, under the outer profile's heavy line.
  if (const std::vector<Eigen::Vector2d> section = WallSection(v); !section.empty()) {
    s << "<polygon points=\"";
    for (const Eigen::Vector2d& p : section) s << Num(X(-p.x())) << "," << Num(Y(p.y())) << " ";
    s << "\" fill=\"#000\" stroke=\"#000\" stroke-width=\"1\"><title>section through the "
         "wall</title></polygon>\n";
  }
  std::ostringstream left, right;
  for (const Eigen::Vector2d& p : profile) {
    left << Num(X(-p.x())) << "," << Num(Y(p.y())) << " ";
    right << Num(X(p.x())) << "," << Num(Y(p.y())) << " ";
  }
  s << "<polyline points=\"" << left.str() << "\" fill=\"none\" stroke=\"#000\" stroke-width=\"2.2\"/>\n"
    << "<polyline points=\"" << right.str() << "\" fill=\"none\" stroke=\"#777\" stroke-width=\"0.8\""
    << (v.IsFragment() ? " stroke-dasharray=\"6 4\"" : "") << "/>\n";
  // A fragment: the preserved section solid, the outline it implies (the rest of the vessel) dashed.
  if (v.IsFragment())
    s << "<text x=\"" << Num(kWidth - 10) << "\" y=\"20\" text-anchor=\"end\" fill=\"#444\">fragment: about "
      << svg::Escape(Format(100 * v.covered_turn, 2))
      << " % of the circumference; outline reconstructed (dashed)"
      << "</text>\n";
  // Rim and base: horizontal lines across the vessel, with their diameters.
  const Eigen::Vector2d base = profile.front(), rim = profile.back();
  const std::string u = svg::Escape(units);
  s << "<line x1=\"" << Num(X(-rim.x())) << "\" y1=\"" << Num(Y(rim.y())) << "\" x2=\"" << Num(X(rim.x()))
    << "\" y2=\"" << Num(Y(rim.y())) << "\" stroke=\"#b2182b\" stroke-width=\"1.2\"/>\n"
    << "<text x=\"" << Num(axis_x) << "\" y=\"" << Num(Y(rim.y()) - 10)
    << "\" text-anchor=\"middle\" fill=\"#b2182b\">rim &#216; " << svg::Escape(Format(2 * rim.x(), 5)) << " "
    << u << "</text>\n"
    << "<line x1=\"" << Num(X(-base.x())) << "\" y1=\"" << Num(Y(base.y())) << "\" x2=\"" << Num(X(base.x()))
    << "\" y2=\"" << Num(Y(base.y())) << "\" stroke=\"#2166ac\" stroke-width=\"1.2\"/>\n"
    << "<text x=\"" << Num(axis_x) << "\" y=\"" << Num(Y(base.y()) + 18)
    << "\" text-anchor=\"middle\" fill=\"#2166ac\">base &#216; " << svg::Escape(Format(2 * base.x(), 5))
    << " " << u << "</text>\n";
  // Height bracket on the right.
  const double hx = X(max_r) + 24;
  s << "<line x1=\"" << Num(hx) << "\" y1=\"" << Num(Y(max_h)) << "\" x2=\"" << Num(hx) << "\" y2=\""
    << Num(Y(min_h)) << "\" stroke=\"#444\"/>\n"
    << "<text transform=\"translate(" << Num(hx + 14) << "," << Num((Y(max_h) + Y(min_h)) / 2)
    << ") rotate(-90)\" text-anchor=\"middle\">height " << svg::Escape(Format(max_h - min_h, 5)) << " " << u
    << "</text>\n";
  // Scale bar: a round length about a fifth of the drawing.
  const std::vector<double> ticks = svg::NiceTicks(0, 2 * max_r, 5);
  const double bar = ticks.size() > 1 ? ticks[1] - ticks[0] : max_r;
  const double bar_y = kHeight - 20;
  s << "<rect x=\"" << Num(kMargin) << "\" y=\"" << Num(bar_y - 6) << "\" width=\"" << Num(scale * bar)
    << "\" height=\"6\" fill=\"#000\"/>\n"
    << "<text x=\"" << Num(kMargin + scale * bar + 6) << "\" y=\"" << Num(bar_y) << "\">"
    << svg::Escape(Format(bar, 4)) << " " << u << "</text>\n"
    << "</svg>\n";
  return s.str();
}

namespace {

// DXF R12 group codes, one pair per two lines (AutoCAD DXF reference: group code, then value).
class DxfWriter {
 public:
  void Pair(int code, const std::string& value) { out_ << code << "\n" << value << "\n"; }
  // Coordinates to 12 significant digits (whatever the units), never "-0".
  void Pair(int code, double value) {
    char buffer[32];
    std::snprintf(buffer, sizeof buffer, "%.12g", value == 0.0 ? 0.0 : value);
    Pair(code, std::string(buffer));
  }
  void Line(const std::string& layer, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    Pair(0, "LINE");
    Pair(8, layer);
    Pair(10, a.x());
    Pair(20, a.y());
    Pair(30, 0.0);
    Pair(11, b.x());
    Pair(21, b.y());
    Pair(31, 0.0);
  }
  void Polyline(const std::string& layer, const std::vector<Eigen::Vector2d>& points, bool closed = false) {
    Pair(0, "POLYLINE");
    Pair(8, layer);
    Pair(66, "1");              // vertices follow
    if (closed) Pair(70, "1");  // polyline flag 1: closed
    Pair(10, 0.0);
    Pair(20, 0.0);
    Pair(30, 0.0);
    for (const Eigen::Vector2d& p : points) {
      Pair(0, "VERTEX");
      Pair(8, layer);
      Pair(10, p.x());
      Pair(20, p.y());
      Pair(30, 0.0);
    }
    Pair(0, "SEQEND");
    Pair(8, layer);
  }
  void Text(const std::string& layer, const Eigen::Vector2d& at, double height, const std::string& text) {
    Pair(0, "TEXT");
    Pair(8, layer);
    Pair(10, at.x());
    Pair(20, at.y());
    Pair(30, 0.0);
    Pair(40, height);
    Pair(1, text);
  }
  std::string str() const { return out_.str(); }

 private:
  std::ostringstream out_;
};

}  // namespace

std::string ProfileDxf(const VesselMeasures& v) {
  double max_r = 0, min_h = 0, max_h = 0;
  for (const std::vector<ProfileSample>* rows : {&v.profile, &v.inner_profile}) {
    for (const ProfileSample& row : *rows) {
      max_r = std::max(max_r, row.radius);
      min_h = std::min(min_h, row.height_above_base);
      max_h = std::max(max_h, row.height_above_base);
    }
  }
  const double text_height = std::max(0.03 * std::max(max_h - min_h, 2 * max_r), 1e-6);
  DxfWriter dxf;
  dxf.Pair(999, "scan2model vessel profile, units " + v.units + " (1 drawing unit = 1 " + v.units + ")");
  dxf.Pair(0, "SECTION");
  dxf.Pair(2, "HEADER");
  dxf.Pair(9, "$ACADVER");
  dxf.Pair(1, "AC1009");
  dxf.Pair(0, "ENDSEC");
  dxf.Pair(0, "SECTION");
  dxf.Pair(2, "ENTITIES");
  dxf.Line("AXIS", {0, min_h - 2 * text_height}, {0, max_h + text_height});
  std::vector<Eigen::Vector2d> section, exterior;
  for (const ProfileSample& row : v.profile) {
    section.emplace_back(-row.radius, row.height_above_base);
    exterior.emplace_back(row.radius, row.height_above_base);
  }
  dxf.Polyline("SECTION", section);
  // A wall: its section as one closed outline (outer profile up, inner profile down).
  if (std::vector<Eigen::Vector2d> wall = WallSection(v); !wall.empty()) {
    for (Eigen::Vector2d& p : wall) p.x() = -p.x();
    dxf.Polyline("SECTION", wall, /*closed=*/true);
  }
  // A fragment's mirrored outline is reconstructed, not preserved: its own layer (for a dashed line type).
  dxf.Polyline(v.IsFragment() ? "RECONSTRUCTED" : "EXTERIOR", exterior);
  if (v.IsFragment())
    dxf.Text("TEXT", {max_r + text_height, max_h}, text_height,
             "fragment: about " + Format(100 * v.covered_turn, 2) + " % of the circumference");
  const Eigen::Vector2d base = exterior.front(), rim = exterior.back();
  dxf.Line("RIM", {-rim.x(), rim.y()}, rim);
  dxf.Text("TEXT", {0, rim.y() + 0.5 * text_height}, text_height,
           "rim diameter " + Format(2 * rim.x(), 5) + " " + v.units);
  dxf.Line("BASE", {-base.x(), base.y()}, base);
  dxf.Text("TEXT", {0, base.y() - 1.5 * text_height}, text_height,
           "base diameter " + Format(2 * base.x(), 5) + " " + v.units);
  const std::vector<double> ticks = svg::NiceTicks(0, 2 * max_r, 5);
  const double bar = ticks.size() > 1 ? ticks[1] - ticks[0] : max_r;
  const double bar_y = min_h - 4 * text_height;
  dxf.Line("SCALE", {-max_r, bar_y}, {-max_r + bar, bar_y});
  dxf.Text("SCALE", {-max_r + bar + 0.5 * text_height, bar_y}, text_height, Format(bar, 4) + " " + v.units);
  dxf.Pair(0, "ENDSEC");
  dxf.Pair(0, "EOF");
  return dxf.str();
}

std::string ProfileKotyleCsv(const VesselMeasures& v) {
  std::ostringstream csv;
  csv.precision(12);
  csv << "x,y\n";
  for (auto row = v.profile.rbegin(); row != v.profile.rend(); ++row)
    csv << row->radius << ',' << row->height_above_base << '\n';
  return csv.str();
}

std::string ProfileGeoJson(const VesselMeasures& v) {
  nlohmann::json line = nlohmann::json::array();
  for (auto row = v.profile.rbegin(); row != v.profile.rend(); ++row)
    line.push_back({row->radius, row->height_above_base});
  nlohmann::json properties = {
      {"units", v.units},
      {"convention", "rim first; x radius, y height above the base; base centre at 0,0"},
      {"rim_diameter", v.rim_diameter.value},
      {"base_diameter", v.base_diameter.value},
      {"height", v.height.value},
      {"rim_diameter_uncertainty", NumberOrNull(v.rim_diameter.uncertainty)},
      {"base_diameter_uncertainty", NumberOrNull(v.base_diameter.uncertainty)},
      {"volume", NumberOrNull(v.volume.value)},
      {"volume_uncertainty", NumberOrNull(v.volume.uncertainty)}};
  const nlohmann::json feature = {{"type", "Feature"},
                                  {"geometry", {{"type", "LineString"}, {"coordinates", line}}},
                                  {"properties", properties}};
  return feature.dump(1) + "\n";
}

void WriteProfileFiles(const std::string& prefix, const VesselMeasures& vessel) {
  WriteTextAtomically(prefix + "_profile.csv", ProfileCsv(vessel));
  WriteTextAtomically(prefix + "_profile.svg", ProfileSvg(vessel));
  WriteTextAtomically(prefix + "_profile.dxf", ProfileDxf(vessel));
  WriteTextAtomically(prefix + "_profile_kotyle.csv", ProfileKotyleCsv(vessel));
  WriteTextAtomically(prefix + "_profile.geojson", ProfileGeoJson(vessel));
}

}  // namespace s2m::pipeline
