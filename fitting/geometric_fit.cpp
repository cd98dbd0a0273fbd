#include "fitting/geometric_fit.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>

#include "fitting/enum_names.h"
#include "fitting/minimizer.h"
#include "fitting/parallel_reduction.h"
#include "fitting/robust_loss.h"

namespace s2m {
namespace {

using Clock = std::chrono::steady_clock;

// CDM's squared weight; near a curvature centre (delta*kappa -> 1) the denominator becomes -(1 + |delta
// kappa|), the rule docs/method.md gives for CDM and GN.
double CdmWeight(double delta, double kappa) {
  const double dk = delta * kappa;
  double denom = dk - 1.0;
  if (std::abs(denom) < 1e-3) denom = -(1.0 + std::abs(dk));
  const double w = dk / denom;
  return w * w;
}

struct Normalization {
  VecS offset;
  double scale = 1.0;
};

// Assembles H = sum J^T M J and g = sum C_P^T M r over all points (in parallel), docs/method.md sections 1-2.
// `weights` (empty: all 1) are the robust loss's IRLS weights rho'(d_j^2) (docs/method.md eq. 46).
void Assemble(const ParametricModel& model, const Eigen::MatrixXd& y, const std::vector<FootPoint>& feet,
              const GeometricFitOptions& options, const Eigen::VectorXd& weights, Eigen::MatrixXd& H,
              Eigen::VectorXd& g) {
  const int r = model.num_parameters();
  const int s = model.ambient_dimension();
  const Eigen::Index n = y.cols();
  H.setZero(r, r);
  g.setZero(r);
  const bool gn = options.error_term == ErrorTerm::kGn;
  // Per-thread partial normal equations and scratch (parallel_reduction.h), added in thread order.
  struct Partial {
    Eigen::MatrixXd h;
    Eigen::VectorXd g;
  };
  struct Scratch {
    LocalGeometry geo;
    std::vector<JacobianEntry> entries;
    std::vector<Eigen::Vector3d> columns;
  };
  std::vector<Partial> partials;
  AccumulateInParallel<Scratch>(
      n, partials,
      [r](Partial& p) {
        p.h.setZero(r, r);
        p.g.setZero(r);
      },
      [&](Eigen::Index j, Scratch& scratch, Partial& mine) {
        LocalGeometry& geo = scratch.geo;
        std::vector<JacobianEntry>& entries = scratch.entries;
        std::vector<Eigen::Vector3d>& columns = scratch.columns;
        Eigen::MatrixXd& h_local = mine.h;
        Eigen::VectorXd& g_local = mine.g;
        const FootPoint& foot = feet[static_cast<std::size_t>(j)];
        const VecS x = y.col(j);
        model.Evaluate(foot.t, 2, geo);
        model.ShapeJacobian(foot.t, gn, entries);
        const Eigen::Vector3d residual = To3(geo.point - x);  // r = s - X
        const int m = static_cast<int>(geo.d1.cols());
        Eigen::Matrix3d M;
        columns.resize(entries.size());
        for (std::size_t a = 0; a < entries.size(); ++a) columns[a] = entries[a].column;
        if (foot.on_boundary && options.open_end_rule) {
          M = EndRuleMatrix(gn ? ErrorTerm::kSdm : options.error_term, ComputePrincipalFrame(geo, x),
                            -residual, s);
        } else if (gn) {
          // Full Jacobian C_P - C_t G^-1 Q, G = C_t^T C_t + [r . C_tk tl], Q_k = C_tk^T C_P + r^T
          // dC_P/dt_k.
          Eigen::Matrix2d G = Eigen::Matrix2d::Identity();
          const Eigen::Vector3d c0 = To3(geo.d1.col(0));
          const Eigen::Vector3d c1 = m > 1 ? To3(geo.d1.col(1)) : Eigen::Vector3d::Zero();
          G(0, 0) = c0.squaredNorm() + residual.dot(To3(geo.d2.col(0)));
          if (m > 1) {
            G(0, 1) = G(1, 0) = c0.dot(c1) + residual.dot(To3(geo.d2.col(1)));
            G(1, 1) = c1.squaredNorm() + residual.dot(To3(geo.d2.col(2)));
          }
          const double det = m == 1 ? G(0, 0) : G.determinant();
          if (std::abs(det) > 1e-14 * std::pow(c0.squaredNorm() + c1.squaredNorm(), m)) {
            const Eigen::Matrix2d Ginv = m == 1 ? Eigen::Matrix2d(Eigen::Matrix2d::Identity() / G(0, 0))
                                                : Eigen::Matrix2d(G.inverse());
            for (std::size_t a = 0; a < entries.size(); ++a) {
              Eigen::Vector2d q = Eigen::Vector2d::Zero();
              q[0] = c0.dot(entries[a].column) + residual.dot(entries[a].dcolumn_dt[0]);
              if (m > 1) q[1] = c1.dot(entries[a].column) + residual.dot(entries[a].dcolumn_dt[1]);
              const Eigen::Vector2d w = Ginv * q;
              columns[a] = entries[a].column - c0 * w[0] -
                           (m > 1 ? Eigen::Vector3d(c1 * w[1]) : Eigen::Vector3d::Zero());
            }
          }
          M.setZero();
          M.topLeftCorner(s, s).setIdentity();
        } else {
          M = ErrorMatrix(options.error_term, ComputePrincipalFrame(geo, x), s);
        }
        if (weights.size() > 0) M *= weights[j];
        const double w_gn = weights.size() > 0 ? weights[j] : 1.0;
        const Eigen::Vector3d m_residual = M * residual;
        for (std::size_t a = 0; a < entries.size(); ++a) {
          const Eigen::Vector3d m_col = M * columns[a];
          // The right-hand side is always C_P^T (M r) with the plain C_P (docs/method.md section 2).
          g_local[entries[a].index] += gn && !foot.on_boundary ? w_gn * entries[a].column.dot(residual)
                                                               : entries[a].column.dot(m_residual);
          for (std::size_t b = 0; b < entries.size(); ++b)
            h_local(entries[b].index, entries[a].index) += columns[b].dot(m_col);
        }
      });
  for (const Partial& p : partials) {
    H += p.h;
    g += p.g;
  }
}

// LDLT with diagonal pivoting reveals the rank of a positive semidefinite matrix: tiny trailing pivots.
bool IsSingular(const Eigen::LDLT<Eigen::MatrixXd>& ldlt) {
  if (ldlt.info() != Eigen::Success) return true;
  const Eigen::VectorXd d = ldlt.vectorD().cwiseAbs();
  return !(d.minCoeff() > 1e-13 * d.maxCoeff());
}

// When H is singular, tells apart harmless null directions from harmful ones. Moving control points along the
// model (re-parametrization, e.g. sliding along a straight segment or a flat patch) changes no distance and
// may stay free. A null direction that moves model points across the normal space, which the
// full-normal-space (GTDM) matrix sees, is a shape change the error term cannot observe: that is reported,
// naming the parameters it moves most.
std::optional<std::string> UnobservableShape(const ParametricModel& model, const Eigen::MatrixXd& y,
                                             const std::vector<FootPoint>& feet,
                                             const GeometricFitOptions& options, const Eigen::MatrixXd& H,
                                             const Eigen::MatrixXd& K) {
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(H);
  const Eigen::VectorXd values = eig.eigenvalues();
  const double top = std::max(values.cwiseAbs().maxCoeff(), 1e-300);
  GeometricFitOptions normal_space = options;
  normal_space.error_term = ErrorTerm::kGtdm;
  Eigen::MatrixXd Hn;
  Eigen::VectorXd unused;
  Assemble(model, y, feet, normal_space, Eigen::VectorXd(), Hn, unused);
  if (K.size() > 0) Hn += 2.0 * K;
  const double top_n = std::max(Hn.diagonal().cwiseAbs().maxCoeff(), 1e-300);
  Eigen::VectorXd weight = Eigen::VectorXd::Zero(H.rows());
  int count = 0;
  for (Eigen::Index k = 0; k < values.size(); ++k) {
    if (values[k] > 1e-12 * top) continue;
    const Eigen::VectorXd v = eig.eigenvectors().col(k);
    if (v.dot(Hn * v) <= 1e-8 * top_n) continue;  // re-parametrization only
    ++count;
    weight += v.cwiseAbs2();
  }
  if (count == 0) return std::nullopt;
  std::vector<Eigen::Index> order(static_cast<std::size_t>(H.rows()));
  for (Eigen::Index i = 0; i < H.rows(); ++i) order[static_cast<std::size_t>(i)] = i;
  std::sort(order.begin(), order.end(),
            [&](Eigen::Index a, Eigen::Index b) { return weight[a] > weight[b]; });
  std::ostringstream names;
  for (std::size_t i = 0; i < std::min<std::size_t>(order.size(), 4); ++i) {
    if (weight[order[i]] < 1e-6) break;
    names << (i ? ", " : "") << model.parameter_name(static_cast<int>(order[i]));
  }
  const bool curve_in_space = model.domain().dimension == 1 && model.ambient_dimension() == 3;
  return std::string("the ") + ToString(options.error_term) + " normal matrix of the " + model.name() +
         " is singular: " + std::to_string(count) + " shape direction(s) it cannot observe, mostly " +
         names.str() +
         (options.error_term == ErrorTerm::kTdm && curve_in_space
              ? ". Plain TDM constrains only the direction towards each data point, which leaves a curve in "
                "3D free "
                "to tilt out of planar data; use gtdm or sdm"
              : ". Add fairness or data that cover the whole model");
}

}  // namespace

Eigen::Matrix3d ErrorMatrix(ErrorTerm term, const PrincipalFrame& f, int s) {
  // Only the parts a term needs are formed: the field's registration pass calls this once per point.
  auto identity = [s] {
    Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
    m.topLeftCorner(s, s).setIdentity();
    return m;
  };
  auto normal_space = [&f] {
    Eigen::Matrix3d m = f.normals[0] * f.normals[0].transpose();
    if (f.normal_count > 1) m.noalias() += f.normals[1] * f.normals[1].transpose();
    return m;
  };
  switch (term) {
    case ErrorTerm::kPdm:
      return identity();
    case ErrorTerm::kTdm:
      return f.normals[0] * f.normals[0].transpose();
    case ErrorTerm::kGtdm:
      return normal_space();
    case ErrorTerm::kSdm:
    case ErrorTerm::kCdm: {
      Eigen::Matrix3d m = normal_space();
      for (int k = 0; k < f.tangent_count; ++k) {
        const auto i = static_cast<std::size_t>(k);
        const double w = term == ErrorTerm::kSdm ? SdmWeight(f.delta, f.curvatures[i])
                                                 : CdmWeight(f.delta, f.curvatures[i]);
        if (w != 0.0) m.noalias() += w * f.tangents[i] * f.tangents[i].transpose();
      }
      return m;
    }
    case ErrorTerm::kGn:
      return identity();  // GN builds its own Jacobian; M is used only for boundary points
  }
  return identity();
}

Eigen::Matrix3d EndRuleMatrix(ErrorTerm term, const PrincipalFrame& f, const Eigen::Vector3d& offset, int s) {
  // docs/method.md section 4: e_outer = cos(theta) e_PD + (1 - cos(theta)) e_term, theta between the
  // boundary's tangent space and X - s.
  double tangential = 0.0;
  for (int k = 0; k < f.tangent_count; ++k)
    tangential += std::pow(f.tangents[static_cast<std::size_t>(k)].dot(offset), 2);
  const double cos_theta = offset.norm() > 0 ? std::sqrt(tangential) / offset.norm() : 0.0;
  Eigen::Matrix3d identity = Eigen::Matrix3d::Zero();
  identity.topLeftCorner(s, s).setIdentity();
  return cos_theta * identity + (1.0 - cos_theta) * ErrorMatrix(term, f, s);
}

namespace {

constexpr std::array<EnumName<ErrorTerm>, 6> kErrorTermNames = {{
    {ErrorTerm::kPdm, "pdm"},
    {ErrorTerm::kTdm, "tdm"},
    {ErrorTerm::kSdm, "sdm"},
    {ErrorTerm::kCdm, "cdm"},
    {ErrorTerm::kGtdm, "gtdm"},
    {ErrorTerm::kGn, "gn"},
}};

}  // namespace

const char* ToString(ErrorTerm term) {
  return NameOf(kErrorTermNames, term);
}

ErrorTerm ErrorTermFromString(const std::string& name) {
  return ValueOf(kErrorTermNames, name, "error term");
}

namespace {

// A geometric fit as the minimizer's problem (docs/method.md sections 1-4 and 14): the state is the model (in
// the unit box) and its exact foot points; a linearization is the normal equations of the chosen error term
// at those feet (Assemble), weighted by the robust loss; a trial moves the shape parameters and recomputes
// the feet, warm-started from the current ones.
class GeometricFitProblem : public NonlinearProblem {
 public:
  GeometricFitProblem(std::unique_ptr<ParametricModel> model, const Eigen::MatrixXd& y, double unit,
                      const GeometricFitOptions& options)
      : model_(std::move(model)),
        y_(y),
        unit_(unit),
        options_(options),
        weighting_(options.optimizer.loss),
        normal_(options.optimizer.damping.diagonal_floor) {
    weighting_.set_units(unit_);
    fairness_ = model_->FairnessMatrix(options.fairness);
    ComputeFootPoints(*model_, y_, feet_);
    UpdateWeights();
    cost_ = Objective(*model_, feet_);
  }

