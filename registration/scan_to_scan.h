#pragma once
// Scan-to-scan registration without a model: every view is aligned to all the others, all poses solved
// together in each sweep (docs/method.md section 5 with both views of a pair moving). One view is held fixed:
// the registration determines the views only relative to each other. Error terms per pair (docs/method.md
// section 2): point-to-plane (TDM; Chen & Medioni 1992), point-to-point (PDM; Besl & McKay 1992, classic
// ICP), or the second-order approximant of the squared distance to the other view's surface (SDM; Pottmann,
// Leopoldseder & Hofer, "Registration without ICP", CVIU 95(1) 2004), with principal curvatures from local
// quadric fits (registration/local_quadric.h).

#include <Eigen/Core>
#include <functional>
#include <vector>

#include "registration/rigid_motion.h"

namespace s2m {

enum class ScanErrorTerm {
  kPdm,  // |x' - p|^2 to the nearest sample p of the other view (point-to-point ICP)
  kTdm,  // (n.(x' - p))^2, n from a local plane fit at p (point-to-plane); see also tdm_to_quadric
  kSdm,  // (x' - s)^T M (x' - s) at the foot point s of x on the local quadric fitted at p, M = sum_k
         // SdmWeight(delta, kappa_k) T_k T_k^T + n n^T
};

struct ScanToScanOptions {
  ScanErrorTerm error_term = ScanErrorTerm::kTdm;
  int max_sweeps = 50;          // a sweep re-pairs all views and solves for all poses at once
  int samples_per_view = 1500;  // evenly spaced points of each view that look for partners
  int normal_neighbours = 12;   // points in the local plane fit that gives each target point its normal
  // Points in the local quadric fit at each target point (SDM, and TDM to the quadric).
  int quadric_neighbours = 20;
  // TDM to the local quadric: the plane at x's foot point on the quadric fitted at the nearest sample,
  // instead of the PCA plane through the nearest sample itself (the normal term of SDM without its tangential
  // terms).
  bool tdm_to_quadric = false;
  // Pairs farther apart are ignored; 0: 3 x the median pair distance of the sample's view or a quarter of
  // the largest view's extent, whichever is smaller (each sample pairs with its nearest point over all other
  // views).
  double max_correspondence = 0.0;
  // Stop when no view moved more than this (rad) and this (relative to the views' extent) in a sweep. Pairs
  // are re-found every sweep, so the steps settle at the level the sampling allows rather than at rounding.
  double rotation_tolerance = 1e-5;
  double translation_tolerance = 1e-5;
  std::size_t fixed_view = 0;
  // Called after every sweep with the sweep's number (from 1) and its RMS (rms_per_sweep's entry); may be
  // empty.
  std::function<void(int sweep, double rms)> progress;
};

// One view's pairs in the last sweep, as the source of pairs (its samples paired with the other views).
struct ScanToScanViewResidual {
  Eigen::Index samples = 0;  // samples that looked for a partner
  Eigen::Index pairs = 0;    // of them, those within the correspondence distance (used in the step)
  double rms = 0.0;          // RMS distance of those pairs to the target's local plane or quadric
  double max = 0.0;          // and the largest
  double correspondence_distance = 0.0;  // the sweep's rejection distance for this view
};

struct ScanToScanResult {
  std::vector<RigidMotion> world_T_scan;
  int sweeps = 0;
  bool converged = false;
  // RMS distance over all accepted pairs, measured before each sweep's step: to the target's local plane
  // (PDM, TDM) or local quadric (SDM, TDM to the quadric).
  std::vector<double> rms_per_sweep;
  // world_T_scan after each sweep (convergence studies).
  std::vector<std::vector<RigidMotion>> poses_per_sweep;
  // Measured in the last sweep, before its step (below the tolerances when converged).
  std::vector<ScanToScanViewResidual> view_residuals;
  // overlap(k, l): pairs of the last sweep from view k's samples to view l's surface (the overlap graph).
  Eigen::MatrixXi overlap;
  // The largest rotation (rad) and displacement of the last sweep's step over the views (below the
  // tolerances when converged).
  double last_step_angle = 0.0;
  double last_step_shift = 0.0;
  // PDM only: the largest rotation (rad) and displacement of the point-to-plane step (TDM's, from the same
  // pairs and the targets' local planes) the last sweep's poses still asked for. Point-to-point pairs with
  // the nearest sample stall where the samples' spacing holds the points (docs/registration.md): their own
  // steps shrink below the tolerances while the views are still off the surfaces, so PDM is declared
  // converged only when this step is below the tolerances too; `stalled` when its own steps settled while
  // this one did not (the sweeps stop there: more would not move the poses).
  double pending_plane_angle = 0.0;
  double pending_plane_shift = 0.0;
  bool stalled = false;
  // Views whose pose relative to the fixed view the last sweep's pairs do not determine: not linked to it
  // through views with at least six pairs between them. In every sweep such views are left out of the step
  // (their poses do not move then, and their pairs do not pull on the others). Their poses are not
  // registered; empty when the overlap graph is connected.
  std::vector<std::size_t> unconstrained_views;
};

// `scans` in their own coordinates, `world_T_scan` their initial poses (within a few degrees and a few
// percent of the part's size of the truth). Throws std::invalid_argument for too few views or poses, views
// with fewer points than a local fit needs, non-finite views, a missing fixed view or non-positive sizes.
ScanToScanResult RegisterScansToEachOther(const std::vector<Eigen::Matrix3Xd>& scans,
                                          std::vector<RigidMotion> world_T_scan,
                                          const ScanToScanOptions& options = {});

// Unit normals of a point set by local plane fits over the k nearest neighbours (sign arbitrary).
Eigen::Matrix3Xd EstimateNormals(const Eigen::Matrix3Xd& points, int neighbours);

}  // namespace s2m
