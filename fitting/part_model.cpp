#include "fitting/part_model.h"

#include <Eigen/Dense>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "fitting/bspline_models.h"
#include "fitting/enum_names.h"
#include "fitting/fast_atan2.h"
#include "fitting/foot_point.h"

namespace s2m {
namespace {

// Unbounded faces: the parameter box only has to contain every foot point.
constexpr double kUnbounded = 1e12;

// To3 for the part's points, which are always 3D: three loads, where To3's run-time sized copy calls memcpy
// (twice per foot point, about 20 instructions).
Eigen::Vector3d Point3(const VecS& x) {
  return x.size() == 3 ? Eigen::Vector3d(x[0], x[1], x[2]) : To3(x);
}

Eigen::Vector3d OriginOf(const PartFace& f, const Eigen::VectorXd& p) {
  return {f.origin[0].Evaluate(p), f.origin[1].Evaluate(p), f.origin[2].Evaluate(p)};
}

// Unit radial direction at angle u in the face's (e1, e2) plane, and its u-derivative.
Eigen::Vector3d Radial(const PartFace& f, double u) {
  return std::cos(u) * f.frame.col(0) + std::sin(u) * f.frame.col(1);
}
Eigen::Vector3d RadialDu(const PartFace& f, double u) {
  return -std::sin(u) * f.frame.col(0) + std::cos(u) * f.frame.col(1);
}

// One analytic face's foot point in closed form (docs/method.md section 10): the unsigned distance and, with
// kParameter, the foot's t (u, v; t[2] is left to the caller). The angle u needs an atan2, the distance does
// not: the nearest-face search asks for t only on the face that wins. `c`: the face's
// PartModel::FaceConstants.
template <bool kParameter, typename FaceConstants>
double AnalyticFoot(const PartFace& f, const FaceConstants& c, const Eigen::Vector3d& x, ParamT* t) {
  const Eigen::Vector3d e1 = f.frame.col(0), e2 = f.frame.col(1), a = f.frame.col(2);
  if (f.type == FaceType::kPlane) {
    if constexpr (kParameter) *t = {e1.dot(x), e2.dot(x), 0.0};
    return std::abs(a.dot(x) - c.offset);
  }
  const Eigen::Vector3d q = x - c.origin;
  const double lx = e1.dot(q), ly = e2.dot(q), lz = a.dot(q);
  // sqrt rather than hypot (as CylinderModel): no overflow or underflow that matters is possible at model
  // coordinates, and glibc's hypot costs a call and about 55 instructions; the result differs by an ulp at
  // most.
  const double rho = std::sqrt(lx * lx + ly * ly);
  // FastAtan2 (fitting/fast_atan2.h): std::atan2 within 2 ulp, cheaper than glibc's.
  const auto angle = [&] { return rho > 0 ? FastAtan2(ly, lx) : 0.0; };
  const double r = c.radius;
  switch (f.type) {
    case FaceType::kCylinder:
      if constexpr (kParameter) *t = {angle(), lz, 0.0};
      return std::abs(rho - r);
    case FaceType::kCone: {
      // Generator in the half-plane of x: (r + v tan(alpha), v), unit direction (sin, cos) alpha. The other
      // nappe (radius < 0 in that half-plane) is the generator of the opposite half-plane: take the nearer.
      const double s = c.sin_alpha, co = c.cos_alpha;
      const double d_near = std::abs((rho - r) * co - lz * s), d_far = std::abs((-rho - r) * co - lz * s);
      if (d_near <= d_far) {
        if constexpr (kParameter) *t = {angle(), ((rho - r) * s + lz * co) * co, 0.0};
        return d_near;
      }
      if constexpr (kParameter) *t = {angle() + M_PI, ((-rho - r) * s + lz * co) * co, 0.0};
      return d_far;
    }
    case FaceType::kSphere:
      if constexpr (kParameter) *t = {angle(), FastAtan2(lz, rho), 0.0};
      return std::abs(q.norm() - r);
    case FaceType::kTorus:
      if constexpr (kParameter) *t = {angle(), FastAtan2(lz, rho - r), 0.0};
      return std::abs(std::sqrt((rho - r) * (rho - r) + lz * lz) - c.minor_radius);
    case FaceType::kPlane:
    case FaceType::kSplinePatch:  // no closed form: PartModel::FaceDistance
      break;
  }
  if constexpr (kParameter) *t = {0.0, 0.0, 0.0};
  return std::numeric_limits<double>::infinity();
}

ParameterDomain PatchDomain(const SplinePatch& patch) {
  ParameterDomain d;
  d.dimension = 2;
  d.lo = {patch.u.lo(), patch.v.lo()};
  d.hi = {patch.u.hi(), patch.v.hi()};
  return d;
}

// Sample parameters of a patch: at least 16 per direction and 8 per knot span, so that the nearest sample
// lies in the basin of the true foot point for points near the patch.
std::vector<double> PatchSamples(const BSplineBasis& basis) {
  const int spans = static_cast<int>(basis.Breakpoints().size()) - 1;
  const int n = std::max(16, 8 * spans);
  std::vector<double> out;
  for (int i = 0; i < n; ++i) out.push_back(basis.lo() + (basis.hi() - basis.lo()) * (i + 0.5) / n);
  return out;
}

// Accumulates coefficient * (column, d/du, d/dv) into the entry of parameter `index`.
void Add(std::vector<JacobianEntry>& out, int index, double coefficient, const Eigen::Vector3d& column,
         const Eigen::Vector3d& du, const Eigen::Vector3d& dv) {
  for (JacobianEntry& e : out) {
    if (e.index == index) {
      e.column += coefficient * column;
      e.dcolumn_dt[0] += coefficient * du;
      e.dcolumn_dt[1] += coefficient * dv;
      return;
    }
  }
  JacobianEntry e;
  e.index = index;
  e.column = coefficient * column;
  e.dcolumn_dt = {coefficient * du, coefficient * dv};
  out.push_back(e);
}

void AddExpression(std::vector<JacobianEntry>& out, const LinearExpression& e, const Eigen::Vector3d& column,
                   const Eigen::Vector3d& du, const Eigen::Vector3d& dv) {
  for (const auto& [index, coefficient] : e.terms) Add(out, index, coefficient, column, du, dv);
}

}  // namespace

double LinearExpression::Evaluate(const Eigen::VectorXd& parameters) const {
  double v = constant;
  for (const auto& [index, coefficient] : terms) v += coefficient * parameters[index];
  return v;
}

namespace {

constexpr std::array<EnumName<FaceType>, 6> kFaceTypeNames = {{
    {FaceType::kPlane, "plane"},
    {FaceType::kCylinder, "cylinder"},
    {FaceType::kCone, "cone"},
    {FaceType::kSphere, "sphere"},
    {FaceType::kTorus, "torus"},
    {FaceType::kSplinePatch, "spline_patch"},
}};

}  // namespace

const char* ToString(FaceType type) {
  return NameOf(kFaceTypeNames, type, "?");
}

PartModel::PartModel(PartDefinition definition) : definition_(std::move(definition)) {
  values_.resize(static_cast<Eigen::Index>(definition_.parameters.size()));
  for (std::size_t i = 0; i < definition_.parameters.size(); ++i)
    values_[static_cast<Eigen::Index>(i)] = definition_.parameters[i].value;
  Validate();
  for (const bool patches : {false, true})
    for (std::size_t k = 0; k < definition_.faces.size(); ++k)
      if ((definition_.faces[k].type == FaceType::kSplinePatch) == patches) search_order_.push_back(k);
  UpdatePatches();
  UpdateFaceConstants();
}

void PartModel::UpdateFaceConstants() {
  constants_.assign(definition_.faces.size(), FaceConstants{});
  for (std::size_t k = 0; k < definition_.faces.size(); ++k) {
    const PartFace& f = definition_.faces[k];
    FaceConstants& c = constants_[k];
    if (f.type == FaceType::kSplinePatch) continue;
    c.origin = OriginOf(f, values_);
    c.offset = f.offset.Evaluate(values_);
    c.radius = f.radius.Evaluate(values_);
    c.minor_radius = f.minor_radius.Evaluate(values_);
    const double alpha = f.half_angle.Evaluate(values_);
    c.sin_alpha = std::sin(alpha);
    c.cos_alpha = std::cos(alpha);
  }
}

void PartModel::Validate() const {
  if (definition_.faces.empty()) throw std::invalid_argument("a part needs at least one face");
  const int n = num_parameters();
  for (const PartFace& f : definition_.faces) {
    const std::string where = "face '" + f.name + "' (" + ToString(f.type) + "): ";
    if (!f.frame.allFinite() || (f.frame.transpose() * f.frame - Eigen::Matrix3d::Identity()).norm() > 1e-9 ||
        f.frame.determinant() < 0) {
      throw std::invalid_argument(where + "its frame is not a rotation");
    }
    auto check = [&](const LinearExpression& e, bool angle, const char* what) {
      for (const auto& [index, coefficient] : e.terms) {
        if (index < 0 || index >= n) throw std::invalid_argument(where + what + " refers to no parameter");
        if (definition_.parameters[static_cast<std::size_t>(index)].angle != angle) {
          throw std::invalid_argument(
              where + what +
              (angle ? " is an angle but uses the length '" : " is a length but uses the angle '") +
              definition_.parameters[static_cast<std::size_t>(index)].name + "'");
        }
        if (!std::isfinite(coefficient)) throw std::invalid_argument(where + what + " has a non-finite term");
      }
      const double v = e.Evaluate(values_);
      if (!std::isfinite(v)) throw std::invalid_argument(where + what + " is not finite");
      return v;
    };
    for (const LinearExpression& e : f.origin) check(e, false, "the origin");
    const double offset = check(f.offset, false, "the offset");
    (void)offset;
    const double radius = check(f.radius, false, "the radius");
    const double minor = check(f.minor_radius, false, "the minor radius");
    const double angle = check(f.half_angle, true, "the half angle");
    if ((f.type == FaceType::kCylinder || f.type == FaceType::kSphere || f.type == FaceType::kTorus) &&
        !(radius > 0)) {
      throw std::invalid_argument(where + "the radius must be positive");
    }
    if (f.type == FaceType::kTorus && !(minor > 0 && minor < radius)) {
      throw std::invalid_argument(where + "the minor radius must be positive and below the major radius");
    }
    if (f.type == FaceType::kCone && !(angle > 0 && angle < M_PI / 2)) {
      throw std::invalid_argument(where + "the half angle must lie in (0, 90) degrees");
    }
    if (f.type == FaceType::kSplinePatch) {
      if (!f.patch) throw std::invalid_argument(where + "has no control net");
      if (f.patch->u.periodic() || f.patch->v.periodic())
        throw std::invalid_argument(where + "a patch is open (clamped) in both directions");
      const std::size_t expected = static_cast<std::size_t>(f.patch->u.num_control()) *
                                   static_cast<std::size_t>(f.patch->v.num_control());
      if (f.patch->control_points.size() != expected) {
        throw std::invalid_argument(where + "the bases need " + std::to_string(f.patch->u.num_control()) +
                                    " x " + std::to_string(f.patch->v.num_control()) +
                                    " control points, not " + std::to_string(f.patch->control_points.size()));
      }
      for (const auto& point : f.patch->control_points)
        for (const LinearExpression& e : point) check(e, false, "a control point");
    }
  }
}

void PartModel::UpdatePatches() {
  patches_.assign(definition_.faces.size(), PatchState{});
  LocalGeometry g;
  for (std::size_t k = 0; k < definition_.faces.size(); ++k) {
    const PartFace& f = definition_.faces[k];
    if (f.type != FaceType::kSplinePatch) continue;
    PatchState& state = patches_[k];
    Eigen::Matrix3Xd control(3, static_cast<Eigen::Index>(f.patch->control_points.size()));
    for (std::size_t i = 0; i < f.patch->control_points.size(); ++i)
      for (std::size_t c = 0; c < 3; ++c)
        control(static_cast<Eigen::Index>(c), static_cast<Eigen::Index>(i)) =
            f.patch->control_points[i][c].Evaluate(values_);
    state.surface.emplace(f.patch->u, f.patch->v, std::move(control));
    const std::vector<double> us = PatchSamples(f.patch->u), vs = PatchSamples(f.patch->v);
    Eigen::Matrix3Xd points(3, static_cast<Eigen::Index>(us.size() * vs.size()));
    for (double u : us) {
      for (double v : vs) {
        const ParamT t{u, v, static_cast<double>(k)};
        state.surface->Evaluate(t, 0, g);
        points.col(static_cast<Eigen::Index>(state.sample_parameters.size())) = g.point;
        state.sample_parameters.push_back(t);
      }
    }
    const auto nv = static_cast<Eigen::Index>(vs.size());
    for (Eigen::Index i = 0; i + 1 < static_cast<Eigen::Index>(us.size()); ++i) {
      for (Eigen::Index j = 0; j < nv; ++j) {
        for (Eigen::Index dj = -1; dj <= 1; ++dj) {
          if (j + dj >= 0 && j + dj < nv) {
            state.covering_radius = std::max(
                state.covering_radius, (points.col((i + 1) * nv + j + dj) - points.col(i * nv + j)).norm());
          }
        }
        if (j + 1 < nv) {
          state.covering_radius =
              std::max(state.covering_radius, (points.col(i * nv + j + 1) - points.col(i * nv + j)).norm());
        }
      }
    }
    state.samples = NearestIndex(std::move(points));
  }
}

double PartModel::FaceDistance(std::size_t k, const Eigen::Vector3d& x, double needed_within,
                               ParamT& patch_t) const {
  const PartFace& f = definition_.faces[k];
  if (f.type != FaceType::kSplinePatch) {
    return AnalyticFoot<false>(f, constants_[k], x, nullptr);
  }
  const PatchState& state = patches_[k];
  const Eigen::Index nearest = state.samples.Nearest(x);
  if ((state.samples.points().col(nearest) - x).norm() - state.covering_radius > needed_within)
    return std::numeric_limits<double>::infinity();
  const ParamT seed = state.sample_parameters[static_cast<std::size_t>(nearest)];
  LocalGeometry g;
  const FootPoint foot = RefineFootPoint(*this, PatchDomain(*f.patch), x, seed, g);
  patch_t = foot.t;
  return foot.distance;
}

ParamT PartModel::FaceParameter(std::size_t k, const Eigen::Vector3d& x) const {
  const PartFace& f = definition_.faces[k];
  ParamT t{0.0, 0.0, 0.0};
  AnalyticFoot<true>(f, constants_[k], x, &t);
  t[2] = static_cast<double>(k);
  return t;
}

int PartModel::NearestFace(const Eigen::Vector3d& x, ParamT& t, double& distance,
                           std::array<double, kKept>* face_distance) const {
  double best = std::numeric_limits<double>::infinity();
  int winner = -1;
  ParamT patch_t{0.0, 0.0, 0.0}, best_patch_t{0.0, 0.0, 0.0};
  for (const std::size_t k : search_order_) {
    // Analytic faces inline (most parts have only these), patches through FaceDistance.
    const PartFace& f = definition_.faces[k];
    const double d = f.type != FaceType::kSplinePatch ? AnalyticFoot<false>(f, constants_[k], x, nullptr)
                                                      : FaceDistance(k, x, best, patch_t);
    if (face_distance != nullptr && k < kKept) (*face_distance)[k] = d;
    if (d < best) {
      best = d;
      winner = static_cast<int>(k);
      if (f.type == FaceType::kSplinePatch) best_patch_t = patch_t;
    }
  }
  if (winner >= 0) {
    const auto k = static_cast<std::size_t>(winner);
    t = definition_.faces[k].type == FaceType::kSplinePatch ? best_patch_t : FaceParameter(k, x);
  }
  distance = best;
  return winner;
}

ParameterDomain PartModel::domain() const {
  ParameterDomain d;
  d.dimension = 2;
  d.lo = {-kUnbounded, -kUnbounded};
  d.hi = {kUnbounded, kUnbounded};
  return d;
}

std::string PartModel::parameter_name(int index) const {
  return definition_.parameters.at(static_cast<std::size_t>(index)).name;
}

void PartModel::set_parameters(const Eigen::VectorXd& p) {
  if (p.size() != values_.size()) throw std::invalid_argument("wrong number of part parameters");
  values_ = p;
  UpdatePatches();
  UpdateFaceConstants();
}

void PartModel::ApplySimilarity(double scale, const VecS& offset) {
  // Lengths scale (parameters and expression constants), angles do not; the offset moves every face.
  const Eigen::Vector3d shift = To3(offset);
  for (Eigen::Index i = 0; i < values_.size(); ++i) {
    if (!definition_.parameters[static_cast<std::size_t>(i)].angle) values_[i] *= scale;
  }
  for (PartFace& f : definition_.faces) {
    for (int c = 0; c < 3; ++c) {
      f.origin[static_cast<std::size_t>(c)].constant =
          scale * f.origin[static_cast<std::size_t>(c)].constant + shift[c];
    }
    f.offset.constant = scale * f.offset.constant + f.frame.col(2).dot(shift);
    f.radius.constant *= scale;
    f.minor_radius.constant *= scale;
    if (f.patch) {
      for (auto& point : f.patch->control_points)
        for (int c = 0; c < 3; ++c)
          point[static_cast<std::size_t>(c)].constant =
              scale * point[static_cast<std::size_t>(c)].constant + shift[c];
    }
  }
  edge_margin_ *= scale;
  UpdatePatches();
  UpdateFaceConstants();
}

void PartModel::Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const {
  const PartFace& f = definition_.faces.at(static_cast<std::size_t>(FaceOf(t)));
  if (f.type == FaceType::kSplinePatch) {
    patches_[static_cast<std::size_t>(FaceOf(t))].surface->Evaluate(t, derivatives, out);
    return;
  }
  const double u = t[0], v = t[1];
  const Eigen::Vector3d a = f.frame.col(2);
  Eigen::Vector3d point = Eigen::Vector3d::Zero(), cu = point, cv = point, cuu = point, cuv = point,
                  cvv = point;
  switch (f.type) {
    case FaceType::kPlane:
      point = f.offset.Evaluate(values_) * a + u * f.frame.col(0) + v * f.frame.col(1);
      cu = f.frame.col(0);
      cv = f.frame.col(1);
      break;
    case FaceType::kCylinder: {
      const double r = f.radius.Evaluate(values_);
      point = OriginOf(f, values_) + r * Radial(f, u) + v * a;
      cu = r * RadialDu(f, u);
      cv = a;
      cuu = -r * Radial(f, u);
      break;
    }
    case FaceType::kCone: {
      const double slope = std::tan(f.half_angle.Evaluate(values_));
      const double rho = f.radius.Evaluate(values_) + v * slope;
      point = OriginOf(f, values_) + rho * Radial(f, u) + v * a;
      cu = rho * RadialDu(f, u);
      cv = slope * Radial(f, u) + a;
      cuu = -rho * Radial(f, u);
      cuv = slope * RadialDu(f, u);
      break;
    }
    case FaceType::kSphere: {
      const double r = f.radius.Evaluate(values_);
      const double cv_ = std::cos(v), sv = std::sin(v);
      point = OriginOf(f, values_) + r * (cv_ * Radial(f, u) + sv * a);
      cu = r * cv_ * RadialDu(f, u);
      cv = r * (-sv * Radial(f, u) + cv_ * a);
      cuu = -r * cv_ * Radial(f, u);
      cuv = -r * sv * RadialDu(f, u);
      cvv = -r * (cv_ * Radial(f, u) + sv * a);
      break;
    }
    case FaceType::kTorus: {
      const double big = f.radius.Evaluate(values_), tube = f.minor_radius.Evaluate(values_);
      const double cv_ = std::cos(v), sv = std::sin(v), rho = big + tube * cv_;
      point = OriginOf(f, values_) + rho * Radial(f, u) + tube * sv * a;
      cu = rho * RadialDu(f, u);
      cv = -tube * sv * Radial(f, u) + tube * cv_ * a;
      cuu = -rho * Radial(f, u);
      cuv = -tube * sv * RadialDu(f, u);
      cvv = -tube * (cv_ * Radial(f, u) + sv * a);
      break;
    }
    case FaceType::kSplinePatch:
      break;  // handled above
  }
  out.point = point;
  if (derivatives >= 1) {
    out.d1.resize(3, 2);
    out.d1 << cu, cv;
  }
  if (derivatives >= 2) {
    out.d2.resize(3, 3);
    out.d2 << cuu, cuv, cvv;
  }
}

void PartModel::ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const {
  (void)with_dt;  // the t-derivatives cost nothing extra here
  out.clear();
  const PartFace& f = definition_.faces.at(static_cast<std::size_t>(FaceOf(t)));
  const double u = t[0], v = t[1];
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero(), a = f.frame.col(2);
  const Eigen::Vector3d w = Radial(f, u), w_u = RadialDu(f, u);
  if (f.type == FaceType::kPlane) {
    AddExpression(out, f.offset, a, zero, zero);
    return;
  }
  if (f.type == FaceType::kSplinePatch) {
    // dS/dP_ij = N_i(u) M_j(v) I: each coordinate's expression gets the basis product along its axis.
    const SplinePatch& patch = *f.patch;
    BSplineBasis::Values bu, bv;
    patch.u.Evaluate(u, 1, bu);
    patch.v.Evaluate(v, 1, bv);
    const int nv = patch.v.num_control();
    for (int i = 0; i < patch.u.order(); ++i) {
      const auto ui = static_cast<std::size_t>(i);
      for (int j = 0; j < patch.v.order(); ++j) {
        const auto vj = static_cast<std::size_t>(j);
        const auto& point = patch.control_points[static_cast<std::size_t>(
            patch.u.ControlIndex(bu.first, i) * nv + patch.v.ControlIndex(bv.first, j))];
        const double b = bu.values[0][ui] * bv.values[0][vj], b_u = bu.values[1][ui] * bv.values[0][vj],
                     b_v = bu.values[0][ui] * bv.values[1][vj];
        for (int c = 0; c < 3; ++c) {
          const Eigen::Vector3d e = Eigen::Vector3d::Unit(c);
          AddExpression(out, point[static_cast<std::size_t>(c)], b * e, b_u * e, b_v * e);
        }
      }
    }
    return;
  }
  // The origin (axis point or centre) moves every point of the face alike.
  for (int c = 0; c < 3; ++c)
    AddExpression(out, f.origin[static_cast<std::size_t>(c)], Eigen::Vector3d::Unit(c), zero, zero);
  switch (f.type) {
    case FaceType::kCylinder:
      AddExpression(out, f.radius, w, w_u, zero);
      break;
    case FaceType::kCone: {
      // dC/dr = w; dC/dalpha = v sec^2(alpha) w (the radius at height v is r + v tan(alpha)).
      const double sec2 = 1.0 / std::pow(std::cos(f.half_angle.Evaluate(values_)), 2);
      AddExpression(out, f.radius, w, w_u, zero);
      AddExpression(out, f.half_angle, v * sec2 * w, v * sec2 * w_u, sec2 * w);
      break;
    }
    case FaceType::kSphere: {
      const double cv = std::cos(v), sv = std::sin(v);
      AddExpression(out, f.radius, cv * w + sv * a, cv * w_u, -sv * w + cv * a);
      break;
    }
    case FaceType::kTorus: {
      const double cv = std::cos(v), sv = std::sin(v);
      AddExpression(out, f.radius, w, w_u, zero);
      AddExpression(out, f.minor_radius, cv * w + sv * a, cv * w_u, -sv * w + cv * a);
      break;
    }
    case FaceType::kPlane:
    case FaceType::kSplinePatch:
      break;
  }
}

std::vector<ParamT> PartModel::SampleParameters() const {
  // A grid per face over the part's size (the largest length among parameters and constants).
  double size = 1.0;
  for (Eigen::Index i = 0; i < values_.size(); ++i) {
    if (!definition_.parameters[static_cast<std::size_t>(i)].angle)
      size = std::max(size, std::abs(values_[i]));
  }
  std::vector<ParamT> out;
  const int n = 16;
  for (std::size_t k = 0; k < definition_.faces.size(); ++k) {
    const PartFace& f = definition_.faces[k];
    const double face = static_cast<double>(k);
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) {
        const double a = (i + 0.5) / n, b = (j + 0.5) / n;
        switch (f.type) {
          case FaceType::kPlane:
            out.push_back({size * (2 * a - 1), size * (2 * b - 1), face});
            break;
          case FaceType::kCylinder:
          case FaceType::kCone:
            out.push_back({2 * M_PI * a, size * (2 * b - 1), face});
            break;
          case FaceType::kSphere:
            out.push_back({2 * M_PI * a, M_PI * (b - 0.5), face});
            break;
          case FaceType::kTorus:
            out.push_back({2 * M_PI * a, 2 * M_PI * b, face});
            break;
          case FaceType::kSplinePatch: {
            const SplinePatch& p = *f.patch;
            out.push_back({p.u.lo() + (p.u.hi() - p.u.lo()) * a, p.v.lo() + (p.v.hi() - p.v.lo()) * b, face});
            break;
          }
        }
      }
    }
  }
  return out;
}

