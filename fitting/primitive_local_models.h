#pragma once
// The primitives' local models (internal to fitting/): per family the closed-form distances, their rows
// d(distance)/d(local parameters) at the zero increment (TDM), the SDM tangential terms, the update that
// applies an increment and the map from the local covariance to user-facing uncertainties. The
// least-squares fits (primitive_fit.cpp) and the Chebyshev fits (minimum_zone.cpp) share them, so each
// Jacobian is written once.
//
// A model provides: Shape, kParams, kSizeParameter (the local parameter that shifts every distance by
// minus its increment, the size or offset: -1 when there is none), kRowsPerPoint (1 for surfaces; 2 for
// the curves, whose residual is the 2-vector across the curve), kSupportsSdm, Linearize, Update, Magnitude
// and Uncertainties.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <string>
#include <vector>

#include "fitting/primitive_fit.h"
#include "fitting/primitives.h"
#include "registration/local_quadric.h"

namespace s2m::primitive_local {

// Data centred at the centroid and scaled uniformly into the unit box (docs/method.md section 3), so that
// tolerances and damping do not depend on the user's units or on where the part sits in the scanner's frame.
struct NormalizedData {
  Eigen::Vector3d offset;
  double scale = 1.0;
  Eigen::Matrix3Xd points;
};

inline NormalizedData Normalize(const Eigen::Ref<const Eigen::Matrix3Xd>& points, Eigen::Index min_points,
                                const char* what) {
  if (points.cols() < min_points) {
    throw FitError(std::string("a ") + what + " fit needs at least " + std::to_string(min_points) +
                   " points, got " + std::to_string(points.cols()));
  }
  if (!points.allFinite())
    throw FitError(std::string("cannot fit a ") + what + ": the points contain NaN or inf");
  NormalizedData n;
  n.offset = points.rowwise().mean();
  const double half_extent = 0.5 * (points.rowwise().maxCoeff() - points.rowwise().minCoeff()).maxCoeff();
  if (!(half_extent > 0.0)) throw FitError(std::string("cannot fit a ") + what + ": all points coincide");
  n.scale = half_extent;
  n.points = (points.colwise() - n.offset) / n.scale;
  return n;
}

// Coordinates of y in the frame whose z axis is an axis through `point`: distance from the axis, the
// direction (cos, sin) around it and the axial position.
struct AxisCoordinates {
  double rho, cos, sin, z;
};
inline AxisCoordinates InAxisFrame(const Eigen::Matrix3d& frame, const Eigen::Vector3d& point,
                                   const Eigen::Vector3d& y) {
  const Eigen::Vector3d v = frame.transpose() * (y - point);
  const double rho = std::hypot(v[0], v[1]);
  return {rho, rho > 0 ? v[0] / rho : 1.0, rho > 0 ? v[1] / rho : 0.0, v[2]};
}

// Applies the axis increments (u1, u2, a1, b1) of the local parametrization: the axis point moves by (u1, u2,
// 0), the direction becomes (a1, b1, 1), both in the frame of the current axis.
inline void MoveAxis(const Eigen::Vector3d& point, const Eigen::Vector3d& direction,
                     const Eigen::VectorXd& delta, Eigen::Vector3d& new_point,
                     Eigen::Vector3d& new_direction) {
  const Eigen::Matrix3d frame = FrameWithAxis(direction);
  new_point = point + frame * Eigen::Vector3d(delta[0], delta[1], 0.0);
  new_direction = (frame * Eigen::Vector3d(delta[2], delta[3], 1.0)).normalized();
}

// ---- Models: closed-form foot points, TDM rows d(distance)/d(params) and SDM tangential rows
// ---------------------- For every model the TDM row equals -n^T C_P at the foot point (Liu & Wang, GMP 2008,
// section 3), and the SDM term adds beta_k (T_k^T C_P)^T (T_k^T C_P) with C_P the motion of the model point
// at a fixed surface parameter.

// An SDM weight scaled by a point's robust IRLS weight (no weights: plain least squares, unchanged).
inline double Weighted(const double* weights, Eigen::Index i, double beta) {
  return weights ? weights[i] * beta : beta;
}

// The plane is fitted in closed form (FitPlane); this local model serves its robust refinement. Local
// parameters (w, t1, t2): the point moves by w n, the normal becomes n + t1 e1 + t2 e2 (normalized) with
// (e1, e2, n) = FrameWithAxis(n); so d = n.(y - p) has the rows (-1, e1.(y - p), e2.(y - p)). A plane has
// no curvature: SDM adds no tangential terms.
struct PlaneLocal {
  using Shape = Plane;
  static constexpr int kParams = 3;
  static constexpr int kSizeParameter = 0;
  static constexpr int kRowsPerPoint = 1;
  static constexpr bool kSupportsSdm = true;
  static std::vector<ParameterUncertainty> Uncertainties(const Eigen::Matrix3d& cov, double scale) {
    return {{"offset", std::sqrt(cov(0, 0)) * scale, false},
            {"normal_direction", std::sqrt(cov(1, 1) + cov(2, 2)), true}};
  }
  static double Magnitude(const Plane& s) { return s.point.norm() + 1.0; }