  double Cost() const override { return cost_; }

  LinearSystem& Linearize() override {
    if (weighting_.is_robust()) {  // the scale follows the current residuals (eq. 47)
      UpdateWeights();
      cost_ = Objective(*model_, feet_);
    }
    Assemble(*model_, y_, feet_, options_, weights_, normal_.H(), normal_.g());
    if (fairness_.size() > 0) {
      normal_.H() += 2.0 * fairness_;
      normal_.g() += 2.0 * fairness_ * model_->parameters();
    }
    // A singular normal matrix means the error term leaves directions unconstrained. Without damping no step
    // can be taken: say which directions, don't guess. With LM a transient singularity (a far start) is
    // damped, but one that persists to the end is reported (FitModel) instead of being hidden.
    last_singular_ = IsSingular(Eigen::LDLT<Eigen::MatrixXd>(normal_.H()));
    if (last_singular_ && options_.optimizer.step_strategy != StepStrategy::kTrustRegion &&
        !checked_singular_) {
      checked_singular_ = true;  // classify once: the eigen-decomposition is not for every iteration
      ThrowIfUnobservable();
    }
    return normal_;
  }

  double EvaluateTrial(const Eigen::VectorXd& step, bool /*final_if_accepted*/) override {
    trial_ = model_->Clone();
    trial_->ApplyStep(step);
    ComputeFootPoints(*trial_, y_, trial_feet_, &feet_);
    trial_cost_ = Objective(*trial_, trial_feet_);
    return std::isfinite(trial_cost_) ? trial_cost_ : std::numeric_limits<double>::infinity();
  }