bool PartModel::ClosedFormFootPoint(const VecS& x, ParamT& t) const {
  double distance = 0.0;
  NearestFace(Point3(x), t, distance, nullptr);
  return true;
}

bool PartModel::FootPointOnBoundary(const VecS& x, const ParamT& t) const {
  const PartFace& f = definition_.faces.at(static_cast<std::size_t>(FaceOf(t)));
  if (f.type != FaceType::kSplinePatch) return false;  // analytic faces are unbounded
  LocalGeometry g;
  Evaluate(t, 1, g);
  return IsBoundaryFootPoint(PatchDomain(*f.patch), t, g, x);
}

bool PartModel::AmbiguousFootPoint(const VecS& x, const ParamT& t) const {
  if (edge_margin_ <= 0.0) return false;
  const Eigen::Vector3d x3 = Point3(x);
  const auto own = static_cast<std::size_t>(FaceOf(t));
  ParamT patch_t{0.0, 0.0, 0.0};
  for (std::size_t k = 0; k < definition_.faces.size(); ++k) {
    if (k != own && FaceDistance(k, x3, edge_margin_, patch_t) < edge_margin_) return true;
  }
  return false;
}

bool PartModel::ClosedFormFoot(const VecS& x, ParamT& t, double& distance, bool& on_boundary,
                               bool& ambiguous) const {
  const Eigen::Vector3d x3 = Point3(x);
  // The distance to every face searched, for the ambiguity test (fixed capacity: no allocation per point;
  // faces beyond it are searched again there). Infinity: a patch skipped as farther than the best so far.
  std::array<double, kKept> face_distance;
  const std::size_t faces = definition_.faces.size();
  t = {0.0, 0.0, 0.0};
  NearestFace(x3, t, distance, &face_distance);
  const auto own = static_cast<std::size_t>(FaceOf(t));
  on_boundary = definition_.faces[own].type == FaceType::kSplinePatch && FootPointOnBoundary(x, t);
  ambiguous = false;
  if (edge_margin_ > 0.0) {
    ParamT patch_t{0.0, 0.0, 0.0};
    for (std::size_t k = 0; k < faces && !ambiguous; ++k) {
      if (k == own) continue;
      // A distance found above is the one FaceDistance would find again (same seed, same Newton); a skipped
      // patch is searched now within the margin.
      const double d = k < kKept && std::isfinite(face_distance[k])
                           ? face_distance[k]
                           : FaceDistance(k, x3, edge_margin_, patch_t);
      ambiguous = d < edge_margin_;
    }
  }
  return true;
}

std::vector<ResidualStatistics> PerFaceResiduals(const PartModel& part, const Eigen::Matrix3Xd& points) {
  std::vector<std::vector<double>> distances(static_cast<std::size_t>(part.face_count()));
  LocalGeometry g;
  for (Eigen::Index j = 0; j < points.cols(); ++j) {
    ParamT t{0.0, 0.0, 0.0};
    const VecS x = points.col(j);
    part.ClosedFormFootPoint(x, t);
    part.Evaluate(t, 0, g);
    distances[static_cast<std::size_t>(PartModel::FaceOf(t))].push_back((g.point - x).norm());
  }
  std::vector<ResidualStatistics> out;
  for (const std::vector<double>& d : distances) {
    out.push_back(ComputeResidualStatistics(
        Eigen::Map<const Eigen::VectorXd>(d.data(), static_cast<Eigen::Index>(d.size()))));
  }
  return out;
}

}  // namespace s2m
