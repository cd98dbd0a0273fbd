#include "fitting/primitive_models.h"

#include <Eigen/Geometry>
#include <cmath>

#include "fitting/fast_atan2.h"

namespace s2m {
namespace {
// The cylinder's axial parameter range: the engine works in the unit box, so this is effectively unbounded.
constexpr double kAxialRange = 1e6;

void AddEntry(std::vector<JacobianEntry>& out, int index, const Eigen::Vector3d& column,
              const Eigen::Vector3d& d0, const Eigen::Vector3d& d1) {
  JacobianEntry e;
  e.index = index;
  e.column = column;
  e.dcolumn_dt = {d0, d1};
  out.push_back(e);
}
}  // namespace

// ---- CylinderModel
// ---------------------------------------------------------------------------------------------

CylinderModel::CylinderModel(const Cylinder& c)
    : point_(c.axis_point), frame_(FrameWithAxis(c.axis_direction.normalized())), radius_(c.radius) {}

Cylinder CylinderModel::shape() const {
  return {point_, frame_.col(2), radius_};
}

ParameterDomain CylinderModel::domain() const {
  ParameterDomain d;
  d.dimension = 2;
  d.lo = {0.0, -kAxialRange};
  d.hi = {2 * M_PI, kAxialRange};
  d.periodic = {true, false};
  return d;
}

std::string CylinderModel::parameter_name(int index) const {
  static const char* names[] = {"axis point x", "axis point y", "axis point z", "rotation x",
                                "rotation y",   "rotation z",   "radius"};
  return names[index];
}

Eigen::VectorXd CylinderModel::parameters() const {
  Eigen::VectorXd p = Eigen::VectorXd::Zero(7);
  p.head<3>() = point_;
  p[6] = radius_;
  return p;
}

void CylinderModel::set_parameters(const Eigen::VectorXd& p) {
  point_ = p.head<3>();
  const Eigen::Vector3d w = p.segment<3>(3);
  if (w.norm() > 0) frame_ = frame_ * Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
  radius_ = p[6];
}

void CylinderModel::ApplySimilarity(double scale, const VecS& offset) {
  point_ = scale * point_ + Eigen::Vector3d(offset);
  radius_ *= scale;
}

void CylinderModel::Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const {
  const double c = std::cos(t[0]), s = std::sin(t[0]);
  out.point = point_ + frame_ * Eigen::Vector3d(radius_ * c, radius_ * s, t[1]);
  out.d1.setZero(3, 2);
  out.d2.setZero(3, 3);
  if (derivatives >= 1) {
    out.d1.col(0) = frame_ * Eigen::Vector3d(-radius_ * s, radius_ * c, 0.0);
    out.d1.col(1) = frame_.col(2);
  }
  if (derivatives >= 2) out.d2.col(0) = frame_ * Eigen::Vector3d(-radius_ * c, -radius_ * s, 0.0);
}

void CylinderModel::ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const {
  out.clear();
  const double c = std::cos(t[0]), s = std::sin(t[0]);
  const Eigen::Vector3d q(radius_ * c, radius_ * s, t[1]), dq0(-radius_ * s, radius_ * c, 0.0), dq1(0, 0, 1);
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) AddEntry(out, k, Eigen::Vector3d::Unit(k), zero, zero);
  for (int k = 0; k < 3; ++k) {  // d/dw_k of R exp([w]x) q at w = 0: R (e_k x q)
    const Eigen::Vector3d e = Eigen::Vector3d::Unit(k);
    AddEntry(out, 3 + k, frame_ * e.cross(q), with_dt ? Eigen::Vector3d(frame_ * e.cross(dq0)) : zero,
             with_dt ? Eigen::Vector3d(frame_ * e.cross(dq1)) : zero);
  }
  AddEntry(out, 6, frame_ * Eigen::Vector3d(c, s, 0.0),
           with_dt ? Eigen::Vector3d(frame_ * Eigen::Vector3d(-s, c, 0.0)) : zero, zero);
}

std::vector<ParamT> CylinderModel::SampleParameters() const {
  std::vector<ParamT> out;
  for (int i = 0; i < 64; ++i)
    for (int j = -8; j <= 8; ++j) out.push_back({2 * M_PI * i / 64, 0.25 * j});
  return out;
}

