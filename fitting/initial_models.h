#pragma once
// Initial models for the fitting engine (docs/method.md section 8).

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
// `margin`: the generatrix reaches that fraction of the points' height range beyond them at each end (its
// end spans then follow from the bending term), so that a small tilt of the axis in the joint fit does not
// carry points past its ends.
KinematicSurface InitialRevolution(const Eigen::Matrix3Xd& points_in_axis_frame, int num_control, int order,
                                   double margin = 0.0);
// The same with u proportional to `along` (one value per point) instead of the height: a position along the
// generatrix for a profile that is not a function of height (a base running level to the axis).
KinematicSurface InitialRevolutionAlong(const Eigen::Matrix3Xd& points_in_axis_frame,
                                        const Eigen::VectorXd& along, int num_control, int order,
                                        double margin = 0.0);

// A helical surface about the z axis of the frame the points are given in, with the given pitch: every point
// is screwed back onto the half-plane v = 0; its turn is chosen by cutting the heights z - pitch * theta,
// taken modulo the lead 2 pi |pitch|, at their largest gap (a single-start thread's profile spans less than
// one lead). The generatrix is then fitted as in InitialRevolution. The angle range covers the data plus
// `margin` radians on each side (a gauge shift must not push data off the model's ends).
class SpiralSurface;
KinematicSurface InitialHelical(const Eigen::Matrix3Xd& points_in_axis_frame, double pitch, int num_control,
                                int order, double margin = 1.0);
// The same with the pitch refined first: the pitch from normals is biased when the views are mis-registered
// (measured: 3.58 for a true 4 from views off by 2 degrees and 2 mm). A scan of +-20 % in 2.5 % steps and a
// parabola through the best three keep the pitch whose initial surface lies closest to the points (RMS of
// the foot-point distances).
KinematicSurface InitialHelicalWithPitchSearch(const Eigen::Matrix3Xd& points_in_axis_frame, double pitch,
                                               int num_control, int order);
// Likewise for the growth of a spiral surface (measured: 0.104 from normals for a true 0.12, views off by 2
// degrees and 2 mm).
SpiralSurface InitialSpiralWithGrowthSearch(const Eigen::Matrix3Xd& points_in_centre_frame, double growth,
                                            int num_control, int order);
// A spiral surface about the z axis through the origin (the centre) of the frame, with the given growth: each
// point's whorl is chosen likewise from ln|x| - growth * theta modulo 2 pi |growth| (whorls do not overlap),
// and the point is scaled back by e^{-growth v} onto the generatrix.
SpiralSurface InitialSpiral(const Eigen::Matrix3Xd& points_in_centre_frame, double growth, int num_control,
                            int order, double margin = 0.3);

// The axis of a kinematic surface from surface normals by line geometry (docs/method.md section 8; Pottmann,
// Randrup, "Rotational and helical surface approximation for reverse engineering", Computing 60 (1998); for
// spiral surfaces Hofer, Pottmann, Ravani, "From curve design algorithms to the design of rigid body
// motions", Visual Computer 20 (2004), equiform motions). The surface is invariant under a one-parameter
// motion whose velocity field v(x) = cbar + c x x + gamma x is tangent to it, so every point x_j with normal
// n_j satisfies n_j . v(x_j) = (x_j x n_j) . c + n_j . cbar + gamma n_j . x_j = 0: linear in (c, cbar,
// gamma). Least squares with |c| = 1 eliminates (cbar, gamma) (a Schur complement) and leaves the smallest
// eigenvector of a 3 x 3 matrix. Revolution: gamma = 0 and the pitch is reported but not used; helical:
// pitch c . cbar, axis through c x cbar; spiral: growth gamma, centre where v vanishes.
enum class KinematicKind { kRevolution, kHelical, kSpiral };
struct KinematicAxis {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  // on the axis; the spiral's centre
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();
  double pitch = 0.0;     // axial advance per radian (helical; near 0 for a surface of revolution)
  double growth = 0.0;    // spiral growth per radian (spiral)
  double residual = 0.0;  // RMS of n_j . v(x_j) at the solution, |c| = 1 (input units)
};
// Throws std::invalid_argument for fewer than 8 points, mismatched sizes or normals spanning less than 3D.
KinematicAxis KinematicAxisFromNormals(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                                       KinematicKind kind);
// The same with a non-negative weight per point in the sums of (26) (the IRLS step of the robust axis,
// fitting/kinematic_starts.h); weight 0 leaves a point out.
KinematicAxis KinematicAxisFromNormals(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                                       KinematicKind kind, const Eigen::VectorXd& weights);

}  // namespace s2m
