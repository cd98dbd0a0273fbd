#include "fitting/model_registration.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>

#include "fitting/foot_point.h"
#include "fitting/linear_solver.h"
#include "fitting/minimizer.h"
#include "fitting/parallel_reduction.h"
#include "fitting/robust_loss.h"
#include "registration/principal_curvatures.h"
#include "registration/rigid_step.h"

namespace s2m {
namespace {

// TDM's and SDM's error matrices at an exact foot on a surface in 3D, added straight from the model's
// derivatives `g` at the foot (TDM as one rank-one direction, SDM by the symmetric blocks): TDM needs only
// the unit normal n = C_u x C_v / |C_u x C_v|; SDM adds the principal directions T_k with the weights
// SdmWeight(delta, kappa_k) (docs/method.md section 2), the principal curvatures and directions being the
// eigenpairs of the shape operator S = I^-1 II (first and second fundamental forms; do Carmo, section 3-3),
// solved in closed form (SolvePrincipalCurvatures). The same M as ComputePrincipalFrame + ErrorMatrix (up to
// rounding) without their 3 x 3 matrices. False (nothing added) for a degenerate metric: the caller falls
// back to the general path.
bool AddSurfaceDirections(ErrorTerm term, const LocalGeometry& g, const Eigen::Vector3d& x, double weight,
                          RigidNormalEquations& eq) {
  const Eigen::Vector3d su = To3(g.d1.col(0)), sv = To3(g.d1.col(1));
  const double e = su.squaredNorm(), f = su.dot(sv), gg = sv.squaredNorm();
  const double det = e * gg - f * f;
  if (!(det > 1e-12 * (e + gg) * (e + gg))) return false;
  Eigen::Vector3d n = su.cross(sv) / std::sqrt(det);  // |C_u x C_v|^2 = det I
  const Eigen::Vector3d r = x - To3(g.point);
  double delta = n.dot(r);
  if (delta < 0) {  // n towards the data point, delta >= 0, curvatures signed w.r.t. n
    n = -n;
    delta = -delta;
  }
  if (term == ErrorTerm::kTdm) {
    eq.AddDirection(x, n, weight, delta);
    return true;
  }
  Eigen::Matrix2d first, second;
  first << e, f, f, gg;
  const double l = n.dot(To3(g.d2.col(0))), m = n.dot(To3(g.d2.col(1))), nn = n.dot(To3(g.d2.col(2)));
  second << l, m, m, nn;
  Eigen::Matrix2d directions;
  Eigen::Vector2d curvatures;
  if (!SolvePrincipalCurvatures(second, first, directions, curvatures)) return false;
  const double b1 = SdmWeight(delta, curvatures[0]), b2 = SdmWeight(delta, curvatures[1]);
  if (!(b1 > 0) && !(b2 > 0)) {
    eq.AddDirection(x, n, weight, delta);
    return true;
  }
  // The I-orthonormal eigenvector of k1 maps to a unit tangent C_t v (at an umbilic any tangent will do: then
  // b1 == b2 and M's tangential part is b1 (I - n n^T) whatever the directions).
  const Eigen::Vector3d t1 = (directions(0, 0) * su + directions(1, 0) * sv).normalized();
  const Eigen::Vector3d t2 = n.cross(t1);  // principal directions are orthogonal
  // M by its symmetric blocks (RigidNormalEquations::AddSymmetric), cheaper than three rank-one terms.
  const Eigen::Matrix3d error_matrix = n * n.transpose() + (b1 > 0 ? b1 : 0.0) * t1 * t1.transpose() +
                                       (b2 > 0 ? b2 : 0.0) * t2 * t2.transpose();
  eq.AddSymmetric(x, error_matrix, weight, r);
  return true;
}

// The 6 x 6 normal equations of a rigid step as the minimizer's linear system, damped as registration
// always was: lambda diag(H) (SolveRigidVelocity).
class RigidSystem : public LinearSystem {
 public:
  RigidNormalEquations eq;
  Eigen::Index num_parameters() const override { return 6; }
  bool Solve(double lambda, Eigen::VectorXd& step) override {
    step = SolveRigidVelocity(eq, lambda);
    return step.allFinite();
  }
  double Slope(const Eigen::VectorXd& step) const override { return eq.g.dot(step); }
  double ModelChange(const Eigen::VectorXd& step) const override {
    return eq.g.dot(step) + 0.5 * step.dot(eq.H * step);
  }
  double GradientMeasure(double cost) const override {
    const double residual_norm = std::sqrt(std::max(2.0 * cost, 0.0));
    double largest = 0.0;
    for (int k = 0; k < 6; ++k) {
      if (eq.H(k, k) > 0.0 && residual_norm > 0.0)
        largest = std::max(largest, std::abs(eq.g[k]) / (std::sqrt(eq.H(k, k)) * residual_norm));
    }
    return largest;  // docs/method.md eq. 42
  }
};

// Per-thread scratch of the registration pass.
struct RegistrationScratch {
  LocalGeometry geo;
  SquaredDistanceField::Answer answer;
};

// Registration to a fixed model as the minimizer's problem (docs/method.md sections 5 and 14): the state is
// the pose, the scan's points placed by it (always from the original scan: no drift), their feet (exact, or
// the squared distance field's in its phase) and the normal equations of the next step, assembled in the
// same pass as the feet. The objective is 1/2 mean rho(d_j^2) (1/2 the mean square without a robust loss).
class RegistrationProblem : public NonlinearProblem {
 public:
  RegistrationProblem(const ParametricModel& model, const Eigen::Matrix3Xd& scan_points,
                      const RigidMotion& initial, const ModelRegistrationOptions& options)
      : model_(model),
        scan_points_(scan_points),
        options_(options),
        // GN's implicit-function Jacobian is for shape parameters; for a rigid motion of the data SDM is its
        // analogue.
        term_(options.error_term == ErrorTerm::kGn ? ErrorTerm::kSdm : options.error_term),
        weight_(1.0 / static_cast<double>(scan_points.cols())),
        context_(model),
        field_(options.squared_distance_field),
        surface_(model.domain().dimension == 2),
        weighting_(options.optimizer.loss),
        field_phase_(field_ != nullptr),
        pose_(initial) {
    size_ = std::max((scan_points.rowwise().maxCoeff() - scan_points.rowwise().minCoeff()).norm(), 1e-300);
    // Both point buffers are allocated once; every trial overwrites `moved_` in place.
    current_.resize(3, scan_points.cols());
    moved_.resize(3, scan_points.cols());
    Place(pose_, current_);
    Pass(current_, false, field_phase_, true, feet_, geometry_, exact_, system_.eq);
    cost_ = Objective(feet_);
  }

