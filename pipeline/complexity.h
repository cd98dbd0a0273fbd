#pragma once
// `--control-points auto|auto:MAX|N|NUxNV` (docs/cli.md) and the report of the automatic model complexity
// (fitting/model_complexity.h, docs/method.md section 18): the `complexity` member of the spline and
// multi-view results and its text block.

#include <nlohmann/json.hpp>
#include <string>

#include "fitting/model_complexity.h"

namespace s2m::pipeline {

struct ControlPointRequest {
  bool automatic = true;
  int first = 0, second = 0;  // the given count (curve, generatrix: first; surface: first x second)
  int max = 0;                // automatic: the largest count (per direction for surfaces); 0: the default
};
// "" and "auto" (the default), "auto:MAX", "N" (curves, generatrices) or "NUxNV" (surfaces). Throws
// std::invalid_argument naming the accepted spellings.
ControlPointRequest ParseControlPoints(const std::string& text, bool surface);

// {"mode": "auto"|"fixed", "chosen": "14", "stop_reason", "criterion": "bic", "significance",
//  "noise_estimate", "noise_dof", "steps": [{"control_points", "parameters", "points", "rms", "bic",
//  "band_rms", "adequate", "iterations"}]} (unknown values as null).
nlohmann::json ComplexityJson(const ComplexityChoice& choice, const ComplexityOptions& options);
// The "control points" block of the text output: the chosen count, and with several steps their table.
std::string ComplexityText(const ComplexityChoice& choice);

}  // namespace s2m::pipeline
