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
#include "fitting/initial_models.h"
#include "fitting/kinematic_starts.h"
#include "fitting/minimizer.h"
#include "fitting/parametric_model.h"
#include "fitting/primitive_detection.h"
#include "fitting/primitive_local_models.h"
#include "fitting/robust_loss.h"

namespace s2m {
namespace {

using primitive_local::CircleLocal;
using primitive_local::ConeLocal;
using primitive_local::CylinderLocal;
using primitive_local::LineLocal;
using primitive_local::Normalize;
using primitive_local::NormalizedData;
using primitive_local::PlaneLocal;
using primitive_local::PointDistances;
using primitive_local::Residuals;
using primitive_local::SphereLocal;
using primitive_local::TorusLocal;

using Clock = std::chrono::steady_clock;

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
// A point's IRLS weight on each of its residual rows (curves have two rows per point).
template <int Rows>
Eigen::VectorXd ExpandToRows(const Eigen::VectorXd& per_point) {
  if constexpr (Rows == 1) {
    return per_point;
  } else {
    Eigen::VectorXd out(Rows * per_point.size());
    for (Eigen::Index i = 0; i < per_point.size(); ++i) out.segment<Rows>(Rows * i).setConstant(per_point[i]);
    return out;
  }
}

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
    d_ = Residuals<Model>(shape_, y_);
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
      const Eigen::VectorXd row_weights = RowWeights(weights_);
      const Eigen::Matrix<double, Eigen::Dynamic, P> WJ = row_weights.asDiagonal() * J_;
      const Mat JtWJ = J_.transpose() * WJ;
      normal_.Set(JtWJ + T_, WJ.transpose() * linear_d_, JtWJ.diagonal(),
                  std::sqrt(row_weights.dot(linear_d_.cwiseAbs2())));
    } else {
      normal_.Set(J_.transpose() * J_ + T_, J_.transpose() * linear_d_,
                  J_.colwise().squaredNorm().transpose(), linear_d_.norm());
    }
    return normal_;
  }

  double EvaluateTrial(const Eigen::VectorXd& step, bool /*final_if_accepted*/) override {
    trial_shape_ = Model::Update(shape_, step);
    trial_d_ = Residuals<Model>(trial_shape_, y_);
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
    record.max_distance = PointDistances<Model>(d_).cwiseAbs().maxCoeff() * unit_;
  }

  // Fills the fit's shape, covariance-based uncertainties (the plain TDM Jacobian at the solution) and the
  // robust loss's final scale and rejections.
  void Describe(PrimitiveFit<Shape>& fit) {
    fit.shape = shape_;
    Eigen::VectorXd weights;
    if (weighting_.is_robust()) {
      UpdateWeights();
      weights = RowWeights(weights_);
      fit.loss_scale = weighting_.scale();
      fit.rejected = (weights_.array() < 0.5).count();
    }
    if (Model::kRowsPerPoint * y_.cols() > P) {
      Model::Linearize(shape_, y_, /*sdm=*/false, nullptr, linear_d_, J_, T_);
      if (const auto cov = LocalCovariance<P>(J_, linear_d_, weights)) {
        if constexpr (requires { Model::FrameOf(shape_); })
          fit.uncertainties = Model::Uncertainties(*cov, unit_, Model::FrameOf(shape_));
        else
          fit.uncertainties = Model::Uncertainties(*cov, unit_);
      }
    }
  }

 private:
  using Vec = Eigen::Matrix<double, P, 1>;
  using Mat = Eigen::Matrix<double, P, P>;

  // 1/2 sum rho(d_j^2) (robust_loss.h); 1/2 sum d_j^2 for plain least squares.
  double Objective(const Eigen::VectorXd& d) const {
    if (!weighting_.is_robust()) return 0.5 * d.squaredNorm();
    const Eigen::VectorXd distances = PointDistances<Model>(d);
    double f = 0.0;
    for (Eigen::Index j = 0; j < distances.size(); ++j) f += 0.5 * weighting_.Rho(distances[j]);
    return f;
  }

  static Eigen::VectorXd RowWeights(const Eigen::VectorXd& per_point) {
    return ExpandToRows<Model::kRowsPerPoint>(per_point);
  }

  void UpdateWeights() {
    if (!weighting_.is_robust()) return;
    const Eigen::VectorXd distances = PointDistances<Model>(d_);
    weighting_.Update(distances);
    weights_ = weighting_.Weights(distances);
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
void Finish(PrimitiveFit<Shape>& fit, const NormalizedData& data, const PointsRef& points) {
  fit.shape = Transformed(fit.shape, data.scale, data.offset);
  if constexpr (requires(Shape s) { MoveAxisPointNear(s, data.offset); })
    MoveAxisPointNear(fit.shape, data.offset);
  // Over the caller's buffer (SignedDistances takes a Matrix3Xd and would copy a mapped one).
  Eigen::VectorXd distances(points.cols());
  for (Eigen::Index i = 0; i < points.cols(); ++i)
    distances[i] = SignedDistance(fit.shape, Eigen::Vector3d(points.col(i)));
  fit.residuals = ComputeResidualStatistics(distances);
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

PrimitiveFit<Plane> FitPlane(const PointsRef& points, const PrimitiveFitOptions& options) {
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

// The circle and the torus take TDM only (their SDM terms are not derived).
template <class Local>
void CheckErrorTerm(const PrimitiveFitOptions& options, const char* what) {
  if (!Local::kSupportsSdm && options.error_term != ErrorTerm::kTdm) {
    throw std::invalid_argument(std::string("a ") + what + " fit takes the error term " +
                                ToString(ErrorTerm::kTdm) + " only, not " + ToString(options.error_term));
  }
}

// A deterministic sign for a direction whose sign carries no meaning: the largest component positive.
Eigen::Vector3d CanonicalSign(const Eigen::Vector3d& v) {
  Eigen::Index k;
  v.cwiseAbs().maxCoeff(&k);
  return v[k] < 0 ? Eigen::Vector3d(-v) : v;
}

// A refinement from the caller's start (given in input units; `to_unit_box` maps it into the unit box of the
// data) or a fit from automatic starts (`starts` in the unit box), then back to input units.
template <class Local, class ToUnitBox>
PrimitiveFit<typename Local::Shape> RefineInUnitBox(const PointsRef& points,
                                                    const PrimitiveFitOptions& options, int min_points,
                                                    const char* what, const ToUnitBox& to_unit_box) {
  CheckOptions(options);
  CheckErrorTerm<Local>(options, what);
  const NormalizedData data = Normalize(points, min_points, what);
  PrimitiveFit<typename Local::Shape> fit = Solve<Local>(data.points, to_unit_box(data), options, data.scale);
  Finish(fit, data, points);
  return fit;
}

template <class Local, class Starts>
PrimitiveFit<typename Local::Shape> FitInUnitBox(const PointsRef& points, const PrimitiveFitOptions& options,
                                                 int min_points, const char* what, const Starts& starts) {
  CheckOptions(options);
  CheckErrorTerm<Local>(options, what);
  const NormalizedData data = Normalize(points, min_points, what);
  PrimitiveFit<typename Local::Shape> fit = FitFromStarts<Local>(data.points, options, data.scale, starts);
  Finish(fit, data, points);
  return fit;
}

PrimitiveFit<Sphere> RefineSphere(const PointsRef& points, const Sphere& initial,
                                  const PrimitiveFitOptions& options) {
  return RefineInUnitBox<SphereLocal>(points, options, 4, "sphere", [&](const NormalizedData& data) {
    return Sphere{(initial.center - data.offset) / data.scale, initial.radius / data.scale};
  });
}

PrimitiveFit<Sphere> FitSphere(const PointsRef& points, const PrimitiveFitOptions& options) {
  return FitInUnitBox<SphereLocal>(points, options, 4, "sphere", [](const Eigen::Matrix3Xd& y) {
    return std::vector<Sphere>{AlgebraicSphere(y)};
  });
}

PrimitiveFit<Cylinder> RefineCylinder(const PointsRef& points, const Cylinder& initial,
                                      const PrimitiveFitOptions& options) {
  return RefineInUnitBox<CylinderLocal>(points, options, 5, "cylinder", [&](const NormalizedData& data) {
    return Cylinder{(initial.axis_point - data.offset) / data.scale, initial.axis_direction.normalized(),
                    initial.radius / data.scale};
  });
}

PrimitiveFit<Cylinder> FitCylinder(const PointsRef& points, const PrimitiveFitOptions& options) {
  return FitInUnitBox<CylinderLocal>(points, options, 5, "cylinder", [&](const Eigen::Matrix3Xd& y) {
    return DirectionSearchStarts<Cylinder>(y, options, CylinderForDirection, "cylinder");
  });
}

PrimitiveFit<Cone> RefineCone(const PointsRef& points, const Cone& initial,
                              const PrimitiveFitOptions& options) {
  return RefineInUnitBox<ConeLocal>(points, options, 6, "cone", [&](const NormalizedData& data) {
    return Cone{(initial.axis_point - data.offset) / data.scale, initial.axis_direction.normalized(),
                initial.half_angle, initial.radius / data.scale};
  });
}

PrimitiveFit<Cone> FitCone(const PointsRef& points, const PrimitiveFitOptions& options) {
  return FitInUnitBox<ConeLocal>(points, options, 6, "cone", [&](const Eigen::Matrix3Xd& y) {
    return DirectionSearchStarts<Cone>(y, options, ConeForDirection, "cone");
  });
}

namespace {

// The least-squares line passes through the centroid along the direction of largest variance (the
// minimizer of the sum of squared distances; docs/metrology.md section 1). Points in normalized units.
Line3d ClosedFormLine(const Eigen::Matrix3Xd& y) {
  const Eigen::Vector3d centroid = y.rowwise().mean();
  const Eigen::Matrix3Xd centred = y.colwise() - centroid;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(centred * centred.transpose());
  if (!(eig.eigenvalues()[2] > 0.0)) throw FitError("cannot fit a line: all points coincide");
  return {centroid, CanonicalSign(eig.eigenvectors().col(2))};
}

// The circle's start: the least-squares plane, then the algebraic (Kasa) circle of the points projected
// into it. Throws FitError when the points are collinear (no circle is determined).
Circle3d CircleStart(const Eigen::Matrix3Xd& y) {
  const Eigen::Vector3d centroid = y.rowwise().mean();
  const Eigen::Matrix3Xd centred = y.colwise() - centroid;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(centred * centred.transpose());
  const Eigen::Vector3d values = eig.eigenvalues();
  if (!(values[1] > 1e-12 * values[2]))
    throw FitError("cannot fit a circle: the points are collinear (a circle is not determined)");
  const Eigen::Vector3d normal = CanonicalSign(eig.eigenvectors().col(0));
  const Eigen::Matrix3d frame = FrameWithAxis(normal);
  const Eigen::Matrix2Xd q = frame.leftCols<2>().transpose() * centred;
  Eigen::Vector2d c;
  double r;
  if (!AlgebraicCircle(q, c, r))
    throw FitError("cannot fit a circle: the points are collinear (a circle is not determined)");
  return {centroid + frame.leftCols<2>() * c, normal, r};
}

// A torus for a given axis (point, direction): in the meridian half-plane each point has coordinates (rho, z)
// (distance from the axis, height along it); the tube's cross-section is a circle there, centred at (R, z0)
// with radius r, fitted algebraically (Kasa). nullopt when the points are collinear in that plane or R <= 0.
std::optional<Torus> TorusForAxis(const Eigen::Matrix3Xd& y, const Eigen::Vector3d& point,
                                  const Eigen::Vector3d& direction) {
  const Eigen::Vector3d a = direction.normalized();
  Eigen::Matrix2Xd meridian(2, y.cols());
  for (Eigen::Index i = 0; i < y.cols(); ++i) {
    const Eigen::Vector3d v = y.col(i) - point;
    const double z = a.dot(v);
    meridian.col(i) << (v - z * a).norm(), z;
  }
  Eigen::Vector2d c;
  double r;
  if (!AlgebraicCircle(meridian, c, r) || !(c[0] > 0.0)) return std::nullopt;
  return Torus{point + c[1] * a, CanonicalSign(a), c[0], r};
}

// The axis point for a given axis direction a from the normals: every normal line meets the axis, (x_i -
// p).(n_i x a) = 0, linear in p (least squares across the axis). nullopt when the normals do not determine
// it.
std::optional<Eigen::Vector3d> AxisPointFromNormals(const Eigen::Matrix3Xd& y,
                                                    const Eigen::Matrix3Xd& normals,
                                                    const Eigen::Vector3d& a) {
  const Eigen::Matrix3d frame = FrameWithAxis(a);
  Eigen::Matrix2d m = Eigen::Matrix2d::Zero();
  Eigen::Vector2d rhs = Eigen::Vector2d::Zero();
  for (Eigen::Index i = 0; i < y.cols(); ++i) {
    const Eigen::Vector3d w = normals.col(i).cross(a);
    const Eigen::Vector2d g = frame.leftCols<2>().transpose() * w;  // p = frame (u, 0): w.p = g.u
    m += g * g.transpose();
    rhs += g * w.dot(y.col(i));
  }
  const Eigen::LDLT<Eigen::Matrix2d> ldlt(m);
  if (ldlt.info() != Eigen::Success || !(std::abs(m.determinant()) > 1e-12 * m.squaredNorm()))
    return std::nullopt;
  return Eigen::Vector3d(frame.leftCols<2>() * ldlt.solve(rhs));
}

// The torus's starts (docs/metrology.md section 1). A search over axis directions as for cylinders (400 on a
// hemisphere and the principal axes): for each the axis point from the normals (AxisPointFromNormals; every
// normal line of a surface of revolution meets its axis) and the tube from the meridian circle
// (TorusForAxis); besides, the axis from the normals alone (KinematicAxisFromNormals, docs/method.md eqs. 26
// and 71), which is fragile on small patches, and the data's least-variance direction through the centroid
// (right for a whole ring). The best few mutually distinct candidates by their sum of squared distances are
// refined. Normals: PCA of 16 nearest neighbours.
std::vector<Torus> TorusStarts(const Eigen::Matrix3Xd& points, const PrimitiveFitOptions& options) {
  const Eigen::Matrix3Xd y = Subsample(points, options.max_initialization_points);
  std::vector<Torus> candidates;
  constexpr int kNeighbours = 16;
  if (y.cols() >= 2 * kNeighbours) {
    const PointNormals normals = EstimatePointNormals(y, kNeighbours);
    for (const Eigen::Vector3d& dir : CandidateDirections(y, options.direction_samples)) {
      if (const auto point = AxisPointFromNormals(y, normals.normals, dir))
        if (auto t = TorusForAxis(y, *point, dir)) candidates.push_back(*t);
    }
    for (const bool robust : {false, true}) {
      try {
        const KinematicAxis axis =
            robust ? RobustKinematicAxisFromNormals(y, normals.normals, KinematicKind::kRevolution)
                   : KinematicAxisFromNormals(y, normals.normals, KinematicKind::kRevolution);
        if (auto t = TorusForAxis(y, axis.point, axis.direction)) candidates.push_back(*t);
      } catch (const std::invalid_argument&) {
        // Normals spanning less than 3-D (e.g. a planar ring of points): the other starts remain.
      }
    }
  }
  const Eigen::Vector3d centroid = y.rowwise().mean();
  const Eigen::Matrix3Xd centred = y.colwise() - centroid;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(centred * centred.transpose());
  if (auto t = TorusForAxis(y, centroid, eig.eigenvectors().col(0))) candidates.push_back(*t);
  std::vector<std::pair<double, std::size_t>> scored;
  for (std::size_t k = 0; k < candidates.size(); ++k) {
    const double score = SignedDistances(candidates[k], y).squaredNorm();
    if (std::isfinite(score)) scored.emplace_back(score, k);
  }
  std::sort(scored.begin(), scored.end());
  const double min_separation_cos = std::cos(10.0 * M_PI / 180.0);
  std::vector<Torus> starts;
  for (const auto& [score, k] : scored) {
    const Torus& t = candidates[k];
    if (std::all_of(starts.begin(), starts.end(),
                    [&](const Torus& o) { return std::abs(o.axis.dot(t.axis)) < min_separation_cos; }))
      starts.push_back(t);
    if (static_cast<int>(starts.size()) >= std::max(1, options.refined_candidates)) break;
  }
  if (starts.empty())
    throw FitError("cannot fit a torus: no axis gives a usable initial guess (degenerate data?)");
  return starts;
}

}  // namespace

PrimitiveFit<Line3d> FitLine(const PointsRef& points, const PrimitiveFitOptions& options) {
  PrimitiveFit<Line3d> fit = FitInUnitBox<LineLocal>(
      points, options, 2, "line",
      [](const Eigen::Matrix3Xd& y) { return std::vector<Line3d>{ClosedFormLine(y)}; });
  // Plain least squares: the start is the exact minimizer, so the refinement can only move it by rounding; it
  // supplies the covariance.
  if (!options.optimizer.loss.is_robust()) fit.stop_reason = StopReason::kClosedForm;
  fit.shape.direction = CanonicalSign(fit.shape.direction);
  return fit;
}

PrimitiveFit<Circle3d> RefineCircle(const PointsRef& points, const Circle3d& initial,
                                    const PrimitiveFitOptions& options) {
  PrimitiveFit<Circle3d> fit =
      RefineInUnitBox<CircleLocal>(points, options, 3, "circle", [&](const NormalizedData& data) {
        return Circle3d{(initial.center - data.offset) / data.scale, initial.normal.normalized(),
                        initial.radius / data.scale};
      });
  fit.shape.normal = CanonicalSign(fit.shape.normal);
  return fit;
}

PrimitiveFit<Circle3d> FitCircle(const PointsRef& points, const PrimitiveFitOptions& options) {
  PrimitiveFit<Circle3d> fit = FitInUnitBox<CircleLocal>(
      points, options, 3, "circle", [](const auto& y) { return std::vector<Circle3d>{CircleStart(y)}; });
  fit.shape.normal = CanonicalSign(fit.shape.normal);
  return fit;
}

PrimitiveFit<Torus> RefineTorus(const PointsRef& points, const Torus& initial,
                                const PrimitiveFitOptions& options) {
  PrimitiveFit<Torus> fit =
      RefineInUnitBox<TorusLocal>(points, options, 7, "torus", [&](const NormalizedData& data) {
        return Torus{(initial.center - data.offset) / data.scale, initial.axis.normalized(),
                     initial.major_radius / data.scale, initial.minor_radius / data.scale};
      });
  fit.shape.axis = CanonicalSign(fit.shape.axis);
  return fit;
}

PrimitiveFit<Torus> FitTorus(const PointsRef& points, const PrimitiveFitOptions& options) {
  PrimitiveFit<Torus> fit = FitInUnitBox<TorusLocal>(points, options, 7, "torus",
                                                     [&](const auto& y) { return TorusStarts(y, options); });
  fit.shape.axis = CanonicalSign(fit.shape.axis);
  return fit;
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

Eigen::MatrixXd DistanceJacobian(const Plane& s, const Eigen::Matrix3Xd& p) {
  return JacobianOf<PlaneLocal>(s, p);
}
Eigen::MatrixXd DistanceJacobian(const Sphere& s, const Eigen::Matrix3Xd& p) {
  return JacobianOf<SphereLocal>(s, p);
}
Eigen::MatrixXd DistanceJacobian(const Cylinder& s, const Eigen::Matrix3Xd& p) {
  return JacobianOf<CylinderLocal>(s, p);
}
Eigen::MatrixXd DistanceJacobian(const Cone& s, const Eigen::Matrix3Xd& p) {
  return JacobianOf<ConeLocal>(s, p);
}
Eigen::MatrixXd DistanceJacobian(const Line3d& s, const Eigen::Matrix3Xd& p) {
  return JacobianOf<LineLocal>(s, p);
}
Eigen::MatrixXd DistanceJacobian(const Circle3d& s, const Eigen::Matrix3Xd& p) {
  return JacobianOf<CircleLocal>(s, p);
}
Eigen::MatrixXd DistanceJacobian(const Torus& s, const Eigen::Matrix3Xd& p) {
  return JacobianOf<TorusLocal>(s, p);
}
Eigen::VectorXd ResidualVector(const Line3d& s, const Eigen::Matrix3Xd& p) {
  return Residuals<LineLocal>(s, p);
}
Eigen::VectorXd ResidualVector(const Circle3d& s, const Eigen::Matrix3Xd& p) {
  return Residuals<CircleLocal>(s, p);
}
Line3d ApplyIncrement(const Line3d& s, const Eigen::VectorXd& delta) {
  return LineLocal::Update(s, delta);
}
Circle3d ApplyIncrement(const Circle3d& s, const Eigen::VectorXd& delta) {
  return CircleLocal::Update(s, delta);
}
Torus ApplyIncrement(const Torus& s, const Eigen::VectorXd& delta) {
  return TorusLocal::Update(s, delta);
}
Plane ApplyIncrement(const Plane& s, const Eigen::VectorXd& delta) {
  return PlaneLocal::Update(s, delta);
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
