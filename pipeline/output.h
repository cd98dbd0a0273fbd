#pragma once
// Shared output helpers for the command line: JSON documents and readable text.

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <string>

#include "fitting/fit_result.h"
#include "fitting/measurement_uncertainty.h"
#include "fitting/robust_loss.h"
#include "registration/scan.h"

namespace s2m::pipeline {

nlohmann::json ToJson(const Eigen::Vector3d& v);
nlohmann::json ToJson(const Eigen::Matrix4d& m);
// Three numbers in parentheses with `digits` significant digits.
std::string Format(const Eigen::Vector3d& v, int digits = 12);
std::string Format(double value, int digits = 12);
// Describes the input file: points, normals, units, bounds.
nlohmann::json DescribeScan(const Scan& scan, const std::string& file, const std::string& format);

// The per-iteration history as JSON (an array of objects) and as CSV (with a header line).
nlohmann::json HistoryJson(const std::vector<IterationRecord>& history);
// The robust loss of a fit: {"kind", "scale" (input units; estimated or given), "scale_from_data",
// "down_weighted" (points with IRLS weight < 0.5), "rejected" (weight 0)}; {"kind": "none"} for least
// squares.
nlohmann::json LossJson(const RobustLoss& loss, double scale, const Eigen::VectorXd& weights);
std::string HistoryCsv(const std::vector<IterationRecord>& history);
// The history as an aligned text table (iteration, RMS, max distance, damping, step, time).
std::string HistoryTable(const std::vector<IterationRecord>& history);
// Writes beside the target, fsyncs, then renames, so that a crash, a full disk or a power cut never leaves a
// half-written file under the final name (and a failed write leaves no partial file). Throws FormatError
// naming the file and the operating system's reason when it cannot be written.
void WriteTextAtomically(const std::string& path, const std::string& text);
// A failure: the message on standard error and, with --json, a scan2model.error/1 document on standard
// output.
int ReportError(const std::string& command, const std::string& message, int exit_code, bool json);

// A number for JSON, null when it is not finite (NaN: unknown; JSON has no NaN or infinity).
nlohmann::json NumberOrNull(double v);

// One derived quantity of a fit with its uncertainty by `method` (docs/metrology.md sections 6-8): the
// linear standard uncertainty expanded with k = 2, or, with `monte_carlo`, the Monte Carlo one with its 95 %
// interval (schema common.schema.json#/$defs/measurand).
nlohmann::json MeasurandJson(const std::string& name, double value, const std::string& unit,
                             const UncertaintyMethod& method, double linear_standard_uncertainty,
                             const MonteCarloSummary* monte_carlo);
// The text block of such quantities.
std::string MeasurandsText(const nlohmann::json& measurands);

}  // namespace s2m::pipeline
