// Open3D's point-to-plane ICP for the benchmark (bench/icp_baselines.h): open3d::pipelines::registration::
// RegistrationICP with TransformationEstimationPointToPlane, in double precision. Open3D builds its k-d tree
// of the target inside every RegistrationICP call, so each Run pays it once.

#include <open3d/geometry/KDTreeSearchParam.h>
#include <open3d/geometry/PointCloud.h>
#include <open3d/pipelines/registration/GlobalOptimization.h>
#include <open3d/pipelines/registration/GlobalOptimizationConvergenceCriteria.h>
#include <open3d/pipelines/registration/GlobalOptimizationMethod.h>
#include <open3d/pipelines/registration/PoseGraph.h>
#include <open3d/pipelines/registration/Registration.h>
#include <open3d/pipelines/registration/TransformationEstimation.h>

#include "bench/icp_baselines.h"

namespace s2m::bench {
namespace {

namespace reg = open3d::pipelines::registration;

std::shared_ptr<open3d::geometry::PointCloud> ToCloud(const Eigen::Matrix3Xd& points,
                                                      const Eigen::Matrix3Xd& normals) {
  auto cloud = std::make_shared<open3d::geometry::PointCloud>();
  cloud->points_.resize(static_cast<std::size_t>(points.cols()));
  for (Eigen::Index i = 0; i < points.cols(); ++i)
    cloud->points_[static_cast<std::size_t>(i)] = points.col(i);
  if (normals.cols() == points.cols()) {
    cloud->normals_.resize(static_cast<std::size_t>(points.cols()));
    for (Eigen::Index i = 0; i < points.cols(); ++i)
      cloud->normals_[static_cast<std::size_t>(i)] = normals.col(i);
  }
  return cloud;
}

class Open3dPointToPlane final : public IcpBaseline {
 public:
  explicit Open3dPointToPlane(const IcpProblem& problem)
      : source_(ToCloud(problem.source, Eigen::Matrix3Xd())),
        target_(ToCloud(problem.target, problem.target_normals)),
        max_distance_(problem.max_correspondence_distance) {}
  std::string name() const override { return "Open3D point-to-plane ICP"; }

  RigidMotion Run(const RigidMotion& start, int iterations) override {
    // Relative fitness and RMSE thresholds 0: Open3D's early stop never fires, exactly `iterations` run.
    const reg::RegistrationResult r = reg::RegistrationICP(*source_, *target_, max_distance_, start.matrix(),
                                                           reg::TransformationEstimationPointToPlane(),
                                                           reg::ICPConvergenceCriteria(0.0, 0.0, iterations));
    return RigidMotion::FromMatrix(r.transformation_);
  }

 private:
  std::shared_ptr<open3d::geometry::PointCloud> source_, target_;
  double max_distance_;
};

}  // namespace

bool HaveOpen3d() {
  return true;
}
std::unique_ptr<IcpBaseline> MakeOpen3dPointToPlane(const IcpProblem& problem) {
  return std::make_unique<Open3dPointToPlane>(problem);
}

Eigen::Matrix3Xd Open3dEstimateNormals(const Eigen::Matrix3Xd& points, int neighbours) {
  const auto cloud = ToCloud(points, Eigen::Matrix3Xd());
  cloud->EstimateNormals(open3d::geometry::KDTreeSearchParamKNN(neighbours));
  Eigen::Matrix3Xd normals(3, points.cols());
  for (Eigen::Index i = 0; i < points.cols(); ++i)
    normals.col(i) = cloud->normals_[static_cast<std::size_t>(i)];
  return normals;
}

std::vector<RigidMotion> Open3dMultiway(const std::vector<Eigen::Matrix3Xd>& views,
                                        const std::vector<RigidMotion>& world_T_scan, int samples,
                                        double max_correspondence_distance) {
  const std::size_t K = views.size();
  std::vector<std::shared_ptr<open3d::geometry::PointCloud>> full, sparse;
  for (const Eigen::Matrix3Xd& v : views) {
    full.push_back(ToCloud(v, Eigen::Matrix3Xd()));
    full.back()->EstimateNormals(open3d::geometry::KDTreeSearchParamKNN(12));
    const Eigen::Index m = std::min<Eigen::Index>(samples, v.cols());
    Eigen::Matrix3Xd picked(3, m);
    for (Eigen::Index i = 0; i < m; ++i) picked.col(i) = v.col(i * v.cols() / m);
    sparse.push_back(ToCloud(picked, Eigen::Matrix3Xd()));
  }
  reg::PoseGraph graph;
  for (std::size_t k = 0; k < K; ++k) graph.nodes_.emplace_back(world_T_scan[k].matrix());
  for (std::size_t s = 0; s < K; ++s) {
    for (std::size_t t = s + 1; t < K; ++t) {
      // target_T_source from the starting poses, refined by ICP (Open3D's convergence defaults).
      const Eigen::Matrix4d start = (world_T_scan[t].inverse() * world_T_scan[s]).matrix();
      const reg::RegistrationResult r =
          reg::RegistrationICP(*sparse[s], *full[t], max_correspondence_distance, start,
                               reg::TransformationEstimationPointToPlane());
      const Eigen::Matrix6d information = reg::GetInformationMatrixFromPointClouds(
          *sparse[s], *full[t], max_correspondence_distance, r.transformation_);
      graph.edges_.emplace_back(static_cast<int>(s), static_cast<int>(t), r.transformation_, information,
                                /*uncertain=*/t != s + 1);
    }
  }
  reg::GlobalOptimization(graph, reg::GlobalOptimizationLevenbergMarquardt(),
                          reg::GlobalOptimizationConvergenceCriteria(),
                          reg::GlobalOptimizationOption(max_correspondence_distance, 0.25, 1.0, 0));
  std::vector<RigidMotion> out;
  for (const reg::PoseGraphNode& node : graph.nodes_) {
    RigidMotion pose = RigidMotion::FromMatrix(node.pose_);
    pose.normalize();
    out.push_back(pose);
  }
  return out;
}

}  // namespace s2m::bench
