#pragma once
// B-spline models for the fitting engine: curves in the plane or in space (open or closed) and tensor-product
// surfaces (clamped, or periodic in u). P enters linearly (docs/method.md section 7).

#include "fitting/bspline_basis.h"
#include "fitting/parametric_model.h"

namespace s2m {

// Per-span power-form (local polynomial) coefficients of a B-spline curve with up to 3 coordinates, for fast
// evaluation: on span s the curve is sum_j a_j y^j in the span's local coordinate y
// (BSplineBasis::LocateSpan), a_j = sum_i c_ji P_(first + i) with c_ji the basis' Taylor coefficients (the
// change to the local power basis, Piegl & Tiller section 6.6), evaluated by Horner's rule. Shared by
// BSplineCurve and KinematicSurface's generatrix; rebuild it whenever the control points change.
class SpanPowerForm {
 public:
  // control: s x basis.num_control(), s <= 3.
  void Build(const BSplineBasis& basis, const Eigen::Ref<const Eigen::MatrixXd>& control);
  // r[d][c] = derivative d (d <= derivatives, else 0) with respect to t of coordinate c (c >= s: 0) at t.
  void Evaluate(const BSplineBasis& basis, double t, int derivatives, double (&r)[3][3]) const;
  bool empty() const { return coefficients_.empty(); }

 private:
  // a_j of span s, padded to 3 doubles, at coefficients_[3 (s order + j) + c].
  std::vector<double> coefficients_;
  int dimension_ = 3;  // s: the lanes Evaluate computes
};

// The fairness matrix of one coordinate of a B-spline curve (or a generatrix) on basis `b`: stretch, bending
// and Fang's curvature variation and junction jumps (docs/method.md section 3, docs/fair-curves.md section
// 8).
Eigen::MatrixXd CurveFairness(const BSplineBasis& b, const FairnessWeights& w);

class BSplineCurve final : public ParametricModel {
 public:
  // control_points: s x n (s = 2 or 3), n == basis.num_control().
  BSplineCurve(BSplineBasis basis, Eigen::MatrixXd control_points);

  const BSplineBasis& basis() const { return basis_; }
  const Eigen::MatrixXd& control_points() const { return control_; }

  std::unique_ptr<ParametricModel> Clone() const override { return std::make_unique<BSplineCurve>(*this); }
  void CopyFrom(const ParametricModel& other) override { *this = dynamic_cast<const BSplineCurve&>(other); }
  std::string name() const override {
    return basis_.periodic() ? "closed B-spline curve" : "open B-spline curve";
  }
  int ambient_dimension() const override { return static_cast<int>(control_.rows()); }
  ParameterDomain domain() const override;
  int num_parameters() const override { return static_cast<int>(control_.size()); }
  std::string parameter_name(int index) const override;
  Eigen::VectorXd parameters() const override;
  void set_parameters(const Eigen::VectorXd& p) override;
  void ApplySimilarity(double scale, const VecS& offset) override;
  void Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const override;
  void ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const override;
  // Control point i moves C by B_i(t) along each coordinate: weights B_i(t), directions the unit axes.
  bool FactoredShapeJacobian(const ParamT& t, FactoredJacobian& out) const override;
  Eigen::MatrixXd FairnessMatrix(const FairnessWeights& weights) const override;
  std::vector<ParamT> SampleParameters() const override;

 private:
  BSplineBasis basis_;
  Eigen::MatrixXd control_;  // s x n
  SpanPowerForm spans_;      // rebuilt whenever control_ changes
};

class BSplineSurface final : public ParametricModel {
 public:
  // control_points: 3 x (nu * nv), index i * nv + j for basis_u function i and basis_v function j.
  BSplineSurface(BSplineBasis basis_u, BSplineBasis basis_v, Eigen::Matrix3Xd control_points);

  const BSplineBasis& basis_u() const { return basis_u_; }
  const BSplineBasis& basis_v() const { return basis_v_; }
  const Eigen::Matrix3Xd& control_points() const { return control_; }

