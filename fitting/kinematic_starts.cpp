#include "fitting/kinematic_starts.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

#include "fitting/foot_point.h"
#include "fitting/kinematic_surfaces.h"
#include "fitting/least_squares.h"
#include "fitting/primitive_fit.h"
#include "fitting/primitives.h"

namespace s2m {
namespace {

constexpr double kDegree = M_PI / 180.0;

// At most `max_points` columns by a deterministic stride (the searches' sample).
std::vector<Eigen::Index> SampleIndices(Eigen::Index n, int max_points) {
  std::vector<Eigen::Index> idx;
  const Eigen::Index m = std::min<Eigen::Index>(n, std::max(max_points, 1));
  const double stride = static_cast<double>(n) / static_cast<double>(m);
  for (Eigen::Index i = 0; i < m; ++i)
    idx.push_back(static_cast<Eigen::Index>(static_cast<double>(i) * stride));
  return idx;
}

Eigen::Matrix3Xd Columns(const Eigen::Matrix3Xd& m, const std::vector<Eigen::Index>& idx) {
  Eigen::Matrix3Xd out(3, static_cast<Eigen::Index>(idx.size()));
  for (std::size_t i = 0; i < idx.size(); ++i) out.col(static_cast<Eigen::Index>(i)) = m.col(idx[i]);
  return out;
}

// The q-quantile of values (0 <= q <= 1), by selection.
double Quantile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  const auto k = static_cast<std::size_t>(std::clamp(q, 0.0, 1.0) * static_cast<double>(values.size() - 1));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

// Entropy of the occupancy (eq. 74) of points with profile coordinates `a` and phases `phase` (modulo 1):
// `a` mapped onto [0, 1] between its 1 % and 99 % quantiles (a few stray points must not squeeze the
// profile into one bin), each point spread bilinearly over its four nearest cells (periodic in phase), so
// that the entropy changes continuously with the candidate.
double OccupancyEntropy(const std::vector<double>& a, const std::vector<double>& phase, int bins) {
  if (a.empty()) return 0.0;
  const double lo = Quantile(a, 0.01), hi = Quantile(a, 0.99);
  const double span = hi > lo ? hi - lo : 1.0;
  std::vector<double> cells(static_cast<std::size_t>(bins * bins), 0.0);
  const double w = 1.0 / static_cast<double>(a.size());
  for (std::size_t j = 0; j < a.size(); ++j) {
    const double s = std::clamp((a[j] - lo) / span, 0.0, 1.0) * (bins - 1);
    const int i0 = std::min(static_cast<int>(s), bins - 2);
    const double fs = s - i0;
    double p = phase[j] - std::floor(phase[j]);
    p *= bins;
    int k0 = static_cast<int>(p);
    const double fp = p - k0;
    k0 %= bins;
    const int k1 = (k0 + 1) % bins;
    auto cell = [&](int i, int k) -> double& { return cells[static_cast<std::size_t>(i * bins + k)]; };
    cell(i0, k0) += w * (1 - fs) * (1 - fp);
    cell(i0, k1) += w * (1 - fs) * fp;
    cell(i0 + 1, k0) += w * fs * (1 - fp);
    cell(i0 + 1, k1) += w * fs * fp;
  }
  double h = 0.0;
  for (double q : cells)
    if (q > 0) h -= q * std::log(q);
  return h;
}

// The axis point of a helical motion with direction c (unit) and pitch p from the normals (26): with
// u_j = n_j x c the residual is e_j = (x_j x n_j) . c + p n_j . c - a . u_j, linear in the axis point a
// (its component along c is free: a lies in the plane through `origin` perpendicular to c).
Eigen::Vector3d HelicalAxisPoint(const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& n,
                                 const Eigen::VectorXd& w, const Eigen::Vector3d& c, double pitch,
                                 const Eigen::Vector3d& origin) {
  const Eigen::Matrix3d frame = FrameWithAxis(c);
  Eigen::Matrix2d A = Eigen::Matrix2d::Zero();
  Eigen::Vector2d b = Eigen::Vector2d::Zero();
  for (Eigen::Index j = 0; j < x.cols(); ++j) {
    const double wj = w.size() ? w[j] : 1.0;
    if (!(wj > 0)) continue;
    const Eigen::Vector3d xj = x.col(j) - origin;
    const Eigen::Vector3d u = n.col(j).cross(c);
    const Eigen::Vector2d u2(u.dot(frame.col(0)), u.dot(frame.col(1)));
    const double rhs = xj.cross(Eigen::Vector3d(n.col(j))).dot(c) + pitch * n.col(j).dot(c);
    A += wj * u2 * u2.transpose();
    b += wj * u2 * rhs;
  }
  const Eigen::Vector2d a = A.ldlt().solve(b);
  return origin + a.x() * frame.col(0) + a.y() * frame.col(1);
}

// The centre of a spiral motion with direction c (unit) and growth g from the normals (26): the residual
// e_j = (x_j x n_j) . c + g n_j . x_j - x0 . (n_j x c + g n_j) is linear in the centre x0. The sums are
// quadratic in g: kept per power of g, so each candidate costs a 3 x 3 solve.
class SpiralCentreFromNormals {
 public:
  SpiralCentreFromNormals(const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& n, const Eigen::VectorXd& w,
                          const Eigen::Vector3d& c)
      : origin_(x.rowwise().mean()) {
    for (Eigen::Index j = 0; j < x.cols(); ++j) {
      const double wj = w.size() ? w[j] : 1.0;
      if (!(wj > 0)) continue;
      const Eigen::Vector3d xj = x.col(j) - origin_, nj = n.col(j);
      const Eigen::Vector3d u = nj.cross(c);
      const double mc = xj.cross(nj).dot(c), nx = nj.dot(xj);
      a0_ += wj * u * u.transpose();
      a1_ += wj * (u * nj.transpose() + nj * u.transpose());
      a2_ += wj * nj * nj.transpose();
      b0_ += wj * u * mc;
      b1_ += wj * (u * nx + nj * mc);
      b2_ += wj * nj * nx;
    }
  }
  Eigen::Vector3d Centre(double g) const {
    const Eigen::Matrix3d A = a0_ + g * a1_ + g * g * a2_;
    return origin_ + A.ldlt().solve(b0_ + g * b1_ + g * g * b2_);
  }

