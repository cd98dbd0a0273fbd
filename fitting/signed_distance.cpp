#include "fitting/signed_distance.h"

#include <Eigen/Geometry>  // cross products
#include <stdexcept>
#include <vector>

#include "fitting/foot_point.h"

namespace s2m {
namespace {

// Signed distances with the sign of (x - foot) . n, n = C_u x C_v at the foot point, optionally turned away
// from the z axis.
Eigen::VectorXd SignedDistances(const ParametricModel& model, const Eigen::Matrix3Xd& points,
                                bool away_from_axis, Eigen::Matrix3Xd* foot_points,
                                const std::vector<FootPoint>* known = nullptr) {
  std::vector<FootPoint> searched;
  if (known == nullptr) ComputeFootPoints(model, Eigen::MatrixXd(points), searched);
  const std::vector<FootPoint>& feet = known != nullptr ? *known : searched;
  Eigen::VectorXd out(points.cols());
  if (foot_points) foot_points->resize(3, points.cols());
  LocalGeometry g;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const FootPoint& foot = feet[static_cast<std::size_t>(i)];
    model.Evaluate(foot.t, 1, g);
    const Eigen::Vector3d c = To3(g.point);
    if (foot_points) foot_points->col(i) = c;
    Eigen::Vector3d n = To3(g.d1.col(0)).cross(To3(g.d1.col(1)));
    if (away_from_axis && n.dot(Eigen::Vector3d(c.x(), c.y(), 0.0)) < 0) n = -n;
    const double side = (Eigen::Vector3d(points.col(i)) - c).dot(n);
    out[i] = side < 0 ? -foot.distance : foot.distance;
  }
  return out;
}

}  // namespace

Eigen::VectorXd SignedDistancesAroundAxis(const ParametricModel& model, const Eigen::Matrix3Xd& points,
                                          Eigen::Matrix3Xd* feet, const std::vector<FootPoint>* known) {
  if (known != nullptr && known->size() != static_cast<std::size_t>(points.cols()))
    throw std::invalid_argument("one known foot point per point");
  return SignedDistances(model, points, true, feet, known);
}

Eigen::VectorXd SignedDistancesToFaces(const PartModel& part, const Eigen::Matrix3Xd& points,
                                       Eigen::Matrix3Xd* feet) {
  return SignedDistances(part, points, false, feet);
}

}  // namespace s2m
