// ComputeFit: the dispatch of `scan2model fit` and `scan2model batch` to the fits of every model family, and
// the primitive fits (plane, sphere, cylinder, cone, line, circle, torus) themselves with their form errors
// (least-squares zone, and the minimum-zone, inscribed or circumscribed fit that --criterion asks for).
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <optional>
#include <set>
#include <sstream>

#include "acquisition/format_error.h"
#include "acquisition/nist_reference.h"
#include "acquisition/point_cloud_io.h"
#include "acquisition/recording.h"
#include "fitting/measurement_uncertainty.h"
#include "fitting/minimum_zone.h"
#include "fitting/noise_estimate.h"
#include "fitting/primitive_compare.h"
#include "fitting/primitive_fit.h"
#include "fitting/primitive_measurands.h"
#include "pipeline/detect.h"
#include "pipeline/domain_measures.h"
#include "pipeline/exit_code.h"
#include "pipeline/fit_option_table.h"
#include "pipeline/fit_options.h"
#include "pipeline/output.h"
#include "pipeline/views.h"

namespace s2m::pipeline {
namespace {

// One named result value with its uncertainty, for both text and JSON output.
struct Row {
  std::string name;
  nlohmann::json value;
  std::string text;
};

std::vector<Row> Parameters(const Plane& s) {
  return {{"point", ToJson(s.point), Format(s.point)}, {"normal", ToJson(s.normal), Format(s.normal)}};
}
std::vector<Row> Parameters(const Sphere& s) {
  return {{"center", ToJson(s.center), Format(s.center)},
          {"radius", s.radius, Format(s.radius)},
          {"diameter", 2 * s.radius, Format(2 * s.radius)}};
}
std::vector<Row> Parameters(const Cylinder& s) {
  return {{"axis_point", ToJson(s.axis_point), Format(s.axis_point)},
          {"axis_direction", ToJson(s.axis_direction), Format(s.axis_direction)},
          {"radius", s.radius, Format(s.radius)},
          {"diameter", 2 * s.radius, Format(2 * s.radius)}};
}
std::vector<Row> Parameters(const Cone& s) {
  const double degrees = 180.0 / M_PI;
  return {{"axis_point", ToJson(s.axis_point), Format(s.axis_point)},
          {"axis_direction", ToJson(s.axis_direction), Format(s.axis_direction)},
          {"radius", s.radius, Format(s.radius) + "  (cross-section through the axis point)"},
          {"surface_distance", s.SurfaceDistanceFromAxisPoint(), Format(s.SurfaceDistanceFromAxisPoint())},
          {"half_angle", s.half_angle, Format(s.half_angle) + " rad"},
          {"apex_angle_deg", 2 * s.half_angle * degrees, Format(2 * s.half_angle * degrees) + " deg (full)"},
          {"apex", ToJson(s.Apex()), Format(s.Apex())}};
}

std::vector<Row> Parameters(const Line3d& s) {
  return {{"point", ToJson(s.point), Format(s.point) + "  (nearest the points' centroid)"},
          {"direction", ToJson(s.direction), Format(s.direction)}};
}
std::vector<Row> Parameters(const Circle3d& s) {
  return {{"center", ToJson(s.center), Format(s.center)},
          {"normal", ToJson(s.normal), Format(s.normal)},
          {"radius", s.radius, Format(s.radius)},
          {"diameter", 2 * s.radius, Format(2 * s.radius)}};
}
std::vector<Row> Parameters(const Torus& s) {
  return {{"center", ToJson(s.center), Format(s.center)},
          {"axis_direction", ToJson(s.axis), Format(s.axis)},
          {"major_radius", s.major_radius, Format(s.major_radius) + "  (axis to the tube's centre circle)"},
          {"minor_radius", s.minor_radius, Format(s.minor_radius) + "  (the tube's radius)"}};
}

// NIST reference files exist for the four primitives of the NIST data sets; none for lines, circles, tori.
template <class Shape>
constexpr bool kHasNistReference = std::is_same_v<Shape, Plane> || std::is_same_v<Shape, Sphere> ||
                                   std::is_same_v<Shape, Cylinder> || std::is_same_v<Shape, Cone>;

// The form error of each primitive by its ISO 1101 name (docs/metrology.md section 2).
const char* FormName(const Plane&) {
  return "flatness";
}
const char* FormName(const Sphere&) {
  return "sphericity";
}
const char* FormName(const Cylinder&) {
  return "cylindricity";
}
const char* FormName(const Cone&) {
  return "conicity";
}
const char* FormName(const Line3d&) {
  return "straightness";
}
const char* FormName(const Circle3d&) {
  return "roundness";
}
const char* FormName(const Torus&) {
  return "torus form deviation";
}

// The Chebyshev fit --criterion asks for, from the least-squares shape; nullopt for lsq. Inscribed and
// circumscribed features exist for circles, cylinders and spheres only.
template <class Shape>
std::optional<ChebyshevFit<Shape>> CriterionFit(FitCriterion criterion, const Eigen::Matrix3Xd& points,
                                                const Shape& start, const std::string& model) {
  switch (criterion) {
    case FitCriterion::kLeastSquares:
      return std::nullopt;
    case FitCriterion::kMinimumZone:
      return MinimumZoneFit(points, start);
    case FitCriterion::kInscribed:
    case FitCriterion::kCircumscribed:
      if constexpr (std::is_same_v<Shape, Circle3d> || std::is_same_v<Shape, Cylinder> ||
                    std::is_same_v<Shape, Sphere>) {
        return criterion == FitCriterion::kInscribed ? InscribedFit(points, start)
                                                     : CircumscribedFit(points, start);
      } else {
        throw FitFailure(kUsage, std::string("--criterion ") + ToString(criterion) +
                                     " applies to circle, cylinder and sphere, not " + model);
      }
  }
  return std::nullopt;
}

template <class Shape>
nlohmann::json ContactsJson(const ChebyshevFit<Shape>& z) {
  nlohmann::json contacts = nlohmann::json::array();
  for (const ZoneContact& c : z.contacts)
    contacts.push_back(
        {{"index", c.index}, {"side", c.side > 0 ? "outer" : "inner"}, {"distance", c.distance}});
  return contacts;
}

std::string ContactsText(const std::vector<ZoneContact>& contacts) {
  std::string out;
  for (std::size_t k = 0; k < contacts.size() && k < 12; ++k)
    out += (k ? ", " : "") + std::to_string(contacts[k].index) + (contacts[k].side > 0 ? "+" : "-");
  if (contacts.size() > 12) out += ", ...";
  return out;
}

Plane ReadReference(const std::string& f, const Plane&) {
  return ReadNistPlaneFit(f);
}
Sphere ReadReference(const std::string& f, const Sphere&) {
  return ReadNistSphereFit(f);
}
Cylinder ReadReference(const std::string& f, const Cylinder&) {
  return ReadNistCylinderFit(f);
}
Cone ReadReference(const std::string& f, const Cone&) {
  return ReadNistConeFit(f);
}

// The points moved onto the primitive, x - d grad d with the gradient of the signed distance d by central
// differences (step 1e-7 of the extent): where each residual sits on the model, free of the residual itself
// (the structure tests' neighbours and orders, docs/method.md section 17).
template <class Shape>
Eigen::Matrix3Xd FootPointsOf(const Shape& shape, const Eigen::Matrix3Xd& points, const Eigen::VectorXd& d,
                              double extent) {
  const double h = 1e-7 * std::max(extent, 1e-300);
  Eigen::Matrix3Xd gradient(3, points.cols());
  for (int axis = 0; axis < 3; ++axis) {
    Eigen::Matrix3Xd plus = points, minus = points;
    plus.row(axis).array() += h;
    minus.row(axis).array() -= h;
    gradient.row(axis) =
        ((SignedDistances(shape, plus) - SignedDistances(shape, minus)) / (2 * h)).transpose();
  }
  return points - gradient * d.asDiagonal();
}

// The shapes with measurands (fitting/primitive_measurands.h).
template <class Shape>
constexpr bool kHasMeasurands =
    std::is_same_v<Shape, Sphere> || std::is_same_v<Shape, Cylinder> || std::is_same_v<Shape, Cone> ||
    std::is_same_v<Shape, Circle3d> || std::is_same_v<Shape, Torus>;

// The derived quantities of a primitive fit with their uncertainties (docs/metrology.md sections 6-8): the
// shape's measurands and, with a --criterion other than lsq, its zone width (the form error). Linear: the
// measurands from the fit's covariance (eq. 13 of JCGM 100:2008), the zone from the sensitivities of the
// re-solved zone to its contacting points times the residuals' standard deviation s (docs/metrology.md eq.
// 19). Monte Carlo: refits of the feet perturbed by s (JCGM 101:2008). Expanded U with the coverage factor
// stated.
template <class Shape>
nlohmann::json MeasurandsJson(const Shape& shape, const Eigen::Matrix3Xd& points, FitCriterion criterion,
                              const ChebyshevFit<Shape>* zone, const std::string& model,
                              const UncertaintyMethod& method, const std::string& units) {
  std::vector<std::string> names;
  Eigen::VectorXd values(0);
  MeasurandContext context;
  context.station = points.rowwise().mean();
  if constexpr (kHasMeasurands<Shape>) {
    names = MeasurandNames(shape);
    values = Measurands(shape, context);
  }
  const double s = ResidualStandardDeviation(shape, points);
  std::vector<double> u(names.size(), std::nan(""));
  const bool with_zone = zone != nullptr;
  double zone_u = std::nan("");
  std::vector<MonteCarloSummary> mc;
  if (method.kind == UncertaintyMethod::Kind::kLinear) {
    if constexpr (kHasMeasurands<Shape>) {
      const std::vector<LinearPropagation> lp = PropagateMeasurands(shape, points, context);
      for (std::size_t i = 0; i < lp.size(); ++i) u[i] = lp[i].standard_uncertainty;
    }
    if (with_zone) {
      const double h = 1e-6 * std::max(ComputeBounds(points).diagonal(), 1e-300);
      double sum = 0;
      for (const ZoneContact& c : zone->contacts)
        for (int axis = 0; axis < 3; ++axis) {
          Eigen::Matrix3Xd plus = points, minus = points;
          plus(axis, c.index) += h;
          minus(axis, c.index) -= h;
          const double dw = (CriterionFit(criterion, plus, zone->shape, model)->zone_width -
                             CriterionFit(criterion, minus, zone->shape, model)->zone_width) /
                            (2 * h);
          sum += dw * dw;
        }
      zone_u = s * std::sqrt(sum);
    }
  } else if (method.kind == UncertaintyMethod::Kind::kMonteCarlo) {
    mc = MonteCarloByRefitting<Shape>(
        shape, points, s, method.trials, method.seed, [&](const Shape& refit, const Eigen::Matrix3Xd& trial) {
          Eigen::VectorXd y(static_cast<Eigen::Index>(names.size()) + (with_zone ? 1 : 0));
          if constexpr (kHasMeasurands<Shape>) y.head(values.size()) = Measurands(refit, context);
          if (with_zone) y[y.size() - 1] = CriterionFit(criterion, trial, refit, model)->zone_width;
          return y;
        });
  }
  nlohmann::json out = nlohmann::json::array();
  auto add = [&](const std::string& name, double value, double standard, std::size_t mc_index) {
    out.push_back(MeasurandJson(name, value, units, method, standard,
                                method.kind == UncertaintyMethod::Kind::kMonteCarlo && mc_index < mc.size()
                                    ? &mc[mc_index]
                                    : nullptr));
  };
  for (std::size_t i = 0; i < names.size(); ++i) add(names[i], values[static_cast<Eigen::Index>(i)], u[i], i);
  if (with_zone)
    add(std::string(FormName(shape)) + " (" + ToString(criterion) + ")", zone->zone_width, zone_u,
        names.size());
  return out;
}

template <class Shape, class FitFn>
FitOutcome ComputePrimitiveFit(const FitOptions& o, const Scan& scan, const std::string& format,
                               FitFn fit_fn) {
  PrimitiveFitOptions options;
  options.error_term = ErrorTermFromString(o.method);
  options.optimizer.max_iterations = o.max_iterations;
  options.optimizer.loss = o.loss;
  const auto start = std::chrono::steady_clock::now();
  const PrimitiveFit<Shape> fit = fit_fn(scan.points, options);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const std::vector<Row> rows = Parameters(fit.shape);
  const double extent = ComputeBounds(scan.points).diagonal();

  std::optional<PrimitiveDeviation> deviation;
  if (!o.reference.empty()) {
    if constexpr (kHasNistReference<Shape>) {
      deviation = Compare(fit.shape, ReadReference(o.reference, fit.shape));
    } else {
      throw FitFailure(
          kUsage,
          "--reference: NIST reference fits exist for plane, sphere, cylinder and cone, not " + o.model);
    }
  }
  if (!o.history.empty()) WriteTextAtomically(o.history, HistoryCsv(fit.history));

  // Adequacy (docs/method.md section 17): the RMS against the cloud's own noise, and the signed residuals'
  // structure along a Hilbert curve through the points and between nearest neighbours.
  const Eigen::VectorXd signed_distances = SignedDistances(fit.shape, scan.points);
  AdequacyEvidence evidence;
  evidence.family = ModelFamily::kPrimitive;
  evidence.model = o.model;
  evidence.fit_rms = fit.residuals.rms;
  ScanSet single;
  single.scans.push_back(scan);
  evidence.noise_estimate = EstimateNoise(single);
  evidence.residuals = signed_distances;
  evidence.points = FootPointsOf(fit.shape, scan.points, signed_distances, extent);
  evidence.weights = RobustWeightsAt(o.loss, fit.loss_scale, signed_distances);
  evidence.extent = extent;
  const Adequacy adequacy = AssessAdequacy(evidence);
  const std::optional<bool> trusted = adequacy.uncertainty_trusted();

  // Form error (docs/metrology.md section 2): the least-squares zone always, the --criterion fit on request.
  const ChebyshevFit<Shape> lsq_zone = ZoneAbout(scan.points, fit.shape);
  const FitCriterion criterion = FitCriterionFromString(o.criterion);
  const auto chebyshev_start = std::chrono::steady_clock::now();
  const std::optional<ChebyshevFit<Shape>> chebyshev =
      CriterionFit(criterion, scan.points, fit.shape, o.model);
  const double chebyshev_seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - chebyshev_start).count();
  nlohmann::json form_json = {{"name", FormName(fit.shape)},
                              {"least_squares_zone",
                               {{"width", lsq_zone.zone_width},
                                {"max_distance", lsq_zone.max_distance},
                                {"min_distance", lsq_zone.min_distance}}},
                              {"criterion", o.criterion}};
  if (chebyshev) {
    nlohmann::json c = {{"width", chebyshev->zone_width},
                        {"max_distance", chebyshev->max_distance},
                        {"min_distance", chebyshev->min_distance},
                        {"contacts", ContactsJson(*chebyshev)},
                        {"iterations", chebyshev->iterations},
                        {"converged", chebyshev->converged},
                        {"stop_reason", chebyshev->stop_reason},
                        {"optimality", chebyshev->optimality},
                        {"seconds", chebyshev_seconds}};
    for (const Row& r : Parameters(chebyshev->shape)) c["parameters"][r.name] = r.value;
    form_json[o.criterion] = c;
  }