  double Cost() const override { return cost_; }

  LinearSystem& Linearize() override {
    if (weighting_.loss().scale_from_data() || !equations_valid_) {
      // The scale follows the current distances (eq. 47); the equations are assembled with it at the
      // current feet (warm from themselves: Newton stops at once).
      if (weighting_.loss().scale_from_data()) weighting_.Update(FootPointDistances(feet_));
      Pass(current_, true, field_phase_, true, trial_feet_, trial_geometry_, trial_exact_, system_.eq);
      feet_.swap(trial_feet_);
      geometry_.swap(trial_geometry_);
      exact_.swap(trial_exact_);
      cost_ = Objective(feet_);
      equations_valid_ = true;
    }
    return system_;
  }

  double EvaluateTrial(const Eigen::VectorXd& step, bool final_if_accepted) override {
    // The field's approximant no longer decreased at the last trial: its fixed point is reached, and the
    // field phase ends (no further, more damped trial is evaluated).
    if (field_phase_ && field_rejected_) return std::numeric_limits<double>::infinity();
    trial_pose_ = RigidMotion::FromHelicalVelocity(step.head<3>(), step.tail<3>()) * pose_;
    Place(trial_pose_, moved_);
    // A trial that, if accepted, is the last of its phase needs no normal equations; a loss scale from the
    // data re-assembles them at the next linearization anyway.
    trial_equations_ = !final_if_accepted && !weighting_.loss().scale_from_data();
    Pass(moved_, true, field_phase_, trial_equations_, trial_feet_, trial_geometry_, trial_exact_, trial_eq_);
    trial_cost_ = Objective(trial_feet_);
    if (field_phase_ && !(trial_cost_ < cost_) &&
        options_.optimizer.step_strategy == StepStrategy::kTrustRegion)
      field_rejected_ = true;
    return std::isnan(trial_cost_) ? std::numeric_limits<double>::infinity() : trial_cost_;
  }

  void AcceptTrial() override {
    pose_ = trial_pose_;
    current_.swap(moved_);
    feet_.swap(trial_feet_);
    geometry_.swap(trial_geometry_);
    exact_.swap(trial_exact_);
    std::swap(system_.eq, trial_eq_);
    equations_valid_ = trial_equations_;
    cost_ = trial_cost_;
  }

