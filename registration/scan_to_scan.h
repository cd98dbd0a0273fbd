#pragma once
// Scan-to-scan registration without a model: every view is aligned to all the others, all poses solved
// together in each sweep (docs/method.md section 5 with both views of a pair moving). One view is held fixed: the
// registration determines the views only relative to each other. Error terms per pair (docs/method.md section 2):
// point-to-plane (TDM; Chen & Medioni 1992), point-to-point (PDM; Besl & McKay 1992, classic ICP), or the
// second-order approximant of the squared distance to the other view's surface (SDM; Pottmann, Leopoldseder &
// Hofer, "Registration without ICP", CVIU 95(1) 2004), with principal curvatures from local quadric fits
// (registration/local_quadric.h).

#include <Eigen/Core>
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
  double max_correspondence = 0.0;  // pairs farther apart are ignored; 0: 3 x the median pair distance, per
                                    // view (each sample pairs with its nearest point over all other views)
  // Stop when no view moved more than this (rad) and this (relative to the views' extent) in a sweep. Pairs
  // are re-found every sweep, so the steps settle at the level the sampling allows rather than at rounding.
  double rotation_tolerance = 1e-5;
  double translation_tolerance = 1e-5;
  std::size_t fixed_view = 0;
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
