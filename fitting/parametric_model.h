#pragma once
// The model interface of the fitting engine: a parametric family C(P; t) with shape parameters P (r numbers)
// and location parameters t (m = 1 for curves, 2 for surfaces) in R^s (s = 2 or 3). docs/method.md section 1.

#include <Eigen/Core>
#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "registration/local_quadric.h"
#include "registration/principal_curvatures.h"

namespace s2m {

constexpr int kMaxAmbient = 3;
// Small fixed-capacity types: no heap allocation on the foot-point hot path.
using VecS = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxAmbient, 1>;
using MatS = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxAmbient, kMaxAmbient>;
// t: curves use t[0], surfaces t[0] and t[1]. t[2] is the face index of multi-face models (PartModel: which
// face the foot point lies on; it never changes in Newton steps) and 0 otherwise.
using ParamT = std::array<double, 3>;
// A rigid-motion velocity (c, cbar) of docs/method.md section 5: rotation c, then translation cbar.
using Motion6 = Eigen::Matrix<double, 6, 1>;

// A point of the model's space padded to 3D (z = 0 for planar models).
inline Eigen::Vector3d To3(const VecS& v) {
  Eigen::Vector3d out = Eigen::Vector3d::Zero();
  out.head(v.size()) = v;
  return out;
}

// SdmWeight(delta, kappa), the SDM weight of one tangential direction, lives in registration/local_quadric.h
// (scan-to-scan SDM uses it too, and registration/ cannot depend on fitting/).

struct ParameterDomain {
  int dimension = 1;  // m
  std::array<double, 2> lo{0.0, 0.0}, hi{1.0, 1.0};
  std::array<bool, 2> periodic{false, false};
};

// Point and derivatives in t at one parameter value.
struct LocalGeometry {
  VecS point;  // C(t)
  MatS d1;     // s x m: columns dC/dt_k
  MatS d2;     // s x (1 or 3): d2C/dt^2 (curves); C_uu, C_uv, C_vv (surfaces)
};

// One non-zero column of the shape Jacobian dC/dP at fixed t, and its t-derivatives (for GN's mixed term).
struct JacobianEntry {
  int index = 0;                              // shape parameter index
  Eigen::Vector3d column;                     // dC/dP_index (first s entries used)
  std::array<Eigen::Vector3d, 2> dcolumn_dt;  // d/dt_k of the column
};

// A shape Jacobian dC/dP at fixed t that factors as weights times directions, as in B-spline models where
// control point k moves C by B_k(t) times a direction per coordinate: the non-zero columns are
// weights[i] * directions.col(c), at parameter index first_index[i] + c (i < weight_count, c <
// direction_count). The assembly of normal equations then forms D^T M D once per point instead of J^T M J
// over all (weight_count x direction_count) columns.
struct FactoredJacobian {
  // Curves of B-spline order up to 8 (BSplineBasis::kMaxOrder), tensor-product surfaces up to 16 control
  // points per span (bicubic); models with more use ShapeJacobian.
  static constexpr int kMaxWeights = 16;
  int weight_count = 0;
  std::array<int, kMaxWeights> first_index{};
  std::array<double, kMaxWeights> weights{};
  int direction_count = 0;                               // <= 3
  Eigen::Matrix3d directions = Eigen::Matrix3d::Zero();  // columns beyond direction_count are zero
};

struct FairnessWeights {
  double stretch = 0.0;  // curves: alpha * integral |C'|^2; surfaces: membrane integral |S_u|^2 + |S_v|^2
  double bending =
      0.0;  // curves: beta * integral |C''|^2; surfaces: thin plate |S_uu|^2 + 2|S_uv|^2 + |S_vv|^2
  // L. Fang's further terms (docs/fair-curves.md section 8): curves integral |C'''|^2 (curvature variation);
  // surfaces integral |S_uuu|^2 + 3|S_uuv|^2 + 3|S_uvv|^2 + |S_vvv|^2.
  double variation = 0.0;
  // Junction springs: curves sum over the knots of |jump of C''|^2 (jump2) and |jump of C'''|^2 (jump3);
  // surfaces the same jumps across the knot lines of the u- and v-derivatives, integrated along the lines.
  double jump2 = 0.0;
  double jump3 = 0.0;
  bool IsZero() const { return stretch == 0 && bending == 0 && variation == 0 && jump2 == 0 && jump3 == 0; }
};

class ParametricModel;

// A foot-point problem that reduces to one on a simpler model (docs/method.md section 10). A surface of
// revolution: the distance from x to its point (u, v) is d^2 = rho^2 + r^2 - 2 rho r cos(v - phi) + (z - h)^2
// (x in cylinder coordinates (rho, phi, h), (r(u), z(u)) the generatrix), which for r >= 0 is smallest at v =
// phi. So the foot of x lies in x's meridian half-plane and is the foot of (rho, h) on the planar generatrix:
// a 1-D Newton on the profile, without the trigonometry and the second parameter of the 2-D one.
class FootPointReduction {
 public:
  virtual ~FootPointReduction() = default;
  // The simpler model. Its t is the leading entries of the full model's t (e.g. u of (u, v)), so a previous
  // full foot warm-starts it. Its foot distance and boundary flag are those of the full foot.
  virtual const ParametricModel& reduced_model() const = 0;
  // x in the reduced model's space; false when x cannot be reduced (e.g. not finite).
  virtual bool Reduce(const VecS& x, VecS& reduced_x) const = 0;
  // The full model's foot t of x and its geometry g there (C and its first and second derivatives), from the
  // reduced model's foot `reduced_t` with the reduced model's geometry `reduced_g` there (up to second
  // derivatives). False when the reduction does not hold at that foot (e.g. the generatrix touches the
  // axis there): the engine then searches the full model's feet itself.
  virtual bool Lift(const VecS& x, const ParamT& reduced_t, const LocalGeometry& reduced_g, ParamT& t,
                    LocalGeometry& g) const = 0;
};

class ParametricModel {
 public:
  virtual ~ParametricModel() = default;
  virtual std::unique_ptr<ParametricModel> Clone() const = 0;
  // Takes over the state of `other`, a model of the same concrete type (e.g. the accepted trial of a step).
  virtual void CopyFrom(const ParametricModel& other) = 0;
  virtual std::string name() const = 0;

