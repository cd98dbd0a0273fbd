#pragma once
// Scan-to-scan registration without a model: every view is aligned to all the others by point-to-plane (TDM)
// steps, all poses solved together in each sweep (METHOD.md section 5 with both views of a pair moving; Chen
// & Medioni 1992 for the point-to-plane error). One view is held fixed: the registration determines the views
// only relative to each other.

#include <Eigen/Core>
#include <vector>

#include "registration/rigid_motion.h"

namespace s2m {

struct ScanToScanOptions {
  int max_sweeps = 50;              // a sweep re-pairs all views and solves for all poses at once
  int samples_per_view = 1500;      // evenly spaced points of each view that look for partners
  int normal_neighbours = 12;       // points in the local plane fit that gives each target point its normal
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
  std::vector<double> rms_per_sweep;  // RMS point-to-plane distance over all accepted pairs
};

// `scans` in their own coordinates, `world_T_scan` their initial poses (within a few degrees and a few
// percent of the part's size of the truth). Throws std::invalid_argument for empty or non-finite views.
ScanToScanResult RegisterScansToEachOther(const std::vector<Eigen::Matrix3Xd>& scans,
                                          std::vector<RigidMotion> world_T_scan,
                                          const ScanToScanOptions& options = {});

// Unit normals of a point set by local plane fits over the k nearest neighbours (sign arbitrary).
Eigen::Matrix3Xd EstimateNormals(const Eigen::Matrix3Xd& points, int neighbours);

}  // namespace s2m
