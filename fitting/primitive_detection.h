#pragma once
// Robust extraction of primitives (planes, spheres, cylinders, cones, tori) from raw scans with clutter:
// efficient RANSAC after Schnabel, Wahl & Klein, "Efficient RANSAC for point-cloud shape detection", Computer
// Graphics Forum 26(2) 2007 (docs/method.md section "Robust extraction", eqs. 49-59).
//
// Per point a normal from the PCA of its k nearest neighbours; candidates from minimal sets with normals
// (plane: 3 points, sphere and cylinder: 2 points, cone: 3 points, torus: 4 points), drawn by localized
// sampling (a point, then a cell of an octree-like grid around it, so that small objects in large scenes are
// found); a candidate's score is the number of points within a distance epsilon AND a normal angle alpha of
// it, restricted to the largest connected component of those points; the best candidate is accepted once the
// probability that a larger shape was missed is below a bound, refitted by the certified least-squares fits
// of primitive_fit.h with a robust loss, its inliers re-collected, and its points removed before the next
// instance. Deterministic for a given seed: one std::mt19937_64 draws every sample in order; OpenMP only
// scores candidates already drawn.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "fitting/primitive_fit.h"
#include "fitting/primitives.h"
#include "fitting/robust_loss.h"

namespace s2m {

enum class PrimitiveKind { kPlane, kSphere, kCylinder, kCone, kTorus };
const char* ToString(PrimitiveKind kind);
// "plane", "sphere", "cylinder", "cone", "torus"; throws std::invalid_argument otherwise.
PrimitiveKind PrimitiveKindFromString(const std::string& name);

struct DetectionOptions {
  std::vector<PrimitiveKind> kinds;  // at least one
  int max_instances = 10;
  // The smallest instance reported (points). 0: max(30, 0.001 N) for N input points.
  int min_support = 0;
  std::uint64_t seed = 1;
  // Inlier distance epsilon in input units; 0: epsilon_noise_factor * sigma with sigma the model-free noise
  // estimate (EstimateNoise) (eq. 55).
  double epsilon = 0.0;
  double epsilon_noise_factor = 3.0;
  // Each instance re-estimates its epsilon from its first refit's residuals, within [epsilon, 4 epsilon]
  // (eq. 59).
  bool adapt_epsilon = true;
  // Normal-angle threshold alpha (radians); 0: from the noise and the neighbourhoods' spread (eq. 55),
  // clamped to [min_alpha, max_alpha].
  double alpha = 0.0;
  double min_alpha = 0.2;
  double max_alpha = 0.6;
  // Connectivity (eq. 56). 0: two inliers are connected when one is among the other's normal_neighbours
  // nearest points of the cloud (the k-nearest-neighbour graph adapts to the spacing, which grows with range
  // and at grazing incidence); > 0: 26-connected cells of a grid of this size (input units).
  double cluster_cell = 0.0;
  // Neighbours of the PCA normals and of the connectivity graph (the normals ignored when given). 40: depth
  // cameras quantize depth in layers a few millimetres apart, and the normals of 12 neighbours within one
  // layer are wrong (measured on the mOSD scene test36: the table in eight slices with 12, one plane of
  // 101525 points with 40).
  int normal_neighbours = 40;
  // The probability of having missed a shape larger than the accepted one (eq. 57).
  double miss_probability = 0.01;
  // Draws of minimal sets per instance at most (the bound may not be reached then: reported).
  int max_draws = 60000;
  // Points of the random subset on which candidates are first scored (eq. 58).
  int score_subset = 3000;
  // Refit-and-recollect rounds on the accepted candidate's inliers.
  int refit_rounds = 2;
  // The refit's loss (robust_loss.h): Tukey's biweight with its scale from the inliers (eq. 47) by default.
  RobustLoss refit_loss = {LossKind::kTukey, 0.0};
  // Curved candidates with a radius above this are rejected (0: the diagonal of the data's bounding box): a
  // sphere or cylinder of huge radius is a plane seen badly. Cones' half-angles must lie in
  // [min_cone_half_angle, max_cone_half_angle] (radians), else they are a cylinder or a plane.
  double max_radius = 0.0;
  double min_cone_half_angle = 0.05;
  double max_cone_half_angle = 1.4;

