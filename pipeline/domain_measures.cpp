#include "pipeline/domain_measures.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>

#include "pipeline/output.h"
#include "pipeline/svg.h"

namespace s2m::pipeline {
namespace {

nlohmann::json NumberOrNull(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

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
                              const DeviationOptions& o) {
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
  std::vector<double> edges, counts(static_cast<std::size_t>(bins), 0.0);
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
  for (Eigen::Index i = 0; i < n; i += stride) {
    sample.push_back({world_points(0, i), world_points(1, i), world_points(2, i), d[i]});
  }
  j["sample"] = {{"stride", stride}, {"columns", {"x", "y", "z", "deviation"}}, {"points", sample}};
  return j;
}

Adequacy AssessAdequacy(double fit_rms, double noise) {
  Adequacy a;
  a.fit_rms = fit_rms;
  a.noise_estimate = noise;
  if (std::isfinite(noise) && noise > 0) a.rms_to_noise = fit_rms / noise;
  if (std::isfinite(a.rms_to_noise)) a.adequate = a.rms_to_noise <= a.threshold;
  a.noise_method = "median over local quadrics of 8 neighbours within each view (docs/batch.md)";
  return a;
}

nlohmann::json Adequacy::ToJson() const {
  return {{"fit_rms", fit_rms},
          {"noise_estimate", NumberOrNull(noise_estimate)},
          {"rms_to_noise", NumberOrNull(rms_to_noise)},
          {"threshold", threshold},
          {"adequate", adequate ? nlohmann::json(*adequate) : nlohmann::json(nullptr)},
          {"noise_method", noise_method}};
}

std::string Adequacy::Text() const {
  std::ostringstream t;
  t << "\n  model adequacy    ";
  if (!std::isfinite(rms_to_noise) || !adequate) {
    t << "unknown (too few points per view to estimate their noise)\n";
  } else {
    t << "RMS / noise " << Format(rms_to_noise, 3) << " (noise estimate " << Format(noise_estimate, 3)
      << "): " << (*adequate ? "adequate" : "NOT adequate") << " (threshold " << threshold << ")\n";
  }
  return t.str();
}

VesselMeasures MeasureVessel(const Eigen::Vector3d& axis_point, const Eigen::Vector3d& axis_direction,
                             const std::vector<Eigen::Vector2d>& height_radius,
                             const std::vector<double>& radius_uncertainty, const std::string& units) {
  const double sign = axis_direction.z() < 0 ? -1.0 : 1.0;  // the rim is the end higher in the world
  VesselMeasures v;
  v.units = units;
  v.up = sign * axis_direction;
  struct Sample {
    double height, radius, uncertainty;
  };
  std::vector<Sample> profile;
  for (std::size_t i = 0; i < height_radius.size(); ++i) {
    profile.push_back({sign * height_radius[i].x(), height_radius[i].y(),
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

nlohmann::json VesselMeasures::ToJson() const {
  nlohmann::json rows = nlohmann::json::array();
  for (const ProfileSample& s : profile)
    rows.push_back({s.height_above_base, s.radius, NumberOrNull(s.radius_uncertainty)});
  return {{"units", units},
          {"up", pipeline::ToJson(up)},
          {"base_centre", pipeline::ToJson(base_centre)},
          {"height", height.value},
          {"base_diameter", base_diameter.value},
          {"base_diameter_uncertainty", NumberOrNull(base_diameter.uncertainty)},
          {"rim_diameter", rim_diameter.value},
          {"rim_diameter_uncertainty", NumberOrNull(rim_diameter.uncertainty)},
          {"max_diameter", max_diameter.value},
          {"max_diameter_height", max_diameter_height},
          {"profile_columns", {"height_above_base", "radius", "radius_uncertainty"}},
          {"profile", rows},
          {"convention", "axis towards the world's +z; base = lower end of the profile, rim = upper end"}};
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
  for (const nlohmann::json& row : j.at("profile")) {
    v.profile.push_back(
        {row.at(0).get<double>(), row.at(1).get<double>(), NumberOr(row.at(2), std::nan(""))});
  }
  return v;
}

std::string VesselMeasures::Text() const {
  auto with_u = [](const Measure& m) {
    return Format(m.value, 6) +
           (std::isfinite(m.uncertainty) ? " +- " + Format(m.uncertainty, 2) : std::string());
  };
  std::ostringstream t;
  t << "\n  vessel (axis towards the world's +z: base below, rim above)\n"
    << "  height            " << Format(height.value, 6) << " " << units << "\n"
    << "  rim diameter      " << with_u(rim_diameter) << " " << units << "\n"
    << "  base diameter     " << with_u(base_diameter) << " " << units << "\n"
    << "  largest diameter  " << Format(max_diameter.value, 6) << " " << units << " at "
    << Format(max_diameter_height, 4) << " above the base\n";
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
  return {{"value", growth.value},
          {"uncertainty", NumberOrNull(growth.uncertainty)},
          {"whorl_expansion_rate", whorl_expansion_rate.value},
          {"whorl_expansion_rate_uncertainty", NumberOrNull(whorl_expansion_rate.uncertainty)}};
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
  std::ostringstream left, right;
  for (const Eigen::Vector2d& p : profile) {
    left << Num(X(-p.x())) << "," << Num(Y(p.y())) << " ";
    right << Num(X(p.x())) << "," << Num(Y(p.y())) << " ";
  }
  s << "<polyline points=\"" << left.str() << "\" fill=\"none\" stroke=\"#000\" stroke-width=\"2.2\"/>\n"
    << "<polyline points=\"" << right.str() << "\" fill=\"none\" stroke=\"#777\" stroke-width=\"0.8\"/>\n";
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

void WriteProfileFiles(const std::string& prefix, const VesselMeasures& vessel) {
  WriteTextAtomically(prefix + "_profile.csv", ProfileCsv(vessel));
  WriteTextAtomically(prefix + "_profile.svg", ProfileSvg(vessel));
}

}  // namespace s2m::pipeline
