#include "fitting/model_complexity.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "fitting/bspline_models.h"
#include "fitting/foot_point.h"
#include "fitting/kinematic_surfaces.h"

namespace s2m {
namespace {

// The knots strictly inside the domain (clamped: the interior knots with their multiplicities; periodic:
// the breakpoints between lo and hi).
std::vector<double> InteriorKnots(const BSplineBasis& b) {
  const std::vector<double>& k = b.knots();
  if (b.periodic()) return {k.begin() + 1, k.end() - 1};
  return {k.begin() + b.order(), k.begin() + b.num_control()};
}

// Rows of the basis functions at parameter t: row(i) = B_i(t).
Eigen::RowVectorXd BasisRow(const BSplineBasis& b, double t) {
  BSplineBasis::Values v;
  b.Evaluate(t, 0, v);
  Eigen::RowVectorXd row = Eigen::RowVectorXd::Zero(b.num_control());
  for (int i = 0; i < b.order(); ++i)
    row[b.ControlIndex(v.first, i)] += v.values[0][static_cast<std::size_t>(i)];
  return row;
}

// The direction a generatrix runs in, from its first sample to its last (a vessel's profile: height; a
// thread's arch-shaped flank profile: along the axis, where the curve's principal axis may lie across).
Eigen::Vector2d PrincipalDirection(const Eigen::Matrix2Xd& samples) {
  const Eigen::Vector2d chord = samples.col(samples.cols() - 1) - samples.col(0);
  return chord.norm() > 0 ? Eigen::Vector2d(chord.normalized()) : Eigen::Vector2d::UnitY();
}

}  // namespace

BasisRefinement RefineBasis(const BSplineBasis& basis, const std::vector<double>& insert, double lo,
                            double hi) {
  const bool trim = std::isfinite(lo) || std::isfinite(hi);
  if (trim && basis.periodic()) throw std::invalid_argument("a periodic basis cannot be trimmed");
  if (!std::isfinite(lo)) lo = basis.lo();
  if (!std::isfinite(hi)) hi = basis.hi();
  if (!(lo >= basis.lo() && hi <= basis.hi() && lo < hi))
    throw std::invalid_argument("the trimmed domain must be a non-empty part of the old one");
  std::vector<double> interior;
  for (double k : InteriorKnots(basis))
    if (k > lo && k < hi) interior.push_back(k);
  for (double k : insert) {
    if (!(k > lo && k < hi)) throw std::invalid_argument("a knot to insert lies outside the domain");
    interior.push_back(k);
  }
  std::sort(interior.begin(), interior.end());
  const int order = basis.order();
  BasisRefinement out;
  out.lo = lo;
  if (basis.periodic()) {
    const int n = static_cast<int>(interior.size()) + 1;  // breakpoints n + 1
    out.scale = n / (hi - lo);
    std::vector<double> breakpoints{0.0};
    for (double k : interior) breakpoints.push_back(out.Map(k));
    breakpoints.push_back(n);
    out.basis = BSplineBasis::Periodic(order, std::move(breakpoints));
  } else {
    const int n = static_cast<int>(interior.size()) + order;
    const double length = n - order + 1;
    out.scale = length / (hi - lo);
    std::vector<double> knots(static_cast<std::size_t>(order), 0.0);
    for (double k : interior) knots.push_back(out.Map(k));
    for (int i = 0; i < order; ++i) knots.push_back(length);
    out.basis = BSplineBasis::Clamped(order, std::move(knots));
  }
  // The old spline on [lo, hi] lies in the new space (Boehm 1980; Piegl & Tiller, eq. 5.11): its
  // coefficients solve the collocation B_new T = B_old exactly, here at order + 1 points per new span.
  const std::vector<double> spans = out.basis.Breakpoints();
  const int per_span = order + 1;
  const auto rows = static_cast<Eigen::Index>((spans.size() - 1) * static_cast<std::size_t>(per_span));
  Eigen::MatrixXd b_new = Eigen::MatrixXd::Zero(rows, out.basis.num_control());
  Eigen::MatrixXd b_old = Eigen::MatrixXd::Zero(rows, basis.num_control());
  Eigen::Index r = 0;
  for (std::size_t s = 0; s + 1 < spans.size(); ++s) {
    for (int i = 0; i < per_span; ++i, ++r) {
      const double w = spans[s] + (spans[s + 1] - spans[s]) * (i + 0.5) / per_span;
      b_new.row(r) = BasisRow(out.basis, w);
      b_old.row(r) = BasisRow(basis, lo + w / out.scale);
    }
  }
  out.transform = b_new.colPivHouseholderQr().solve(b_old);
  const double error = (b_new * out.transform - b_old).cwiseAbs().maxCoeff();
  if (!(error < 1e-8)) throw std::logic_error("knot refinement does not reproduce the spline");
  return out;
}

SpanResiduals ResidualsPerSpan(const BSplineBasis& basis, const std::vector<double>& parameters,
                               const std::vector<double>& squared_residuals) {
  SpanResiduals out;
  out.breakpoints = basis.Breakpoints();
  const std::size_t spans = out.breakpoints.size() - 1;
  out.sum_squares.assign(spans, 0.0);
  out.points.assign(spans, 0);
  for (std::size_t j = 0; j < parameters.size(); ++j) {
    const double t = basis.Normalize(parameters[j]);
    auto it = std::upper_bound(out.breakpoints.begin(), out.breakpoints.end(), t);
    std::size_t s =
        it == out.breakpoints.begin() ? 0 : static_cast<std::size_t>(it - out.breakpoints.begin()) - 1;
    s = std::min(s, spans - 1);
    out.sum_squares[s] += squared_residuals[j];
    ++out.points[s];
  }
  return out;
}

double InformationCriterion(double sum_squares, double points, int parameters) {
  return points * std::log(std::max(sum_squares, 1e-300) / points) + parameters * std::log(points);
}

double NormalQuantile(double p) {
  // Acklam's algorithm: rational approximations in the centre and the tails.
  static const double a[] = {-3.969683028665376e+01, 2.209460984245205e+02,  -2.759285104469687e+02,
                             1.383577518672690e+02,  -3.066479806614716e+01, 2.506628277459239e+00};
  static const double b[] = {-5.447609879822406e+01, 1.615858368580409e+02, -1.556989798598866e+02,
                             6.680131188771972e+01, -1.328068155288572e+01};
  static const double c[] = {-7.784894002430293e-03, -3.223964580411365e-01, -2.400758277161838e+00,
                             -2.549732539343734e+00, 4.374664141464968e+00,  2.938163982698783e+00};
  static const double d[] = {7.784695709041462e-03, 3.224671290700398e-01, 2.445134137142996e+00,
                             3.754408661907416e+00};
  if (!(p > 0 && p < 1)) throw std::invalid_argument("a normal quantile needs 0 < p < 1");
  const double low = 0.02425;
  if (p < low) {
    const double q = std::sqrt(-2 * std::log(p));
    return (((((c[0] * q + c[1]) * q + c[2]) * q + c[3]) * q + c[4]) * q + c[5]) /
           ((((d[0] * q + d[1]) * q + d[2]) * q + d[3]) * q + 1);
  }
  if (p > 1 - low) return -NormalQuantile(1 - p);
  const double q = p - 0.5, r = q * q;
  return (((((a[0] * r + a[1]) * r + a[2]) * r + a[3]) * r + a[4]) * r + a[5]) * q /
         (((((b[0] * r + b[1]) * r + b[2]) * r + b[3]) * r + b[4]) * r + 1);
}

double FQuantile(double alpha, double d1, double d2) {
  // Paulson (1942): (1 - a2) y - (1 - a1) is about normal with variance a1 + a2 y^2 for y = F^(1/3),
  // a_i = 2 / (9 d_i); the quantile is the larger root of the squared equation.
  const double z = NormalQuantile(1 - alpha);
  const double a1 = 2 / (9 * d1), a2 = std::isfinite(d2) ? 2 / (9 * d2) : 0.0;
  const double A = (1 - a2) * (1 - a2) - z * z * a2, B = -2 * (1 - a1) * (1 - a2),
               C = (1 - a1) * (1 - a1) - z * z * a1;
  const double disc = std::max(B * B - 4 * A * C, 0.0);
  const double y = (-B + std::sqrt(disc)) / (2 * A);
  return y * y * y;
}

namespace {

constexpr double kCriterionTie = 2.0;

ComplexityStep MakeStep(const RefinableFit::Outcome& r, const RefinableFit& fit, const ComplexityOptions& o) {
  ComplexityStep s;
  s.control_points = fit.ControlPoints();
  s.parameters = r.shape_parameters;
  s.points = r.points;
  s.sum_squares = r.sum_squares;
  s.rms = std::sqrt(r.sum_squares / std::max(r.points, 1.0));
  s.bic = InformationCriterion(r.sum_squares, r.points, r.shape_parameters);
  s.iterations = r.iterations;
  s.valid = r.valid;
  const double dof = r.points - r.shape_parameters - r.other_parameters;
  if (std::isfinite(o.noise) && o.noise > 0 && dof > 0) {
    // Eq. 50: s^2 = SS / (n - p) against sigma^2 F_(1-alpha)(n - p, nu); as an RMS over all n points.
    const double f = FQuantile(o.significance, dof, o.noise_dof);
    s.band_rms = o.noise * std::sqrt(f * dof / r.points);
    s.adequate = s.rms <= s.band_rms;
  }
  return s;
}

}  // namespace

ComplexityChoice ChooseComplexity(RefinableFit& fit, const ComplexityOptions& o) {
  ComplexityChoice out;
  double best = std::numeric_limits<double>::infinity();
  std::optional<bool> best_adequate;  // of the valid step with the lowest criterion so far
  int without_gain = 0;
  for (;;) {
    const RefinableFit::Outcome r = fit.Fit();
    fit.Keep(out.steps.size());
    out.steps.push_back(MakeStep(r, fit, o));
    const ComplexityStep& step = out.steps.back();
    if (step.valid && step.bic < best) {
      best = step.bic;
      best_adequate = step.adequate;
      without_gain = 0;
    } else {
      ++without_gain;
    }
    // The patience depends on whether the best model so far is adequate (or the noise unknown).
    const bool adequate = best_adequate.value_or(true);
    if (without_gain >= (adequate ? o.patience_adequate : o.patience_inadequate)) {
      out.stop_reason = "patience";  // worded below, from the chosen step
      break;
    }
    if (!fit.Refine()) {
      out.stop_reason = "largest number of control points reached";
      break;
    }
  }
  // The lowest criterion among the adequate steps, else among all.
  bool any_adequate = false, any_valid = false;
  for (const ComplexityStep& s : out.steps) {
    any_adequate |= s.valid && s.adequate.value_or(false);
    any_valid |= s.valid;
  }
  auto eligible = [&](const ComplexityStep& s) {
    return (!any_valid || s.valid) && (!any_adequate || s.adequate.value_or(false));
  };
  double lowest = std::numeric_limits<double>::infinity();
  for (const ComplexityStep& s : out.steps)
    if (eligible(s)) lowest = std::min(lowest, s.bic);
  // Criteria within 2 of the lowest are a tie (Kass & Raftery 1995: "not worth more than a bare mention"):
  // the larger count, the smaller bias, wins it. Steps are in increasing count.
  for (std::size_t i = 0; i < out.steps.size(); ++i)
    if (eligible(out.steps[i]) && out.steps[i].bic <= lowest + kCriterionTie) out.chosen = i;
  if (out.stop_reason == "patience") {
    const std::optional<bool>& a = out.steps[out.chosen].adequate;
    out.stop_reason = !a   ? "further knots do not lower the criterion"
                      : *a ? "adequate, and further knots do not lower the criterion"
                           : "not adequate, and further knots do not lower the criterion";
  }
  fit.Restore(out.chosen);
  return out;
}

ComplexityChoice FitFixedComplexity(RefinableFit& fit, const ComplexityOptions& o, int refine_to) {
  ComplexityChoice out;
  out.mode = "fixed";
  if (refine_to > 0 && std::stoi(fit.ControlPoints()) < refine_to) {
    fit.Fit();
    while (std::stoi(fit.ControlPoints()) < refine_to && fit.Refine()) {
    }
  }
  out.steps.push_back(MakeStep(fit.Fit(), fit, o));
  out.stop_reason = "control points given";
  return out;
}

// ---------------------------------------------------------------------------------------------------------
// B-spline curves and surfaces.

RefinableSplineFit::RefinableSplineFit(ParametricModel& model, const Eigen::MatrixXd& points,
                                       GeometricFitOptions options, int max_control_points)
    : model_(model), points_(points), options_(std::move(options)), max_control_points_(max_control_points) {
  if (!dynamic_cast<BSplineCurve*>(&model) && !dynamic_cast<BSplineSurface*>(&model))
    throw std::invalid_argument("automatic complexity needs a B-spline curve or surface");
}

namespace {

RefinableFit::Outcome OutcomeOf(const Eigen::VectorXd& distances, const Eigen::VectorXd& weights,
                                int shape_parameters, int iterations) {
  RefinableFit::Outcome r;
  const bool weighted = weights.size() == distances.size();
  for (Eigen::Index j = 0; j < distances.size(); ++j) {
    const double w = weighted ? weights[j] : 1.0;
    r.sum_squares += w * distances[j] * distances[j];
    r.points += w;
  }
  r.shape_parameters = shape_parameters;
  r.iterations = iterations;
  return r;
}

}  // namespace

RefinableFit::Outcome RefinableSplineFit::Fit() {
  result_ = FitModel(model_, points_, options_);
  total_iterations_ += result_.iterations;
  return OutcomeOf(FootPointDistances(result_.foot_points), result_.weights, model_.num_parameters(),
                   result_.iterations);
}

std::string RefinableSplineFit::ControlPoints() const {
  if (const auto* c = dynamic_cast<const BSplineCurve*>(&model_))
    return std::to_string(c->basis().num_control());
  const auto& s = dynamic_cast<const BSplineSurface&>(model_);
  return std::to_string(s.basis_u().num_control()) + "x" + std::to_string(s.basis_v().num_control());
}

bool RefinableSplineFit::Refine() {
  const std::size_t n = result_.foot_points.size();
  std::vector<double> d2(n), u(n), v(n);
  for (std::size_t j = 0; j < n; ++j) {
    const FootPoint& f = result_.foot_points[j];
    const double w = result_.weights.size() == static_cast<Eigen::Index>(n)
                         ? result_.weights[static_cast<Eigen::Index>(j)]
                         : 1.0;
    d2[j] = w * f.distance * f.distance;
    u[j] = f.t[0];
    v[j] = f.t[1];
  }
  // The span with the largest sum of squared residuals gets a knot at its middle (eq. 69); a surface compares
  // the strips of u- and v-spans by that sum per control point the insertion adds.
  auto best_span = [&](const BSplineBasis& b, const std::vector<double>& t, double& value) {
    const SpanResiduals s = ResidualsPerSpan(b, t, d2);
    int best = -1;
    value = -1;
    for (std::size_t i = 0; i < s.sum_squares.size(); ++i) {
      if (s.points[i] == 0 || s.sum_squares[i] <= value) continue;
      value = s.sum_squares[i];
      best = static_cast<int>(i);
    }
    return best < 0 ? std::numeric_limits<double>::quiet_NaN()
                    : 0.5 * (s.breakpoints[static_cast<std::size_t>(best)] +
                             s.breakpoints[static_cast<std::size_t>(best) + 1]);
  };
  if (auto* c = dynamic_cast<BSplineCurve*>(&model_)) {
    if (c->basis().num_control() >= max_control_points_) return false;
    double value = 0;
    const double knot = best_span(c->basis(), u, value);
    if (!std::isfinite(knot)) return false;
    const BasisRefinement r = RefineBasis(c->basis(), {knot});
    model_.CopyFrom(BSplineCurve(r.basis, c->control_points() * r.transform.transpose()));
    return true;
  }
  auto& s = dynamic_cast<BSplineSurface&>(model_);
  const int nu = s.basis_u().num_control(), nv = s.basis_v().num_control();
  double value_u = -1, value_v = -1;
  const double knot_u = nu < max_control_points_ ? best_span(s.basis_u(), u, value_u) : std::nan("");
  const double knot_v = nv < max_control_points_ ? best_span(s.basis_v(), v, value_v) : std::nan("");
  const bool in_u = std::isfinite(knot_u) && (!std::isfinite(knot_v) || value_u / nv >= value_v / nu);
  if (!in_u && !std::isfinite(knot_v)) return false;
  // Tensor product: refine the rows (u) or the columns (v) of the control grid, index i * nv + j.
  const BasisRefinement r = RefineBasis(in_u ? s.basis_u() : s.basis_v(), {in_u ? knot_u : knot_v});
  const Eigen::Matrix3Xd& p = s.control_points();
  const int nu2 = in_u ? r.basis.num_control() : nu, nv2 = in_u ? nv : r.basis.num_control();
  Eigen::Matrix3Xd q = Eigen::Matrix3Xd::Zero(3, nu2 * nv2);
  for (int i2 = 0; i2 < nu2; ++i2)
    for (int j2 = 0; j2 < nv2; ++j2)
      for (int k = 0; k < (in_u ? nu : nv); ++k) {
        const double w = r.transform(in_u ? i2 : j2, k);
        if (w != 0.0) q.col(i2 * nv2 + j2) += w * p.col(in_u ? k * nv + j2 : i2 * nv + k);
      }
  model_.CopyFrom(BSplineSurface(in_u ? r.basis : s.basis_u(), in_u ? s.basis_v() : r.basis, q));
  return true;
}

void RefinableSplineFit::Keep(std::size_t index) {
  kept_.resize(std::max(kept_.size(), index + 1));
  kept_[index] = {model_.Clone(), result_};
}

void RefinableSplineFit::Restore(std::size_t index) {
  model_.CopyFrom(*kept_.at(index).first);
  result_ = kept_[index].second;
}

// ---------------------------------------------------------------------------------------------------------
// Generatrices of kinematic and spiral surfaces.

const BSplineBasis* GeneratrixBasis(const ParametricModel& model) {
  if (const auto* k = dynamic_cast<const KinematicSurface*>(&model)) return &k->basis();
  if (const auto* s = dynamic_cast<const SpiralSurface*>(&model)) return &s->basis();
  return nullptr;
}

const Eigen::Matrix2Xd* GeneratrixProfile(const ParametricModel& model) {
  if (const auto* k = dynamic_cast<const KinematicSurface*>(&model)) return &k->profile();
  if (const auto* s = dynamic_cast<const SpiralSurface*>(&model)) return &s->profile();
  return nullptr;
}

std::unique_ptr<ParametricModel> WithGeneratrix(const ParametricModel& model, BSplineBasis basis,
                                                Eigen::Matrix2Xd profile) {
  if (const auto* k = dynamic_cast<const KinematicSurface*>(&model)) {
    if (!k->helical())
      return std::make_unique<KinematicSurface>(
          KinematicSurface::Revolution(std::move(basis), std::move(profile)));
    const double turns = k->domain().hi[1] / M_PI;
    return std::make_unique<KinematicSurface>(
        KinematicSurface::Helical(std::move(basis), std::move(profile), k->pitch(), turns));
  }
  if (const auto* s = dynamic_cast<const SpiralSurface*>(&model)) {
    return std::make_unique<SpiralSurface>(s->WithGeneratrix(std::move(basis), std::move(profile)));
  }
  throw std::invalid_argument("not a surface with a generatrix: " + model.name());
}

RefinableGeneratrixFit::RefinableGeneratrixFit(ParametricModel& model,
                                               const std::vector<Eigen::Matrix3Xd>& scans,
                                               std::vector<RigidMotion> model_T_scan, JointFitOptions options,
                                               int max_control_points)
    : model_(model),
      scans_(scans),
      model_T_scan_(std::move(model_T_scan)),
      options_(std::move(options)),
      max_control_points_(max_control_points) {
  if (!GeneratrixBasis(model))
    throw std::invalid_argument("not a surface with a generatrix: " + model.name());
}

void RefinableGeneratrixFit::ComputeFeet() {
  // The points the fit uses: those options_.left_out leaves out (off the surface, docs/method.md eq. 77)
  // count neither in the criterion nor in the end rule.
  used_per_scan_.assign(scans_.size(), 0);
  Eigen::Index total = 0;
  for (std::size_t k = 0; k < scans_.size(); ++k) {
    const bool masked = k < options_.left_out.size() && !options_.left_out[k].empty();
    for (Eigen::Index j = 0; j < scans_[k].cols(); ++j)
      if (!masked || !options_.left_out[k][static_cast<std::size_t>(j)]) ++used_per_scan_[k];
    total += used_per_scan_[k];
  }
  Eigen::Matrix3Xd registered(3, total);
  Eigen::Index at = 0;
  for (std::size_t k = 0; k < scans_.size(); ++k) {
    const bool masked = k < options_.left_out.size() && !options_.left_out[k].empty();
    const Eigen::Matrix3Xd placed = model_T_scan_[k].apply(scans_[k]);
    for (Eigen::Index j = 0; j < placed.cols(); ++j)
      if (!masked || !options_.left_out[k][static_cast<std::size_t>(j)]) registered.col(at++) = placed.col(j);
  }
  std::vector<FootPoint> feet;
  ComputeFootPoints(model_, registered, feet);
  feet_u_.resize(feet.size());
  feet_d2_.resize(feet.size());
  for (std::size_t j = 0; j < feet.size(); ++j) {
    feet_u_[j] = feet[j].t[0];
    feet_d2_[j] = feet[j].excluded ? 0.0 : feet[j].distance * feet[j].distance;
  }
}

Eigen::MatrixXd RefinableGeneratrixFit::InsertKnotAtLargestResidual() {
  const BSplineBasis& basis = *GeneratrixBasis(model_);
  const SpanResiduals s = ResidualsPerSpan(basis, feet_u_, feet_d2_);
  int best = -1;
  for (std::size_t i = 0; i < s.sum_squares.size(); ++i)
    if (s.points[i] > 0 && (best < 0 || s.sum_squares[i] > s.sum_squares[static_cast<std::size_t>(best)]))
      best = static_cast<int>(i);
  if (best < 0) throw std::invalid_argument("no knot span holds data");
  const auto b = static_cast<std::size_t>(best);
  const BasisRefinement r = RefineBasis(basis, {0.5 * (s.breakpoints[b] + s.breakpoints[b + 1])});
  model_.CopyFrom(*WithGeneratrix(model_, r.basis, *GeneratrixProfile(model_) * r.transform.transpose()));
  for (double& u : feet_u_) u = r.Map(u);
  return r.transform;
}

std::array<double, 2> GeneratrixEndRuleSpan(const BSplineBasis& basis, const Eigen::Matrix2Xd& profile,
                                            std::vector<double> feet_u, double tolerance) {
  // Eq. 52: keep the generatrix on [u_lo, u_hi], the parameters of the data's feet, and within that span
  // cut it where it turns back along its principal direction by more than the tolerance (a fold: the end
  // span doubling back along the surface, or curling off it as a lip), unless that would drop more than a
  // quarter of its length (a profile that truly turns back).
  if (feet_u.empty()) return {basis.lo(), basis.hi()};
  std::sort(feet_u.begin(), feet_u.end());
  double lo = feet_u.front(), hi = feet_u.back();
  const double median = feet_u[feet_u.size() / 2];
  const int samples = 400;
  Eigen::Matrix2Xd c(2, samples + 1);
  std::vector<double> us(samples + 1);
  BSplineBasis::Values v;
  for (int i = 0; i <= samples; ++i) {
    us[static_cast<std::size_t>(i)] = lo + (hi - lo) * i / samples;
    basis.Evaluate(us[static_cast<std::size_t>(i)], 0, v);
    Eigen::Vector2d p = Eigen::Vector2d::Zero();
    for (int k = 0; k < basis.order(); ++k)
      p += v.values[0][static_cast<std::size_t>(k)] * profile.col(basis.ControlIndex(v.first, k));
    c.col(i) = p;
  }
  const Eigen::Vector2d d = PrincipalDirection(c);
  const Eigen::VectorXd s = d.transpose() * c;
  const int mid = static_cast<int>(std::lround((median - lo) / std::max(hi - lo, 1e-300) * samples));
  const double sign = s[samples] >= s[0] ? 1.0 : -1.0;
  // Walking outwards from the median foot: the first sample after which the curve falls back by more than
  // the tolerance below the running extreme.
  auto find_fold = [&](int from, int step) {
    double extreme = sign * step * s[from];
    int at_extreme = from;
    for (int i = from; i >= 0 && i <= samples; i += step) {
      const double value = sign * step * s[i];
      if (value > extreme) {
        extreme = value;
        at_extreme = i;
      } else if (extreme - value > tolerance) {
        return at_extreme;
      }
    }
    return -1;
  };
  const int fold_hi = find_fold(mid, +1), fold_lo = find_fold(mid, -1);
  auto arc = [&](int a, int b) {
    double l = 0;
    for (int i = a; i < b; ++i) l += (c.col(i + 1) - c.col(i)).norm();
    return l;
  };
  const double length = arc(0, samples);
  if (fold_hi >= 0 && arc(fold_hi, samples) < 0.25 * length) hi = us[static_cast<std::size_t>(fold_hi)];
  if (fold_lo >= 0 && arc(0, fold_lo) < 0.25 * length) lo = us[static_cast<std::size_t>(fold_lo)];
  return {lo, hi};
}

bool RefinableGeneratrixFit::ApplyEndRule(Eigen::MatrixXd* transform, double tolerance_in_rms) {
  const BSplineBasis& basis = *GeneratrixBasis(model_);
  const Eigen::Matrix2Xd& profile = *GeneratrixProfile(model_);
  if (feet_u_.empty()) return false;
  const std::array<double, 2> kept = GeneratrixEndRuleSpan(
      basis, profile, feet_u_, tolerance_in_rms * std::max(result_.residuals.rms, 1e-12));
  const double lo = kept[0], hi = kept[1];
  // Trim only what is more than a hundredth of a span off (feet reach the ends of a well-fitted model).
  const double span = (basis.hi() - basis.lo()) / std::max(1, basis.num_control() - basis.order() + 1);
  const bool trim_lo = lo > basis.lo() + 1e-2 * span, trim_hi = hi < basis.hi() - 1e-2 * span;
  if (!trim_lo && !trim_hi) return false;
  const int count = basis.num_control();
  const BasisRefinement r = RefineBasis(basis, {}, trim_lo ? lo : basis.lo(), trim_hi ? hi : basis.hi());
  model_.CopyFrom(*WithGeneratrix(model_, r.basis, profile * r.transform.transpose()));
  for (double& u : feet_u_) u = std::clamp(r.Map(u), r.basis.lo(), r.basis.hi());
  ++end_rule_cuts_;
  Eigen::MatrixXd total = r.transform;
  // Keep the count: a trimmed-off span's control point goes back where the residuals are largest.
  while (GeneratrixBasis(model_)->num_control() < count) total = InsertKnotAtLargestResidual() * total;
  if (transform) *transform = total;
  return true;
}

RefinableFit::Outcome RefinableGeneratrixFit::Fit() {
  // Refits start from the last poses with per-view motions (their shared stage is over).
  result_ = FitJointly(model_, scans_, model_T_scan_, options_);
  model_T_scan_ = result_.model_T_scan;
  options_.shared_motion_iterations = 0;
  total_iterations_ += result_.iterations;
  int iterations = result_.iterations;
  ComputeFeet();
  if (ApplyEndRule()) {
    result_ = FitJointly(model_, scans_, model_T_scan_, options_);
    model_T_scan_ = result_.model_T_scan;
    total_iterations_ += result_.iterations;
    iterations += result_.iterations;
    ComputeFeet();
    // Noisy data can make a free end fold back again in the refit (two sheets fit the noise band better
    // than one): then the fold is cut and the fit kept as it is on the main branch.
    Eigen::MatrixXd transform;
    if (ApplyEndRule(&transform)) {
      ComputeFeet();
      UpdateResultAfterCut(transform);
    }
  }
  Outcome r;
  for (double d2 : feet_d2_) r.sum_squares += d2;
  r.points = static_cast<double>(feet_d2_.size());
  r.shape_parameters = model_.num_parameters();
  r.other_parameters = 6 * static_cast<int>(scans_.size());
  r.iterations = iterations;
  r.valid = !Folded();
  return r;
}

void RefinableGeneratrixFit::UpdateResultAfterCut(const Eigen::MatrixXd& transform) {
  // Residuals of the feet on the cut generatrix, overall and per scan.
  std::size_t at = 0;
  double total = 0.0, largest = 0.0;
  for (std::size_t k = 0; k < scans_.size(); ++k) {
    double sum = 0.0, max_abs = 0.0;
    const auto n = static_cast<std::size_t>(used_per_scan_[k]);
    for (std::size_t j = 0; j < n; ++j, ++at) {
      sum += feet_d2_[at];
      max_abs = std::max(max_abs, std::sqrt(feet_d2_[at]));
    }
    if (k < result_.per_scan.size()) {
      result_.per_scan[k].rms = std::sqrt(sum / std::max<double>(1.0, static_cast<double>(n)));
      result_.per_scan[k].max_abs = max_abs;
    }
    total += sum;
    largest = std::max(largest, max_abs);
  }
  result_.residuals.rms = std::sqrt(total / std::max<double>(1.0, static_cast<double>(at)));
  result_.residuals.max_abs = largest;
  // The covariance of the profile's coordinates (r_k, z_k interleaved) maps by the same transform per
  // coordinate; a trailing pitch or growth stays.
  if (result_.shape_covariance.size() == 0) return;
  const Eigen::Index old_profile = 2 * transform.cols(),
                     extra = result_.shape_covariance.rows() - old_profile;
  Eigen::MatrixXd map = Eigen::MatrixXd::Zero(2 * transform.rows() + extra, old_profile + extra);
  for (Eigen::Index i = 0; i < transform.rows(); ++i)
    for (Eigen::Index k = 0; k < transform.cols(); ++k)
      for (int c = 0; c < 2; ++c) map(2 * i + c, 2 * k + c) = transform(i, k);
  map.bottomRightCorner(extra, extra).setIdentity();
  result_.shape_covariance = map * result_.shape_covariance * map.transpose();
  result_.shape_uncertainty = result_.shape_covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
}

bool RefinableGeneratrixFit::Folded() const {
  const BSplineBasis& basis = *GeneratrixBasis(model_);
  const Eigen::Matrix2Xd& profile = *GeneratrixProfile(model_);
  const int samples = 400;
  Eigen::Matrix2Xd c(2, samples + 1);
  BSplineBasis::Values v;
  for (int i = 0; i <= samples; ++i) {
    basis.Evaluate(basis.lo() + (basis.hi() - basis.lo()) * i / samples, 0, v);
    c.col(i).setZero();
    for (int k = 0; k < basis.order(); ++k)
      c.col(i) += v.values[0][static_cast<std::size_t>(k)] * profile.col(basis.ControlIndex(v.first, k));
  }
  const Eigen::VectorXd s = PrincipalDirection(c).transpose() * c;
  const double sign = s[samples] >= s[0] ? 1.0 : -1.0;
  const double tolerance = 0.1 * std::max(result_.residuals.rms, 1e-12);
  double extreme = sign * s[0];
  for (int i = 1; i <= samples; ++i) {
    extreme = std::max(extreme, sign * s[i]);
    if (extreme - sign * s[i] > tolerance) return true;
  }
  return false;
}

std::string RefinableGeneratrixFit::ControlPoints() const {
  return std::to_string(GeneratrixBasis(model_)->num_control());
}

bool RefinableGeneratrixFit::Refine() {
  if (GeneratrixBasis(model_)->num_control() >= max_control_points_) return false;
  InsertKnotAtLargestResidual();
  return true;
}

void RefinableGeneratrixFit::Keep(std::size_t index) {
  kept_.resize(std::max(kept_.size(), index + 1));
  kept_[index] = {model_.Clone(), result_, model_T_scan_};
}

void RefinableGeneratrixFit::Restore(std::size_t index) {
  KeptState& s = kept_.at(index);
  model_.CopyFrom(*s.model);
  result_ = s.result;
  model_T_scan_ = s.poses;
  ComputeFeet();
}

}  // namespace s2m
