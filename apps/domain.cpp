#include "apps/domain.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "apps/output.h"
#include "apps/svg.h"
#include "fitting/foot_point.h"
#include "registration/local_quadric.h"
#include "registration/nearest_index.h"

namespace s2m::app {
namespace {

nlohmann::json NumberOrNull(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

double NumberOr(const nlohmann::json& j, double fallback) {
  return j.is_number() ? j.get<double>() : fallback;
}

// Signed distances with the sign of (x - foot) . n, n = C_u x C_v at the foot point, optionally turned away
// from the z axis.
Eigen::VectorXd SignedDistances(const ParametricModel& model, const Eigen::Matrix3Xd& points,
                                bool away_from_axis) {
  std::vector<FootPoint> feet;
  ComputeFootPoints(model, Eigen::MatrixXd(points), feet);
  Eigen::VectorXd out(points.cols());
  LocalGeometry g;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const FootPoint& foot = feet[static_cast<std::size_t>(i)];
    model.Evaluate(foot.t, 1, g);
    const Eigen::Vector3d c = To3(g.point);
    Eigen::Vector3d n = To3(g.d1.col(0)).cross(To3(g.d1.col(1)));
    if (away_from_axis && n.dot(Eigen::Vector3d(c.x(), c.y(), 0.0)) < 0) n = -n;
    const double side = (Eigen::Vector3d(points.col(i)) - c).dot(n);
    out[i] = side < 0 ? -foot.distance : foot.distance;
  }
  return out;
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

Eigen::VectorXd SignedDistancesAroundAxis(const ParametricModel& model, const Eigen::Matrix3Xd& points) {
  return SignedDistances(model, points, true);
}

Eigen::VectorXd SignedDistancesToFaces(const PartModel& part, const Eigen::Matrix3Xd& points) {
  return SignedDistances(part, points, false);
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

// The median of a chi-square variable with `dof` degrees of freedom: exact for 2 (2 ln 2), else the
// Wilson-Hilferty approximation k (1 - 2 / (9k))^3 (relative error below 1e-3 for k >= 3).
double ChiSquareMedian(int dof) {
  if (dof == 2) return 2 * std::log(2.0);
  const double k = dof;
  return k * std::pow(1 - 2 / (9 * k), 3);
}

double EstimateNoise(const ScanSet& set) {
  // 8 neighbours (2 degrees of freedom each, hundreds of neighbourhoods per view): larger patches bias the
  // estimate upwards where the surface's third-order terms show (measured on the synthetic pots of
  // acquisition/synthetic_batch.h, noise 0.02, about 4 mm point spacing: 0.0226 with 8 neighbours, 0.0267
  // with 10, 0.058 with 20, pooled).
  constexpr int kNeighbours = 8;
  constexpr Eigen::Index kCentres = 500;
  // Per neighbourhood the variance estimate s^2 = SS / dof, scaled so that its median is sigma^2; the median
  // over all neighbourhoods ignores those straddling an edge of a part (measured on the demo block, noise
  // 0.02: the pooled mean gives 0.0297, the median 0.020).
  std::vector<double> scaled_variances;
  for (const Scan& scan : set.scans) {
    const Eigen::Index n = scan.points.cols();
    if (n < 2 * kNeighbours) continue;
    const NearestIndex index(scan.points);
    const Eigen::Index stride = std::max<Eigen::Index>(1, n / kCentres);
    Eigen::Matrix3Xd neighbours(3, kNeighbours);
    for (Eigen::Index c = 0; c < n; c += stride) {
      const Eigen::Vector3d centre = scan.points.col(c);
      const std::vector<Eigen::Index> near = index.KNearest(centre, kNeighbours);
      if (static_cast<int>(near.size()) < kNeighbours) continue;
      for (int k = 0; k < kNeighbours; ++k)
        neighbours.col(k) = scan.points.col(near[static_cast<std::size_t>(k)]);
      try {
        const LocalQuadric q = LocalQuadric::Fit(neighbours, centre);
        double sum_squares = 0.0;
        for (int k = 0; k < kNeighbours; ++k) {
          const Eigen::Vector3d local =
              q.frame().transpose() * (Eigen::Vector3d(neighbours.col(k)) - q.origin());
          const double r = local.z() - q.Height(local.x(), local.y());
          sum_squares += r * r;
        }
        const int dof = kNeighbours - (q.quadratic() ? 6 : 3);
        scaled_variances.push_back(sum_squares / ChiSquareMedian(dof));
      } catch (const std::invalid_argument&) {  // degenerate neighbourhood: no information
      }
    }
  }
  if (scaled_variances.size() < 10) return std::numeric_limits<double>::quiet_NaN();
  auto middle = scaled_variances.begin() + static_cast<std::ptrdiff_t>(scaled_variances.size() / 2);
  std::nth_element(scaled_variances.begin(), middle, scaled_variances.end());
  return std::sqrt(*middle);
}

nlohmann::json AdequacyJson(double fit_rms, double noise) {
  const double ratio = std::isfinite(noise) && noise > 0 ? fit_rms / noise : std::nan("");
  return {{"fit_rms", fit_rms},
          {"noise_estimate", NumberOrNull(noise)},
          {"rms_to_noise", NumberOrNull(ratio)},
          {"threshold", kAdequacyThreshold},
          {"adequate",
           std::isfinite(ratio) ? nlohmann::json(ratio <= kAdequacyThreshold) : nlohmann::json(nullptr)},
          {"noise_method", "median over local quadrics of 8 neighbours within each view (docs/batch.md)"}};
}

std::string AdequacyText(const nlohmann::json& a) {
  std::ostringstream t;
  t << "\n  model adequacy    ";
  if (a["rms_to_noise"].is_null()) {
    t << "unknown (too few points per view to estimate their noise)\n";
  } else {
    t << "RMS / noise " << Format(a["rms_to_noise"].get<double>(), 3) << " (noise estimate "
      << Format(a["noise_estimate"].get<double>(), 3)
      << "): " << (a["adequate"].get<bool>() ? "adequate" : "NOT adequate") << " (threshold "
      << kAdequacyThreshold << ")\n";
  }
  return t.str();
}

nlohmann::json VesselJson(const nlohmann::json& m, const std::string& units) {
  Eigen::Vector3d point, up;
  for (int i = 0; i < 3; ++i) {
    point[i] = m.at("axis").at("point").at(static_cast<std::size_t>(i)).get<double>();
    up[i] = m.at("axis").at("direction").at(static_cast<std::size_t>(i)).get<double>();
  }
  const double sign = up.z() < 0 ? -1.0 : 1.0;  // the rim is the end higher in the world
  up *= sign;
  const nlohmann::json& samples = m.at("profile").at("samples_height_radius");
  const nlohmann::json& uncertainty = m.at("profile").at("samples_radius_uncertainty");
  struct Sample {
    double height, radius, uncertainty;
  };
  std::vector<Sample> profile;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    profile.push_back({sign * samples[i][0].get<double>(), samples[i][1].get<double>(),
                       i < uncertainty.size() ? NumberOr(uncertainty[i], std::nan("")) : std::nan("")});
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
  nlohmann::json rows = nlohmann::json::array();
  for (const Sample& s : profile)
    rows.push_back({s.height - base_height, s.radius, NumberOrNull(s.uncertainty)});
  const Sample& base = profile.front();
  const Sample& rim = profile.back();
  return {{"units", units},
          {"up", ToJson(up)},
          {"base_centre", ToJson(Eigen::Vector3d(point + base_height * up))},
          {"height", highest - lowest},
          {"base_diameter", 2 * base.radius},
          {"base_diameter_uncertainty", NumberOrNull(2 * base.uncertainty)},
          {"rim_diameter", 2 * rim.radius},
          {"rim_diameter_uncertainty", NumberOrNull(2 * rim.uncertainty)},
          {"max_diameter", 2 * profile[widest].radius},
          {"max_diameter_height", profile[widest].height - base_height},
          {"profile_columns", {"height_above_base", "radius", "radius_uncertainty"}},
          {"profile", rows},
          {"convention", "axis towards the world's +z; base = lower end of the profile, rim = upper end"}};
}

std::string VesselText(const nlohmann::json& v, const std::string& units) {
  auto with_u = [](const nlohmann::json& value, const nlohmann::json& u) {
    return Format(value.get<double>(), 6) +
           (u.is_number() ? " +- " + Format(u.get<double>(), 2) : std::string());
  };
  std::ostringstream t;
  t << "\n  vessel (axis towards the world's +z: base below, rim above)\n"
    << "  height            " << Format(v["height"].get<double>(), 6) << " " << units << "\n"
    << "  rim diameter      " << with_u(v["rim_diameter"], v["rim_diameter_uncertainty"]) << " " << units
    << "\n"
    << "  base diameter     " << with_u(v["base_diameter"], v["base_diameter_uncertainty"]) << " " << units
    << "\n"
    << "  largest diameter  " << Format(v["max_diameter"].get<double>(), 6) << " " << units << " at "
    << Format(v["max_diameter_height"].get<double>(), 4) << " above the base\n";
  return t.str();
}

std::string ProfileCsv(const nlohmann::json& vessel) {
  std::ostringstream csv;
  csv.precision(12);
  csv << "height_above_base,radius,radius_uncertainty\n";
  for (const nlohmann::json& row : vessel.at("profile")) {
    csv << row[0].get<double>() << ',' << row[1].get<double>() << ',';
    if (row[2].is_number()) csv << row[2].get<double>();
    csv << '\n';
  }
  return csv.str();
}

std::string ProfileSvg(const nlohmann::json& v, const std::string& units) {
  using svg::Num;
  std::vector<Eigen::Vector2d> profile;  // (radius, height above base)
  double max_r = 0, min_h = 0, max_h = 0;
  for (const nlohmann::json& row : v.at("profile")) {
    profile.emplace_back(row[1].get<double>(), row[0].get<double>());
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

void WriteProfileFiles(const std::string& prefix, const nlohmann::json& vessel, const std::string& units) {
  WriteTextAtomically(prefix + "_profile.csv", ProfileCsv(vessel));
  WriteTextAtomically(prefix + "_profile.svg", ProfileSvg(vessel, units));
}

}  // namespace s2m::app
