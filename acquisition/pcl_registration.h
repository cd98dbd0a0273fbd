#pragma once
// PCL at the edge (issue 4): PCL's own ICP as an outside reference for our registration maths, and coarse
// alignment of views that come without usable poses (normals, FPFH features, prerejective RANSAC). Only Eigen
// and our types appear here; PCL stays inside pcl_registration.cpp, so nothing else in the project sees PCL's
// headers. Built only when PCL 1.13 is found (target s2m_pcl).

#include <Eigen/Core>
#include <cstddef>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "registration/rigid_motion.h"

namespace s2m {

// pcl::IterativeClosestPoint: point-to-point ICP with closed-form (SVD) steps (Besl & McKay, PAMI 14(2)
// 1992), run as PCL runs it, in single precision on the coordinates as given.
struct PclIcpOptions {
  int max_iterations = 50;
  double transformation_epsilon = 1e-8;       // PCL's stop on the squared change of the transformation
  double max_correspondence_distance = 0.05;  // pairs farther apart are ignored (units of the data)
};

struct PclIcpResult {
  RigidMotion target_T_source;  // PCL's getFinalTransformation(), widened to double
  bool converged = false;       // PCL's hasConverged()
  int iterations = 0;
  std::string stop_reason;     // PCL's convergence state, e.g. "transformation epsilon"
  double fitness_score = 0.0;  // PCL's getFitnessScore(): mean squared nearest-neighbour distance at the end
};

// Throws std::invalid_argument for empty or non-finite clouds or non-positive settings.
PclIcpResult PclIterativeClosestPoint(const Eigen::Matrix3Xd& source, const Eigen::Matrix3Xd& target,
                                      const PclIcpOptions& options = {});

// x y z of a PCD file read by PCL's own reader (pcl::io::loadPCDFile): a cross-check of our reader. Throws
// std::runtime_error naming the file when PCL cannot read it.
Eigen::Matrix3Xd ReadPcdPointsWithPcl(const std::filesystem::path& path);

// Coarse alignment without poses: both views are downsampled on a voxel grid, given normals (local plane
// fits) and FPFH descriptors (Rusu, Blodow, Beetz, ICRA 2009), and matched by RANSAC over three feature
// correspondences whose edge lengths must agree before a pose is even scored (prerejective RANSAC: Buch,
// Kraft, Kamarainen, Petersen, Krueger, ICRA 2013, pcl::SampleConsensusPrerejective). The result is meant to
// start a fine registration (RegisterScansToEachOther), not to replace it: its accuracy is about the voxel
// size. Scale-dependent settings left at 0 follow the voxel size, which itself follows the views' extent.
struct CoarseAlignOptions {
  double voxel_size = 0.0;       // 0: 1/50 of the largest view's bounding-box diagonal
  double normal_radius = 0.0;    // 0: 2 voxels (about a dozen samples in the plane fit)
  double feature_radius = 0.0;   // 0: 5 voxels (FPFH must see more than the normal's neighbourhood)
  double inlier_distance = 0.0;  // 0: 1.5 voxels; a source sample this close to a target sample is an inlier
  double min_inlier_fraction = 0.25;  // of the source samples; poses below it are not accepted
  int max_iterations = 50000;         // RANSAC hypotheses
  int correspondence_randomness = 3;  // each sample draws its partner among this many nearest features
  double similarity_threshold = 0.9;  // prerejection: edge-length ratios of the two triangles
  // PCL's RANSAC draws from the C library's rand(); std::srand(seed) before each run makes the result
  // repeatable (a process-wide side effect).
  unsigned seed = 1;
};

struct CoarseAlignment {
  RigidMotion target_T_source;  // identity when nothing was found
  bool found = false;           // a pose reached min_inlier_fraction
  double inlier_fraction = 0.0;
  double inlier_rms = 0.0;  // RMS nearest-sample distance of the inliers
  bool source_normals_flipped = false;
  Eigen::Index source_samples = 0, target_samples = 0;
  double voxel_size = 0.0;  // the one used
};

// `source` and `target` in their own coordinates (any relative pose); returns target_T_source. Throws
// std::invalid_argument for empty or non-finite views, views with too few points for features, or negative
// settings.
CoarseAlignment CoarseAlign(const Eigen::Matrix3Xd& source, const Eigen::Matrix3Xd& target,
                            const CoarseAlignOptions& options = {});

// Several views: every pair is coarse-aligned, and the poses follow the maximum spanning tree of the pairs'
// inlier counts from view 0 (world = view 0's frame), so each view hangs on its most reliable overlap.
struct MultiViewCoarseAlignment {
  std::vector<RigidMotion> world_T_view;
  std::vector<bool> placed;  // false: no accepted pair links this view to view 0 (its pose is the identity)
  std::vector<std::pair<std::size_t, std::size_t>> tree;  // (parent, child) edges used
  std::vector<CoarseAlignment> tree_alignments;           // parent_T_child per edge
  double voxel_size = 0.0;
};

// Throws std::invalid_argument for fewer than two views or any view CoarseAlign rejects.
MultiViewCoarseAlignment CoarseAlignViews(const std::vector<Eigen::Matrix3Xd>& views,
                                          const CoarseAlignOptions& options = {});

}  // namespace s2m
