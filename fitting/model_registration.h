#pragma once
// Registration of scans to a fixed model (docs/method.md section 5): the model stays, each scan moves
// rigidly. Every iteration computes foot points of the scan's current points, builds the chosen error term at
// them, solves for the velocity (c, cbar) and applies it as the exact helical motion; points are re-expressed
// from the original scan every iteration, so no drift accumulates.

#include <Eigen/Core>
#include <functional>
#include <vector>

#include "fitting/fit_result.h"
#include "fitting/geometric_fit.h"
#include "fitting/optimizer_options.h"
#include "fitting/parametric_model.h"
#include "fitting/squared_distance_field.h"
#include "registration/rigid_motion.h"
#include "registration/scan.h"

namespace s2m {

// Registration's minimizer settings (fitting/minimizer.h), the values its own loop always used: at most 100
// iterations (both phases together); Levenberg-Marquardt on the 6 x 6 system from damping 1e-6 (x 10 on a
// rejected step, x 0.1 on an accepted one, kept in [1e-12, 1e12]), the true RMS re-evaluated at every trial;
// StepStrategy::kFullStep takes the undamped step whatever the RMS does (plain ICP / point-to-plane as
// usually run). No objective and no gradient test (0): registration stops on its own step test, a rotation
// and a translation (rotation_tolerance, translation_tolerance below; optimizer.step_tolerance is not used).
// target_rms (input units) and the robust loss (optimizer.loss; scale in input units, 0: from the normal
// distances at every linearization) apply as documented there.
inline OptimizerOptions ModelRegistrationOptimizerDefaults() {
  OptimizerOptions o;
  o.max_iterations = 100;
  o.objective_tolerance = 0.0;
  o.gradient_tolerance = 0.0;
  o.damping.initial = 1e-6;
  o.damping.min = 1e-12;
  o.damping.max = 1e12;
  return o;
}

struct ModelRegistrationOptions {
  ErrorTerm error_term =
      ErrorTerm::kSdm;  // pdm (ICP), tdm (point-to-plane), sdm; cdm, gtdm and gn also accepted
  OptimizerOptions optimizer = ModelRegistrationOptimizerDefaults();
  double rotation_tolerance = 1e-12;     // stop when the step's rotation (rad) ...
  double translation_tolerance = 1e-12;  // ... and translation (relative to the scan's size) fall below these
  // A precomputed squared distance field of the SAME model (null: off, every foot exact). When given, the
  // iterations first use its O(1) approximants of d^2 (squared_distance_field.h; Mitra, Gelfand, Pottmann,
  // Guibas, SGP 2004) for the points inside its band (exact feet for the others) until a step moves the scan
  // by less than field_step_tolerance (rotation in rad, translation relative to the scan's size) or no longer
  // decreases the approximate RMS; then up to exact_final_iterations iterations with exact feet (Newton
  // from the field's foot parameters, then from the previous exact feet with their geometry), so the
  // final pose and residuals are the model's exact ones
  // (0: no exact step, only the exact feet at the field's final pose for the residuals). The field's accuracy
  // is set by its cell size. A lazy field (SquaredDistanceField::Options::lazy) gains the cells the scan
  // visits as the registration goes (hence not const); one field may serve many scans of the model in turn,
  // not at the same time.
  SquaredDistanceField* squared_distance_field = nullptr;
  double field_step_tolerance = 1e-7;
  int exact_final_iterations = 1;
  // Called after every accepted iteration with its number (from 1) and the RMS distance of the scan's points
  // to the model there (input units; approximate in the field phase); may be empty.
  std::function<void(int iteration, double rms)> progress;
};

struct ModelRegistrationResult {
  RigidMotion model_T_scan;  // maps the scan's original coordinates onto the model
  ResidualStatistics residuals;
  int iterations = 0;
  StopReason stop_reason = StopReason::kMaxIterations;
  std::vector<IterationRecord> history;
  std::vector<RigidMotion> pose_history;  // model_T_scan after each iteration (history[i]'s pose)
  int field_iterations = 0;               // of `iterations`, those with the squared distance field
  // The robust loss's scale at the solution, input units (the given one or the last estimate from the
  // data); 0 for plain least squares.
  double loss_scale = 0.0;
};

// Registers `scan_points` (3 x n, scan coordinates) to `model` starting from `initial` (model_T_scan).
ModelRegistrationResult RegisterToModel(const ParametricModel& model, const Eigen::Matrix3Xd& scan_points,
                                        const RigidMotion& initial,
                                        const ModelRegistrationOptions& options = {});

// `options` whose progress tells `also` as well (after its own, when it has one): one registration's
// iterations labelled by a caller that runs several (a view, a stage).
ModelRegistrationOptions WithProgress(ModelRegistrationOptions options,
                                      std::function<void(int iteration, double rms)> also);

// Registers every scan of the set independently to the model, which is placed in the world by world_T_model;
// each scan's world_T_scan is updated (accumulated) in place. Returns one result per scan. `progress` (may be
// empty) is told every iteration of every scan with the scan's index (options.progress, when set, as well).
// Throws RegisterToModel's std::invalid_argument with the failing scan's index ("scan 2: ...").
std::vector<ModelRegistrationResult> RegisterScansToModel(
    const ParametricModel& model, const RigidMotion& world_T_model, ScanSet& scans,
    const ModelRegistrationOptions& options = {},
    const std::function<void(std::size_t scan, int iteration, double rms)>& progress = {});

// How well a fixed surface holds a rigid body through points x_i on it with unit normals n_i: the smallest
// eigenvalue of the point-to-plane normal matrix sum a_i a_i^T, a_i = [(x_i - c) x n_i / r; n_i] (c the
// points' centroid, r their RMS distance from it, so rotations and translations are on one scale), over its
// largest (docs/method.md section 5). 0 when a motion leaves every point on its tangent plane (a plane leaves
// three, a sphere three rotations, a cylinder the rotation about and the translation along its axis); a ratio
// 1e-3 means the worst determined motion is sqrt(1000) = 32 times less well determined than the best one.
// Returns 0 for fewer than 6 points or points that coincide. points and normals: 3 x n.
double PoseConditioning(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals);

}  // namespace s2m
