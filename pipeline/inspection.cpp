#include "pipeline/inspection.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <map>
#include <random>
#include <sstream>

#include "acquisition/file_hash.h"
#include "acquisition/format_error.h"
#include "acquisition/formats/readers.h"
#include "acquisition/mesh_io.h"
#include "acquisition/recording.h"
#include "fitting/geometric_fit.h"
#include "fitting/measurement_uncertainty.h"
#include "fitting/minimum_zone.h"
#include "fitting/noise_estimate.h"
#include "fitting/nominal_inspection.h"
#include "fitting/primitive_fit.h"
#include "fitting/primitive_measurands.h"
#include "pipeline/domain_measures.h"
#include "pipeline/fit_options.h"
#include "pipeline/output.h"
#include "pipeline/svg.h"
#include "pipeline/views.h"

namespace s2m::pipeline {
namespace {

constexpr double kRadToDeg = 57.29577951308232;

double NaN() {
  return std::numeric_limits<double>::quiet_NaN();
}

}  // namespace

ChecksFile ParseChecksFile(const std::string& text, const std::string& file) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    throw FormatError(file, AtByte(e.byte), std::string("not valid JSON: ") + e.what());
  } catch (const nlohmann::json::exception& e) {
    // A number beyond double's range ("1e400") is out_of_range, not a parse_error.
    throw FormatError(file, "", std::string("not valid JSON: ") + e.what());
  }
  auto fail = [&](const std::string& where, const std::string& problem) {
    throw FormatError(file, where, problem);
  };
  if (!j.is_object()) fail("", "a checks file is a JSON object");
  if (!j.contains("schema") || j["schema"] != "scan2model.checks/1")
    fail("schema", "expected \"schema\": \"scan2model.checks/1\"");
  ChecksFile out;
  if (j.contains("part")) {
    if (!j["part"].is_string()) fail("part", "must be a string");
    out.part = j["part"];
  }
  if (j.contains("datums")) {
    if (!j["datums"].is_array()) fail("datums", "must be an array of face group names");
    for (const auto& d : j["datums"]) {
      if (!d.is_string()) fail("datums", "must be an array of face group names");
      out.datums.push_back(d);
    }
  }
  if (!j.contains("checks") || !j["checks"].is_array()) fail("checks", "an array of checks is required");
  int index = 0;
  for (const auto& c : j["checks"]) {
    const std::string where = "checks[" + std::to_string(index++) + "]";
    if (!c.is_object()) fail(where, "a check is an object");
    CheckSpec s;
    auto text_member = [&](const char* key, bool required) {
      if (!c.contains(key)) {
        if (required) fail(where, std::string("missing \"") + key + "\"");
        return std::string();
      }
      if (!c[key].is_string()) fail(where, std::string("\"") + key + "\" must be a string");
      return c[key].get<std::string>();
    };
    auto number_member = [&](const char* key) -> std::optional<double> {
      if (!c.contains(key)) return std::nullopt;
      if (!c[key].is_number() || !std::isfinite(c[key].get<double>()))
        fail(where, std::string("\"") + key + "\" must be a finite number");
      return c[key].get<double>();
    };
    s.type = text_member("type", true);
    s.group = text_member("group", true);
    s.name = text_member("name", false);
    if (s.name.empty()) s.name = s.type + " of " + s.group;
    if (s.type == "profile" || s.type == "flatness" || s.type == "position") {
      const std::optional<double> t = number_member("tolerance");
      if (!t || !(*t > 0)) fail(where, "\"tolerance\" (a positive zone width) is required for " + s.type);
      s.tolerance = *t;
    } else if (s.type == "diameter" || s.type == "distance") {
      if (s.type == "distance") {
        s.to = text_member("to", true);
        if (s.to == s.group)
          fail(where, "a distance check needs two different face groups (\"group\", \"to\")");
        if (!c.contains("name")) s.name = "distance from " + s.group + " to " + s.to;
      }
      s.nominal = number_member("nominal");
      const std::optional<double> lo = number_member("lower"), hi = number_member("upper");
      if (!lo || !hi)
        fail(where, "a " + s.type + " check needs \"lower\" and \"upper\" (deviations from the nominal)");
      if (*lo > *hi) fail(where, "\"lower\" exceeds \"upper\"");
      s.lower = *lo;
      s.upper = *hi;
    } else {
      fail(where, "unknown check type \"" + s.type + "\" (profile, flatness, position, diameter, distance)");
    }
    out.checks.push_back(s);
  }
  return out;
}