 private:
  Eigen::Vector3d origin_;
  Eigen::Matrix3d a0_ = Eigen::Matrix3d::Zero(), a1_ = Eigen::Matrix3d::Zero(), a2_ = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b0_ = Eigen::Vector3d::Zero(), b1_ = Eigen::Vector3d::Zero(), b2_ = Eigen::Vector3d::Zero();
};

// The meridian profile residuals (eq. 75) of points about the axis (a, c): (rho_j, z_j) in the meridian
// half-plane, y = f(t) a cubic B-spline function with `num_control` coefficients fitted by weighted linear
// least squares with a small bending term (as InitialRevolution), t = z and y = rho (`along_height`), or
// the reverse; d_j = (y_j - f(t_j)) / sqrt(1 + f'(t_j)^2), the distance to the profile to first order.
Eigen::VectorXd MeridianResiduals(const Eigen::Matrix3Xd& p, const Eigen::VectorXd& w,
                                  const Eigen::Vector3d& a, const Eigen::Vector3d& c, int num_control,
                                  bool along_height) {
  const Eigen::Index n = p.cols();
  Eigen::VectorXd t(n), y(n);
  double lo = INFINITY, hi = -INFINITY;
  for (Eigen::Index j = 0; j < n; ++j) {
    const Eigen::Vector3d d = p.col(j) - a;
    const double z = d.dot(c), rho = (d - z * c).norm();
    t[j] = along_height ? z : rho;
    y[j] = along_height ? rho : z;
    if (w.size() == 0 || w[j] > 0) {
      lo = std::min(lo, t[j]);
      hi = std::max(hi, t[j]);
    }
  }
  if (!(hi > lo)) return y.array() - y.mean();
  const BSplineBasis basis = UnitSpacedClamped(4, num_control);
  const double to_u = (basis.hi() - basis.lo()) / (hi - lo);
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(num_control, num_control);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(num_control);
  BSplineBasis::Values v;
  auto u_of = [&](double tj) { return std::clamp(basis.lo() + (tj - lo) * to_u, basis.lo(), basis.hi()); };
  for (Eigen::Index j = 0; j < n; ++j) {
    const double wj = w.size() ? w[j] : 1.0;
    if (!(wj > 0)) continue;
    basis.Evaluate(u_of(t[j]), 0, v);
    for (int i = 0; i < basis.order(); ++i) {
      const double bi = wj * v.values[0][static_cast<std::size_t>(i)];
      b[basis.ControlIndex(v.first, i)] += bi * y[j];
      for (int k = 0; k < basis.order(); ++k)
        A(basis.ControlIndex(v.first, i), basis.ControlIndex(v.first, k)) +=
            bi * v.values[0][static_cast<std::size_t>(k)];
    }
  }
  const std::vector<double> g = basis.GramMatrix(2);
  const Eigen::MatrixXd K =
      Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
          g.data(), num_control, num_control);
  const double mu = 1e-3 * A.trace() / std::max(K.trace(), 1e-300);
  const Eigen::VectorXd coef = (A + mu * K).ldlt().solve(b);
  Eigen::VectorXd d(n);
  for (Eigen::Index j = 0; j < n; ++j) {
    basis.Evaluate(u_of(t[j]), 1, v);
    double f = 0.0, df = 0.0;
    for (int i = 0; i < basis.order(); ++i) {
      const double ci = coef[basis.ControlIndex(v.first, i)];
      f += ci * v.values[0][static_cast<std::size_t>(i)];
      df += ci * v.values[1][static_cast<std::size_t>(i)] * to_u;
    }
    d[j] = (y[j] - f) / std::sqrt(1.0 + df * df);
  }
  return d;
}

// Weights 1 for the points whose normal lies within 45 degrees of the meridian plane through them (where a
// surface of revolution about (a, c) has its normal, eq. 77), 0 for the others: a sherd's side breaks face
// along the circumference. All 1 without normals.
Eigen::VectorXd MeridianNormalWeights(const Eigen::Matrix3Xd& p, const Eigen::Matrix3Xd& n,
                                      const Eigen::Vector3d& a, const Eigen::Vector3d& c) {
  Eigen::VectorXd w = Eigen::VectorXd::Ones(p.cols());
  if (n.cols() != p.cols()) return w;
  const double limit = std::sin(45 * kDegree);
  for (Eigen::Index j = 0; j < p.cols(); ++j) {
    const Eigen::Vector3d around = c.cross(Eigen::Vector3d(p.col(j) - a));
    const double norm = around.norm() * n.col(j).norm();
    if (norm > 0 && std::abs(around.dot(n.col(j))) > limit * norm) w[j] = 0.0;
  }
  return w;
}

// The entries of d where mask is positive.
Eigen::VectorXd Masked(const Eigen::VectorXd& d, const Eigen::VectorXd& mask) {
  std::vector<double> kept;
  for (Eigen::Index j = 0; j < d.size(); ++j)
    if (mask[j] > 0) kept.push_back(d[j]);
  return Eigen::Map<const Eigen::VectorXd>(kept.data(), static_cast<Eigen::Index>(kept.size()));
}

// Does the profile span more height than radius about this axis (then rho is fitted as a function of z)?
bool SpansMoreHeight(const Eigen::Matrix3Xd& p, const Eigen::Vector3d& a, const Eigen::Vector3d& c) {
  std::vector<double> z, rho;
  for (Eigen::Index j = 0; j < p.cols(); ++j) {
    const Eigen::Vector3d d = p.col(j) - a;
    z.push_back(d.dot(c));
    rho.push_back((d - z.back() * c).norm());
  }
  return Quantile(z, 0.99) - Quantile(z, 0.01) >= Quantile(rho, 0.99) - Quantile(rho, 0.01);
}

// The axis point for direction c from the normals at zero pitch, with a few IRLS steps on (26) (the
// fracture faces' normals would pull it otherwise).
Eigen::Vector3d RevolutionAxisPoint(const Eigen::Matrix3Xd& x, const Eigen::Matrix3Xd& n,
                                    const Eigen::Vector3d& c, const Eigen::Vector3d& origin,
                                    const RobustLoss& loss) {
  Eigen::VectorXd w;
  Eigen::Vector3d a = HelicalAxisPoint(x, n, w, c, 0.0, origin);
  if (!loss.is_robust()) return a;
  RobustWeighting weighting(loss);
  for (int it = 0; it < 3; ++it) {
    KinematicAxis axis;
    axis.point = a;
    axis.direction = c;
    const Eigen::VectorXd e = AxisFromNormalsResiduals(x, n, axis, KinematicKind::kRevolution);
    weighting.Update(e);
    w = weighting.Weights(e);
    a = HelicalAxisPoint(x, n, w, c, 0.0, origin);
  }
  return a;
}

// The robust scale (47) of (53) about (a, c): the profile fitted to the points the normal test keeps, then
// once more with Tukey weights of its residuals.
double RobustCollapseScore(const Eigen::Matrix3Xd& p, const Eigen::Matrix3Xd& n, const Eigen::Vector3d& a,
                           const Eigen::Vector3d& c, int num_control, bool along_height) {
  const Eigen::VectorXd mask = MeridianNormalWeights(p, n, a, c);
  if (mask.sum() < 2 * num_control) return INFINITY;
  const Eigen::VectorXd d = MeridianResiduals(p, mask, a, c, num_control, along_height);
  RobustWeighting weighting(RobustLoss{LossKind::kTukey});
  weighting.Update(Masked(d, mask));
  return MadSigma(Masked(
      MeridianResiduals(p, weighting.Weights(d).cwiseProduct(mask), a, c, num_control, along_height), mask));
}

// Local refinement of (53) over the axis direction (two tilts) and point (two shifts across it) from
// (a0, c0) by least squares (fitting/least_squares.h, forward-difference Jacobian), in three IRLS rounds
// with Tukey weights of the residuals (scale from their MAD, eq. 47).
AxisCandidate RefineAxisByProfile(const Eigen::Matrix3Xd& p, const Eigen::Matrix3Xd& n, Eigen::Vector3d a0,
                                  Eigen::Vector3d c0, int num_control, double length) {
  const bool along_height = SpansMoreHeight(p, a0, c0);
  Eigen::VectorXd w = Eigen::VectorXd::Ones(p.cols());
  RobustWeighting weighting(RobustLoss{LossKind::kTukey});
  for (int round = 0; round < 3; ++round) {
    const Eigen::Matrix3d frame = FrameWithAxis(c0);
    auto axis_of = [&](const Eigen::VectorXd& x, Eigen::Vector3d& a, Eigen::Vector3d& c) {
      c = (c0 + x[0] * frame.col(0) + x[1] * frame.col(1)).normalized();
      a = a0 + length * (x[2] * frame.col(0) + x[3] * frame.col(1));
    };
    const Eigen::VectorXd mask = MeridianNormalWeights(p, n, a0, c0);
    const Eigen::VectorXd d0 = MeridianResiduals(p, w.cwiseProduct(mask), a0, c0, num_control, along_height);
    weighting.Update(Masked(d0, mask));
    w = weighting.Weights(d0).cwiseProduct(mask);
    const Eigen::VectorXd sqrt_w = w.cwiseSqrt();
    LeastSquaresProblem problem;
    problem.num_residuals = static_cast<int>(p.cols());
    problem.num_parameters = 4;
    problem.evaluate = [&](const Eigen::VectorXd& x, Eigen::VectorXd& r, Eigen::MatrixXd* J) {
      Eigen::Vector3d a, c;
      axis_of(x, a, c);
      r = MeridianResiduals(p, w, a, c, num_control, along_height).cwiseProduct(sqrt_w) / length;
      if (J) {
        J->resize(r.size(), 4);
        for (int k = 0; k < 4; ++k) {
          Eigen::VectorXd xk = x;
          const double h = 1e-6;
          xk[k] += h;
          axis_of(xk, a, c);
          J->col(k) =
              (MeridianResiduals(p, w, a, c, num_control, along_height).cwiseProduct(sqrt_w) / length - r) /
              h;
        }
      }
      return r.allFinite();
    };
    LeastSquaresOptions ls;
    ls.max_iterations = 100;
    ls.function_tolerance = 1e-10;
    ls.step_tolerance = 1e-10;
    ls.gradient_tolerance = 1e-12;
    ls.damping_scaling = DampingScaling::kIsotropic;
    const LeastSquaresResult result = SolveLeastSquares(problem, Eigen::VectorXd::Zero(4), ls);
    axis_of(result.x, a0, c0);
  }
  AxisCandidate out;
  out.point = a0;
  out.direction = c0;
  out.score = RobustCollapseScore(p, n, a0, c0, num_control, along_height);
  return out;
}

// The axis point moved along the axis to the foot of the points' centroid (a reporting convention: the
// model frame's origin at the data's mean height).
Eigen::Vector3d AtMeanHeight(const Eigen::Vector3d& a, const Eigen::Vector3d& c,
                             const Eigen::Vector3d& centroid) {
  return a + c * c.dot(centroid - a);
}

double DataSize(const Eigen::Matrix3Xd& p) {
  return std::sqrt((p.colwise() - p.rowwise().mean()).squaredNorm() /
                   std::max(1.0, static_cast<double>(p.cols())));
}

}  // namespace