  // Uncertainties of the derived quantities (docs/metrology.md sections 6-8): the measurands of the shape and
  // the --criterion zone, by the law of propagation or by Monte Carlo refits.
  const UncertaintyMethod uncertainty_method = UncertaintyMethod::FromString(o.uncertainty);
  const nlohmann::json measurands =
      uncertainty_method.kind == UncertaintyMethod::Kind::kNone
          ? nlohmann::json(nullptr)
          : MeasurandsJson(fit.shape, scan.points, criterion, chebyshev ? &*chebyshev : nullptr, o.model,
                           uncertainty_method, scan.units);

  FitOutcome outcome;
  {
    nlohmann::json& j = outcome.document;
    j["schema"] = "scan2model.fit/1";
    j["input"] = DescribeScan(scan, o.file, format);
    j.update(PrimitiveFitJson(o.model, options.error_term, fit, scan.units));
    j["form"] = form_json;
    j["loss"] = LossJson(o.loss, fit.loss_scale, evidence.weights);
    j["loss"]["reason"] = o.loss_reason;
    j["seconds"] = seconds;
    if (deviation) {
      j["reference"] = {{"file", o.reference},
                        {"extent", extent},
                        {"position", deviation->position},
                        {"direction_rad", deviation->direction},
                        {"size", deviation->size},
                        {"apex_angle_rad", deviation->angle}};
    }
    j["deviations"] = DeviationsJson(scan.points, signed_distances, {}, evidence.weights);
    j["adequacy"] = adequacy.ToJson();
    if (!measurands.is_null()) j["measurands"] = measurands;
    MarkUncertainties(j, trusted);
  }

