#pragma once
// Synthetic multi-view sources with known truth, for tests, benchmarks and demos: a model's surface sampled,
// seen by a scanner from several directions (a point is seen when its outward normal faces the scanner;
// self-occlusion is ignored), with Gaussian noise along the normal and device poses that are off by a
// given rotation and translation. And five reference cases of issue 4: a vase (surface of revolution), a
// helical screw, a spiral shell, the counterbored block of docs/examples/counterbored_block.part.json and a
// plate with a free-form top (a constrained part with a spline-patch face).

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "fitting/bspline_models.h"
#include "fitting/joint_fit.h"
#include "fitting/parametric_model.h"
#include "fitting/part_model.h"
#include "registration/rigid_motion.h"
#include "registration/scan.h"

namespace s2m {

struct SurfaceSample {
  Eigen::Matrix3Xd points;                           // model frame
  Eigen::Matrix3Xd normals;                          // unit, outward
  Eigen::Matrix2Xd parameters = Eigen::Matrix2Xd();  // (u, v) of each point where the sampler gives them
};

// `count` points uniform in the parameter box [u0, u1] x [v0, v1] of face 0, normals oriented away from the
// model's z axis (outward for surfaces around an axis).
SurfaceSample SampleAroundAxis(const ParametricModel& model, double u0, double u1, double v0, double v1,
                               int count, std::uint64_t seed);

// The block of docs/examples/counterbored_block.part.json (part frame: bottom centre, z up the bore) sampled
// uniformly by area on all its faces: values = width, depth, height, bore diameter, counterbore diameter,
// counterbore depth.
SurfaceSample SampleCounterboredBlock(const Eigen::VectorXd& values, int count, std::uint64_t seed);

// A plate width x depth, 10 thick, its bottom at z = 0 (part parameters "width", "depth"), whose top is a
// clamped uniform bicubic B-spline patch over the whole plate ("top", free_along z) with control points on
// the Greville grid in x and y (so x = (u - 1/2) width and y = (v - 1/2) depth exactly) at heights 10 +
// `displacement(i, j)`, each a free parameter "top[i,j]"; at least 4 x 4.
PartDefinition FreeformPlate(double width, double depth, const Eigen::MatrixXd& displacement);
// `count` points about uniform by area on the plate's six faces (the top by its (u, v): its slopes are
// small).
SurfaceSample SampleFreeformPlate(const PartModel& plate, int count, std::uint64_t seed);

struct ViewOptions {
  double noise = 0.0;               // standard deviation along the normal, model units
  double rotation_error = 0.0;      // radians: each recorded device pose is off by this, about a random axis
  double translation_error = 0.0;   // model units, in a random direction
  double scanner_distance = 300.0;  // from the model frame's origin, model units
  double min_facing_cosine = 0.25;  // a point is seen when n . (towards the scanner) exceeds this
  std::uint64_t seed = 1;
};

struct SyntheticViews {
  std::vector<Eigen::Matrix3Xd> scans;  // each in its scanner's coordinates
  std::vector<RigidMotion> model_T_scan_true;
  std::vector<RigidMotion> model_T_scan_recorded;  // the device's poses, off by the stated errors
};

// One view per unit direction (from the model towards the scanner).
SyntheticViews ScanFromDirections(const SurfaceSample& surface,
                                  const std::vector<Eigen::Vector3d>& directions, const ViewOptions& options);

// A FreeformPlate (50 x 30) whose top needs 7 x 5 control points (clamped uniform: inner knots at 1/4, 1/2,
// 3/4 along u and 1/2 along v, which knot insertion at span middles reaches from a 4 x 4 net), relief up to
// 0.5 mm; and 8 views of it (8000 points; 6 from 45 degrees above, 2 from 70), noise 0.02, recorded poses
// off by 1 degree and 1 mm (deterministic).
PartDefinition ReliefPlate();
SyntheticViews ReliefPlateViews();
// `count` directions at `elevation` (radians above the xy plane), equally spaced in azimuth from `azimuth0`.
std::vector<Eigen::Vector3d> RingOfDirections(int count, double elevation, double azimuth0 = 0.0);

// A measured quantity of a case with its truth and standard uncertainty.
struct MeasuredQuantity {
  std::string name;
  double truth = 0.0;
  double value = 0.0;
  double uncertainty = 0.0;
};

struct SyntheticCase {
  std::string name;
  std::unique_ptr<ParametricModel> truth;
  std::unique_ptr<ParametricModel> start;  // the initial model the fit starts from
  SyntheticViews views;
  JointFitOptions options;
  double noise = 0.0;
  // Directions the case leaves unobservable by design (besides control points sliding along a generatrix,
  // a re-parametrization): the fit must report exactly this many more.
  std::size_t gauge_directions = 0;
  // Quantities of the fitted model (gauge-free: comparable with the truth whatever the fixed gauge).
  std::function<std::vector<MeasuredQuantity>(const ParametricModel& fitted, const JointFitResult& result)>
      measure;
};

// "vase", "helical", "spiral", "part", "freeform" (a plate with a free-form spline-patch top): 8, 6, 6, 8 and
// 8 views, 0.02 mm noise, device poses off by 2 degrees and 2 mm (deterministic). Throws
// std::invalid_argument for other names. `sample_scale` multiplies the number of surface points sampled (8000
// to 16000 at 1, of which the views see a part; the benchmark's cost per point of each family uses larger
// ones).
SyntheticCase MakeSyntheticCase(const std::string& name, double sample_scale = 1.0);
std::vector<std::string> SyntheticCaseNames();

// The case as a recording: each view in its scanner's coordinates, placed by the device's (erroneous) pose in
// the model frame as world_T_scan, in millimetres.
ScanSet RecordedViews(const SyntheticCase& c);

// The error of each scan's fitted pose (model_T_scan) against the truth as (rotation vector, translation) in
// the model frame, with the components along the model's gauge removed (each scan's invariant motions; the
// common motions the shape absorbs, relative to scan 0): what the data can determine.
std::vector<Motion6> ObservablePoseErrors(const ParametricModel& model,
                                          const std::vector<RigidMotion>& fitted,
                                          const std::vector<RigidMotion>& truth);

// A single cloud of a kinematic surface with known axis (docs/method.md section 19): points with Gaussian
// noise along the surface normal, placed in a world frame where the axis is tilted and off the origin.
struct KinematicCloud {
  Eigen::Matrix3Xd points;  // world; the first `surface_points` on the surface, the rest on fracture faces
  Eigen::Index surface_points = 0;
  Eigen::Vector3d axis_point = Eigen::Vector3d::Zero();  // truth, world (a spiral's centre)
  Eigen::Vector3d axis_direction = Eigen::Vector3d::UnitZ();
  double pitch = 0.0;                      // truth (helical)
  double growth = 0.0;                     // truth (spiral)
  std::unique_ptr<ParametricModel> truth;  // in the axis frame
  RigidMotion world_T_model;
  // The truth's (u, v) of each surface point before the noise (the clouds around an axis; else empty): where
  // the sample really ends, for calibrations that separate the fit's error from the sampling's.
  Eigen::Matrix2Xd surface_parameters;
};

// A shallow thread: a helical surface of radius 28 mm whose generatrix rises and falls by 0.4 mm over one
// lead (pitch 4 mm/rad, lead 25.1 mm), three turns, seen all round: its normals are nearly radial, so the
// axis from normals (26) determines the axis well and the pitch poorly.
KinematicCloud ShallowThreadCloud(double relief, double noise, int count, std::uint64_t seed);

// A conical shell: a spiral surface (growth 0.05/rad) whose generatrix is a ray from the centre at 60
// degrees below the horizontal with a shallow ripple of 0.3 mm over one whorl, four whorls: the cone is
// invariant under every spiral motion about its apex, so (26) hardly determines the growth.
KinematicCloud ConicalShellCloud(double ripple, double noise, int count, std::uint64_t seed);

// A shell with allometric growth (docs/shells.md eq. S1): the "spiral" case's whorl (20-31 mm from the axis
// and 16 mm high at v = 0), growth 0.12/rad at v = 0 changing by `growth_change` per radian, the axial scale
// growing faster than the radial by `axial_excess` per radian; two whorls (v from -pi to 3 pi) seen all
// round. growth_change = axial_excess = 0 is a logarithmic shell.
KinematicCloud AllometricShellCloud(double growth_change, double axial_excess, double noise, int count,
                                    std::uint64_t seed);

// A sherd: `arc_fraction` of the circumference of the demo vase's surface of revolution (150 mm tall,
// radius 30-66 mm) between heights of about 30 and 110 mm, one surface (the outside), its side breaks
// slanted; with `fracture_faces`, points also on the breaks of a 6 mm thick wall (planar-ish faces
// perpendicular to the surface along the sherd's outline, as dense as the surface).
KinematicCloud SherdCloud(double arc_fraction, bool fracture_faces, double noise, int count,
                          std::uint64_t seed);

// The sherds of the archaeology tests (docs/archaeology.md section 9), from the same vase and wall.
struct SherdSpec {
  double arc_fraction = 0.25;  // of the circumference, at the sherd's widest
  // A rim sherd: the top edge is the vase's rim (150 mm, level across the axis) and the sherd reaches down to
  // about 95 mm; otherwise a body sherd between about 30 and 110 mm.
  bool rim = false;
  // Breaks across the profile (the top and bottom edges of a body sherd, the bottom edge of a rim sherd)
  // wander up and down by up to about 6 mm along the arc, as real breaks do; false: cut level.
  bool irregular_breaks = true;
  bool fracture_faces = false;  // points on the breaks, as dense as the surface
  bool lip = false;             // a rim sherd's lip (the face across the wall at the rim) scanned too
  bool inner_surface = false;   // the inside scanned too: the wall's inner surface, 6 mm in along the normal
  bool upside_down = false;     // placed in the world rim down (the axis' world direction points down)
  double noise = 0.05;          // mm, along the normal
  int count = 8000;             // points on the outer surface (the inner one gets as many per area)
  std::uint64_t seed = 1;
};
// The cloud and what the sherd measures should find. `surface_points` counts the outer surface's points,
// which come first; then the inner surface's (`inner_points` of them), then the breaks'.
struct SherdTruth {
  KinematicCloud cloud;
  Eigen::Index inner_points = 0;
  double wall_thickness = 6.0;            // mm, along the outer surface's normal
  double profile_lo = 0, profile_hi = 0;  // the generatrix parameters the sherd spans (at its widest)
  double rim_diameter = 0;                // the outer surface's diameter at the top of the sherd
  // The arc of the outer surface at profile parameter u, in radians about the axis from a fixed start; empty
  // where the sherd does not reach height u (outside its top and bottom edges).
  std::function<std::optional<std::pair<double, double>>(double u)> arc;
};
SherdTruth MakeSherd(const SherdSpec& spec);

// A whole vessel scanned inside and out (docs/archaeology.md section 10): the demo vase's surface of
// revolution (radius 30-66 mm, u in [0.3, 5], heights about 6 to 150 mm) all round as the outside, and its
// offset 6 mm in along the normal as the inside, `count` points on each, Gaussian noise along the normal.
// The outside's points come first (`cloud.surface_points` of them), then the inside's. `with_base`: instead
// a straight-walled pot with its base, the generatrix starting on the axis and running level out to a
// rounded foot (the outside's underside at height 0, the inside's floor 6 mm above it) before it rises
// straight to the rim (radius 42 mm, height 80 mm).
struct WallTruth {
  KinematicCloud cloud;  // truth: the outer surface, in the axis frame
  Eigen::Index inner_points = 0;
  double thickness = 6.0;  // mm, square to the wall, at every height
  // The inner surface's lowest and highest heights in the axis frame, and the volume it encloses between
  // them (numerical integration of the offset generatrix, relative error below 1e-9).
  double inner_lo = 0, inner_hi = 0, capacity = 0;
};
WallTruth MakeTwoSurfaceVessel(double noise, int count, std::uint64_t seed, bool with_base = false);

// The bumpy 100 x 100 mm free-form patch of the registration benchmark (bench/compare.cpp, section 1) and of
// the foot point and squared distance field tests: a bicubic B-spline (clamped, unit-spaced knots) with
// 10 x 10 control points over [-50, 50]^2 at heights
//   z = 10 sin(0.07 x + 0.4) cos(0.05 y - 0.3) + 0.002 x y + x_tilt x
// (bumps of 10 mm, curvature radii >= about 20 mm), whose shape fixes all six degrees of freedom of a scan on
// it. x_tilt = 0.03 is the benchmark's; the foot point tests use 0.
BSplineSurface BumpyPatch(double x_tilt = 0.03);

}  // namespace s2m