  template <class JacobianT, class TangentialT>
  static void Linearize(const Plane& s, const Eigen::Matrix3Xd& y, bool /*sdm*/, const double* /*weights*/,
                        Eigen::VectorXd& d, JacobianT& J, TangentialT& T) {
    const Eigen::Matrix3d frame = FrameWithAxis(s.normal);
    const Eigen::Index n = y.cols();
    d.resize(n);
    J.resize(n, kParams);
    T.setZero();
    for (Eigen::Index i = 0; i < n; ++i) {
      const Eigen::Vector3d v = y.col(i) - s.point;
      d[i] = s.normal.dot(v);
      J.row(i) << -1.0, frame.col(0).dot(v), frame.col(1).dot(v);
    }
  }

  static Plane Update(const Plane& s, const Eigen::VectorXd& delta) {
    const Eigen::Matrix3d frame = FrameWithAxis(s.normal);
    Plane out;
    out.point = s.point + delta[0] * s.normal;
    out.normal = (s.normal + delta[1] * frame.col(0) + delta[2] * frame.col(1)).normalized();
    out.point = out.normal * out.normal.dot(out.point);  // the foot of the origin: a canonical point
    return out;
  }
};

struct SphereLocal {
  using Shape = Sphere;
  static constexpr int kParams = 4;
  static constexpr int kSizeParameter = 3;
  static constexpr int kRowsPerPoint = 1;
  static constexpr bool kSupportsSdm = true;
  // User-facing uncertainties: which local parameters (summed in quadrature) and whether the result is a
  // length.
  static std::vector<ParameterUncertainty> Uncertainties(const Eigen::Matrix4d& cov, double scale) {
    return {{"center_x", std::sqrt(cov(0, 0)) * scale, false},
            {"center_y", std::sqrt(cov(1, 1)) * scale, false},
            {"center_z", std::sqrt(cov(2, 2)) * scale, false},
            {"radius", std::sqrt(cov(3, 3)) * scale, false}};
  }
  static double Magnitude(const Sphere& s) { return s.center.norm() + std::abs(s.radius); }