  std::ostringstream text;
  text << "scan2model fit: " << o.model << " to " << scan.size() << " points of " << o.file << " (" << format
       << ", units " << scan.units << ")\n\n";
  for (const Row& r : rows) text << "  " << std::left << std::setw(18) << r.name << r.text << "\n";
  if (!fit.uncertainties.empty()) {
    text << "\n  standard uncertainties (type A, from the residuals)\n"
         << UntrustedUncertaintiesLine(trusted);
    for (const ParameterUncertainty& u : fit.uncertainties) {
      text << "  " << std::left << std::setw(18) << u.name << UncertaintyText(u.standard_uncertainty, trusted)
           << (u.is_angle ? " rad" : "") << "\n";
    }
  } else {
    text << "\n  no uncertainties: as many parameters as points (the fit interpolates and may not be "
            "unique)\n";
  }
  text << "\n  residuals         RMS " << Format(fit.residuals.rms, 6) << ", max "
       << Format(fit.residuals.max_abs, 6) << ", mean " << Format(fit.residuals.mean, 3) << "\n"
       << "  solver            " << ToString(options.error_term) << " + Levenberg-Marquardt, "
       << fit.iterations << " iterations, stopped: " << ToString(fit.stop_reason) << ", "
       << Format(seconds * 1e3, 3) << " ms\n";
  if (o.loss.is_robust()) {
    text << "  loss              " << ToString(o.loss.kind) << ", scale " << Format(fit.loss_scale, 6)
         << (o.loss.scale_from_data() ? " (from the data)" : "") << ", " << fit.rejected
         << " points down-weighted (IRLS weight < 0.5); " << o.loss_reason << "\n";
  } else {
    text << "  loss              none; " << o.loss_reason << "\n";
  }
  const char* form = FormName(fit.shape);
  text << "\n  " << std::left << std::setw(18) << "form (ISO 1101)" << form << " "
       << Format(lsq_zone.zone_width, 6) << " about the least-squares fit ("
       << (std::is_same_v<Shape, Line3d> ? "2 x max distance" : "max - min distance")
       << "; an upper bound of the minimum zone)\n";
  if (chebyshev) {
    const char* what = criterion == FitCriterion::kMinimumZone ? "minimum zone"
                       : criterion == FitCriterion::kInscribed ? "inscribed"
                                                               : "circumscribed";
    text << "  " << std::left << std::setw(18) << what << form << " " << Format(chebyshev->zone_width, 6)
         << " (max " << Format(chebyshev->max_distance, 6) << ", min " << Format(chebyshev->min_distance, 6)
         << "), " << chebyshev->contacts.size() << " contacting points [" << ContactsText(chebyshev->contacts)
         << "], " << chebyshev->iterations << " iterations, "
         << (chebyshev->converged ? "converged" : "NOT converged (" + chebyshev->stop_reason + ")") << ", "
         << Format(chebyshev_seconds * 1e3, 3) << " ms\n";
    for (const Row& r : Parameters(chebyshev->shape))
      text << "    " << std::left << std::setw(16) << r.name << r.text << "\n";
  }
  if (!measurands.is_null()) text << MeasurandsText(measurands);
  text << adequacy.Text();
  if (o.verbose) text << HistoryTable(fit.history);
  if (deviation) {
    text << "\n  against reference " << o.reference << " (relative to the data's extent " << Format(extent, 6)
         << ")\n"
         << "  position          " << Format(deviation->position / extent, 3) << "\n";
    if (deviation->direction > 0 || !std::is_same_v<Shape, Sphere>) {
      text << "  direction         " << Format(deviation->direction, 3) << " rad\n";
    }
    if (!std::is_same_v<Shape, Plane>)
      text << "  size              " << Format(deviation->size / extent, 3) << "\n";
    if (std::is_same_v<Shape, Cone>)
      text << "  apex angle        " << Format(deviation->angle, 3) << " rad\n";
  }
  outcome.text = text.str();
  return outcome;
}

// `fit --robust`: the dominant instance of the model (detect with one instance), then the usual primitive
// fit and report on its inliers, started at the detection's refit; the rejected points are counted and, when
// asked, written.
FitOutcome ComputeRobustPrimitiveFit(FitOptions o, const Scan& scan, const std::string& format) {
  if (o.model == "line" || o.model == "circle")
    throw FitFailure(kUsage, "--robust detects surfaces (plane, sphere, cylinder, cone, torus), not a " +
                                 o.model + "; use --loss for a robust " + o.model + " fit");
  const DetectionOptions detection = MakeDetectionOptions({o.model}, 1, 0, o.seed, 0.0, 0.0);
  DetectionResult found;
  try {
    found = DetectPrimitives(scan.points, detection, scan.has_normals() ? scan.normals : Eigen::Matrix3Xd());
  } catch (const std::invalid_argument& e) {
    throw FitFailure(kFitError, o.file + ": " + e.what());
  }
  if (found.instances.empty()) {
    throw FitFailure(kFitError, o.file + ": --robust found no " + o.model + " with at least " +
                                    std::to_string(found.min_support) + " points (" + found.stop_reason +
                                    ")");
  }
  const DetectedPrimitive& instance = found.instances.front();
  Scan inliers = scan;
  inliers.points.resize(3, instance.support());
  inliers.normals.resize(3, 0);
  inliers.weights.resize(0);
  inliers.labels.clear();
  for (Eigen::Index k = 0; k < instance.support(); ++k)
    inliers.points.col(k) = scan.points.col(instance.inliers[static_cast<std::size_t>(k)]);
  if (!o.loss.is_robust()) {
    o.loss = detection.refit_loss;
    o.loss_reason = "the refit of --robust (its inliers may still hold a few outliers)";
  }
  FitOutcome outcome;
  const DetectedShape start = instance.shape;
  if (o.model == "plane") {
    outcome = ComputePrimitiveFit<Plane>(o, inliers, format,
                                         [](const auto& p, const auto& opt) { return FitPlane(p, opt); });
  } else if (o.model == "sphere") {
    outcome = ComputePrimitiveFit<Sphere>(o, inliers, format, [&](const auto& p, const auto& opt) {
      return RefineSphere(p, std::get<Sphere>(start), opt);
    });
  } else if (o.model == "cylinder") {
    outcome = ComputePrimitiveFit<Cylinder>(o, inliers, format, [&](const auto& p, const auto& opt) {
      return RefineCylinder(p, std::get<Cylinder>(start), opt);
    });
  } else if (o.model == "cone") {
    outcome = ComputePrimitiveFit<Cone>(o, inliers, format, [&](const auto& p, const auto& opt) {
      return RefineCone(p, std::get<Cone>(start), opt);
    });
  } else {
    outcome = ComputePrimitiveFit<Torus>(o, inliers, format, [&](const auto& p, const auto& opt) {
      return RefineTorus(p, std::get<Torus>(start), opt);
    });
  }
  outcome.document["input"] = DescribeScan(scan, o.file, format);
  nlohmann::json robust = DetectionJson(found);
  robust["inliers"] = instance.support();
  robust["rejected"] = scan.size() - instance.support();
  robust["seed"] = o.seed;
  robust["miss_probability"] = instance.miss_probability;
  if (!o.rejected_output.empty()) {
    std::vector<Eigen::Index> rejected;
    std::vector<char> in(static_cast<std::size_t>(scan.size()), 0);
    for (Eigen::Index i : instance.inliers) in[static_cast<std::size_t>(i)] = 1;
    for (Eigen::Index i = 0; i < scan.size(); ++i)
      if (!in[static_cast<std::size_t>(i)]) rejected.push_back(i);
    if (!rejected.empty()) {
      WritePointsPly(o.rejected_output, scan.points, rejected,
                     std::vector<std::array<int, 3>>(rejected.size(), {128, 128, 128}));
    }
    robust["rejected_output"] = o.rejected_output;
  }
  outcome.document["robust"] = robust;
  std::ostringstream text;
  text << "  robust            " << instance.support() << " inliers of " << scan.size() << " points, "
       << scan.size() - instance.support() << " rejected (epsilon " << Format(found.epsilon, 3) << ", alpha "
       << Format(found.alpha, 3) << " rad, seed " << o.seed << ")";
  if (!o.rejected_output.empty()) text << "; rejected points written to " << o.rejected_output;
  text << "\n";
  outcome.text += text.str();
  outcome.notes = scan.metadata.notes;
  return outcome;
}

}  // namespace

