#include "fitting/primitive_fit.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/QR>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <string>

#include "fitting/covariance.h"
#include "fitting/minimizer.h"
#include "fitting/parametric_model.h"
#include "fitting/robust_loss.h"

namespace s2m {
namespace {

using Clock = std::chrono::steady_clock;

// Data centred at the centroid and scaled uniformly into the unit box (docs/method.md section 3), so that
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

// An SDM weight scaled by a point's robust IRLS weight (no weights: plain least squares, unchanged).
double Weighted(const double* weights, Eigen::Index i, double beta) {
  return weights ? weights[i] * beta : beta;
}

// The plane is fitted in closed form (FitPlane); this local model serves its robust refinement. Local
// parameters (w, t1, t2): the point moves by w n, the normal becomes n + t1 e1 + t2 e2 (normalized) with
// (e1, e2, n) = FrameWithAxis(n); so d = n.(y - p) has the rows (-1, e1.(y - p), e2.(y - p)). A plane has
// no curvature: SDM adds no tangential terms.
struct PlaneLocal {
  using Shape = Plane;
  static constexpr int kParams = 3;
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

// ---- The fit as the minimizer's problem (minimizer.h; docs/method.md section 9)
// -----------------------------------------------------------------------------------------------------------

// Cov = s_w^2 (J^T W J)^-1 with s_w^2 = sum w d^2 / (sum w - p) at the solution (normalized units); without
// weights s^2 (J^T J)^-1 with s^2 = sum d^2 / (n - p), the Gauss-Newton covariance (GUM type A). The
// weighted normal matrix with the effective degrees of freedom sum w - p is the robust fits' estimate (the
// first-order form of the M-estimator's covariance; Huber, "Robust Statistics", 1981, section 7.6). nullopt
// when the normal matrix is singular or there are no degrees of freedom left.
template <int P>
std::optional<Eigen::Matrix<double, P, P>> LocalCovariance(const Eigen::Matrix<double, Eigen::Dynamic, P>& J,
                                                           const Eigen::VectorXd& d,
                                                           const Eigen::VectorXd& weights) {
  using Mat = Eigen::Matrix<double, P, P>;
  const bool weighted = weights.size() > 0;
  const double effective_count = weighted ? weights.sum() : static_cast<double>(d.size());
  const Mat normal = weighted ? Mat(J.transpose() * weights.asDiagonal() * J) : Mat(J.transpose() * J);
  const double weighted_squares = weighted ? weights.dot(d.cwiseAbs2()) : d.squaredNorm();
  // The one covariance routine (fitting/covariance.h): s_w^2 N^+ with the effective degrees of freedom.
  const CovarianceEstimate estimate = EstimateCovariance(normal, weighted_squares, effective_count);
  if (estimate.covariance.size() == 0 || !estimate.null_directions.empty()) return std::nullopt;
  return Mat(estimate.covariance);
}

// The normal equations H = J^T W J + T, g = J^T W d of one linearization, P x P. The damped step is solved
// by a fixed-size LDLT (stack storage, unrolled: the systems have 3 to 6 unknowns) with the damping of
// AddDamping (linear_solver.h). Its optimality measure is the largest cosine between the (weighted)
// residual vector and a Jacobian column, |g_k| / (|W^1/2 J_k| |W^1/2 d|): the SDM terms T are not part of a
// column's length.
template <int P>
class PrimitiveNormalEquations : public DenseNormalEquations {
 public:
  using Vec = Eigen::Matrix<double, P, 1>;
  using Mat = Eigen::Matrix<double, P, P>;
  explicit PrimitiveNormalEquations(double diagonal_floor) : floor_(diagonal_floor) {}
  void Set(const Mat& h, const Vec& g, const Vec& column_squared_norms, double residual_norm) {
    h_ = h;
    g_ = g;
    H() = h;
    this->g() = g;
    column_squared_norms_ = column_squared_norms;
    residual_norm_ = residual_norm;
  }
  bool Solve(double lambda, Eigen::VectorXd& step) override {
    Mat a = h_;
    const double floor = floor_ * h_.diagonal().maxCoeff();
    a.diagonal() += lambda * h_.diagonal().cwiseMax(floor);
    const Vec x = a.ldlt().solve(-g_);
    step = x;
    return step.allFinite();
  }
  double GradientMeasure(double /*cost*/) const override {
    if (!(residual_norm_ > 0.0)) return 0.0;
    double largest = 0.0;
    for (int k = 0; k < P; ++k) {
      const double column = std::sqrt(column_squared_norms_[k]);
      if (column > 0) largest = std::max(largest, std::abs(g_[k]) / (column * residual_norm_));
    }
    return largest;
  }