bool CylinderModel::ClosedFormFootPoint(const VecS& x, ParamT& t) const {
  const Eigen::Vector3d q = frame_.transpose() * (Eigen::Vector3d(x) - point_);
  t = {FastAtan2(q.y(), q.x()), q.z()};
  t[0] += 2 * M_PI * static_cast<double>(t[0] < 0);  // into [0, 2 pi) without a branch on the data
  return true;
}

// In the cylinder's frame C(t) - x = (r - rho) (cos theta, sin theta, 0) with rho = |(q_x, q_y)| at the foot
// theta = atan2(q_y, q_x): the distance is |r - rho| (also for rho = 0 and a negative r during a fit),
// without evaluating C again.
bool CylinderModel::ClosedFormFoot(const VecS& x, ParamT& t, double& distance, bool& on_boundary,
                                   bool& ambiguous) const {
  const Eigen::Vector3d q = frame_.transpose() * (Eigen::Vector3d(x) - point_);
  t = {FastAtan2(q.y(), q.x()), q.z(), 0.0};
  t[0] += 2 * M_PI * static_cast<double>(t[0] < 0);  // into [0, 2 pi) without a branch on the data
  // sqrt rather than hypot: no overflow is possible at model coordinates, and hypot costs as much as atan2.
  // FastAtan2 (fitting/fast_atan2.h): std::atan2 within 2 ulp, cheaper than glibc's.
  distance = std::abs(radius_ - std::sqrt(q.x() * q.x() + q.y() * q.y()));
  on_boundary = false;  // the domain is periodic in theta and unbounded along the axis
  ambiguous = false;
  return true;
}

// ---- SphereModel
// -----------------------------------------------------------------------------------------------

SphereModel::SphereModel(const Sphere& sphere, const Eigen::Matrix3d& frame)
    : center_(sphere.center), frame_(frame), radius_(sphere.radius) {}

ParameterDomain SphereModel::domain() const {
  ParameterDomain d;
  d.dimension = 2;
  d.lo = {0.0, -M_PI / 2};
  d.hi = {2 * M_PI, M_PI / 2};
  d.periodic = {true, false};
  return d;
}

std::string SphereModel::parameter_name(int index) const {
  static const char* names[] = {"centre x", "centre y", "centre z", "radius"};
  return names[index];
}

Eigen::VectorXd SphereModel::parameters() const {
  Eigen::VectorXd p(4);
  p << center_, radius_;
  return p;
}

void SphereModel::set_parameters(const Eigen::VectorXd& p) {
  center_ = p.head<3>();
  radius_ = p[3];
}

void SphereModel::ApplySimilarity(double scale, const VecS& offset) {
  center_ = scale * center_ + Eigen::Vector3d(offset);
  radius_ *= scale;
}

void SphereModel::Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const {
  const double ct = std::cos(t[0]), st = std::sin(t[0]), cp = std::cos(t[1]), sp = std::sin(t[1]);
  const Eigen::Vector3d u(cp * ct, cp * st, sp);
  out.point = center_ + radius_ * (frame_ * u);
  out.d1.setZero(3, 2);
  out.d2.setZero(3, 3);
  if (derivatives >= 1) {
    out.d1.col(0) = radius_ * (frame_ * Eigen::Vector3d(-cp * st, cp * ct, 0.0));
    out.d1.col(1) = radius_ * (frame_ * Eigen::Vector3d(-sp * ct, -sp * st, cp));
  }
  if (derivatives >= 2) {
    out.d2.col(0) = radius_ * (frame_ * Eigen::Vector3d(-cp * ct, -cp * st, 0.0));
    out.d2.col(1) = radius_ * (frame_ * Eigen::Vector3d(sp * st, -sp * ct, 0.0));
    out.d2.col(2) = radius_ * (frame_ * Eigen::Vector3d(-cp * ct, -cp * st, -sp));
  }
}

void SphereModel::ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const {
  out.clear();
  const double ct = std::cos(t[0]), st = std::sin(t[0]), cp = std::cos(t[1]), sp = std::sin(t[1]);
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) AddEntry(out, k, Eigen::Vector3d::Unit(k), zero, zero);
  AddEntry(out, 3, frame_ * Eigen::Vector3d(cp * ct, cp * st, sp),
           with_dt ? Eigen::Vector3d(frame_ * Eigen::Vector3d(-cp * st, cp * ct, 0.0)) : zero,
           with_dt ? Eigen::Vector3d(frame_ * Eigen::Vector3d(-sp * ct, -sp * st, cp)) : zero);
}

