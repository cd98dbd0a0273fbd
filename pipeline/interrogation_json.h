#pragma once
// The JSON of a curve's interrogation (fitting/curve_interrogation.h; docs/cli.md "interrogation"): shared by
// the Hermite, B-spline curve and generatrix results, and drawn by the report (curvature, dkappa/ds, comb).

#include <nlohmann/json.hpp>

#include "fitting/curve_interrogation.h"

namespace s2m::pipeline {

// length, comb_scale, max_abs_kappa, zeta, dkappa_ds_squared, kappa_squared, curvature_extrema, inflections,
// max_g1, max_g2, junctions and the samples (s, u, kappa, dkappa_ds, point, comb_tip; torsion for space
// curves).
nlohmann::json InterrogationJson(const CurveInterrogation& q, int dimension);

}  // namespace s2m::pipeline