Eigen::VectorXd AxisFromNormalsResiduals(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                                         const KinematicAxis& axis, KinematicKind kind) {
  const Eigen::Vector3d c = axis.direction.normalized();
  Eigen::VectorXd e(points.cols());
  for (Eigen::Index j = 0; j < points.cols(); ++j) {
    const Eigen::Vector3d d = points.col(j) - axis.point;
    Eigen::Vector3d v = c.cross(d);  // the velocity of (26) with |c| = 1
    if (kind == KinematicKind::kSpiral) {
      v += axis.growth * d;
    } else if (kind == KinematicKind::kHelical) {
      v += axis.pitch * c;
    }
    e[j] = normals.col(j).normalized().dot(v);
  }
  return e;
}

KinematicAxis RobustKinematicAxisFromNormals(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                                             KinematicKind kind, const RobustLoss& loss,
                                             Eigen::VectorXd* weights) {
  KinematicAxis axis = KinematicAxisFromNormals(points, normals, kind);
  Eigen::VectorXd w = Eigen::VectorXd::Ones(points.cols());
  if (loss.is_robust()) {
    RobustWeighting weighting(loss);
    for (int it = 0; it < 30; ++it) {
      // Revolution: (26) is solved as for a helical surface (the pitch is reported, not used), and so are
      // its residuals.
      const KinematicKind residual_kind = kind == KinematicKind::kRevolution ? KinematicKind::kHelical : kind;
      const Eigen::VectorXd e = AxisFromNormalsResiduals(points, normals, axis, residual_kind);
      weighting.Update(e);
      w = weighting.Weights(e);
      const KinematicAxis next = KinematicAxisFromNormals(points, normals, kind, w);
      const double turn = std::acos(std::min(1.0, std::abs(next.direction.dot(axis.direction))));
      axis = next;
      if (turn < 1e-9) break;
    }
  }
  if (weights) *weights = w;
  return axis;
}