std::vector<ParamT> SphereModel::SampleParameters() const {
  std::vector<ParamT> out;
  for (int i = 0; i < 32; ++i)
    for (int j = -7; j <= 7; ++j) out.push_back({2 * M_PI * i / 32, M_PI / 2 * j / 8});
  return out;
}

bool SphereModel::ClosedFormFootPoint(const VecS& x, ParamT& t) const {
  const Eigen::Vector3d q = frame_.transpose() * (Eigen::Vector3d(x) - center_);
  t = {FastAtan2(q.y(), q.x()), FastAtan2(q.z(), std::sqrt(q.x() * q.x() + q.y() * q.y()))};
  t[0] += 2 * M_PI * static_cast<double>(t[0] < 0);  // into [0, 2 pi) without a branch on the data
  return true;
}

// C(t) - x = (r - |q|) q / |q| at the foot: the distance is |r - |q||.
bool SphereModel::ClosedFormFoot(const VecS& x, ParamT& t, double& distance, bool& on_boundary,
                                 bool& ambiguous) const {
  const Eigen::Vector3d q = frame_.transpose() * (Eigen::Vector3d(x) - center_);
  const double rho = std::sqrt(q.x() * q.x() + q.y() * q.y());  // as ClosedFormFootPoint
  t = {FastAtan2(q.y(), q.x()), FastAtan2(q.z(), rho), 0.0};
  t[0] += 2 * M_PI * static_cast<double>(t[0] < 0);  // into [0, 2 pi) without a branch on the data
  distance = std::abs(radius_ - q.norm());
  on_boundary = false;  // the poles are not boundaries of the surface
  ambiguous = false;
  return true;
}

// A rotation with unit angular velocity a about the line through p has the velocity field v(x) = a x (x - p)
// = cbar + a x x with cbar = p x a (docs/method.md section 5's (c, cbar)).
std::vector<Motion6> CylinderModel::InvariantMotions() const {
  const Eigen::Vector3d a = frame_.col(2);
  Motion6 rotation, translation;
  rotation << a, point_.cross(a);
  translation << Eigen::Vector3d::Zero(), a;
  return {rotation, translation};
}

std::vector<Motion6> SphereModel::InvariantMotions() const {
  std::vector<Motion6> out;
  for (int i = 0; i < 3; ++i) {
    Motion6 rotation;
    rotation << Eigen::Vector3d::Unit(i), center_.cross(Eigen::Vector3d::Unit(i));
    out.push_back(rotation);
  }
  return out;
}

// ---- LineModel
// -------------------------------------------------------------------------------------------------

LineModel::LineModel(const Line3d& line)
    : point_(line.point), frame_(FrameWithAxis(line.direction.normalized())) {}

ParameterDomain LineModel::domain() const {
  ParameterDomain d;
  d.dimension = 1;
  d.lo = {-kAxialRange, 0.0};
  d.hi = {kAxialRange, 0.0};
  d.periodic = {false, false};
  return d;
}

std::string LineModel::parameter_name(int index) const {
  static const char* names[] = {"point x", "point y", "point z", "rotation x", "rotation y", "rotation z"};
  return names[index];
}

Eigen::VectorXd LineModel::parameters() const {
  Eigen::VectorXd p = Eigen::VectorXd::Zero(6);
  p.head<3>() = point_;
  return p;
}

void LineModel::set_parameters(const Eigen::VectorXd& p) {
  point_ = p.head<3>();
  const Eigen::Vector3d w = p.segment<3>(3);
  if (w.norm() > 0) frame_ = frame_ * Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
}

void LineModel::ApplySimilarity(double scale, const VecS& offset) {
  point_ = scale * point_ + Eigen::Vector3d(offset);
}

void LineModel::Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const {
  out.point = point_ + t[0] * frame_.col(2);
  out.d1.setZero(3, 1);
  out.d2.setZero(3, 1);
  if (derivatives >= 1) out.d1.col(0) = frame_.col(2);
}

