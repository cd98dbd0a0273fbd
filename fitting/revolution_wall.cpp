#include "fitting/revolution_wall.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <stdexcept>
#include <string>

#include "fitting/foot_point.h"

namespace s2m {

namespace {

// The lowest and highest height of a generatrix, from dense samples (a B-spline's extremes lie between
// samples by at most the curve's variation over one step: 32 steps per control point).
std::array<double, 2> HeightRange(const KinematicSurface& face) {
  const BSplineBasis& basis = face.basis();
  const int samples = 32 * basis.num_control();
  std::array<double, 2> range{std::numeric_limits<double>::infinity(),
                              -std::numeric_limits<double>::infinity()};
  for (int i = 0; i <= samples; ++i) {
    const double z = face.ProfilePoint(basis.lo() + (basis.hi() - basis.lo()) * i / samples).y();
    range[0] = std::min(range[0], z);
    range[1] = std::max(range[1], z);
  }
  return range;
}

std::array<double, 2> Intersect(const std::array<double, 2>& a, const std::array<double, 2>& b) {
  return {std::max(a[0], b[0]), std::min(a[1], b[1])};
}

// The mean radius of a generatrix at `count` heights spread over [lo, hi] (heights it does not reach, or
// where it turns back, are skipped).
double MeanRadius(const KinematicSurface& face, double lo, double hi, int count) {
  double sum = 0.0;
  int n = 0;
  for (int i = 0; i < count; ++i) {
    try {
      sum += face.RadiusAtHeight(lo + (hi - lo) * (i + 0.5) / count);
      ++n;
    } catch (const std::domain_error&) {
    }
  }
  return n > 0 ? sum / n : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace

RevolutionWall::RevolutionWall(KinematicSurface a, KinematicSurface b) : faces_{std::move(a), std::move(b)} {
  if (faces_[0].helical() || faces_[1].helical())
    throw std::invalid_argument("a wall of revolution needs two surfaces of revolution (not helical ones)");
  const std::array<double, 2> common = Intersect(HeightRange(faces_[0]), HeightRange(faces_[1]));
  if (!(common[1] > common[0]))
    throw std::invalid_argument("the two surfaces of a wall share no height along the axis");
  const double r0 = MeanRadius(faces_[0], common[0], common[1], 16);
  const double r1 = MeanRadius(faces_[1], common[0], common[1], 16);
  if (!(std::isfinite(r0) && std::isfinite(r1)))
    throw std::invalid_argument("the two surfaces of a wall share no height where both are functions of it");
  if (r1 > r0) std::swap(faces_[0], faces_[1]);
  Rebuild();
}

RevolutionWall::RevolutionWall(const RevolutionWall& other) : ParametricModel(other), faces_(other.faces_) {
  Rebuild();
}

RevolutionWall& RevolutionWall::operator=(const RevolutionWall& other) {
  if (this != &other) {
    faces_ = other.faces_;
    Rebuild();
  }
  return *this;
}

RevolutionWall::~RevolutionWall() = default;

void RevolutionWall::Rebuild() {
  for (std::size_t k = 0; k < 2; ++k) contexts_[k] = std::make_unique<FootPointContext>(faces_[k]);
}

std::array<double, 2> RevolutionWall::CommonHeights() const {
  return Intersect(HeightRange(faces_[0]), HeightRange(faces_[1]));
}

double RevolutionWall::ThicknessAtHeight(double height, Eigen::VectorXd* gradient,
                                         Eigen::Vector2d* inner_foot) const {
  Eigen::VectorXd outer_gradient;
  const double radius = faces_[kOuter].RadiusAtHeight(height, gradient ? &outer_gradient : nullptr);
  // Q moves only radially at a fixed height: dQ/dP_outer = (dr/dP, 0, 0) from RadiusAtHeight.
  return ThicknessFromOuterPoint(
      Eigen::Vector2d(radius, height),
      [&](const Eigen::Vector3d& e, Eigen::Ref<Eigen::VectorXd> outer_part) {
        outer_part = e.x() * outer_gradient;
      },
      gradient, inner_foot, "at height " + std::to_string(height));
}

double RevolutionWall::ThicknessAtOuterParameter(double u, Eigen::VectorXd* gradient,
                                                 Eigen::Vector2d* inner_foot) const {
  const KinematicSurface& outer = faces_[kOuter];
  const ParamT t{u, 0.0, 0.0};
  // Q = C_o(u) at a fixed parameter: it moves with the outer generatrix's control points, dQ/dP = dC_o/dP.
  return ThicknessFromOuterPoint(
      outer.ProfilePoint(u),
      [&](const Eigen::Vector3d& e, Eigen::Ref<Eigen::VectorXd> outer_part) {
        std::vector<JacobianEntry> columns;
        outer.ShapeJacobian(t, false, columns);
        for (const JacobianEntry& c : columns) outer_part[c.index] += e.dot(c.column);
      },
      gradient, inner_foot, "at the outer profile's parameter " + std::to_string(u));
}

double RevolutionWall::ThicknessFromOuterPoint(
    const Eigen::Vector2d& radius_height,
    const std::function<void(const Eigen::Vector3d&, Eigen::Ref<Eigen::VectorXd>)>& outer_gradient,
    Eigen::VectorXd* gradient, Eigen::Vector2d* inner_foot, const std::string& where) const {
  // The outer generatrix's point in the meridian half-plane v = 0, and its foot on the inner surface, which
  // lies in the same half-plane (docs/method.md section 10).
  VecS x(3);
  x << radius_height.x(), 0.0, radius_height.y();
  LocalGeometry g;
  const FootPoint foot = FootPointOf(*contexts_[kInner], x, nullptr, WarmStart::kVerified, g);
  if (foot.on_boundary)
    throw std::domain_error("the inner surface ends before it faces the outer one " + where);
  faces_[kInner].Evaluate(foot.t, 0, g);
  if (inner_foot) *inner_foot = Eigen::Vector2d(To3(g.point).head<2>().norm(), To3(g.point).z());
  const Eigen::Vector3d difference = To3(x) - To3(g.point);
  const double thickness = difference.norm();
  if (gradient) {
    // eq. A22: d|Q - P| = e . (dQ - dP) with e the unit vector from P to Q; the foot's own motion along the
    // inner generatrix drops out (e is normal to it there).
    const Eigen::Vector3d e =
        thickness > 0 ? Eigen::Vector3d(difference / thickness) : Eigen::Vector3d::Zero();
    gradient->setZero(num_parameters());
    outer_gradient(e, gradient->head(faces_[kOuter].num_parameters()));
    std::vector<JacobianEntry> columns;
    faces_[kInner].ShapeJacobian(foot.t, false, columns);
    for (const JacobianEntry& c : columns) (*gradient)[offset(kInner) + c.index] -= e.dot(c.column);
  }
  return thickness;
}

double RevolutionWall::EnclosedVolume(int index, double z_lo, double z_hi, Eigen::VectorXd* gradient) const {
  const KinematicSurface& f = face(index);
  Eigen::VectorXd face_gradient;
  const double volume = f.EnclosedVolume(z_lo, z_hi, gradient ? &face_gradient : nullptr);
  if (gradient) {
    gradient->setZero(num_parameters());
    gradient->segment(offset(index), f.num_parameters()) = face_gradient;
  }
  return volume;
}

std::string RevolutionWall::parameter_name(int index) const {
  const int n0 = faces_[0].num_parameters();
  return index < n0 ? "outer " + faces_[0].parameter_name(index)
                    : "inner " + faces_[1].parameter_name(index - n0);
}

Eigen::VectorXd RevolutionWall::parameters() const {
  Eigen::VectorXd p(num_parameters());
  p << faces_[0].parameters(), faces_[1].parameters();
  return p;
}

void RevolutionWall::set_parameters(const Eigen::VectorXd& p) {
  const int n0 = faces_[0].num_parameters();
  faces_[0].set_parameters(p.head(n0));
  faces_[1].set_parameters(p.tail(faces_[1].num_parameters()));
  Rebuild();
}

void RevolutionWall::ApplySimilarity(double scale, const VecS& offset_along) {
  for (KinematicSurface& f : faces_) f.ApplySimilarity(scale, offset_along);
  Rebuild();
}

void RevolutionWall::Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const {
  face(static_cast<int>(t[2])).Evaluate(t, derivatives, out);
}

void RevolutionWall::ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const {
  const int index = static_cast<int>(t[2]);
  face(index).ShapeJacobian(t, with_dt, out);
  for (JacobianEntry& e : out) e.index += offset(index);
}

bool RevolutionWall::FactoredShapeJacobian(const ParamT& t, FactoredJacobian& out) const {
  const int index = static_cast<int>(t[2]);
  if (!face(index).FactoredShapeJacobian(t, out)) return false;
  for (int i = 0; i < out.weight_count; ++i) out.first_index[static_cast<std::size_t>(i)] += offset(index);
  return true;
}

Eigen::MatrixXd RevolutionWall::FairnessMatrix(const FairnessWeights& weights) const {
  const Eigen::MatrixXd a = faces_[0].FairnessMatrix(weights), b = faces_[1].FairnessMatrix(weights);
  if (a.size() == 0 && b.size() == 0) return {};
  const int n0 = faces_[0].num_parameters(), n1 = faces_[1].num_parameters();
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(n0 + n1, n0 + n1);
  if (a.size() > 0) out.topLeftCorner(n0, n0) = a;
  if (b.size() > 0) out.bottomRightCorner(n1, n1) = b;
  return out;
}

std::vector<ParamT> RevolutionWall::SampleParameters() const {
  std::vector<ParamT> out;
  for (int index = 0; index < 2; ++index)
    for (ParamT t : face(index).SampleParameters()) {
      t[2] = index;
      out.push_back(t);
    }
  return out;
}

bool RevolutionWall::ClosedFormFootPoint(const VecS& x, ParamT& t) const {
  double distance = 0.0;
  bool on_boundary = false, ambiguous = false;
  return ClosedFormFoot(x, t, distance, on_boundary, ambiguous);
}

bool RevolutionWall::ClosedFormFoot(const VecS& x, ParamT& t, double& distance, bool& on_boundary,
                                    bool& ambiguous) const {
  LocalGeometry g;
  FootPoint best;
  for (int index = 0; index < 2; ++index) {
    FootPoint foot =
        FootPointOf(*contexts_[static_cast<std::size_t>(index)], x, nullptr, WarmStart::kVerified, g);
    foot.t[2] = index;
    if (index == 0 || foot.distance < best.distance) best = foot;
  }
  t = best.t;
  distance = best.distance;
  on_boundary = best.on_boundary;
  ambiguous = false;
  return true;
}

}  // namespace s2m