double HelicalPhaseEntropy(const Eigen::Matrix3Xd& p, double pitch, int bins) {
  if (!(std::abs(pitch) > 0)) throw std::invalid_argument("a helical phase needs a non-zero pitch");
  std::vector<double> radius(static_cast<std::size_t>(p.cols())), phase(radius.size());
  const double lead = 2 * M_PI * std::abs(pitch);
  for (Eigen::Index j = 0; j < p.cols(); ++j) {
    const auto i = static_cast<std::size_t>(j);
    radius[i] = std::hypot(p(0, j), p(1, j));
    phase[i] = (p(2, j) - pitch * std::atan2(p(1, j), p(0, j))) / lead;  // eq. 72
  }
  return OccupancyEntropy(radius, phase, bins);
}

double SpiralPhaseEntropy(const Eigen::Matrix3Xd& p, double growth, int bins) {
  if (!(std::abs(growth) > 0)) throw std::invalid_argument("a spiral phase needs a non-zero growth");
  std::vector<double> meridian, phase;
  const double period = 2 * M_PI * std::abs(growth);
  for (Eigen::Index j = 0; j < p.cols(); ++j) {
    const double rho = std::hypot(p(0, j), p(1, j)), size = p.col(j).norm();
    if (!(size > 0)) continue;
    meridian.push_back(std::atan2(p(2, j), rho));
    phase.push_back((std::log(size) - growth * std::atan2(p(1, j), p(0, j))) / period);  // eq. 73
  }
  return OccupancyEntropy(meridian, phase, bins);
}

std::vector<SpectrumPeak> SpectrumPeaks(double estimate, double reference_scale,
                                        const KinematicStartOptions& options,
                                        const std::function<double(double)>& entropy_of) {
  if (!(options.search_factor > 1.0) || !(options.grid_ratio > 1.0))
    throw std::invalid_argument("the pitch or growth search needs a factor and a grid ratio above 1");
  const double centre = std::max(std::abs(estimate), reference_scale);
  if (!(centre > 0) || !std::isfinite(centre))
    throw std::invalid_argument("no scale for the pitch or growth search");
  const double log_step = std::log(options.grid_ratio);
  const int half = static_cast<int>(std::ceil(std::log(options.search_factor) / log_step));
  std::vector<SpectrumPeak> peaks;
  for (const double sign : {1.0, -1.0}) {
    std::vector<double> h(static_cast<std::size_t>(2 * half + 1));
    auto value = [&](double k) { return sign * centre * std::exp(k * log_step); };
    for (int k = -half; k <= half; ++k) h[static_cast<std::size_t>(k + half)] = entropy_of(value(k));
    for (int i = 0; i <= 2 * half; ++i) {
      const auto u = static_cast<std::size_t>(i);
      const bool left = i == 0 || h[u] <= h[u - 1], right = i == 2 * half || h[u] < h[u + 1];
      if (!left || !right) continue;
      double k = i - half;
      if (i > 0 && i < 2 * half) {  // a parabola through the three in log |value|
        const double curvature = h[u - 1] - 2 * h[u] + h[u + 1];
        if (curvature > 0) k += 0.5 * (h[u - 1] - h[u + 1]) / curvature;
      }
      peaks.push_back({value(k), h[u]});
    }
  }
  std::sort(peaks.begin(), peaks.end(),
            [](const SpectrumPeak& a, const SpectrumPeak& b) { return a.entropy < b.entropy; });
  return peaks;
}

double ProfileCollapseScore(const Eigen::Matrix3Xd& points, const Eigen::Vector3d& axis_point,
                            const Eigen::Vector3d& axis_direction, int num_control) {
  const Eigen::Vector3d c = axis_direction.normalized();
  return MadSigma(MeridianResiduals(points, Eigen::VectorXd(), axis_point, c, num_control,
                                    SpansMoreHeight(points, axis_point, c)));
}

