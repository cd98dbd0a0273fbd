#pragma once
// Hermite finite-element curves (L. Fang, MIT PhD thesis 1994, section 3.2; docs/fair-curves.md sections
// 1-3): a curve w(u), u in [0, 1], in 2D or 3D, made of polynomial elements between nodes u_0 < u_1 < ...;
// each node carries the position and the first (cubic, C1) or first and second (quintic, C2) derivatives with
// respect to u, shared by the two elements that meet there. Open curves have elements + 1 nodes; closed ones
// as many nodes as elements, the last element joining the last node to the first (the domain is periodic).
//
// The model's parameters are the nodal dofs numbered node by node, [w(u_0), w'(u_0), (w''(u_0)), w(u_1), ...]
// with the coordinates of each dof consecutive, so that the fairness matrix is banded. A cubic curve made C2
// by the reduced transformation (Fang section 5.3, docs/fair-curves.md eq. F11) has the positions (and, open,
// the two end slopes) as parameters; its interior slopes follow from them.

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "fitting/element_energy.h"
#include "fitting/parametric_model.h"

namespace s2m {

// The Hermite shape functions of one element of degree 3 or 5 (Fang Table 3.1, docs/fair-curves.md eq. F3):
// power coefficients in t = u / h, rows in dof order [w(0), w'(0), (w''(0)), w(h), w'(h), (w''(h))], the
// derivative dofs' rows scaled by h^k.
Eigen::MatrixXd HermiteShapeCoefficients(int degree, double h);
// The element as an ElementBasis (y = t on [0, 1]).
ElementBasis HermiteElementBasis(int degree, double h);

// The fairness weights of Fang's energy (docs/fair-curves.md eq. F1): alpha_p integral |w^(p)|^2 du for
// p = 1..3, and beta_p sum over junctions |jump of w^(p)|^2 for p = 2, 3; on the parameter domain [0, 1].
struct HermiteFairness {
  double alpha1 = 0.0;  // stretch
  double alpha2 = 0.0;  // bending
  double alpha3 = 0.0;  // curvature variation
  double beta2 = 0.0;   // second-derivative jumps (cubic only: a quintic is C2 by construction)
  double beta3 = 0.0;   // third-derivative jumps
  bool IsZero() const { return alpha1 == 0 && alpha2 == 0 && alpha3 == 0 && beta2 == 0 && beta3 == 0; }
};

class HermiteCurve final : public ParametricModel {
 public:
  // degree 3 or 5; knots: the nodes' parameters, strictly increasing, first 0 and last 1 (open curves: one
  // per node; closed curves: one per node plus the closing 1); dofs: s x (nodes * (degree + 1) / 2), the
  // nodal values node by node (column node * k + j is the j-th derivative at that node, k = (degree + 1) /
  // 2). c2 (cubic only): parameters reduced to positions (and open ends' slopes); the given interior slopes
  // are replaced by those of the C2 curve through the given positions.
  HermiteCurve(int degree, std::vector<double> knots, Eigen::MatrixXd dofs, bool closed, bool c2 = false);
  // Uniform knots (h = 1 / elements) with the given nodal dofs.
  static HermiteCurve Uniform(int degree, int elements, Eigen::MatrixXd dofs, bool closed, bool c2 = false);

