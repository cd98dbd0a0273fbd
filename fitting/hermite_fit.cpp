#include "fitting/hermite_fit.h"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "fitting/geometric_fit.h"
#include "fitting/initial_models.h"
#include "fitting/linear_solver.h"
#include "fitting/minimizer.h"
#include "fitting/noise_estimate.h"

namespace s2m {
namespace {

using Clock = std::chrono::steady_clock;

// ---- Fang's sliding springs as a problem of the minimizer (docs/fair-curves.md eqs. F14-F16, F28)
// State: the curve (in the unit box) and its exact feet. Cost: 1/2 sum d_j^2 + Q^T K Q. Linearization: the
// gradient 2 K Q - F, F the spring forces (X_j - w(u_j)) resolved over the elements around each attachment
// point (Fang's Method 2); the Hessian 2 K of the fairness, plus (unless `fairness_hessian_only`, Fang's
// eq. 5.1.4 as printed) the sliding springs' own stiffness: a zero-length spring that slides along the
// curve resists only motion across it, sum_j Psi_j n_j n_j^T Psi_j^T (eq. F28). The minimizer's
// Levenberg-Marquardt damping keeps the steps finite where the Hessian is singular (rigid translations with
// the fairness alone) and its acceptance test on the true cost replaces the thesis' undamped step.
// The generalized forces of a unit point load at u on all nodal dofs (per coordinate): the shape functions
// Psi(u) of its element, the exact gradient of 1/2 d^2 at a fixed foot (envelope theorem).
Eigen::VectorXd PointForce(const HermiteCurve& curve, double u) {
  const int per = curve.derivatives_per_node();
  Eigen::VectorXd out = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(curve.num_nodes()) * per);
  double t = 0.0;
  const int e = curve.Locate(u, t);
  const ElementBasis basis = HermiteElementBasis(curve.degree(), curve.knots()[e + 1] - curve.knots()[e]);
  const Eigen::VectorXd phi = ElementDerivativeRow(basis, 0, t);
  for (int l = 0; l < curve.degree() + 1; ++l) out[curve.ElementNode(e, l / per) * per + l % per] += phi[l];
  return out;
}

class SpringProblem : public NonlinearProblem {
 public:
  // geometric_weight > 0: the cost also has geometric_weight integral (dkappa/ds)^2 ds (eq. F30), with its
  // Gauss-Newton model in the Hessian.
  SpringProblem(HermiteCurve curve, const Eigen::MatrixXd& y, double unit, double diagonal_floor,
                bool fairness_hessian_only, double geometric_weight = 0.0, double reference_curvature = 0.0)
      : curve_(std::move(curve)),
        trial_(curve_),
        y_(y),
        unit_(unit),
        fairness_only_(fairness_hessian_only),
        geometric_weight_(geometric_weight),
        reference_curvature_(reference_curvature),
        normal_(diagonal_floor) {
    k_ = curve_.FairnessMatrix({});
    if (k_.size() == 0) k_ = Eigen::MatrixXd::Zero(curve_.num_parameters(), curve_.num_parameters());
    ComputeFootPoints(curve_, y_, feet_);
    cost_ = Objective(curve_, feet_);
  }

  double Cost() const override { return cost_; }

  LinearSystem& Linearize() override {
    const int s = curve_.ambient_dimension();
    const Eigen::Index dofs = curve_.expansion().rows();
    // F per coordinate over all nodal dofs, then onto the independent ones (T^T F).
    Eigen::MatrixXd force = Eigen::MatrixXd::Zero(dofs, s);
    LocalGeometry g;
    for (Eigen::Index j = 0; j < y_.cols(); ++j) {
      const FootPoint& foot = feet_[static_cast<std::size_t>(j)];
      curve_.Evaluate(foot.t, 0, g);
      const Eigen::VectorXd pull = y_.col(j) - Eigen::VectorXd(g.point);
      force += (exact_forces_ ? PointForce(curve_, foot.t[0]) : ResolvedUnitForce(curve_, foot.t[0])) *
               pull.transpose();
    }
    const Eigen::MatrixXd reduced = curve_.expansion().transpose() * force;
    Eigen::VectorXd f(curve_.num_parameters());
    for (Eigen::Index k = 0; k < reduced.rows(); ++k)
      for (int c = 0; c < s; ++c) f[k * s + c] = reduced(k, c);
    normal_.H() = 2.0 * k_;
    normal_.g() = 2.0 * k_ * curve_.parameters() - f;
    if (geometric_weight_ > 0) {
      Eigen::VectorXd r;
      Eigen::MatrixXd j;
      GeometricCurvatureVariation(curve_, r, &j, reference_curvature_);
      normal_.H() += 2.0 * geometric_weight_ * j.transpose() * j;
      normal_.g() += 2.0 * geometric_weight_ * j.transpose() * r;
    }
    if (!fairness_only_) {
      // The springs' stiffness across the curve: (Psi_j^T n_j)(Psi_j^T n_j)^T per point, n_j the unit
      // residual direction (normal to the curve at an interior foot); a point on the curve adds none.
      std::vector<JacobianEntry> entries;
      for (Eigen::Index j = 0; j < y_.cols(); ++j) {
        const FootPoint& foot = feet_[static_cast<std::size_t>(j)];
        curve_.Evaluate(foot.t, 0, g);
        const Eigen::VectorXd r = y_.col(j) - Eigen::VectorXd(g.point);
        const double d = r.norm();
        if (!(d > 0)) continue;
        const Eigen::VectorXd n = r / d;
        curve_.ShapeJacobian(foot.t, false, entries);
        for (const JacobianEntry& a : entries) {
          const double an = a.column.head(s).dot(n);
          if (an == 0.0) continue;
          for (const JacobianEntry& b : entries)
            normal_.H()(a.index, b.index) += an * b.column.head(s).dot(n);
        }
      }
    }
    return normal_;
  }

