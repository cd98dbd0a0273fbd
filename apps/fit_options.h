#pragma once
// Options of `scan2model fit`, shared by the primitive and the spline paths.

#include <string>

#include "registration/scan.h"

namespace s2m::app {

struct FitOptions {
  std::string file;
  std::string model;
  std::string method;  // default per model family: tdm for primitives, sdm for splines
  std::string reference;
  std::string history;
  std::string units;
  int max_iterations = 200;
  bool json = false;
  bool verbose = false;            // print the per-iteration history table
  bool joint = false;              // multi-view: the joint method, stated explicitly (it is the default)
  bool alternating = false;        // multi-view: the alternating baseline instead of the joint method
  bool register_then_fit = false;  // multi-view: one shared motion only (fit the pre-registered cloud)
  // Splines.
  std::string control_points;  // curve: "N"; surface: "NUxNV"
  int order = 4;
  bool closed = false;  // closed (periodic) curve; for surfaces: periodic in u over a fitted cylinder
  double stretch = 0.0;
  double bending = 1e-3;
  std::string step_control = "lm";
  std::string output;   // prefix for PREFIX.json, PREFIX.ply, PREFIX_history.csv
  int contour = 0;      // .glif inputs: which contour
  std::string initial;  // a scan2model.bspline/1 JSON to start from instead of the automatic initial model
};

// Runs a B-spline curve or surface fit; returns the exit code.
int RunSplineFit(const FitOptions& options);
// Runs a joint multi-view fit (surface of revolution); returns the exit code.
int RunMultiViewFit(const FitOptions& options);
// Runs a joint multi-view fit of a constrained part (`--model part:FILE`, docs/parts.md); returns the exit
// code.
int RunPartFit(const FitOptions& options);

}  // namespace s2m::app
