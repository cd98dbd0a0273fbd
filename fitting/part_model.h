#pragma once
// Constrained parts (docs/method.md section 7, last item; Liu, Pottmann, Wang, CAD 38(6) 2006, section 6):
// several faces (plane, cylinder, cone, sphere, torus, B-spline patch) placed in ONE adapted part frame and
// sharing named parameters, e.g. a block whose top face lies at z = height and whose counterbore floor at z =
// height
// - depth. Every face quantity is a linear expression in the named parameters, so the part's shape Jacobian
// is exact and cheap; the orientation of each face in the part frame is fixed (it is the design), the part's
// pose is what the joint solver's per-scan motions find.
//
// Each data point belongs to the face of its nearest foot point (the smallest distance wins): in closed form
// on the analytic faces, by safeguarded Newton from the nearest of the patch's samples on a spline patch.
// Analytic faces are complete surfaces (an unbounded plane, an infinite cylinder): a point is assigned
// wrongly only within its own distance of where two faces' extensions cross, which costs at most that
// distance. A spline patch is bounded by its parameter rectangle; beyond it its nearest point lies on its
// border.
//
// Parameter t = (u, v, face): planes u, v along the face's e1, e2; surfaces of revolution u the angle about
// the face's axis; cylinder and cone v along the axis, sphere v the latitude, torus v the angle about the
// tube; spline patches the B-spline parameters.

#include <array>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "fitting/bspline_basis.h"
#include "fitting/bspline_models.h"
#include "fitting/fit_result.h"
#include "fitting/parametric_model.h"
#include "registration/nearest_index.h"

namespace s2m {

// value = constant + sum coefficient * P[index], over the part's named (free) parameters.
struct LinearExpression {
  double constant = 0.0;
  std::vector<std::pair<int, double>> terms;  // (parameter index, coefficient)

  double Evaluate(const Eigen::VectorXd& parameters) const;
};

enum class FaceType { kPlane, kCylinder, kCone, kSphere, kTorus, kSplinePatch };
const char* ToString(FaceType type);

// A tensor-product B-spline patch S(u, v) = sum_i sum_j N_i(u) M_j(v) P_ij (Piegl & Tiller, The NURBS Book,
// eq. 3.11) over clamped bases, its control points in the part frame with every coordinate a linear
// expression: a free-form face that moves, stretches or deforms with the part's named parameters.
struct SplinePatch {
  BSplineBasis u = BSplineBasis::ClampedUniform(4, 4);
  BSplineBasis v = BSplineBasis::ClampedUniform(4, 4);
  // u-major: P_ij at index i * v.num_control() + j.
  std::vector<std::array<LinearExpression, 3>> control_points;
  // Free-form patches (docs/parts.md, "free_along"): every control point P_ij has its own free displacement
  // along `free_along` (unit), the part parameter first_displacement + i * v.num_control() + j (u-major, in
  // one block). -1: none (the patch only moves and stretches with the named parameters).
  Eigen::Vector3d free_along = Eigen::Vector3d::Zero();
  int first_displacement = -1;
};

struct PartFace {
  std::string name;
  FaceType type = FaceType::kPlane;
  // Fixed orientation in the part frame, orthonormal and right-handed: columns e1, e2, and the axis
  // (planes: the normal; cone: towards increasing radius).
  Eigen::Matrix3d frame = Eigen::Matrix3d::Identity();
  // Cylinder, cone, torus: a point on the axis; sphere: the centre. Unused for planes.
  std::array<LinearExpression, 3> origin;
  LinearExpression offset;  // plane: normal . x = offset
  // Cylinder, sphere: the radius; cone: the radius of the cross-section through `origin`; torus: the
  // distance from the axis to the tube's centre circle.
  LinearExpression radius;
  LinearExpression minor_radius;     // torus: the tube's radius
  LinearExpression half_angle;       // cone, radians, in (0, pi/2)
  std::optional<SplinePatch> patch;  // spline patches only (their frame is unused)
};

struct PartParameter {
  std::string name;
  double value = 0.0;
  bool angle = false;  // radians; otherwise a length (scales with the data)
};

struct PartDefinition {
  std::string name;
  std::vector<PartParameter> parameters;  // the free ones; fixed values are constants of the expressions
  std::vector<PartFace> faces;
};

class PartModel final : public ParametricModel {
 public:
  // Throws std::invalid_argument naming the face for: no faces, a frame that is not a rotation, an
  // expression that refers to an unknown parameter or mixes lengths and angles, a radius, angle or
  // offset out of range at the given values, or a spline patch whose control net does not match its bases
  // or is not open (clamped) in both directions.
  explicit PartModel(PartDefinition definition);

  const PartDefinition& definition() const { return definition_; }
  int face_count() const { return static_cast<int>(definition_.faces.size()); }
  static int FaceOf(const ParamT& t) { return static_cast<int>(t[2]); }