  double EvaluateTrial(const Eigen::VectorXd& step, bool) override {
    trial_ = curve_;
    trial_.set_parameters(curve_.parameters() + step);
    ComputeFootPoints(trial_, y_, trial_feet_);
    trial_cost_ = Objective(trial_, trial_feet_);
    return std::isfinite(trial_cost_) ? trial_cost_ : std::numeric_limits<double>::infinity();
  }

  void AcceptTrial() override {
    curve_ = trial_;
    feet_.swap(trial_feet_);
    cost_ = trial_cost_;
  }

  double ParameterNorm() const override { return curve_.parameters().norm(); }

  void DescribeState(IterationRecord& record) const override {
    double sum = 0.0;
    record.max_distance = 0.0;
    for (const FootPoint& p : feet_) {
      sum += p.distance * p.distance;
      record.max_distance = std::max(record.max_distance, p.distance * unit_);
    }
    record.rms = std::sqrt(sum / static_cast<double>(y_.cols())) * unit_;
  }

  HermiteCurve& curve() { return curve_; }
  // The finishing stage: the exact generalized forces Psi(u_j) of the point loads instead of the resolved
  // ones (eq. F29).
  void UseExactForces() { exact_forces_ = true; }

 private:
  double Objective(const HermiteCurve& c, const std::vector<FootPoint>& feet) const {
    double f = 0.0;
    for (const FootPoint& p : feet) f += 0.5 * p.distance * p.distance;
    const Eigen::VectorXd q = c.parameters();
    f += q.dot(k_ * q);
    if (geometric_weight_ > 0) {
      Eigen::VectorXd r;
      GeometricCurvatureVariation(c, r, nullptr, reference_curvature_);
      f += geometric_weight_ * r.squaredNorm();
    }
    return f;
  }