void LineModel::ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const {
  out.clear();
  const Eigen::Vector3d q(0.0, 0.0, t[0]), dq(0.0, 0.0, 1.0);
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) AddEntry(out, k, Eigen::Vector3d::Unit(k), zero, zero);
  for (int k = 0; k < 3; ++k) {  // d/dw_k of R exp([w]x) q at w = 0: R (e_k x q)
    const Eigen::Vector3d e = Eigen::Vector3d::Unit(k);
    AddEntry(out, 3 + k, frame_ * e.cross(q), with_dt ? Eigen::Vector3d(frame_ * e.cross(dq)) : zero, zero);
  }
}

std::vector<ParamT> LineModel::SampleParameters() const {
  std::vector<ParamT> out;
  for (int i = -32; i <= 32; ++i) out.push_back({0.0625 * i, 0.0});
  return out;
}

bool LineModel::ClosedFormFootPoint(const VecS& x, ParamT& t) const {
  t = {frame_.col(2).dot(Eigen::Vector3d(x) - point_), 0.0, 0.0};
  return true;
}

bool LineModel::ClosedFormFoot(const VecS& x, ParamT& t, double& distance, bool& on_boundary,
                               bool& ambiguous) const {
  const Eigen::Vector3d v = Eigen::Vector3d(x) - point_;
  t = {frame_.col(2).dot(v), 0.0, 0.0};
  distance = (v - t[0] * frame_.col(2)).norm();
  on_boundary = false;  // unbounded
  ambiguous = false;
  return true;
}

std::vector<Motion6> LineModel::InvariantMotions() const {
  const Eigen::Vector3d a = frame_.col(2);
  Motion6 rotation, translation;
  rotation << a, point_.cross(a);
  translation << Eigen::Vector3d::Zero(), a;
  return {rotation, translation};
}

// ---- TorusModel
// ------------------------------------------------------------------------------------------------

TorusModel::TorusModel(const Torus& torus)
    : center_(torus.center),
      frame_(FrameWithAxis(torus.axis.normalized())),
      major_(torus.major_radius),
      minor_(torus.minor_radius) {}

ParameterDomain TorusModel::domain() const {
  ParameterDomain d;
  d.dimension = 2;
  d.lo = {0.0, 0.0};
  d.hi = {2 * M_PI, 2 * M_PI};
  d.periodic = {true, true};
  return d;
}

std::string TorusModel::parameter_name(int index) const {
  static const char* names[] = {"centre x",   "centre y",   "centre z",     "rotation x",
                                "rotation y", "rotation z", "major radius", "minor radius"};
  return names[index];
}

Eigen::VectorXd TorusModel::parameters() const {
  Eigen::VectorXd p = Eigen::VectorXd::Zero(8);
  p.head<3>() = center_;
  p[6] = major_;
  p[7] = minor_;
  return p;
}

void TorusModel::set_parameters(const Eigen::VectorXd& p) {
  center_ = p.head<3>();
  const Eigen::Vector3d w = p.segment<3>(3);
  if (w.norm() > 0) frame_ = frame_ * Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
  major_ = p[6];
  minor_ = p[7];
}

void TorusModel::ApplySimilarity(double scale, const VecS& offset) {
  center_ = scale * center_ + Eigen::Vector3d(offset);
  major_ *= scale;
  minor_ *= scale;
}

void TorusModel::Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const {
  const double ct = std::cos(t[0]), st = std::sin(t[0]), cp = std::cos(t[1]), sp = std::sin(t[1]);
  const double w = major_ + minor_ * cp;  // distance of the point from the axis
  out.point = center_ + frame_ * Eigen::Vector3d(w * ct, w * st, minor_ * sp);
  out.d1.setZero(3, 2);
  out.d2.setZero(3, 3);
  if (derivatives >= 1) {
    out.d1.col(0) = frame_ * Eigen::Vector3d(-w * st, w * ct, 0.0);
    out.d1.col(1) = frame_ * Eigen::Vector3d(-minor_ * sp * ct, -minor_ * sp * st, minor_ * cp);
  }
  if (derivatives >= 2) {
    out.d2.col(0) = frame_ * Eigen::Vector3d(-w * ct, -w * st, 0.0);
    out.d2.col(1) = frame_ * Eigen::Vector3d(minor_ * sp * st, -minor_ * sp * ct, 0.0);
    out.d2.col(2) = frame_ * Eigen::Vector3d(-minor_ * cp * ct, -minor_ * cp * st, -minor_ * sp);
  }
}

