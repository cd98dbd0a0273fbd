#pragma once
// Kinematic surfaces with a B-spline generatrix (docs/method.md section 7; Liu, Pottmann, Wang, CAD 38(6)
// 2006, section 4): surfaces of revolution (pots) and helical surfaces (drills), in their own adapted frame
// whose z axis is the axis:  x(u, v) = sum_k (r_k cos v, r_k sin v, z_k) B_k(u) + (0, 0, p v),  p = 0 for
// revolution.

#include "fitting/bspline_basis.h"
#include "fitting/bspline_models.h"
#include "fitting/parametric_model.h"

namespace s2m {

class KinematicSurface final : public ParametricModel {
 public:
  // Surface of revolution: profile control points (r_k, z_k) as the columns of a 2 x n matrix.
  static KinematicSurface Revolution(BSplineBasis basis, Eigen::Matrix2Xd profile);
  // Helical surface with pitch p (axial advance per radian), v in [-pi turns, pi turns]. The pitch is a
  // parameter.
  static KinematicSurface Helical(BSplineBasis basis, Eigen::Matrix2Xd profile, double pitch, double turns);

  const BSplineBasis& basis() const { return basis_; }
  const Eigen::Matrix2Xd& profile() const { return profile_; }
  double pitch() const { return pitch_; }
  bool helical() const { return helical_; }
  // Radius and height of the generatrix at u (derivative 0), or their derivative d/du (1) or d2/du2 (2).
  Eigen::Vector2d ProfilePoint(double u, int derivative = 0) const;
  // The radius where the generatrix reaches `height` (Newton on z(u) = height; the profile must be monotone
  // in height there), and its gradient with respect to the shape parameters (implicit function: dr/dP - r'/z'
  // dz/dP), which propagates a parameter covariance to the radius. Throws std::domain_error when the height
  // is not reached.
  double RadiusAtHeight(double height, Eigen::VectorXd* gradient = nullptr) const;
  // The volume inside the surface of revolution between the planes z = z_lo and z = z_hi across its axis
  // (z_lo < z_hi; where the generatrix ends between them, the plane through its end closes the solid):
  // V = pi |integral r(u)^2 z'(u) [z_lo <= z(u) <= z_hi] du| (docs/archaeology.md eqs. A1-A2), disc
  // integration written along the generatrix, exact also where the profile turns back in height (the planes
  // and the axis add nothing to the integral). Gauss-Legendre on each knot span split where z(u) crosses a
  // plane: exact to rounding for degree <= 5. With `gradient`, dV/dP over the shape parameters with the
  // planes held where they are (eq. A3). Surfaces of revolution only (std::logic_error for helical ones).
  double EnclosedVolume(double z_lo, double z_hi, Eigen::VectorXd* gradient = nullptr) const;

  std::unique_ptr<ParametricModel> Clone() const override {
    return std::make_unique<KinematicSurface>(*this);
  }
  void CopyFrom(const ParametricModel& other) override {
    *this = dynamic_cast<const KinematicSurface&>(other);
  }
  std::string name() const override { return helical_ ? "helical surface" : "surface of revolution"; }
  int ambient_dimension() const override { return 3; }
  ParameterDomain domain() const override;
  int num_parameters() const override { return static_cast<int>(profile_.size()) + (helical_ ? 1 : 0); }
  std::string parameter_name(int index) const override;
  Eigen::VectorXd parameters() const override;
  void set_parameters(const Eigen::VectorXd& p) override;
  // The axis is the frame's z axis: only scaling and shifts along z are representable (see
  // SupportsTranslation).
  void ApplySimilarity(double scale, const VecS& offset) override;
  bool SupportsTranslation() const override { return false; }
  void Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const override;
  void ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const override;
  // Surfaces of revolution: weights B_k(u), directions (cos v, sin v, 0) and (0, 0, 1) for (r_k, z_k).
  // Helical surfaces (the pitch column does not factor): false.
  bool FactoredShapeJacobian(const ParamT& t, FactoredJacobian& out) const override;
  Eigen::MatrixXd FairnessMatrix(const FairnessWeights& weights) const override;
  std::vector<ParamT> SampleParameters() const override;
  std::vector<Motion6> InvariantMotions() const override;
  std::vector<Motion6> CommonMotionsAbsorbedByShape() const override;
  // Surfaces of revolution whose profile radii r_k are all >= 0 (so r(u) >= 0 everywhere, a B-spline being a
  // convex combination of its control points): the foot of x lies in x's meridian half-plane, v = atan2(y,
  // x), and u is the foot of (rho, h) on the planar generatrix (FootPointReduction). Null for helical
  // surfaces and profiles that may cross the axis; feet where r(u) = 0 (on the axis) are left to the 2-D
  // Newton.
  std::unique_ptr<FootPointReduction> MakeFootPointReduction() const override;
  // Helical: a foot at the generatrix's end continues at its start one turn on, and vice versa.
  std::optional<ParamT> ContinuationSeed(const ParamT& t) const override;

