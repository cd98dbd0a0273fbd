// `scan2model fit --model bspline-curve|bspline-surface`: the fitting engine from the command line.

#include <unistd.h>

#include <Eigen/Eigenvalues>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <limits>
#include <sstream>

#include "acquisition/format_error.h"
#include "acquisition/glyph_outline.h"
#include "acquisition/point_cloud_io.h"
#include "fitting/curve_interrogation.h"
#include "fitting/geometric_fit.h"
#include "fitting/initial_models.h"
#include "fitting/model_complexity.h"
#include "fitting/noise_estimate.h"
#include "fitting/residual_structure.h"
#include "pipeline/complexity.h"
#include "pipeline/domain_measures.h"
#include "pipeline/exit_code.h"
#include "pipeline/fit_option_table.h"
#include "pipeline/fit_options.h"
#include "pipeline/interrogation_json.h"
#include "pipeline/output.h"
#include "pipeline/surface_model_json.h"
#include "pipeline/views.h"

namespace s2m::pipeline {
namespace {

class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

StepStrategy ParseStepControl(const std::string& s) {
  if (s == "none") return StepStrategy::kFullStep;
  if (s == "armijo") return StepStrategy::kArmijo;
  return StepStrategy::kTrustRegion;
}

// A curve's initial model: quadtree chain in the data's plane (2D data as is; 3D data on their best-fit
// plane).
std::unique_ptr<ParametricModel> InitialCurve(const Eigen::MatrixXd& points, int n, int order, bool closed) {
  if (points.rows() == 2)
    return std::make_unique<BSplineCurve>(InitialCurveFromQuadtree(points, n, order, closed));
  const Eigen::Vector3d c = points.rowwise().mean();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig((points.colwise() - c) *
                                                     (points.colwise() - c).transpose());
  Eigen::Matrix<double, 3, 2> plane;
  plane << eig.eigenvectors().col(2), eig.eigenvectors().col(1);
  const Eigen::Matrix2Xd flat = plane.transpose() * (points.colwise() - c);
  const BSplineCurve curve2d = InitialCurveFromQuadtree(flat, n, order, closed);
  const Eigen::MatrixXd control = (plane * curve2d.control_points()).colwise() + c;
  return std::make_unique<BSplineCurve>(curve2d.basis(), control);
}

// A user-given initial curve or surface: a scan2model.bspline/1 document (docs/method.md section 8).
std::unique_ptr<ParametricModel> ReadInitialModel(const std::string& path, bool surface) {
  try {
    std::ifstream in(path);
    if (!in) throw std::invalid_argument("cannot open");
    const nlohmann::json j = nlohmann::json::parse(in);
    if (j.value("schema", "") != "scan2model.bspline/1")
      throw std::invalid_argument("not a scan2model.bspline/1 document");
    if (surface) {
      const Eigen::MatrixXd cp = ControlPointsFromJson(j.at("control_points"));
      if (cp.rows() != 3) throw std::invalid_argument("surface control points must be 3D");
      return std::make_unique<BSplineSurface>(BasisFromJson(j.at("basis_u")), BasisFromJson(j.at("basis_v")),
                                              cp);
    }
    return std::make_unique<BSplineCurve>(BasisFromJson(j.at("basis")),
                                          ControlPointsFromJson(j.at("control_points")));
  } catch (const std::exception& e) {  // JSON syntax, missing members, invalid knot vectors
    throw FormatError(path, "", std::string("unusable initial model: ") + e.what());
  }
}

// Samples of the fitted model (curve: 20 per knot span; surface: 10 x 10 per patch) for the PLY output.
Eigen::Matrix3Xd Samples(const ParametricModel& model) {
  const ParameterDomain d = model.domain();
  std::vector<Eigen::Vector3d> out;
  LocalGeometry g;
  auto add = [&](double u, double v) {
    model.Evaluate({u, v}, 0, g);
    Eigen::Vector3d p = Eigen::Vector3d::Zero();
    p.head(g.point.size()) = g.point;
    out.push_back(p);
  };
  if (d.dimension == 1) {
    const int n = 20 * static_cast<int>(std::ceil(d.hi[0] - d.lo[0]));
    for (int i = 0; i <= n; ++i) add(d.lo[0] + (d.hi[0] - d.lo[0]) * i / n, 0.0);
  } else {
    const int nu = 10 * static_cast<int>(std::ceil(d.hi[0] - d.lo[0])),
              nv = 10 * static_cast<int>(std::ceil(d.hi[1] - d.lo[1]));
    for (int i = 0; i <= nu; ++i)
      for (int j = 0; j <= nv; ++j)
        add(d.lo[0] + (d.hi[0] - d.lo[0]) * i / nu, d.lo[1] + (d.hi[1] - d.lo[1]) * j / nv);
  }
  Eigen::Matrix3Xd m(3, static_cast<Eigen::Index>(out.size()));
  for (std::size_t i = 0; i < out.size(); ++i) m.col(static_cast<Eigen::Index>(i)) = out[i];
  return m;
}

}  // namespace

Eigen::MatrixXd ReadFitPoints(const FitOptions& o, std::string& format, std::string& units,
                              std::vector<std::string>& notes, std::string& device) {
  if (o.views) {
    const std::optional<Scan> scan = InputCloud(o.file, o.views.get());
    notes = scan->metadata.notes;
    device = scan->metadata.device;
    format = "memory";
    units = scan->units;
    return scan->points;
  }
  if (std::filesystem::path(o.file).extension() == ".glif") {
    const auto contours = ReadGlifContours(o.file);
    if (o.contour < 0 || o.contour >= static_cast<int>(contours.size())) {
      throw FitFailure(kUsage, "--contour " + std::to_string(o.contour) + ": the glyph has " +
                                   std::to_string(contours.size()) + " contours");
    }
    format = "glif";
    units = "font units";
    return contours[static_cast<std::size_t>(o.contour)];
  }
  const PointCloudFormat f = DetectFormat(o.file);
  const Scan scan = ReadPointCloud(o.file, f);
  notes = scan.metadata.notes;
  device = scan.metadata.device;
  format = ToString(f);
  units = scan.units;
  return scan.points;
}

FitOutcome ComputeSplineFit(const FitOptions& given) {
  FitOptions o = given;
  const bool surface = o.model == "bspline-surface";
  try {
    ControlPointRequest request;
    try {
      request = ParseControlPoints(o.control_points, surface);
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
    // A user-given initial model keeps its count unless auto is asked for explicitly.
    if (!o.initial.empty() && o.control_points.empty()) request.automatic = false;
    // Automatic complexity (the default) starts coarse (docs/method.md section 18): one span more than a
    // single polynomial piece, a closed curve with two more control points than its order.
    const int coarse = o.order + (o.closed && !surface ? 2 : 1);
    const int n1 = request.automatic ? coarse : request.first;
    const int n2 = request.automatic ? coarse : request.second;
    std::string format, units;
    FitOutcome outcome;
    std::string device = "file";
    const Eigen::MatrixXd points = ReadFitPoints(o, format, units, outcome.notes, device);
    ResolveDefaultLoss(o, ClassifyInput(o.file, device));
    const std::string units_out = o.units.empty() ? units : o.units;
    if (surface && points.rows() != 3) throw UsageError("a B-spline surface needs 3D points");
    std::unique_ptr<ParametricModel> model;
    Eigen::MatrixXd data = points;
    if (surface) {
      model = !o.initial.empty() ? ReadInitialModel(o.initial, true)
                                 : std::make_unique<BSplineSurface>(InitialSurfaceByProjection(
                                       points, n1, n2, o.order,
                                       o.closed ? SurfaceProjection::kCylinder : SurfaceProjection::kPlane));
    } else {
      // Planar input with constant z is fitted in 2D (TDM is then well posed); otherwise as a curve in space.
      if (points.rows() == 3 && (points.row(2).array() == points(2, 0)).all()) data = points.topRows(2);
      model =
          !o.initial.empty() ? ReadInitialModel(o.initial, false) : InitialCurve(data, n1, o.order, o.closed);
      if (model->ambient_dimension() != data.rows()) {
        throw UsageError("the initial curve is " + std::to_string(model->ambient_dimension()) +
                         "D but the data are " + std::to_string(data.rows()) + "D");
      }
    }
    GeometricFitOptions options;
    options.error_term = ErrorTermFromString(o.method.empty() ? "sdm" : o.method);
    options.optimizer.step_strategy = ParseStepControl(o.step_control);
    options.fairness = {o.stretch, o.bending, o.alpha3_given ? o.alpha3 : 0.0, o.beta2, o.beta3};
    options.optimizer.max_iterations = o.max_iterations;
    options.optimizer.loss = o.loss;
    const bool progress = o.interactive && !o.json && isatty(STDERR_FILENO);
    if (progress) {
      options.on_iteration = [](const IterationRecord& r) {
        std::cerr << "\r  iteration " << std::setw(4) << r.iteration << "  RMS " << std::setw(12)
                  << Format(r.rms, 6) << "  max " << std::setw(12) << Format(r.max_distance, 6) << std::flush;
      };
    }
    const auto start = std::chrono::steady_clock::now();
    // The model-free noise that the automatic complexity's adequacy band needs: local quadrics for surfaces,
    // local parabolas for plane curves (fitting/noise_estimate.h); unknown for curves in space.
    ComplexityOptions complexity_options;
    NoiseEstimate noise;
    if (surface) {
      ScanSet one;
      one.scans.emplace_back();
      one.scans.back().points = data;
      noise = EstimateNoiseWithDof(one);
    } else if (data.rows() == 2) {
      noise = EstimateCurveNoise(data);
    } else {
      noise.sigma = std::numeric_limits<double>::quiet_NaN();
    }
    complexity_options.noise = noise.sigma;
    complexity_options.noise_dof = noise.dof;
    const int max_control_points =
        request.max > 0 ? request.max
                        : (surface ? 30 : static_cast<int>(std::min<Eigen::Index>(100, data.cols() / 4)));
    RefinableSplineFit refinable(*model, data, options, std::max(max_control_points, n1));
    const ComplexityChoice complexity = request.automatic ? ChooseComplexity(refinable, complexity_options)
                                                          : FitFixedComplexity(refinable, complexity_options);
    const GeometricFitResult& r = refinable.result();
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (progress) std::cerr << "\n";

    // Adequacy (docs/method.md section 17): the RMS against the data's own noise (a curve's or a surface's
    // estimate), and the residuals' structure along the curve parameter (surfaces: along a Hilbert curve over
    // (u, v)) and between nearest neighbours. Residuals are signed by the model's normal, except for a curve
    // in space, whose distances have no sign.
    AdequacyEvidence evidence;
    evidence.family = ModelFamily::kSpline;
    evidence.reports_uncertainties = false;
    evidence.model = o.model;
    evidence.fit_rms = r.residuals.rms;
    const Eigen::Index count = data.cols();
    evidence.residuals.resize(count);
    evidence.points = Eigen::Matrix3Xd::Zero(3, count);
    evidence.signed_residuals = surface || data.rows() == 2;
    Eigen::MatrixXd feet(surface ? 2 : 1, count);
    {
      LocalGeometry g;
      for (Eigen::Index i = 0; i < count; ++i) {
        const FootPoint& foot = r.foot_points[static_cast<std::size_t>(i)];
        model->Evaluate(foot.t, 1, g);
        const Eigen::VectorXd offset = data.col(i) - Eigen::VectorXd(g.point);
        double sign = 1.0;
        if (surface) {
          const Eigen::Vector3d normal = Eigen::Vector3d(g.d1.col(0)).cross(Eigen::Vector3d(g.d1.col(1)));
          sign = normal.dot(offset) < 0 ? -1.0 : 1.0;
        } else if (data.rows() == 2) {
          sign = -g.d1(1, 0) * offset[0] + g.d1(0, 0) * offset[1] < 0 ? -1.0 : 1.0;  // left of the tangent
        }
        evidence.residuals[i] = sign * foot.distance;
        evidence.points.col(i).head(g.point.size()) = g.point;  // the foot: positions free of the residual
        for (Eigen::Index k = 0; k < feet.rows(); ++k) feet(k, i) = foot.t[static_cast<std::size_t>(k)];
      }
    }
    if (surface) {
      const auto& s = dynamic_cast<const BSplineSurface&>(*model);
      evidence.control_points =
          std::to_string(s.basis_u().num_control()) + "x" + std::to_string(s.basis_v().num_control());
      evidence.order = HilbertOrder(feet);
      evidence.order_description = "a Hilbert curve over the surface parameters (u, v)";
      ScanSet single;
      single.scans.emplace_back();
      single.scans.back().points = points;
      evidence.noise_estimate = EstimateNoise(single);
    } else {
      evidence.control_points =
          std::to_string(dynamic_cast<const BSplineCurve&>(*model).basis().num_control());
      evidence.order = OrderByParameter(feet.row(0).transpose());
      evidence.order_description = "the curve parameter";
      evidence.noise_estimate = EstimateCurveNoise(data).sigma;
      evidence.noise_method =
          "median over local quadratics of 7 neighbours along the curve (docs/method.md section 17)";
    }
    if (o.loss.is_robust()) evidence.weights = r.weights;
    {
      Eigen::Matrix3Xd padded = Eigen::Matrix3Xd::Zero(3, count);
      padded.topRows(data.rows()) = data;
      evidence.extent = ComputeBounds(padded).diagonal();
    }
    const Adequacy adequacy = AssessAdequacy(evidence);

    nlohmann::json& j = outcome.document;
    j["schema"] = "scan2model.bspline/1";
    j["input"] = {{"file", o.file}, {"format", format}, {"points", points.cols()}, {"units", units_out}};
    j["model"] = o.model;
    j["method"] = ToString(options.error_term);
    j["step_control"] = ToString(options.optimizer.step_strategy);
    j["loss"] = LossJson(o.loss, r.loss_scale, r.weights);
    j["loss"]["reason"] = o.loss_reason;
    j["fairness"] = {{"stretch", options.fairness.stretch},
                     {"bending", options.fairness.bending},
                     {"variation", options.fairness.variation},
                     {"jump2", options.fairness.jump2},
                     {"jump3", options.fairness.jump3}};
    if (surface) {
      const auto& s = dynamic_cast<const BSplineSurface&>(*model);
      j["basis_u"] = BasisJson(s.basis_u());
      j["basis_v"] = BasisJson(s.basis_v());
      j["control_grid"] = {s.basis_u().num_control(), s.basis_v().num_control()};
      std::vector<std::vector<double>> cp;
      for (Eigen::Index i = 0; i < s.control_points().cols(); ++i)
        cp.push_back({s.control_points()(0, i), s.control_points()(1, i), s.control_points()(2, i)});
      j["control_points"] = cp;
    } else {
      const auto& c = dynamic_cast<const BSplineCurve&>(*model);
      j["basis"] = BasisJson(c.basis());
      std::vector<std::vector<double>> cp;
      for (Eigen::Index i = 0; i < c.control_points().cols(); ++i) {
        const Eigen::VectorXd col = c.control_points().col(i);
        cp.emplace_back(col.data(), col.data() + col.size());
      }
      j["control_points"] = cp;
      // The curve's fairness (docs/fair-curves.md section 6), drawn by the report.
      j["interrogation"] =
          InterrogationJson(InterrogateCurve(ToInterrogated(c), {256, 0.0}), c.ambient_dimension());
    }
    j["complexity"] = ComplexityJson(complexity, complexity_options);
    j["residuals"] = {
        {"count", r.residuals.count}, {"rms", r.residuals.rms}, {"max_abs", r.residuals.max_abs}};
    j["iterations"] = r.iterations;
    j["stop_reason"] = ToString(r.stop_reason);
    j["seconds"] = seconds;
    j["history"] = HistoryJson(r.history);
    j["adequacy"] = adequacy.ToJson();
    std::string history_path = o.history;
    if (!o.output.empty()) {
      WriteTextAtomically(o.output + ".json", j.dump(2) + "\n");
      Scan samples;
      samples.points = Samples(*model);
      samples.units = units_out;
      WritePly(o.output + ".ply", samples);
      if (history_path.empty()) history_path = o.output + "_history.csv";
    }
    if (!history_path.empty()) WriteTextAtomically(history_path, HistoryCsv(r.history));
    std::ostringstream text;
    text << "scan2model fit: " << model->name() << " (" << model->num_parameters() << " parameters) to "
         << points.cols() << " points of " << o.file << " (" << format << ", units " << units_out << ")\n\n"
         << "  method            " << ToString(options.error_term) << " + "
         << ToString(options.optimizer.step_strategy) << ", fairness stretch " << o.stretch << " bending "
         << o.bending << "\n"
         << ComplexityText(complexity) << "  residuals         RMS " << Format(r.residuals.rms, 6) << ", max "
         << Format(r.residuals.max_abs, 6) << "\n"
         << "  solver            " << r.iterations << " iterations, stopped: " << ToString(r.stop_reason)
         << ", " << Format(seconds * 1e3, 4) << " ms\n";
    if (o.loss.is_robust()) {
      const nlohmann::json& loss = j["loss"];
      text << "  loss              " << ToString(o.loss.kind) << ", scale " << Format(r.loss_scale, 6)
           << (o.loss.scale_from_data() ? " (from the data)" : "") << ", "
           << loss["down_weighted"].get<long>() << " points down-weighted, " << loss["rejected"].get<long>()
           << " rejected; " << o.loss_reason << "\n";
    } else {
      text << "  loss              none; " << o.loss_reason << "\n";
    }
    text << adequacy.Text();
    if (o.verbose) text << HistoryTable(r.history);
    if (!o.output.empty()) {
      text << "  written           " << o.output << ".json, " << o.output << ".ply, " << history_path << "\n";
    }
    outcome.text = text.str();
    return outcome;
  } catch (const FitFailure&) {
    throw;
  } catch (const UsageError& e) {
    throw FitFailure(kUsage, e.what());
  } catch (const FormatError& e) {
    throw FitFailure(kInputError, e.what());
  } catch (const std::exception& e) {  // singular systems, degenerate data, invalid knots
    throw FitFailure(kFitError, o.file + ": " + e.what());
  }
}

}  // namespace s2m::pipeline
