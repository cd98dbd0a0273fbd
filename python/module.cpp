// The Python module `scan2model` (pybind11): the pipeline library (pipeline/, docs/pipeline.md) in-process,
// points as NumPy arrays read in place. docs/python.md.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <stdexcept>

#include "acquisition/format_error.h"
#include "fitting/primitive_fit.h"
#include "pipeline/exit_code.h"
#include "pipeline/fit_options.h"
#include "python/bindings.h"
#include "python/json_object.h"
#include "python/points.h"

namespace s2m::python {
namespace {

using pipeline::FitFailure;

py::object NewException(py::module_& m, const char* name, const char* doc, py::handle bases) {
  const std::string qualified = std::string("scan2model.") + name;
  PyObject* type = PyErr_NewExceptionWithDoc(qualified.c_str(), doc, bases.ptr(), nullptr);
  if (!type) throw py::error_already_set();
  auto object = py::reinterpret_steal<py::object>(type);
  m.attr(name) = object;
  return object;
}

// Kept for the module's lifetime (the module holds them too).
py::handle error_type, usage_type, input_type, fit_type;

void Raise(py::handle type, const std::string& message, int exit_code) {
  py::object instance = py::reinterpret_borrow<py::object>(type)(message);
  instance.attr("exit_code") = exit_code;
  PyErr_SetObject(type.ptr(), instance.ptr());
}

}  // namespace

void BindErrors(py::module_& m) {
  py::object error = NewException(m, "Error",
                                  "A scan2model failure; `exit_code` is the command's exit code for it "
                                  "(docs/cli.md) and the message is the command's.",
                                  PyExc_RuntimeError);
  py::object usage = NewException(m, "UsageError", "Bad options or arguments (exit code 2).",
                                  py::make_tuple(error, py::handle(PyExc_ValueError)));
  py::object input =
      NewException(m, "InputError",
                   "An unreadable, corrupt, empty or degenerate input (exit code 3); the message "
                   "names the file, the line or byte, and the problem.",
                   py::make_tuple(error, py::handle(PyExc_OSError)));
  py::object fit = NewException(m, "FitError", "The fit could not be computed (exit code 4).", error);
  error_type = error.release();
  usage_type = usage.release();
  input_type = input.release();
  fit_type = fit.release();
  py::object warning = NewException(m, "ConversionWarning",
                                    "An array of points was copied and converted to N x 3 float64 "
                                    "C-contiguous (the layout the fits read in place).",
                                    PyExc_UserWarning);
  SetConversionWarning(warning.release());

  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const FitFailure& e) {
      const int code = e.exit_code();
      Raise(code == pipeline::kUsage        ? usage_type
            : code == pipeline::kInputError ? input_type
            : code == pipeline::kFitError   ? fit_type
                                            : error_type,
            e.what(), code);
    } catch (const FormatError& e) {
      Raise(input_type, e.what(), pipeline::kInputError);
    } catch (const s2m::FitError& e) {
      Raise(fit_type, e.what(), pipeline::kFitError);
    } catch (const std::invalid_argument& e) {
      Raise(usage_type, e.what(), pipeline::kUsage);
    }
  });
}