  template <class JacobianT, class TangentialT>
  static void Linearize(const Sphere& s, const Eigen::Matrix3Xd& y, bool sdm, const double* weights,
                        Eigen::VectorXd& d, JacobianT& J, TangentialT& T) {
    const Eigen::Index n = y.cols();
    d.resize(n);
    J.resize(n, kParams);
    T.setZero();
    const double kappa = -1.0 / s.radius;  // outward normal: the sphere bends away from n
    for (Eigen::Index i = 0; i < n; ++i) {
      const Eigen::Vector3d v = y.col(i) - s.center;
      const double rho = v.norm();
      const Eigen::Vector3d normal = rho > 0 ? Eigen::Vector3d(v / rho) : Eigen::Vector3d::UnitZ();
      d[i] = rho - s.radius;
      J.row(i) << -normal.transpose(), -1.0;
      if (sdm) {
        const double beta = Weighted(weights, i, SdmWeight(d[i], kappa));
        // C_P = [I | n]: both tangential directions see the centre block only.
        if (beta > 0)
          T.template topLeftCorner<3, 3>() +=
              beta * (Eigen::Matrix3d::Identity() - normal * normal.transpose());
      }
    }
  }

  static Sphere Update(const Sphere& s, const Eigen::VectorXd& delta) {
    return {s.center + delta.head<3>(), s.radius + delta[3]};
  }
};

struct CylinderLocal {
  using Shape = Cylinder;
  static constexpr int kParams = 5;
  static constexpr int kSizeParameter = 4;
  static constexpr int kRowsPerPoint = 1;
  static constexpr bool kSupportsSdm = true;
  static std::vector<ParameterUncertainty> Uncertainties(const Eigen::Matrix<double, 5, 5>& cov,
                                                         double scale) {
    return {{"axis_position", std::sqrt(cov(0, 0) + cov(1, 1)) * scale, false},
            {"axis_direction", std::sqrt(cov(2, 2) + cov(3, 3)), true},
            {"radius", std::sqrt(cov(4, 4)) * scale, false}};
  }
  static double Magnitude(const Cylinder& s) { return s.axis_point.norm() + 1.0 + std::abs(s.radius); }

  // Local parameters (u1, u2, a1, b1, r): axis point (u1, u2, 0) and direction (a1, b1, 1) in the frame whose
  // z axis is the current axis (Forbes, NPL DITC 140/89, section 6). Foot point of y: s = y - d n, n = (cos
  // t, sin t, 0).
  template <class JacobianT, class TangentialT>
  static void Linearize(const Cylinder& s, const Eigen::Matrix3Xd& y, bool sdm, const double* weights,
                        Eigen::VectorXd& d, JacobianT& J, TangentialT& T) {
    const Eigen::Matrix3d frame = FrameWithAxis(s.axis_direction);
    const Eigen::Index n = y.cols();
    d.resize(n);
    J.resize(n, kParams);
    T.setZero();
    const double kappa = -1.0 / s.radius;
    Eigen::Matrix<double, kParams, 1> t;
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto [rho, c, sn, z] = InAxisFrame(frame, s.axis_point, y.col(i));
      d[i] = rho - s.radius;
      J.row(i) << -c, -sn, -c * z, -sn * z, -1.0;
      if (sdm) {
        // Circumferential direction T1 = (-sin, cos, 0), kappa1 = -1/r; the rulings are straight (kappa2 =
        // 0).
        const double beta = Weighted(weights, i, SdmWeight(d[i], kappa));
        if (beta > 0) {
          t << -sn, c, -z * sn, z * c, 0.0;
          T.noalias() += beta * t * t.transpose();
        }
      }
    }
  }

  static Cylinder Update(const Cylinder& s, const Eigen::VectorXd& delta) {
    Cylinder out;
    MoveAxis(s.axis_point, s.axis_direction, delta, out.axis_point, out.axis_direction);
    out.radius = s.radius + delta[4];
    MoveAxisPointNear(out, Eigen::Vector3d::Zero());
    return out;
  }
};

struct ConeLocal {
  using Shape = Cone;
  static constexpr int kParams = 6;
  static constexpr int kSizeParameter = 5;
  static constexpr int kRowsPerPoint = 1;
  static constexpr bool kSupportsSdm = true;
  static std::vector<ParameterUncertainty> Uncertainties(const Eigen::Matrix<double, 6, 6>& cov,
                                                         double scale) {
    return {{"axis_position", std::sqrt(cov(0, 0) + cov(1, 1)) * scale, false},
            {"axis_direction", std::sqrt(cov(2, 2) + cov(3, 3)), true},
            {"half_angle", std::sqrt(cov(4, 4)), true},
            {"surface_distance", std::sqrt(cov(5, 5)) * scale, false}};
  }
  static double Magnitude(const Cone& s) {
    return s.axis_point.norm() + 1.0 + std::abs(s.radius) + s.half_angle;
  }

