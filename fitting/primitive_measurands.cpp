#include "fitting/primitive_measurands.h"

#include <cmath>
#include <type_traits>

#include "fitting/covariance.h"
#include "fitting/primitive_fit.h"

namespace s2m {

std::vector<std::string> MeasurandNames(const Sphere&) {
  return {"diameter"};
}
std::vector<std::string> MeasurandNames(const Cylinder&) {
  return {"diameter"};
}
std::vector<std::string> MeasurandNames(const Cone&) {
  return {"diameter_at_station"};
}
std::vector<std::string> MeasurandNames(const Circle3d&) {
  return {"diameter"};
}
std::vector<std::string> MeasurandNames(const Torus&) {
  return {"major_diameter", "minor_diameter"};
}

Eigen::VectorXd Measurands(const Sphere& s, const MeasurandContext&) {
  return Eigen::VectorXd::Constant(1, 2 * s.radius);
}
Eigen::VectorXd Measurands(const Cylinder& s, const MeasurandContext&) {
  return Eigen::VectorXd::Constant(1, 2 * s.radius);
}
Eigen::VectorXd Measurands(const Cone& s, const MeasurandContext& context) {
  // The section radius grows by tan(psi) per unit length along the axis from the axis point's section.
  const double along = s.axis_direction.normalized().dot(context.station - s.axis_point);
  return Eigen::VectorXd::Constant(1, 2 * (s.radius + std::tan(s.half_angle) * along));
}
Eigen::VectorXd Measurands(const Circle3d& s, const MeasurandContext&) {
  return Eigen::VectorXd::Constant(1, 2 * s.radius);
}
Eigen::VectorXd Measurands(const Torus& s, const MeasurandContext&) {
  Eigen::VectorXd y(2);
  y << 2 * s.major_radius, 2 * s.minor_radius;
  return y;
}

namespace {

template <class Shape>
Eigen::MatrixXd CovarianceOf(const Shape& shape, const Eigen::Matrix3Xd& points) {
  const Eigen::MatrixXd j = DistanceJacobian(shape, points);
  Eigen::VectorXd r;
  if constexpr (std::is_same_v<Shape, Circle3d>)
    r = ResidualVector(shape, points);
  else
    r = SignedDistances(shape, points);
  if (r.size() <= j.cols()) return {};
  const CovarianceEstimate e =
      EstimateCovariance(j.transpose() * j, r.squaredNorm(), static_cast<double>(r.size()));
  return e.covariance;
}

}  // namespace

Eigen::MatrixXd LocalParameterCovariance(const Sphere& shape, const Eigen::Matrix3Xd& points) {
  return CovarianceOf(shape, points);
}
Eigen::MatrixXd LocalParameterCovariance(const Cylinder& shape, const Eigen::Matrix3Xd& points) {
  return CovarianceOf(shape, points);
}
Eigen::MatrixXd LocalParameterCovariance(const Cone& shape, const Eigen::Matrix3Xd& points) {
  return CovarianceOf(shape, points);
}
Eigen::MatrixXd LocalParameterCovariance(const Circle3d& shape, const Eigen::Matrix3Xd& points) {
  return CovarianceOf(shape, points);
}
Eigen::MatrixXd LocalParameterCovariance(const Torus& shape, const Eigen::Matrix3Xd& points) {
  return CovarianceOf(shape, points);
}

template <class Shape>
std::vector<LinearPropagation> PropagateMeasurands(const Shape& shape, const Eigen::Matrix3Xd& points,
                                                   const MeasurandContext& context) {
  const Eigen::MatrixXd covariance = LocalParameterCovariance(shape, points);
  if (covariance.size() == 0) {
    std::vector<LinearPropagation> out;
    const Eigen::VectorXd y = Measurands(shape, context);
    for (Eigen::Index i = 0; i < y.size(); ++i) out.push_back({y[i], std::nan(""), Eigen::VectorXd()});
    return out;
  }
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(covariance.rows());
  return PropagateLinear(
      [&](const Eigen::VectorXd& delta) { return Measurands(ApplyIncrement(shape, delta), context); }, zero,
      covariance);
}

template std::vector<LinearPropagation> PropagateMeasurands(const Sphere&, const Eigen::Matrix3Xd&,
                                                            const MeasurandContext&);
template std::vector<LinearPropagation> PropagateMeasurands(const Cylinder&, const Eigen::Matrix3Xd&,
                                                            const MeasurandContext&);
template std::vector<LinearPropagation> PropagateMeasurands(const Cone&, const Eigen::Matrix3Xd&,
                                                            const MeasurandContext&);
template std::vector<LinearPropagation> PropagateMeasurands(const Circle3d&, const Eigen::Matrix3Xd&,
                                                            const MeasurandContext&);
template std::vector<LinearPropagation> PropagateMeasurands(const Torus&, const Eigen::Matrix3Xd&,
                                                            const MeasurandContext&);

}  // namespace s2m
