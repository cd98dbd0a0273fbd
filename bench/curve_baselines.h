#pragma once
// Outside baselines of the fair-curve benchmark (bench/fair_curves.cpp): OpenCASCADE's variational smoothing
// (Geom2dAPI_PointsToBSpline with tension / flexion / jerk weights, AppDef_Variational inside), built only
// when OpenCASCADE is found at configure time (occt_curve_baseline.cpp), otherwise absent
// (no_occt_curve_baseline.cpp).

#include <Eigen/Core>
#include <optional>
#include <string>

#include "fitting/bspline_models.h"

namespace s2m::bench {

// Whether the baseline was built; `why` says why not.
bool OcctAvailable(std::string* why);

// A smoothing B-spline through ordered 2D points (open: OpenCASCADE has no closed variant), weights of the
// tension, flexion and jerk criteria, at most degree `max_degree` (C2), tolerance `tolerance`; as our
// BSplineCurve (its knots and poles). Empty when the algorithm fails or the baseline is absent.
std::optional<BSplineCurve> OcctSmoothing(const Eigen::Matrix2Xd& points, double tension, double flexion,
                                          double jerk, int max_degree, double tolerance);

}  // namespace s2m::bench