template <class Shape>
nlohmann::json PrimitiveFitJson(const std::string& model, ErrorTerm method, const PrimitiveFit<Shape>& fit,
                                const std::string& units) {
  nlohmann::json j;
  j["model"] = model;
  j["method"] = ToString(method);
  for (const Row& r : Parameters(fit.shape)) j["parameters"][r.name] = r.value;
  j["nist_layout"] = ToNistLayout(fit.shape);
  for (const ParameterUncertainty& u : fit.uncertainties) {
    j["uncertainties"][u.name] = {{"standard_uncertainty", u.standard_uncertainty},
                                  {"unit", u.is_angle ? "rad" : units}};
  }
  j["residuals"] = {{"count", fit.residuals.count},
                    {"rms", fit.residuals.rms},
                    {"max_abs", fit.residuals.max_abs},
                    {"mean", fit.residuals.mean}};
  j["iterations"] = fit.iterations;
  j["stop_reason"] = ToString(fit.stop_reason);
  j["history"] = HistoryJson(fit.history);
  return j;
}
template nlohmann::json PrimitiveFitJson(const std::string&, ErrorTerm, const PrimitiveFit<Plane>&,
                                         const std::string&);
template nlohmann::json PrimitiveFitJson(const std::string&, ErrorTerm, const PrimitiveFit<Sphere>&,
                                         const std::string&);
