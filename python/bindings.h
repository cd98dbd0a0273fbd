#pragma once
// What the parts of the Python module (module.cpp, io_bindings.cpp, fit_bindings.cpp) share: the result
// objects, the views of a multi-view input, and the conversion of the pipeline's errors (docs/python.md).

#include <pybind11/pybind11.h>

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "registration/scan.h"

namespace s2m::python {

namespace py = pybind11;

// A result: the document of the pipeline's JSON writers (the schema of docs/schemas/ its "schema" member
// names), the text `scan2model` prints, and the readers' notes. The Python classes FitResult,
// PrimitiveFitResult, DetectResult, RegistrationResult and BatchResult derive from it.
struct Result {
  nlohmann::json document;
  std::string text;
  std::vector<std::string> notes;
};
struct FitResult : Result {};
struct PrimitiveFitResult : Result {};
struct DetectResult : Result {};
struct RegistrationResult : Result {};
// The document is the summary written to OUTPUT/summary.json (scan2model.batch_summary/1); `run` counts
// what this run did: computed, skipped, ok, failed, not_started.
struct BatchResult : Result {
  nlohmann::json run;
};

// The views of a multi-view input as Python holds them: each Scan shared with Python (its points are viewed
// in place by NumPy), so that `views[k].points` stays valid while the set grows.
struct Views {
  std::string name;
  std::vector<std::shared_ptr<Scan>> scans;

  // A ScanSet for the pipeline (the scans copied).
  ScanSet ToScanSet() const;
  // From a ScanSet read by the pipeline (the scans moved, no copy).
  static Views FromScanSet(ScanSet&& set);
};

// Registers the exceptions (scan2model.Error and its subclasses) and the translator of the pipeline's errors:
// FitFailure by its exit code (UsageError 2, InputError 3, FitError 4), FormatError as InputError,
// s2m::FitError as FitError, std::invalid_argument as UsageError. The messages are those of `scan2model`.
void BindErrors(py::module_& m);
void BindResults(py::module_& m);
void BindIo(py::module_& m);
void BindFits(py::module_& m);

// A str or os.PathLike as a path string; throws py::type_error naming `what` otherwise.
std::string PathArg(py::handle object, const char* what);
bool IsPathLike(py::handle object);

}  // namespace s2m::python