  void AcceptTrial() override {
    model_ = std::move(trial_);
    feet_.swap(trial_feet_);
    cost_ = trial_cost_;
  }

  double ParameterNorm() const override { return model_->parameters().norm(); }

  void DescribeState(IterationRecord& record) const override {
    double sum = 0.0;
    record.max_distance = 0.0;
    for (const FootPoint& p : feet_) {
      sum += p.distance * p.distance;
      record.max_distance = std::max(record.max_distance, p.distance * unit_);
    }
    record.rms = std::sqrt(sum / static_cast<double>(y_.cols())) * unit_;
  }

  std::optional<StopReason> AfterIteration(const IterationSummary& summary,
                                           std::optional<StopReason> proposed) override {
    if (options_.on_iteration) options_.on_iteration(summary.record);
    if (!std::isfinite(summary.record.rms)) {
      throw std::runtime_error("the fit diverged (RMS is not finite after iteration " +
                               std::to_string(summary.record.iteration) + ")");
    }
    return proposed;
  }

  void ThrowIfUnobservable() const {
    if (auto message = UnobservableShape(*model_, y_, feet_, options_, normal_.H(), fairness_))
      throw SingularSystemError(*message);
  }

  bool last_singular() const { return last_singular_; }
  ParametricModel& model() { return *model_; }
  std::vector<FootPoint>& feet() { return feet_; }
  const RobustWeighting& weighting() const { return weighting_; }
  Eigen::VectorXd FinalWeights() const { return weighting_.Weights(FootPointDistances(feet_)); }