std::vector<AxisCandidate> RevolutionAxisCandidates(const Eigen::Matrix3Xd& points,
                                                    const Eigen::Matrix3Xd& normals,
                                                    const KinematicStartOptions& options) {
  if (points.cols() != normals.cols()) throw std::invalid_argument("one normal per point is needed");
  const std::vector<Eigen::Index> idx = SampleIndices(points.cols(), options.max_sample);
  const Eigen::Matrix3Xd p = Columns(points, idx), n = Columns(normals, idx);
  const Eigen::Vector3d centroid = p.rowwise().mean();
  const double length = DataSize(p);
  const int m = options.num_control;
  // A coarser sample scores the hemisphere (eq. 76); the refinement uses the whole sample.
  const std::vector<Eigen::Index> coarse_idx = SampleIndices(p.cols(), 1500);
  const Eigen::Matrix3Xd pc = Columns(p, coarse_idx), nc = Columns(n, coarse_idx);

  std::vector<AxisCandidate> seeds;
  const KinematicAxis from_normals =
      RobustKinematicAxisFromNormals(p, n, KinematicKind::kRevolution, options.axis_loss);
  seeds.push_back({from_normals.point, from_normals.direction,
                   RobustCollapseScore(pc, nc, from_normals.point, from_normals.direction, m,
                                       SpansMoreHeight(pc, from_normals.point, from_normals.direction)),
                   "normals"});
  try {
    const Cylinder cyl = FitCylinder(p).shape;
    seeds.push_back({cyl.axis_point, cyl.axis_direction,
                     RobustCollapseScore(pc, nc, cyl.axis_point, cyl.axis_direction, m,
                                         SpansMoreHeight(pc, cyl.axis_point, cyl.axis_direction)),
                     "cylinder"});
  } catch (const std::exception&) {  // no cylinder: the other seeds stand
  }
  std::vector<AxisCandidate> lattice;
  for (const Eigen::Vector3d& c : FibonacciHemisphere(options.direction_samples)) {
    const Eigen::Vector3d a = RevolutionAxisPoint(pc, nc, c, centroid, RobustLoss{LossKind::kTukey});
    lattice.push_back(
        {a, c, RobustCollapseScore(pc, nc, a, c, m, SpansMoreHeight(pc, a, c)), "direction search"});
  }
  std::sort(lattice.begin(), lattice.end(),
            [](const AxisCandidate& a, const AxisCandidate& b) { return a.score < b.score; });
  // The best distinct lattice directions (more than 3 lattice spacings apart).
  const double spacing = std::sqrt(2 * M_PI / std::max(options.direction_samples, 1));
  int taken = 0;
  for (const AxisCandidate& c : lattice) {
    if (taken >= 4) break;
    bool distinct = true;
    for (const AxisCandidate& s : seeds)
      distinct = distinct && std::acos(std::min(1.0, std::abs(s.direction.dot(c.direction)))) > 3 * spacing;
    if (!distinct) continue;
    seeds.push_back(c);
    ++taken;
  }
  std::vector<AxisCandidate> refined;
  for (const AxisCandidate& s : seeds) {
    AxisCandidate r = RefineAxisByProfile(p, n, s.point, s.direction, m, length);
    r.source = s.source;
    r.point = AtMeanHeight(r.point, r.direction, centroid);
    bool distinct = std::isfinite(r.score);
    for (const AxisCandidate& q : refined) {
      const double angle = std::acos(std::min(1.0, std::abs(q.direction.dot(r.direction))));
      const Eigen::Vector3d offset = r.point - q.point;
      const double apart = (offset - q.direction * q.direction.dot(offset)).norm();
      if (angle < 1 * kDegree && apart < 0.01 * length) distinct = false;
    }
    if (distinct) refined.push_back(r);
  }
  std::sort(refined.begin(), refined.end(),
            [](const AxisCandidate& a, const AxisCandidate& b) { return a.score < b.score; });
  return refined;
}

bool OffSurfaceTest::IsValid(std::string* why) const {
  const auto fail = [why](const char* message) {
    if (why) *why = message;
    return false;
  };
  if (!(distance_in_sigma > 0.0) || !std::isfinite(distance_in_sigma))
    return fail("the distance limit must be finite and positive");
  if (!(min_angle_deg > 0.0) || !(max_angle_deg <= 90.0) || !(min_angle_deg <= max_angle_deg))
    return fail("the normal limits must satisfy 0 < min <= max <= 90 degrees");
  if (min_points_for_spread < 1) return fail("min_points_for_spread must be at least 1");
  return true;
}

double NormalAngleLimitDeg(std::vector<double> angles_rad, const OffSurfaceTest& test) {
  if (!test.angle_from_spread || static_cast<int>(angles_rad.size()) < test.min_points_for_spread)
    return test.max_angle_deg;
  // docs/method.md eq. (77a). A unit normal's error across the surface is a 2-D normal variable of standard
  // deviation s per component, so the angle it makes is Rayleigh(s): median s sqrt(2 ln 2), tail
  // P(theta > t) = exp(-t^2 / (2 s^2)). The limit puts that tail at the distance test's two-sided normal tail
  // erfc(k / sqrt 2), k = distance_in_sigma: t = s sqrt(-2 ln erfc(k / sqrt 2)) (5.06 s at k = 4.6851).
  const auto mid = angles_rad.begin() + static_cast<std::ptrdiff_t>(angles_rad.size() / 2);
  std::nth_element(angles_rad.begin(), mid, angles_rad.end());
  const double scale = *mid / std::sqrt(2.0 * std::log(2.0));
  const double tail = std::erfc(test.distance_in_sigma / std::sqrt(2.0));
  const double limit_deg = scale * std::sqrt(-2.0 * std::log(tail)) / kDegree;
  return std::clamp(limit_deg, test.min_angle_deg, test.max_angle_deg);
}

