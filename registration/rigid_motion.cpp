#include "registration/rigid_motion.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>

namespace s2m {
namespace {

// sin(x)/x and (1 - cos x)/x^2 with Taylor series near 0, where the direct quotients lose all digits.
double Sinc(double x) {
  if (std::abs(x) < 1e-4) return 1.0 - x * x / 6.0;
  return std::sin(x) / x;
}
double OneMinusCosOverSquare(double x) {
  if (std::abs(x) < 1e-4) return 0.5 - x * x / 24.0;
  return (1.0 - std::cos(x)) / (x * x);
}

}  // namespace

Eigen::Matrix3d RotationAboutAxis(const Eigen::Vector3d& axis, double angle) {
  return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
}

RigidMotion RigidMotion::FromHelicalVelocity(const Eigen::Vector3d& c, const Eigen::Vector3d& cbar) {
  const double phi = c.norm();
  if (phi == 0.0) return {Eigen::Matrix3d::Identity(), cbar};
  const Eigen::Vector3d a = c / phi;
  const Eigen::Vector3d cbar_par = a.dot(cbar) * a;
  const Eigen::Vector3d cbar_perp = cbar - cbar_par;
  const Eigen::Vector3d t = cbar_par + Sinc(phi) * cbar_perp + OneMinusCosOverSquare(phi) * c.cross(cbar);
  return {Eigen::AngleAxisd(phi, a).toRotationMatrix(), t};
}

Eigen::Matrix4d RigidMotion::matrix() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = rotation_;
  m.topRightCorner<3, 1>() = translation_;
  return m;
}

Eigen::Matrix3Xd RigidMotion::apply(const Eigen::Matrix3Xd& points) const {
  return (rotation_ * points).colwise() + translation_;
}

double RigidMotion::angle() const {
  const double c = std::clamp((rotation_.trace() - 1.0) / 2.0, -1.0, 1.0);
  // acos loses precision near 0; use atan2 of |axial vector| and cos.
  const Eigen::Vector3d w(rotation_(2, 1) - rotation_(1, 2), rotation_(0, 2) - rotation_(2, 0),
                          rotation_(1, 0) - rotation_(0, 1));
  return std::atan2(0.5 * w.norm(), c);
}

void RigidMotion::normalize() {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(rotation_, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d r = svd.matrixU() * svd.matrixV().transpose();
  if (r.determinant() < 0) {
    Eigen::Matrix3d u = svd.matrixU();
    u.col(2) *= -1.0;
    r = u * svd.matrixV().transpose();
  }
  rotation_ = r;
}

}  // namespace s2m