  // Local parameters (u1, u2, a1, b1, psi, s) with d = rho cos(psi) - z sin(psi) - s (Forbes, NPL DITC
  // 140/89, section 7): s, the orthogonal distance from the axis point to the surface, stays well conditioned
  // for small apex angles where the apex runs off to infinity.
  template <class JacobianT, class TangentialT>
  static void Linearize(const Cone& s, const Eigen::Matrix3Xd& y, bool sdm, const double* weights,
                        Eigen::VectorXd& d, JacobianT& J, TangentialT& T) {
    const Eigen::Matrix3d frame = FrameWithAxis(s.axis_direction);
    const double cpsi = std::cos(s.half_angle), spsi = std::sin(s.half_angle);
    const double offset = s.radius * cpsi;
    const Eigen::Index n = y.cols();
    d.resize(n);
    J.resize(n, kParams);
    T.setZero();
    Eigen::Matrix<double, kParams, 1> t;
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto [rho, c, sn, z] = InAxisFrame(frame, s.axis_point, y.col(i));
      d[i] = rho * cpsi - z * spsi - offset;
      const double dpsi = -rho * spsi - z * cpsi;
      J.row(i) << -cpsi * c, -cpsi * sn, c * dpsi, sn * dpsi, dpsi, -1.0;
      if (sdm) {
        // Foot point s = y - d n with n = (cos psi e_rho - sin psi e_z): radius rho_f = rho - d cos psi,
        // axial h = z + d sin psi. The circle direction has normal curvature -cos(psi)/rho_f; the rulings are
        // straight.
        const double rho_foot = rho - d[i] * cpsi;
        if (rho_foot > 0) {
          const double beta = Weighted(weights, i, SdmWeight(d[i], -cpsi / rho_foot));
          const double h = z + d[i] * spsi;
          if (beta > 0) {
            t << -sn, c, -h * sn, h * c, 0.0, 0.0;
            T.noalias() += beta * t * t.transpose();
          }
        }
      }
    }
  }

  static Cone Update(const Cone& s, const Eigen::VectorXd& delta) {
    Cone out;
    MoveAxis(s.axis_point, s.axis_direction, delta, out.axis_point, out.axis_direction);
    out.half_angle = s.half_angle + delta[4];
    out.radius = (s.radius * std::cos(s.half_angle) + delta[5]) / std::cos(out.half_angle);
    if (out.half_angle < 0) {  // the same cone, opening the other way
      out.half_angle = -out.half_angle;
      out.axis_direction = -out.axis_direction;
    }
    MoveAxisPointNear(out, Eigen::Vector3d::Zero());
    return out;
  }
};

// A line: local parameters (u1, u2, a1, b1), the point moved by u1 e1 + u2 e2 and the direction turned to
// a + a1 e1 + b1 e2 (normalized), (e1, e2, a) = FrameWithAxis(a). The residual of y is the 2-vector
// (e1.v, e2.v), v = y - p, whose length is the distance; to first order it becomes (e1.v - u1 - a1 z,
// e2.v - u2 - b1 z) with z = a.v (docs/metrology.md eq. 1). Straight: SDM adds nothing, TDM is exact
// Gauss-Newton.
struct LineLocal {
  using Shape = Line3d;
  static constexpr int kParams = 4;
  static constexpr int kSizeParameter = -1;
  static constexpr int kRowsPerPoint = 2;
  static constexpr bool kSupportsSdm = true;
  static std::vector<ParameterUncertainty> Uncertainties(const Eigen::Matrix4d& cov, double scale) {
    return {{"position", std::sqrt(cov(0, 0) + cov(1, 1)) * scale, false},
            {"direction", std::sqrt(cov(2, 2) + cov(3, 3)), true}};
  }
  static double Magnitude(const Line3d& s) { return s.point.norm() + 1.0; }