 private:
  Mat h_;
  Vec g_, column_squared_norms_;
  double residual_norm_ = 0.0;
  double floor_;
};

// The state is the shape (normalized units) and its signed distances; a linearization is the TDM or SDM
// normal equations at the frozen closed-form foot points, weighted by the robust loss (scale re-estimated
// from the current distances first); a trial applies the local increment and recomputes the distances.
template <class Model>
class PrimitiveFitProblem : public NonlinearProblem {
 public:
  using Shape = typename Model::Shape;
  static constexpr int P = Model::kParams;

  PrimitiveFitProblem(const Eigen::Matrix3Xd& y, const Shape& start, const PrimitiveFitOptions& options,
                      double unit)
      : y_(y),
        shape_(start),
        sdm_(options.error_term == ErrorTerm::kSdm),
        unit_(unit),
        weighting_(options.optimizer.loss),
        normal_(options.optimizer.damping.diagonal_floor) {
    weighting_.set_units(unit_);
    d_ = SignedDistances(shape_, y_);
    UpdateWeights();
    cost_ = Objective(d_);
  }

  double Cost() const override { return cost_; }

  LinearSystem& Linearize() override {
    if (weighting_.is_robust()) {  // the scale follows the current residuals (robust_loss.h)
      UpdateWeights();
      cost_ = Objective(d_);
    }
    const double* weights = weighting_.is_robust() ? weights_.data() : nullptr;
    Model::Linearize(shape_, y_, sdm_, weights, linear_d_, J_, T_);
    if (weights) {
      const Eigen::Matrix<double, Eigen::Dynamic, P> WJ = weights_.asDiagonal() * J_;
      const Mat JtWJ = J_.transpose() * WJ;
      normal_.Set(JtWJ + T_, WJ.transpose() * linear_d_, JtWJ.diagonal(),
                  std::sqrt(weights_.dot(linear_d_.cwiseAbs2())));
    } else {
      normal_.Set(J_.transpose() * J_ + T_, J_.transpose() * linear_d_,
                  J_.colwise().squaredNorm().transpose(), linear_d_.norm());
    }
    return normal_;
  }

  double EvaluateTrial(const Eigen::VectorXd& step, bool /*final_if_accepted*/) override {
    trial_shape_ = Model::Update(shape_, step);
    trial_d_ = SignedDistances(trial_shape_, y_);
    trial_cost_ = Objective(trial_d_);
    return std::isfinite(trial_cost_) ? trial_cost_ : std::numeric_limits<double>::infinity();
  }

  void AcceptTrial() override {
    shape_ = trial_shape_;
    d_.swap(trial_d_);
    cost_ = trial_cost_;
  }

  double ParameterNorm() const override { return Model::Magnitude(shape_); }

  void DescribeState(IterationRecord& record) const override {
    record.rms = std::sqrt(d_.squaredNorm() / static_cast<double>(y_.cols())) * unit_;
    record.max_distance = d_.cwiseAbs().maxCoeff() * unit_;
  }

