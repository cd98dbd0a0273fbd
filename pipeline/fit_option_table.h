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

// The models of `scan2model fit`; returns an empty string for a model it knows, else why not.
std::string ModelError(const std::string& model);

}  // namespace s2m::pipeline