  int degree() const { return degree_; }
  int derivatives_per_node() const { return per_node_; }  // (degree + 1) / 2
  bool closed() const { return closed_; }
  bool c2() const { return c2_; }
  int num_elements() const { return static_cast<int>(knots_.size()) - 1; }
  int num_nodes() const { return closed_ ? num_elements() : num_elements() + 1; }
  const std::vector<double>& knots() const { return knots_; }
  // s x (nodes * per_node): every nodal value (the dependent slopes of a C2 cubic included).
  const Eigen::MatrixXd& nodal_values() const { return values_; }
  // The node of the end of element e that is its `side` (0: start, 1: end).
  int ElementNode(int element, int side) const {
    return closed_ ? (element + side) % num_nodes() : element + side;
  }
  // The element containing u (wrapped into [0, 1) when closed, clamped when open) and the local t in [0, 1].
  int Locate(double u, double& t) const;
  // Derivatives 0..order (order <= degree) of w with respect to u at u: out is s x (order + 1).
  void EvaluateJet(double u, int order, Eigen::MatrixXd& out) const;
  // The same on element e at its local t (t = 0 or 1: the one-sided values at the element's ends).
  void EvaluateOnElement(int element, double t, int order, Eigen::MatrixXd& out) const;
  // The curve with every element split at its middle (the same curve: a polynomial element is determined by
  // its Hermite data at both ends), or only the elements listed.
  HermiteCurve Refined(const std::vector<int>& elements) const;
  // The first u (of `samples` + 1 evenly spaced) where the tangent w' turns back against the previous
  // sample's (w'(u_k) . w'(u_{k-1}) <= 0): where the curve folds over itself or stops; empty when it runs one
  // way.
  std::optional<double> FirstFold(int samples = 400) const;

  // K of E(Q) = Q^T K Q for the parameters (docs/fair-curves.md eqs. F5-F10), a full-size matrix.
  Eigen::MatrixXd FairnessMatrixOf(const HermiteFairness& weights) const;
  // Each term's value for the current shape: alpha1..3 and beta2..3 as the weighted energies.
  HermiteFairness EnergyBreakdown(const HermiteFairness& weights) const;
  // The dof expansion: all nodal dofs (per coordinate) = T * independent dofs (identity unless c2).
  const Eigen::MatrixXd& expansion() const { return expansion_; }

  // ParametricModel.
  std::unique_ptr<ParametricModel> Clone() const override { return std::make_unique<HermiteCurve>(*this); }
  void CopyFrom(const ParametricModel& other) override { *this = dynamic_cast<const HermiteCurve&>(other); }
  std::string name() const override;
  int ambient_dimension() const override { return static_cast<int>(values_.rows()); }
  ParameterDomain domain() const override;
  int num_parameters() const override { return static_cast<int>(independent_.size()); }
  std::string parameter_name(int index) const override;
  Eigen::VectorXd parameters() const override;
  void set_parameters(const Eigen::VectorXd& p) override;
  void ApplySimilarity(double scale, const VecS& offset) override;
  void Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const override;
  void ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const override;
  // FairnessWeights maps stretch, bending, variation, jump2, jump3 to alpha1..3, beta2, beta3, added to the
  // model's own terms (set_fairness).
  Eigen::MatrixXd FairnessMatrix(const FairnessWeights& weights) const override;
  std::vector<ParamT> SampleParameters() const override;
  // Exact feet by Bernstein root isolation on every element that can hold the foot (hermite_curve.cpp).
  bool ClosedFormFootPoint(const VecS& x, ParamT& t) const override;
  bool ClosedFormFoot(const VecS& x, ParamT& t, double& distance, bool& on_boundary,
                      bool& ambiguous) const override;
  bool FootPointOnBoundary(const VecS& x, const ParamT& t) const override;

  // The fairness energy FairnessMatrix adds (the engine's fits read it through FairnessMatrix).
  void set_fairness(const HermiteFairness& f) { fairness_ = f; }
  const HermiteFairness& fairness() const { return fairness_; }

 private:
  void BuildExpansion();
  void Rebuild();  // values_ from independent_, then the per-element tables
  // The global dof (scalar, per coordinate) of local dof k of element e.
  int GlobalDof(int element, int local) const;
  double FootOnElement(int e, const VecS& x, double& t_best) const;

  int degree_, per_node_;
  std::vector<double> knots_;
  bool closed_, c2_;
  Eigen::MatrixXd independent_;          // s x independent dofs
  Eigen::MatrixXd expansion_;            // dofs x independent dofs (identity unless c2)
  std::vector<int> independent_global_;  // the global dof of each independent one
  Eigen::MatrixXd values_;               // s x dofs
  HermiteFairness fairness_;
  // Per element: power coefficients in t (s x (degree + 1)), and the bounding box of its Bezier points.
  std::vector<Eigen::MatrixXd> power_;
  std::vector<Eigen::VectorXd> box_lo_, box_hi_;
};

}  // namespace s2m