 private:
  KinematicSurface(BSplineBasis basis, Eigen::Matrix2Xd profile, bool helical, double pitch, double turns);
  BSplineBasis basis_;
  Eigen::Matrix2Xd profile_;  // rows: r, z
  bool helical_ = false;
  double pitch_ = 0.0;
  double turns_ = 1.0;

  // The generatrix (r(u), z(u)) and its u-derivatives up to `derivatives` (value, d/du, d2/du2 as columns;
  // higher ones 0), from the per-span power form: the same values as summing the basis functions, to
  // rounding.
  Eigen::Matrix<double, 2, 3> ProfileAt(double u, int derivatives) const;
  SpanPowerForm generatrix_;  // of profile_; rebuilt in the constructor, set_parameters and ApplySimilarity
};

// Spiral surface (shells; docs/method.md section 7): x(u, v) = e^{p v} sum_k (r_k cos v, r_k sin v, z_k)
// B_k(u) for v in [v_lo, v_hi] (the whorls, unwrapped), growth parameter p. The growth enters non-linearly;
// its Jacobian at fixed (u, v) is v x(u, v), the linearization at the current value (section 6). The whorl
// expansion rate is exp(2 pi p).
//
// Allometric growth (docs/shells.md eq. S1): the radial scale e^{g(v)}, g(v) = p v + q (v - v_c)^2 / 2, and
// the axial scale e^{g(v) + a (v - v_c)}, i.e. x(u, v) = (e^g r(u) cos v, e^g r(u) sin v, e^{g + a (v - v_c)}
// z(u)): q is the change of the growth rate per radian of coiling (the whorl expansion rate is not
// constant), a the excess of the axial over the radial growth rate (the generating curve's height-to-width
// ratio changes), p the growth rate at the reference angle v_c. q = a = 0 is the logarithmic (isometric)
// spiral; WithAllometry() frees both as two more parameters, the nested model the adequacy test of
// docs/shells.md section 3 fits, with v_c the middle of the angle range: q and a do not depend on v_c (a
// shift of it changes p and the generating curve's scale only), but about the middle of the data they are
// nearly uncorrelated with p.
class SpiralSurface final : public ParametricModel {
 public:
  SpiralSurface(BSplineBasis basis, Eigen::Matrix2Xd profile, double growth, double v_lo, double v_hi);
  // This surface with q and a as parameters (after the growth), set to the given values, v_c the middle of
  // the angle range.
  SpiralSurface WithAllometry(double growth_change = 0.0, double axial_excess = 0.0) const;
  // This surface with another generating curve (growth, angle range and allometry kept).
  SpiralSurface WithGeneratrix(BSplineBasis basis, Eigen::Matrix2Xd profile) const;
  // This surface over another range of coiling angles (the allometry's v_c kept).
  SpiralSurface WithAngleRange(double v_lo, double v_hi) const;