  HermiteCurve curve_, trial_;
  const Eigen::MatrixXd& y_;
  double unit_;
  bool fairness_only_;
  double geometric_weight_;
  double reference_curvature_;  // > 0: the curvature-relative form (eq. F34), in the problem's units
  bool exact_forces_ = false;
  Eigen::MatrixXd k_;
  DenseNormalEquations normal_;
  std::vector<FootPoint> feet_, trial_feet_;
  double cost_ = 0.0, trial_cost_ = 0.0;
};

// The reference curvature of the curvature-relative variation (eq. F34): pi / L0, the curvature of a half
// circle as long as the data. The form is the absolute one where the curve is flatter, the variation of
// log kappa where it is much sharper (the choice among 0.1 to 10 times 2 pi / L0 is measured in
// docs/fair-curves.md section 7).
double RelativeVariationCurvature(double reference_length) {
  return M_PI / reference_length;
}

struct OneFit {
  HermiteCurve curve;
  GeometricFitResult fit;
};

// One approximation at fixed elements and weights, from `start`.
OneFit FitOnce(const HermiteCurve& start, const Eigen::MatrixXd& points, const HermiteFairness& weights,
               const HermiteFitOptions& options, double reference_length) {
  HermiteCurve curve = start;
  const bool geometric = options.geometric_variation > 0;
  HermiteFairness own = weights;
  if (geometric) own.alpha3 *= 1.0 - options.geometric_variation;
  curve.set_fairness(own);
  GeometricFitResult fit;
  if (options.method != HermiteMethod::kSpring && !geometric) {
    GeometricFitOptions o;
    o.error_term = options.method == HermiteMethod::kSdm   ? ErrorTerm::kSdm
                   : options.method == HermiteMethod::kTdm ? ErrorTerm::kTdm
                                                           : ErrorTerm::kPdm;
    o.fairness = {};  // the curve's own terms (set_fairness)
    o.optimizer = options.optimizer;
    fit = FitModel(curve, points, o);
    return {curve, fit};
  }
  // The spring method in the unit box (the energy ratio is scale-free: both terms are quadratic in lengths).
  const int s = static_cast<int>(points.rows());
  const VecS offset = points.rowwise().mean();
  const double half = 0.5 * (points.rowwise().maxCoeff() - points.rowwise().minCoeff()).maxCoeff();
  const double scale = half > 0 ? half : 1.0;
  const Eigen::MatrixXd y = (points.colwise() - Eigen::VectorXd(offset)) / scale;
  HermiteCurve unit = curve;
  unit.ApplySimilarity(1.0 / scale, VecS(-offset / scale));
  // The geometric term's weight in the unit box: alpha3 L0^5 with L0 the reference length in its units.
  const double geometric_weight =
      geometric ? weights.alpha3 * options.geometric_variation * std::pow(reference_length / scale, 5) : 0.0;
  const double reference_curvature =
      geometric && options.relative_variation ? RelativeVariationCurvature(reference_length / scale) : 0.0;
  SpringProblem problem(unit, y, scale, options.optimizer.damping.diagonal_floor,
                        options.spring_as_in_thesis && !geometric, geometric_weight, reference_curvature);
  // With the geometric term the closeness is always the exact point forces (eq. F29).
  if (geometric) problem.UseExactForces();
  MinimizerSummary summary = TrustRegionMinimizer(options.optimizer).Minimize(problem);
  if (!geometric && !options.spring_as_in_thesis && summary.iterations < options.optimizer.max_iterations) {
    // Where the resolved forces stop decreasing E, finish with the exact point forces (eq. F29).
    problem.UseExactForces();
    OptimizerOptions rest = options.optimizer;
    rest.max_iterations = options.optimizer.max_iterations - summary.iterations;
    const MinimizerSummary finish = TrustRegionMinimizer(rest).Minimize(problem, summary.iterations);
    summary.iterations += finish.iterations;
    summary.stop_reason = finish.stop_reason;
    summary.history.insert(summary.history.end(), finish.history.begin(), finish.history.end());
  }
  curve = problem.curve();
  curve.ApplySimilarity(scale, offset);
  curve.set_fairness(weights);
  (void)s;
  fit.iterations = summary.iterations;
  fit.stop_reason = summary.stop_reason;
  fit.history = summary.history;
  ComputeFootPoints(curve, points, fit.foot_points);
  fit.residuals = ComputeResidualStatistics(FootPointDistances(fit.foot_points));
  return {curve, fit};
}

HermiteFairness Scaled(const HermiteFairness& f, double k) {
  return {f.alpha1 * k, f.alpha2 * k, f.alpha3 * k, f.beta2 * k, f.beta3 * k};
}

// Mean squared distance of the points whose foot lies on each element, and their count.
void LocalErrors(const HermiteCurve& curve, const std::vector<FootPoint>& feet, std::vector<double>& ms,
                 std::vector<int>& count) {
  ms.assign(static_cast<std::size_t>(curve.num_elements()), 0.0);
  count.assign(ms.size(), 0);
  for (const FootPoint& f : feet) {
    double t = 0.0;
    const auto e = static_cast<std::size_t>(curve.Locate(f.t[0], t));
    ms[e] += f.distance * f.distance;
    ++count[e];
  }
  for (std::size_t e = 0; e < ms.size(); ++e)
    if (count[e] > 0) ms[e] /= count[e];
}

void CheckPoints(const Eigen::MatrixXd& points, const HermiteFitOptions& options) {
  if (points.rows() != 2 && points.rows() != 3)
    throw std::invalid_argument("Hermite curves are fitted to 2D or 3D points");
  if (!points.allFinite()) throw std::invalid_argument("the points contain NaN or inf");
  if (options.interpolate) {
    if (points.cols() < 2) throw std::invalid_argument("an interpolation needs at least 2 points");
    for (Eigen::Index j = 0; j + 1 < points.cols() + (options.closed ? 1 : 0); ++j) {
      const Eigen::Index next = (j + 1) % points.cols();
      if ((points.col(j) - points.col(next)).norm() == 0.0) {
        throw std::invalid_argument(
            "points " + std::to_string(j) + " and " + std::to_string(next) +
            " coincide: an interpolating curve cannot pass twice through one place in "
            "one element (remove the duplicate)");
      }
    }
    if (options.closed && points.cols() < 3)
      throw std::invalid_argument("a closed interpolation needs at least 3 points");
    return;
  }
  // Distinct points: an approximation needs at least 3.
  Eigen::Index distinct = 0;
  for (Eigen::Index j = 0; j < points.cols() && distinct < 3; ++j) {
    bool seen = false;
    for (Eigen::Index k = 0; k < j && !seen; ++k) seen = (points.col(j) - points.col(k)).norm() == 0.0;
    if (!seen) ++distinct;
  }
  if (distinct < 3)
    throw std::invalid_argument("an approximation needs at least 3 distinct points (got " +
                                std::to_string(distinct) + "); use --interpolate for 2");
}

HermiteFitResult Interpolate(const Eigen::MatrixXd& points, const HermiteFitOptions& options) {
  const int s = static_cast<int>(points.rows()), per = (options.degree + 1) / 2;
  const int nodes = static_cast<int>(points.cols());
  const int elements = options.closed ? nodes : nodes - 1;
  Eigen::MatrixXd dofs = Eigen::MatrixXd::Zero(s, nodes * per);
  for (int i = 0; i < nodes; ++i) dofs.col(i * per) = points.col(i);
  // Chord slopes as the start (only for the C2 reduction's end slopes; the solve below replaces them).
  for (int i = 0; i < nodes; ++i) {
    const int a = options.closed ? (i + nodes - 1) % nodes : std::max(i - 1, 0);
    const int b = options.closed ? (i + 1) % nodes : std::min(i + 1, nodes - 1);
    const int steps = options.closed ? 2 : b - a;  // knot steps of 1 / elements between a and b
    dofs.col(i * per + 1) = (points.col(b) - points.col(a)) * elements / steps;
  }
  HermiteCurve curve = HermiteCurve::Uniform(options.degree, elements, dofs, options.closed, options.c2);
  curve.set_fairness(options.fairness);
  // min Q^T K Q over the free dofs (derivatives; positions fixed): K_ff Q_f = -K_fp Q_p, the fixed dofs'
  // rows and columns deleted (Fang section 5.3). The minimum-norm solution where K_ff is singular.
  const Eigen::MatrixXd k = curve.FairnessMatrixOf(options.fairness);
  const Eigen::VectorXd q = curve.parameters();
  std::vector<Eigen::Index> free, fixed;
  for (int p = 0; p < curve.num_parameters(); ++p)
    (curve.parameter_name(p).find("position") != std::string::npos ? fixed : free).push_back(p);
  Eigen::VectorXd result = q;
  if (!free.empty()) {
    const auto nf = static_cast<Eigen::Index>(free.size()), np = static_cast<Eigen::Index>(fixed.size());
    Eigen::MatrixXd kff(nf, nf), kfp(nf, np);
    Eigen::VectorXd qp(np);
    for (Eigen::Index a = 0; a < nf; ++a) {
      for (Eigen::Index b = 0; b < nf; ++b) kff(a, b) = k(free[a], free[b]);
      for (Eigen::Index b = 0; b < np; ++b) kfp(a, b) = k(free[a], fixed[b]);
    }
    for (Eigen::Index b = 0; b < np; ++b) qp[b] = q[fixed[b]];
    const Eigen::VectorXd qf = kff.completeOrthogonalDecomposition().solve(Eigen::VectorXd(-kfp * qp));
    for (Eigen::Index a = 0; a < nf; ++a) result[free[a]] = qf[a];
  }
  curve.set_parameters(result);
  HermiteFitResult out(curve);
  out.weights = options.fairness;
  out.energy = curve.EnergyBreakdown(options.fairness);
  ComputeFootPoints(curve, points, out.foot_points);
  out.residuals = ComputeResidualStatistics(FootPointDistances(out.foot_points));
  out.stop_reason = StopReason::kClosedForm;
  out.fits = 1;
  out.noise = std::numeric_limits<double>::quiet_NaN();
  return out;
}

// Arc length by 5-point Gauss-Legendre on 8 sub-intervals of every element.
double ArcLength(const HermiteCurve& curve) {
  static const double x[5] = {0.0469100770306680, 0.2307653449471585, 0.5, 0.7692346550528415,
                              0.9530899229693320};
  static const double w[5] = {0.1184634425280945, 0.2393143352496832, 0.2844444444444444, 0.2393143352496832,
                              0.1184634425280945};
  const std::vector<double>& k = curve.knots();
  Eigen::MatrixXd jet;
  double length = 0.0;
  for (std::size_t e = 0; e + 1 < k.size(); ++e)
    for (int sub = 0; sub < 8; ++sub) {
      const double a = k[e] + (k[e + 1] - k[e]) * sub / 8.0, b = k[e] + (k[e + 1] - k[e]) * (sub + 1) / 8.0;
      for (int q = 0; q < 5; ++q) {
        curve.EvaluateJet(a + (b - a) * x[q], 1, jet);
        length += w[q] * (b - a) * jet.col(1).norm();
      }
    }
  return length;
}

}  // namespace

