#pragma once
// The boundary of an n-sided patch given as fitted boundary curves (docs/fe-surfaces.md section 6a): cubic
// Hermite curves from `fit --model hermite-curve` documents (scan2model.hermite/1), chained end to end into a
// loop, and the domain polygon they define (L. Fang, MIT PhD thesis 1994, section 4.3): one straight side per
// curve with the curve's arc length, turns from the angles between the curves where they meet, closed by the
// method of multipliers (fitting/polygon_closure.h), the curves' nodes on the sides in proportion to their
// parameters so that the surface conforms to the curves exactly (eq. P12).

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "fitting/domain_mesh.h"
#include "fitting/fe_surface_fit.h"
#include "fitting/hermite_curve.h"
#include "fitting/polygon_closure.h"

namespace s2m::pipeline {

struct CurvedBoundary {
  std::vector<std::string> files;
  std::vector<HermiteCurve> sides;  // oriented along the loop, their shared corners made to coincide
  std::vector<double> lengths;      // the curves' arc lengths (the sides' lengths)
  std::vector<double> turns;        // theta_i^0: the turn from curve i to curve i + 1 in the loop's plane
  std::vector<double> corner_gaps;  // how far apart the curves' ends were at each corner (after curve i)
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // of the loop's best plane, the loop counter-clockwise
  PolygonClosure closure;
  DomainPolygon polygon;  // the closed polygon's corners and the curves' nodes between them

  // The curves at a point of the polygon's boundary (fitting/fe_surface_fit.h FeBoundaryTrace).
  FeBoundaryTrace Trace() const;
  // {curves: [{file, arc_length, elements, turn_deg, closed_turn_deg, gap_after}], normal, closure {...}}.
  nlohmann::json ToJson() const;
};

// Whether a --boundary value names boundary curves: a .json document, or several files separated by commas.
bool IsCurveBoundary(const std::string& boundary);

// Reads the curves of `boundary` (comma-separated scan2model.hermite/1 documents, in their order round the
// loop, each either way round) and builds the polygon. Throws FitFailure: kInputError for unreadable or
// unsuitable documents (not cubic, not 3-D, closed), kFitError for curves that do not form a loop (fewer than
// 3, ends more than 5 % of the shorter curve's length apart, turns that do not sum to one turn) or whose
// polygon cannot close.
CurvedBoundary ReadCurvedBoundary(const std::string& boundary);

}  // namespace s2m::pipeline