template nlohmann::json PrimitiveFitJson(const std::string&, ErrorTerm, const PrimitiveFit<Cylinder>&,
                                         const std::string&);
template nlohmann::json PrimitiveFitJson(const std::string&, ErrorTerm, const PrimitiveFit<Cone>&,
                                         const std::string&);
template nlohmann::json PrimitiveFitJson(const std::string&, ErrorTerm, const PrimitiveFit<Line3d>&,
                                         const std::string&);
template nlohmann::json PrimitiveFitJson(const std::string&, ErrorTerm, const PrimitiveFit<Circle3d>&,
                                         const std::string&);
template nlohmann::json PrimitiveFitJson(const std::string&, ErrorTerm, const PrimitiveFit<Torus>&,
                                         const std::string&);

FitOutcome ComputeFit(const FitOptions& o) {
  // Options of one model family given to another would be ignored silently: refused instead.
  if (o.fill_height > 0 && o.model != "revolution")
    throw FitFailure(kUsage, "--fill-height applies to --model revolution (a vessel's volume)");
  if (o.geometric_variation > 0 && o.model != "hermite-curve")
    throw FitFailure(kUsage, "--geometric-variation applies to --model hermite-curve");
  if (o.efd_harmonics > 0 && o.model != "revolution")
    throw FitFailure(kUsage, "--efd applies to --model revolution (a vessel's outline)");
  if (o.relative_variation && o.model != "hermite-curve")
    throw FitFailure(kUsage, "--relative-variation applies to --model hermite-curve");
  // Derived quantities with a chosen uncertainty method exist for primitives and multi-view fits; the
  // others would ignore the option silently.
  if (!o.uncertainty.empty() && o.uncertainty != "none" &&
      (o.model == "bspline-curve" || o.model == "bspline-surface" || o.model == "hermite-curve" ||
       o.model == "fe-surface" || o.model.rfind("part:", 0) == 0))
    throw FitFailure(
        kUsage, "--uncertainty applies to primitives and to revolution, helical and spiral fits (" + o.model +
                    " reports its parameters' standard uncertainties from the fit)");
  if (((!o.boundary.empty() && o.boundary != "auto") || o.size > 0 || o.projection != "plane") &&
      o.model != "fe-surface")
    throw FitFailure(kUsage, "--boundary, --size and --projection apply to --model fe-surface");
  if (o.model == "bspline-curve" || o.model == "bspline-surface") return ComputeSplineFit(o);
  if (o.model == "hermite-curve") return ComputeHermiteFit(o);
  if (o.model == "fe-surface") return ComputeFeSurfaceFit(o);
  if (o.wall && o.model != "revolution")
    throw FitFailure(kUsage, "--wall applies to --model revolution (a vessel's inner and outer surfaces)");
  if (o.wall) return ComputeWallFit(o);
  if (o.model == "revolution" || o.model == "helical" || o.model == "spiral") return ComputeMultiViewFit(o);
  if (o.model.rfind("part:", 0) == 0) return ComputePartFit(o);
  if (o.model != "plane" && o.model != "sphere" && o.model != "cylinder" && o.model != "cone" &&
      o.model != "line" && o.model != "circle" && o.model != "torus")
    throw FitFailure(kUsage, o.model + " is not a model (docs/cli.md)");
  FitOptions options = o;
  if (options.method.empty()) options.method = "tdm";
  if (options.method != "tdm" && options.method != "sdm") {
    throw FitFailure(kUsage, "--method " + options.method + " applies to splines; primitives use tdm or sdm");
  }
  try {
    // A recording, a views manifest or views in memory: merged in the world (a primitive has no poses to
    // fit).
    const std::string extension = std::filesystem::path(options.file).extension().string();
    Scan scan;
    std::string f;
    if (std::optional<Scan> cloud = InputCloud(options.file, options.views.get())) {
      scan = std::move(*cloud);
      f = options.views ? "memory" : extension == kRecordingExtension ? "recording" : "views";
    } else {
      const PointCloudFormat format = DetectFormat(options.file);
      scan = ReadPointCloud(options.file, format);
      f = ToString(format);
    }
    if (!options.units.empty()) scan.units = options.units;
    ResolveDefaultLoss(options, ClassifyInput(options.file, scan.metadata.device));
    FitOutcome outcome;
    if (options.robust) {
      outcome = ComputeRobustPrimitiveFit(options, scan, f);
    } else if (options.model == "plane") {
      outcome = ComputePrimitiveFit<Plane>(options, scan, f,
                                           [](const auto& p, const auto& opt) { return FitPlane(p, opt); });
    } else if (options.model == "sphere") {
      outcome = ComputePrimitiveFit<Sphere>(options, scan, f,
                                            [](const auto& p, const auto& opt) { return FitSphere(p, opt); });
    } else if (options.model == "cylinder") {
      outcome = ComputePrimitiveFit<Cylinder>(
          options, scan, f, [](const auto& p, const auto& opt) { return FitCylinder(p, opt); });
    } else if (options.model == "line") {
      outcome = ComputePrimitiveFit<Line3d>(options, scan, f,
                                            [](const auto& p, const auto& opt) { return FitLine(p, opt); });
    } else if (options.model == "circle") {
      outcome = ComputePrimitiveFit<Circle3d>(
          options, scan, f, [](const auto& p, const auto& opt) { return FitCircle(p, opt); });
    } else if (options.model == "torus") {
      outcome = ComputePrimitiveFit<Torus>(options, scan, f,
                                           [](const auto& p, const auto& opt) { return FitTorus(p, opt); });
    } else {
      outcome = ComputePrimitiveFit<Cone>(options, scan, f,
                                          [](const auto& p, const auto& opt) { return FitCone(p, opt); });
    }
    outcome.notes = scan.metadata.notes;
    if (!options.output.empty())
      WriteTextAtomically(options.output + ".json", outcome.document.dump(2) + "\n");
    return outcome;
  } catch (const FormatError& e) {
    throw FitFailure(kInputError, e.what());
  } catch (const FitError& e) {
    throw FitFailure(kFitError, options.file + ": " + e.what());
  }
}

}  // namespace s2m::pipeline
