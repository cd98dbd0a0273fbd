#pragma once
// The model families of the benchmark's cost table (docs/benchmarks.md section 4): for each family a known
// model seen from several views with about a requested number of points, and the model the joint fit starts
// from. One place for the cases, shared by the scaling rows (the 12-control-point vase) and the table of the
// cost per point per iteration of every family.

#include <memory>
#include <string>
#include <vector>

#include "fitting/joint_fit.h"
#include "fitting/parametric_model.h"
#include "synthetic/synthetic_cases.h"

namespace s2m::bench {

struct FamilyCase {
  std::string family;       // the table's name of the model family
  std::string description;  // the model and its views, one line
  std::unique_ptr<ParametricModel> start;
  SyntheticViews views;
  JointFitOptions options;  // the family's own settings; the benchmark sets the term and the iterations
};

// "revolution-12" (the scaling rows' vase: 12 control points, `views` views at 20 degrees), "sphere",
// "cylinder", "torus", "bspline-surface" (10 x 10 control points; `views` views each), and the reference
// cases of synthetic/synthetic_cases.h "vase", "helical", "spiral", "part", "freeform" (their own views).
std::vector<std::string> CostFamilyNames();

// One line naming the family's model (throws std::invalid_argument for an unknown family).
std::string FamilyDescription(const std::string& family);

// About `points` points in all (the views overlap: a point seen twice counts twice), noise 0.02 along the
// normal, recorded poses off by 0.5 degree and 0.5 (the reference cases: by their own errors), the shape 1 %
// off (the reference cases: their own starts). Throws std::invalid_argument for an unknown family.
FamilyCase MakeFamilyCase(const std::string& family, long long points, int views);

}  // namespace s2m::bench
