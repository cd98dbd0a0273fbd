#pragma once
// `scan2model inspect` (docs/metrology.md sections 5-9, docs/cli.md): scan views against a nominal mesh.
// Reads the nominal (acquisition/mesh_io.h) and the views (pipeline/views.h), registers them to the nominal
// (fitting/nominal_inspection.h), measures the characteristics a checks file names (profile of a surface,
// flatness of a face, position and diameter of a bore) with their uncertainties (linear propagation or Monte
// Carlo, fitting/measurement_uncertainty.h) and ISO 14253-1 decisions, and writes the metrology report as
// JSON (scan2model.inspection/1) and HTML with the same content, with a traceability block.

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

namespace s2m::pipeline {

struct InspectOptions {
  std::string nominal;              // STL, OBJ or PLY mesh
  std::string input;                // the views: a cloud, views.json, recording or E57
  std::string checks;               // a scan2model.checks/1 file (empty: deviations only)
  std::string output;               // PREFIX: PREFIX.json, PREFIX.html, PREFIX_deviations.csv
  std::string units;                // the nominal's units when its file has none (default: the views')
  std::string method = "sdm";       // registration's error term: sdm, tdm or pdm
  std::vector<std::string> datums;  // face groups to align on (overrides the checks file's "datums")
  bool per_view = true;
  std::string uncertainty = "linear";  // none | linear | monte-carlo:N
  std::uint64_t seed = 1;
  std::string operator_name;  // the traceability block's operator (empty: null)
  std::string software_version = "unknown";
  bool json = false;
};

// One characteristic of a checks file.
struct CheckSpec {
  std::string name;
  std::string type;                 // profile, flatness, position, diameter, distance
  std::string group;                // the nominal's face group it applies to
  std::string to;                   // distance: the other feature's face group
  double tolerance = 0.0;           // profile, flatness, position: the zone's width
  std::optional<double> nominal;    // diameter, distance: the nominal size (default: the nominal mesh's)
  double lower = 0.0, upper = 0.0;  // diameter, distance: deviations allowed from the nominal
};

struct ChecksFile {
  std::string part;
  std::vector<std::string> datums;
  std::vector<CheckSpec> checks;
};
// Parses a scan2model.checks/1 document (docs/metrology.md section 5); `file` names it in errors. Throws
// FormatError naming the file, the check and the problem.
ChecksFile ParseChecksFile(const std::string& text, const std::string& file);

struct InspectOutcome {
  nlohmann::json document;  // scan2model.inspection/1
  std::string text;
  std::string html;
  std::vector<std::string> notes;
};

// Runs the inspection; writes PREFIX.json, PREFIX.html and PREFIX_deviations.csv when `output` is set.
// Throws FitFailure (pipeline/fit_options.h) with the exit code: kUsage, kInputError, kFitError.
InspectOutcome ComputeInspection(const InspectOptions& options);

// The HTML report of a scan2model.inspection/1 document (self-contained, inline SVG).
std::string InspectionHtml(const nlohmann::json& document);

}  // namespace s2m::pipeline