void TorusModel::ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const {
  out.clear();
  const double ct = std::cos(t[0]), st = std::sin(t[0]), cp = std::cos(t[1]), sp = std::sin(t[1]);
  const double w = major_ + minor_ * cp;
  const Eigen::Vector3d q(w * ct, w * st, minor_ * sp), dq0(-w * st, w * ct, 0.0),
      dq1(-minor_ * sp * ct, -minor_ * sp * st, minor_ * cp);
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) AddEntry(out, k, Eigen::Vector3d::Unit(k), zero, zero);
  for (int k = 0; k < 3; ++k) {  // d/dw_k of R exp([w]x) q at w = 0: R (e_k x q)
    const Eigen::Vector3d e = Eigen::Vector3d::Unit(k);
    AddEntry(out, 3 + k, frame_ * e.cross(q), with_dt ? Eigen::Vector3d(frame_ * e.cross(dq0)) : zero,
             with_dt ? Eigen::Vector3d(frame_ * e.cross(dq1)) : zero);
  }
  AddEntry(out, 6, frame_ * Eigen::Vector3d(ct, st, 0.0),
           with_dt ? Eigen::Vector3d(frame_ * Eigen::Vector3d(-st, ct, 0.0)) : zero, zero);
  AddEntry(out, 7, frame_ * Eigen::Vector3d(cp * ct, cp * st, sp),
           with_dt ? Eigen::Vector3d(frame_ * Eigen::Vector3d(-cp * st, cp * ct, 0.0)) : zero,
           with_dt ? Eigen::Vector3d(frame_ * Eigen::Vector3d(-sp * ct, -sp * st, cp)) : zero);
}

std::vector<ParamT> TorusModel::SampleParameters() const {
  std::vector<ParamT> out;
  for (int i = 0; i < 32; ++i)
    for (int j = 0; j < 16; ++j) out.push_back({2 * M_PI * i / 32, 2 * M_PI * j / 16});
  return out;
}

bool TorusModel::ClosedFormFootPoint(const VecS& x, ParamT& t) const {
  double distance;
  bool on_boundary, ambiguous;
  return ClosedFormFoot(x, t, distance, on_boundary, ambiguous);
}

// In the meridian half-plane of x the torus is the circle of radius r about (R0, 0): the foot is on the ray
// from that centre through (rho, q_z), and the distance |hypot(rho - R0, q_z) - r|.
bool TorusModel::ClosedFormFoot(const VecS& x, ParamT& t, double& distance, bool& on_boundary,
                                bool& ambiguous) const {
  const Eigen::Vector3d q = frame_.transpose() * (Eigen::Vector3d(x) - center_);
  const double rho = std::sqrt(q.x() * q.x() + q.y() * q.y());
  t = {std::atan2(q.y(), q.x()), std::atan2(q.z(), rho - major_), 0.0};
  for (int k = 0; k < 2; ++k) t[k] += 2 * M_PI * static_cast<double>(t[k] < 0);  // into [0, 2 pi)
  distance = std::abs(std::hypot(rho - major_, q.z()) - minor_);
  on_boundary = false;   // periodic in both parameters
  ambiguous = rho == 0;  // on the axis every meridian is as near
  return true;
}

std::vector<Motion6> TorusModel::InvariantMotions() const {
  const Eigen::Vector3d a = frame_.col(2);
  Motion6 rotation;
  rotation << a, center_.cross(a);
  return {rotation};
}

namespace {
std::vector<Motion6> AllRigidMotions() {
  std::vector<Motion6> out;
  for (int i = 0; i < 6; ++i) out.push_back(Motion6::Unit(i));
  return out;
}
}  // namespace

std::vector<Motion6> CylinderModel::CommonMotionsAbsorbedByShape() const {
  return AllRigidMotions();
}

std::vector<Motion6> SphereModel::CommonMotionsAbsorbedByShape() const {
  return AllRigidMotions();
}

std::vector<Motion6> LineModel::CommonMotionsAbsorbedByShape() const {
  return AllRigidMotions();
}

std::vector<Motion6> TorusModel::CommonMotionsAbsorbedByShape() const {
  return AllRigidMotions();
}

}  // namespace s2m