 private:
  // 1/2 sum rho(d_j^2) + P^T K P (docs/method.md eqs. 1, 11 and 43).
  double Objective(const ParametricModel& m, const std::vector<FootPoint>& feet) const {
    double f = 0.0;
    for (const FootPoint& p : feet) f += 0.5 * weighting_.Rho(p.distance);
    if (fairness_.size() > 0) {
      const Eigen::VectorXd p = m.parameters();
      f += p.dot(fairness_ * p);
    }
    return f;
  }

  void UpdateWeights() {
    if (!weighting_.is_robust()) return;
    const Eigen::VectorXd d = FootPointDistances(feet_);
    weighting_.Update(d);
    weights_ = weighting_.Weights(d);
  }

  std::unique_ptr<ParametricModel> model_, trial_;
  const Eigen::MatrixXd& y_;
  double unit_;
  const GeometricFitOptions& options_;
  RobustWeighting weighting_;
  Eigen::VectorXd weights_;  // empty for plain least squares
  Eigen::MatrixXd fairness_;
  DenseNormalEquations normal_;
  std::vector<FootPoint> feet_, trial_feet_;
  double cost_ = 0.0, trial_cost_ = 0.0;
  bool last_singular_ = false, checked_singular_ = false;
};

}  // namespace

GeometricFitResult FitModel(ParametricModel& model, const Eigen::MatrixXd& points,
                            const GeometricFitOptions& options) {
  const int s = model.ambient_dimension();
  if (points.rows() != s) {
    throw std::invalid_argument("the model lives in " + std::to_string(s) + "D but the points have " +
                                std::to_string(points.rows()) + " coordinates");
  }
  if (points.cols() == 0) throw std::invalid_argument("no data points to fit");
  if (!points.allFinite()) throw std::invalid_argument("the data points contain NaN or inf");
  if (!model.parameters().allFinite())
    throw std::invalid_argument("the initial " + model.name() + " has NaN or inf parameters");
  const auto start = Clock::now();

  // Normalize data and model into the unit box (docs/method.md section 3).
  Normalization norm;
  norm.offset = VecS::Zero(s);
  if (options.normalize) {
    if (model.SupportsTranslation()) norm.offset = points.rowwise().mean();
    const double half = 0.5 * (points.rowwise().maxCoeff() - points.rowwise().minCoeff()).maxCoeff();
    norm.scale = half > 0 ? half : 1.0;
  }
  const Eigen::MatrixXd y = (points.colwise() - Eigen::VectorXd(norm.offset)) / norm.scale;
  std::unique_ptr<ParametricModel> current = model.Clone();
  current->ApplySimilarity(1.0 / norm.scale, VecS(-norm.offset / norm.scale));

  GeometricFitProblem problem(std::move(current), y, norm.scale, options);
  const MinimizerSummary summary = TrustRegionMinimizer(options.optimizer).Minimize(problem, 0, start);
  if (problem.last_singular()) problem.ThrowIfUnobservable();

  GeometricFitResult result;
  result.iterations = summary.iterations;
  result.stop_reason = summary.stop_reason;
  result.history = summary.history;
  result.loss_scale = problem.weighting().scale();
  result.weights = problem.FinalWeights();
  ParametricModel& fitted = problem.model();
  fitted.ApplySimilarity(norm.scale, norm.offset);
  model.CopyFrom(fitted);
  std::vector<FootPoint>& feet = problem.feet();
  for (FootPoint& f : feet) f.distance *= norm.scale;
  result.residuals = ComputeResidualStatistics(FootPointDistances(feet));
  result.foot_points = std::move(feet);
  return result;
}

}  // namespace s2m
