#include "acquisition/pcl_registration.h"

#include <pcl/features/fpfh_omp.h>
#include <pcl/features/normal_3d_omp.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/icp.h>
#include <pcl/registration/sample_consensus_prerejective.h>
#include <pcl/search/kdtree.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <stdexcept>
#include <string>

#include "fitting/enum_names.h"

namespace s2m {
namespace {

using Cloud = pcl::PointCloud<pcl::PointXYZ>;
using Normals = pcl::PointCloud<pcl::Normal>;
using Features = pcl::PointCloud<pcl::FPFHSignature33>;

void CheckView(const Eigen::Matrix3Xd& points, const std::string& what) {
  if (points.cols() == 0) throw std::invalid_argument(what + " is empty");
  if (!points.allFinite()) throw std::invalid_argument(what + " contains NaN or inf coordinates");
}

// PCL works in single precision; coordinates are shifted by `origin` first so that data far from the origin
// (millimetres in a machine frame) keep their resolution.
Cloud::Ptr ToCloud(const Eigen::Matrix3Xd& points, const Eigen::Vector3d& origin) {
  Cloud::Ptr cloud(new Cloud);
  cloud->resize(static_cast<std::size_t>(points.cols()));
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const Eigen::Vector3d p = points.col(i) - origin;
    (*cloud)[static_cast<std::size_t>(i)] =
        pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()));
  }
  return cloud;
}

// PCL keeps the iteration count protected; this exposes it for the report.
class CountingIcp : public pcl::IterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ> {
 public:
  int iterations() const { return nr_iterations_; }
};

std::string StopReason(pcl::registration::DefaultConvergenceCriteria<float>::ConvergenceState state) {
  using C = pcl::registration::DefaultConvergenceCriteria<float>;
  static constexpr std::array<EnumName<C::ConvergenceState>, 7> kStateNames = {{
      {C::CONVERGENCE_CRITERIA_ITERATIONS, "maximum iterations"},
      {C::CONVERGENCE_CRITERIA_TRANSFORM, "transformation epsilon"},
      {C::CONVERGENCE_CRITERIA_ABS_MSE, "absolute MSE"},
      {C::CONVERGENCE_CRITERIA_REL_MSE, "relative MSE"},
      {C::CONVERGENCE_CRITERIA_NO_CORRESPONDENCES, "no correspondences"},
      {C::CONVERGENCE_CRITERIA_FAILURE_AFTER_MAX_ITERATIONS, "failure after maximum iterations"},
      {C::CONVERGENCE_CRITERIA_NOT_CONVERGED, "not converged"},
  }};
  return NameOf(kStateNames, state, "not converged");
}

double Diagonal(const Eigen::Matrix3Xd& p) {
  return (p.rowwise().maxCoeff() - p.rowwise().minCoeff()).norm();
}

struct Settings {
  double voxel = 0, normal_radius = 0, feature_radius = 0, inlier_distance = 0;
};

Settings Resolve(const CoarseAlignOptions& o, double diagonal) {
  if (o.voxel_size < 0 || o.normal_radius < 0 || o.feature_radius < 0 || o.inlier_distance < 0)
    throw std::invalid_argument("coarse alignment: sizes and radii must not be negative");
  if (!(o.min_inlier_fraction >= 0 && o.min_inlier_fraction <= 1))
    throw std::invalid_argument("coarse alignment: min_inlier_fraction must lie in [0, 1]");
  if (!(o.similarity_threshold >= 0 && o.similarity_threshold < 1))
    throw std::invalid_argument("coarse alignment: similarity_threshold must lie in [0, 1)");
  if (o.max_iterations <= 0 || o.correspondence_randomness <= 0)
    throw std::invalid_argument(
        "coarse alignment: max_iterations and correspondence_randomness must be positive");
  Settings s;
  s.voxel = o.voxel_size > 0 ? o.voxel_size : diagonal / 50.0;
  if (!(s.voxel > 0))
    throw std::invalid_argument("coarse alignment: the views have no extent (all points equal)");
  s.normal_radius = o.normal_radius > 0 ? o.normal_radius : 2.0 * s.voxel;
  s.feature_radius = o.feature_radius > 0 ? o.feature_radius : 5.0 * s.voxel;
  s.inlier_distance = o.inlier_distance > 0 ? o.inlier_distance : 1.5 * s.voxel;
  return s;
}

