#pragma once
// The options of a fit, in one table: `scan2model fit`'s flags (apps/fit_command.cpp) and the batch
// manifest's keys (pipeline/batch.cpp) are both generated from it, so that a new option, a default or an
// accepted value is stated once. docs/cli.md and docs/batch.md list them.

#include <functional>
#include <string>
#include <vector>

#include "pipeline/fit_options.h"

namespace s2m::pipeline {

enum class FitOptionKind {
  kText,     // any string
  kPath,     // a file; a manifest resolves it against its own folder
  kInteger,  // within [min, max]
  kNumber,   // finite, within [min, max]
  kFlag,     // true or false (a manifest also takes 1 or 0); on the command line a flag without value
  kChoice,   // one of `choices`
};

struct FitOptionSpec {
  std::string key;    // manifest key or CSV column, e.g. "max_iterations"; empty: command line only
  std::string names;  // CLI11 names, e.g. "--max-iterations"; empty: manifest only
  FitOptionKind kind = FitOptionKind::kText;
  std::string default_text;  // shown in the help; empty: no default shown
  std::string help;
  std::vector<std::string> choices;  // kChoice
  // kChoice only: each choice is also a flag of its own, `--CHOICE` (e.g. --alternating); the first choice
  // (the default) excludes the others.
  bool choices_as_flags = false;
  double min = -1e300, max = 1e300;  // kInteger, kNumber
  // Sets the FitOptions member from a value already checked by ParseFitOption.
  std::function<void(FitOptions&, const std::string&)> set;
  // kText only: throws std::invalid_argument naming the accepted spellings when `text` is not one (empty:
  // any).
  std::function<void(const std::string&)> check = {};
};

// Every option of a fit but the input file and the model, in the order `fit --help` shows them.
const std::vector<FitOptionSpec>& FitOptionTable();
// The row of a manifest key, or nullptr.
const FitOptionSpec* FindManifestOption(const std::string& key);
// The manifest keys, comma-separated (for error messages).
std::string ManifestOptionKeys();

// Checks `text` against the row (kind, range, choices) and returns it normalized ("1" -> "true" for flags);
// throws std::invalid_argument with a message naming the option and the accepted values.
std::string ParseFitOption(const FitOptionSpec& option, const std::string& text);
// ParseFitOption, then the row's setter.
void ApplyFitOption(const FitOptionSpec& option, const std::string& text, FitOptions& options);

// What kind of input a fit reads, for the default robust loss (docs/cli.md "--loss", docs/method.md
// section 17): recordings, device frames and organized depth clouds carry flying pixels and mixed edges;
// certified reference data must be fitted by plain least squares, as certified.
enum class InputKind {
  kCertified,       // NIST .ds reference data
  kRecording,       // a .s2mrec recording (device frames replayed)
  kDeviceFrame,     // a depth image back-projected (file:depth-frame) or a live device's frames
  kOrganizedCloud,  // an organized point cloud (a PCD with HEIGHT > 1: a depth camera's pixel grid)
  kPointFile,       // any other point file or views manifest
};
const char* ToString(InputKind kind);
// From the file's name and the device its first scan names (Scan::metadata.device: "file",
// "file:organized", "file:depth-frame", "virtual:...", a recording's device).
InputKind ClassifyInput(const std::string& file, const std::string& device);
// The loss a fit uses: the given one, or the default for the input's kind: Cauchy with the MAD scale for
// recordings, device frames and organized clouds; none for certified data and other point files. Sets
// `options.loss` and `options.loss_reason` (e.g. "default for recordings (flying pixels and mixed edges)").
void ResolveDefaultLoss(FitOptions& options, InputKind kind);

// The models of `scan2model fit`; returns an empty string for a model it knows, else why not.
std::string ModelError(const std::string& model);

}  // namespace s2m::pipeline
