// `scan2model fit --model part:<part.json> <views.json|.conf|cloud>`: a constrained part (docs/parts.md)
// fitted jointly with the poses of several views. The views' recorded world poses place the data near the
// part in the part frame (world = part frame, e.g. a fixture's): the fit corrects every view's pose and
// measures the part's free parameters.

#include <chrono>
#include <cmath>
#include <iomanip>
#include <iostream>
#include <limits>
#include <optional>
#include <sstream>

#include "acquisition/format_error.h"
#include "acquisition/part_file.h"
#include "fitting/joint_fit.h"
#include "fitting/noise_estimate.h"
#include "fitting/part_complexity.h"
#include "fitting/part_model.h"
#include "pipeline/complexity.h"
#include "pipeline/domain_measures.h"
#include "pipeline/exit_code.h"
#include "pipeline/fit_option_table.h"
#include "pipeline/fit_options.h"
#include "pipeline/output.h"
#include "pipeline/surface_model_json.h"
#include "pipeline/views.h"

namespace s2m::pipeline {
namespace {

constexpr double kDegreesPerRadian = 180.0 / M_PI;

// The units the result is stated in: the part file's and the views' must agree when both say.
std::string ResolveUnits(const PartFile& part, const std::string& part_path, const ScanSet& set,
                         const FitOptions& o) {
  const std::string views = !o.units.empty()    ? o.units
                            : set.scans.empty() ? std::string("unknown")
                                                : set.scans.front().units;
  const bool views_known = !views.empty() && views != "unknown";
  if (!part.units.empty() && views_known && views != part.units) {
    throw FormatError(o.file, "",
                      "the views are in " + views + " but the part " + part_path + " is in " + part.units +
                          " (convert one of them, or declare the views' units with --units)");
  }
  return !part.units.empty() ? part.units : views_known ? views : "unknown";
}

// A parameter's reported value and unit: angles in degrees, lengths in the part's units.
struct Reported {
  double value = 0.0;
  double uncertainty = std::numeric_limits<double>::quiet_NaN();
  double nominal = 0.0;
  std::string unit;
};

Reported Report(const PartParameter& p, double value, double uncertainty, const std::string& units) {
  const double k = p.angle ? kDegreesPerRadian : 1.0;
  return {value * k, uncertainty * k, p.value * k, p.angle ? "deg" : units};
}

// The correlation matrix of the shape parameters; empty when there is no covariance (too few points). Rows
// and columns of parameters without a finite uncertainty (unobservable) are NaN.
Eigen::MatrixXd Correlation(const Eigen::MatrixXd& covariance, const std::vector<Reported>& parameters) {
  if (covariance.size() == 0) return {};
  const Eigen::VectorXd s = covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
  Eigen::MatrixXd c(covariance.rows(), covariance.cols());
  for (Eigen::Index i = 0; i < c.rows(); ++i) {
    for (Eigen::Index j = 0; j < c.cols(); ++j) {
      const bool known = std::isfinite(parameters[static_cast<std::size_t>(i)].uncertainty) &&
                         std::isfinite(parameters[static_cast<std::size_t>(j)].uncertainty) && s[i] > 0 &&
                         s[j] > 0;
      c(i, j) = known ? covariance(i, j) / (s[i] * s[j]) : std::numeric_limits<double>::quiet_NaN();
    }
  }
  return c;
}

std::string CorrelationTable(const std::vector<std::string>& names, const Eigen::MatrixXd& c) {
  std::ostringstream t;
  t << "\n  parameter correlations\n  " << std::setw(24) << "";
  for (std::size_t i = 0; i < names.size(); ++i) t << std::setw(8) << ("[" + std::to_string(i + 1) + "]");
  t << "\n";
  for (Eigen::Index i = 0; i < c.rows(); ++i) {
    const std::string label = "[" + std::to_string(i + 1) + "] " + names[static_cast<std::size_t>(i)];
    t << "  " << std::left << std::setw(24) << label << std::right << std::fixed << std::setprecision(3);
    for (Eigen::Index j = 0; j < c.cols(); ++j) {
      if (std::isfinite(c(i, j))) {
        t << std::setw(8) << c(i, j);
      } else {
        t << std::setw(8) << "-";
      }
    }
    t << std::defaultfloat << "\n";
  }
  return t.str();
}

}  // namespace

FitOutcome ComputePartFit(const FitOptions& given) {
  FitOptions o = given;
  const std::string part_path = o.model.substr(std::string("part:").size());
  JointFitOptions options;
  try {
    options = JointOptions(o);
  } catch (const std::invalid_argument& e) {
    throw FitFailure(kUsage, std::string("--method: ") + e.what());
  }
  try {
    const PartFile file = ReadPartFile(part_path);
    ScanSet storage;
    const ScanSet& set = InputViews(o, storage);
    ResolveDefaultLoss(o, ClassifyInput(o.file, set.scans.empty() ? "" : set.scans.front().metadata.device));
    options.optimizer.loss = o.loss;
    const std::string units = ResolveUnits(file, part_path, set, o);
    const std::size_t K = set.scans.size();
    // World = part frame: the recorded poses are the initial poses of the views in the part frame.
    std::vector<Eigen::Matrix3Xd> scans;
    std::vector<RigidMotion> initial;
    for (const Scan& s : set.scans) {
      scans.push_back(s.points);
      initial.push_back(s.world_T_scan);
    }
    // Free-form spline patches (docs/cli.md, "Automatic model complexity"): `auto` (the default) grows their
    // nets from the file's where the residuals are largest until the fit is adequate (docs/method.md
    // section 18); `file` keeps the file's nets. A part without free-form patches is fitted once either way.
    bool search = false;
    int max_control_points = 0;
    if (o.control_points != "file") {
      const std::string refused =
          "--control-points '" + o.control_points +
          "': a part's spline patches start from its file's nets; give auto, auto:MAX "
          "or file";
      ControlPointRequest request;
      try {
        request = ParseControlPoints(o.control_points, true);
      } catch (const std::invalid_argument&) {
        throw FitFailure(kUsage, refused);
      }
      if (!request.automatic) throw FitFailure(kUsage, refused);
      search = RefinablePartFit::HasFreeFormPatches(file.definition);
      max_control_points = request.max > 0 ? request.max : 30;
    }
    PartModel part(file.definition);
    const auto start = std::chrono::steady_clock::now();
    JointFitResult r;
    std::optional<ComplexityChoice> complexity;
    ComplexityOptions complexity_options;
    if (search) {
      const NoiseEstimate noise = EstimateNoiseWithDof(set);
      complexity_options.noise = noise.sigma;
      complexity_options.noise_dof = noise.dof;
      RefinablePartFit refinable(part, scans, initial, options, max_control_points);
      complexity = ChooseComplexity(refinable, complexity_options);
      r = refinable.result();
    } else {
      r = FitPartJointly(part, scans, initial, options);
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

    // Parameters, uncertainties, correlations.
    const PartDefinition& d = part.definition();
    const Eigen::VectorXd values = part.parameters();
    PartDefinition fitted = d;  // a fit that left the part's valid range (a radius through zero) is no result
    for (std::size_t i = 0; i < fitted.parameters.size(); ++i)
      fitted.parameters[i].value = values[static_cast<Eigen::Index>(i)];
    try {
      const PartModel check(fitted);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(
          "the fit left the part's valid range (" + std::string(e.what()) + ", RMS " +
          Format(r.residuals.rms, 3) + " " + units +
          "): do the views' world poses place the data on the part in its part frame (docs/parts.md)?");
    }
    const bool have_uncertainty = r.shape_uncertainty.size() == values.size();
    std::vector<std::string> names;
    std::vector<Reported> reported;
    for (std::size_t i = 0; i < d.parameters.size(); ++i) {
      const Eigen::Index n = static_cast<Eigen::Index>(i);
      names.push_back(d.parameters[i].name);
      // A refined patch's displacements replace the file's block (their nominal, as every displacement's, 0).
      const bool from_file =
          i < file.definition.parameters.size() && file.definition.parameters[i].name == d.parameters[i].name;
      const PartParameter nominal = from_file
                                        ? file.definition.parameters[i]
                                        : PartParameter{d.parameters[i].name, 0.0, d.parameters[i].angle};
      reported.push_back(
          Report(nominal, values[n], have_uncertainty ? r.shape_uncertainty[n] : std::nan(""), units));
    }
    const Eigen::MatrixXd correlation = Correlation(r.shape_covariance, reported);

    // Per face, on the registered points.
    Eigen::Matrix3Xd registered(3, set.TotalPoints());
    Eigen::Index at = 0;
    for (std::size_t k = 0; k < K; ++k) {
      registered.middleCols(at, scans[k].cols()) = r.model_T_scan[k].apply(scans[k]);
      at += scans[k].cols();
    }
    const std::vector<ResidualStatistics> faces = PerFaceResiduals(part, registered);

    FitOutcome outcome;
    nlohmann::json& j = outcome.document;
    j["schema"] = "scan2model.part_fit/1";
    j["input"] = {{"file", o.file}, {"views", K}, {"points", set.TotalPoints()}, {"units", units}};
    j["model"] = o.model;
    j["part"] = {{"file", part_path}, {"name", d.name}, {"units", units}, {"faces", d.faces.size()}};
    if (const std::string nets = PatchControlPoints(d); !nets.empty()) j["part"]["control_points"] = nets;
    if (complexity) j["complexity"] = ComplexityJson(*complexity, complexity_options);
    j["method"] = ToString(options.error_term);
    j["solver"] = SolverName(options);
    j["loss"] = LossJson(o.loss, r.loss_scale, Eigen::VectorXd());
    j["loss"]["reason"] = o.loss_reason;
    j["parameters"] = nlohmann::json::array();
    std::string verdict;  // over the parameters with tolerances: "pass", "fail", or none
    for (std::size_t i = 0; i < reported.size(); ++i) {
      const Reported& p = reported[i];
      nlohmann::json entry = {{"name", names[i]},
                              {"value", p.value},
                              {"standard_uncertainty", NumberOrNull(p.uncertainty)},
                              {"nominal", p.nominal},
                              {"deviation", p.value - p.nominal},
                              {"unit", p.unit}};
      if (const auto t = file.tolerances.find(names[i]); t != file.tolerances.end()) {
        const ToleranceCheck check = CheckTolerance(p.value - p.nominal, t->second, p.uncertainty);
        entry["tolerance"] = t->second;
        entry["verdict"] = check.verdict;
        entry["decision"] = check.decision;
        verdict = verdict == "fail" || check.verdict == "fail" ? "fail" : "pass";
      }
      j["parameters"].push_back(std::move(entry));
    }
    if (!verdict.empty()) j["verdict"] = verdict;
    j["fixed_parameters"] = nlohmann::json::array();
    for (const PartParameter& p : file.fixed_parameters) {
      const Reported f = Report(p, p.value, 0.0, units);
      j["fixed_parameters"].push_back({{"name", p.name}, {"value", f.value}, {"unit", f.unit}});
    }
    j["correlation"] = nullptr;
    if (correlation.size() > 0) {
      nlohmann::json rows = nlohmann::json::array();
      for (Eigen::Index i = 0; i < correlation.rows(); ++i) {
        nlohmann::json row = nlohmann::json::array();
        for (Eigen::Index c = 0; c < correlation.cols(); ++c) row.push_back(NumberOrNull(correlation(i, c)));
        rows.push_back(row);
      }
      j["correlation"] = {{"parameters", names}, {"matrix", rows}};
    }
    j["faces"] = nlohmann::json::array();
    for (std::size_t f = 0; f < faces.size(); ++f) {
      j["faces"].push_back({{"name", d.faces[f].name},
                            {"type", ToString(d.faces[f].type)},
                            {"points", faces[f].count},
                            {"rms", faces[f].rms},
                            {"max_abs", faces[f].max_abs}});
      // A spline patch as fitted, exactly (its control points at the fitted values, in the part frame = the
      // world): the report and `scan2model interrogate` draw its interrogation (docs/interrogation.md).
      if (d.faces[f].type == FaceType::kSplinePatch && d.faces[f].patch) {
        const SplinePatch& patch = *d.faces[f].patch;
        nlohmann::json control = nlohmann::json::array();
        for (const std::array<LinearExpression, 3>& point : patch.control_points)
          control.push_back(
              {point[0].Evaluate(values), point[1].Evaluate(values), point[2].Evaluate(values)});
        j["faces"].back()["surface"] = {
            {"basis_u", BasisJson(patch.u)}, {"basis_v", BasisJson(patch.v)}, {"control_points", control}};
      }
    }
    j["excluded_points"] = r.excluded_points;
    j["edge_margin"] = part.edge_margin();
    j["views"] = ViewsJson(set, r.model_T_scan, r);  // world = part frame
    AddSolverJson(j, r, seconds);
    // Signed deviations of the registered points (world = part frame) and the fit's adequacy against the
    // views' own noise (docs/batch.md).
    // Adequacy (docs/method.md section 17): the RMS against the views' own noise, and the signed residuals'
    // structure along a Hilbert curve through the registered points and between nearest neighbours.
    Eigen::Matrix3Xd feet;
    const Eigen::VectorXd deviations = SignedDistancesToFaces(part, registered, &feet);
    AdequacyEvidence evidence;
    evidence.family = ModelFamily::kPart;
    evidence.model = o.model;
    evidence.fit_rms = r.residuals.rms;
    evidence.noise_estimate = EstimateNoise(set);
    evidence.residuals = deviations;
    evidence.points = feet;
    evidence.weights = RobustWeightsAt(o.loss, r.loss_scale, deviations);
    evidence.extent = ComputeBounds(registered).diagonal();
    const Adequacy adequacy = AssessAdequacy(evidence);
    const std::optional<bool> trusted = adequacy.uncertainty_trusted();
    j["deviations"] = DeviationsJson(registered, deviations, {}, evidence.weights);
    j["adequacy"] = adequacy.ToJson();
    MarkUncertainties(j, trusted);
    WriteRequestedFiles(o, j, r);

    std::ostringstream text;
    text << "scan2model fit: part \"" << part.name() << "\" (" << part_path << ", " << d.faces.size()
         << " faces) to " << K << " views (" << set.TotalPoints() << " points) of " << o.file << " (units "
         << units << ")\n\n"
         << "  solver            " << SolverSummary(options, r, seconds) << "\n"
         << "  loss              " << ToString(o.loss) << "; " << o.loss_reason << "\n"
         << "  residuals         RMS " << Format(r.residuals.rms, 6) << ", max "
         << Format(r.residuals.max_abs, 6) << "\n"
         << "  near edges        " << r.excluded_points << " points within " << Format(part.edge_margin(), 3)
         << " " << units << " of a second face left out of the final pass\n\n"
         << UntrustedUncertaintiesLine(trusted)
         << "  parameter                          value    standard uncertainty       nominal\n";
    for (std::size_t i = 0; i < reported.size(); ++i) {
      const Reported& p = reported[i];
      text << "  " << std::left << std::setw(24) << names[i] << std::right << std::setw(14)
           << Format(p.value, 8) << std::setw(24) << UncertaintyText(p.uncertainty, trusted) << std::setw(14)
           << Format(p.nominal, 8) << "  " << p.unit << "\n";
    }
    for (const PartParameter& p : file.fixed_parameters) {
      const Reported f = Report(p, p.value, 0.0, units);
      text << "  " << std::left << std::setw(24) << p.name << std::right << std::setw(14)
           << Format(f.value, 8) << std::setw(24) << "(fixed)" << std::setw(14) << ""
           << "  " << f.unit << "\n";
    }
    if (j.contains("verdict")) {
      text << "\n  tolerances (nominal +- tolerance; decision by ISO 14253-1 with U = 2u)\n";
      for (const nlohmann::json& p : j["parameters"]) {
        if (!p.contains("tolerance")) continue;
        text << "  " << std::left << std::setw(24) << p["name"].get<std::string>() << std::right
             << " deviation " << std::setw(12) << Format(p["deviation"].get<double>(), 4) << "  tolerance +-"
             << std::setw(8) << Format(p["tolerance"].get<double>(), 4) << "  "
             << p["verdict"].get<std::string>() << " (" << p["decision"].get<std::string>() << ")\n";
      }
      text << "  verdict           " << j["verdict"].get<std::string>() << "\n";
    }
    if (correlation.size() > 0) text << CorrelationTable(names, correlation);
    text << "\n  face                      type        points          RMS          max\n";
    for (std::size_t f = 0; f < faces.size(); ++f) {
      text << "  " << std::left << std::setw(24) << d.faces[f].name << "  " << std::setw(10)
           << ToString(d.faces[f].type) << std::right << std::setw(8) << faces[f].count << std::setw(13)
           << Format(faces[f].rms, 4) << std::setw(13) << Format(faces[f].max_abs, 4) << "\n";
    }
    if (complexity) text << "\n" << ComplexityText(*complexity);
    text << ViewsTable(j["views"]) << UnobservableText(r);
    if (o.verbose) text << HistoryTable(r.history);
    text << adequacy.Text();
    outcome.text = text.str();
    return outcome;
  } catch (const FormatError& e) {
    throw FitFailure(kInputError, e.what());
  } catch (const FitFailure&) {
    throw;
  } catch (const std::exception& e) {
    throw FitFailure(kFitError, o.file + ": " + e.what());
  }
}

}  // namespace s2m::pipeline