// One view ready for matching: voxel samples (centred on `origin`) with FPFH descriptors for both signs of
// the normals.
struct PreparedView {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Cloud::Ptr samples;
  Features::Ptr features, flipped_features;
};

// FPFH needs at least a handful of samples with neighbours; fewer cannot give three distinct correspondences.
constexpr std::size_t kMinSamples = 10;

Features::Ptr ComputeFpfh(const Cloud::Ptr& samples, const Normals::Ptr& normals, double radius) {
  pcl::FPFHEstimationOMP<pcl::PointXYZ, pcl::Normal, pcl::FPFHSignature33> fpfh;
  fpfh.setInputCloud(samples);
  fpfh.setInputNormals(normals);
  fpfh.setSearchMethod(pcl::search::KdTree<pcl::PointXYZ>::Ptr(new pcl::search::KdTree<pcl::PointXYZ>));
  fpfh.setRadiusSearch(radius);
  Features::Ptr features(new Features);
  fpfh.compute(*features);
  return features;
}

bool FiniteHistogram(const pcl::FPFHSignature33& f) {
  return std::all_of(std::begin(f.histogram), std::end(f.histogram),
                     [](float v) { return std::isfinite(v); });
}

PreparedView Prepare(const Eigen::Matrix3Xd& points, const Settings& s, const std::string& what) {
  PreparedView view;
  view.origin = points.rowwise().mean();
  const Cloud::Ptr full = ToCloud(points, view.origin);
  Cloud::Ptr grid_samples(new Cloud);
  pcl::VoxelGrid<pcl::PointXYZ> grid;
  grid.setInputCloud(full);
  const auto leaf = static_cast<float>(s.voxel);
  grid.setLeafSize(leaf, leaf, leaf);
  grid.filter(*grid_samples);

  // Normals from plane fits over the full-resolution points near each sample (more points, steadier normals).
  // Their sign matters to FPFH. A range view is seen from one side, so the normals are oriented towards a far
  // viewpoint along the view's direction of least spread; which side that is stays unknown without the
  // sensor, so the matching tries the source's normals both ways (see AlignPrepared).
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : *grid_samples) {
    const Eigen::Vector3d v(p.x, p.y, p.z);
    cov += v * v.transpose();
  }
  const Eigen::Vector3d axis = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvectors().col(0);
  // 20 diagonals away: nearly parallel viewing rays.
  const Eigen::Vector3d viewpoint = 20.0 * Diagonal(points) * axis;
  pcl::NormalEstimationOMP<pcl::PointXYZ, pcl::Normal> estimator;
  estimator.setInputCloud(grid_samples);
  estimator.setSearchSurface(full);
  estimator.setSearchMethod(pcl::search::KdTree<pcl::PointXYZ>::Ptr(new pcl::search::KdTree<pcl::PointXYZ>));
  estimator.setRadiusSearch(s.normal_radius);
  estimator.setViewPoint(static_cast<float>(viewpoint.x()), static_cast<float>(viewpoint.y()),
                         static_cast<float>(viewpoint.z()));
  Normals grid_normals;
  estimator.compute(grid_normals);

  // Samples whose normal could not be estimated (too few neighbours) carry no usable descriptor.
  view.samples.reset(new Cloud);
  Normals::Ptr normals(new Normals), flipped(new Normals);
  for (std::size_t i = 0; i < grid_samples->size(); ++i) {
    const pcl::Normal& n = grid_normals[i];
    if (!std::isfinite(n.normal_x) || !std::isfinite(n.normal_y) || !std::isfinite(n.normal_z)) continue;
    view.samples->push_back((*grid_samples)[i]);
    normals->push_back(n);
    flipped->push_back(pcl::Normal(-n.normal_x, -n.normal_y, -n.normal_z));
  }
  if (view.samples->size() < kMinSamples)
    throw std::invalid_argument(what + " has too few points for features (" +
                                std::to_string(view.samples->size()) +
                                " samples with normals at voxel size " + std::to_string(s.voxel) + ")");
  const Features::Ptr features = ComputeFpfh(view.samples, normals, s.feature_radius);
  const Features::Ptr flipped_features = ComputeFpfh(view.samples, flipped, s.feature_radius);
  // Keep samples whose descriptors are finite under both signs, so points and features stay one to one.
  Cloud::Ptr kept(new Cloud);
  view.features.reset(new Features);
  view.flipped_features.reset(new Features);
  for (std::size_t i = 0; i < view.samples->size(); ++i) {
    if (!FiniteHistogram((*features)[i]) || !FiniteHistogram((*flipped_features)[i])) continue;
    kept->push_back((*view.samples)[i]);
    view.features->push_back((*features)[i]);
    view.flipped_features->push_back((*flipped_features)[i]);
  }
  view.samples = kept;
  if (view.samples->size() < kMinSamples)
    throw std::invalid_argument(what + " has too few points with finite FPFH descriptors");
  return view;
}