double FairnessFractionScale(double fraction, int points, double sigma, double length,
                             const HermiteFairness& mix, double* closeness_reference,
                             double* fairness_reference) {
  // C0 = 1/2 N sigma^2: the closeness of a curve at the noise. F0: the alpha terms of a circle of perimeter
  // L at constant speed on [0, 1], |w^(p)| = L (2 pi)^(p - 1) (the jump terms vanish on it).
  const double two_pi = 2.0 * M_PI;
  const double c0 = 0.5 * points * sigma * sigma;
  const double f0 =
      length * length * (mix.alpha1 + mix.alpha2 * std::pow(two_pi, 2) + mix.alpha3 * std::pow(two_pi, 4));
  if (closeness_reference) *closeness_reference = c0;
  if (fairness_reference) *fairness_reference = f0;
  if (!(c0 > 0) || !(f0 > 0)) throw std::invalid_argument("fairness fraction: zero noise, length or weights");
  return fraction / (1.0 - fraction) * c0 / f0;
}

const char* ToString(HermiteMethod m) {
  switch (m) {
    case HermiteMethod::kSpring:
      return "spring";
    case HermiteMethod::kSdm:
      return "sdm";
    case HermiteMethod::kTdm:
      return "tdm";
    case HermiteMethod::kPdm:
      return "pdm";
  }
  return "?";
}

HermiteMethod HermiteMethodFromString(const std::string& name) {
  if (name == "spring") return HermiteMethod::kSpring;
  if (name == "sdm") return HermiteMethod::kSdm;
  if (name == "tdm") return HermiteMethod::kTdm;
  if (name == "pdm") return HermiteMethod::kPdm;
  throw std::invalid_argument("unknown Hermite fit method '" + name + "' (spring, sdm, tdm or pdm)");
}