  // Registration's own step test: the step's rotation (rad) and translation (relative to the scan's size)
  // below their tolerances; in the field phase below field_step_tolerance too.
  bool StepIsNegligible(const Eigen::VectorXd& step, double /*tolerance*/) const override {
    const RigidMotion motion = RigidMotion::FromHelicalVelocity(step.head<3>(), step.tail<3>());
    const double tolerance = field_phase_ ? options_.field_step_tolerance : 0.0;
    return motion.angle() <= std::max(tolerance, options_.rotation_tolerance) &&
           motion.translation().norm() <= std::max(tolerance, options_.translation_tolerance) * size_;
  }

  void DescribeState(IterationRecord& record) const override {
    double sum = 0.0;
    record.max_distance = 0.0;
    for (const FootPoint& f : feet_) {
      sum += f.distance * f.distance;
      record.max_distance = std::max(record.max_distance, f.distance);
    }
    record.rms = std::sqrt(sum / static_cast<double>(feet_.size()));
  }

  std::optional<StopReason> AfterIteration(const IterationSummary& summary,
                                           std::optional<StopReason> proposed) override {
    pose_history_.push_back(pose_);
    if (field_phase_) ++field_iterations_;
    if (options_.progress) options_.progress(summary.record.iteration, summary.record.rms);
    return proposed;
  }

  // Leaves the field: exact feet at the current pose (warm from the field's parameters).
  void SwitchToExact() {
    field_phase_ = false;
    Pass(current_, true, false, true, trial_feet_, trial_geometry_, trial_exact_, trial_eq_);
    feet_.swap(trial_feet_);
    geometry_.swap(trial_geometry_);
    exact_.swap(trial_exact_);
    std::swap(system_.eq, trial_eq_);
    equations_valid_ = true;
    cost_ = Objective(feet_);
  }

  bool field_phase() const { return field_phase_; }
  int field_iterations() const { return field_iterations_; }
  const RigidMotion& pose() const { return pose_; }
  std::vector<RigidMotion>& pose_history() { return pose_history_; }
  const std::vector<FootPoint>& feet() const { return feet_; }
  double loss_scale() const { return weighting_.scale(); }

 private:
  void Place(const RigidMotion& pose, Eigen::Matrix3Xd& out) const {
    // A coefficient-wise product: a 3 x 3 rotation gains nothing from GEMM's packing.
    out.noalias() = pose.rotation().lazyProduct(scan_points_);
    out.colwise() += pose.translation();
  }

  // 1/2 mean rho(d_j^2) (docs/method.md eqs. 16 and 43).
  double Objective(const std::vector<FootPoint>& feet) const {
    double sum = 0.0;
    for (const FootPoint& f : feet) sum += weighting_.Rho(f.distance);
    return 0.5 * (sum / static_cast<double>(feet.size()));
  }

  void Pass(const Eigen::Matrix3Xd& points, bool warm, bool use_field, bool equations,
            std::vector<FootPoint>& out, std::vector<LocalGeometry>& out_geometry,
            std::vector<char>& out_exact, RigidNormalEquations& eq);

