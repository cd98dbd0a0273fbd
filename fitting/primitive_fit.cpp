#include "fitting/primitive_fit.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/QR>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <string>

#include "fitting/covariance.h"
#include "fitting/parametric_model.h"

namespace s2m {
namespace {

using Clock = std::chrono::steady_clock;

// Data centred at the centroid and scaled uniformly into the unit box (METHOD.md section 3), so that
// tolerances and damping do not depend on the user's units or on where the part sits in the scanner's frame.
struct NormalizedData {
  Eigen::Vector3d offset;
  double scale = 1.0;
  Eigen::Matrix3Xd points;
};

NormalizedData Normalize(const Eigen::Matrix3Xd& points, Eigen::Index min_points, const char* what) {
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
AxisCoordinates InAxisFrame(const Eigen::Matrix3d& frame, const Eigen::Vector3d& point,
                            const Eigen::Vector3d& y) {
  const Eigen::Vector3d v = frame.transpose() * (y - point);
  const double rho = std::hypot(v[0], v[1]);
  return {rho, rho > 0 ? v[0] / rho : 1.0, rho > 0 ? v[1] / rho : 0.0, v[2]};
}

// Applies the axis increments (u1, u2, a1, b1) of the local parametrization: the axis point moves by (u1, u2,
// 0), the direction becomes (a1, b1, 1), both in the frame of the current axis.
void MoveAxis(const Eigen::Vector3d& point, const Eigen::Vector3d& direction, const Eigen::VectorXd& delta,
              Eigen::Vector3d& new_point, Eigen::Vector3d& new_direction) {
  const Eigen::Matrix3d frame = FrameWithAxis(direction);
  new_point = point + frame * Eigen::Vector3d(delta[0], delta[1], 0.0);
  new_direction = (frame * Eigen::Vector3d(delta[2], delta[3], 1.0)).normalized();
}

// ---- Models: closed-form foot points, TDM rows d(distance)/d(params) and SDM tangential rows
// ---------------------- For every model the TDM row equals -n^T C_P at the foot point (Liu & Wang, GMP 2008,
// section 3), and the SDM term adds beta_k (T_k^T C_P)^T (T_k^T C_P) with C_P the motion of the model point
// at a fixed surface parameter.

struct SphereLocal {
  using Shape = Sphere;
  static constexpr int kParams = 4;
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
  static void Linearize(const Sphere& s, const Eigen::Matrix3Xd& y, bool sdm, Eigen::VectorXd& d,
                        JacobianT& J, TangentialT& T) {
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
        const double beta = SdmWeight(d[i], kappa);
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
  static void Linearize(const Cylinder& s, const Eigen::Matrix3Xd& y, bool sdm, Eigen::VectorXd& d,
                        JacobianT& J, TangentialT& T) {
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
        const double beta = SdmWeight(d[i], kappa);
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
  static void Linearize(const Cone& s, const Eigen::Matrix3Xd& y, bool sdm, Eigen::VectorXd& d, JacobianT& J,
                        TangentialT& T) {
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
          const double beta = SdmWeight(d[i], -cpsi / rho_foot);
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

// ---- Levenberg-Marquardt over a model's local parametrization (METHOD.md section 9)
// ----------------------------

template <class Model>
PrimitiveFit<typename Model::Shape> Solve(const Eigen::Matrix3Xd& y, typename Model::Shape shape,
                                          const PrimitiveFitOptions& options, double scale) {
  constexpr int P = Model::kParams;
  using Vec = Eigen::Matrix<double, P, 1>;
  using Mat = Eigen::Matrix<double, P, P>;
  const SolverOptions& so = options.solver;
  const bool sdm = options.method == PrimitiveMethod::kSdm;
  const auto start = Clock::now();
  const double n = static_cast<double>(y.cols());

  PrimitiveFit<typename Model::Shape> fit;
  fit.stop_reason = StopReason::kMaxIterations;
  Eigen::VectorXd d = SignedDistances(shape, y);
  double f = 0.5 * d.squaredNorm();
  double lambda = so.initial_damping;
  Eigen::Matrix<double, Eigen::Dynamic, P> J;
  Mat T;
  bool stopped = false;

  while (!stopped && fit.iterations < so.max_iterations) {
    Model::Linearize(shape, y, sdm, d, J, T);
    const Vec g = J.transpose() * d;
    // First-order optimality, scale-free: the largest cosine between the residual and a Jacobian column.
    const double d_norm = d.norm();
    double max_cos = 0.0;
    for (int k = 0; k < P; ++k) {
      const double col = J.col(k).norm();
      if (col > 0 && d_norm > 0) max_cos = std::max(max_cos, std::abs(g[k]) / (col * d_norm));
    }
    if (d_norm == 0.0 || max_cos <= so.gradient_tolerance) {
      fit.stop_reason = StopReason::kGradientTolerance;
      break;
    }
    const Mat H = J.transpose() * J + T;
    const double diag_floor = 1e-12 * H.diagonal().maxCoeff();
    while (true) {
      Mat A = H;
      A.diagonal() += lambda * H.diagonal().cwiseMax(diag_floor);
      const Vec delta = A.ldlt().solve(-g);
      if (delta.allFinite() && delta.norm() <= so.step_tolerance * (1.0 + Model::Magnitude(shape))) {
        fit.stop_reason = StopReason::kStepTolerance;
        stopped = true;
        break;
      }
      if (delta.allFinite()) {
        const typename Model::Shape candidate = Model::Update(shape, delta);
        Eigen::VectorXd dc = SignedDistances(candidate, y);
        const double fc = 0.5 * dc.squaredNorm();
        if (fc < f) {
          const double relative_decrease = (f - fc) / f;
          shape = candidate;
          d = std::move(dc);
          f = fc;
          ++fit.iterations;
          if (so.record_history) {
            IterationRecord r;
            r.iteration = fit.iterations;
            r.rms = std::sqrt(2.0 * f / n) * scale;
            r.max_distance = d.cwiseAbs().maxCoeff() * scale;
            r.objective = f;
            r.damping = lambda;
            r.step_norm = delta.norm();
            r.seconds = std::chrono::duration<double>(Clock::now() - start).count();
            fit.history.push_back(r);
          }
          lambda = std::max(lambda * 0.1, 1e-15);
          if (relative_decrease <= so.objective_tolerance) {
            fit.stop_reason = StopReason::kObjectiveTolerance;
            stopped = true;
          }
          break;
        }
      }
      lambda *= 10.0;
      if (lambda > so.max_damping) {
        fit.stop_reason = StopReason::kNoFurtherDecrease;
        stopped = true;
        break;
      }
    }
  }
  fit.shape = shape;
  // Covariance of the local parameters at the solution (Gauss-Newton, normalized units); none when J^T J is
  // singular (a degenerate fit: its local parameters are not all determined).
  if (y.cols() > P) {
    Model::Linearize(shape, y, /*sdm=*/false, d, J, T);
    const Mat JtJ = J.transpose() * J;
    const CovarianceEstimate estimate =
        EstimateCovariance(JtJ, d.squaredNorm(), static_cast<double>(y.cols()));
    if (estimate.null_directions.empty())
      fit.uncertainties = Model::Uncertainties(Mat(estimate.covariance), scale);
  }
  return fit;
}

template <class Shape>
void Finish(PrimitiveFit<Shape>& fit, const NormalizedData& data, const Eigen::Matrix3Xd& points) {
  fit.shape = Transformed(fit.shape, data.scale, data.offset);
  if constexpr (requires(Shape s) { MoveAxisPointNear(s, data.offset); })
    MoveAxisPointNear(fit.shape, data.offset);
  fit.residuals = ComputeResidualStatistics(SignedDistances(fit.shape, points));
}

// ---- Initial guesses
// ------------------------------------------------------------------------------------------

Eigen::Matrix3Xd Subsample(const Eigen::Matrix3Xd& y, int max_points) {
  if (y.cols() <= max_points) return y;
  Eigen::Matrix3Xd out(3, max_points);
  const double stride = static_cast<double>(y.cols()) / max_points;
  for (int i = 0; i < max_points; ++i) out.col(i) = y.col(static_cast<Eigen::Index>(i * stride));
  return out;
}

// Candidate axis directions: a Fibonacci lattice on the upper hemisphere plus the principal axes of the data.
std::vector<Eigen::Vector3d> CandidateDirections(const Eigen::Matrix3Xd& y, int samples) {
  std::vector<Eigen::Vector3d> dirs;
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < samples; ++i) {
    const double z = 1.0 - (i + 0.5) / samples;
    const double r = std::sqrt(1.0 - z * z);
    dirs.emplace_back(r * std::cos(golden * i), r * std::sin(golden * i), z);
  }
  const Eigen::Matrix3d cov = y * y.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  for (int k = 0; k < 3; ++k) dirs.push_back(eig.eigenvectors().col(k));
  return dirs;
}

// Algebraic circle fit (Kasa) of 2D points: |q|^2 = 2 c.q + k. Returns false when the points are collinear.
bool AlgebraicCircle(const Eigen::Matrix2Xd& q, Eigen::Vector2d& center, double& radius) {
  Eigen::MatrixXd A(q.cols(), 3);
  A.leftCols<2>() = 2.0 * q.transpose();
  A.col(2).setOnes();
  const Eigen::VectorXd b = q.colwise().squaredNorm().transpose();
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(A);
  if (qr.rank() < 3) return false;
  const Eigen::Vector3d x = qr.solve(b);
  center = x.head<2>();
  const double r2 = x[2] + center.squaredNorm();
  if (!(r2 > 0)) return false;
  radius = std::sqrt(r2);
  return true;
}

std::optional<Cylinder> CylinderForDirection(const Eigen::Matrix3Xd& y, const Eigen::Vector3d& dir) {
  const Eigen::Matrix3d frame = FrameWithAxis(dir);
  const Eigen::Matrix2Xd q = frame.leftCols<2>().transpose() * y;
  Eigen::Vector2d c;
  double r;
  if (!AlgebraicCircle(q, c, r)) return std::nullopt;
  Cylinder cyl{frame.leftCols<2>() * c, dir, r};
  return cyl;
}

// Algebraic cone fit for a given axis direction (derived): with q the coordinates across the axis and z along
// it, |q - c|^2 = (r0 + k z)^2 is linear in (c, r0^2 - |c|^2, 2 r0 k, k^2) when the coupling k^2 = (2 r0
// k)^2/(4 r0^2) is dropped; k = tan(half angle).
std::optional<Cone> ConeForDirection(const Eigen::Matrix3Xd& y, const Eigen::Vector3d& dir) {
  const Eigen::Matrix3d frame = FrameWithAxis(dir);
  const Eigen::Matrix2Xd q = frame.leftCols<2>().transpose() * y;
  const Eigen::VectorXd z = (dir.transpose() * y).transpose();
  Eigen::MatrixXd A(y.cols(), 5);
  A.leftCols<2>() = 2.0 * q.transpose();
  A.col(2).setOnes();
  A.col(3) = z;
  A.col(4) = z.cwiseProduct(z);
  const Eigen::VectorXd b = q.colwise().squaredNorm().transpose();
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(A);
  if (qr.rank() < 5) return std::nullopt;
  const Eigen::VectorXd x = qr.solve(b);
  const Eigen::Vector2d c = x.head<2>();
  const double r2 = x[2] + c.squaredNorm();
  if (!(r2 > 0)) return std::nullopt;
  const double r0 = std::sqrt(r2);
  double k = x[3] / (2.0 * r0);
  Cone cone{frame.leftCols<2>() * c, dir, std::atan(std::abs(k)), r0};
  if (k < 0) cone.axis_direction = -dir;
  if (!(cone.half_angle > 1e-9) || cone.half_angle > 1.5) return std::nullopt;
  return cone;
}

// Scores every candidate direction, then refines the best few mutually distinct ones and keeps the lowest
// objective.
template <class Model, class Guess>
PrimitiveFit<typename Model::Shape> FitWithDirectionSearch(const NormalizedData& data,
                                                           const PrimitiveFitOptions& options, Guess guess,
                                                           const char* what) {
  using Shape = typename Model::Shape;
  const Eigen::Matrix3Xd sample = Subsample(data.points, options.max_initialization_points);
  struct Scored {
    double score;
    Shape shape;
  };
  std::vector<Scored> scored;
  for (const Eigen::Vector3d& dir : CandidateDirections(sample, options.direction_samples)) {
    if (auto shape = guess(sample, dir)) {
      const double score = SignedDistances(*shape, sample).squaredNorm();
      if (std::isfinite(score)) scored.push_back({score, *shape});
    }
  }
  if (scored.empty())
    throw FitError(std::string("cannot fit a ") + what +
                   ": no axis direction gives a usable initial guess (degenerate data?)");
  std::sort(scored.begin(), scored.end(), [](const Scored& a, const Scored& b) { return a.score < b.score; });

  const double min_separation_cos = std::cos(10.0 * M_PI / 180.0);
  std::vector<Shape> starts;
  for (const Scored& s : scored) {
    const bool distinct = std::all_of(starts.begin(), starts.end(), [&](const Shape& other) {
      return std::abs(other.axis_direction.dot(s.shape.axis_direction)) < min_separation_cos;
    });
    if (distinct) starts.push_back(s.shape);
    if (static_cast<int>(starts.size()) >= std::max(1, options.refined_candidates)) break;
  }

  // Starts are in order of their algebraic score. A later start replaces the current best only when it is
  // clearly lower: with as many points as parameters several surfaces interpolate the data exactly (objective
  // at rounding level), and the one reached from the best algebraic guess is the one closest to the data's
  // overall shape.
  const double rounding_floor = 1e-24 * static_cast<double>(data.points.cols());
  std::optional<PrimitiveFit<Shape>> best;
  double best_objective = std::numeric_limits<double>::infinity();
  for (const Shape& start : starts) {
    PrimitiveFit<Shape> fit = Solve<Model>(data.points, start, options, data.scale);
    const double objective = SignedDistances(fit.shape, data.points).squaredNorm();
    if (objective < best_objective * (1.0 - 1e-9) - rounding_floor) {
      best_objective = objective;
      best = std::move(fit);
    }
  }
  return *best;
}

Sphere AlgebraicSphere(const Eigen::Matrix3Xd& y) {
  Eigen::MatrixXd A(y.cols(), 4);
  A.leftCols<3>() = 2.0 * y.transpose();
  A.col(3).setOnes();
  const Eigen::VectorXd b = y.colwise().squaredNorm().transpose();
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(A);
  if (qr.rank() < 4)
    throw FitError("cannot fit a sphere: the points are coplanar (a sphere is not determined)");
  const Eigen::Vector4d x = qr.solve(b);
  const double r2 = x[3] + x.head<3>().squaredNorm();
  if (!(r2 > 0)) throw FitError("cannot fit a sphere: the algebraic initial guess has no real radius");
  return {x.head<3>(), std::sqrt(r2)};
}

}  // namespace

const char* ToString(PrimitiveMethod method) {
  return method == PrimitiveMethod::kSdm ? "sdm" : "tdm";
}

PrimitiveFit<Plane> FitPlane(const Eigen::Matrix3Xd& points, const PrimitiveFitOptions&) {
  const NormalizedData data = Normalize(points, 3, "plane");
  // The least-squares plane passes through the centroid; its normal is the direction of least variance
  // (the minimizer of sum (n.(x - c))^2 over unit n), so no iteration is needed.
  const Eigen::Matrix3d scatter = data.points * data.points.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
  const Eigen::Vector3d values = eig.eigenvalues();
  // Second singular value below 1e-6 of the first: the points lie on a line (to rounding), the normal is
  // arbitrary.
  if (!(values[1] > 1e-12 * values[2])) throw FitError("cannot fit a plane: the points are collinear");
  Eigen::Vector3d normal = eig.eigenvectors().col(0);
  Eigen::Index k;
  normal.cwiseAbs().maxCoeff(&k);
  if (normal[k] < 0) normal = -normal;  // deterministic sign: largest component positive
  PrimitiveFit<Plane> fit;
  fit.shape = {Eigen::Vector3d::Zero(), normal};
  fit.stop_reason = StopReason::kClosedForm;
  const Eigen::Index n = data.points.cols();
  if (n > 3) {
    // Local parameters (offset along n, tilts towards e1 and e2): d ~ d0 - w - t1 (e1.y) - t2 (e2.y).
    Eigen::MatrixXd J(n, 3);
    J.col(0).setConstant(-1.0);
    J.col(1) = -(eig.eigenvectors().col(2).transpose() * data.points).transpose();
    J.col(2) = -(eig.eigenvectors().col(1).transpose() * data.points).transpose();
    // values[0] = sum of the squared distances to the plane.
    const Eigen::Matrix3d cov =
        EstimateCovariance(J.transpose() * J, values[0], static_cast<double>(n)).covariance;
    fit.uncertainties = {{"offset", std::sqrt(cov(0, 0)) * data.scale, false},
                         {"normal_direction", std::sqrt(cov(1, 1) + cov(2, 2)), true}};
  }
  Finish(fit, data, points);
  return fit;
}

PrimitiveFit<Sphere> RefineSphere(const Eigen::Matrix3Xd& points, const Sphere& initial,
                                  const PrimitiveFitOptions& options) {
  const NormalizedData data = Normalize(points, 4, "sphere");
  const Sphere start{(initial.center - data.offset) / data.scale, initial.radius / data.scale};
  PrimitiveFit<Sphere> fit = Solve<SphereLocal>(data.points, start, options, data.scale);
  Finish(fit, data, points);
  return fit;
}

PrimitiveFit<Sphere> FitSphere(const Eigen::Matrix3Xd& points, const PrimitiveFitOptions& options) {
  const NormalizedData data = Normalize(points, 4, "sphere");
  PrimitiveFit<Sphere> fit =
      Solve<SphereLocal>(data.points, AlgebraicSphere(data.points), options, data.scale);
  Finish(fit, data, points);
  return fit;
}

PrimitiveFit<Cylinder> RefineCylinder(const Eigen::Matrix3Xd& points, const Cylinder& initial,
                                      const PrimitiveFitOptions& options) {
  const NormalizedData data = Normalize(points, 5, "cylinder");
  Cylinder start{(initial.axis_point - data.offset) / data.scale, initial.axis_direction.normalized(),
                 initial.radius / data.scale};
  PrimitiveFit<Cylinder> fit = Solve<CylinderLocal>(data.points, start, options, data.scale);
  Finish(fit, data, points);
  return fit;
}

PrimitiveFit<Cylinder> FitCylinder(const Eigen::Matrix3Xd& points, const PrimitiveFitOptions& options) {
  const NormalizedData data = Normalize(points, 5, "cylinder");
  PrimitiveFit<Cylinder> fit =
      FitWithDirectionSearch<CylinderLocal>(data, options, CylinderForDirection, "cylinder");
  Finish(fit, data, points);
  return fit;
}

PrimitiveFit<Cone> RefineCone(const Eigen::Matrix3Xd& points, const Cone& initial,
                              const PrimitiveFitOptions& options) {
  const NormalizedData data = Normalize(points, 6, "cone");
  Cone start{(initial.axis_point - data.offset) / data.scale, initial.axis_direction.normalized(),
             initial.half_angle, initial.radius / data.scale};
  PrimitiveFit<Cone> fit = Solve<ConeLocal>(data.points, start, options, data.scale);
  Finish(fit, data, points);
  return fit;
}

PrimitiveFit<Cone> FitCone(const Eigen::Matrix3Xd& points, const PrimitiveFitOptions& options) {
  const NormalizedData data = Normalize(points, 6, "cone");
  PrimitiveFit<Cone> fit = FitWithDirectionSearch<ConeLocal>(data, options, ConeForDirection, "cone");
  Finish(fit, data, points);
  return fit;
}

namespace {
template <class Model>
Eigen::MatrixXd JacobianOf(const typename Model::Shape& s, const Eigen::Matrix3Xd& points) {
  Eigen::VectorXd d;
  Eigen::Matrix<double, Eigen::Dynamic, Model::kParams> J;
  Eigen::Matrix<double, Model::kParams, Model::kParams> T;
  Model::Linearize(s, points, false, d, J, T);
  return J;
}
}  // namespace

Eigen::MatrixXd DistanceJacobian(const Sphere& s, const Eigen::Matrix3Xd& p) {
  return JacobianOf<SphereLocal>(s, p);
}
Eigen::MatrixXd DistanceJacobian(const Cylinder& s, const Eigen::Matrix3Xd& p) {
  return JacobianOf<CylinderLocal>(s, p);
}
Eigen::MatrixXd DistanceJacobian(const Cone& s, const Eigen::Matrix3Xd& p) {
  return JacobianOf<ConeLocal>(s, p);
}
Sphere ApplyIncrement(const Sphere& s, const Eigen::VectorXd& delta) {
  return SphereLocal::Update(s, delta);
}
Cylinder ApplyIncrement(const Cylinder& s, const Eigen::VectorXd& delta) {
  return CylinderLocal::Update(s, delta);
}
Cone ApplyIncrement(const Cone& s, const Eigen::VectorXd& delta) {
  return ConeLocal::Update(s, delta);
}

}  // namespace s2m