  std::unique_ptr<ParametricModel> Clone() const override { return std::make_unique<PartModel>(*this); }
  void CopyFrom(const ParametricModel& other) override { *this = dynamic_cast<const PartModel&>(other); }
  std::string name() const override { return definition_.name.empty() ? "part" : definition_.name; }
  int ambient_dimension() const override { return 3; }
  ParameterDomain domain() const override;
  int num_parameters() const override { return static_cast<int>(values_.size()); }
  std::string parameter_name(int index) const override;
  Eigen::VectorXd parameters() const override { return values_; }
  void set_parameters(const Eigen::VectorXd& p) override;
  void ApplySimilarity(double scale, const VecS& offset) override;
  void Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const override;
  void ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const override;
  std::vector<ParamT> SampleParameters() const override;
  // The part computes its own feet (closed form per analytic face, Newton on spline patches; see above).
  bool ClosedFormFootPoint(const VecS& x, ParamT& t) const override;
  bool FootPointOnBoundary(const VecS& x, const ParamT& t) const override;
  // True when another face lies within the edge margin of x: near an edge the nearest face is a guess, and a
  // wrong guess is biased (the top face's points next to a side are all on the material side of that side's
  // plane, pulling it inwards by a fraction of the noise).
  bool AmbiguousFootPoint(const VecS& x, const ParamT& t) const override;
  // All three in one pass: the distance is the face's own (closed form or Newton's), and the ambiguity test
  // reuses the feet on the other faces found while searching for the nearest one.
  bool ClosedFormFoot(const VecS& x, ParamT& t, double& distance, bool& on_boundary,
                      bool& ambiguous) const override;

  // Points closer than this (model units) to a second face are left out of fits; 0 (default) keeps all.
  // About 3 x the scanner's noise: FitPartJointly (joint_fit.h) sets it from a first pass.
  void set_edge_margin(double margin) { edge_margin_ = margin; }
  double edge_margin() const { return edge_margin_; }

 private:
  // What a spline patch needs at the current parameter values: the B-spline surface of its evaluated
  // control points, and samples in a k-d tree that seed its foot points. Rebuilt whenever the values change
  // (never lazily: feet are computed in parallel).
  struct PatchState {
    std::optional<BSplineSurface> surface;
    std::vector<ParamT> sample_parameters;
    NearestIndex samples;
    // Every point of the patch lies within this distance of a sample (the largest distance between grid
    // neighbours, diagonals included): dist(x, nearest sample) - covering_radius bounds dist(x, patch) below.
    double covering_radius = 0.0;
  };
  // The closed-form faces' quantities at the current parameter values (each expression evaluated once per
  // change of the values, not once per point and face). Unused fields are 0.
  struct FaceConstants {
    Eigen::Vector3d origin = Eigen::Vector3d::Zero();
    double offset = 0.0, radius = 0.0, minor_radius = 0.0;
    double sin_alpha = 0.0, cos_alpha = 0.0;  // cone
  };
  void Validate() const;
  void UpdatePatches();
  void UpdateFaceConstants();
  // Distance from x to face k. A spline patch that cannot come closer than `needed_within` is not searched
  // (distance infinity): most points are far from most patches; a patch searched also gives its foot's
  // parameter in `patch_t` (Newton finds both). An analytic face's parameter is computed only for the face
  // that wins (FaceParameter): the angle costs an atan2, the distance does not need it.
  double FaceDistance(std::size_t k, const Eigen::Vector3d& x, double needed_within, ParamT& patch_t) const;
  ParamT FaceParameter(std::size_t k, const Eigen::Vector3d& x) const;  // analytic faces only
  // The face nearest to x (analytic faces first: their distances let most spline patches be skipped), its
  // foot's parameter and distance; -1 when no face has a distance below infinity (t untouched). With
  // `face_distance`, the distance to each of the first kKept faces searched (infinity: a patch skipped).
  static constexpr std::size_t kKept = 32;
  int NearestFace(const Eigen::Vector3d& x, ParamT& t, double& distance,
                  std::array<double, kKept>* face_distance) const;

  PartDefinition definition_;
  Eigen::VectorXd values_;
  double edge_margin_ = 0.0;
  std::vector<PatchState> patches_;        // parallel to the faces; empty for analytic faces
  std::vector<FaceConstants> constants_;   // parallel to the faces
  std::vector<std::size_t> search_order_;  // analytic faces, then spline patches
};

// Distances of the points (part frame) to their nearest faces, grouped by face: per face the count, RMS and
// largest distance of the points assigned to it.
std::vector<ResidualStatistics> PerFaceResiduals(const PartModel& part, const Eigen::Matrix3Xd& points);

}  // namespace s2m