  template <class JacobianT, class TangentialT>
  static void Linearize(const Line3d& s, const Eigen::Matrix3Xd& y, bool /*sdm*/, const double* /*weights*/,
                        Eigen::VectorXd& d, JacobianT& J, TangentialT& T) {
    const Eigen::Matrix3d frame = FrameWithAxis(s.direction);
    const Eigen::Index n = y.cols();
    d.resize(2 * n);
    J.setZero(2 * n, kParams);
    T.setZero();
    for (Eigen::Index i = 0; i < n; ++i) {
      const Eigen::Vector3d q = frame.transpose() * (y.col(i) - s.point);
      d[2 * i] = q.x();
      d[2 * i + 1] = q.y();
      J(2 * i, 0) = -1.0;
      J(2 * i, 2) = -q.z();
      J(2 * i + 1, 1) = -1.0;
      J(2 * i + 1, 3) = -q.z();
    }
  }

  static Line3d Update(const Line3d& s, const Eigen::VectorXd& delta) {
    Line3d out;
    MoveAxis(s.point, s.direction, delta, out.point, out.direction);
    MoveAxisPointNear(out, Eigen::Vector3d::Zero());
    return out;
  }
};

// A circle in space: local parameters (c1, c2, c3, t1, t2, r), the centre moved by c1 e1 + c2 e2 + c3 n,
// the normal turned to n + t1 e1 + t2 e2 (normalized), (e1, e2, n) = FrameWithAxis(n), the radius r added.
// With (q1, q2, h) = F^T (y - c), rho = |(q1, q2)| and (cos t, sin t) = (q1, q2) / rho, the residual is the
// 2-vector (h, rho - r) (height over the plane, radial offset in it), whose length is the distance, with
// the rows (0, 0, -1, q1, q2, 0) and (-cos t, -sin t, 0, -h cos t, -h sin t, -1) (docs/metrology.md
// eq. 2). TDM only: the SDM terms of a space curve are not derived here.
struct CircleLocal {
  using Shape = Circle3d;
  static constexpr int kParams = 6;
  static constexpr int kSizeParameter = -1;  // the radius shifts only the in-plane component
  static constexpr int kRowsPerPoint = 2;
  static constexpr bool kSupportsSdm = false;
  // The centre's covariance is mapped from the circle's frame to world axes: F C F^T. `frame` is the
  // circle's frame at the solution (FrameWithAxis(normal)).
  static std::vector<ParameterUncertainty> Uncertainties(const Eigen::Matrix<double, 6, 6>& cov, double scale,
                                                         const Eigen::Matrix3d& frame) {
    const Eigen::Matrix3d c = frame * cov.topLeftCorner<3, 3>() * frame.transpose();
    return {{"center_x", std::sqrt(c(0, 0)) * scale, false},
            {"center_y", std::sqrt(c(1, 1)) * scale, false},
            {"center_z", std::sqrt(c(2, 2)) * scale, false},
            {"normal_direction", std::sqrt(cov(3, 3) + cov(4, 4)), true},
            {"radius", std::sqrt(cov(5, 5)) * scale, false}};
  }
  static Eigen::Matrix3d FrameOf(const Circle3d& s) { return FrameWithAxis(s.normal); }
  static double Magnitude(const Circle3d& s) { return s.center.norm() + 1.0 + std::abs(s.radius); }

