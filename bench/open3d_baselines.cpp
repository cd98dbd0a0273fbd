// Open3D's point-to-plane ICP for the benchmark (bench/icp_baselines.h): open3d::pipelines::registration::
// RegistrationICP with TransformationEstimationPointToPlane, in double precision. Open3D builds its k-d tree
// of the target inside every RegistrationICP call, so each Run pays it once.

#include <open3d/geometry/PointCloud.h>
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

}  // namespace s2m::bench
