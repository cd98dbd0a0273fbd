#pragma once
// A vessel's wall: two surfaces of revolution, the outer and the inner, sharing one axis (the z axis of one
// adapted frame), fitted together as one model (docs/archaeology.md section 10; a constrained part of two
// kinematic faces, Liu, Pottmann, Wang, CAD 38(6) 2006, sections 4 and 6). The shape parameters are the outer
// generatrix's control points followed by the inner one's; the views' poses are shared, so the one axis is
// what both faces' points determine together.
//
// Each data point belongs to the face of its nearer foot point (the smaller distance wins), found on each
// face as on a single surface of revolution (its meridian half-plane, docs/method.md section 10). A wall is
// several millimetres thick where the scans' noise is a fraction of one, so the assignment is a guess only
// at the lip, between the two generatrices' ends, where the end rule applies.
//
// Parameter t = (u, v, face): face 0 the outer surface, 1 the inner.

#include <array>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "fitting/kinematic_surfaces.h"
#include "fitting/parametric_model.h"

namespace s2m {

struct FootPointContext;

class RevolutionWall final : public ParametricModel {
 public:
  static constexpr int kOuter = 0;
  static constexpr int kInner = 1;

  // Two surfaces of revolution in one frame (each generatrix on its own parameter interval). Which is outer
  // is decided here: the face farther from the axis at the heights both reach (they are swapped if given the
  // other way). Throws std::invalid_argument for helical faces or no common height.
  RevolutionWall(KinematicSurface a, KinematicSurface b);
  RevolutionWall(const RevolutionWall& other);
  RevolutionWall& operator=(const RevolutionWall& other);
  ~RevolutionWall() override;

  const KinematicSurface& face(int index) const { return faces_[static_cast<std::size_t>(index)]; }
  // Where face `index`'s parameters start in the wall's parameter vector.
  int offset(int index) const { return index == kOuter ? 0 : faces_[0].num_parameters(); }

  // The heights both generatrices reach (the lowest and the highest height of each, intersected).
  std::array<double, 2> CommonHeights() const;

  // The wall's thickness at `height`: the distance from the outer generatrix's point at that height to the
  // inner generatrix (eq. A21), i.e. measured along the outer surface's normal where the inner surface is
  // the outer's offset (as a calliper held square to the wall measures it). With `gradient`, its gradient
  // over the wall's parameters (eq. A22), to propagate their covariance; with `inner_foot`, that nearest
  // point of the inner generatrix as (radius, height). Throws std::domain_error where the outer generatrix
  // does not reach the height or the nearest point of the inner one is its end (the wall is not closed
  // there).
  double ThicknessAtHeight(double height, Eigen::VectorXd* gradient = nullptr,
                           Eigen::Vector2d* inner_foot = nullptr) const;
  // The same from the outer generatrix's point C_o(u) at parameter u instead of its point at a height (a
  // base, where the radius is no function of height, docs/archaeology.md eq. A21c): the gradient's outer
  // part is then that of C_o(u) at the fixed parameter.
  double ThicknessAtOuterParameter(double u, Eigen::VectorXd* gradient = nullptr,
                                   Eigen::Vector2d* inner_foot = nullptr) const;

  // The volume inside face `index` between the heights z_lo and z_hi (KinematicSurface::EnclosedVolume),
  // with its gradient over the wall's parameters (zero on the other face's).
  double EnclosedVolume(int index, double z_lo, double z_hi, Eigen::VectorXd* gradient = nullptr) const;

  std::unique_ptr<ParametricModel> Clone() const override { return std::make_unique<RevolutionWall>(*this); }
  void CopyFrom(const ParametricModel& other) override { *this = dynamic_cast<const RevolutionWall&>(other); }
  std::string name() const override { return "wall of revolution"; }
  int ambient_dimension() const override { return 3; }
  // The outer face's: the engine needs only its dimension (2); each face's u lies in its own interval, which
  // the wall's feet respect.
  ParameterDomain domain() const override { return faces_[0].domain(); }
  int num_parameters() const override { return faces_[0].num_parameters() + faces_[1].num_parameters(); }
  std::string parameter_name(int index) const override;
  Eigen::VectorXd parameters() const override;
  void set_parameters(const Eigen::VectorXd& p) override;
  void ApplySimilarity(double scale, const VecS& offset) override;
  bool SupportsTranslation() const override { return false; }
  void Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const override;
  void ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const override;
  bool FactoredShapeJacobian(const ParamT& t, FactoredJacobian& out) const override;
  Eigen::MatrixXd FairnessMatrix(const FairnessWeights& weights) const override;
  std::vector<ParamT> SampleParameters() const override;
  std::vector<Motion6> InvariantMotions() const override { return faces_[0].InvariantMotions(); }
  // A common axial shift of every view moves both generatrices' heights together.
  std::vector<Motion6> CommonMotionsAbsorbedByShape() const override {
    return faces_[0].CommonMotionsAbsorbedByShape();
  }
  bool ClosedFormFootPoint(const VecS& x, ParamT& t) const override;
  bool ClosedFormFoot(const VecS& x, ParamT& t, double& distance, bool& on_boundary,
                      bool& ambiguous) const override;

 private:
  void Rebuild();  // the faces' foot-point contexts, after any change of shape
  // eqs. A21-A22 from the outer point Q = (radius, height): `outer_gradient(e, part)` fills the gradient's
  // outer part, e.dQ/dP, for the unit vector e from the inner foot to Q.
  double ThicknessFromOuterPoint(
      const Eigen::Vector2d& radius_height,
      const std::function<void(const Eigen::Vector3d&, Eigen::Ref<Eigen::VectorXd>)>& outer_gradient,
      Eigen::VectorXd* gradient, Eigen::Vector2d* inner_foot, const std::string& where) const;
  std::array<KinematicSurface, 2> faces_;
  std::array<std::unique_ptr<FootPointContext>, 2> contexts_;
};

}  // namespace s2m