  // Why the options cannot be used ("" when they can).
  bool IsValid(std::string* why = nullptr) const;
};

using DetectedShape = std::variant<Plane, Sphere, Cylinder, Cone, Torus>;

struct DetectedPrimitive {
  PrimitiveKind kind = PrimitiveKind::kPlane;
  DetectedShape shape;
  std::vector<ParameterUncertainty> uncertainties;  // from the refit (primitive_fit.h)
  std::vector<Eigen::Index> inliers;                // indices into the input points, ascending
  double rms = 0.0;                                 // RMS orthogonal distance of the inliers
  double epsilon = 0.0;                             // the instance's inlier distance (eq. 59)
  Eigen::Index support() const { return static_cast<Eigen::Index>(inliers.size()); }
  // The bound of eq. 57 when the instance was accepted, and the draws it took.
  double miss_probability = 1.0;
  int draws = 0;
};

struct DetectionResult {
  std::vector<DetectedPrimitive> instances;  // in the order found (largest first, as a rule)
  std::vector<Eigen::Index> rejected;        // points in no instance, ascending
  // The thresholds used (input units, radians) and what they came from.
  double noise_sigma = 0.0;
  double point_spacing = 0.0;  // median nearest-neighbour distance
  double epsilon = 0.0;
  double alpha = 0.0;
  double cluster_cell = 0.0;  // 0: the k-nearest-neighbour graph
  Eigen::Index min_support = 0;
  int octree_levels = 0;
  // Why the search stopped: "max-instances", "no-shape-left" (eq. 57 says no shape with min_support points
  // remains), "draw-limit" (the draws ran out before the bound was met) or "too-few-points".
  std::string stop_reason;
  double final_miss_probability = 1.0;  // eq. 57 for a shape of min_support points at the stop
};

// Detects instances of `options.kinds` among `points` (input units). `normals`: empty, or one unit normal
// per point (e.g. from the file); empty means PCA normals. Throws std::invalid_argument for invalid options,
// non-finite points, or fewer than 2 * normal_neighbours points.
DetectionResult DetectPrimitives(const Eigen::Matrix3Xd& points, const DetectionOptions& options,
                                 const Eigen::Matrix3Xd& normals = Eigen::Matrix3Xd());

// Unit normals by PCA of each point's k nearest neighbours (the point included), and for every point the
// standard uncertainty of that normal's direction for a noise sigma (eq. 53): sigma / sqrt(lambda_2) with
// lambda_2 the middle eigenvalue of the neighbours' scatter matrix. Sign arbitrary.
struct PointNormals {
  Eigen::Matrix3Xd normals;
  Eigen::VectorXd plane_residual;     // sqrt(lambda_0 / (k - 3)): the RMS distance from the PCA plane
  Eigen::VectorXd tangential_spread;  // sqrt(lambda_2) per point
  Eigen::VectorXd nearest_distance;   // distance to the nearest other point
  int neighbours = 0;
  std::vector<Eigen::Index> neighbour_indices;  // point i\'s neighbours at [i k, (i + 1) k), nearest first
};
PointNormals EstimatePointNormals(const Eigen::Matrix3Xd& points, int neighbours);

// Candidate constructions from minimal sets with normals (eqs. 49-52); nullopt for degenerate sets.
std::optional<Plane> PlaneFromPoints(const Eigen::Vector3d& p1, const Eigen::Vector3d& p2,
                                     const Eigen::Vector3d& p3);
std::optional<Sphere> SphereFromPointNormals(const Eigen::Vector3d& p1, const Eigen::Vector3d& n1,
                                             const Eigen::Vector3d& p2, const Eigen::Vector3d& n2);
std::optional<Cylinder> CylinderFromPointNormals(const Eigen::Vector3d& p1, const Eigen::Vector3d& n1,
                                                 const Eigen::Vector3d& p2, const Eigen::Vector3d& n2);
std::optional<Cone> ConeFromPointNormals(const Eigen::Vector3d& p1, const Eigen::Vector3d& n1,
                                         const Eigen::Vector3d& p2, const Eigen::Vector3d& n2,
                                         const Eigen::Vector3d& p3, const Eigen::Vector3d& n3);

// A torus from four points with normals (docs/method.md eq. 78): its axis meets every normal line (a surface
// of revolution's normals pass through its axis), and the lines meeting four given lines are found in
// Pluecker coordinates as the two roots of a quadratic on a pencil; for each real one the tube's centre in
// the meridian plane is where the points' normals cross (least squares over the four) and the minor radius
// the mean distance from it. Zero, one or two candidates; none for degenerate sets.
std::vector<Torus> TorusFromPointNormals(const std::array<Eigen::Vector3d, 4>& points,
                                         const std::array<Eigen::Vector3d, 4>& normals);

// The unit normal of the shape at the foot point of x (outward), for the normal-angle test.
Eigen::Vector3d SurfaceNormal(const DetectedShape& shape, const Eigen::Vector3d& x);
double Distance(const DetectedShape& shape, const Eigen::Vector3d& x);  // signed, outside positive

}  // namespace s2m
