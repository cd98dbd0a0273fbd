#pragma once
// Shared by the multi-view fits of `scan2model fit` (surface of revolution, constrained part): reading the
// views, the joint solver's options from the command line, and reporting per-view results and the solver's
// run.

#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "fitting/joint_fit.h"
#include "pipeline/fit_options.h"
#include "registration/scan.h"

namespace s2m::pipeline {

// A scan2model.views/1 manifest (.json), Stanford .conf, recording or E57 file (each data3D scan a view with
// its pose); any other file is read as one cloud, one view in world coordinates. Throws FormatError.
ScanSet ReadViews(const std::string& file);
// The views of a fit: options.views when given in memory, else ReadViews(options.file) kept in `storage`.
const ScanSet& InputViews(const FitOptions& options, ScanSet& storage);
// One cloud of an input: the only view of `views` (in memory) as it is when its pose is the identity, else
// the views merged in the world frame with the first view's units and metadata (a views manifest or recording
// named by `file` likewise). nullopt when `views` is null and `file` is a point file (E57 included) the
// caller reads itself.
std::optional<Scan> InputCloud(const std::string& file, const ScanSet* views);

// Where a joint fit's model frame lies in the data's world. The fit fixes the views only relative to each
// other and to the model; the model is placed so that the views' pose corrections average to zero (the
// least total correction: no single device pose is trusted more than the others).
RigidMotion PlaceModelInWorld(const ScanSet& set, const std::vector<RigidMotion>& model_T_scan);

// Unit normals of each view in its own coordinates (local plane fits over 12 neighbours), for deciding which
// points lie off a fitted surface; a view too small for them gets none (distance test only).
std::vector<Eigen::Matrix3Xd> ViewNormals(const ScanSet& set);

// The members every scan2model.multiview/1 document opens with: schema, input, model, method, solver, loss
// (with the loss' scale at the solution and the reason it was chosen) and axis (world frame).
nlohmann::json MultiViewDocumentHead(const FitOptions& o, const ScanSet& set, const JointFitOptions& options,
                                     double loss_scale, const Eigen::Vector3d& axis_point,
                                     const Eigen::Vector3d& axis_direction, const std::string& units);

// The error term (default tdm), iteration cap and solver variant (joint, alternating, register-then-fit).
// Throws std::invalid_argument for a method the joint solver does not know.
JointFitOptions JointOptions(const FitOptions& o);
// "joint", "alternating" or "register-then-fit".
std::string SolverName(const JointFitOptions& options);

// One entry per view: source, points, RMS and max over the points fitted, the corrected `world_T_scan`
// (4x4 row-major), its correction relative to the recorded pose (rotation angle in degrees, translation
// length) and, when known, the pose uncertainty (rotation about x, y, z in degrees; translation).
nlohmann::json ViewsJson(const ScanSet& set, const std::vector<RigidMotion>& world_T_scan,
                         const JointFitResult& result);
// The text table of those entries.
std::string ViewsTable(const nlohmann::json& views);

// The solver's members of a result document: residuals, iterations, shared_iterations, stop_reason,
// unobservable, seconds, history.
void AddSolverJson(nlohmann::json& j, const JointFitResult& result, double seconds);
// The solver line of the text output ("joint registration and fitting, tdm, 23 iterations ...").
std::string SolverSummary(const JointFitOptions& options, const JointFitResult& result, double seconds);
// "\n  unobservable: a; b;\n" when directions are unobservable, else "".
std::string UnobservableText(const JointFitResult& result);
// Writes PREFIX.json (with -o) and the history CSV (with --history) when asked.
void WriteRequestedFiles(const FitOptions& o, const nlohmann::json& document, const JointFitResult& result);

}  // namespace s2m::pipeline