void BindResults(py::module_& m) {
  py::class_<Result>(m, "Result",
                     "A result document of the pipeline (the JSON Schema its `schema` member names, in "
                     "docs/schemas/), the text `scan2model` prints and the readers' notes.")
      .def(
          "to_dict", [](const Result& r) { return ToPython(r.document); },
          "The document as dicts and lists: the same members and values as the command's --json output.")
      .def(
          "to_json", [](const Result& r, int indent) { return r.document.dump(indent); },
          py::arg("indent") = 2, "The document as JSON text (as `scan2model ... --json` prints it).")
      .def_property_readonly(
          "schema", [](const Result& r) { return r.document.value("schema", std::string()); },
          "The document's schema, e.g. 'scan2model.fit/1'.")
      .def_property_readonly(
          "text", [](const Result& r) { return r.text; }, "The readable text `scan2model` prints.")
      .def_property_readonly(
          "notes", [](const Result& r) { return r.notes; }, "What the readers did to the data.")
      .def("__repr__", [](py::object self) {
        const Result& r = self.cast<const Result&>();
        std::string repr = "<scan2model." + std::string(py::str(py::type::of(self).attr("__name__")));
        if (r.document.contains("schema")) repr += " " + r.document["schema"].get<std::string>();
        if (r.document.contains("model") && r.document["model"].is_string())
          repr += " model=" + r.document["model"].get<std::string>();
        return repr + ">";
      });

  const auto member = [](const char* key) {
    return [key](const Result& r) {
      return r.document.contains(key) ? ToPython(r.document[key]) : py::object(py::none());
    };
  };
  py::class_<FitResult, Result>(m, "FitResult",
                                "The result of fit(): scan2model.fit/1 (primitives), bspline/1, hermite/1, "
                                "multiview/1 or part_fit/1.")
      .def_property_readonly("model", member("model"), "The model fitted.")
      .def_property_readonly("parameters", member("parameters"),
                             "The fitted parameters by name (None if the "
                             "document has none).")
      .def_property_readonly("uncertainties", member("uncertainties"), "Standard uncertainties by parameter.")
      .def_property_readonly("residuals", member("residuals"), "count, rms, max_abs, mean (input units).")
      .def_property_readonly("adequacy", member("adequacy"), "The model-adequacy verdict and its evidence.")
      .def_property_readonly("iterations", member("iterations"), "Solver iterations.")
      .def_property_readonly("stop_reason", member("stop_reason"), "Why the solver stopped.");
  py::class_<PrimitiveFitResult, Result>(
      m, "PrimitiveFitResult",
      "A direct primitive fit (fit_plane, fit_sphere, ...): the members of scan2model.fit/1 the fit alone "
      "gives (model, method, parameters, nist_layout, uncertainties, residuals, iterations, stop_reason, "
      "history).")
      .def_property_readonly("model", member("model"))
      .def_property_readonly("parameters", member("parameters"))
      .def_property_readonly("uncertainties", member("uncertainties"))
      .def_property_readonly("residuals", member("residuals"))
      .def_property_readonly("iterations", member("iterations"))
      .def_property_readonly("stop_reason", member("stop_reason"));
  py::class_<DetectResult, Result>(m, "DetectResult", "The result of detect(): scan2model.detect/1.")
      .def_property_readonly("instances", member("instances"),
                             "The detected instances, largest support first.");
  py::class_<RegistrationResult, Result>(m, "RegistrationResult",
                                         "The result of register_scans(): the corrected poses.")
      .def_property_readonly(
          "world_T_scan",
          [](const RegistrationResult& r) {
            py::list poses;
            for (const nlohmann::json& pose : r.document["world_T_scan"]) {
              py::array_t<double> a({4, 4});
              auto v = a.mutable_unchecked<2>();
              for (int i = 0; i < 4; ++i)
                for (int k = 0; k < 4; ++k) v(i, k) = pose[i][k].get<double>();
              poses.append(a);
            }
            return poses;
          },
          "One 4 x 4 pose per view (maps scan coordinates to world coordinates).")
      .def_property_readonly("rms_per_sweep", member("rms_per_sweep"))
      .def_property_readonly("converged", member("converged"))
      .def_property_readonly("stalled", member("stalled"),
                             "PDM only: its steps settled while the point-to-plane step of its pairs did not "
                             "(not converged).")
      .def_property_readonly(
          "unregistered_views", member("unregistered_views"),
          "Views whose poses the overlap does not determine (empty when all are registered).");
  py::class_<BatchResult, Result>(m, "BatchResult",
                                  "The result of run_batch(): its summary (scan2model.batch_summary/1, as "
                                  "written to OUTPUT/summary.json) and what this run did.")
      .def_property_readonly("entries", member("objects"), "One summary entry per object, in manifest order.")
      .def_property_readonly("counts", member("counts"), "objects, ok, error, missing, adequate, inadequate.")
      .def_property_readonly(
          "run", [](const BatchResult& r) { return ToPython(r.run); },
          "This run: computed, skipped, ok, failed, not_started.");
}

}  // namespace s2m::python

PYBIND11_MODULE(_scan2model, m) {
  namespace python = s2m::python;
  m.doc() =
      "scan2model: fits of models to point clouds (primitives, B-splines, Hermite curves, surfaces of "
      "revolution, "
      "helical and spiral surfaces, constrained parts) with the poses of several views, registration, "
      "detection, recordings, E57 files, batches and reports. Points are N x 3 float64 NumPy arrays, read in "
      "place. docs/python.md.";
  m.attr("__version__") = S2M_VERSION;
  python::BindErrors(m);
  python::BindResults(m);
  python::BindIo(m);
  python::BindFits(m);
}
