#include "fitting/geometric_fit.h"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <sstream>

namespace s2m {
namespace {

using Clock = std::chrono::steady_clock;

// CDM's squared weight; near a curvature centre (delta*kappa -> 1) the denominator becomes -(1 + |delta
// kappa|), the rule METHOD.md gives for CDM and GN.
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

// Assembles H = sum J^T M J and g = sum C_P^T M r over all points (in parallel), METHOD.md sections 1-2.
void Assemble(const ParametricModel& model, const Eigen::MatrixXd& y, const std::vector<FootPoint>& feet,
              const GeometricFitOptions& options, Eigen::MatrixXd& H, Eigen::VectorXd& g) {
  const int r = model.num_parameters();
  const int s = model.ambient_dimension();
  const Eigen::Index n = y.cols();
  H.setZero(r, r);
  g.setZero(r);
  const bool gn = options.error_term == ErrorTerm::kGn;
#pragma omp parallel
  {
    Eigen::MatrixXd h_local = Eigen::MatrixXd::Zero(r, r);
    Eigen::VectorXd g_local = Eigen::VectorXd::Zero(r);
    LocalGeometry geo;
    std::vector<JacobianEntry> entries;
    std::vector<Eigen::Vector3d> columns;
#pragma omp for schedule(static)
    for (Eigen::Index j = 0; j < n; ++j) {
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
        M = EndRuleMatrix(gn ? ErrorTerm::kSdm : options.error_term, ComputePrincipalFrame(geo, x), -residual,
                          s);
      } else if (gn) {
        // Full Jacobian C_P - C_t G^-1 Q, G = C_t^T C_t + [r . C_tk tl], Q_k = C_tk^T C_P + r^T dC_P/dt_k.
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
          const Eigen::Matrix2d Ginv =
              m == 1 ? Eigen::Matrix2d(Eigen::Matrix2d::Identity() / G(0, 0)) : Eigen::Matrix2d(G.inverse());
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
      const Eigen::Vector3d m_residual = M * residual;
      for (std::size_t a = 0; a < entries.size(); ++a) {
        const Eigen::Vector3d m_col = M * columns[a];
        // The right-hand side is always C_P^T (M r) with the plain C_P (METHOD.md section 2).
        g_local[entries[a].index] +=
            gn && !foot.on_boundary ? entries[a].column.dot(residual) : entries[a].column.dot(m_residual);
        for (std::size_t b = 0; b < entries.size(); ++b)
          h_local(entries[b].index, entries[a].index) += columns[b].dot(m_col);
      }
    }
#pragma omp critical
    {
      H += h_local;
      g += g_local;
    }
  }
}

double DataObjective(const std::vector<FootPoint>& feet) {
  double f = 0.0;
  for (const FootPoint& p : feet) f += 0.5 * p.distance * p.distance;
  return f;
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
  Assemble(model, y, feet, normal_space, Hn, unused);
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
  Eigen::Matrix3d identity = Eigen::Matrix3d::Zero();
  identity.topLeftCorner(s, s).setIdentity();
  Eigen::Matrix3d normal_space = Eigen::Matrix3d::Zero();
  for (int k = 0; k < f.normal_count; ++k) {
    normal_space +=
        f.normals[static_cast<std::size_t>(k)] * f.normals[static_cast<std::size_t>(k)].transpose();
  }
  switch (term) {
    case ErrorTerm::kPdm:
      return identity;
    case ErrorTerm::kTdm:
      return f.normals[0] * f.normals[0].transpose();
    case ErrorTerm::kGtdm:
      return normal_space;
    case ErrorTerm::kSdm:
    case ErrorTerm::kCdm: {
      Eigen::Matrix3d m = normal_space;
      for (int k = 0; k < f.tangent_count; ++k) {
        const auto i = static_cast<std::size_t>(k);
        const double w = term == ErrorTerm::kSdm ? SdmWeight(f.delta, f.curvatures[i])
                                                 : CdmWeight(f.delta, f.curvatures[i]);
        m += w * f.tangents[i] * f.tangents[i].transpose();
      }
      return m;
    }
    case ErrorTerm::kGn:
      return identity;  // GN builds its own Jacobian; M is used only for boundary points
  }
  return identity;
}

Eigen::Matrix3d EndRuleMatrix(ErrorTerm term, const PrincipalFrame& f, const Eigen::Vector3d& offset, int s) {
  // METHOD.md section 4: e_outer = cos(theta) e_PD + (1 - cos(theta)) e_term, theta between the boundary's
  // tangent space and X - s.
  double tangential = 0.0;
  for (int k = 0; k < f.tangent_count; ++k)
    tangential += std::pow(f.tangents[static_cast<std::size_t>(k)].dot(offset), 2);
  const double cos_theta = offset.norm() > 0 ? std::sqrt(tangential) / offset.norm() : 0.0;
  Eigen::Matrix3d identity = Eigen::Matrix3d::Zero();
  identity.topLeftCorner(s, s).setIdentity();
  return cos_theta * identity + (1.0 - cos_theta) * ErrorMatrix(term, f, s);
}

const char* ToString(ErrorTerm term) {
  switch (term) {
    case ErrorTerm::kPdm:
      return "pdm";
    case ErrorTerm::kTdm:
      return "tdm";
    case ErrorTerm::kSdm:
      return "sdm";
    case ErrorTerm::kCdm:
      return "cdm";
    case ErrorTerm::kGtdm:
      return "gtdm";
    case ErrorTerm::kGn:
      return "gn";
  }
  return "unknown";
}

ErrorTerm ErrorTermFromString(const std::string& name) {
  for (ErrorTerm t : {ErrorTerm::kPdm, ErrorTerm::kTdm, ErrorTerm::kSdm, ErrorTerm::kCdm, ErrorTerm::kGtdm,
                      ErrorTerm::kGn}) {
    if (name == ToString(t)) return t;
  }
  throw std::invalid_argument("unknown error term '" + name + "' (pdm, tdm, sdm, cdm, gtdm, gn)");
}

const char* ToString(StepControl control) {
  switch (control) {
    case StepControl::kNone:
      return "none";
    case StepControl::kLevenbergMarquardt:
      return "levenberg-marquardt";
    case StepControl::kArmijo:
      return "armijo";
  }
  return "unknown";
}

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
  const double n = static_cast<double>(points.cols());