bool HermiteFitOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& reason) {
    if (why) *why = reason;
    return false;
  };
  if (degree != 3 && degree != 5) return fail("degree must be 3 or 5");
  if (c2 && degree != 3) return fail("the C2 reduction is for cubic curves (a quintic is C2 already)");
  if (elements < 0) return fail("elements must be positive, or 0 for adaptive");
  if (closed && elements == 1) return fail("a closed curve needs at least 2 elements");
  if (max_elements < 1) return fail("max_elements must be positive");
  for (const double w : {fairness.alpha1, fairness.alpha2, fairness.alpha3, fairness.beta2, fairness.beta3})
    if (!(w >= 0) || !std::isfinite(w)) return fail("fairness weights must be finite and >= 0");
  if (!(tolerance >= 0) || !std::isfinite(tolerance)) return fail("tolerance must be finite and >= 0");
  if (tolerance > 0 && fairness.IsZero()) return fail("a tolerance scales the fairness weights: give one");
  if (interpolate && fairness.IsZero()) return fail("an interpolation minimizes the fairness: give a weight");
  if (interpolate && tolerance > 0) return fail("an interpolation passes through the points: no tolerance");
  if (!(fairness_fraction >= 0 && fairness_fraction < 1))
    return fail("the fairness fraction must be in [0, 1) (0: not used)");
  if (fairness_fraction > 0 && tolerance > 0)
    return fail("give a fairness fraction or a tolerance, not both (each sets the weights' scale)");
  if (fairness_fraction > 0 && interpolate)
    return fail("an interpolation passes through the points: no fairness fraction");
  if (!(geometric_variation >= 0 && geometric_variation < 1))
    return fail("the geometric share of the curvature variation must be in [0, 1) (0: parametric only)");
  if (geometric_variation > 0 && !(fairness.alpha3 > 0))
    return fail("the geometric curvature variation is a share of alpha3: give an alpha3 weight");
  if (geometric_variation > 0 && interpolate)
    return fail("an interpolation minimizes the parametric energy only: no geometric curvature variation");
  if (relative_variation && !(geometric_variation > 0))
    return fail(
        "the curvature-relative variation weighs the geometric share: give a geometric variation > 0");
  if (fairness_fraction > 0 && fairness.alpha1 == 0 && fairness.alpha2 == 0 && fairness.alpha3 == 0)
    return fail("the fairness fraction normalizes the alpha terms: give at least one alpha weight");
  return optimizer.IsValid(why);
}

// Residuals r_q = kappa_s(u_q) sqrt(|w'(u_q)| W_q), so that |r|^2 is integral (dkappa/ds)^2 ds (eq. F30).
// Plane curves: kappa_s = Y / n^2 - 3 X D / n^3 (eq. F20), n = |w'|^2, X = w' x w'', Y = w' x w''',
// D = w' . w''; so r_q = (Y n^(-7/4) - 3 X D n^(-11/4)) sqrt(W_q), differentiated by hand below.
void GeometricCurvatureVariation(const HermiteCurve& curve, Eigen::VectorXd& r, Eigen::MatrixXd* jacobian,
                                 double reference_curvature) {
  static const double x[5] = {0.0469100770306680, 0.2307653449471585, 0.5, 0.7692346550528415,
                              0.9530899229693320};
  static const double w[5] = {0.1184634425280945, 0.2393143352496832, 0.2844444444444444, 0.2393143352496832,
                              0.1184634425280945};
  constexpr int kSub = 8;
  if (curve.ambient_dimension() != 2)
    throw std::invalid_argument("the geometric curvature variation is implemented for plane curves only");
  const int s = curve.ambient_dimension(), per = curve.derivatives_per_node(), n_fun = curve.degree() + 1;
  const int elements = curve.num_elements();
  const std::vector<double>& k = curve.knots();
  r.resize(static_cast<Eigen::Index>(elements) * kSub * 5);
  if (jacobian) *jacobian = Eigen::MatrixXd::Zero(r.size(), curve.num_parameters());
  const Eigen::MatrixXd& values = curve.nodal_values();
  const Eigen::MatrixXd& expansion = curve.expansion();
  Eigen::Index row = 0;
  for (int e = 0; e < elements; ++e) {
    const double h = k[e + 1] - k[e];
    const ElementBasis basis = HermiteElementBasis(curve.degree(), h);
    std::vector<int> global(static_cast<std::size_t>(n_fun));
    Eigen::MatrixXd local(s, n_fun);
    for (int l = 0; l < n_fun; ++l) {
      global[l] = curve.ElementNode(e, l / per) * per + l % per;
      local.col(l) = values.col(global[l]);
    }
    for (int sub = 0; sub < kSub; ++sub) {
      for (int q = 0; q < 5; ++q, ++row) {
        const double t = (sub + x[q]) / kSub, weight = w[q] * h / kSub;
        const Eigen::VectorXd p1 = ElementDerivativeRow(basis, 1, t), p2 = ElementDerivativeRow(basis, 2, t),
                              p3 = ElementDerivativeRow(basis, 3, t);
        const Eigen::Vector2d a = local * p1, b = local * p2, c = local * p3;
        const double n = a.squaredNorm(), cross_ab = a.x() * b.y() - a.y() * b.x(),
                     cross_ac = a.x() * c.y() - a.y() * c.x(), dot_ab = a.dot(b);
        const double root = std::sqrt(weight), n74 = std::pow(n, -1.75), n114 = std::pow(n, -2.75);
        const double f = cross_ac * n74 - 3.0 * cross_ab * dot_ab * n114;
        // The curvature-relative form (eq. F34): f m with m = (1 + (kappa / kappa_r)^2)^(-1/2).
        double m = 1.0, kappa = 0.0;
        if (reference_curvature > 0) {
          kappa = cross_ab * std::pow(n, -1.5);
          const double ratio = kappa / reference_curvature;
          m = 1.0 / std::sqrt(1.0 + ratio * ratio);
        }
        r[row] = root * f * m;
        if (!jacobian) continue;
        // Partial derivatives of r_q / sqrt(W_q) with respect to w', w'', w''' at u_q.
        const Eigen::Vector2d dx_da(b.y(), -b.x()), dx_db(-a.y(), a.x()), dy_da(c.y(), -c.x()),
            dy_dc(-a.y(), a.x());
        Eigen::Vector2d df_da = dy_da * n74 - 3.5 * cross_ac * n114 * a -
                                3.0 * n114 * (dx_da * dot_ab + cross_ab * b) +
                                16.5 * cross_ab * dot_ab * std::pow(n, -3.75) * a;
        Eigen::Vector2d df_db = -3.0 * n114 * (dx_db * dot_ab + cross_ab * a);
        Eigen::Vector2d df_dc = dy_dc * n74;
        if (reference_curvature > 0) {
          // d(f m) = m df + f dm/dkappa dkappa, dm/dkappa = -kappa m^3 / kappa_r^2, kappa = X n^(-3/2).
          const double f_dm = -f * kappa * m * m * m / (reference_curvature * reference_curvature);
          const double n15 = std::pow(n, -1.5);
          const Eigen::Vector2d dk_da = dx_da * n15 - 3.0 * cross_ab * std::pow(n, -2.5) * a,
                                dk_db = dx_db * n15;
          df_da = m * df_da + f_dm * dk_da;
          df_db = m * df_db + f_dm * dk_db;
          df_dc *= m;
        }
        // Onto the nodal dofs (per coordinate), then the independent parameters (index * s + coordinate).
        for (int l = 0; l < n_fun; ++l) {
          const Eigen::Vector2d g = root * (df_da * p1[l] + df_db * p2[l] + df_dc * p3[l]);
          for (Eigen::Index i = 0; i < expansion.cols(); ++i) {
            const double t_li = expansion(global[l], i);
            if (t_li == 0.0) continue;
            for (int cc = 0; cc < 2; ++cc) (*jacobian)(row, i * s + cc) += g[cc] * t_li;
          }
        }
      }
    }
  }
}

