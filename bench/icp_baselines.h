#pragma once
// Outside ICP implementations the benchmark compares against (issue 7): PCL's point-to-point and
// point-to-plane ICP and Open3D's point-to-plane ICP. Only Eigen and our types appear here; PCL stays in
// pcl_baselines.cpp and Open3D in open3d_baselines.cpp (each built only when the library is found, see
// bench/CMakeLists.txt), so the driver compiles without either.
//
// A baseline is prepared once for a (source, target) pair and then runs a given number of iterations from a
// given pose. Its iterations depend only on the current pose, so running 1 iteration k times from the
// previous result retraces one k-iteration run: the benchmark uses that to record the pose after every
// iteration (untimed) and then times one fresh run of exactly the iterations needed (timed, including the
// library's own set-up, e.g. its k-d tree of the target).

#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "registration/rigid_motion.h"

namespace s2m::bench {

struct IcpProblem {
  Eigen::Matrix3Xd source;          // moves; in its own coordinates
  Eigen::Matrix3Xd target;          // fixed
  Eigen::Matrix3Xd target_normals;  // unit (point-to-plane); may be empty for point-to-point
  double max_correspondence_distance = 1.0;
};

class IcpBaseline {
 public:
  virtual ~IcpBaseline() = default;
  virtual std::string name() const = 0;
  // Runs exactly `iterations` iterations (the library's convergence tests switched off) from
  // target_T_source = `start`; returns the final target_T_source.
  virtual RigidMotion Run(const RigidMotion& start, int iterations) = 0;
};

// Which baselines this build has (the libraries are optional).
bool HavePcl();
bool HaveOpen3d();

// nullptr when the library is absent from this build. Set-up (clouds, k-d tree of the target) happens in the
// factory or in the first Run.
std::unique_ptr<IcpBaseline> MakePclPointToPoint(const IcpProblem& problem);
std::unique_ptr<IcpBaseline> MakePclPointToPlane(const IcpProblem& problem);
std::unique_ptr<IcpBaseline> MakeOpen3dPointToPlane(const IcpProblem& problem);

// Open3D's own normals of `points` (PointCloud::EstimateNormals over the `neighbours` nearest points, its
// k-d tree included), as a user of its point-to-plane ICP computes them for the target; empty when Open3D is
// absent from this build.
Eigen::Matrix3Xd Open3dEstimateNormals(const Eigen::Matrix3Xd& points, int neighbours);

// Open3D's multiway registration (its tutorial's pipeline, the anchor of the global scan-to-scan comparison):
// normals by EstimateNormals (12 nearest neighbours), point-to-plane ICP of every pair of views (each view's
// `samples` evenly spaced points against the other's full cloud, from the relative pose of `world_T_scan`),
// edges between consecutive views certain and the others uncertain, each weighted by
// GetInformationMatrixFromPointClouds, then GlobalOptimization (Levenberg-Marquardt with line processes,
// edge prune threshold 0.25, view 0 the reference). Returns every view's world_T_scan; empty when Open3D is
// absent from this build.
std::vector<RigidMotion> Open3dMultiway(const std::vector<Eigen::Matrix3Xd>& views,
                                        const std::vector<RigidMotion>& world_T_scan, int samples,
                                        double max_correspondence_distance);

}  // namespace s2m::bench
