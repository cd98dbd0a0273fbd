#pragma once
// Initial models for the fitting engine (METHOD.md section 8).

#include <Eigen/Core>

#include "fitting/bspline_models.h"

namespace s2m {

// Uniform knots with unit spacing (knot values 0, 1, 2, ...): the convention under which the paper's fairness
// weights (bending 0.001 for curves in the unit box) are meant.
BSplineBasis UnitSpacedClamped(int order, int num_control);
BSplineBasis UnitSpacedPeriodic(int order, int num_control);

// A B-spline curve through the chain of occupied quadtree cells of 2D data (Wang, Pottmann, Liu 2006, section
// 6): cells of the finest level with between 2 and 8 cells per control point are chained by nearest
// neighbours and the chain is resampled by arc length into the control polygon. Throws std::invalid_argument
// for fewer than 3 points.
BSplineCurve InitialCurveFromQuadtree(const Eigen::Matrix2Xd& points, int num_control, int order,
                                      bool closed);

enum class SurfaceProjection { kPlane, kCylinder };

// A B-spline surface by linear least squares over a parametrization of the points by projection onto their
// fitted plane (clamped in u and v) or fitted cylinder (periodic in u = angle, clamped in v = axial
// position), with a small thin-plate term so that cells without data stay smooth.
BSplineSurface InitialSurfaceByProjection(const Eigen::Matrix3Xd& points, int num_control_u,
                                          int num_control_v, int order, SurfaceProjection projection);

// A surface of revolution about the z axis of the frame the points are given in: the generatrix (r(u), z(u))
// by linear least squares over u proportional to height, with a small bending term (an initial model for the
// joint fit).
class KinematicSurface;
KinematicSurface InitialRevolution(const Eigen::Matrix3Xd& points_in_axis_frame, int num_control, int order);

}  // namespace s2m