Eigen::VectorXd LinearLoadVector(int degree, double h, double q_a, double q_b) {
  const ElementBasis basis = HermiteElementBasis(degree, h);
  // F_k = h integral_0^1 phi_k(t) (q_a (1 - t) + q_b t) dt, term by term of phi_k's power coefficients.
  Eigen::VectorXd out = Eigen::VectorXd::Zero(degree + 1);
  for (int j = 0; j <= degree; ++j) {
    const double m0 = 1.0 / (j + 1), m1 = 1.0 / (j + 2);  // integral t^j, t^(j+1)
    out += basis.coefficients.col(j) * h * (q_a * (m0 - m1) + q_b * m1);
  }
  return out;
}

Eigen::VectorXd ResolvedUnitForce(const HermiteCurve& curve, double u) {
  const int per = curve.derivatives_per_node(), n = curve.degree() + 1, e_count = curve.num_elements();
  Eigen::VectorXd out = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(curve.num_nodes()) * per);
  double t = 0.0;
  const int e = curve.Locate(u, t);
  const std::vector<double>& k = curve.knots();
  auto h_of = [&](int element) { return k[element + 1] - k[element]; };
  auto add = [&](int element, double q_a, double q_b) {
    const Eigen::VectorXd f = LinearLoadVector(curve.degree(), h_of(element), q_a, q_b);
    for (int l = 0; l < n; ++l) out[curve.ElementNode(element, l / per) * per + l % per] += f[l];
  };
  const double hi = h_of(e), u0 = t * hi;
  const bool neighbours = curve.closed() ? e_count >= 2 : (e > 0 && e + 1 < e_count);
  if (!neighbours) {
    // Method 1 (Fang eq. 5.1.9a): the host element alone.
    add(e, (4.0 - 6.0 * t) / hi, (6.0 * t - 2.0) / hi);
    return out;
  }
  const int prev = (e + e_count - 1) % e_count, next = (e + 1) % e_count;
  const double hp = h_of(prev), hn = h_of(next), total = hp + hi + hn;
  // Method 2 (eq. 5.1.9b): 0 -> p_a over the previous element, p_a -> p_b over the host, p_b -> 0 over the
  // next; total force 1 applied at u0 (measured from the host's first node).
  const double p_a = (2.0 * hn + 4.0 * hi - 6.0 * u0) / ((hp + hi) * total);
  const double p_b = (6.0 * u0 + 2.0 * hp - 2.0 * hi) / ((hi + hn) * total);
  add(prev, 0.0, p_a);
  add(e, p_a, p_b);
  add(next, p_b, 0.0);
  return out;
}