  // Fills the fit's shape, covariance-based uncertainties (the plain TDM Jacobian at the solution) and the
  // robust loss's final scale and rejections.
  void Describe(PrimitiveFit<Shape>& fit) {
    fit.shape = shape_;
    Eigen::VectorXd weights;
    if (weighting_.is_robust()) {
      UpdateWeights();
      weights = weights_;
      fit.loss_scale = weighting_.scale();
      fit.rejected = (weights_.array() < 0.5).count();
    }
    if (y_.cols() > P) {
      Model::Linearize(shape_, y_, /*sdm=*/false, nullptr, linear_d_, J_, T_);
      if (const auto cov = LocalCovariance<P>(J_, linear_d_, weights))
        fit.uncertainties = Model::Uncertainties(*cov, unit_);
    }
  }

 private:
  using Vec = Eigen::Matrix<double, P, 1>;
  using Mat = Eigen::Matrix<double, P, P>;

  // 1/2 sum rho(d_j^2) (robust_loss.h); 1/2 sum d_j^2 for plain least squares.
  double Objective(const Eigen::VectorXd& d) const {
    if (!weighting_.is_robust()) return 0.5 * d.squaredNorm();
    double f = 0.0;
    for (Eigen::Index j = 0; j < d.size(); ++j) f += 0.5 * weighting_.Rho(d[j]);
    return f;
  }

  void UpdateWeights() {
    if (!weighting_.is_robust()) return;
    weighting_.Update(d_);
    weights_ = weighting_.Weights(d_);
  }