  const ParametricModel& model_;
  const Eigen::Matrix3Xd& scan_points_;
  const ModelRegistrationOptions& options_;
  ErrorTerm term_;
  double weight_;
  FootPointContext context_;
  SquaredDistanceField* field_;
  bool surface_;
  RobustWeighting weighting_;
  bool field_phase_;
  bool field_rejected_ = false;
  double size_ = 1.0;
  RigidMotion pose_, trial_pose_;
  Eigen::Matrix3Xd current_, moved_;
  std::vector<FootPoint> feet_, trial_feet_;
  std::vector<LocalGeometry> geometry_, trial_geometry_;
  std::vector<char> exact_, trial_exact_;
  RigidSystem system_;
  RigidNormalEquations trial_eq_;
  std::vector<RigidNormalEquations> partials_;
  bool equations_valid_ = true, trial_equations_ = true;
  double cost_ = 0.0, trial_cost_ = 0.0;
  std::vector<RigidMotion> pose_history_;
  int field_iterations_ = 0;
};

// One pass over the points per pose: the foot point (warm from the current feet when `warm`) and, at it,
// the point's contribution to the 6x6 normal equations of the next step (with its IRLS weight rho'(d^2)),
// accumulated per thread and summed in thread order (deterministic for a given thread count). Newton leaves
// the model's point and derivatives at the foot in the scratch geometry, so the assembly evaluates the model
// again only for closed-form feet. The model's geometry at each foot is kept for the next pass: the model is
// fixed, so Newton's first evaluation at the previous foot would recompute exactly these numbers. With a
// squared distance field, points inside its band take the field's approximate foot and SDM approximant
// instead (exact[i] = 0): no Newton, no model evaluation. `equations` false: only the feet are computed
// (neither the frames, the normal equations nor the geometry for a next pass).
void RegistrationProblem::Pass(const Eigen::Matrix3Xd& points, bool warm, bool use_field, bool equations,
                               std::vector<FootPoint>& out, std::vector<LocalGeometry>& out_geometry,
                               std::vector<char>& out_exact, RigidNormalEquations& eq) {
  const std::vector<FootPoint>* warm_feet = warm ? &feet_ : nullptr;
  out.resize(static_cast<std::size_t>(points.cols()));
  // Newton's geometry is kept for the next pass only in the exact phase (not touching 100 bytes per point in
  // the field's passes).
  if (use_field || !equations)
    out_geometry.clear();
  else
    out_geometry.resize(static_cast<std::size_t>(points.cols()));
  out_exact.resize(static_cast<std::size_t>(points.cols()));
  SquaredDistanceField* field = field_;
  // A lazy field computes the cells these points fall in first (once each; nothing for a field built whole).
  if (use_field) field->Prepare(points);
  const ErrorTerm term = term_;
  // The previous pass kept Newton's geometry only when it assembled equations in the exact phase.
  const bool warm_geometry = warm && geometry_.size() == feet_.size() && exact_.size() == feet_.size();
  AccumulateInParallel<RegistrationScratch>(
      points.cols(), partials_, [](RigidNormalEquations& p) { p = RigidNormalEquations(); },
      [&](Eigen::Index j, RegistrationScratch& scratch, RigidNormalEquations& mine) {
        const auto i = static_cast<std::size_t>(j);
        SquaredDistanceField::Answer& answer = scratch.answer;
        if (use_field && field->Query(points.col(j), answer, equations && term != ErrorTerm::kTdm)) {
          out[i] = FootPoint{answer.t, std::sqrt(answer.squared_distance), false, false};
          out_exact[i] = 0;
          if (!equations) return;
          const double weight = weight_ * weighting_.Weight(out[i].distance);
          const PrincipalFrame& f = answer.frame;
          const Eigen::Vector3d x3 = points.col(j), r = x3 - answer.foot;
          // TDM's M = n n^T as one rank-one term; SDM's n n^T + sum_k SdmWeight(delta, kappa_k) T_k T_k^T
          // (and the others') by the symmetric blocks, cheaper than three rank-one terms.
          if (term == ErrorTerm::kTdm)
            mine.AddDirection(x3, f.normals[0], weight, f.normals[0].dot(r));
          else
            mine.AddSymmetric(x3, ErrorMatrix(term, f, 3), weight, r);
          return;
        }
        const VecS x = points.col(j);
        // The model is fixed and the points moved by one small rigid step: the previous feet are trusted.
        // Newton's geometry at the previous foot is reused only when that foot was exact.
        const bool reuse = warm_geometry && !context_.closed_form && exact_[i] != 0;
        // Newton works in place in the kept geometry (no copy afterwards).
        LocalGeometry& g = use_field || !equations ? scratch.geo : out_geometry[i];
        if (reuse) g = geometry_[i];
        out[i] = FootPointOf(context_, x, warm_feet != nullptr ? &(*warm_feet)[i].t : nullptr,
                             WarmStart::kTrusted, g, reuse);
        out_exact[i] = use_field ? 0 : 1;
        if (!equations) return;
        const double weight = weight_ * weighting_.Weight(out[i].distance);
        if (context_.closed_form) model_.Evaluate(out[i].t, 2, g);
        if (surface_ && (term == ErrorTerm::kTdm || term == ErrorTerm::kSdm) &&
            AddSurfaceDirections(term, g, points.col(j), weight, mine))
          return;
        const PrincipalFrame frame = ComputePrincipalFrame(g, x);
        mine.Add({points.col(j), To3(g.point), ErrorMatrix(term, frame, 3), weight});
      });
  eq = RigidNormalEquations();
  for (const RigidNormalEquations& p : partials_) eq.Add(p);
}

}  // namespace

ModelRegistrationResult RegisterToModel(const ParametricModel& model, const Eigen::Matrix3Xd& scan_points,
                                        const RigidMotion& initial, const ModelRegistrationOptions& options) {
  if (model.ambient_dimension() != 3) throw std::invalid_argument("rigid registration needs a model in 3D");
  if (scan_points.cols() == 0) throw std::invalid_argument("no scan points to register");
  if (!scan_points.allFinite()) throw std::invalid_argument("the scan points contain NaN or inf");
  const auto start = std::chrono::steady_clock::now();
  TrustRegionMinimizer minimizer(options.optimizer);  // validates the options
  RegistrationProblem problem(model, scan_points, initial, options);
  MinimizerSummary summary = minimizer.Minimize(problem, 0, start);
  if (problem.field_phase()) {
    // The field phase then up to exact_final_iterations iterations with exact feet (Newton from the field's
    // foot parameters, then from the previous exact feet with their geometry), fresh damping, one history.
    problem.SwitchToExact();
    OptimizerOptions exact = options.optimizer;
    exact.max_iterations = std::min(options.optimizer.max_iterations - summary.iterations,
                                    std::max(0, options.exact_final_iterations));
    MinimizerSummary exact_summary = TrustRegionMinimizer(exact).Minimize(problem, summary.iterations, start);
    summary.iterations += exact_summary.iterations;
    summary.stop_reason = exact_summary.stop_reason;
    for (const IterationRecord& rec : exact_summary.history) summary.history.push_back(rec);
  }
  ModelRegistrationResult result;
  result.model_T_scan = problem.pose();
  result.model_T_scan.normalize();
  result.iterations = summary.iterations;
  result.field_iterations = problem.field_iterations();
  result.stop_reason = summary.stop_reason;
  result.history = std::move(summary.history);
  result.pose_history = std::move(problem.pose_history());
  result.loss_scale = problem.loss_scale();
  result.residuals = ComputeResidualStatistics(FootPointDistances(problem.feet()));
  return result;
}

ModelRegistrationOptions WithProgress(ModelRegistrationOptions options,
                                      std::function<void(int iteration, double rms)> also) {
  options.progress = [own = std::move(options.progress), also = std::move(also)](int iteration, double rms) {
    if (own) own(iteration, rms);
    if (also) also(iteration, rms);
  };
  return options;
}

std::vector<ModelRegistrationResult> RegisterScansToModel(
    const ParametricModel& model, const RigidMotion& world_T_model, ScanSet& scans,
    const ModelRegistrationOptions& options,
    const std::function<void(std::size_t scan, int iteration, double rms)>& progress) {
  std::vector<ModelRegistrationResult> results;
  const RigidMotion model_T_world = world_T_model.inverse();
  for (std::size_t k = 0; k < scans.scans.size(); ++k) {
    Scan& scan = scans.scans[k];
    ModelRegistrationResult r;
    try {
      r = RegisterToModel(
          model, scan.points, model_T_world * scan.world_T_scan,
          progress ? WithProgress(options, [&progress, k](int i, double rms) { progress(k, i, rms); })
                   : options);
    } catch (const std::invalid_argument& e) {  // the scan named: a set's caller cannot tell which one
      throw std::invalid_argument("scan " + std::to_string(k) + ": " + e.what());
    }
    scan.world_T_scan = world_T_model * r.model_T_scan;
    results.push_back(std::move(r));
  }
  return results;
}

double PoseConditioning(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals) {
  if (points.cols() != normals.cols())
    throw std::invalid_argument("PoseConditioning: " + std::to_string(points.cols()) + " points but " +
                                std::to_string(normals.cols()) + " normals");
  if (points.cols() < 6) return 0.0;
  const Eigen::Vector3d c = points.rowwise().mean();
  const double r = std::sqrt((points.colwise() - c).colwise().squaredNorm().mean());
  if (!(r > 0.0)) return 0.0;
  Eigen::Matrix<double, 6, 6> h = Eigen::Matrix<double, 6, 6>::Zero();
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    Eigen::Matrix<double, 6, 1> a;
    a << (points.col(i) - c).cross(normals.col(i)) / r, normals.col(i);
    h.selfadjointView<Eigen::Lower>().rankUpdate(a);
  }
  const Eigen::Matrix<double, 6, 1> eig =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>>(h, Eigen::EigenvaluesOnly).eigenvalues();
  return eig(5) > 0.0 ? std::max(eig(0), 0.0) / eig(5) : 0.0;
}

}  // namespace s2m