HermiteCurve InitialHermiteCurve(const Eigen::MatrixXd& points, int degree, int elements, bool closed,
                                 bool c2) {
  const int s = static_cast<int>(points.rows());
  // A B-spline chain through the data (in their best plane for space curves), then its nodal values.
  const int control =
      std::max(degree + 3, std::min<int>(2 * elements + 4, static_cast<int>(points.cols()) / 2));
  const int order = 4;
  Eigen::MatrixXd plane_basis = Eigen::MatrixXd::Identity(s, 2);
  Eigen::VectorXd centre = Eigen::VectorXd::Zero(s);
  Eigen::Matrix2Xd flat;
  if (s == 2) {
    flat = points;
  } else {
    centre = points.rowwise().mean();
    const Eigen::MatrixXd centred = points.colwise() - centre;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(centred * centred.transpose());
    plane_basis.col(0) = eig.eigenvectors().col(2);
    plane_basis.col(1) = eig.eigenvectors().col(1);
    flat = plane_basis.transpose() * centred;
  }
  const BSplineCurve chain = InitialCurveFromQuadtree(flat, std::max(control, order + 2), order, closed);
  const double lo = chain.basis().lo(), hi = chain.basis().hi(), span = hi - lo;
  const int per = (degree + 1) / 2, nodes = closed ? elements : elements + 1;
  Eigen::MatrixXd dofs(s, nodes * per);
  LocalGeometry g;
  for (int i = 0; i < nodes; ++i) {
    chain.Evaluate({lo + span * i / elements, 0.0, 0.0}, 2, g);
    dofs.col(i * per) = plane_basis * Eigen::Vector2d(g.point) + centre;
    dofs.col(i * per + 1) = plane_basis * Eigen::Vector2d(g.d1.col(0)) * span;
    if (per == 3) dofs.col(i * per + 2) = plane_basis * Eigen::Vector2d(g.d2.col(0)) * span * span;
  }
  return HermiteCurve::Uniform(degree, elements, dofs, closed, c2);
}