  const Eigen::Matrix3Xd& y_;
  Shape shape_, trial_shape_;
  bool sdm_;
  double unit_;
  RobustWeighting weighting_;
  Eigen::VectorXd weights_;  // IRLS weights rho'(d^2) at the last linearization (robust fits only)
  PrimitiveNormalEquations<P> normal_;
  Eigen::VectorXd d_, trial_d_, linear_d_;
  Eigen::Matrix<double, Eigen::Dynamic, P> J_;
  Mat T_;
  double cost_ = 0.0, trial_cost_ = 0.0;
};

template <class Model>
PrimitiveFit<typename Model::Shape> Solve(const Eigen::Matrix3Xd& y, const typename Model::Shape& start,
                                          const PrimitiveFitOptions& options, double scale) {
  PrimitiveFitProblem<Model> problem(y, start, options, scale);
  MinimizerSummary summary = TrustRegionMinimizer(options.optimizer).Minimize(problem);
  PrimitiveFit<typename Model::Shape> fit;
  fit.iterations = summary.iterations;
  fit.stop_reason = summary.stop_reason;
  if (options.record_history) fit.history = std::move(summary.history);
  problem.Describe(fit);
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
  std::vector<Eigen::Vector3d> dirs = FibonacciHemisphere(samples);
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

// Scores every candidate direction and returns the best few mutually distinct algebraic guesses, best first.
template <class Shape, class Guess>
std::vector<Shape> DirectionSearchStarts(const Eigen::Matrix3Xd& points, const PrimitiveFitOptions& options,
                                         Guess guess, const char* what) {
  const Eigen::Matrix3Xd sample = Subsample(points, options.max_initialization_points);
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
  return starts;
}

// 1/2 sum rho(d^2) at loss scale `scale` (input units; the data are in units of `unit`).
template <class Shape>
double RobustObjective(const Shape& shape, const Eigen::Matrix3Xd& y, const RobustLoss& loss, double scale,
                       double unit) {
  RobustLoss fixed = loss;
  fixed.scale = scale;
  RobustWeighting weighting(fixed);
  weighting.set_units(unit);
  const Eigen::VectorXd d = SignedDistances(shape, y);
  double f = 0.0;
  for (Eigen::Index j = 0; j < d.size(); ++j) f += 0.5 * weighting.Rho(d[j]);
  return f;
}

// Refines every start and keeps the lowest objective. Starts are in order of preference. A later start
// replaces the current best only when it is clearly lower: with as many points as parameters several surfaces
// interpolate the data exactly (objective at rounding level), and the one reached from the best algebraic
// guess is the one closest to the data's overall shape. Robust objectives are compared at one scale, the
// smallest of the fits' final scales: a fit that is off has a wider MAD scale, and a wider scale alone lowers
// a bounded loss's objective (Tukey's rho saturates at c^2 / 3).
template <class Model>
PrimitiveFit<typename Model::Shape> RefineBest(const Eigen::Matrix3Xd& y,
                                               const std::vector<typename Model::Shape>& starts,
                                               const PrimitiveFitOptions& options, double unit) {
  using Shape = typename Model::Shape;
  std::vector<PrimitiveFit<Shape>> fits;
  fits.reserve(starts.size());
  for (const Shape& start : starts) fits.push_back(Solve<Model>(y, start, options, unit));
  const RobustLoss& loss = options.optimizer.loss;
  double common_scale = std::numeric_limits<double>::infinity();
  for (const PrimitiveFit<Shape>& fit : fits) common_scale = std::min(common_scale, fit.loss_scale);
  const double rounding_floor = 1e-24 * static_cast<double>(y.cols());
  std::size_t best = 0;
  double best_objective = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < fits.size(); ++k) {
    const double objective = loss.is_robust() ? RobustObjective(fits[k].shape, y, loss, common_scale, unit)
                                              : SignedDistances(fits[k].shape, y).squaredNorm();
    if (objective < best_objective * (1.0 - 1e-9) - rounding_floor) {
      best_objective = objective;
      best = k;
    }
  }
  return std::move(fits[best]);
}

// The points of y nearest `shape`: the given fraction of them (at least `min_points`), in their order.
template <class Shape>
Eigen::Matrix3Xd NearestPoints(const Eigen::Matrix3Xd& y, const Shape& shape, double fraction,
                               Eigen::Index min_points) {
  const Eigen::VectorXd distance = SignedDistances(shape, y).cwiseAbs();
  const Eigen::Index keep = std::min(
      y.cols(), std::max(min_points, static_cast<Eigen::Index>(fraction * static_cast<double>(y.cols()))));
  std::vector<Eigen::Index> order(static_cast<std::size_t>(y.cols()));
  std::iota(order.begin(), order.end(), Eigen::Index{0});
  std::nth_element(order.begin(), order.begin() + (keep - 1), order.end(),
                   [&](Eigen::Index a, Eigen::Index b) { return distance[a] < distance[b]; });
  order.resize(static_cast<std::size_t>(keep));
  std::sort(order.begin(), order.end());
  Eigen::Matrix3Xd out(3, keep);
  for (Eigen::Index i = 0; i < keep; ++i) out.col(i) = y.col(order[static_cast<std::size_t>(i)]);
  return out;
}

// A fit from the usual (algebraic, least-squares) starts; a robust fit also refines from a start found on a
// trimmed set: the least-squares fit of the half of the points nearest the plain least-squares fit, refined
// by concentration steps, which the gross outliers (uniform in space, mostly far from any surface near the
// data) do not reach (primitive_fit.h). `starts_for(points)` gives the usual starts of a point set.
template <class Model, class StartsFor>
PrimitiveFit<typename Model::Shape> FitFromStarts(const Eigen::Matrix3Xd& y,
                                                  const PrimitiveFitOptions& options, double unit,
                                                  StartsFor starts_for) {
  using Shape = typename Model::Shape;
  std::vector<Shape> starts = starts_for(y);
  if (!options.optimizer.loss.is_robust()) return RefineBest<Model>(y, starts, options, unit);
  PrimitiveFitOptions plain = options;
  plain.optimizer.loss = RobustLoss{};
  plain.record_history = false;
  Shape trimmed_start = RefineBest<Model>(y, starts, plain, unit).shape;
  try {
    // Concentration steps of least trimmed squares (Rousseeuw & Van Driessen, "Computing LTS regression for
    // large data sets", 2006, section 2): refit the half of the points nearest the current fit; each step
    // lowers the trimmed sum of squares. The first searches starts afresh on the trimmed half.
    for (int round = 0; round < 3; ++round) {
      const Eigen::Matrix3Xd trimmed = NearestPoints(y, trimmed_start, 0.5, 2 * Model::kParams);
      const std::vector<Shape> trimmed_starts =
          round == 0 ? starts_for(trimmed) : std::vector<Shape>{trimmed_start};
      trimmed_start = RefineBest<Model>(trimmed, trimmed_starts, plain, unit).shape;
    }
    starts.push_back(trimmed_start);
  } catch (const FitError&) {
    // The trimmed half is degenerate (e.g. collinear): the usual starts remain.
  }
  return RefineBest<Model>(y, starts, options, unit);
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

namespace {

// Primitives take the two error terms their closed-form feet support; invalid optimizer options are reported
// before any work (OptimizerOptions::IsValid).
void CheckOptions(const PrimitiveFitOptions& options) {
  if (options.error_term != ErrorTerm::kTdm && options.error_term != ErrorTerm::kSdm) {
    throw std::invalid_argument(std::string("primitive fits accept the error terms ") +
                                ToString(ErrorTerm::kTdm) + " and " + ToString(ErrorTerm::kSdm) + ", not " +
                                ToString(options.error_term));
  }
  std::string why;
  if (!options.optimizer.IsValid(&why)) throw std::invalid_argument("invalid optimizer options: " + why);
}

// The least-squares plane passes through the centroid; its normal is the direction of least variance (the
// minimizer of sum (n.(x - c))^2 over unit n), so no iteration is needed. Points in normalized units.
PrimitiveFit<Plane> ClosedFormPlane(const Eigen::Matrix3Xd& y) {
  const Eigen::Vector3d centroid = y.rowwise().mean();
  const Eigen::Matrix3Xd centred = y.colwise() - centroid;
  const Eigen::Matrix3d scatter = centred * centred.transpose();
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
  fit.shape = {centroid, normal};
  fit.stop_reason = StopReason::kClosedForm;
  const Eigen::Index n = y.cols();
  if (n > 3) {
    // Local parameters (offset along n, tilts towards e1 and e2): d ~ d0 - w - t1 (e1.y) - t2 (e2.y).
    Eigen::MatrixXd J(n, 3);
    J.col(0).setConstant(-1.0);
    J.col(1) = -(eig.eigenvectors().col(2).transpose() * centred).transpose();
    J.col(2) = -(eig.eigenvectors().col(1).transpose() * centred).transpose();
    // values[0] = sum of the squared distances to the plane.
    const Eigen::Matrix3d cov =
        EstimateCovariance(J.transpose() * J, values[0], static_cast<double>(n)).covariance;
    fit.uncertainties = {{"offset", std::sqrt(cov(0, 0)), false},
                         {"normal_direction", std::sqrt(cov(1, 1) + cov(2, 2)), true}};
  }
  return fit;
}

}  // namespace

PrimitiveFit<Plane> FitPlane(const Eigen::Matrix3Xd& points, const PrimitiveFitOptions& options) {
  CheckOptions(options);
  const NormalizedData data = Normalize(points, 3, "plane");
  PrimitiveFit<Plane> fit;
  if (options.optimizer.loss.is_robust()) {
    // A robust plane iterates (PlaneLocal) from the closed-form plane and from the trimmed set's.
    fit = FitFromStarts<PlaneLocal>(data.points, options, data.scale, [](const Eigen::Matrix3Xd& y) {
      return std::vector<Plane>{ClosedFormPlane(y).shape};
    });
  } else {
    fit = ClosedFormPlane(data.points);
    for (ParameterUncertainty& u : fit.uncertainties)
      if (!u.is_angle) u.standard_uncertainty *= data.scale;
  }
  Finish(fit, data, points);
  return fit;
}

// A refinement from the caller's start (given in input units; `to_unit_box` maps it into the unit box of the
// data) or a fit from automatic starts (`starts` in the unit box), then back to input units.
template <class Local, class ToUnitBox>
PrimitiveFit<typename Local::Shape> RefineInUnitBox(const Eigen::Matrix3Xd& points,
                                                    const PrimitiveFitOptions& options, int min_points,
                                                    const char* what, const ToUnitBox& to_unit_box) {
  CheckOptions(options);
  const NormalizedData data = Normalize(points, min_points, what);
  PrimitiveFit<typename Local::Shape> fit = Solve<Local>(data.points, to_unit_box(data), options, data.scale);
  Finish(fit, data, points);
  return fit;
}

template <class Local, class Starts>
PrimitiveFit<typename Local::Shape> FitInUnitBox(const Eigen::Matrix3Xd& points,
                                                 const PrimitiveFitOptions& options, int min_points,
                                                 const char* what, const Starts& starts) {
  CheckOptions(options);
  const NormalizedData data = Normalize(points, min_points, what);
  PrimitiveFit<typename Local::Shape> fit = FitFromStarts<Local>(data.points, options, data.scale, starts);
  Finish(fit, data, points);
  return fit;
}

PrimitiveFit<Sphere> RefineSphere(const Eigen::Matrix3Xd& points, const Sphere& initial,
                                  const PrimitiveFitOptions& options) {
  return RefineInUnitBox<SphereLocal>(points, options, 4, "sphere", [&](const NormalizedData& data) {
    return Sphere{(initial.center - data.offset) / data.scale, initial.radius / data.scale};
  });
}

PrimitiveFit<Sphere> FitSphere(const Eigen::Matrix3Xd& points, const PrimitiveFitOptions& options) {
  return FitInUnitBox<SphereLocal>(points, options, 4, "sphere", [](const Eigen::Matrix3Xd& y) {
    return std::vector<Sphere>{AlgebraicSphere(y)};
  });
}

PrimitiveFit<Cylinder> RefineCylinder(const Eigen::Matrix3Xd& points, const Cylinder& initial,
                                      const PrimitiveFitOptions& options) {
  return RefineInUnitBox<CylinderLocal>(points, options, 5, "cylinder", [&](const NormalizedData& data) {
    return Cylinder{(initial.axis_point - data.offset) / data.scale, initial.axis_direction.normalized(),
                    initial.radius / data.scale};
  });
}

PrimitiveFit<Cylinder> FitCylinder(const Eigen::Matrix3Xd& points, const PrimitiveFitOptions& options) {
  return FitInUnitBox<CylinderLocal>(points, options, 5, "cylinder", [&](const Eigen::Matrix3Xd& y) {
    return DirectionSearchStarts<Cylinder>(y, options, CylinderForDirection, "cylinder");
  });
}

PrimitiveFit<Cone> RefineCone(const Eigen::Matrix3Xd& points, const Cone& initial,
                              const PrimitiveFitOptions& options) {
  return RefineInUnitBox<ConeLocal>(points, options, 6, "cone", [&](const NormalizedData& data) {
    return Cone{(initial.axis_point - data.offset) / data.scale, initial.axis_direction.normalized(),
                initial.half_angle, initial.radius / data.scale};
  });
}

PrimitiveFit<Cone> FitCone(const Eigen::Matrix3Xd& points, const PrimitiveFitOptions& options) {
  return FitInUnitBox<ConeLocal>(points, options, 6, "cone", [&](const Eigen::Matrix3Xd& y) {
    return DirectionSearchStarts<Cone>(y, options, ConeForDirection, "cone");
  });
}

namespace {
template <class Model>
Eigen::MatrixXd JacobianOf(const typename Model::Shape& s, const Eigen::Matrix3Xd& points) {
  Eigen::VectorXd d;
  Eigen::Matrix<double, Eigen::Dynamic, Model::kParams> J;
  Eigen::Matrix<double, Model::kParams, Model::kParams> T;
  Model::Linearize(s, points, false, nullptr, d, J, T);
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
