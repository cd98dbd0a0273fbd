#pragma once
// Joint registration and fitting (docs/method.md section 6; Liu, Pottmann, Wang, CAD 38(6) 2006, section 5):
// one rigid motion per scan and the model's shape parameters are solved TOGETHER, one linear solve per
// iteration.
//
// Per iteration, with frames and error terms frozen at the current foot points, F = sum_k w_k sum_j e^T M e
// with e = x + cbar_k + c_k x x - s_+ is quadratic in (D, c_1, cbar_1, ..., c_K, cbar_K). Its normal matrix
// has block-arrow structure (shape block, one 6x6 block per scan, dense coupling); the scan blocks are
// eliminated by Schur complement, so the cost per iteration is linear in the number of points. Scans then
// move by their exact helical motions. Gauge: motion directions the model is invariant to
// (ParametricModel::InvariantMotions) are removed from every scan, and common motions a change of shape
// absorbs (CommonMotionsAbsorbedByShape) from the first scan only. Staging: all scans first share one motion
// (the initially registered cloud), then each scan gets its own.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "fitting/fit_result.h"
#include "fitting/geometric_fit.h"
#include "fitting/optimizer_options.h"
#include "fitting/parametric_model.h"
#include "fitting/part_model.h"
#include "registration/rigid_motion.h"

