// The fits, detection, registration, batches and reports in Python: the pipeline's own entry points
// (ComputeFit, ComputeDetect, RunBatchObjects, ReportHtml) and JSON writers, the GIL released while they run
// (docs/python.md).
#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <filesystem>
#include <fstream>

#include "acquisition/format_error.h"
#include "fitting/primitive_fit.h"
#include "fitting/robust_loss.h"
#include "pipeline/batch.h"
#include "pipeline/detect.h"
#include "pipeline/domain_measures.h"
#include "pipeline/fit_option_table.h"
#include "pipeline/fit_options.h"
#include "pipeline/output.h"
#include "pipeline/report.h"
#include "python/bindings.h"
#include "python/json_object.h"
#include "python/points.h"
#include "registration/scan_to_scan.h"

namespace s2m::python {
namespace {

namespace fs = std::filesystem;
using pipeline::FitFailure;

// The input of a fit or detection: a file (the pipeline reads it), or views in memory under `name`.
struct Input {
  std::string file;
  std::shared_ptr<const ScanSet> views;
};

Input InputArg(py::handle input, const std::string& name) {
  Input in;
  if (IsPathLike(input)) {
    in.file = PathArg(input, "input");
    return in;
  }
  auto set = std::make_shared<ScanSet>();
  if (py::isinstance<Views>(input)) {
    *set = input.cast<const Views&>().ToScanSet();
  } else if (py::isinstance<Scan>(input)) {
    set->scans.push_back(input.cast<const Scan&>());
  } else if (py::isinstance<py::list>(input) && py::len(input) > 0 &&
             py::isinstance<Scan>(input[py::int_(0)])) {
    for (const py::handle item : input) set->scans.push_back(item.cast<const Scan&>());
  } else {
    Scan scan;
    scan.points = CopyPoints(input, "input");
    set->scans.push_back(std::move(scan));
  }
  in.file = name;
  in.views = std::move(set);
  return in;
}

// An option's value as the manifest's text: booleans as true/false, numbers by repr, strings as they are.
std::string OptionText(py::handle value) {
  if (py::isinstance<py::bool_>(value)) return value.cast<bool>() ? "true" : "false";
  if (py::isinstance<py::str>(value)) return value.cast<std::string>();
  if (IsPathLike(value)) return PathArg(value, "option");
  return py::repr(value).cast<std::string>();
}

pipeline::FitOptions FitOptionsOf(const Input& in, const std::string& model, const py::dict& options) {
  pipeline::FitOptions o;
  o.file = in.file;
  o.views = in.views;
  o.model = model;
  o.interactive = false;
  if (const std::string error = pipeline::ModelError(model); !error.empty())
    throw FitFailure(pipeline::kUsage, error);
  for (const auto& [key, value] : options) {
    const std::string k = key.cast<std::string>();
    if (k == "output") {
      o.output = PathArg(value, "output");
      continue;
    }
    if (k == "history") {
      o.history = PathArg(value, "history");
      continue;
    }
    const pipeline::FitOptionSpec* spec = pipeline::FindManifestOption(k);
    if (!spec) {
      throw FitFailure(pipeline::kUsage, "unknown option '" + k + "'; options: " +
                                             pipeline::ManifestOptionKeys() + ", output, history");
    }
    pipeline::ApplyFitOption(*spec, OptionText(value), o);
  }
  return o;
}

template <class Shape, class Fit>
PrimitiveFitResult DirectFit(const char* model, py::handle points, const std::string& method,
                             const std::string& loss, int max_iterations, const std::string& units, Fit fit) {
  const PointsArg in(points, "points");
  PrimitiveFitOptions options;
  options.error_term = ErrorTermFromString(method);
  options.optimizer.max_iterations = max_iterations;
  options.optimizer.loss = ParseRobustLoss(loss);
  PrimitiveFitResult result;
  {
    py::gil_scoped_release release;
    const PrimitiveFit<Shape> f = fit(in.map(), options);
    result.document = pipeline::PrimitiveFitJson(model, options.error_term, f, units);
    const auto points_in_place = in.map();
    Eigen::VectorXd distances(points_in_place.cols());
    for (Eigen::Index i = 0; i < points_in_place.cols(); ++i)
      distances[i] = SignedDistance(f.shape, Eigen::Vector3d(points_in_place.col(i)));
    result.document["loss"] =
        pipeline::LossJson(options.optimizer.loss, f.loss_scale,
                           pipeline::RobustWeightsAt(options.optimizer.loss, f.loss_scale, distances));
  }
  return result;
}

template <class Shape, class Fit>
void DefineDirectFit(py::module_& m, const char* name, const char* model, Fit fit) {
  const std::string doc =
      std::string("The least-squares ") + model +
      " of N x 3 points, read in place when float64 C-contiguous (no copy), by the core's "
      "certified fit (docs/primitives.md). method: tdm or sdm; loss: none, huber[:scale], "
      "cauchy[:scale], tukey[:scale]; units: of the uncertainties. Raises FitError for too few "
      "or degenerate points, UsageError for bad options.";
  m.def(
      name,
      [model, fit](py::handle points, const std::string& method, const std::string& loss, int max_iterations,
                   const std::string& units) {
        return DirectFit<Shape>(model, points, method, loss, max_iterations, units, fit);
      },
      py::arg("points"), py::arg("method") = "tdm", py::arg("loss") = "none", py::arg("max_iterations") = 200,
      py::arg("units") = "unknown", doc.c_str());
}

nlohmann::json PoseJson(const RigidMotion& pose) {
  return pipeline::ToJson(Eigen::Matrix4d(pose.matrix()));
}

}  // namespace

void BindFits(py::module_& m) {
  m.def(
      "fit",
      [](py::handle input, const std::string& model, const std::string& name, py::kwargs options) {
        const Input in = InputArg(input, name);
        const pipeline::FitOptions o = FitOptionsOf(in, model, options);
        FitResult result;
        py::gil_scoped_release release;
        pipeline::FitOutcome outcome = pipeline::ComputeFit(o);
        result.document = std::move(outcome.document);
        result.text = std::move(outcome.text);
        result.notes = std::move(outcome.notes);
        return result;
      },
      py::arg("input"), py::arg("model"), py::kw_only(), py::arg("name") = "<memory>",
      "Fits `model` as `scan2model fit --model MODEL INPUT --json` does, in-process (the same code, "
      "documents "
      "and messages). input: a path (any file fit reads), an N x 3 array, a Scan, a ScanSet or a list of "
      "Scan "
      "(views with their poses for revolution, helical, spiral and part:FILE). model: plane, sphere, "
      "cylinder, "
      "cone, line, circle, torus, bspline-curve, bspline-surface, hermite-curve, revolution, helical, "
      "spiral, "
      "part:FILE. name: how messages and the document name an input in memory. Options: the batch manifest's "
      "keys (docs/batch.md) as keywords, e.g. criterion='minzone', loss='tukey', control_points='8x6', "
      "closed=True, tolerance=0.5, max_iterations=50; and output='PREFIX' (PREFIX.json ...), "
      "history='h.csv'. "
      "Raises UsageError, InputError or FitError with the command's message.");

  DefineDirectFit<Plane>(m, "fit_plane", "plane",
                         [](const PointsRef& p, const PrimitiveFitOptions& o) { return FitPlane(p, o); });
  DefineDirectFit<Sphere>(m, "fit_sphere", "sphere",
                          [](const PointsRef& p, const PrimitiveFitOptions& o) { return FitSphere(p, o); });
  DefineDirectFit<Cylinder>(
      m, "fit_cylinder", "cylinder",
      [](const PointsRef& p, const PrimitiveFitOptions& o) { return FitCylinder(p, o); });
  DefineDirectFit<Cone>(m, "fit_cone", "cone",
                        [](const PointsRef& p, const PrimitiveFitOptions& o) { return FitCone(p, o); });
  DefineDirectFit<Line3d>(m, "fit_line", "line",
                          [](const PointsRef& p, const PrimitiveFitOptions& o) { return FitLine(p, o); });
  DefineDirectFit<Circle3d>(m, "fit_circle", "circle",
                            [](const PointsRef& p, const PrimitiveFitOptions& o) { return FitCircle(p, o); });
  DefineDirectFit<Torus>(m, "fit_torus", "torus",
                         [](const PointsRef& p, const PrimitiveFitOptions& o) { return FitTorus(p, o); });

  m.def(
      "detect",
      [](py::handle input, const std::vector<std::string>& models, int max_instances, int min_support,
         std::uint64_t seed, double epsilon, double alpha, const std::string& units, py::handle output,
         const std::string& name) {
        const Input in = InputArg(input, name);
        pipeline::DetectOptions o;
        o.file = in.file;
        o.views = in.views;
        o.models = models;
        o.max_instances = max_instances;
        o.min_support = min_support;
        o.seed = seed;
        o.epsilon = epsilon;
        o.alpha = alpha;
        o.units = units;
        if (!output.is_none()) o.output = PathArg(output, "output");
        DetectResult result;
        py::gil_scoped_release release;
        pipeline::DetectOutcome outcome = pipeline::ComputeDetect(o);
        result.document = std::move(outcome.document);
        result.text = std::move(outcome.text);
        result.notes = std::move(outcome.notes);
        return result;
      },
      py::arg("input"), py::arg("models"), py::kw_only(), py::arg("max_instances") = 10,
      py::arg("min_support") = 0, py::arg("seed") = 1, py::arg("epsilon") = 0.0, py::arg("alpha") = 0.0,
      py::arg("units") = "", py::arg("output") = py::none(), py::arg("name") = "<memory>",
      "Every instance of the models (plane, sphere, cylinder, cone, torus) among clutter, as `scan2model "
      "detect` "
      "(efficient RANSAC; docs/cli.md): scan2model.detect/1. min_support 0, epsilon 0, alpha 0: automatic. "
      "output: PREFIX for PREFIX_inliers.ply and PREFIX_rejected.ply.");

  m.def(
      "register_scans",
      [](py::handle views, const std::string& method, int max_sweeps, int samples_per_view,
         std::size_t fixed_view) {
        const ScanSet set = py::isinstance<Views>(views)
                                ? views.cast<const Views&>().ToScanSet()
                                : Views{"", views.cast<std::vector<std::shared_ptr<Scan>>>()}.ToScanSet();
        ScanToScanOptions options;
        options.error_term =
            method == "pdm"   ? ScanErrorTerm::kPdm
            : method == "tdm" ? ScanErrorTerm::kTdm
            : method == "sdm"
                ? ScanErrorTerm::kSdm
                : throw std::invalid_argument("method: '" + method + "' is not one of pdm, tdm, sdm");
        options.max_sweeps = max_sweeps;
        options.samples_per_view = samples_per_view;
        options.fixed_view = fixed_view;
        std::vector<Eigen::Matrix3Xd> points;
        std::vector<RigidMotion> poses;
        for (const Scan& s : set.scans) {
          points.push_back(s.points);
          poses.push_back(s.world_T_scan);
        }
        RegistrationResult result;
        py::gil_scoped_release release;
        const ScanToScanResult r = RegisterScansToEachOther(points, poses, options);
        nlohmann::json& j = result.document;
        j["method"] = method;
        j["views"] = set.scans.size();
        j["fixed_view"] = fixed_view;
        j["world_T_scan"] = nlohmann::json::array();
        for (const RigidMotion& pose : r.world_T_scan) j["world_T_scan"].push_back(PoseJson(pose));
        j["sweeps"] = r.sweeps;
        j["converged"] = r.converged;
        j["stalled"] = r.stalled;  // PDM only: settled short of the surfaces (scan_to_scan.h)
        j["rms_per_sweep"] = r.rms_per_sweep;
        j["unregistered_views"] = r.unconstrained_views;
        return result;
      },
      py::arg("views"), py::kw_only(), py::arg("method") = "tdm", py::arg("max_sweeps") = 50,
      py::arg("samples_per_view") = 1500, py::arg("fixed_view") = 0,
      "Scan-to-scan registration without a model (docs/registration.md): every view aligned to all the "
      "others from its pose, one view held fixed. method: pdm (point-to-point ICP), tdm (point-to-plane), "
      "sdm "
      "(Pottmann et al.'s squared-distance approximant). Returns the corrected poses; assign them to the "
      "scans' world_T_scan to use them. Views listed in unregistered_views overlap none of the views linked "
      "to the fixed one: their poses are not registered.");

  m.def(
      "run_batch",
      [](py::handle manifest_path, py::handle output_dir, int jobs, int threads_per_job, bool force,
         bool reports, bool progress) {
        const std::string manifest_file = PathArg(manifest_path, "manifest");
        pipeline::BatchOptions options;
        if (output_dir.is_none()) {
          const fs::path manifest_fs(manifest_file);
          options.output_dir =
              (manifest_fs.parent_path() / (manifest_fs.stem().string() + "_results")).string();
        } else {
          options.output_dir = PathArg(output_dir, "output_dir");
        }
        options.jobs = jobs;
        options.threads_per_job = threads_per_job;
        options.force = force;
        options.reports = reports;
        options.progress = progress;
        BatchResult result;
        py::gil_scoped_release release;
        pipeline::BatchManifest manifest;
        try {
          manifest = pipeline::ReadBatchManifest(manifest_file);
        } catch (const FormatError& e) {
          throw FitFailure(pipeline::kUsage, e.what());
        }
        std::vector<std::size_t> positions(manifest.objects.size());
        for (std::size_t k = 0; k < positions.size(); ++k) positions[k] = k;
        pipeline::BatchCounts counts;
        const std::vector<nlohmann::json> entries =
            pipeline::RunBatchObjects(manifest, positions, options, counts);
        pipeline::WriteBatchSummary(options.output_dir, "summary", manifest, entries);
        const fs::path summary = fs::path(options.output_dir) / "summary.json";
        std::ifstream in(summary);
        result.document = nlohmann::json::parse(in);
        result.run = {{"computed", counts.computed},
                      {"skipped", counts.skipped},
                      {"ok", counts.ok},
                      {"failed", counts.failed},
                      {"not_started", counts.not_started},
                      {"output_dir", options.output_dir}};
        result.text = "[batch] " + std::to_string(entries.size()) + " objects: " + std::to_string(counts.ok) +
                      " ok, " + std::to_string(counts.failed) + " failed; summary: " + summary.string() +
                      "\n";
        return result;
      },
      py::arg("manifest"), py::kw_only(), py::arg("output_dir") = py::none(), py::arg("jobs") = 0,
      py::arg("threads_per_job") = 0, py::arg("force") = false, py::arg("reports") = false,
      py::arg("progress") = false,
      "Runs a batch manifest (CSV or scan2model.batch/1 JSON; docs/batch.md) as `scan2model batch`: objects "
      "in "
      "parallel, resumable (finished objects are skipped unless force), OUTPUT/objects/<id>.json per object "
      "and "
      "OUTPUT/summary.json and .csv. output_dir: default MANIFEST_results beside the manifest.");

  m.def(
      "report_html",
      [](py::handle document) {
        const nlohmann::json j =
            py::isinstance<Result>(document) ? document.cast<const Result&>().document : FromPython(document);
        py::gil_scoped_release release;
        return pipeline::ReportHtml(j);
      },
      py::arg("result"),
      "The self-contained HTML report (docs/batch.md) of a fit result, a fit document (dict) or a batch "
      "object "
      "record, as `scan2model report` writes it. Raises UsageError for other documents.");
  m.def(
      "write_report",
      [](py::handle document, py::handle path) {
        const std::string file = PathArg(path, "path");
        const nlohmann::json j =
            py::isinstance<Result>(document) ? document.cast<const Result&>().document : FromPython(document);
        py::gil_scoped_release release;
        pipeline::WriteTextAtomically(file, pipeline::ReportHtml(j));
      },
      py::arg("result"), py::arg("path"), "Writes report_html(result) to `path` (atomically).");
  m.def(
      "write_json",
      [](const Result& result, py::handle path) {
        const std::string file = PathArg(path, "path");
        py::gil_scoped_release release;
        pipeline::WriteTextAtomically(file, result.document.dump(2) + "\n");
      },
      py::arg("result"), py::arg("path"),
      "Writes the result's document as `scan2model fit -o PREFIX` writes PREFIX.json (atomically).");
  m.def(
      "fit_option_keys", [] { return pipeline::ManifestOptionKeys(); },
      "The option keywords fit() takes besides output and history (the batch manifest's keys).");
}

}  // namespace s2m::python
