#include "fitting/foot_point.h"

#include <Eigen/Dense>
#include <cmath>
#include <optional>

namespace s2m {
namespace {

// Brings t into the domain: wraps periodic directions, clamps open ones.
void Confine(const ParameterDomain& d, ParamT& t) {
  for (int k = 0; k < d.dimension; ++k) {
    const auto i = static_cast<std::size_t>(k);
    if (d.periodic[i]) {
      const double period = d.hi[i] - d.lo[i];
      double u = std::fmod(t[i] - d.lo[i], period);
      if (u < 0) u += period;
      t[i] = d.lo[i] + u;
    } else {
      t[i] = std::clamp(t[i], d.lo[i], d.hi[i]);
    }
  }
}

// Backtracking from t along step (step1 only for surfaces, m = 2): halves until f = |C - X|^2 / 2 (from
// `half_residual2`, which reads `g`) does not increase beyond rounding, or takes the full step when
// `below_rounding`. On success `trial`, `f` and `g` are the accepted point's; otherwise `g` is at t again.
template <typename HalfResidual2>
bool BacktrackingStep(const ParametricModel& model, const ParameterDomain& d, const ParamT& t, double step0,
                      double step1, bool below_rounding, const HalfResidual2& half_residual2, double& f,
                      LocalGeometry& g, ParamT& trial) {
  double alpha = 1.0;
  for (int ls = 0; ls < 30; ++ls, alpha *= 0.5) {
    trial = t;  // keeps t[2] (a part's face index)
    trial[0] += alpha * step0;
    if (d.dimension > 1) trial[1] += alpha * step1;
    Confine(d, trial);
    model.Evaluate(trial, 2, g);
    const double ft = half_residual2();
    // Accept increases at rounding level: near the foot point f stalls before the orthogonality residual
    // does.
    if (below_rounding || ft <= f * (1.0 + 1e-13) + 1e-300) {
      f = ft;
      return true;
    }
  }
  model.Evaluate(t, 2, g);
  return false;
}

// s-vector dot product on raw storage (s = 2 or 3).
double Dot(const double* a, const double* b, int s) {
  double sum = a[0] * b[0] + a[1] * b[1];
  return s > 2 ? sum + a[2] * b[2] : sum;
}

// RefineFootPoint for curves (m = 1; e.g. the generatrix of a surface of revolution's reduced feet): the same
// safeguarded Newton and decisions as the general loop below, in scalars (the general loop's 2 x 2 algebra
// on run-time sized vectors was most of a curve foot's cost outside the model's evaluations).
FootPoint RefineCurveFootPoint(const ParametricModel& model, const ParameterDomain& d, const VecS& x,
                               ParamT t, LocalGeometry& g, bool g_at_t0) {
  Confine(d, t);
  if (!g_at_t0) model.Evaluate(t, 2, g);
  const int s = static_cast<int>(x.size());
  const double lo = d.lo[0], hi = d.hi[0], span = hi - lo;
  const double x_norm = x.norm();
  auto residual_norm2 = [&]() {
    double sum = 0.0;
    for (int i = 0; i < s; ++i) sum += (g.point[i] - x[i]) * (g.point[i] - x[i]);
    return sum;
  };
  double f = 0.5 * residual_norm2();
  for (int iter = 0; iter < 50; ++iter) {
    double r[3] = {0.0, 0.0, 0.0};
    for (int i = 0; i < s; ++i) r[i] = g.point[i] - x[i];
    const double* c1 = g.d1.data();
    const double grad = Dot(c1, r, s), speed2 = Dot(c1, c1, s);
    const double hess = speed2 + Dot(r, g.d2.data(), s);
    // Pinned at an open end with the gradient pushing outwards: the foot (active set).
    if (!d.periodic[0] && ((t[0] <= lo && grad > 0) || (t[0] >= hi && grad < 0))) break;
    const double h00 = hess > 0 ? hess : speed2;  // Newton where convex along t, else Gauss-Newton
    const double step = h00 > 0 ? -grad / h00 : 0.0;
    if (!std::isfinite(step) || step == 0.0) break;
    if (std::abs(step) <= 1e-15 * span) break;
    const double predicted = -0.5 * grad * step;
    const bool below_rounding = predicted <= 1e-15 * std::sqrt(2.0 * f) * (g.point.norm() + x_norm);
    ParamT trial = t;
    if (!BacktrackingStep(
            model, d, t, step, 0.0, below_rounding, [&] { return 0.5 * residual_norm2(); }, f, g, trial))
      break;
    const double moved = std::abs(trial[0] - t[0]);
    t = trial;
    if (moved <= 1e-15 * span) break;
  }
  return {t, std::sqrt(2.0 * f), IsBoundaryFootPoint(d, t, g, x)};
}

}  // namespace

FootPoint RefineFootPoint(const ParametricModel& model, const ParameterDomain& d, const VecS& x, ParamT t,
                          LocalGeometry& g, bool g_at_t0) {
  const int m = d.dimension;
  if (m == 1) return RefineCurveFootPoint(model, d, x, t, g, g_at_t0);
  Confine(d, t);
  if (!g_at_t0) model.Evaluate(t, 2, g);
  VecS r = g.point - x;
  double f = 0.5 * r.squaredNorm();
  const double span = (d.hi[0] - d.lo[0]) + (m > 1 ? d.hi[1] - d.lo[1] : 0.0);
  for (int iter = 0; iter < 50; ++iter) {
    // Gradient C_t^T r and Hessian C_t^T C_t + [r . C_tk tl] of f(t) = |C(t) - X|^2 / 2.
    Eigen::Vector2d grad = Eigen::Vector2d::Zero();
    Eigen::Matrix2d hess = Eigen::Matrix2d::Identity();
    for (int k = 0; k < m; ++k) grad[k] = g.d1.col(k).dot(r);
    if (m == 1) {
      hess(0, 0) = g.d1.col(0).squaredNorm() + r.dot(g.d2.col(0));
    } else {
      hess(0, 0) = g.d1.col(0).squaredNorm() + r.dot(g.d2.col(0));
      hess(0, 1) = hess(1, 0) = g.d1.col(0).dot(g.d1.col(1)) + r.dot(g.d2.col(1));
      hess(1, 1) = g.d1.col(1).squaredNorm() + r.dot(g.d2.col(2));
    }
    // Open boundaries: a parameter pinned at its bound with the gradient pushing outwards is fixed (active
    // set).
    std::array<bool, 2> fixed{false, false};
    for (int k = 0; k < m; ++k) {
      const auto i = static_cast<std::size_t>(k);
      if (d.periodic[i]) continue;
      if ((t[i] <= d.lo[i] && grad[k] > 0) || (t[i] >= d.hi[i] && grad[k] < 0)) fixed[i] = true;
    }
    Eigen::Vector2d step = Eigen::Vector2d::Zero();
    Eigen::Matrix2d h = hess;
    for (int k = 0; k < m; ++k) {
      if (fixed[static_cast<std::size_t>(k)]) {
        h.row(k).setZero();
        h.col(k).setZero();
        h(k, k) = 1.0;
        grad[k] = 0.0;
      }
    }
    if (m == 1) {
      // Newton when the curvature term keeps f convex along t, else Gauss-Newton (always a descent
      // direction).
      const double h00 = h(0, 0) > 0 ? h(0, 0) : g.d1.col(0).squaredNorm();
      step[0] = h00 > 0 ? -grad[0] / h00 : 0.0;
    } else {
      Eigen::Matrix2d hh = h.topLeftCorner(2, 2);
      if (!(hh.determinant() > 0 && hh(0, 0) > 0)) {
        hh(0, 0) = fixed[0] ? 1.0 : g.d1.col(0).squaredNorm();
        hh(1, 1) = fixed[1] ? 1.0 : g.d1.col(1).squaredNorm();
        hh(0, 1) = hh(1, 0) = (fixed[0] || fixed[1]) ? 0.0 : g.d1.col(0).dot(g.d1.col(1));
      }
      step = hh.ldlt().solve(-grad);
    }
    if (!step.allFinite() || step.norm() == 0.0) break;
    // A full step below the stop tolerance (1e-15 of the span: the rounding level of t) would be taken and
    // then end the loop; stop here instead, without the model evaluation that step would cost. `g` and `f`
    // stay those of t, the foot returned.
    if (std::abs(step[0]) + (m > 1 ? std::abs(step[1]) : 0.0) <= 1e-15 * span) break;
    // The decrease of f the quadratic model predicts for the full step (a descent direction), against the
    // rounding of f (|C - X| times the rounding of C - X, ~1e-15 of the coordinates): below it no trial's f
    // can show a decrease, and halving on rounding noise took up to 30 evaluations (a third of the feet of a
    // surface fitted to 1e-4 of its size). The gradient is accurate there: the full step is taken.
    const double predicted = -0.5 * grad.dot(step);
    const bool below_rounding = predicted <= 1e-15 * std::sqrt(2.0 * f) * (g.point.norm() + x.norm());
    // Backtracking: halve until |C - X| decreases (the orthogonality residual may be far from zero).
    ParamT trial = t;
    if (!BacktrackingStep(
            model, d, t, step[0], step[1], below_rounding, [&] { return 0.5 * (g.point - x).squaredNorm(); },
            f, g, trial))
      break;
    const double moved = std::abs(trial[0] - t[0]) + (m > 1 ? std::abs(trial[1] - t[1]) : 0.0);
    t = trial;
    r = g.point - x;
    if (moved <= 1e-15 * span) break;
  }
  return {t, std::sqrt(2.0 * f), IsBoundaryFootPoint(d, t, g, x)};
}

bool IsBoundaryFootPoint(const ParameterDomain& d, const ParamT& t, const LocalGeometry& g, const VecS& x) {
  // On an open boundary the orthogonality condition need not hold: record it for the end rule (docs/method.md
  // section 4).
  const VecS r = g.point - x;
  for (int k = 0; k < d.dimension; ++k) {
    const auto i = static_cast<std::size_t>(k);
    if (!d.periodic[i] && (t[i] <= d.lo[i] || t[i] >= d.hi[i])) {
      const double c = g.d1.col(k).norm() * r.norm();
      if (c > 0 && std::abs(g.d1.col(k).dot(r)) > 1e-9 * c) return true;
    }
  }
  return false;
}

FootPointSeeds::FootPointSeeds(const ParametricModel& model) : params_(model.SampleParameters()) {
  Eigen::Matrix3Xd samples(3, static_cast<Eigen::Index>(params_.size()));
  LocalGeometry g;
  for (std::size_t i = 0; i < params_.size(); ++i) {
    model.Evaluate(params_[i], 0, g);
    samples.col(static_cast<Eigen::Index>(i)) = To3(g.point);
  }
  index_ = NearestIndex(std::move(samples));
}

ParamT FootPointSeeds::Nearest(const VecS& x) const {
  return params_[static_cast<std::size_t>(index_.Nearest(To3(x)))];
}

const FootPointSeeds& LazyFootPointSeeds::get() const {
  std::call_once(once_, [this] { seeds_.emplace(model_); });
  return *seeds_;
}

FootPointContext::FootPointContext(const ParametricModel& m)
    : model(m), domain(m.domain()), seeds(m), reduction(m.MakeFootPointReduction()) {
  ParamT probe{0.0, 0.0, 0.0};
  closed_form = m.ClosedFormFootPoint(VecS::Zero(m.ambient_dimension()), probe);
  if (reduction != nullptr) {
    reduced_domain = reduction->reduced_model().domain();
    reduced_seeds.emplace(reduction->reduced_model());
  }
}

namespace {

// Newton's foot on `model` (no closed form) from the warm start as `mode` says (FootPointOf).
// A foot on an open boundary where the model's sheet continues elsewhere (ParametricModel::
// ContinuationSeed): Newton again from the continuation, the closer foot kept (g at the returned foot).
FootPoint ContinueAcrossBoundary(const ParametricModel& model, const ParameterDomain& domain, const VecS& x,
                                 const FootPoint& foot, LocalGeometry& g) {
  if (!foot.on_boundary) return foot;
  const std::optional<ParamT> seed = model.ContinuationSeed(foot.t);
  if (!seed) return foot;
  const FootPoint other = RefineFootPoint(model, domain, x, *seed, g);
  if (other.distance < foot.distance) return other;
  model.Evaluate(foot.t, 2, g);
  return foot;
}

FootPoint NewtonFoot(const ParametricModel& model, const ParameterDomain& domain,
                     const LazyFootPointSeeds& seeds, const VecS& x, const ParamT* previous, WarmStart mode,
                     LocalGeometry& g, bool g_at_previous) {
  if (previous != nullptr && mode == WarmStart::kTrusted) {
    const FootPoint warm = RefineFootPoint(model, domain, x, *previous, g, g_at_previous);
    if (!warm.on_boundary) return warm;
    const FootPoint cold = RefineFootPoint(model, domain, x, seeds.get().Nearest(x), g);
    if (cold.distance < warm.distance) return ContinueAcrossBoundary(model, domain, x, cold, g);
    model.Evaluate(warm.t, 2, g);  // g at the returned foot
    return ContinueAcrossBoundary(model, domain, x, warm, g);
  }
  ParamT start = seeds.get().Nearest(x);
  if (previous != nullptr) {
    model.Evaluate(start, 0, g);
    const double d_seed = (g.point - x).squaredNorm();
    model.Evaluate(*previous, 0, g);
    if ((g.point - x).squaredNorm() <= d_seed) start = *previous;
  }
  return ContinueAcrossBoundary(model, domain, x, RefineFootPoint(model, domain, x, start, g), g);
}

}  // namespace

FootPoint FootPointOf(const FootPointContext& c, const VecS& x, const ParamT* previous, WarmStart mode,
                      LocalGeometry& g, bool g_at_previous) {
  if (c.closed_form) {
    FootPoint foot;
    c.model.ClosedFormFoot(x, foot.t, foot.distance, foot.on_boundary, foot.excluded);
    return foot;
  }
  VecS reduced_x;
  if (c.reduction != nullptr && c.reduction->Reduce(x, reduced_x)) {
    // The reduced model's t is the leading entries of the full t (FootPointReduction): the previous foot's
    // warm-starts it. Its geometry is lifted, so the full model is not evaluated at all.
    ParamT reduced_previous{0.0, 0.0, 0.0};
    if (previous != nullptr) {
      for (int k = 0; k < c.reduced_domain.dimension; ++k)
        reduced_previous[static_cast<std::size_t>(k)] = (*previous)[static_cast<std::size_t>(k)];
    }
    LocalGeometry reduced_g;
    FootPoint foot = NewtonFoot(c.reduction->reduced_model(), c.reduced_domain, *c.reduced_seeds, reduced_x,
                                previous != nullptr ? &reduced_previous : nullptr, mode, reduced_g, false);
    ParamT t{0.0, 0.0, 0.0};
    if (c.reduction->Lift(x, foot.t, reduced_g, t, g)) {
      foot.t = t;
      return foot;
    }
  }
  return NewtonFoot(c.model, c.domain, c.seeds, x, previous, mode, g, g_at_previous);
}

void ComputeFootPoints(const ParametricModel& model, const Eigen::Ref<const Eigen::MatrixXd>& points,
                       std::vector<FootPoint>& feet, const std::vector<FootPoint>* warm, WarmStart mode) {
  const Eigen::Index n = points.cols();
  feet.resize(static_cast<std::size_t>(n));
  if (n == 0) return;
  const FootPointContext context(model);
#pragma omp parallel
  {
    LocalGeometry g;
#pragma omp for schedule(static)
    for (Eigen::Index j = 0; j < n; ++j) {
      const auto i = static_cast<std::size_t>(j);
      feet[i] = FootPointOf(context, points.col(j), warm != nullptr ? &(*warm)[i].t : nullptr, mode, g);
    }
  }
}

Eigen::VectorXd FootPointDistances(const std::vector<FootPoint>& feet) {
  Eigen::VectorXd d(static_cast<Eigen::Index>(feet.size()));
  for (std::size_t j = 0; j < feet.size(); ++j) d[static_cast<Eigen::Index>(j)] = feet[j].distance;
  return d;
}

}  // namespace s2m