namespace s2m {

// The joint fit's minimizer settings (fitting/minimizer.h), the values its own loop always used: damping
// from 1e-6 (x 10 on a rejected step, x 0.1 on an accepted one, kept in [1e-12, 1e12]) relative to each
// block's diagonal, floored at 1e-9 of the block's largest diagonal entry (the motion blocks of a nearly
// invariant model have near-null directions); at most 100 accepted iterations, both stages together; stop
// (in stage 2) when the relative decrease falls below 1e-10. No gradient test and no step test (0): a
// joint step mixes shape parameters and motions, which no single step norm compares, and the objective test
// ends the fit first. target_rms (input units) and the robust loss (optimizer.loss; its scale a distance in
// input units, 0: from the normal distances at every linearization) apply as documented there.
inline OptimizerOptions JointFitOptimizerDefaults() {
  OptimizerOptions o;
  o.max_iterations = 100;
  o.objective_tolerance = 1e-10;
  o.step_tolerance = 0.0;
  o.gradient_tolerance = 0.0;
  o.damping.initial = 1e-6;
  o.damping.min = 1e-12;
  o.damping.max = 1e12;
  o.damping.diagonal_floor = 1e-9;
  return o;
}

struct JointFitOptions {
  ErrorTerm error_term = ErrorTerm::kSdm;
  // Termination, damping and robust loss (JointFitOptimizerDefaults). The alternating baseline runs two
  // minimizers with these settings, one per half-step, each keeping its own damping.
  OptimizerOptions optimizer = JointFitOptimizerDefaults();
  int shared_motion_iterations = 5;  // stage 1 length (0: start with per-scan motions)
  bool per_scan_motions = true;  // false: stay in stage 1, i.e. fit the initially registered cloud (baseline)
  // The alternating baseline of docs/method.md section 6: per iteration one registration step (motions only),
  // then one fitting step (shape only), instead of one joint step. Converges linearly (zig-zag).
  bool alternating = false;
  // Remove the gauge directions the model declares (default). Off, the solver runs on the full motions
  // (damping keeps it going) and reports the directions it could not observe, by name.
  bool remove_gauge = true;
  FairnessWeights fairness;  // on data scaled into the unit box
  bool scan_weights = true;  // w_k = 1 / N_k (each scan counts the same), else 1
  // Points to leave out, per scan (true: left out), fixed for the whole fit; empty: none. Overrides the
  // model's own per-iteration choice (AmbiguousFootPoint), which can settle differently from different
  // starts.
  std::vector<std::vector<bool>> left_out;
  // Assemble the next iteration's normal equations in the foot point pass that evaluates a trial, from the
  // model's geometry Newton ends with at each foot (default). Off: a separate assembly pass evaluates the
  // model at every foot again (the reference path; same results to rounding).
  bool reuse_foot_geometry = true;
  // Warm starts of the foot points after a step (foot_point.h): trusted (Newton straight from the previous
  // foot's parameter, no search for the nearest model sample; feet ending on an open boundary still compare
  // with the nearest sample) when no shape parameter and no motion component changed by more than this in
  // the step (data scaled into the unit box; radians), else verified (the better of the previous parameter
  // and the nearest sample). A small step moves the model and the points by about that much, far less than
  // the distance between two basins of the distance function on a smooth model, so the previous foot's basin
  // holds the new foot; a large shape step can move where a foot near an open end belongs (the reason the
  // fits verify). 0: always verified.
  double trusted_warm_start_step = 1e-2;
};

// Standard uncertainty of a scan's pose correction, for the motion (c, cbar) in the model frame at the
// solution: rotation components in radians, translation in input units. Gauge directions have zero
// uncertainty (they are fixed).
struct ScanPoseUncertainty {
  Eigen::Vector3d rotation = Eigen::Vector3d::Zero();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  // The motion's full covariance (c then cbar: radians and input units), for quantities that depend on
  // several components (a sherd's arc about the axis, fitting/sherd_measures.h). Along unobservable
  // directions it is the pseudo-inverse's, like shape_covariance.
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
};

struct JointFitResult {
  std::vector<RigidMotion> model_T_scan;     // per scan: maps the scan's coordinates into the model frame
  ResidualStatistics residuals;              // all points, input units
  std::vector<ResidualStatistics> per_scan;  // over the points not excluded
  Eigen::Index excluded_points = 0;          // left out as ambiguous (near a part's edges)
  int iterations = 0;
  int shared_iterations = 0;  // how many of them used one shared motion
  StopReason stop_reason = StopReason::kMaxIterations;
  std::vector<IterationRecord> history;
  // The robust loss's scale at the solution, input units (optimizer.loss: the given one or the last estimate
  // from the data); 0 for plain least squares.
  double loss_scale = 0.0;
  // Directions of the final normal matrix (whole normal space) with no information, each named by its
  // dominant parameter, e.g. "scan 2 rotation z". Empty when every remaining unknown is determined.
  std::vector<std::string> unobservable;
  // Type-A standard uncertainties (independent, equal-variance errors along the normals; adequate model): one
  // per shape parameter (input units) and one per scan; empty when N <= unknowns. Along unobservable
  // directions the covariance is the pseudo-inverse's (no variance): quantities invariant along them (e.g. a
  // radius at a height under control points sliding along a profile) keep valid uncertainties; a parameter or
  // pose component that moves along them gets NaN.
  Eigen::VectorXd shape_uncertainty;
  Eigen::MatrixXd shape_covariance;  // of the shape parameters, input units squared (for derived quantities)
  std::vector<ScanPoseUncertainty> pose_uncertainty;
};

// The joint fit's normal equations (docs/method.md eqs. 19-20) at the given model and poses, at exact foot
// points, in input units and full motions: unknowns [D; m_1; ...; m_K] with m_k = (c_k, cbar_k) the velocity
// of scan k in the model frame (x' = x + cbar + c x x), unit weights, no gauge reduction and no fairness. The
// matrix H and the gradient g of F = 1/2 sum e^T M e, and F itself (1/2 sum d^2). Exposed for the numeric
// checks of the assembly (tests/normal_equations_test.cpp) and for diagnostics.
struct JointNormalEquations {
  Eigen::MatrixXd H;
  Eigen::VectorXd g;
  double objective = 0.0;
};
JointNormalEquations LinearizeJointFit(const ParametricModel& model,
                                       const std::vector<Eigen::Matrix3Xd>& scans,
                                       const std::vector<RigidMotion>& model_T_scan, ErrorTerm term);

// Fits `model` (updated in place) and the scans' poses together. `scans` are in their own coordinates,
// `model_T_scan` their initial poses (e.g. device or turntable poses, or a coarse registration).
JointFitResult FitJointly(ParametricModel& model, const std::vector<Eigen::Matrix3Xd>& scans,
                          std::vector<RigidMotion> model_T_scan, const JointFitOptions& options = {});

// A constrained part in two passes: all points first; then, from that result, the points within
// `edge_margin_in_rms` x the first pass's RMS of a second face are chosen ONCE (part_model.h) and left out of
// the refined fit. `part`'s own edge margin, when set, replaces the second pass's.
JointFitResult FitPartJointly(PartModel& part, const std::vector<Eigen::Matrix3Xd>& scans,
                              const std::vector<RigidMotion>& model_T_scan,
                              const JointFitOptions& options = {}, double edge_margin_in_rms = 3.0);

}  // namespace s2m
