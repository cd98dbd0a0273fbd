#pragma once
// Registration of scans to a fixed model (METHOD.md section 5): the model stays, each scan moves rigidly.
// Every iteration computes foot points of the scan's current points, builds the chosen error term at them,
// solves for the velocity (c, cbar) and applies it as the exact helical motion; points are re-expressed from
// the original scan every iteration, so no drift accumulates.

#include <Eigen/Core>
#include <vector>

#include "fitting/fit_result.h"
#include "fitting/geometric_fit.h"
#include "fitting/parametric_model.h"
#include "registration/rigid_motion.h"
#include "registration/scan.h"

namespace s2m {

struct ModelRegistrationOptions {
  ErrorTerm error_term =
      ErrorTerm::kSdm;  // pdm (ICP), tdm (point-to-plane), sdm; cdm, gtdm and gn also accepted
  int max_iterations = 100;
  double rotation_tolerance = 1e-12;     // stop when the step's rotation (rad) ...
  double translation_tolerance = 1e-12;  // ... and translation (relative to the scan's size) fall below these
  double target_rms = 0.0;               // stop as soon as RMS <= target (0: off)
  bool damping = true;                   // Levenberg-Marquardt on the 6x6 system, true RMS re-evaluated
};

struct ModelRegistrationResult {
  RigidMotion model_T_scan;  // maps the scan's original coordinates onto the model
  ResidualStatistics residuals;
  int iterations = 0;
  StopReason stop_reason = StopReason::kMaxIterations;
  std::vector<IterationRecord> history;
  std::vector<RigidMotion> pose_history;  // model_T_scan after each iteration (history[i]'s pose)
};

// Registers `scan_points` (3 x n, scan coordinates) to `model` starting from `initial` (model_T_scan).
ModelRegistrationResult RegisterToModel(const ParametricModel& model, const Eigen::Matrix3Xd& scan_points,
                                        const RigidMotion& initial,
                                        const ModelRegistrationOptions& options = {});

// Registers every scan of the set independently to the model, which is placed in the world by world_T_model;
// each scan's world_T_scan is updated (accumulated) in place. Returns one result per scan.
std::vector<ModelRegistrationResult> RegisterScansToModel(const ParametricModel& model,
                                                          const RigidMotion& world_T_model, ScanSet& scans,
                                                          const ModelRegistrationOptions& options = {});

}  // namespace s2m
