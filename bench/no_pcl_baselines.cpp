// Stand-ins when PCL is absent from the build: the benchmark reports the PCL rows as not run.
#include "bench/icp_baselines.h"

namespace s2m::bench {
bool HavePcl() {
  return false;
}
std::unique_ptr<IcpBaseline> MakePclPointToPoint(const IcpProblem&) {
  return nullptr;
}
std::unique_ptr<IcpBaseline> MakePclPointToPlane(const IcpProblem&) {
  return nullptr;
}
}  // namespace s2m::bench