CoarseAlignment AlignPrepared(const PreparedView& source, const PreparedView& target, const Settings& s,
                              const CoarseAlignOptions& o) {
  CoarseAlignment best;
  best.source_samples = static_cast<Eigen::Index>(source.samples->size());
  best.target_samples = static_cast<Eigen::Index>(target.samples->size());
  best.voxel_size = s.voxel;
  Eigen::Matrix4d centred_T = Eigen::Matrix4d::Identity();
  for (const bool flip : {false, true}) {
    pcl::SampleConsensusPrerejective<pcl::PointXYZ, pcl::PointXYZ, pcl::FPFHSignature33> ransac;
    ransac.setInputSource(source.samples);
    ransac.setSourceFeatures(flip ? source.flipped_features : source.features);
    ransac.setInputTarget(target.samples);
    ransac.setTargetFeatures(target.features);
    ransac.setMaximumIterations(o.max_iterations);
    ransac.setNumberOfSamples(3);
    ransac.setCorrespondenceRandomness(o.correspondence_randomness);
    ransac.setSimilarityThreshold(static_cast<float>(o.similarity_threshold));
    ransac.setMaxCorrespondenceDistance(s.inlier_distance);
    ransac.setInlierFraction(static_cast<float>(o.min_inlier_fraction));
    std::srand(o.seed);  // PCL draws its samples from rand(): reseeding makes every run repeatable
    Cloud aligned;
    ransac.align(aligned);
    if (!ransac.hasConverged()) continue;
    const double fraction =
        static_cast<double>(ransac.getInliers().size()) / static_cast<double>(source.samples->size());
    // Both signs can pass; the right one explains more of the source.
    if (best.found && fraction <= best.inlier_fraction) continue;
    best.found = true;
    best.inlier_fraction = fraction;
    // PCL's fitness score over pairs within the inlier distance (it compares squared distances).
    best.inlier_rms = std::sqrt(ransac.getFitnessScore(s.inlier_distance * s.inlier_distance));
    best.source_normals_flipped = flip;
    centred_T = ransac.getFinalTransformation().cast<double>();
  }
  // Undo the centring: x_t = o_t + T (x_s - o_s).
  const RigidMotion centred = RigidMotion::FromMatrix(centred_T);
  best.target_T_source = best.found ? RigidMotion(centred.rotation(), target.origin + centred.translation() -
                                                                          centred.rotation() * source.origin)
                                    : RigidMotion::Identity();
  best.target_T_source.normalize();  // single-precision rotation back to an exact one
  return best;
}

}  // namespace

PclIcpResult PclIterativeClosestPoint(const Eigen::Matrix3Xd& source, const Eigen::Matrix3Xd& target,
                                      const PclIcpOptions& options) {
  CheckView(source, "ICP source cloud");
  CheckView(target, "ICP target cloud");
  if (options.max_iterations <= 0 || !(options.max_correspondence_distance > 0) ||
      !(options.transformation_epsilon >= 0))
    throw std::invalid_argument("ICP: iterations and correspondence distance must be positive");
  // As PCL's own test runs it: the coordinates as given, no centring.
  const Eigen::Vector3d none = Eigen::Vector3d::Zero();
  CountingIcp icp;
  icp.setInputSource(ToCloud(source, none));
  icp.setInputTarget(ToCloud(target, none));
  icp.setMaximumIterations(options.max_iterations);
  icp.setTransformationEpsilon(options.transformation_epsilon);
  icp.setMaxCorrespondenceDistance(options.max_correspondence_distance);
  Cloud aligned;
  icp.align(aligned);
  PclIcpResult result;
  result.target_T_source = RigidMotion::FromMatrix(icp.getFinalTransformation().cast<double>());
  result.converged = icp.hasConverged();
  result.iterations = icp.iterations();
  result.stop_reason = StopReason(icp.getConvergeCriteria()->getConvergenceState());
  result.fitness_score = icp.getFitnessScore();
  return result;
}

