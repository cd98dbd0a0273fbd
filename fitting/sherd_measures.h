#pragma once
// What a fragment of a surface of revolution (a sherd) tells about its vessel beyond the fitted axis and
// profile (docs/archaeology.md section 9): which end of the profile is the rim (its stance: the rim up,
// the axis vertical) and the fraction of the circumference that is preserved, with its standard
// uncertainty from the axis' (the poses') covariance and from the sampling of the break.

#include <Eigen/Core>
#include <limits>
#include <string>
#include <vector>

#include "fitting/kinematic_surfaces.h"

namespace s2m {

struct SherdMeasureOptions {
  // The covered arc is cut into this many sectors of equal angle; in each, the highest and the lowest point
  // along the axis trace the sherd's top and bottom edges.
  int sectors = 8;
  // An edge is level (across the axis, as a rim is) when its robust spread over the sectors is within what a
  // level edge shows from the sampling and the noise alone in all but this fraction of cases: the (1 -
  // level_false_rejection) quantile of the spread under that null (eq. A13a), from `null_draws` seeded draws.
  // A level edge (a rim) is then missed this often; the smaller it is, the wider the limit and the more often
  // a break that is nearly level is taken for a rim.
  double level_false_rejection = 1e-3;
  int null_draws = 20000;
  // The preserved fraction is measured in a band this deep (a fraction of the sherd's height) below the rim,
  // or, on a body sherd, in each of `bands` bands of equal height but the two at the ends (the one whose
  // central 90 % of points spans the widest arc is reported, eq. A14a; thin bands keep a break slanting
  // across one from thinning its ends); a band needs `min_band_points` points (when no band has them, the
  // sherd is cut into half as many bands, and so on; with fewer than three bands none is left out).
  double rim_band_depth = 0.03;
  int bands = 20;
  int min_band_points = 30;
  bool IsValid(std::string* why = nullptr) const;
};

// An edge of the sherd across the profile: its height along the axis sector by sector.
struct EdgeLevelness {
  double height = std::numeric_limits<double>::quiet_NaN();    // median over the sectors
  double spread = std::numeric_limits<double>::quiet_NaN();    // 1.4826 x median |h_s - height|
  double expected = std::numeric_limits<double>::quiet_NaN();  // of a level edge (eq. A13)
  double limit = std::numeric_limits<double>::quiet_NaN();     // a level edge's spread stays under (A13a)
  int sectors = 0;                                             // holding points
  bool level = false;
};

// The angular extent of the points in a band of heights, as a fraction of the full turn.
struct PreservedArc {
  double fraction = std::numeric_limits<double>::quiet_NaN();     // (eq. A14), corrected for the sampling
  double uncertainty = std::numeric_limits<double>::quiet_NaN();  // combined (eq. A16)
  double axis_uncertainty = std::numeric_limits<double>::quiet_NaN();      // from the poses (eq. A15)
  double sampling_uncertainty = std::numeric_limits<double>::quiet_NaN();  // from the point spacing
  // The range of the central 90 % of the points (their angles' 5th to 95th percentile): what the band's
  // arc sets and its two end points hardly move (eq. A14a).
  double central_fraction = std::numeric_limits<double>::quiet_NaN();
  double height_lo = 0, height_hi = 0;  // the band, model frame (along the axis)
  Eigen::Index points = 0;
};

struct SherdMeasures {
  // The part of the circumference the points cover (the turn less its largest empty gap).
  double covered_fraction = std::numeric_limits<double>::quiet_NaN();
  EdgeLevelness upper, lower;  // the edges at the larger and at the smaller height along the model's z
  // +1: the rim is the upper edge (larger z), -1: the lower one; 0: not told by the edges (both level, or
  // neither), `rim_reason` says which.
  int rim_side = 0;
  std::string rim_reason;
  PreservedArc preserved;  // in the band below the rim, or the widest band of a body sherd
  bool preserved_at_rim = false;
};

// `points`: the sherd's surface points in the model frame of the fitted surface of revolution (its axis is
// the z axis), the points judged off the surface (breaks) left out; `view_of_point[i]` the view point i came
// from and `pose_covariance[k]` the 6x6 covariance of view k's pose correction (rotation c, then translation
// cbar, in the model frame: x' = x + cbar + c x x; radians and the points' units); `noise` the data's
// noise (the points' units). Throws std::invalid_argument for invalid options, mismatched sizes or fewer
// than `min_band_points` points.
SherdMeasures MeasureSherd(const Eigen::Matrix3Xd& points, const std::vector<int>& view_of_point,
                           const std::vector<Eigen::Matrix<double, 6, 6>>& pose_covariance, double noise,
                           const SherdMeasureOptions& options = {});

// The angular extent of `points` about the z axis as a fraction of a turn, corrected for the sampling, with
// its uncertainty (eqs. A14-A16), and the range of its central 90 % (A14a); points with heights outside
// [height_lo, height_hi] are skipped. NaN when fewer than `min_points` are inside. Throws
// std::invalid_argument when a point's view has no pose covariance.
PreservedArc MeasureArc(const Eigen::Matrix3Xd& points, const std::vector<int>& view_of_point,
                        const std::vector<Eigen::Matrix<double, 6, 6>>& pose_covariance, double height_lo,
                        double height_hi, int min_points);

// Which of `points` (in the frame of `surface`, a surface of revolution about the z axis) lie within `band`
// of its generatrix continued beyond each end (docs/archaeology.md eq. A12a): the end's second-order Taylor
// expansion in the (radius, height) half-plane, over one end knot span's parameter length. A sherd's
// generatrix can end short of its surface points (trimmed to the feet of the points the fit kept, eq. 70);
// those beyond the end lie on the continuation, the breaks' faces across it. Throws std::invalid_argument
// for a helical surface, a periodic basis or a band that is not positive.
std::vector<bool> NearGeneratrixContinuation(const KinematicSurface& surface, const Eigen::Matrix3Xd& points,
                                             double band);

}  // namespace s2m
