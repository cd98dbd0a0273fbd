// Stand-in when Open3D is absent from the build: the benchmark reports the Open3D rows as not run.
#include "bench/icp_baselines.h"

namespace s2m::bench {
bool HaveOpen3d() {
  return false;
}
std::unique_ptr<IcpBaseline> MakeOpen3dPointToPlane(const IcpProblem&) {
  return nullptr;
}
Eigen::Matrix3Xd Open3dEstimateNormals(const Eigen::Matrix3Xd&, int) {
  return {};
}
std::vector<RigidMotion> Open3dMultiway(const std::vector<Eigen::Matrix3Xd>&, const std::vector<RigidMotion>&,
                                        int, double) {
  return {};
}
}  // namespace s2m::bench
