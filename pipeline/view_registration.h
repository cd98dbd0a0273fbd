#pragma once
// `scan2model register` (docs/cli.md, docs/method.md section 5): the views of a part registered from the
// command line, either to each other (all views globally, no model: registration/scan_to_scan.h), to a
// nominal mesh (fitting/nominal_inspection.h's registration steps) or to a part a fit measured
// (fitting/model_registration.h), written as a views manifest whose poses are the corrected world_T_scan,
// with every view's residuals.

#include <cstddef>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace s2m::pipeline {

struct RegisterOptions {
  std::string input;  // the views: views.json, Stanford .conf, recording (.s2mrec) or E57
  // Empty: scan-to-scan; a result document (.json): a constrained part's fit (scan2model.part_fit/1: the part
  // file with the fitted values) or a finite-element surface's (scan2model.fe-surface/1); else a nominal mesh
  // (.stl, .obj, .ply).
  std::string to;
  std::string method = "tdm";   // pdm, tdm or sdm
  std::string output;           // a views manifest (.json) to write, with one PLY per view beside it
  std::string units;            // the nominal's units when its file states none (default: the views')
  int samples_per_view = 1500;  // scan-to-scan: samples of each view that look for partners per sweep
  int max_sweeps = 50;          // scan-to-scan: at most this many sweeps
  std::size_t fixed_view = 0;   // scan-to-scan: the view that stays where it is (the gauge)
  bool per_view = true;         // to a nominal: after the common alignment, each view on its own
  bool json = false;
};

struct RegisterOutcome {
  nlohmann::json document;  // scan2model.registration/1
  std::string text;
  std::vector<std::string> notes;
  // Views whose poses the data do not determine (scan-to-scan: not linked to the fixed view by overlap; to
  // an FE surface: their points on the patch leave a motion free). ComputeRegistration writes no manifest
  // then, and the command exits with kFitError.
  std::vector<std::size_t> unregistered_views;
  std::string unregistered_reason;  // why, when not the scan-to-scan reason
};

// Progress lines for long runs ("sweep 3: RMS 0.00012 m"); may be empty.
using RegisterProgress = std::function<void(const std::string& line)>;

// Reads the views (and the nominal), registers them and, when `output` is set and every view is registered,
// writes the manifest. Throws FitFailure (pipeline/fit_options.h) with the exit code: kUsage for bad options,
// kInputError for unreadable or degenerate input, kFitError when the registration cannot be computed.
RegisterOutcome ComputeRegistration(const RegisterOptions& options, const RegisterProgress& progress = {});

}  // namespace s2m::pipeline
