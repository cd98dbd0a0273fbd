#pragma once
// Constrained parts (METHOD.md section 7, last item; Liu, Pottmann, Wang, CAD 38(6) 2006, section 6): several
// faces (plane, cylinder, cone, sphere, torus) placed in ONE adapted part frame and sharing named parameters,
// e.g. a block whose top face lies at z = height and whose counterbore floor at z = height - depth. Every
// face quantity is a linear expression in the named parameters, so the part's shape Jacobian is exact and
// cheap; the orientation of each face in the part frame is fixed (it is the design), the part's pose is what
// the joint solver's per-scan motions find.
//
// Each data point belongs to the face of its nearest foot point (closed form per face, the smallest distance
// wins). Faces are complete surfaces (an unbounded plane, an infinite cylinder): a point is assigned wrongly
// only within its own distance of where two faces' extensions cross, which costs at most that distance.
//
// Parameter t = (u, v, face): planes u, v along the face's e1, e2; surfaces of revolution u the angle about
// the face's axis; cylinder and cone v along the axis, sphere v the latitude, torus v the angle about the
// tube.

#include <array>
#include <string>
#include <utility>
#include <vector>

#include "fitting/fit_result.h"
#include "fitting/parametric_model.h"

namespace s2m {

// value = constant + sum coefficient * P[index], over the part's named (free) parameters.
struct LinearExpression {
  double constant = 0.0;
  std::vector<std::pair<int, double>> terms;  // (parameter index, coefficient)

  double Evaluate(const Eigen::VectorXd& parameters) const;
};

enum class FaceType { kPlane, kCylinder, kCone, kSphere, kTorus };
const char* ToString(FaceType type);

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
  LinearExpression minor_radius;  // torus: the tube's radius
  LinearExpression half_angle;    // cone, radians, in (0, pi/2)
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
  // expression that refers to an unknown parameter or mixes lengths and angles, or a radius, angle or
  // offset out of range at the given values.
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
  bool ClosedFormFootPoint(const VecS& x, ParamT& t) const override;
  // True when another face lies within the edge margin of x: near an edge the nearest face is a guess, and a
  // wrong guess is biased (the top face's points next to a side are all on the material side of that side's
  // plane, pulling it inwards by a fraction of the noise).
  bool AmbiguousFootPoint(const VecS& x, const ParamT& t) const override;

  // Points closer than this (model units) to a second face are left out of fits; 0 (default) keeps all.
  // About 3 x the scanner's noise: FitPartJointly (joint_fit.h) sets it from a first pass.
  void set_edge_margin(double margin) { edge_margin_ = margin; }
  double edge_margin() const { return edge_margin_; }

 private:
  void Validate() const;
  PartDefinition definition_;
  Eigen::VectorXd values_;
  double edge_margin_ = 0.0;
};

// Distances of the points (part frame) to their nearest faces, grouped by face: per face the count, RMS and
// largest distance of the points assigned to it.
std::vector<ResidualStatistics> PerFaceResiduals(const PartModel& part, const Eigen::Matrix3Xd& points);

}  // namespace s2m
