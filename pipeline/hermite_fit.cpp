// `scan2model fit --model hermite-curve`: Hermite finite-element curves with L. Fang's fairness energy and
// the curve's interrogation (docs/fair-curves.md), from the command line and batch manifests.

#include "fitting/hermite_fit.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <optional>
#include <sstream>

#include "acquisition/format_error.h"
#include "acquisition/point_cloud_io.h"
#include "fitting/curve_interrogation.h"
#include "pipeline/exit_code.h"
#include "pipeline/fit_options.h"
#include "pipeline/interrogation_json.h"
#include "pipeline/output.h"

namespace s2m::pipeline {
namespace {

std::vector<double> Column(const Eigen::VectorXd& v) {
  return std::vector<double>(v.data(), v.data() + v.size());
}

nlohmann::json WeightsJson(const HermiteFairness& f) {
  return {{"alpha1", f.alpha1},
          {"alpha2", f.alpha2},
          {"alpha3", f.alpha3},
          {"beta2", f.beta2},
          {"beta3", f.beta3}};
}

// How to evaluate the curve from the JSON alone (docs/fair-curves.md eq. F3).
const char* kEvaluation =
    "On element i (u_i <= u <= u_(i+1), h = u_(i+1) - u_i, t = (u - u_i) / h): w(u) = sum_j "
    "[ w^(j)(u_i) h^j H_j(t) + w^(j)(u_(i+1)) h^j G_j(t) ], j = 0..1 (cubic) or 0..2 (quintic), with the "
    "Hermite polynomials of docs/fair-curves.md eq. F3: cubic H_0 = 1 - 3t^2 + 2t^3, H_1 = t - 2t^2 + t^3, "
    "G_0 = 3t^2 - 2t^3, G_1 = -t^2 + t^3; quintic H_0 = 1 - 10t^3 + 15t^4 - 6t^5, H_1 = t - 6t^3 + 8t^4 - "
    "3t^5, H_2 = (t^2 - 3t^3 + 3t^4 - t^5) / 2, G_0 = 10t^3 - 15t^4 + 6t^5, G_1 = -4t^3 + 7t^4 - 3t^5, "
    "G_2 = (t^3 - 2t^4 + t^5) / 2. A closed curve's last element ends at node 0.";

}  // namespace

FitOutcome ComputeHermiteFit(const FitOptions& o) {
  try {
    std::string format, units, device = "file";
    FitOutcome outcome;
    const Eigen::MatrixXd points = ReadFitPoints(o, format, units, outcome.notes, device);
    const std::string units_out = o.units.empty() ? units : o.units;
    Eigen::MatrixXd data = points;
    // Planar input with constant z is fitted in 2D (signed curvature, inflections, the comb).
    if (points.rows() == 3 && (points.row(2).array() == points(2, 0)).all()) data = points.topRows(2);
    HermiteFitOptions h;
    h.degree = o.degree;
    h.closed = o.closed;
    h.c2 = o.c2;
    h.interpolate = o.interpolate;
    if (o.elements == "auto" || o.elements.empty()) {
      h.elements = 0;
    } else {
      try {
        std::size_t used = 0;
        h.elements = std::stoi(o.elements, &used);
        if (used != o.elements.size() || h.elements < 1) throw std::invalid_argument("");
      } catch (const std::exception&) {
        throw FitFailure(kUsage, "--elements " + o.elements + ": a positive number of elements or auto");
      }
    }
    h.fairness = {o.alpha1, o.alpha2, o.alpha3, o.beta2, o.beta3};
    const std::string method = o.method.empty() ? "sdm" : o.method;
    try {
      h.method = HermiteMethodFromString(method);
    } catch (const std::invalid_argument& e) {
      throw FitFailure(kUsage, std::string("--method: ") + e.what());
    }
    h.tolerance = o.tolerance;
    h.fairness_fraction = o.fairness_fraction;
    h.geometric_variation = o.geometric_variation;
    h.relative_variation = o.relative_variation;
    h.optimizer.max_iterations = o.max_iterations;
    std::string why;
    if (!h.IsValid(&why)) throw FitFailure(kUsage, "hermite-curve: " + why);
    if (h.geometric_variation > 0 && data.rows() != 2)
      throw FitFailure(kUsage, "hermite-curve: --geometric-variation is implemented for plane curves only; " +
                                   o.file + " holds a space curve (z not constant)");
    const HermiteFitResult r = FitHermiteCurve(data, h);
    const HermiteCurve& curve = r.curve;
    const CurveInterrogation q = InterrogateCurve(ToInterrogated(curve), {256, 0.0});
    // An open curve's free ends are held by nothing in the default energy (a straight run of points costs no
    // curvature variation however far it extends or folds back): say so when the data do not reach the ends
    // or the tangent turns back.
    double covered_lo = 1.0, covered_hi = 0.0;
    for (const FootPoint& f : r.foot_points) {
      covered_lo = std::min(covered_lo, f.t[0]);
      covered_hi = std::max(covered_hi, f.t[0]);
    }
    std::optional<double> fold_at;
    if (!curve.closed()) {
      fold_at = curve.FirstFold();
      if (covered_lo > 0.01 || covered_hi < 0.99)
        outcome.notes.push_back(
            "the curve runs past its data: the points' feet cover u in [" + Format(covered_lo, 3) + ", " +
            Format(covered_hi, 3) +
            "] only (an open curve's ends are not held by the curvature-variation energy; "
            "add --alpha1 or --alpha2, or use the covered range)");
      if (fold_at)
        outcome.notes.push_back(
            "the curve folds back on itself near u = " + Format(*fold_at, 3) +
            " (its tangent reverses): not a faithful curve of the points; add --alpha1 or "
            "--alpha2");
    }

    nlohmann::json& j = outcome.document;
    j["schema"] = "scan2model.hermite/1";
    j["input"] = {{"file", o.file}, {"format", format}, {"points", points.cols()}, {"units", units_out}};
    j["model"] = "hermite-curve";
    j["method"] = ToString(h.method);
    j["mode"] = h.interpolate ? "interpolation" : "approximation";
    j["degree"] = curve.degree();
    j["closed"] = curve.closed();
    j["c2"] = curve.c2();
    j["dimension"] = curve.ambient_dimension();
    j["elements"] = curve.num_elements();
    j["weights"] = WeightsJson(r.weights);
    j["weights"]["given"] = WeightsJson(h.fairness);
    j["weights"]["scale"] = r.weight_scale;
    j["weights"]["geometric_variation"] = h.geometric_variation;
    j["weights"]["relative_variation"] = h.relative_variation;
    j["tolerance"] = {{"target", h.tolerance}, {"met", r.tolerance_met}};
    if (h.fairness_fraction > 0) {
      const HermiteFitResult::Fraction& f = r.fraction;
      j["fairness_fraction"] = {{"fraction", f.fraction},
                                {"noise", f.sigma},
                                {"length", f.length},
                                {"closeness_reference", f.closeness_reference},
                                {"fairness_reference", f.fairness_reference},
                                {"normalized_closeness", f.closeness},
                                {"normalized_fairness", f.fairness}};
    }
    j["knots"] = curve.knots();
    nlohmann::json nodes = nlohmann::json::array();
    const int per = curve.derivatives_per_node();
    for (int i = 0; i < curve.num_nodes(); ++i) {
      nlohmann::json node = {{"u", curve.knots()[static_cast<std::size_t>(i)]},
                             {"position", Column(curve.nodal_values().col(i * per))},
                             {"first_derivative", Column(curve.nodal_values().col(i * per + 1))}};
      if (per == 3) node["second_derivative"] = Column(curve.nodal_values().col(i * per + 2));
      nodes.push_back(node);
    }
    j["nodes"] = nodes;
    j["evaluation"] = kEvaluation;
    j["energy"] = WeightsJson(r.energy);
    j["energy"]["geometric_variation"] = r.geometric_energy;
    j["energy"]["closeness"] = r.closeness;
    j["energy"]["total"] = r.closeness + r.energy.alpha1 + r.energy.alpha2 + r.energy.alpha3 +
                           r.energy.beta2 + r.energy.beta3 + r.geometric_energy;
    j["residuals"] = {
        {"count", r.residuals.count}, {"rms", r.residuals.rms}, {"max_abs", r.residuals.max_abs}};
    j["noise"] = std::isfinite(r.noise) ? nlohmann::json(r.noise) : nlohmann::json(nullptr);
    j["iterations"] = r.iterations;
    j["total_iterations"] = r.total_iterations;
    j["fits"] = r.fits;
    j["stop_reason"] = ToString(r.stop_reason);
    j["seconds"] = r.seconds;
    j["history"] = HistoryJson(r.history);
    if (!r.note.empty()) j["note"] = r.note;
    if (!curve.closed()) {
      j["data_range"] = {covered_lo, covered_hi};
      j["folds_at"] = fold_at ? nlohmann::json(*fold_at) : nlohmann::json(nullptr);
    }
    j["interrogation"] = InterrogationJson(q, curve.ambient_dimension());

    std::string history_path = o.history;
    if (!o.output.empty()) {
      WriteTextAtomically(o.output + ".json", j.dump(2) + "\n");
      Scan samples;
      samples.points = Eigen::Matrix3Xd::Zero(3, static_cast<Eigen::Index>(q.samples.size()));
      for (std::size_t i = 0; i < q.samples.size(); ++i)
        samples.points.col(static_cast<Eigen::Index>(i)) = q.samples[i].point;
      samples.units = units_out;
      WritePly(o.output + ".ply", samples);
      if (history_path.empty()) history_path = o.output + "_history.csv";
    }
    if (!history_path.empty()) WriteTextAtomically(history_path, HistoryCsv(r.history));

    std::ostringstream text;
    text << "scan2model fit: " << curve.name() << ", " << curve.num_elements() << " elements ("
         << curve.num_parameters() << " parameters) to " << points.cols() << " points of " << o.file << " ("
         << format << ", units " << units_out << ")\n\n"
         << "  method            " << (h.interpolate ? "interpolation" : ToString(h.method))
         << ", weights alpha " << Format(r.weights.alpha1, 4) << " / " << Format(r.weights.alpha2, 4) << " / "
         << Format(r.weights.alpha3, 4) << ", beta " << Format(r.weights.beta2, 4) << " / "
         << Format(r.weights.beta3, 4);
    if (h.tolerance > 0)
      text << " (x" << Format(r.weight_scale, 4) << " for the tolerance " << h.tolerance << ")";
    if (h.fairness_fraction > 0)
      text << " (x" << Format(r.weight_scale, 4) << " for the fairness fraction " << h.fairness_fraction
           << "; normalized closeness " << Format(r.fraction.closeness, 4) << ", fairness "
           << Format(r.fraction.fairness, 4) << ")";
    if (h.geometric_variation > 0)
      text << ", " << Format(h.geometric_variation, 4) << " of alpha3 along the arc"
           << (h.relative_variation ? " (relative to the curvature)" : "");
    text << "\n  energy            closeness " << Format(r.closeness, 6) << ", stretch "
         << Format(r.energy.alpha1, 6) << ", bending " << Format(r.energy.alpha2, 6) << ", variation "
         << Format(r.energy.alpha3, 6);
    if (h.geometric_variation > 0) text << " + " << Format(r.geometric_energy, 6) << " along the arc";
    text << ", jumps " << Format(r.energy.beta2 + r.energy.beta3, 6) << "\n"
         << "  residuals         RMS " << Format(r.residuals.rms, 6) << ", max "
         << Format(r.residuals.max_abs, 6);
    if (std::isfinite(r.noise)) text << " (noise estimate " << Format(r.noise, 4) << ")";
    text << "\n  solver            " << r.iterations << " iterations (" << r.total_iterations << " over "
         << r.fits << " fits), stopped: " << ToString(r.stop_reason) << ", " << Format(r.seconds * 1e3, 4)
         << " ms\n"
         << "  fairness          length " << Format(q.length, 6) << ", max |kappa| "
         << Format(q.max_abs_kappa, 4) << ", integral (dkappa/ds)^2 ds " << Format(q.dkappa_ds_squared, 4)
         << ", zeta " << Format(q.zeta, 4) << ", " << q.inflections.size() << " inflections, max G1 break "
         << Format(q.max_g1, 3) << " rad, max G2 break " << Format(q.max_g2, 3) << "\n";
    if (!r.note.empty()) text << "  note              " << r.note << "\n";
    if (o.verbose) text << HistoryTable(r.history);
    if (!o.output.empty()) {
      text << "  written           " << o.output << ".json, " << o.output << ".ply, " << history_path << "\n";
    }
    outcome.text = text.str();
    return outcome;
  } catch (const FitFailure&) {
    throw;
  } catch (const FormatError& e) {
    throw FitFailure(kInputError, e.what());
  } catch (const std::exception& e) {  // degenerate data, invalid options found by the core
    throw FitFailure(kFitError, o.file + ": " + e.what());
  }
}

}  // namespace s2m::pipeline