  virtual int ambient_dimension() const = 0;  // s
  virtual ParameterDomain domain() const = 0;
  virtual int num_parameters() const = 0;  // r
  virtual std::string parameter_name(int index) const = 0;
  virtual Eigen::VectorXd parameters() const = 0;
  virtual void set_parameters(const Eigen::VectorXd& p) = 0;
  // Applies a step D of the linearized problem. Models whose parameters enter non-linearly (rotations)
  // linearize at the current value and override this (docs/method.md section 6, last item); the default adds
  // D.
  virtual void ApplyStep(const Eigen::VectorXd& step) { set_parameters(parameters() + step); }
  // Maps the model by x -> scale * x + offset (data normalization into the unit box and back).
  virtual void ApplySimilarity(double scale, const VecS& offset) = 0;
  // False for models tied to their own frame (kinematic surfaces: the axis is the frame's z axis): data are
  // then normalized by scale alone.
  virtual bool SupportsTranslation() const { return true; }
  // Gauge of the joint solver (docs/method.md section 6): rigid-motion velocities of one scan the model is
  // invariant to (e.g. rotation about the axis of a surface of revolution), and velocities that, applied to
  // all scans together, a change of shape absorbs (a common translation along that axis). Both are removed
  // from the unknowns.
  virtual std::vector<Motion6> InvariantMotions() const { return {}; }
  virtual std::vector<Motion6> CommonMotionsAbsorbedByShape() const { return {}; }

