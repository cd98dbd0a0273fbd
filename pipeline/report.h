#pragma once
// `scan2model report`: a self-contained HTML report of one fit (no scripts, no network; plots as inline SVG):
// parameter table with uncertainties, model adequacy, convergence (RMS per iteration, log scale), residual
// histogram, the data coloured by signed deviation from the model, per-view pose corrections, and the
// vessel's profile drawing for surfaces of revolution. docs/batch.md.

#include <nlohmann/json.hpp>
#include <string>

namespace s2m::pipeline {

// The report of a fit document (any schema of `scan2model fit --json`) or of a batch object record
// (scan2model.batch_object/1, which may also be a failure). Throws std::invalid_argument for other documents.
std::string ReportHtml(const nlohmann::json& document);

}  // namespace s2m::pipeline