  std::unique_ptr<ParametricModel> Clone() const override { return std::make_unique<BSplineSurface>(*this); }
  void CopyFrom(const ParametricModel& other) override { *this = dynamic_cast<const BSplineSurface&>(other); }
  std::string name() const override { return "tensor-product B-spline surface"; }
  int ambient_dimension() const override { return 3; }
  ParameterDomain domain() const override;
  int num_parameters() const override { return static_cast<int>(control_.size()); }
  std::string parameter_name(int index) const override;
  Eigen::VectorXd parameters() const override;
  void set_parameters(const Eigen::VectorXd& p) override;
  void ApplySimilarity(double scale, const VecS& offset) override;
  void Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const override;
  void ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const override;
  // Control point (i, j) moves S by B_i(u) B_j(v) along each axis: weights B_i(u) B_j(v), directions the unit
  // axes; false when a span has more control points than FactoredJacobian holds (above bicubic).
  bool FactoredShapeJacobian(const ParamT& t, FactoredJacobian& out) const override;
  Eigen::MatrixXd FairnessMatrix(const FairnessWeights& weights) const override;
  std::vector<ParamT> SampleParameters() const override;

 private:
  void BuildPatches();

  BSplineBasis basis_u_, basis_v_;
  Eigen::Matrix3Xd control_;
  // Bicubic surfaces (order 4 x 4, the common case): per patch (span su of u, span sv of v) the power-form
  // coefficients of S in the spans' local coordinates, A_jk with S = sum_jk A_jk y^j z^k: 16 points padded
  // to 4 doubles, at patches_[64 (su num_spans_v + sv) + 16 j + 4 k + c]. Rebuilt whenever control_ changes;
  // empty for other orders (Evaluate then sums the basis functions).
  std::vector<double> patches_;
};

// A 3D ellipse (or circle) C(t) = c + R (a cos t, b sin t, 0), t in [0, 2 pi). Parameters: centre (3), a
// rotation increment (3, linearized at zero and applied exactly as R <- R exp([w]x)), then a and b (ellipse)
// or r (circle).
class Ellipse3D final : public ParametricModel {
 public:
  Ellipse3D(const Eigen::Vector3d& center, const Eigen::Matrix3d& rotation, double a, double b,
            bool circle = false);

  const Eigen::Vector3d& center() const { return center_; }
  const Eigen::Matrix3d& rotation() const { return rotation_; }
  Eigen::Vector3d normal() const { return rotation_.col(2); }
  double a() const { return a_; }
  double b() const { return circle_ ? a_ : b_; }

  std::unique_ptr<ParametricModel> Clone() const override { return std::make_unique<Ellipse3D>(*this); }
  void CopyFrom(const ParametricModel& other) override { *this = dynamic_cast<const Ellipse3D&>(other); }
  std::string name() const override { return circle_ ? "3D circle" : "3D ellipse"; }
  int ambient_dimension() const override { return 3; }
  ParameterDomain domain() const override;
  int num_parameters() const override { return circle_ ? 7 : 8; }
  std::string parameter_name(int index) const override;
  Eigen::VectorXd parameters() const override;
  void set_parameters(const Eigen::VectorXd& p) override;
  // Applies the step, then keeps a, b positive by turning the frame half a turn (the same point set).
  void ApplyStep(const Eigen::VectorXd& step) override;
  void ApplySimilarity(double scale, const VecS& offset) override;
  void Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const override;
  void ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const override;
  std::vector<ParamT> SampleParameters() const override;
  // Circles only (the ellipse's foot is a quartic: the engine's Newton feet): in the circle's plane the
  // nearest point lies on the ray from the centre through x's projection, t = atan2(q_y, q_x) for q = R^T
  // (x - c), at the distance sqrt(q_z^2 + (rho - a)^2) (docs/metrology.md eq. 2). Ambiguous on the axis.
  bool ClosedFormFootPoint(const VecS& x, ParamT& t) const override;
  bool ClosedFormFoot(const VecS& x, ParamT& t, double& distance, bool& on_boundary,
                      bool& ambiguous) const override;

 private:
  Eigen::Vector3d center_;
  Eigen::Matrix3d rotation_;
  double a_, b_;
  bool circle_;
};

}  // namespace s2m
