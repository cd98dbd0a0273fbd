#pragma once
// Primitives as models of the fitting engine (closed-form foot points): the same surfaces as primitive_fit.h,
// here parametrized globally so that the engine's error terms, step control and, later, the joint solver can
// use them.

#include "fitting/parametric_model.h"
#include "fitting/primitives.h"

namespace s2m {

// C(theta, h) = p + R (r cos theta, r sin theta, h), R's third column the axis. Parameters: axis point p (3),
// a rotation increment of the frame (3, linearized at zero, applied exactly), radius r. The axial shift of p
// and the rotation about the axis are gauge freedoms (re-parametrizations), left to the damping.
class CylinderModel final : public ParametricModel {
 public:
  explicit CylinderModel(const Cylinder& cylinder);
  Cylinder shape() const;

  std::unique_ptr<ParametricModel> Clone() const override { return std::make_unique<CylinderModel>(*this); }
  void CopyFrom(const ParametricModel& other) override { *this = dynamic_cast<const CylinderModel&>(other); }
  std::string name() const override { return "cylinder"; }
  int ambient_dimension() const override { return 3; }
  ParameterDomain domain() const override;
  int num_parameters() const override { return 7; }
  std::string parameter_name(int index) const override;
  Eigen::VectorXd parameters() const override;
  void set_parameters(const Eigen::VectorXd& p) override;
  void ApplySimilarity(double scale, const VecS& offset) override;
  void Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const override;
  void ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const override;
  std::vector<ParamT> SampleParameters() const override;
  bool ClosedFormFootPoint(const VecS& x, ParamT& t) const override;
  bool ClosedFormFoot(const VecS& x, ParamT& t, double& distance, bool& on_boundary,
                      bool& ambiguous) const override;
  // Per scan in the joint solver: the rotation about and the translation along the (start) axis.
  std::vector<Motion6> InvariantMotions() const override;
  // The cylinder carries its own pose: any motion of all scans together is a motion of the cylinder.
  std::vector<Motion6> CommonMotionsAbsorbedByShape() const override;

 private:
  Eigen::Vector3d point_;
  Eigen::Matrix3d frame_;
  double radius_;
};

// C(theta, phi) = c + r (cos phi cos theta, cos phi sin theta, sin phi) in a frame R whose poles (+-z) should
// lie away from the data (the parametrization is singular there). Parameters: centre (3), radius.
class SphereModel final : public ParametricModel {
 public:
  explicit SphereModel(const Sphere& sphere, const Eigen::Matrix3d& frame = Eigen::Matrix3d::Identity());
  Sphere shape() const { return {center_, radius_}; }

  std::unique_ptr<ParametricModel> Clone() const override { return std::make_unique<SphereModel>(*this); }
  void CopyFrom(const ParametricModel& other) override { *this = dynamic_cast<const SphereModel&>(other); }
  std::string name() const override { return "sphere"; }
  int ambient_dimension() const override { return 3; }
  ParameterDomain domain() const override;
  int num_parameters() const override { return 4; }
  std::string parameter_name(int index) const override;
  Eigen::VectorXd parameters() const override;
  void set_parameters(const Eigen::VectorXd& p) override;
  void ApplySimilarity(double scale, const VecS& offset) override;
  void Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const override;
  void ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const override;
  std::vector<ParamT> SampleParameters() const override;
  bool ClosedFormFootPoint(const VecS& x, ParamT& t) const override;
  bool ClosedFormFoot(const VecS& x, ParamT& t, double& distance, bool& on_boundary,
                      bool& ambiguous) const override;
  // Per scan in the joint solver: the three rotations about the (start) centre.
  std::vector<Motion6> InvariantMotions() const override;
  // The sphere carries its own position: a common translation of all scans moves its centre.
  std::vector<Motion6> CommonMotionsAbsorbedByShape() const override;

 private:
  Eigen::Vector3d center_;
  Eigen::Matrix3d frame_;
  double radius_;
};

// L(t) = p + t a with a the third column of a frame R. Parameters: point p (3), a rotation increment of the
// frame (3, linearized at zero, applied exactly). The shift of p along the line and the rotation about it
// are gauge freedoms, left to the damping. Closed-form feet: t = a.(x - p).
class LineModel final : public ParametricModel {
 public:
  explicit LineModel(const Line3d& line);
  Line3d shape() const { return {point_, frame_.col(2)}; }

  std::unique_ptr<ParametricModel> Clone() const override { return std::make_unique<LineModel>(*this); }
  void CopyFrom(const ParametricModel& other) override { *this = dynamic_cast<const LineModel&>(other); }
  std::string name() const override { return "3D line"; }
  int ambient_dimension() const override { return 3; }
  ParameterDomain domain() const override;
  int num_parameters() const override { return 6; }
  std::string parameter_name(int index) const override;
  Eigen::VectorXd parameters() const override;
  void set_parameters(const Eigen::VectorXd& p) override;
  void ApplySimilarity(double scale, const VecS& offset) override;
  void Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const override;
  void ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const override;
  std::vector<ParamT> SampleParameters() const override;
  bool ClosedFormFootPoint(const VecS& x, ParamT& t) const override;
  bool ClosedFormFoot(const VecS& x, ParamT& t, double& distance, bool& on_boundary,
                      bool& ambiguous) const override;
  // Per scan: the rotation about and the translation along the line.
  std::vector<Motion6> InvariantMotions() const override;
  std::vector<Motion6> CommonMotionsAbsorbedByShape() const override;

 private:
  Eigen::Vector3d point_;
  Eigen::Matrix3d frame_;
};

// T(theta, phi) = c + R ((R0 + r cos phi) cos theta, (R0 + r cos phi) sin theta, r sin phi), R's third column
// the axis, R0 the major and r the minor radius. Parameters: centre (3), a rotation increment of the frame
// (3), R0, r. The rotation about the axis is a gauge freedom. Closed-form feet (docs/metrology.md eq. 4):
// theta = atan2(q_y, q_x), phi = atan2(q_z, rho - R0) for q = R^T (x - c), rho = |(q_x, q_y)|; ambiguous on
// the axis (rho = 0).
class TorusModel final : public ParametricModel {
 public:
  explicit TorusModel(const Torus& torus);
  Torus shape() const { return {center_, frame_.col(2), major_, minor_}; }

  std::unique_ptr<ParametricModel> Clone() const override { return std::make_unique<TorusModel>(*this); }
  void CopyFrom(const ParametricModel& other) override { *this = dynamic_cast<const TorusModel&>(other); }
  std::string name() const override { return "torus"; }
  int ambient_dimension() const override { return 3; }
  ParameterDomain domain() const override;
  int num_parameters() const override { return 8; }
  std::string parameter_name(int index) const override;
  Eigen::VectorXd parameters() const override;
  void set_parameters(const Eigen::VectorXd& p) override;
  void ApplySimilarity(double scale, const VecS& offset) override;
  void Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const override;
  void ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const override;
  std::vector<ParamT> SampleParameters() const override;
  bool ClosedFormFootPoint(const VecS& x, ParamT& t) const override;
  bool ClosedFormFoot(const VecS& x, ParamT& t, double& distance, bool& on_boundary,
                      bool& ambiguous) const override;
  // Per scan: the rotation about the axis.
  std::vector<Motion6> InvariantMotions() const override;
  std::vector<Motion6> CommonMotionsAbsorbedByShape() const override;

 private:
  Eigen::Vector3d center_;
  Eigen::Matrix3d frame_;
  double major_, minor_;
};

}  // namespace s2m
