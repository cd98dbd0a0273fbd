// PCL's ICP variants for the benchmark (bench/icp_baselines.h). PCL runs in single precision: coordinates
// are shifted by the target's centroid first so that millimetre data keep their resolution.

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/icp.h>
#include <pcl/registration/transformation_estimation_point_to_plane_lls.h>

#include "bench/icp_baselines.h"

namespace s2m::bench {
namespace {

using PointN = pcl::PointNormal;
using CloudN = pcl::PointCloud<PointN>;

CloudN::Ptr ToCloud(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                    const Eigen::Vector3d& origin) {
  CloudN::Ptr cloud(new CloudN);
  cloud->resize(static_cast<std::size_t>(points.cols()));
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    PointN& p = (*cloud)[static_cast<std::size_t>(i)];
    const Eigen::Vector3f x = (points.col(i) - origin).cast<float>();
    p.x = x.x();
    p.y = x.y();
    p.z = x.z();
    const Eigen::Vector3f n = normals.cols() == points.cols() ? Eigen::Vector3f(normals.col(i).cast<float>())
                                                              : Eigen::Vector3f::Zero();
    p.normal_x = n.x();
    p.normal_y = n.y();
    p.normal_z = n.z();
  }
  return cloud;
}

// One PCL ICP object, kept across runs so that the target's k-d tree is built once (PCL rebuilds it only when
// the target changes).
class PclIcp final : public IcpBaseline {
 public:
  PclIcp(const IcpProblem& problem, bool point_to_plane) : point_to_plane_(point_to_plane) {
    origin_ = problem.target.rowwise().mean();
    source_ = ToCloud(problem.source, Eigen::Matrix3Xd(), origin_);
    CloudN::Ptr target = ToCloud(problem.target, problem.target_normals, origin_);
    if (point_to_plane_)
      icp_.setTransformationEstimation(
          pcl::make_shared<pcl::registration::TransformationEstimationPointToPlaneLLS<PointN, PointN>>());
    icp_.setInputSource(source_);
    icp_.setInputTarget(target);
    icp_.setMaxCorrespondenceDistance(problem.max_correspondence_distance);
    // No early stop: the benchmark decides how many iterations run.
    icp_.setTransformationEpsilon(0.0);
    icp_.setEuclideanFitnessEpsilon(0.0);
    icp_.setTransformationRotationEpsilon(0.0);
  }
  std::string name() const override { return point_to_plane_ ? "PCL point-to-plane ICP" : "PCL ICP"; }

  RigidMotion Run(const RigidMotion& start, int iterations) override {
    icp_.setMaximumIterations(iterations);
    // In the shifted frame: target'_T_source' = shift(-o) * target_T_source * shift(o) with source' = source
    // - o.
    const RigidMotion shift_in(Eigen::Matrix3d::Identity(), origin_);
    const RigidMotion shift_out(Eigen::Matrix3d::Identity(), -origin_);
    const RigidMotion guess = shift_out * start * shift_in;
    CloudN aligned;
    icp_.align(aligned, guess.matrix().cast<float>());
    return shift_in * RigidMotion::FromMatrix(icp_.getFinalTransformation().cast<double>()) * shift_out;
  }

 private:
  bool point_to_plane_;
  Eigen::Vector3d origin_;
  CloudN::Ptr source_;
  pcl::IterativeClosestPoint<PointN, PointN> icp_;
};

}  // namespace

bool HavePcl() {
  return true;
}
std::unique_ptr<IcpBaseline> MakePclPointToPoint(const IcpProblem& problem) {
  return std::make_unique<PclIcp>(problem, false);
}
std::unique_ptr<IcpBaseline> MakePclPointToPlane(const IcpProblem& problem) {
  return std::make_unique<PclIcp>(problem, true);
}

}  // namespace s2m::bench