  template <class JacobianT, class TangentialT>
  static void Linearize(const Circle3d& s, const Eigen::Matrix3Xd& y, bool /*sdm*/, const double* /*weights*/,
                        Eigen::VectorXd& d, JacobianT& J, TangentialT& T) {
    const Eigen::Matrix3d frame = FrameWithAxis(s.normal);
    const Eigen::Index n = y.cols();
    d.resize(2 * n);
    J.setZero(2 * n, kParams);
    T.setZero();
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto [rho, c, sn, h] = InAxisFrame(frame, s.center, y.col(i));
      d[2 * i] = h;
      d[2 * i + 1] = rho - s.radius;
      J(2 * i, 2) = -1.0;
      J(2 * i, 3) = rho * c;
      J(2 * i, 4) = rho * sn;
      J.row(2 * i + 1) << -c, -sn, 0.0, -h * c, -h * sn, -1.0;
    }
  }

  static Circle3d Update(const Circle3d& s, const Eigen::VectorXd& delta) {
    const Eigen::Matrix3d frame = FrameWithAxis(s.normal);
    Circle3d out;
    out.center = s.center + frame * delta.head<3>();
    out.normal = (s.normal + delta[3] * frame.col(0) + delta[4] * frame.col(1)).normalized();
    out.radius = s.radius + delta[5];
    return out;
  }
};

// A torus: local parameters (u1, u2, w, a1, b1, R, r), the centre moved by u1 e1 + u2 e2 + w a, the axis
// turned about the centre to a + a1 e1 + b1 e2 (normalized), (e1, e2, a) = FrameWithAxis(a), the radii
// added. With (q1, q2, z) = F^T (y - c), rho = |(q1, q2)|, (cos t, sin t) = (q1, q2) / rho, e = rho - R and
// D = |(e, z)|, d = D - r and the meridian normal (n_rho, n_z) = (e, z) / D, the row is
// (-n_rho cos t, -n_rho sin t, -n_z, cos t (n_z rho - n_rho z), sin t (n_z rho - n_rho z), -n_rho, -1)
// (docs/metrology.md eq. 3). TDM only: the SDM terms of the torus are not derived here.
struct TorusLocal {
  using Shape = Torus;
  static constexpr int kParams = 7;
  static constexpr int kSizeParameter = 6;  // the minor radius
  static constexpr int kRowsPerPoint = 1;
  static constexpr bool kSupportsSdm = false;
  static std::vector<ParameterUncertainty> Uncertainties(const Eigen::Matrix<double, 7, 7>& cov, double scale,
                                                         const Eigen::Matrix3d& frame) {
    const Eigen::Matrix3d c = frame * cov.topLeftCorner<3, 3>() * frame.transpose();
    return {{"center_x", std::sqrt(c(0, 0)) * scale, false},
            {"center_y", std::sqrt(c(1, 1)) * scale, false},
            {"center_z", std::sqrt(c(2, 2)) * scale, false},
            {"axis_direction", std::sqrt(cov(3, 3) + cov(4, 4)), true},
            {"major_radius", std::sqrt(cov(5, 5)) * scale, false},
            {"minor_radius", std::sqrt(cov(6, 6)) * scale, false}};
  }
  static Eigen::Matrix3d FrameOf(const Torus& s) { return FrameWithAxis(s.axis); }
  static double Magnitude(const Torus& s) {
    return s.center.norm() + 1.0 + std::abs(s.major_radius) + std::abs(s.minor_radius);
  }