std::vector<bool> PointsOffTheSurface(const ParametricModel& model, const Eigen::Matrix3Xd& points,
                                      const Eigen::Matrix3Xd& normals, const OffSurfaceTest& test,
                                      double* sigma, Eigen::VectorXd* distances, double* angle_limit_deg) {
  std::string why;
  if (!test.IsValid(&why)) throw std::invalid_argument("points off the surface: " + why);
  std::vector<FootPoint> feet;
  ComputeFootPoints(model, points, feet);
  const Eigen::VectorXd d = FootPointDistances(feet);
  const double s = MadSigma(d);
  if (sigma) *sigma = s;
  if (distances) *distances = d;
  if (angle_limit_deg) *angle_limit_deg = 0.0;
  std::vector<bool> off(static_cast<std::size_t>(points.cols()), false);
  for (Eigen::Index j = 0; j < points.cols(); ++j)
    off[static_cast<std::size_t>(j)] = d[j] > test.distance_in_sigma * s;
  if (normals.cols() != points.cols()) return off;
  // The angle between each in-band point's normal (sign arbitrary) and the surface normal at its foot; NaN
  // where either is degenerate (such a point is judged by its distance alone) and for points already off.
  Eigen::VectorXd angle = Eigen::VectorXd::Constant(points.cols(), std::nan(""));
  std::vector<double> in_band;
  LocalGeometry g;
  for (Eigen::Index j = 0; j < points.cols(); ++j) {
    if (off[static_cast<std::size_t>(j)]) continue;  // already off by its distance
    model.Evaluate(feet[static_cast<std::size_t>(j)].t, 1, g);
    const Eigen::Vector3d surface_normal = To3(g.d1.col(0)).cross(To3(g.d1.col(1)));
    const double norm = surface_normal.norm() * normals.col(j).norm();
    if (!(norm > 0)) continue;
    angle[j] = std::acos(std::min(1.0, std::abs(surface_normal.dot(normals.col(j))) / norm));
    in_band.push_back(angle[j]);
  }
  const double limit_deg = NormalAngleLimitDeg(std::move(in_band), test);
  if (angle_limit_deg) *angle_limit_deg = limit_deg;
  for (Eigen::Index j = 0; j < points.cols(); ++j)
    if (angle[j] > limit_deg * kDegree) off[static_cast<std::size_t>(j)] = true;
  return off;
}