Eigen::Matrix3Xd ReadPcdPointsWithPcl(const std::filesystem::path& path) {
  Cloud cloud;
  if (pcl::io::loadPCDFile<pcl::PointXYZ>(path.string(), cloud) < 0)
    throw std::runtime_error(path.string() + ": PCL could not read the PCD file");
  Eigen::Matrix3Xd points(3, static_cast<Eigen::Index>(cloud.size()));
  for (std::size_t i = 0; i < cloud.size(); ++i)
    points.col(static_cast<Eigen::Index>(i)) << cloud[i].x, cloud[i].y, cloud[i].z;
  return points;
}

CoarseAlignment CoarseAlign(const Eigen::Matrix3Xd& source, const Eigen::Matrix3Xd& target,
                            const CoarseAlignOptions& options) {
  CheckView(source, "coarse alignment: the source view");
  CheckView(target, "coarse alignment: the target view");
  const Settings s = Resolve(options, std::max(Diagonal(source), Diagonal(target)));
  return AlignPrepared(Prepare(source, s, "coarse alignment: the source view"),
                       Prepare(target, s, "coarse alignment: the target view"), s, options);
}

MultiViewCoarseAlignment CoarseAlignViews(const std::vector<Eigen::Matrix3Xd>& views,
                                          const CoarseAlignOptions& options) {
  const std::size_t K = views.size();
  if (K < 2) throw std::invalid_argument("coarse alignment needs at least two views");
  double diagonal = 0.0;
  for (std::size_t k = 0; k < K; ++k) {
    CheckView(views[k], "coarse alignment: view " + std::to_string(k));
    diagonal = std::max(diagonal, Diagonal(views[k]));
  }
  const Settings s = Resolve(options, diagonal);
  std::vector<PreparedView> prepared;
  for (std::size_t k = 0; k < K; ++k)
    prepared.push_back(Prepare(views[k], s, "coarse alignment: view " + std::to_string(k)));
  // Every pair once (source l, target k < l); the reverse motion is the inverse.
  std::vector<std::vector<CoarseAlignment>> pairs(K, std::vector<CoarseAlignment>(K));
  for (std::size_t k = 0; k < K; ++k)
    for (std::size_t l = k + 1; l < K; ++l) pairs[k][l] = AlignPrepared(prepared[l], prepared[k], s, options);
  const auto weight = [&](std::size_t a, std::size_t b) {
    const CoarseAlignment& c = a < b ? pairs[a][b] : pairs[b][a];
    return c.found ? c.inlier_fraction * static_cast<double>(c.source_samples) : -1.0;
  };
  // Prim's algorithm for the maximum spanning tree from view 0.
  MultiViewCoarseAlignment result;
  result.voxel_size = s.voxel;
  result.world_T_view.assign(K, RigidMotion::Identity());
  result.placed.assign(K, false);
  result.placed[0] = true;
  for (std::size_t added = 1; added < K; ++added) {
    double best = 0.0;
    std::size_t parent = K, child = K;
    for (std::size_t a = 0; a < K; ++a) {
      if (!result.placed[a]) continue;
      for (std::size_t b = 0; b < K; ++b) {
        if (result.placed[b] || b == a) continue;
        const double w = weight(a, b);
        if (w > best) {
          best = w;
          parent = a;
          child = b;
        }
      }
    }
    if (child == K) break;  // the remaining views share no accepted pair with the placed ones
    // pairs[k][l] holds k_T_l; the tree needs parent_T_child.
    CoarseAlignment edge = parent < child ? pairs[parent][child] : pairs[child][parent];
    if (parent > child) edge.target_T_source = edge.target_T_source.inverse();
    result.world_T_view[child] = result.world_T_view[parent] * edge.target_T_source;
    result.placed[child] = true;
    result.tree.emplace_back(parent, child);
    result.tree_alignments.push_back(edge);
  }
  return result;
}

}  // namespace s2m