  // Normalize data and model into the unit box (METHOD.md section 3).
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

  const Eigen::MatrixXd K = current->FairnessMatrix(options.fairness);
  auto fairness_energy = [&](const ParametricModel& m) {
    if (K.size() == 0) return 0.0;
    const Eigen::VectorXd p = m.parameters();
    return p.dot(K * p);
  };

  GeometricFitResult result;
  std::vector<FootPoint> feet, trial_feet;
  ComputeFootPoints(*current, y, feet);
  double f = DataObjective(feet) + fairness_energy(*current);
  double lambda = options.initial_damping;
  Eigen::MatrixXd H;
  Eigen::VectorXd g;
  auto rms_of = [&](const std::vector<FootPoint>& ft) {
    return std::sqrt(2.0 * DataObjective(ft) / n) * norm.scale;
  };
  double rms = rms_of(feet);

  bool last_singular = false, checked_singular = false;
  result.stop_reason = StopReason::kMaxIterations;
  if (options.target_rms > 0 && rms <= options.target_rms) result.stop_reason = StopReason::kTargetReached;
  while (result.stop_reason == StopReason::kMaxIterations && result.iterations < options.max_iterations) {
    Assemble(*current, y, feet, options, H, g);
    if (K.size() > 0) {
      H += 2.0 * K;
      g += 2.0 * K * current->parameters();
    }
    const double g_scale =
        1.0 + std::sqrt(2.0 * DataObjective(feet)) * std::sqrt(H.diagonal().cwiseAbs().maxCoeff());
    if (g.norm() <= options.gradient_tolerance * g_scale) {
      result.stop_reason = StopReason::kGradientTolerance;
      break;
    }
    // A singular normal matrix means the error term leaves directions unconstrained. Without damping no step
    // can be taken: say which directions, don't guess. With LM a transient singularity (a far start) is
    // damped, but one that persists to the end is reported (below) instead of being hidden.
    Eigen::LDLT<Eigen::MatrixXd> ldlt(H);
    last_singular = IsSingular(ldlt);
    if (last_singular && options.step_control != StepControl::kLevenbergMarquardt && !checked_singular) {
      checked_singular = true;  // classify once: the eigen-decomposition is not for every iteration
      if (auto message = UnobservableShape(*current, y, feet, options, H, K))
        throw SingularSystemError(*message);
    }
    Eigen::VectorXd step;
    const double previous_objective = f;
    double used_damping = 0.0;
    bool accepted = false;
    const double p_norm = current->parameters().norm();
    if (options.step_control == StepControl::kLevenbergMarquardt) {
      // The floor keeps damping effective in (near-)null directions, where diag(H) alone would vanish.
      const double floor = 1e-6 * H.diagonal().cwiseAbs().maxCoeff();
      while (true) {
        Eigen::MatrixXd A = H;
        A.diagonal() += lambda * H.diagonal().cwiseAbs().cwiseMax(floor);
        step = A.ldlt().solve(-g);
        if (step.norm() <= options.step_tolerance * (1.0 + p_norm)) break;
        std::unique_ptr<ParametricModel> trial = current->Clone();
        trial->ApplyStep(step);
        ComputeFootPoints(*trial, y, trial_feet, &feet);
        const double ft = DataObjective(trial_feet) + fairness_energy(*trial);
        if (ft < f) {
          used_damping = lambda;
          lambda = std::max(lambda * 0.1, 1e-12);
          current = std::move(trial);
          feet.swap(trial_feet);
          f = ft;
          accepted = true;
          break;
        }
        lambda *= 10.0;
        if (lambda > 1e16) break;
      }
    } else {
      step = ldlt.solve(-g);
      double alpha = 1.0;
      for (int ls = 0; ls < (options.step_control == StepControl::kArmijo ? 40 : 1); ++ls, alpha *= 0.5) {
        if (alpha * step.norm() <= options.step_tolerance * (1.0 + p_norm)) break;
        std::unique_ptr<ParametricModel> trial = current->Clone();
        trial->ApplyStep(alpha * step);
        ComputeFootPoints(*trial, y, trial_feet, &feet);
        const double ft = DataObjective(trial_feet) + fairness_energy(*trial);
        // Armijo: sufficient decrease along the step (g is the gradient of the objective).
        if (options.step_control == StepControl::kNone || ft <= f + options.armijo_c * alpha * g.dot(step)) {
          current = std::move(trial);
          feet.swap(trial_feet);
          f = ft;
          accepted = true;
          step *= alpha;
          break;
        }
      }
    }
    if (!accepted) {
      result.stop_reason = step.norm() <= options.step_tolerance * (1.0 + p_norm)
                               ? StopReason::kStepTolerance
                               : StopReason::kNoFurtherDecrease;
      break;
    }
    ++result.iterations;
    const double new_rms = rms_of(feet);
    IterationRecord rec;
    rec.iteration = result.iterations;
    rec.rms = new_rms;
    for (const FootPoint& p : feet) rec.max_distance = std::max(rec.max_distance, p.distance * norm.scale);
    rec.objective = f;
    rec.damping = used_damping;
    rec.step_norm = step.norm();
    rec.seconds = std::chrono::duration<double>(Clock::now() - start).count();
    result.history.push_back(rec);
    if (options.on_iteration) options.on_iteration(rec);
    if (!std::isfinite(new_rms)) {
      throw std::runtime_error("the fit diverged (RMS is not finite after iteration " +
                               std::to_string(result.iterations) + ")");
    }
    const double relative_decrease =
        previous_objective > 0 ? (previous_objective - f) / previous_objective : 0.0;
    rms = new_rms;
    if (options.target_rms > 0 && rms <= options.target_rms) {
      result.stop_reason = StopReason::kTargetReached;
    } else if (step.norm() <= options.step_tolerance * (1.0 + p_norm)) {
      result.stop_reason = StopReason::kStepTolerance;
    } else if (std::abs(relative_decrease) <= options.objective_tolerance) {
      result.stop_reason = StopReason::kObjectiveTolerance;
    }
  }

  if (last_singular) {
    if (auto message = UnobservableShape(*current, y, feet, options, H, K))
      throw SingularSystemError(*message);
  }
  current->ApplySimilarity(norm.scale, norm.offset);
  model.CopyFrom(*current);
  Eigen::VectorXd d(static_cast<Eigen::Index>(feet.size()));
  for (std::size_t j = 0; j < feet.size(); ++j) {
    feet[j].distance *= norm.scale;
    d[static_cast<Eigen::Index>(j)] = feet[j].distance;
  }
  result.residuals = ComputeResidualStatistics(d);
  result.foot_points = std::move(feet);
  return result;
}

}  // namespace s2m