std::vector<KinematicStart> FindKinematicStarts(const Eigen::Matrix3Xd& points,
                                                const Eigen::Matrix3Xd& normals, KinematicKind kind,
                                                const KinematicStartOptions& options) {
  if (points.cols() != normals.cols()) throw std::invalid_argument("one normal per point is needed");
  if (points.cols() < std::max(8, options.num_control))
    throw std::invalid_argument("too few points for a kinematic surface");
  const std::vector<Eigen::Index> idx = SampleIndices(points.cols(), options.max_sample);
  const Eigen::Matrix3Xd p = Columns(points, idx), n = Columns(normals, idx);
  const Eigen::Vector3d centroid = p.rowwise().mean();
  const int m = options.num_control, order = options.order;

  struct Frame {
    Eigen::Vector3d point, direction;
    double value, normals_value;
    std::string source;
  };
  std::vector<Frame> frames;
  if (kind == KinematicKind::kRevolution) {
    for (const AxisCandidate& c : RevolutionAxisCandidates(points, normals, options))
      frames.push_back({c.point, c.direction, 0.0, 0.0, c.source});
  } else {
    Eigen::VectorXd w;
    KinematicAxis axis = RobustKinematicAxisFromNormals(p, n, kind, options.axis_loss, &w);
    if (kind == KinematicKind::kHelical) {
      const Eigen::Vector3d c = axis.direction.normalized();
      const RigidMotion frame(FrameWithAxis(c), axis.point);
      const Eigen::Matrix3Xd local = frame.inverse().apply(p);
      const double centre = options.estimate != 0.0 ? options.estimate : axis.pitch;
      const auto peaks = SpectrumPeaks(centre, 1e-3 * DataSize(p), options,
                                       [&](double pitch) { return HelicalPhaseEntropy(local, pitch); });
      for (std::size_t k = 0; k < peaks.size() && k < static_cast<std::size_t>(2 * options.max_starts); ++k) {
        const Eigen::Vector3d a = HelicalAxisPoint(p, n, w, c, peaks[k].value, centroid);
        frames.push_back({AtMeanHeight(a, c, centroid), c, peaks[k].value, axis.pitch, "pitch spectrum"});
      }
    } else {
      if (axis.growth < 0) {  // the same motion reversed (the pipeline's convention: growing whorls)
        axis.growth = -axis.growth;
        axis.direction = -axis.direction;
      }
      const Eigen::Vector3d c = axis.direction.normalized();
      const SpiralCentreFromNormals centres(p, n, w, c);
      const Eigen::Matrix3d R = FrameWithAxis(c);
      const double centre = options.estimate != 0.0 ? options.estimate : axis.growth;
      const auto peaks = SpectrumPeaks(centre, 1e-3, options, [&](double g) {
        return SpiralPhaseEntropy(RigidMotion(R, centres.Centre(g)).inverse().apply(p), g);
      });
      for (std::size_t k = 0; k < peaks.size() && k < static_cast<std::size_t>(2 * options.max_starts); ++k) {
        const double g = peaks[k].value;
        // Negative growth about c: positive about -c.
        frames.push_back({centres.Centre(g), g > 0 ? c : Eigen::Vector3d(-c), std::abs(g), axis.growth,
                          "growth spectrum"});
      }
    }
  }

  std::vector<KinematicStart> starts;
  for (const Frame& f : frames) {
    KinematicStart s;
    s.world_T_model = RigidMotion(FrameWithAxis(f.direction.normalized()), f.point);
    s.source = f.source;
    s.normals_value = f.normals_value;
    const RigidMotion model_T_world = s.world_T_model.inverse();
    const Eigen::Matrix3Xd local = model_T_world.apply(p), all = model_T_world.apply(points);
    const Eigen::Matrix3Xd local_normals = model_T_world.rotation() * n,
                           all_normals = model_T_world.rotation() * normals;
    // The pitch or growth refined on the sample (the +-20 % search by the initial surface's RMS), from all
    // sample points, then again from those on the surface (eq. 77): a fracture face or a stand must not
    // bend the initial profile. The initial surface itself from all points on the surface (measured on the
    // synthetic shell: a generatrix from 4000 of its 25000 points let the joint fit stop at 1.14 x the
    // noise).
    double value = f.value;
    auto build = [&](const Eigen::Matrix3Xd& q, bool search) -> std::shared_ptr<ParametricModel> {
      if (kind == KinematicKind::kRevolution)
        return std::make_shared<KinematicSurface>(InitialRevolution(q, m, order, options.profile_margin));
      if (kind == KinematicKind::kHelical) {
        auto model = std::make_shared<KinematicSurface>(
            search ? InitialHelicalWithPitchSearch(q, value, m, order) : InitialHelical(q, value, m, order));
        value = model->pitch();
        return model;
      }
      auto model = std::make_shared<SpiralSurface>(search ? InitialSpiralWithGrowthSearch(q, value, m, order)
                                                          : InitialSpiral(q, value, m, order));
      value = model->growth();
      return model;
    };
    auto on_surface = [&](const ParametricModel& model, const Eigen::Matrix3Xd& q,
                          const Eigen::Matrix3Xd& qn) {
      const std::vector<bool> off = PointsOffTheSurface(model, q, qn, options.off_surface);
      std::vector<Eigen::Index> on;
      for (Eigen::Index j = 0; j < q.cols(); ++j)
        if (!off[static_cast<std::size_t>(j)]) on.push_back(j);
      return on;
    };
    try {
      std::shared_ptr<ParametricModel> sampled = build(local, true);
      const std::vector<Eigen::Index> on = on_surface(*sampled, local, local_normals);
      if (static_cast<Eigen::Index>(on.size()) < local.cols() && static_cast<int>(on.size()) > 2 * m)
        sampled = build(Columns(local, on), true);
      const std::vector<Eigen::Index> all_on = on_surface(*sampled, all, all_normals);
      s.model = static_cast<int>(all_on.size()) > 2 * m ? build(Columns(all, all_on), false) : sampled;
    } catch (const std::invalid_argument&) {
      continue;  // a candidate the data cannot carry (e.g. no extent along it)
    }
    s.searched_value = kind == KinematicKind::kRevolution ? 0.0 : value;
    s.off_surface = PointsOffTheSurface(*s.model, all, all_normals, options.off_surface, &s.score);
    starts.push_back(std::move(s));
  }
  if (starts.empty()) throw std::invalid_argument("no initial surface fits the points");
  std::stable_sort(starts.begin(), starts.end(),
                   [](const KinematicStart& a, const KinematicStart& b) { return a.score < b.score; });
  // The best few, and only those within 1.5 times the best robust scale: each costs a joint fit (in the
  // synthetic cases of docs/method.md section 19 the start that won was always the best-scored or within
  // that factor of it; the factor is a cost bound, not a tuned threshold).
  const double best = starts.front().score;
  std::vector<KinematicStart> kept;
  for (KinematicStart& s : starts) {
    if (static_cast<int>(kept.size()) >= options.max_starts || s.score > 1.5 * best) break;
    kept.push_back(std::move(s));
  }
  return kept;
}

double AllPointsObjective(const Eigen::Ref<const Eigen::VectorXd>& distances, double scale) {
  if (distances.size() == 0) return 0.0;
  if (!(scale > 0) || !std::isfinite(scale))
    throw std::invalid_argument("the objective needs a positive scale");
  const double c = TuningConstant(LossKind::kTukey) * scale;
  const double cap = c * c / 3.0;  // rho beyond c (eq. 44)
  double sum = 0.0;
  for (Eigen::Index j = 0; j < distances.size(); ++j)
    sum += EvaluateLoss(LossKind::kTukey, c, distances[j] * distances[j]).rho / cap;  // eq. 79
  return sum / static_cast<double>(distances.size());
}

Eigen::VectorXd PlacedDistances(const ParametricModel& model, const std::vector<Eigen::Matrix3Xd>& scans,
                                const std::vector<RigidMotion>& model_T_scan) {
  Eigen::Index count = 0;
  for (const Eigen::Matrix3Xd& s : scans) count += s.cols();
  Eigen::VectorXd all(count);
  Eigen::Index at = 0;
  std::vector<FootPoint> feet;
  for (std::size_t k = 0; k < scans.size(); ++k) {
    ComputeFootPoints(model, model_T_scan[k].apply(scans[k]), feet);
    all.segment(at, scans[k].cols()) = FootPointDistances(feet);
    at += scans[k].cols();
  }
  return all;
}