namespace {

// The points of one face group (nominal frame), with their indices.
struct GroupPoints {
  Eigen::Matrix3Xd points;
  std::vector<Eigen::Index> index;
};
GroupPoints PointsOfGroup(const NominalInspection& r, int group) {
  GroupPoints g;
  for (Eigen::Index i = 0; i < r.points.cols(); ++i)
    if (r.group[static_cast<std::size_t>(i)] == group) g.index.push_back(i);
  g.points.resize(3, static_cast<Eigen::Index>(g.index.size()));
  for (std::size_t k = 0; k < g.index.size(); ++k)
    g.points.col(static_cast<Eigen::Index>(k)) = r.points.col(g.index[k]);
  return g;
}

// The vertices of a face group's triangles, each once.
Eigen::Matrix3Xd GroupVertices(const TriangleMesh& mesh, int group) {
  std::vector<int> used(static_cast<std::size_t>(mesh.vertices.cols()), 0);
  for (Eigen::Index f = 0; f < mesh.triangle_count(); ++f)
    if (mesh.GroupOf(f) == group)
      for (int k = 0; k < 3; ++k) used[static_cast<std::size_t>(mesh.triangles(k, f))] = 1;
  std::vector<Eigen::Index> which;
  for (std::size_t i = 0; i < used.size(); ++i)
    if (used[i]) which.push_back(static_cast<Eigen::Index>(i));
  Eigen::Matrix3Xd v(3, static_cast<Eigen::Index>(which.size()));
  for (std::size_t i = 0; i < which.size(); ++i)
    v.col(static_cast<Eigen::Index>(i)) = mesh.vertices.col(which[i]);
  return v;
}

// The nominal bore of a face group: the least-squares cylinder through the group's vertices (exact for a
// prism whose vertices lie on the cylinder).
Cylinder NominalCylinder(const TriangleMesh& mesh, int group, const std::string& check) {
  const Eigen::Matrix3Xd v = GroupVertices(mesh, group);
  if (v.cols() < 6)
    throw FitFailure(kInputError,
                     "check '" + check + "': the nominal's group has too few vertices for a cylinder");
  try {
    return FitCylinder(v).shape;
  } catch (const std::exception& e) {
    throw FitFailure(kInputError,
                     "check '" + check + "': no cylinder through the nominal's group: " + e.what());
  }
}

// ISO 1101 position of an axis: twice the largest distance of the actual axis from the nominal one at the
// feature's two ends (stations t_lo, t_hi along the nominal axis), i.e. the diameter of the smallest
// cylinder about the nominal axis holding the actual axis over the feature's length.
double AxisPosition(const Cylinder& actual, const Cylinder& nominal, double t_lo, double t_hi) {
  const Eigen::Vector3d a0 = nominal.axis_direction.normalized(), a = actual.axis_direction.normalized();
  double worst = 0;
  for (double t : {t_lo, t_hi}) {
    const Eigen::Vector3d q = nominal.axis_point + t * a0;
    const double s = a0.dot(q - actual.axis_point) / a0.dot(a);
    worst = std::max(worst, (actual.axis_point + s * a - q).norm());
  }
  return 2 * worst;
}

// One feature of a distance check (docs/metrology.md eq. 17a): a plane, or a cylinder's axis. `anchor` is
// the nominal group's area centroid; the feature's reference point is its foot on the plane, or on the axis.
struct Feature {
  bool is_plane = true;
  Plane plane;
  Cylinder cylinder;
  Eigen::Vector3d anchor = Eigen::Vector3d::Zero();
};

// The nominal group as a feature: its vertices on one plane, else on one cylinder, to 1e-6 of the mesh's
// size (a CAD mesh's planar face or a prism approximating a bore); anything else is refused.
Feature NominalFeature(const TriangleMesh& mesh, int group, const std::string& check) {
  Feature f;
  double area = 0;
  for (Eigen::Index t = 0; t < mesh.triangle_count(); ++t) {
    if (mesh.GroupOf(t) != group) continue;
    const Eigen::Vector3d a = mesh.vertices.col(mesh.triangles(0, t)),
                          b = mesh.vertices.col(mesh.triangles(1, t)),
                          c = mesh.vertices.col(mesh.triangles(2, t));
    const double w = 0.5 * (b - a).cross(c - a).norm();
    f.anchor += w * (a + b + c) / 3.0;
    area += w;
  }
  const Eigen::Matrix3Xd v = GroupVertices(mesh, group);
  if (!(area > 0) || v.cols() < 3)
    throw FitFailure(kInputError, "check '" + check + "': face group '" + mesh.GroupName(group) +
                                      "' of the nominal has no area");
  f.anchor /= area;
  const double tolerance = 1e-6 * std::max(ComputeBounds(mesh.vertices).diagonal(), 1e-300);
  f.plane = FitPlane(v).shape;
  f.plane.normal.normalize();
  if (SignedDistances(f.plane, v).cwiseAbs().maxCoeff() <= tolerance) return f;
  f.is_plane = false;
  if (v.cols() >= 6) {
    try {
      f.cylinder = FitCylinder(v).shape;
      f.cylinder.axis_direction.normalize();
      if (SignedDistances(f.cylinder, v).cwiseAbs().maxCoeff() <= tolerance) return f;
    } catch (const std::exception&) {
    }
  }
  throw FitFailure(kInputError, "check '" + check + "': face group '" + mesh.GroupName(group) +
                                    "' of the nominal is neither a plane nor a cylinder (a distance is "
                                    "measured between planes and cylinders' axes)");
}

Eigen::Vector3d ReferencePoint(const Feature& f) {
  if (f.is_plane) return f.anchor - f.plane.normal * f.plane.normal.dot(f.anchor - f.plane.point);
  const Eigen::Vector3d a = f.cylinder.axis_direction.normalized();
  return f.cylinder.axis_point + a * a.dot(f.anchor - f.cylinder.axis_point);
}

// docs/metrology.md eq. 17a: from a plane, the other feature's reference point's distance along its normal;
// between two axes, the distance of the second's reference point from the first axis.
double FeatureDistance(const Feature& a, const Feature& b) {
  if (a.is_plane) return std::abs(a.plane.normal.normalized().dot(ReferencePoint(b) - a.plane.point));
  if (b.is_plane) return std::abs(b.plane.normal.normalized().dot(ReferencePoint(a) - b.plane.point));
  const Eigen::Vector3d d = a.cylinder.axis_direction.normalized(),
                        v = ReferencePoint(b) - a.cylinder.axis_point;
  return (v - d * d.dot(v)).norm();
}

// The feature fitted to scanned points: the least-squares plane, or the cylinder refined from the nominal's.
Feature FitFeature(const Feature& nominal, const Eigen::Matrix3Xd& points) {
  Feature f = nominal;
  PrimitiveFitOptions quiet;
  quiet.record_history = false;
  if (f.is_plane) {
    f.plane = FitPlane(points, quiet).shape;
    f.plane.normal.normalize();
  } else {
    f.cylinder = RefineCylinder(points, nominal.cylinder, quiet).shape;
  }
  return f;
}

Eigen::MatrixXd FeatureCovariance(const Feature& f, const Eigen::Matrix3Xd& points) {
  return f.is_plane ? LocalParameterCovariance(f.plane, points)
                    : LocalParameterCovariance(f.cylinder, points);
}

Feature IncrementFeature(const Feature& f, const Eigen::VectorXd& delta) {
  Feature out = f;
  if (f.is_plane)
    out.plane = ApplyIncrement(f.plane, delta);
  else
    out.cylinder = ApplyIncrement(f.cylinder, delta);
  return out;
}

struct Evaluated {
  double value = NaN();
  double nominal = 0.0;
  double u_linear = NaN();
  nlohmann::json details = nlohmann::json::object();
  // For Monte Carlo trials: the shape to refine from.
  std::optional<Cylinder> cylinder;
  std::optional<Plane> plane;
};

// One characteristic from the inspected points; with `linear`, also its standard uncertainty by the law of
// propagation. `sigma`: the points' noise; `u_pose`: each point's deviation uncertainty from its view's pose.
Evaluated Evaluate(const CheckSpec& c, int group, int to_group, const TriangleMesh& mesh,
                   const NominalInspection& r, double sigma, const Eigen::VectorXd& u_pose, bool linear,
                   const Evaluated* start) {
  const GroupPoints g = PointsOfGroup(r, group);
  Evaluated e;
  if (g.points.cols() < 10)
    throw FitFailure(kFitError, "check '" + c.name + "': only " + std::to_string(g.points.cols()) +
                                    " scanned points lie on face group '" + c.group + "'");
  if (c.type == "distance") {
    // The features' kinds come from the nominal: a group that is neither a plane nor a cylinder is refused
    // before its points are counted.
    const Feature nominal_a = NominalFeature(mesh, group, c.name),
                  nominal_b = NominalFeature(mesh, to_group, c.name);
    const GroupPoints h = PointsOfGroup(r, to_group);
    if (h.points.cols() < 10)
      throw FitFailure(kFitError, "check '" + c.name + "': only " + std::to_string(h.points.cols()) +
                                      " scanned points lie on face group '" + c.to + "'");
    const Feature a = FitFeature(nominal_a, g.points), b = FitFeature(nominal_b, h.points);
    e.nominal = c.nominal ? *c.nominal : FeatureDistance(nominal_a, nominal_b);
    e.value = FeatureDistance(a, b);
    if (linear) {
      // The two fits use disjoint points: their parameters' covariance is block diagonal (eq. 18).
      const Eigen::MatrixXd va = FeatureCovariance(a, g.points), vb = FeatureCovariance(b, h.points);
      if (va.size() > 0 && vb.size() > 0) {
        const Eigen::Index na = va.rows(), nb = vb.rows();
        Eigen::MatrixXd v = Eigen::MatrixXd::Zero(na + nb, na + nb);
        v.topLeftCorner(na, na) = va;
        v.bottomRightCorner(nb, nb) = vb;
        e.u_linear = PropagateLinear(
                         [&](const Eigen::VectorXd& delta) {
                           return FeatureDistance(IncrementFeature(a, delta.head(na)),
                                                  IncrementFeature(b, delta.tail(nb)));
                         },
                         Eigen::VectorXd::Zero(na + nb), v)
                         .standard_uncertainty;
      }
    }
    auto kind = [](const Feature& f) { return f.is_plane ? "plane" : "axis"; };
    e.details = {{"points", g.points.cols()},
                 {"to_points", h.points.cols()},
                 {"features", {kind(a), kind(b)}},
                 {"reference_points", {ToJson(ReferencePoint(a)), ToJson(ReferencePoint(b))}},
                 {"nominal_from_mesh", FeatureDistance(nominal_a, nominal_b)}};
  } else if (c.type == "profile") {
    // ISO 1101 profile of a surface (symmetric zone about the nominal): the zone width 2 max |d| that holds
    // every point.
    Eigen::Index worst = 0;
    double largest = -1;
    for (std::size_t k = 0; k < g.index.size(); ++k) {
      const double d = std::abs(r.deviations[g.index[k]]);
      if (d > largest) {
        largest = d;
        worst = g.index[k];
      }
    }
    e.value = 2 * largest;
    e.details = {{"points", g.points.cols()},
                 {"worst_point", ToJson(Eigen::Vector3d(r.points.col(worst)))},
                 {"worst_deviation", r.deviations[worst]}};
    if (linear) {
      const double up = u_pose.size() > worst && std::isfinite(u_pose[worst]) ? u_pose[worst] : 0.0;
      e.u_linear = 2 * std::sqrt(sigma * sigma + up * up);  // docs/metrology.md eq. 20
    }
  } else if (c.type == "flatness") {
    Plane start_plane = start && start->plane ? *start->plane : FitPlane(g.points).shape;
    const ChebyshevFit<Plane> zone = MinimumZoneFit(g.points, start_plane);
    e.value = zone.zone_width;
    e.plane = zone.shape;
    e.details = {
        {"points", g.points.cols()}, {"contacts", zone.contacts.size()}, {"converged", zone.converged}};
    if (linear) {
      // Sensitivities of the zone width to each contacting point's coordinates by central differences of the
      // re-solved minimum zone (JCGM 100:2008, 5.1.3 note 2); the other points do not move it to first order.
      const double h = 1e-6 * std::max(ComputeBounds(g.points).diagonal(), 1e-300);
      double sum = 0;
      for (const ZoneContact& contact : zone.contacts) {
        for (int axis = 0; axis < 3; ++axis) {
          Eigen::Matrix3Xd plus = g.points, minus = g.points;
          plus(axis, contact.index) += h;
          minus(axis, contact.index) -= h;
          const double dw =
              (MinimumZoneFit(plus, zone.shape).zone_width - MinimumZoneFit(minus, zone.shape).zone_width) /
              (2 * h);
          sum += dw * dw;
        }
      }
      e.u_linear = sigma * std::sqrt(sum);  // docs/metrology.md eq. 19
    }
  } else {  // position, diameter: the bore's least-squares cylinder
    PrimitiveFitOptions quiet;
    quiet.record_history = false;
    const Cylinder fit = start && start->cylinder ? RefineCylinder(g.points, *start->cylinder, quiet).shape
                                                  : FitCylinder(g.points, quiet).shape;
    e.cylinder = fit;
    const Cylinder nominal = NominalCylinder(mesh, group, c.name);
    if (c.type == "diameter") {
      e.nominal = c.nominal ? *c.nominal : 2 * nominal.radius;
      MeasurandContext context;
      e.value = 2 * fit.radius;
      if (linear) e.u_linear = PropagateMeasurands(fit, g.points, context)[0].standard_uncertainty;
      e.details = {{"points", g.points.cols()},
                   {"axis_point", ToJson(fit.axis_point)},
                   {"axis_direction", ToJson(fit.axis_direction)}};
    } else {
      const Eigen::Vector3d a0 = nominal.axis_direction.normalized();
      double lo = std::numeric_limits<double>::infinity(), hi = -lo;
      for (Eigen::Index i = 0; i < g.points.cols(); ++i) {
        const double t = a0.dot(g.points.col(i) - nominal.axis_point);
        lo = std::min(lo, t);
        hi = std::max(hi, t);
      }
      e.value = AxisPosition(fit, nominal, lo, hi);
      if (linear) {
        const Eigen::MatrixXd v = LocalParameterCovariance(fit, g.points);
        if (v.size() > 0)
          e.u_linear = PropagateLinear(
                           [&](const Eigen::VectorXd& delta) {
                             return AxisPosition(ApplyIncrement(fit, delta), nominal, lo, hi);
                           },
                           Eigen::VectorXd::Zero(v.rows()), v)
                           .standard_uncertainty;
      }
      e.details = {{"points", g.points.cols()},
                   {"nominal_axis_point", ToJson(nominal.axis_point)},
                   {"nominal_axis_direction", ToJson(a0)},
                   {"actual_axis_point", ToJson(fit.axis_point)},
                   {"actual_axis_direction", ToJson(fit.axis_direction)},
                   {"length", hi - lo}};
    }
  }
  return e;
}

Specification SpecOf(const CheckSpec& c, double nominal) {
  Specification s;
  if (c.type == "diameter" || c.type == "distance") {
    s.lower = nominal + c.lower;
    s.upper = nominal + c.upper;
  } else {
    s.upper = c.tolerance;
  }
  return s;
}

std::string UtcNow() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buffer[32];
  std::strftime(buffer, sizeof buffer, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buffer;
}

bool EndsWith(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// The deviations as CSV: view, x, y, z (nominal frame), deviation, group.
std::string DeviationsCsv(const NominalInspection& r, const TriangleMesh& mesh) {
  std::ostringstream out;
  out.precision(10);
  out << "view,x,y,z,deviation,group\n";
  for (Eigen::Index i = 0; i < r.points.cols(); ++i)
    out << r.view_of_point[static_cast<std::size_t>(i)] << "," << r.points(0, i) << "," << r.points(1, i)
        << "," << r.points(2, i) << "," << r.deviations[i] << ","
        << mesh.GroupName(r.group[static_cast<std::size_t>(i)]) << "\n";
  return out.str();
}

}  // namespace

InspectOutcome ComputeInspection(const InspectOptions& o) {
  UncertaintyMethod method;
  try {
    method = UncertaintyMethod::FromString(o.uncertainty);
    method.seed = o.seed;
  } catch (const std::invalid_argument& e) {
    throw FitFailure(kUsage, e.what());
  }
  NominalInspectionOptions options;
  try {
    options.registration.error_term = ErrorTermFromString(o.method);
  } catch (const std::invalid_argument& e) {
    throw FitFailure(kUsage, std::string("--method: ") + e.what());
  }
  if (options.registration.error_term != ErrorTerm::kSdm &&
      options.registration.error_term != ErrorTerm::kTdm &&
      options.registration.error_term != ErrorTerm::kPdm)
    throw FitFailure(kUsage, "--method: registration to a nominal takes sdm, tdm or pdm");
  options.per_view = o.per_view;

  InspectOutcome outcome;
  ScanSet views;
  TriangleMesh mesh;
  MeshFormat mesh_format{};
  ChecksFile checks;
  try {
    views = ReadViews(o.input);
    if (views.scans.empty()) throw FormatError(o.input, "", "no views");
    const std::string units = !o.units.empty() ? o.units : views.scans[0].units;
    mesh = ReadMesh(o.nominal, units, &mesh_format);
    if (!o.checks.empty()) checks = ParseChecksFile(formats::ReadFileBytes(o.checks), o.checks);
  } catch (const FormatError& e) {
    throw FitFailure(kInputError, e.what());
  }
  const std::string units = views.scans[0].units;
  if (mesh.units != "unknown" && units != "unknown" && mesh.units != units)
    throw FitFailure(kInputError, "the nominal " + o.nominal + " is in " + mesh.units + " but the views " +
                                      o.input + " are in " + units +
                                      " (give --units to override the nominal's)");
  const std::vector<std::string> datum_names = !o.datums.empty() ? o.datums : checks.datums;
  for (const std::string& name : datum_names) {
    const int g = mesh.FindGroup(name);
    if (g < 0) {
      std::string known;
      for (int k = 0; k < mesh.group_count(); ++k) known += (k ? ", " : "") + mesh.GroupName(k);
      throw FitFailure(kUsage,
                       "datum '" + name + "' is not a face group of " + o.nominal + " (" + known + ")");
    }
    options.datum_groups.push_back(g);
  }
  std::vector<int> check_groups, to_groups;
  for (const CheckSpec& c : checks.checks) {
    auto find = [&](const std::string& name) {
      const int g = mesh.FindGroup(name);
      if (g < 0)
        throw FitFailure(kInputError, "check '" + c.name + "' names face group '" + name + "', which " +
                                          o.nominal + " does not have");
      return g;
    };
    check_groups.push_back(find(c.group));
    to_groups.push_back(c.to.empty() ? -1 : find(c.to));
  }

  const TriangleMeshModel nominal(mesh);
  std::vector<Eigen::Matrix3Xd> scans;
  std::vector<RigidMotion> initial;
  for (const Scan& s : views.scans) {
    scans.push_back(s.points);
    initial.push_back(s.world_T_scan);
  }
  const auto start = std::chrono::steady_clock::now();
  NominalInspection r;
  try {
    r = InspectAgainstNominal(nominal, scans, initial, options);
  } catch (const std::invalid_argument& e) {
    throw FitFailure(kFitError, std::string("registration to the nominal failed: ") + e.what());
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const NoiseEstimate noise = EstimateNoiseWithDof(views);
  const double sigma = std::isfinite(noise.sigma) && noise.sigma > 0 ? noise.sigma : NaN();
  if (!std::isfinite(sigma) && method.kind == UncertaintyMethod::Kind::kMonteCarlo && !checks.checks.empty())
    throw FitFailure(kFitError, "--uncertainty " + method.ToString() +
                                    ": the views' noise could not be estimated (too few neighbourhoods)");
  const Eigen::VectorXd u_pose = PoseDeviationUncertainty(r);

  // The characteristics, measured once, with linear uncertainties when asked.
  const bool linear = method.kind == UncertaintyMethod::Kind::kLinear;
  std::vector<Evaluated> measured;
  for (std::size_t k = 0; k < checks.checks.size(); ++k) {
    try {
      measured.push_back(
          Evaluate(checks.checks[k], check_groups[k], to_groups[k], mesh, r, sigma, u_pose, linear, nullptr));
    } catch (const FitError& e) {
      throw FitFailure(kFitError, "check '" + checks.checks[k].name + "': " + e.what());
    }
  }
  // Monte Carlo (JCGM 101): each trial perturbs every point along the nominal's normal at its foot by the
  // views' noise (in its view's coordinates), registers again from the final poses and re-measures.
  std::vector<MonteCarloSummary> mc;
  if (method.kind == UncertaintyMethod::Kind::kMonteCarlo && !checks.checks.empty()) {
    mc = RunMonteCarlo(
        method.trials, method.seed, [&](int, std::mt19937_64& random) -> std::optional<Eigen::VectorXd> {
          std::normal_distribution<double> normal(0.0, sigma);
          std::vector<Eigen::Matrix3Xd> perturbed = scans;
          Eigen::Index at = 0;
          for (std::size_t v = 0; v < scans.size(); ++v) {
            const Eigen::Matrix3d rt = r.nominal_T_scan[v].rotation().transpose();
            for (Eigen::Index i = 0; i < scans[v].cols(); ++i, ++at)
              perturbed[v].col(i) += normal(random) * (rt * r.normals.col(at));
          }
          try {
            const NominalInspection trial =
                InspectAgainstNominal(nominal, perturbed, r.nominal_T_scan, options);
            Eigen::VectorXd y(static_cast<Eigen::Index>(checks.checks.size()));
            for (std::size_t k = 0; k < checks.checks.size(); ++k)
              y[static_cast<Eigen::Index>(k)] = Evaluate(checks.checks[k], check_groups[k], to_groups[k],
                                                         mesh, trial, sigma, u_pose, false, &measured[k])
                                                    .value;
            return y;
          } catch (const std::exception&) {
            return std::nullopt;
          }
        });
  }

  nlohmann::json& j = outcome.document;
  j["schema"] = "scan2model.inspection/1";
  j["part"] = checks.part;
  j["units"] = units;
  nlohmann::json groups = nlohmann::json::array();
  for (int g = 0; g < mesh.group_count(); ++g) groups.push_back(mesh.GroupName(g));
  j["nominal"] = {{"file", o.nominal},
                  {"format", ToString(mesh_format)},
                  {"vertices", mesh.vertices.cols()},
                  {"triangles", mesh.triangle_count()},
                  {"groups", groups},
                  {"units", mesh.units}};
  j["input"] = {{"file", o.input}, {"views", views.scans.size()}, {"points", views.TotalPoints()}};
  nlohmann::json view_json = nlohmann::json::array();
  for (std::size_t k = 0; k < views.scans.size(); ++k) {
    const RigidMotion correction = r.nominal_T_scan[k] * initial[k].inverse();
    const ModelRegistrationResult& reg = r.registration[k];
    view_json.push_back({{"points", views.scans[k].size()},
                         {"rms", reg.residuals.rms},
                         {"iterations", reg.iterations},
                         {"stop_reason", ToString(reg.stop_reason)},
                         {"correction_rotation_deg", correction.angle() * kRadToDeg},
                         {"correction_translation", correction.translation().norm()},
                         {"world_T_scan", ToJson(r.nominal_T_scan[k].matrix())}});
  }
  nlohmann::json datums = nlohmann::json::array();
  for (const std::string& d : datum_names) datums.push_back(d);
  // The scanned points on each datum face: a datum the scan barely sees holds the registration weakly in
  // the directions only it constrains (its points' noise then moves the whole part), which the result
  // must say. 10 points: the fewest a check measures a face group by (Evaluate).
  nlohmann::json datum_points = nlohmann::json::object();
  for (std::size_t k = 0; k < datum_names.size(); ++k) {
    const int g = options.datum_groups[k];
    const auto count = std::count(r.group.begin(), r.group.end(), g);
    datum_points[datum_names[k]] = count;
    if (count < 10)
      outcome.notes.push_back("datum '" + datum_names[k] + "' has only " + std::to_string(count) +
                              " scanned points: the registration rests on the other datums in the directions "
                              "it alone constrains; scan it or choose another datum");
  }
  j["registration"] = {{"method", ToString(options.registration.error_term)},
                       {"per_view", options.per_view},
                       {"datums", datums},
                       {"datum_points", datum_points},
                       {"points_used", r.registration_points},
                       {"common_correction_rotation_deg", r.common_correction.angle() * kRadToDeg},
                       {"common_correction_translation", r.common_correction.translation().norm()},
                       {"seconds", seconds},
                       {"views", view_json}};
  j["noise"] = {{"sigma", NumberOrNull(sigma)},
                {"method", "local quadrics (fitting/noise_estimate.h)"},
                {"neighbourhoods", noise.neighbourhoods}};
  j["deviations"] = DeviationsJson(r.points, r.deviations);
  nlohmann::json regions = nlohmann::json::array();
  for (const RegionDeviation& g : r.regions)
    regions.push_back({{"name", g.name},
                       {"nominal_area", g.nominal_area},
                       {"count", g.count},
                       {"mean", NumberOrNull(g.mean)},
                       {"standard_deviation", NumberOrNull(g.standard_deviation)},
                       {"rms", NumberOrNull(g.rms)},
                       {"min", NumberOrNull(g.min)},
                       {"max", NumberOrNull(g.max)}});
  j["regions"] = regions;
  j["uncertainty"] = {
      {"method", method.ToString()},
      {"coverage_probability", 0.95},
      {"coverage_factor",
       method.kind == UncertaintyMethod::Kind::kLinear ? nlohmann::json(2.0) : nlohmann::json(nullptr)},
      {"decision_rule", "ISO 14253-1:2017 (conformance zone narrowed, non-conformance zone widened by U)"}};
  if (method.kind == UncertaintyMethod::Kind::kMonteCarlo) j["uncertainty"]["trials"] = method.trials;
  nlohmann::json characteristics = nlohmann::json::array();
  for (std::size_t k = 0; k < checks.checks.size(); ++k) {
    const CheckSpec& c = checks.checks[k];
    const Evaluated& e = measured[k];
    ExpandedUncertainty expanded;
    if (method.kind == UncertaintyMethod::Kind::kLinear)
      expanded = ExpandLinear(e.u_linear);
    else if (method.kind == UncertaintyMethod::Kind::kMonteCarlo)
      expanded = ExpandMonteCarlo(mc[k]);
    const Specification spec = SpecOf(c, e.nominal);
    const ConformityDecision decision = DecideConformity(e.value, expanded.expanded, spec);
    nlohmann::json ch = {
        {"name", c.name},
        {"type", c.type},
        {"group", c.group},
        {"nominal", e.nominal},
        {"actual", e.value},
        {"deviation", e.value - e.nominal},
        {"lower_limit", spec.lower ? nlohmann::json(*spec.lower) : nlohmann::json(nullptr)},
        {"upper_limit", spec.upper ? nlohmann::json(*spec.upper) : nlohmann::json(nullptr)},
        {"tolerance", c.type == "diameter" || c.type == "distance" ? c.upper - c.lower : c.tolerance},
        {"standard_uncertainty", NumberOrNull(expanded.standard_uncertainty)},
        {"expanded_uncertainty", NumberOrNull(expanded.expanded)},
        {"coverage_factor", NumberOrNull(expanded.coverage_factor)},
        {"uncertainty_method", method.ToString()},
        {"verdict", PlainVerdict(e.value, spec)},
        {"decision", ToString(decision)},
        {"unit", units},
        {"details", e.details}};
    if (method.kind == UncertaintyMethod::Kind::kMonteCarlo)
      ch["monte_carlo"] = {{"trials", mc[k].trials},
                           {"failed_trials", mc[k].failed_trials},
                           {"mean", NumberOrNull(mc[k].mean)},
                           {"interval_low", NumberOrNull(mc[k].interval_low)},
                           {"interval_high", NumberOrNull(mc[k].interval_high)}};
    characteristics.push_back(ch);
  }
  j["characteristics"] = characteristics;

  // Traceability (docs/metrology.md section 9).
  nlohmann::json files = nlohmann::json::array();
  auto hash = [&](const std::string& role, const std::string& path) {
    try {
      files.push_back({{"role", role}, {"path", path}, {"sha256", Sha256OfFile(path)}});
    } catch (const FormatError& e) {
      throw FitFailure(kInputError, e.what());
    }
  };
  hash("nominal", o.nominal);
  hash("scan", o.input);
  if (!o.checks.empty()) hash("checks", o.checks);
  nlohmann::json scanner = nullptr, calibration = nullptr;
  if (EndsWith(o.input, ".s2mrec")) {
    try {
      const RecordingSummary summary = RecordingReader::Open(o.input).Summary();
      scanner = nlohmann::json::parse(summary.device.empty() ? "null" : summary.device);
      calibration = nlohmann::json::parse(summary.calibration.empty() ? "null" : summary.calibration);
    } catch (const std::exception& e) {
      outcome.notes.push_back(std::string("the recording's device description could not be read: ") +
                              e.what());
    }
  } else if (!views.scans[0].metadata.device.empty()) {
    scanner = {{"name", views.scans[0].metadata.device}};
  }
  j["traceability"] = {
      {"software", "scan2model"},
      {"version", o.software_version},
      {"method", "registration of the views to the nominal mesh (" +
                     std::string(ToString(options.registration.error_term)) +
                     (options.per_view ? ", all views then each view" : ", all views as one") +
                     (datum_names.empty() ? "" : ", on the datum faces") +
                     "); signed point-to-triangle deviations; " + "uncertainty " + method.ToString() +
                     " (JCGM 100:2008 / JCGM 101:2008); decisions ISO 14253-1:2017"},
      {"date", UtcNow()},
      {"operator", o.operator_name.empty() ? nlohmann::json(nullptr) : nlohmann::json(o.operator_name)},
      {"files", files},
      {"scanner", scanner},
      {"calibration", calibration}};

  std::ostringstream text;
  text << "scan2model inspect: " << views.TotalPoints() << " points in " << views.scans.size() << " views of "
       << o.input << " against " << o.nominal << " (" << mesh.triangle_count() << " triangles, units "
       << units << ")\n\n"
       << "  registration      " << ToString(options.registration.error_term)
       << (datum_names.empty() ? ", every face" : ", datums") << ", common correction "
       << Format(r.common_correction.angle() * kRadToDeg, 3) << " deg / "
       << Format(r.common_correction.translation().norm(), 3) << ", " << Format(seconds, 3) << " s\n"
       << "  noise (views)     " << Format(sigma, 3) << "\n\n"
       << "  region                 points        mean          sd         min         max\n";
  for (const RegionDeviation& g : r.regions)
    text << "  " << std::left << std::setw(18) << g.name << std::right << std::setw(11) << g.count
         << std::setw(12) << Format(g.mean, 3) << std::setw(12) << Format(g.standard_deviation, 3)
         << std::setw(12) << Format(g.min, 3) << std::setw(12) << Format(g.max, 3) << "\n";
  if (!checks.checks.empty()) {
    text << "\n  characteristic               nominal      actual   deviation   tolerance           U   "
            "decision\n";
    for (const auto& ch : characteristics) {
      text << "  " << std::left << std::setw(24) << ch["name"].get<std::string>() << std::right
           << std::setw(12) << Format(ch["nominal"].get<double>(), 5) << std::setw(12)
           << Format(ch["actual"].get<double>(), 5) << std::setw(12)
           << Format(ch["deviation"].get<double>(), 4) << std::setw(12)
           << Format(ch["tolerance"].get<double>(), 4) << std::setw(12)
           << (ch["expanded_uncertainty"].is_null() ? std::string("-")
                                                    : Format(ch["expanded_uncertainty"].get<double>(), 3))
           << "   " << ch["decision"].get<std::string>() << " (" << ch["verdict"].get<std::string>() << ")\n";
    }
    text << "\n  U: expanded uncertainty, "
         << (linear ? "k = 2 (law of propagation)" : "95 % Monte Carlo interval")
         << "; decisions per ISO 14253-1:2017\n";
  }
  outcome.text = text.str();
  outcome.html = InspectionHtml(j);
  if (!o.output.empty()) {
    WriteTextAtomically(o.output + ".json", j.dump(2) + "\n");
    WriteTextAtomically(o.output + ".html", outcome.html);
    WriteTextAtomically(o.output + "_deviations.csv", DeviationsCsv(r, mesh));
  }
  return outcome;
}

std::string InspectionHtml(const nlohmann::json& d) {
  using svg::Escape;
  auto num = [](const nlohmann::json& v, int digits = 4) {
    if (v.is_null()) return std::string("&ndash;");
    std::ostringstream s;
    s << std::setprecision(digits) << v.get<double>();
    return s.str();
  };
  std::ostringstream h;
  h << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>Inspection report</title>\n"
    << "<style>body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}"
       "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:3px "
       "8px;text-align:right}"
       "th{background:#eee}td.l,th.l{text-align:left}.conforms{background:#d8f0d8}"
       ".not-conform{background:#f6d0d0}.undecided{background:#fbeebd}.note{color:#555;font-size:90%}</style>"
       "</head><body>\n";
  h << "<h1>Inspection report"
    << (d["part"].get<std::string>().empty() ? "" : ": " + Escape(d["part"].get<std::string>())) << "</h1>\n";
  const std::string units = d["units"].get<std::string>();
  // Characteristics.
  h << "<h2>Characteristics</h2>\n";
  if (d["characteristics"].empty()) {
    h << "<p class=\"note\">No checks file: deviations only.</p>\n";
  } else {
    h << "<table><tr><th class=\"l\">characteristic</th><th class=\"l\">type</th><th class=\"l\">face</th>"
         "<th>nominal</th><th>actual</th><th>deviation</th><th>lower limit</th><th>upper limit</th><th>u</th>"
         "<th>U</th><th>k</th><th class=\"l\">decision (ISO 14253-1)</th><th class=\"l\">plain "
         "verdict</th></tr>\n";
    for (const auto& c : d["characteristics"]) {
      const std::string decision = c["decision"];
      const char* cls = decision == "conforms"           ? "conforms"
                        : decision == "does not conform" ? "not-conform"
                                                         : "undecided";
      h << "<tr><td class=\"l\">" << Escape(c["name"]) << "</td><td class=\"l\">" << Escape(c["type"])
        << "</td><td class=\"l\">" << Escape(c["group"]) << "</td><td>" << num(c["nominal"], 6) << "</td><td>"
        << num(c["actual"], 6) << "</td><td>" << num(c["deviation"]) << "</td><td>"
        << num(c["lower_limit"], 6) << "</td><td>" << num(c["upper_limit"], 6) << "</td><td>"
        << num(c["standard_uncertainty"], 3) << "</td><td>" << num(c["expanded_uncertainty"], 3)
        << "</td><td>" << num(c["coverage_factor"], 3) << "</td><td class=\"l " << cls << "\">"
        << Escape(decision) << "</td><td class=\"l\">" << Escape(c["verdict"]) << "</td></tr>\n";
    }
    h << "</table>\n<p class=\"note\">Values in " << Escape(units)
      << ". Uncertainty: " << Escape(d["uncertainty"]["method"]) << "; U = k u for about 95 % coverage. "
      << Escape(d["uncertainty"]["decision_rule"]) << ".</p>\n";
  }
  // Regions.
  h << "<h2>Deviation by face group</h2>\n<table><tr><th class=\"l\">face group</th><th>nominal area</th>"
       "<th>points</th><th>mean</th><th>sd</th><th>rms</th><th>min</th><th>max</th></tr>\n";
  for (const auto& r : d["regions"])
    h << "<tr><td class=\"l\">" << Escape(r["name"]) << "</td><td>" << num(r["nominal_area"], 5)
      << "</td><td>" << r["count"].get<long long>() << "</td><td>" << num(r["mean"], 3) << "</td><td>"
      << num(r["standard_deviation"], 3) << "</td><td>" << num(r["rms"], 3) << "</td><td>" << num(r["min"], 3)
      << "</td><td>" << num(r["max"], 3) << "</td></tr>\n";
  h << "</table>\n";
  // Colour map: the sample in three orthographic views.
  const nlohmann::json& sample = d["deviations"]["sample"]["points"];
  double range = 0;
  std::vector<double> values;
  for (const auto& p : sample) values.push_back(p[3].get<double>());
  if (!values.empty()) {
    std::vector<double> sorted;
    for (double v : values) sorted.push_back(std::abs(v));
    std::sort(sorted.begin(), sorted.end());
    range = std::max(sorted[static_cast<std::size_t>(0.99 * static_cast<double>(sorted.size() - 1))], 1e-12);
  }
  h << "<h2>Deviation map</h2>\n<p class=\"note\">Every "
    << d["deviations"]["sample"]["stride"].get<long long>()
    << "-th point coloured by its signed deviation from the nominal (red outside, blue inside; the scale "
       "saturates at the 99th percentile of |deviation|, "
    << svg::Num(range) << " " << Escape(units) << ").</p>\n";
  const char* names[3] = {"top (x, y)", "front (x, z)", "side (y, z)"};
  const int axes[3][2] = {{0, 1}, {0, 2}, {1, 2}};
  for (int v = 0; v < 3; ++v) {
    std::vector<Eigen::Vector2d> projected;
    for (const auto& p : sample)
      projected.emplace_back(p[axes[v][0]].get<double>(), p[axes[v][1]].get<double>());
    h << "<figure>"
      << svg::ColouredScatter(std::string("View from the ") + names[v], projected, values, range, units,
                              {540, 400})
      << "</figure>\n";
  }
  const nlohmann::json& hist = d["deviations"]["histogram"];
  h << "<figure>"
    << svg::Histogram("Signed deviations", "deviation (" + units + ")",
                      hist["edges"].get<std::vector<double>>(), hist["counts"].get<std::vector<double>>())
    << "</figure>\n";
  // Registration.
  h << "<h2>Registration</h2>\n<p>" << Escape(d["registration"]["method"]) << ", "
    << (d["registration"]["per_view"].get<bool>() ? "all views then each view"
                                                  : "all views as one rigid body");
  if (!d["registration"]["datums"].empty()) {
    h << ", on the datum faces";
    for (const auto& x : d["registration"]["datums"]) h << " " << Escape(x);
  }
  h << ". Noise of the views (local quadrics): " << num(d["noise"]["sigma"], 3) << " " << Escape(units)
    << ".</p>\n"
    << "<table><tr><th>view</th><th>points</th><th>rms</th><th>iterations</th><th>pose correction (deg)</th>"
       "<th>pose correction ("
    << Escape(units) << ")</th></tr>\n";
  int k = 0;
  for (const auto& v : d["registration"]["views"])
    h << "<tr><td>" << k++ << "</td><td>" << v["points"].get<long long>() << "</td><td>" << num(v["rms"], 3)
      << "</td><td>" << v["iterations"].get<int>() << "</td><td>" << num(v["correction_rotation_deg"], 3)
      << "</td><td>" << num(v["correction_translation"], 3) << "</td></tr>\n";
  h << "</table>\n";
  // Traceability.
  const nlohmann::json& t = d["traceability"];
  h << "<h2>Traceability</h2>\n<table>"
    << "<tr><th class=\"l\">software</th><td class=\"l\">" << Escape(t["software"]) << " "
    << Escape(t["version"]) << "</td></tr><tr><th class=\"l\">method</th><td class=\"l\">"
    << Escape(t["method"]) << "</td></tr><tr><th class=\"l\">date (UTC)</th><td class=\"l\">"
    << Escape(t["date"]) << "</td></tr><tr><th class=\"l\">operator</th><td class=\"l\">"
    << (t["operator"].is_null() ? std::string("&ndash;") : Escape(t["operator"]))
    << "</td></tr><tr><th class=\"l\">scanner</th><td class=\"l\">"
    << (t["scanner"].is_null() ? std::string("&ndash;") : Escape(t["scanner"].dump()))
    << "</td></tr><tr><th class=\"l\">calibration</th><td class=\"l\">"
    << (t["calibration"].is_null() ? std::string("&ndash;") : Escape(t["calibration"].dump()))
    << "</td></tr>\n";
  for (const auto& f : t["files"])
    h << "<tr><th class=\"l\">" << Escape(f["role"]) << "</th><td class=\"l\">" << Escape(f["path"])
      << "<br><code>SHA-256 " << Escape(f["sha256"]) << "</code></td></tr>\n";
  h << "</table>\n<p class=\"note\">The same content as JSON: the report's .json file (schema "
       "scan2model.inspection/1).</p>\n</body></html>\n";
  return h.str();
}

}  // namespace s2m::pipeline