  template <class JacobianT, class TangentialT>
  static void Linearize(const Torus& s, const Eigen::Matrix3Xd& y, bool /*sdm*/, const double* /*weights*/,
                        Eigen::VectorXd& d, JacobianT& J, TangentialT& T) {
    const Eigen::Matrix3d frame = FrameWithAxis(s.axis);
    const Eigen::Index n = y.cols();
    d.resize(n);
    J.resize(n, kParams);
    T.setZero();
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto [rho, c, sn, z] = InAxisFrame(frame, s.center, y.col(i));
      const double e = rho - s.major_radius;
      const double D = std::hypot(e, z);
      const double n_rho = D > 0 ? e / D : 1.0, n_z = D > 0 ? z / D : 0.0;
      d[i] = D - s.minor_radius;
      const double tilt = n_z * rho - n_rho * z;
      J.row(i) << -n_rho * c, -n_rho * sn, -n_z, c * tilt, sn * tilt, -n_rho, -1.0;
    }
  }

  static Torus Update(const Torus& s, const Eigen::VectorXd& delta) {
    const Eigen::Matrix3d frame = FrameWithAxis(s.axis);
    Torus out;
    out.center = s.center + frame * delta.head<3>();
    out.axis = (s.axis + delta[3] * frame.col(0) + delta[4] * frame.col(1)).normalized();
    out.major_radius = s.major_radius + delta[5];
    out.minor_radius = s.minor_radius + delta[6];
    return out;
  }
};

// A circle's roundness model (ISO 12181): the circle in its fixed plane, local parameters (c1, c2, r), the
// centre moved by c1 e1 + c2 e2 within the plane, the radius r added; d = rho - r with rho the distance of
// the point's projection onto the plane from the centre (the height over the plane is not part of
// roundness), with the row (-cos t, -sin t, -1).
struct PlanarCircleLocal {
  using Shape = Circle3d;
  static constexpr int kParams = 3;
  static constexpr int kSizeParameter = 2;
  static constexpr int kRowsPerPoint = 1;
  static constexpr bool kSupportsSdm = false;
  static double Magnitude(const Circle3d& s) { return s.center.norm() + 1.0 + std::abs(s.radius); }

  template <class JacobianT, class TangentialT>
  static void Linearize(const Circle3d& s, const Eigen::Matrix3Xd& y, bool /*sdm*/, const double* /*weights*/,
                        Eigen::VectorXd& d, JacobianT& J, TangentialT& T) {
    const Eigen::Matrix3d frame = FrameWithAxis(s.normal);
    const Eigen::Index n = y.cols();
    d.resize(n);
    J.resize(n, kParams);
    T.setZero();
    for (Eigen::Index i = 0; i < n; ++i) {
      const auto [rho, c, sn, h] = InAxisFrame(frame, s.center, y.col(i));
      (void)h;
      d[i] = rho - s.radius;
      J.row(i) << -c, -sn, -1.0;
    }
  }

  static Circle3d Update(const Circle3d& s, const Eigen::VectorXd& delta) {
    const Eigen::Matrix3d frame = FrameWithAxis(s.normal);
    return {s.center + frame.leftCols<2>() * delta.head<2>(), s.normal, s.radius + delta[2]};
  }
};

// The residual vector of a model at a shape: the signed distances (one row per point), or for the curves
// the stacked 2-vectors across the curve (kRowsPerPoint = 2).
template <class Model>
Eigen::VectorXd Residuals(const typename Model::Shape& s, const Eigen::Matrix3Xd& y) {
  if constexpr (Model::kRowsPerPoint == 1) {
    return SignedDistances(s, y);
  } else {
    Eigen::VectorXd d;
    Eigen::Matrix<double, Eigen::Dynamic, Model::kParams> J;
    Eigen::Matrix<double, Model::kParams, Model::kParams> T;
    Model::Linearize(s, y, false, nullptr, d, J, T);
    return d;
  }
}

// Per point, the length of its residual rows: the (unsigned) distance of a curve's point, or the signed
// distance itself for surfaces.
template <class Model>
Eigen::VectorXd PointDistances(const Eigen::VectorXd& residuals) {
  if constexpr (Model::kRowsPerPoint == 1) {
    return residuals;
  } else {
    const Eigen::Index n = residuals.size() / Model::kRowsPerPoint;
    Eigen::VectorXd out(n);
    for (Eigen::Index i = 0; i < n; ++i)
      out[i] = residuals.segment<Model::kRowsPerPoint>(Model::kRowsPerPoint * i).norm();
    return out;
  }
}

}  // namespace s2m::primitive_local
