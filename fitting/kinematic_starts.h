#pragma once
// Global starts for kinematic surfaces (docs/method.md section 19). The joint fit is local: it needs an axis
// within a few degrees, a pitch or growth within about 20 % and a generatrix near the data. The axis from
// normals (26) gives that on clean data of a whole object, but not
// - when points of other surfaces (fracture faces of a sherd, a stand, flying pixels) enter its sums:
//   RobustKinematicAxisFromNormals reweights them away (IRLS, eq. 71);
// - when the normals hardly constrain the pitch or growth (a shallow thread, a drill's flutes): the pitch
//   or growth comes from a global 1-D search over the data's self-similarity, the entropy of the points in
//   the invariant coordinates of the candidate motion (eqs. 72-74), over a log-spaced grid spanning a factor
//   `search_factor` each side of the normals' estimate, both signs;
// - when the surface of revolution covers a small arc (a sherd): the axis comes from a search over
//   directions scored by how well the points collapse onto one smooth meridian profile (eqs. 75-76), then a
//   local least-squares refinement of that score.
// Each start comes with the points it finds off the surface (eq. 77); FitJointlyFromStarts runs the joint
// fit from the best few starts and keeps the lowest final robust objective.

#include <Eigen/Core>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "fitting/initial_models.h"
#include "fitting/joint_fit.h"
#include "fitting/parametric_model.h"
#include "fitting/robust_loss.h"
#include "registration/rigid_motion.h"

namespace s2m {

// The axis from normals by iteratively reweighted least squares on the residuals e_j = n_j . v(x_j) of (26)
// at |c| = 1 (eq. 71): weights rho'(e_j^2) of `loss` (fitting/robust_loss.h), its scale from the MAD of the
// residuals (eq. 47) at every iteration, from the plain solution until the direction settles. `weights`
// (optional) receives the final weights: 0 for the points the loss rejects. Throws as
// KinematicAxisFromNormals.
KinematicAxis RobustKinematicAxisFromNormals(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                                             KinematicKind kind, const RobustLoss& loss = {LossKind::kTukey},
                                             Eigen::VectorXd* weights = nullptr);

// The residuals e_j = n_j . v(x_j) of (26) for a found axis (|c| = 1; input units).
Eigen::VectorXd AxisFromNormalsResiduals(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                                         const KinematicAxis& axis, KinematicKind kind);

// The test of eq. (77) for points off a fitted surface: a point is off when its distance exceeds
// `distance_in_sigma` robust standard deviations of all distances (eq. 47; 4.6851 is Tukey's rejection point)
// or its normal makes more than the angle limit with the surface normal at its foot. The limit is
// max_angle_deg, or with `angle_from_spread` it is taken from the normals' own spread (eq. 77a: the angles of
// the points within the distance band read as Rayleigh distributed, the limit where their tail equals the
// distance test's two-sided normal tail), kept within [min_angle_deg, max_angle_deg]. The command turns the
// spread on for fragments (docs/method.md section 19), whose breaks' creases it is for: estimated normals
// can have a far heavier tail than a Rayleigh's (measured on a whole thin-walled vessel, whose points are all
// on its surfaces), and a whole object keeps the fixed limit.
struct OffSurfaceTest {
  double distance_in_sigma = 4.6851;
  bool angle_from_spread = false;
  double min_angle_deg = 5.0;
  double max_angle_deg = 45.0;
  // Points within the distance band needed to read the normals' spread; fewer: max_angle_deg.
  int min_points_for_spread = 20;

