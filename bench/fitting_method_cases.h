#pragma once
// The fitting-method comparison of docs/fitting-engine.md (docs/method.md section 11), shared by the
// fitting_methods report and the compare driver: each error term fits the same cases from the same start for
// a full budget; the common target is 5 % above the lowest RMS any method reaches.

#include <Eigen/Core>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "fitting/geometric_fit.h"

namespace s2m::bench {

struct FittingCase {
  std::string name;
  Eigen::MatrixXd points;
  std::function<std::unique_ptr<ParametricModel>()> start;
  double bending = 0.0;
  bool curve = true;
};

// Sparse non-uniform points on a circle, a square from a one-sided start, the glyph outlines of `glyphs`
// (skipped with a note on stderr when absent) and, with `with_surface`, a bumpy B-spline surface fitted from
// a flat start.
std::vector<FittingCase> FittingCases(const std::filesystem::path& glyphs, bool with_surface);

struct MethodRow {
  std::string case_name;
  ErrorTerm method = ErrorTerm::kSdm;
  double target_rms = 0.0;
  int iterations_to_target = -1;  // -1: not reached
  double seconds_to_target = 0.0;
  double seconds_per_iteration = 0.0;
  double lowest_rms = 0.0;
  int iterations_run = 0;
  std::vector<double> rms;  // after each iteration (rms[i] after iteration i + 1), for other targets
};

// Iterations `row` needed to reach RMS <= target (-1: not within its budget).
int IterationsTo(const MethodRow& row, double target_rms);

// Iterations one error term needs on case `c` to reach RMS <= target, within `budget` (-1: not reached).
int IterationsToRms(const FittingCase& c, ErrorTerm term, int budget, double target_rms);

// All six error terms on one case, `budget` iterations each.
std::vector<MethodRow> RunFittingMethods(const FittingCase& c, int budget);

}  // namespace s2m::bench