  // C and its t-derivatives up to `derivatives` (0, 1 or 2) at t (wrapped/clamped into the domain).
  virtual void Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const = 0;
  // Non-zero columns of dC/dP at t; with `with_dt`, also their t-derivatives. `out` is cleared first.
  virtual void ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const = 0;
  // ShapeJacobian(t, false, .) in factored form (FactoredJacobian), for models whose Jacobian factors so at
  // every t; returns false (the default) otherwise, and the caller uses ShapeJacobian.
  virtual bool FactoredShapeJacobian(const ParamT& t, FactoredJacobian& out) const {
    (void)t;
    (void)out;
    return false;
  }
  // Fairness energy E(P) = P^T K P; returns K (r x r), or an empty matrix when the model has none.
  virtual Eigen::MatrixXd FairnessMatrix(const FairnessWeights& weights) const {
    (void)weights;
    return {};
  }
  // Parameter values whose model points seed the foot-point search (spread over the whole domain).
  virtual std::vector<ParamT> SampleParameters() const = 0;
  // Whether t belongs to the model: a model over a polygonal parameter domain (fitting/fe_surface_model.h)
  // has domain()'s box around it, and the box's corners are not part of the surface.
  virtual bool InDomain(const ParamT& /*t*/) const { return true; }
  // Models that compute their own foot points (closed form on primitives, docs/method.md section 10; per face
  // on parts) fill t and return true; the engine then skips its sample search and Newton.
  virtual bool ClosedFormFootPoint(const VecS& x, ParamT& t) const {
    (void)x;
    (void)t;
    return false;
  }
  // Models with their own feet, everything the engine needs of one foot in one call: t, the distance |C(t) -
  // x|, FootPointOnBoundary and AmbiguousFootPoint. The default composes those calls and Evaluate; models
  // override it when they know the distance without evaluating C again (primitives) or can share work
  // between the foot and the ambiguity test (parts). Returns false for models without closed-form feet.
  virtual bool ClosedFormFoot(const VecS& x, ParamT& t, double& distance, bool& on_boundary,
                              bool& ambiguous) const;
  // Models whose Newton feet reduce to those of a simpler model (FootPointReduction) return the reduction
  // for their current shape; null (the default) when there is none. The engine then runs its warm starts,
  // sample search and safeguarded Newton on the reduced model and lifts the result.
  virtual std::unique_ptr<FootPointReduction> MakeFootPointReduction() const { return nullptr; }
  // Surfaces whose sheet continues across an open boundary of the parameter box in another place of it (a
  // helical surface whose generatrix spans about one lead: its end at angle v meets its start at v + 2 pi).
  // For a foot t on such a boundary, the parameter where the neighbouring sheet continues: NewtonFoot
  // searches again from there and keeps the closer foot (a cold search from the nearest sample can stop on
  // the boundary of one turn while the point lies on the next). Default: none.
  virtual std::optional<ParamT> ContinuationSeed(const ParamT& t) const {
    (void)t;
    return std::nullopt;
  }
  // Models with their own feet: true when the foot point t of x lies on an open boundary, where the
  // orthogonality condition need not hold (the end rule applies, docs/method.md section 4).
  virtual bool FootPointOnBoundary(const VecS& x, const ParamT& t) const {
    (void)x;
    (void)t;
    return false;
  }
  // Multi-face models: true when x lies about as close to another face as to the face of its foot point t
  // (near an edge, where the assignment is a guess); such points are left out of fits.
  virtual bool AmbiguousFootPoint(const VecS& x, const ParamT& t) const {
    (void)x;
    (void)t;
    return false;
  }
};

// The principal frame of the model at a foot point, oriented towards a data point X (docs/method.md section
// 2): unit tangents T_k with signed curvatures kappa_k w.r.t. the unit normal n, an orthonormal basis of the
// normal space, and delta = n.(X - s) >= 0.
struct PrincipalFrame {
  int tangent_count = 1;
  std::array<Eigen::Vector3d, 2> tangents;
  std::array<double, 2> curvatures{0.0, 0.0};
  int normal_count = 1;
  std::array<Eigen::Vector3d, 2> normals;  // normals[0] == n
  double delta = 0.0;
};
PrincipalFrame ComputePrincipalFrame(const LocalGeometry& g, const VecS& data_point);

}  // namespace s2m
