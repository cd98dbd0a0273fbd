#pragma once
// Derived quantities (measurands) of the fitted primitives and their covariance route (docs/metrology.md
// section 6): the covariance of the fit's local parameters V = s^2 (J^T J)^+ (the Gauss-Newton covariance
// behind the reported standard uncertainties, fitting/covariance.h), and each measurand as a function of the
// local increment delta, y = f(ApplyIncrement(shape, delta)), so the law of propagation (JCGM 100:2008, eq.
// 13) takes its sensitivities at delta = 0.
//
// Measurands: sphere, cylinder, circle: the diameter; cone: the diameter in the plane across the axis
// through `station` (the data's centroid: the cone's diameter at the data's mid-height, a quantity that
// depends on the axis point, the direction, the radius and the half-angle together); torus: the major and
// the minor diameter. Planes and lines have none (their form error is handled by the zone, section 7).

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "fitting/measurement_uncertainty.h"
#include "fitting/primitives.h"

namespace s2m {

struct MeasurandContext {
  Eigen::Vector3d station = Eigen::Vector3d::Zero();  // cone: where the diameter is taken
};

std::vector<std::string> MeasurandNames(const Sphere&);
std::vector<std::string> MeasurandNames(const Cylinder&);
std::vector<std::string> MeasurandNames(const Cone&);
std::vector<std::string> MeasurandNames(const Circle3d&);
std::vector<std::string> MeasurandNames(const Torus&);
Eigen::VectorXd Measurands(const Sphere& s, const MeasurandContext& context);
Eigen::VectorXd Measurands(const Cylinder& s, const MeasurandContext& context);
Eigen::VectorXd Measurands(const Cone& s, const MeasurandContext& context);
Eigen::VectorXd Measurands(const Circle3d& s, const MeasurandContext& context);
Eigen::VectorXd Measurands(const Torus& s, const MeasurandContext& context);

// V = s^2 (J^T J)^+ of the local parameters at `shape` (the least-squares solution for `points`), with
// s^2 = sum r^2 / (m - p) over the m residuals (2 per point for circles). Empty when m <= p.
Eigen::MatrixXd LocalParameterCovariance(const Plane& shape, const Eigen::Matrix3Xd& points);
Eigen::MatrixXd LocalParameterCovariance(const Sphere& shape, const Eigen::Matrix3Xd& points);
Eigen::MatrixXd LocalParameterCovariance(const Cylinder& shape, const Eigen::Matrix3Xd& points);
Eigen::MatrixXd LocalParameterCovariance(const Cone& shape, const Eigen::Matrix3Xd& points);
Eigen::MatrixXd LocalParameterCovariance(const Circle3d& shape, const Eigen::Matrix3Xd& points);
Eigen::MatrixXd LocalParameterCovariance(const Torus& shape, const Eigen::Matrix3Xd& points);

// The measurands of `shape` with their standard uncertainties by the law of propagation from
// LocalParameterCovariance (NaN uncertainties when it is empty).
template <class Shape>
std::vector<LinearPropagation> PropagateMeasurands(const Shape& shape, const Eigen::Matrix3Xd& points,
                                                   const MeasurandContext& context);

// The closest points of `shape` to the points: x - d grad d, the gradient of the distance d by central
// differences (step 1e-7 of the points' extent).
template <class Shape>
Eigen::Matrix3Xd FeetOnShape(const Shape& shape, const Eigen::Matrix3Xd& points);

// The residuals' standard deviation s = sqrt(sum r^2 / (m - p)) of a least-squares fit (m residuals, 2 per
// point for circles and lines; p local parameters); NaN when m <= p.
template <class Shape>
double ResidualStandardDeviation(const Shape& shape, const Eigen::Matrix3Xd& points);

// GUM Supplement 1 (JCGM 101:2008) by refitting: each trial moves every foot of the fit (FeetOnShape) by an
// isotropic normal error of standard deviation `sigma` per coordinate (the model the least-squares
// covariance assumes: its normal component has variance sigma^2), refits from `shape` (Refine* for sphere,
// cylinder, cone, circle and torus; Fit* for plane and line) and evaluates `outputs` of the refit and the
// trial's points. Trials whose refit throws are counted as failed. One summary per output.
template <class Shape>
std::vector<MonteCarloSummary> MonteCarloByRefitting(
    const Shape& shape, const Eigen::Matrix3Xd& points, double sigma, int trials, std::uint64_t seed,
    const std::function<Eigen::VectorXd(const Shape& refit, const Eigen::Matrix3Xd& trial_points)>& outputs);

}  // namespace s2m
