#include "fitting/part_model.h"

#include <Eigen/Dense>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace s2m {
namespace {

// Unbounded faces: the parameter box only has to contain every foot point.
constexpr double kUnbounded = 1e12;

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

// One face's foot point in closed form (METHOD.md section 10): t and the unsigned distance.
std::pair<ParamT, double> FaceFootPoint(const PartFace& f, const Eigen::VectorXd& p,
                                        const Eigen::Vector3d& x) {
  const Eigen::Vector3d e1 = f.frame.col(0), e2 = f.frame.col(1), a = f.frame.col(2);
  if (f.type == FaceType::kPlane) {
    return {{e1.dot(x), e2.dot(x), 0.0}, std::abs(a.dot(x) - f.offset.Evaluate(p))};
  }
  const Eigen::Vector3d q = x - OriginOf(f, p);
  const double lx = e1.dot(q), ly = e2.dot(q), lz = a.dot(q);
  const double rho = std::hypot(lx, ly);
  const double u = rho > 0 ? std::atan2(ly, lx) : 0.0;
  const double r = f.radius.Evaluate(p);
  switch (f.type) {
    case FaceType::kCylinder:
      return {{u, lz, 0.0}, std::abs(rho - r)};
    case FaceType::kCone: {
      // Generator in the half-plane of x: (r + v tan(alpha), v), unit direction (sin, cos) alpha. The other
      // nappe (radius < 0 in that half-plane) is the generator of the opposite half-plane: take the nearer.
      const double alpha = f.half_angle.Evaluate(p), s = std::sin(alpha), c = std::cos(alpha);
      const double d_near = std::abs((rho - r) * c - lz * s), d_far = std::abs((-rho - r) * c - lz * s);
      if (d_near <= d_far) return {{u, ((rho - r) * s + lz * c) * c, 0.0}, d_near};
      return {{u + M_PI, ((-rho - r) * s + lz * c) * c, 0.0}, d_far};
    }
    case FaceType::kSphere:
      return {{u, std::atan2(lz, rho), 0.0}, std::abs(q.norm() - r)};
    case FaceType::kTorus: {
      const double tube = f.minor_radius.Evaluate(p);
      return {{u, std::atan2(lz, rho - r), 0.0}, std::abs(std::hypot(rho - r, lz) - tube)};
    }
    case FaceType::kPlane:
      break;
  }
  return {{0.0, 0.0, 0.0}, std::numeric_limits<double>::infinity()};
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

const char* ToString(FaceType type) {
  switch (type) {
    case FaceType::kPlane:
      return "plane";
    case FaceType::kCylinder:
      return "cylinder";
    case FaceType::kCone:
      return "cone";
    case FaceType::kSphere:
      return "sphere";
    case FaceType::kTorus:
      return "torus";
  }
  return "?";
}

PartModel::PartModel(PartDefinition definition) : definition_(std::move(definition)) {
  values_.resize(static_cast<Eigen::Index>(definition_.parameters.size()));
  for (std::size_t i = 0; i < definition_.parameters.size(); ++i)
    values_[static_cast<Eigen::Index>(i)] = definition_.parameters[i].value;
  Validate();
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
  }
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
  }
  edge_margin_ *= scale;
}

void PartModel::Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const {
  const PartFace& f = definition_.faces.at(static_cast<std::size_t>(FaceOf(t)));
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
        }
      }
    }
  }
  return out;
}

bool PartModel::ClosedFormFootPoint(const VecS& x, ParamT& t) const {
  const Eigen::Vector3d x3 = To3(x);
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < definition_.faces.size(); ++k) {
    auto [tk, d] = FaceFootPoint(definition_.faces[k], values_, x3);
    if (d < best) {
      best = d;
      t = tk;
      t[2] = static_cast<double>(k);
    }
  }
  return true;
}

bool PartModel::AmbiguousFootPoint(const VecS& x, const ParamT& t) const {
  if (edge_margin_ <= 0.0) return false;
  const Eigen::Vector3d x3 = To3(x);
  const auto own = static_cast<std::size_t>(FaceOf(t));
  for (std::size_t k = 0; k < definition_.faces.size(); ++k) {
    if (k != own && FaceFootPoint(definition_.faces[k], values_, x3).second < edge_margin_) return true;
  }
  return false;
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