  bool IsValid(std::string* why = nullptr) const;
};

struct KinematicStartOptions {
  int num_control = 8;  // of the initial generatrix
  int order = 4;
  // The pitch or growth grid spans [|e| / f, f |e|] around the normals' estimate e (both signs), log-spaced
  // with ratio `grid_ratio` between neighbours (eq. 74).
  double search_factor = 30.0;
  double grid_ratio = 1.01;
  // The pitch or growth to centre the grid on instead of the normals' estimate (0: the normals'), e.g. a
  // nominal value the user knows.
  double estimate = 0.0;
  int max_starts = 3;           // starts returned (and joint fits run by FitJointlyFromStarts)
  int max_sample = 4000;        // points the searches use (a deterministic stride through the data)
  int direction_samples = 600;  // revolution: directions on a hemisphere scored by (54)
  RobustLoss axis_loss{LossKind::kTukey};  // of the axis from normals (eq. 71)
  double profile_margin = 0.05;            // revolution: InitialRevolution's margin
  OffSurfaceTest off_surface;              // which points are left out as off the surface (eq. 77)
};

// Invariant coordinates of points under a candidate motion (eqs. 72-73) and the entropy of their
// occupancy (eq. 74), for a helical motion of pitch p about the z axis of the points' frame: profile
// coordinate the radius, phase (z - p theta) / (2 pi |p|) modulo 1.
double HelicalPhaseEntropy(const Eigen::Matrix3Xd& points_in_axis_frame, double pitch, int bins = 32);
// For a spiral motion of growth g about the z axis through the origin (the centre): profile coordinate the
// meridian angle atan2(z, rho), phase (ln |x| - g theta) / (2 pi |g|) modulo 1.
double SpiralPhaseEntropy(const Eigen::Matrix3Xd& points_in_centre_frame, double growth, int bins = 32);

// A local minimum of the entropy over the grid, refined by a parabola in log |value|.
struct SpectrumPeak {
  double value = 0.0;
  double entropy = 0.0;
};
// The grid of (52) about the normals' estimate (its centre max(|estimate|, reference_scale), both signs),
// its local minima sorted by entropy (lowest first). `entropy_of` maps a candidate to its entropy.
std::vector<SpectrumPeak> SpectrumPeaks(double estimate, double reference_scale,
                                        const KinematicStartOptions& options,
                                        const std::function<double(double)>& entropy_of);

// The robust scale (eq. 47) of the meridian profile residuals (eq. 75) of points about an axis: how well the
// points collapse onto one smooth generatrix (a B-spline function of height, or of radius when the points
// span more radius than height).
double ProfileCollapseScore(const Eigen::Matrix3Xd& points, const Eigen::Vector3d& axis_point,
                            const Eigen::Vector3d& axis_direction, int num_control);

struct AxisCandidate {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();
  double score = 0.0;  // ProfileCollapseScore, input units
  std::string source;  // "normals", "cylinder", "direction search"
};
// Axes of a surface of revolution (a whole object or a small arc of it), best first (eq. 76): the robust
// axis from normals, the best cylinder's axis, and the best directions of a hemisphere each with its axis
// point from the normals (26) at that direction and zero pitch, every one refined by least squares on
// (53) over direction and point; distinct ones only (more than 1 degree or 1 % of the data's size apart).
std::vector<AxisCandidate> RevolutionAxisCandidates(const Eigen::Matrix3Xd& points,
                                                    const Eigen::Matrix3Xd& normals,
                                                    const KinematicStartOptions& options = {});

struct KinematicStart {
  RigidMotion world_T_model;  // the model frame: z along the axis, origin on it (a spiral's centre)
  std::shared_ptr<ParametricModel> model;  // the initial surface in that frame
  double score = 0.0;             // robust scale (eq. 47) of the initial surface's distances to the points
  std::string source;             // how the axis and pitch or growth were found
  double searched_value = 0.0;    // the pitch or growth the search found (0 for revolution)
  double normals_value = 0.0;     // the normals' estimate of it
  std::vector<bool> off_surface;  // per input point (eq. 77) at the initial surface
};

// The best few starts (at most options.max_starts, best score first) of a surface of revolution, helical
// or spiral surface for `points` (world) with unit `normals` (sign arbitrary). Throws std::invalid_argument
// when the points cannot carry an axis (too few, normals spanning less than 3D).
std::vector<KinematicStart> FindKinematicStarts(const Eigen::Matrix3Xd& points,
                                                const Eigen::Matrix3Xd& normals, KinematicKind kind,
                                                const KinematicStartOptions& options = {});

// Points off a fitted surface by `test` (eq. 77, 77a). `normals` may be empty (distance test only). Fills
// `sigma` with the distances' robust scale, `distances` with every point's distance and `angle_limit_deg`
// with the normal limit used (0 without normals) when given.
std::vector<bool> PointsOffTheSurface(const ParametricModel& model, const Eigen::Matrix3Xd& points,
                                      const Eigen::Matrix3Xd& normals, const OffSurfaceTest& test,
                                      double* sigma = nullptr, Eigen::VectorXd* distances = nullptr,
                                      double* angle_limit_deg = nullptr);

// The normal limit of eq. (77a) from the angles (radians) between the normals of the points within the
// distance band and the surface's: Rayleigh scale median / sqrt(2 ln 2), limit where the Rayleigh tail
// equals the two-sided normal tail at `distance_in_sigma`, clamped to the test's range (degrees).
double NormalAngleLimitDeg(std::vector<double> angles_rad, const OffSurfaceTest& test);

// The all-points objective of a fit (eq. 79): the mean over ALL points, those left out as off the surface
// included, of Tukey's rho (eq. 44) of their distances at the common scale c = 4.6851 s, divided by its
// value beyond c, so that it lies in [0, 1]: about 0.05 for a fit at the noise (s the noise), and each point
// farther than c counts 1 whichever start left it behind. Unlike a robust scale (47), which ignores up to
// half of the points, it cannot be won by leaving a view or a stretch of the surface behind.
double AllPointsObjective(const Eigen::Ref<const Eigen::VectorXd>& distances, double scale);

// The distances of the scans placed by `model_T_scan` to `model`, all points, scan after scan.
Eigen::VectorXd PlacedDistances(const ParametricModel& model, const std::vector<Eigen::Matrix3Xd>& scans,
                                const std::vector<RigidMotion>& model_T_scan);

// The fraction of a full turn about the axis (point, unit direction) the points cover (eq. 80): the
// occupied share of 72 sectors of 5 degrees, a sector counting when it holds at least a tenth of the mean
// count of the occupied ones (stray points do not widen a sherd). 1 for a whole object.
double CoveredTurnFraction(const Eigen::Matrix3Xd& points, const Eigen::Vector3d& axis_point,
                           const Eigen::Vector3d& axis_direction);

struct StartedJointFit {
  std::shared_ptr<ParametricModel> model;  // fitted
  RigidMotion world_T_model;               // of the chosen start (the fit's model frame)
  JointFitResult result;
  std::size_t chosen = 0;                // index into the starts
  std::vector<double> final_scores;      // per start tried: robust scale (47) of all points' distances
  std::vector<double> final_objectives;  // per start tried: AllPointsObjective (eq. 79)
  std::vector<Eigen::Index> left_out_per_start;
  double objective_scale = 0.0;                   // s of eq. 79
  Eigen::Index left_out = 0;                      // points left out as off the surface in the chosen fit
  std::vector<std::vector<bool>> left_out_masks;  // per scan, of the chosen fit
};

// The joint fit (FitJointly) from each start: poses model_T_world * world_T_scan, the start's off-surface
// points left out; at its solution the off-surface points are decided again against the fitted surface
// (per-scan normals `scan_normals`, in scan coordinates; may be empty) and, when they changed, the fit is
// run once more from there. The start whose final fit has the lowest all-points objective (eq. 79) at the
// common scale `noise` wins (a start cannot win by leaving points out); `noise` NaN or not positive: the
// smallest robust scale (47) among the final fits. Throws what FitJointly throws.
StartedJointFit FitJointlyFromStarts(const std::vector<KinematicStart>& starts,
                                     const std::vector<Eigen::Matrix3Xd>& scans,
                                     const std::vector<RigidMotion>& world_T_scan,
                                     const std::vector<Eigen::Matrix3Xd>& scan_normals,
                                     const JointFitOptions& options,
                                     const KinematicStartOptions& start_options = {},
                                     double noise = std::numeric_limits<double>::quiet_NaN());

}  // namespace s2m