double CoveredTurnFraction(const Eigen::Matrix3Xd& points, const Eigen::Vector3d& axis_point,
                           const Eigen::Vector3d& axis_direction) {
  constexpr int kSectors = 72;
  const Eigen::Matrix3d frame = FrameWithAxis(axis_direction.normalized());
  std::vector<double> count(kSectors, 0.0);
  for (Eigen::Index j = 0; j < points.cols(); ++j) {
    const Eigen::Vector3d d = points.col(j) - axis_point;
    const double x = d.dot(frame.col(0)), y = d.dot(frame.col(1));
    if (x == 0.0 && y == 0.0) continue;
    const double turn = (std::atan2(y, x) + M_PI) / (2 * M_PI);  // [0, 1]
    count[static_cast<std::size_t>(std::min(kSectors - 1, static_cast<int>(turn * kSectors)))] += 1.0;
  }
  double occupied = 0.0, total = 0.0;
  for (double c : count)
    if (c > 0) {
      occupied += 1.0;
      total += c;
    }
  if (occupied == 0.0) return 1.0;
  const double floor = 0.1 * total / occupied;
  int kept = 0;
  for (double c : count) kept += c >= floor;
  return static_cast<double>(kept) / kSectors;
}

StartedJointFit FitJointlyFromStarts(const std::vector<KinematicStart>& starts,
                                     const std::vector<Eigen::Matrix3Xd>& scans,
                                     const std::vector<RigidMotion>& world_T_scan,
                                     const std::vector<Eigen::Matrix3Xd>& scan_normals,
                                     const JointFitOptions& options,
                                     const KinematicStartOptions& start_options, double noise) {
  if (starts.empty()) throw std::invalid_argument("no start for the joint fit");
  if (world_T_scan.size() != scans.size()) throw std::invalid_argument("one pose per scan is needed");
  const bool with_normals = scan_normals.size() == scans.size();
  struct Tried {
    std::shared_ptr<ParametricModel> model;
    JointFitResult result;
    std::vector<std::vector<bool>> masks;
    Eigen::VectorXd distances;
    Eigen::Index left_out = 0;
  };
  std::vector<Tried> tried;
  double best_scale = INFINITY;
  for (const KinematicStart& start : starts) {
    std::shared_ptr<ParametricModel> model = start.model->Clone();
    const RigidMotion model_T_world = start.world_T_model.inverse();
    std::vector<RigidMotion> initial;
    for (const RigidMotion& pose : world_T_scan) initial.push_back(model_T_world * pose);
    JointFitOptions o = options;
    // The start's off-surface points, per scan (the merged points are the scans in order), for one view
    // only: views merged at mis-registered poses stand off one another by the pose errors, and the start
    // would leave out whole stretches of a view (measured on the synthetic shell: RMS 1.13 x the noise
    // after 82 iterations instead of the noise).
    std::size_t at = 0;
    o.left_out.assign(scans.size(), {});
    for (std::size_t k = 0; k < scans.size(); ++k) {
      for (Eigen::Index j = 0; j < scans[k].cols(); ++j, ++at)
        o.left_out[k].push_back(scans.size() == 1 && at < start.off_surface.size() && start.off_surface[at]);
    }
    JointFitResult r = FitJointly(*model, scans, initial, o);
    // Decide again at the solution, against the fitted surface and the registered scans.
    auto judge = [&](const JointFitResult& fit, std::vector<std::vector<bool>>& masks, Eigen::VectorXd& all) {
      masks.assign(scans.size(), {});
      std::vector<Eigen::VectorXd> parts;
      Eigen::Index count = 0;
      for (std::size_t k = 0; k < scans.size(); ++k) {
        const Eigen::Matrix3Xd placed = fit.model_T_scan[k].apply(scans[k]);
        const Eigen::Matrix3Xd normals =
            with_normals ? Eigen::Matrix3Xd(fit.model_T_scan[k].rotation() * scan_normals[k])
                         : Eigen::Matrix3Xd();
        Eigen::VectorXd d;
        masks[k] = PointsOffTheSurface(*model, placed, normals, start_options.off_surface, nullptr, &d);
        parts.push_back(d);
        count += placed.cols();
      }
      all.resize(count);
      Eigen::Index pos = 0;
      for (const Eigen::VectorXd& d : parts) {
        all.segment(pos, d.size()) = d;
        pos += d.size();
      }
    };
    std::vector<std::vector<bool>> masks;
    Eigen::VectorXd distances;
    judge(r, masks, distances);
    // A start already far behind the best final fit is not refined further (a second pass moves the robust
    // scale by a few percent, not by half).
    const bool behind = MadSigma(distances) > 1.5 * best_scale;
    if (masks != o.left_out && !behind) {
      o.left_out = masks;
      JointFitResult again = FitJointly(*model, scans, r.model_T_scan, o);
      again.iterations += r.iterations;
      again.shared_iterations += r.shared_iterations;
      r = std::move(again);
      judge(r, masks, distances);
    }
    Tried t;
    for (const auto& mask : o.left_out) t.left_out += std::count(mask.begin(), mask.end(), true);
    best_scale = std::min(best_scale, MadSigma(distances));
    t.model = model;
    t.result = std::move(r);
    t.masks = o.left_out;
    t.distances = std::move(distances);
    tried.push_back(std::move(t));
  }
  StartedJointFit best;
  best.objective_scale = noise > 0 && std::isfinite(noise) ? noise : best_scale;
  if (!(best.objective_scale > 0)) best.objective_scale = 1e-12;  // exact data: every fit at zero
  double best_objective = INFINITY;
  for (std::size_t s = 0; s < tried.size(); ++s) {
    best.final_scores.push_back(MadSigma(tried[s].distances));
    best.final_objectives.push_back(AllPointsObjective(tried[s].distances, best.objective_scale));
    best.left_out_per_start.push_back(tried[s].left_out);
    if (best.final_objectives.back() < best_objective) {
      best_objective = best.final_objectives.back();
      best.chosen = s;
    }
  }
  Tried& chosen = tried[best.chosen];
  best.model = chosen.model;
  best.world_T_model = starts[best.chosen].world_T_model;
  best.result = std::move(chosen.result);
  best.left_out = chosen.left_out;
  best.left_out_masks = std::move(chosen.masks);
  return best;
}

}  // namespace s2m