  const BSplineBasis& basis() const { return basis_; }
  const Eigen::Matrix2Xd& profile() const { return profile_; }
  double growth() const { return growth_; }
  bool allometric() const { return allometric_; }
  double growth_change() const { return growth_change_; }  // q, 1/rad^2
  double axial_excess() const { return axial_excess_; }    // a, 1/rad
  double v_lo() const { return v_lo_; }
  double v_hi() const { return v_hi_; }
  double allometry_reference() const { return allometry_reference_; }  // v_c
  double WhorlExpansionRate() const;
  // The whorl at coiling angle v (docs/shells.md eqs. S4-S6): the generating curve there, e^{g(v)} times
  // its extents in r and e^{g(v) + a v} times its extent in z. `height` along the axis and `width` across it
  // are the whorl's own; `umbilical_width` is the distance across the axis between the curve's inner edges
  // at v and at v - pi (0 when the curve reaches the axis: no umbilicus), `diameter` the same between the
  // outer edges, the shell's breadth through the axis there.
  struct Whorl {
    double height = 0.0, width = 0.0, umbilical_width = 0.0, diameter = 0.0;
  };
  Whorl WhorlAt(double v) const;
  // The same with given extents (r_min, r_max, z_min, z_max) of the generating curve, e.g. ExtentsBetween's.
  Whorl WhorlAt(double v, const Eigen::Vector4d& extents) const;
  // The generating curve (r, z) at u (derivative 0), or its derivative d/du (1) or d2/du2 (2).
  Eigen::Vector2d CurvePoint(double u, int derivative = 0) const;
  // The generating curve's extents (r_min, r_max, z_min, z_max) over the part of it the data cover, u in
  // [u_lo, u_hi] within the basis' range (docs/shells.md eq. S5a): 2001 samples, the two ends being the
  // points `end_lo`, `end_hi` (where the data end) moved onto the curve's tangent line at u_lo, u_hi. To
  // first order that is their foot on the curve: a change of the curve that slides it along itself leaves
  // the ends where the data put them. With end_lo = CurvePoint(u_lo), end_hi = CurvePoint(u_hi) on this
  // curve they are its plain extents there.
  Eigen::Vector4d ExtentsBetween(double u_lo, double u_hi, const Eigen::Vector2d& end_lo,
                                 const Eigen::Vector2d& end_hi) const;
  // Raup's coiling parameters of the surface (docs/archaeology.md section 7): W = exp(2 pi p); D = r_min /
  // r_max, the generating curve's inner edge over its outer edge (distances from the axis); T = z_c / r_c,
  // the axial over the radial coordinate of the generating curve's centre (the middle of its extent in r
  // and z) seen from the spiral's apex, the frame's origin. On a logarithmic spiral every point moves along
  // a ray from the apex, so T is Raup's translation dz/dr of the centre along the coil and D and T are the
  // same at every v. Extents by 2001 samples of the generatrix. D is NaN when the curve crosses the axis.
  struct Raup {
    double w = 0.0, d = 0.0, t = 0.0;
  };
  Raup RaupParameters() const;
  // The same with given extents (r_min, r_max, z_min, z_max) of the generating curve, e.g. ExtentsBetween's.
  Raup RaupParameters(const Eigen::Vector4d& extents) const;
  // The growing-tube parameters (Okamoto 1988) of the logarithmic coil with Raup's W, D and T
  // (docs/archaeology.md section 7, eqs. A18-A20): the centre of a circular generating curve of radius r
  // moves along a conical logarithmic helix of arc length s; E = dr/ds (the tube's expansion per length),
  // C = kappa r and T = tau r (the helix' curvature and torsion standardized by the tube's radius), in the
  // convention of Noshita (2014), whose translation rate is the centre's height over the outer edge's
  // distance from the axis, T (1 + D) / 2 in ours. NaN unless W > 1 and -1 < D < 1.
  struct GrowingTube {
    double expansion = 0.0, curvature = 0.0, torsion = 0.0;
  };
  static GrowingTube GrowingTubeFromRaup(const Raup& raup);

  std::unique_ptr<ParametricModel> Clone() const override { return std::make_unique<SpiralSurface>(*this); }
  void CopyFrom(const ParametricModel& other) override { *this = dynamic_cast<const SpiralSurface&>(other); }
  std::string name() const override { return "spiral surface"; }
  int ambient_dimension() const override { return 3; }
  ParameterDomain domain() const override;
  int num_parameters() const override { return static_cast<int>(profile_.size()) + (allometric_ ? 3 : 1); }
  std::string parameter_name(int index) const override;
  Eigen::VectorXd parameters() const override;
  void set_parameters(const Eigen::VectorXd& p) override;
  // The spiral's centre is the frame's origin: only scaling is representable (a shift would move the centre).
  void ApplySimilarity(double scale, const VecS& offset) override;
  bool SupportsTranslation() const override { return false; }
  void Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const override;
  void ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const override;
  std::vector<ParamT> SampleParameters() const override;
  // A common rotation of all scans about the axis is a rescaling of the profile (e^{p phi}): the shape
  // absorbs it.
  std::vector<Motion6> CommonMotionsAbsorbedByShape() const override;

 private:
  // The generating curve's extents (r_min, r_max, z_min, z_max) by 2001 samples.
  Eigen::Vector4d Extents() const;
  // e^{g(v)} and e^{g(v) + a (v - v_c)} (eq. S1) and their log-derivatives g'(v) = p + q (v - v_c), g'(v) +
  // a.
  struct Scales {
    double radial, axial, radial_rate, axial_rate;
  };
  Scales ScalesAt(double v) const;

  BSplineBasis basis_;
  Eigen::Matrix2Xd profile_;
  double growth_;
  double v_lo_, v_hi_;
  bool allometric_ = false;
  double growth_change_ = 0.0, axial_excess_ = 0.0, allometry_reference_ = 0.0;
};

}  // namespace s2m
