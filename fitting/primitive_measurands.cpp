#include "fitting/primitive_measurands.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <random>
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

Eigen::MatrixXd LocalParameterCovariance(const Plane& shape, const Eigen::Matrix3Xd& points) {
  return CovarianceOf(shape, points);
}
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

template <class Shape>
Eigen::Matrix3Xd FeetOnShape(const Shape& shape, const Eigen::Matrix3Xd& points) {
  const double extent =
      points.cols() > 0 ? (points.rowwise().maxCoeff() - points.rowwise().minCoeff()).norm() : 1.0;
  const double h = 1e-7 * std::max(extent, 1e-300);
  Eigen::Matrix3Xd feet(3, points.cols());
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const Eigen::Vector3d x = points.col(i);
    Eigen::Vector3d gradient;
    for (int axis = 0; axis < 3; ++axis) {
      Eigen::Vector3d plus = x, minus = x;
      plus[axis] += h;
      minus[axis] -= h;
      gradient[axis] = (SignedDistance(shape, plus) - SignedDistance(shape, minus)) / (2 * h);
    }
    feet.col(i) = x - SignedDistance(shape, x) * gradient;
  }
  return feet;
}

template <class Shape>
double ResidualStandardDeviation(const Shape& shape, const Eigen::Matrix3Xd& points) {
  Eigen::VectorXd r;
  Eigen::Index p = 0;
  if constexpr (std::is_same_v<Shape, Circle3d> || std::is_same_v<Shape, Line3d>) {
    r = ResidualVector(shape, points);
  } else {
    r = SignedDistances(shape, points);
  }
  if constexpr (std::is_same_v<Shape, Plane>) {
    p = 3;
  } else {
    p = DistanceJacobian(shape, points.leftCols(std::min<Eigen::Index>(points.cols(), 1))).cols();
  }
  if (r.size() <= p) return std::nan("");
  return std::sqrt(r.squaredNorm() / static_cast<double>(r.size() - p));
}

namespace {

PrimitiveFitOptions QuietOptions() {
  PrimitiveFitOptions o;
  o.record_history = false;
  return o;
}
Plane Refit(const Eigen::Matrix3Xd& x, const Plane&) {
  return FitPlane(x, QuietOptions()).shape;
}
Line3d Refit(const Eigen::Matrix3Xd& x, const Line3d&) {
  return FitLine(x, QuietOptions()).shape;
}
Sphere Refit(const Eigen::Matrix3Xd& x, const Sphere& s) {
  return RefineSphere(x, s, QuietOptions()).shape;
}
Cylinder Refit(const Eigen::Matrix3Xd& x, const Cylinder& s) {
  return RefineCylinder(x, s, QuietOptions()).shape;
}
Cone Refit(const Eigen::Matrix3Xd& x, const Cone& s) {
  return RefineCone(x, s, QuietOptions()).shape;
}
Circle3d Refit(const Eigen::Matrix3Xd& x, const Circle3d& s) {
  return RefineCircle(x, s, QuietOptions()).shape;
}
Torus Refit(const Eigen::Matrix3Xd& x, const Torus& s) {
  return RefineTorus(x, s, QuietOptions()).shape;
}

}  // namespace

template <class Shape>
std::vector<MonteCarloSummary> MonteCarloByRefitting(
    const Shape& shape, const Eigen::Matrix3Xd& points, double sigma, int trials, std::uint64_t seed,
    const std::function<Eigen::VectorXd(const Shape& refit, const Eigen::Matrix3Xd& trial_points)>& outputs) {
  const Eigen::Matrix3Xd feet = FeetOnShape(shape, points);
  return RunMonteCarlo(trials, seed, [&](int, std::mt19937_64& random) -> std::optional<Eigen::VectorXd> {
    std::normal_distribution<double> normal(0.0, sigma);
    Eigen::Matrix3Xd trial = feet;
    for (Eigen::Index i = 0; i < trial.cols(); ++i)
      for (int c = 0; c < 3; ++c) trial(c, i) += normal(random);
    try {
      return outputs(Refit(trial, shape), trial);
    } catch (const std::exception&) {
      return std::nullopt;
    }
  });
}

#define S2M_INSTANTIATE(Shape)                                                      \
  template Eigen::Matrix3Xd FeetOnShape(const Shape&, const Eigen::Matrix3Xd&);     \
  template double ResidualStandardDeviation(const Shape&, const Eigen::Matrix3Xd&); \
  template std::vector<MonteCarloSummary> MonteCarloByRefitting(                    \
      const Shape&, const Eigen::Matrix3Xd&, double, int, std::uint64_t,            \
      const std::function<Eigen::VectorXd(const Shape&, const Eigen::Matrix3Xd&)>&);
S2M_INSTANTIATE(Plane)
S2M_INSTANTIATE(Line3d)
S2M_INSTANTIATE(Sphere)
S2M_INSTANTIATE(Cylinder)
S2M_INSTANTIATE(Cone)
S2M_INSTANTIATE(Circle3d)
S2M_INSTANTIATE(Torus)
#undef S2M_INSTANTIATE

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