HermiteFitResult FitHermiteCurve(const Eigen::MatrixXd& points, const HermiteFitOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument("Hermite fit options: " + why);
  CheckPoints(points, options);
  const auto start = Clock::now();
  if (options.interpolate) {
    HermiteFitResult r = Interpolate(points, options);
    r.seconds = std::chrono::duration<double>(Clock::now() - start).count();
    return r;
  }
  const bool adaptive = options.elements == 0;
  const double noise = EstimateCurveNoise(points).sigma;
  // Adaptive elements aim at the tolerance, or at the data's own noise (the RMS a right model leaves).
  const double target = options.tolerance > 0 ? options.tolerance : noise;
  int elements = adaptive ? (options.closed ? 3 : 2) : options.elements;
  HermiteCurve curve = InitialHermiteCurve(points, options.degree, elements, options.closed, options.c2);
  HermiteFitResult result(curve);
  result.noise = noise;
  // The weights of the fits: as given, or scaled by the fairness fraction's factor (eq. F27).
  HermiteFairness base = options.fairness;
  double scale = 1.0;
  if (options.fairness_fraction > 0) {
    HermiteFitResult::Fraction& f = result.fraction;
    f.fraction = options.fairness_fraction;
    // The data's length: the initial chain sampled with at least 16 elements (the fit's own curve, once
    // found, has nearly the same length; the reference must not depend on the result).
    f.length = ArcLength(
        elements >= 16 ? curve : InitialHermiteCurve(points, options.degree, 16, options.closed, false));
    // The noise estimate, floored at 1e-6 of the length (noise-free data: the floor of double-precision
    // coordinates' resolution at that scale, not a smoothing).
    if (!std::isfinite(noise))
      throw std::invalid_argument(
          "the fairness fraction needs the data's noise estimate, which needs more points along the curve; "
          "give --tolerance or the raw weights");
    f.sigma = std::max(noise, 1e-6 * f.length);
    scale = FairnessFractionScale(f.fraction, static_cast<int>(points.cols()), f.sigma, f.length,
                                  options.fairness, &f.closeness_reference, &f.fairness_reference);
    base = Scaled(options.fairness, scale);
  }
  // The geometric curvature variation's reference length (eq. F30): the initial chain's, sampled with at
  // least 16 elements (fixed for the whole fit, so that the energy stays alpha3 times a fixed scale).
  double reference_length = 0.0;
  if (options.geometric_variation > 0) {
    if (points.rows() != 2)
      throw std::invalid_argument("the geometric curvature variation is implemented for plane curves only");
    reference_length = ArcLength(
        elements >= 16 ? curve : InitialHermiteCurve(points, options.degree, 16, options.closed, false));
  }
  int fits = 0, total_iterations = 0;
  auto run = [&](const HermiteCurve& from, const HermiteFairness& w) {
    OneFit f = FitOnce(from, points, w, options, reference_length);
    ++fits;
    total_iterations += f.fit.iterations;
    return f;
  };
  if (options.geometric_variation > 0) {
    // The geometric term does not depend on the parametrization and is not defined where the speed
    // vanishes: started from an initial chain whose speed nearly does somewhere (a near-cusp), its
    // Gauss-Newton model stays there. The parametric energy alone regularizes the speed first (one fit at
    // the same weights), and the geometric fit starts from that curve (docs/fair-curves.md section 5).
    HermiteFitOptions parametric = options;
    parametric.geometric_variation = 0.0;
    const OneFit regular = FitOnce(curve, points, base, parametric, 0.0);
    curve = regular.curve;
    ++fits;
    total_iterations += regular.fit.iterations;
  }
  OneFit best = run(curve, base);
  if (adaptive && std::isfinite(target)) {
    // Split every element whose points' mean squared distance exceeds the target's square by more than its
    // chi-square spread at 3 sigma (n points: sigma^2 (1 + 3 sqrt(2 / n))), until none does.
    while (best.curve.num_elements() < options.max_elements) {
      std::vector<double> ms;
      std::vector<int> count;
      LocalErrors(best.curve, best.fit.foot_points, ms, count);
      std::vector<int> split;
      for (std::size_t e = 0; e < ms.size(); ++e) {
        if (count[e] == 0) continue;
        if (ms[e] > target * target * (1.0 + 3.0 * std::sqrt(2.0 / count[e])))
          split.push_back(static_cast<int>(e));
      }
      if (split.empty()) break;
      const int room = options.max_elements - best.curve.num_elements();
      if (static_cast<int>(split.size()) > room) {
        std::sort(split.begin(), split.end(), [&](int a, int b) { return ms[a] > ms[b]; });
        split.resize(static_cast<std::size_t>(room));
      }
      best = run(best.curve.Refined(split), base);
    }
  } else if (adaptive) {
    result.note = "the data's noise could not be estimated (too few points along the curve): " +
                  std::to_string(elements) + " elements kept; give --elements or --tolerance";
  }
  if (options.tolerance > 0) {
    // The one factor k on all weights with RMS(k) = tolerance: the fairest curve within it. RMS grows with k;
    // bracket by factors of 10, then bisect log k to 1 % of the tolerance.
    const double tol = options.tolerance;
    auto rms_of = [](const OneFit& f) { return f.fit.residuals.rms; };
    double lo = 0.0, hi = 0.0;
    OneFit at_lo = best;
    if (rms_of(best) <= tol) {
      lo = 1.0;
      double k = 1.0;
      while (k < 1e12) {
        k *= 10.0;
        OneFit f = run(at_lo.curve, Scaled(options.fairness, k));
        if (rms_of(f) > tol) {
          hi = k;
          break;
        }
        lo = k;
        at_lo = std::move(f);
      }
    } else {
      hi = 1.0;
      double k = 1.0;
      while (k > 1e-12) {
        k /= 10.0;
        OneFit f = run(best.curve, Scaled(options.fairness, k));
        if (rms_of(f) <= tol) {
          lo = k;
          at_lo = std::move(f);
          break;
        }
        hi = k;
      }
    }
    if (lo == 0.0) {
      result.tolerance_met = false;
      result.note = "the tolerance " + std::to_string(tol) + " is below what " +
                    std::to_string(best.curve.num_elements()) +
                    " elements reach with any fairness weight (add elements or use --elements auto)";
      scale = 1.0;
    } else {
      if (hi > 0.0) {
        for (int it = 0; it < 30 && std::abs(rms_of(at_lo) - tol) > 0.01 * tol; ++it) {
          const double k = std::sqrt(lo * hi);
          OneFit f = run(at_lo.curve, Scaled(options.fairness, k));
          if (rms_of(f) <= tol) {
            lo = k;
            at_lo = std::move(f);
          } else {
            hi = k;
          }
          if (hi / lo < 1.0001) break;
        }
      }
      scale = lo;
      best = std::move(at_lo);
    }
  }
  result.curve = best.curve;
  result.weights = Scaled(options.fairness, scale);
  result.weight_scale = scale;
  result.curve.set_fairness(result.weights);
  if (options.geometric_variation > 0) {
    // The parametric (1 - g) share of alpha3 and the geometric g share along the arc (eq. F30).
    HermiteFairness parametric = result.weights;
    parametric.alpha3 *= 1.0 - options.geometric_variation;
    result.energy = result.curve.EnergyBreakdown(parametric);
    Eigen::VectorXd r;
    GeometricCurvatureVariation(
        result.curve, r, nullptr,
        options.relative_variation ? RelativeVariationCurvature(reference_length) : 0.0);
    result.geometric_energy =
        result.weights.alpha3 * options.geometric_variation * std::pow(reference_length, 5) * r.squaredNorm();
  } else {
    result.energy = result.curve.EnergyBreakdown(result.weights);
  }
  result.foot_points = best.fit.foot_points;
  result.residuals = best.fit.residuals;
  result.closeness = 0.0;
  for (const FootPoint& f : result.foot_points) result.closeness += 0.5 * f.distance * f.distance;
  if (options.fairness_fraction > 0) {
    const HermiteFairness& e = result.energy;
    result.fraction.closeness = result.closeness / result.fraction.closeness_reference;
    result.fraction.fairness =
        (e.alpha1 + e.alpha2 + e.alpha3 + e.beta2 + e.beta3 + result.geometric_energy) /
        (scale * result.fraction.fairness_reference);
  }
  result.iterations = best.fit.iterations;
  result.stop_reason = best.fit.stop_reason;
  result.history = best.fit.history;
  result.fits = fits;
  result.total_iterations = total_iterations;
  result.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  return result;
}

}  // namespace s2m
