#include "fitting/model_registration.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>

#include "fitting/foot_point.h"
#include "registration/principal_curvatures.h"
#include "registration/rigid_step.h"

namespace s2m {
namespace {

double MeanSquare(const std::vector<FootPoint>& feet) {
  double sum = 0.0;
  for (const FootPoint& f : feet) sum += f.distance * f.distance;
  return sum / static_cast<double>(feet.size());
}

// TDM's and SDM's error matrices at an exact foot on a surface in 3D, added as rank-one directions
// (RigidNormalEquations::AddDirection) straight from the model's derivatives `g` at the foot: TDM needs only
// the unit normal n = C_u x C_v / |C_u x C_v|; SDM adds the principal directions T_k with the weights
// SdmWeight(delta, kappa_k) (METHOD.md section 2), the principal curvatures and directions being the
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
  eq.AddDirection(x, n, weight, delta);
  const double b1 = SdmWeight(delta, curvatures[0]), b2 = SdmWeight(delta, curvatures[1]);
  if (!(b1 > 0) && !(b2 > 0)) return true;
  // The I-orthonormal eigenvector of k1 maps to a unit tangent C_t v (at an umbilic any tangent will do: then
  // b1 == b2 and M's tangential part is b1 (I - n n^T) whatever the directions).
  const Eigen::Vector3d t1 = (directions(0, 0) * su + directions(1, 0) * sv).normalized();
  const Eigen::Vector3d t2 = n.cross(t1);  // principal directions are orthogonal
  if (b1 > 0) eq.AddDirection(x, t1, weight * b1, t1.dot(r));
  if (b2 > 0) eq.AddDirection(x, t2, weight * b2, t2.dot(r));
  return true;
}

}  // namespace

ModelRegistrationResult RegisterToModel(const ParametricModel& model, const Eigen::Matrix3Xd& scan_points,
                                        const RigidMotion& initial, const ModelRegistrationOptions& options) {
  if (model.ambient_dimension() != 3) throw std::invalid_argument("rigid registration needs a model in 3D");
  if (scan_points.cols() == 0) throw std::invalid_argument("no scan points to register");
  if (!scan_points.allFinite()) throw std::invalid_argument("the scan points contain NaN or inf");
  const auto start = std::chrono::steady_clock::now();
  const double size =
      std::max((scan_points.rowwise().maxCoeff() - scan_points.rowwise().minCoeff()).norm(), 1e-300);

  ModelRegistrationResult result;
  result.model_T_scan = initial;
  // Both point buffers are allocated once; every trial overwrites `moved` in place.
  Eigen::Matrix3Xd current(3, scan_points.cols()), moved(3, scan_points.cols());
  auto place = [&scan_points](const RigidMotion& pose, Eigen::Matrix3Xd& out) {
    // A coefficient-wise product: a 3 x 3 rotation gains nothing from GEMM's packing.
    out.noalias() = pose.rotation().lazyProduct(scan_points);
    out.colwise() += pose.translation();
  };
  // GN's implicit-function Jacobian is for shape parameters; for a rigid motion of the data SDM is its
  // analogue.
  const ErrorTerm term = options.error_term == ErrorTerm::kGn ? ErrorTerm::kSdm : options.error_term;
  const double weight = 1.0 / static_cast<double>(scan_points.cols());
  const FootPointContext context(model);
  // One pass over the points per pose: the foot point (warm from `warm` when given) and, at it, the point's
  // contribution to the 6x6 normal equations of the next step, accumulated per thread and summed in thread
  // order (deterministic for a given thread count). Newton leaves the model's point and derivatives at the
  // foot in `geo`, so the assembly evaluates the model again only for closed-form feet. The normal equations
  // of a rejected trial are simply dropped. The model's geometry at each foot is kept for the next pass: the
  // model is fixed, so Newton's first evaluation at the previous foot would recompute exactly these numbers.
  // With a squared distance field (options.squared_distance_field), points inside its band take the field's
  // approximate foot and SDM approximant instead (exact[i] = 0): no Newton, no model evaluation.
  const SquaredDistanceField* field = options.squared_distance_field;
  // `equations` false: the pass is the last one whatever its outcome (its step ends the iterations or the
  // field phase if accepted, and a rejected trial re-solves the previous equations), so only the feet are
  // computed: neither the frames, the normal equations nor the geometry for a next pass.
  const bool surface = model.domain().dimension == 2;
  auto feet_and_equations = [&](const Eigen::Matrix3Xd& points, const std::vector<FootPoint>* warm,
                                const std::vector<LocalGeometry>* warm_geometry,
                                const std::vector<char>* warm_exact, bool use_field, bool equations,
                                std::vector<FootPoint>& out, std::vector<LocalGeometry>& out_geometry,
                                std::vector<char>& out_exact, RigidNormalEquations& eq) {
    out.resize(static_cast<std::size_t>(points.cols()));
    // Newton's geometry is kept for the next pass only in the exact phase (not touching 100 bytes per point
    // in the field's passes).
    if (use_field || !equations)
      out_geometry.clear();
    else
      out_geometry.resize(static_cast<std::size_t>(points.cols()));
    out_exact.resize(static_cast<std::size_t>(points.cols()));
    std::vector<RigidNormalEquations> partial;
#pragma omp parallel
    {
#pragma omp single
      partial.resize(static_cast<std::size_t>(omp_get_num_threads()));
      RigidNormalEquations& mine = partial[static_cast<std::size_t>(omp_get_thread_num())];
      LocalGeometry geo;
      SquaredDistanceField::Answer answer;
#pragma omp for schedule(static)
      for (Eigen::Index j = 0; j < points.cols(); ++j) {
        const auto i = static_cast<std::size_t>(j);
        if (use_field && field->Query(points.col(j), answer, equations && term != ErrorTerm::kTdm)) {
          out[i] = FootPoint{answer.t, std::sqrt(answer.squared_distance), false, false};
          out_exact[i] = 0;
          if (!equations) continue;
          const PrincipalFrame& f = answer.frame;
          const Eigen::Vector3d x3 = points.col(j), r = x3 - answer.foot;
          if (term == ErrorTerm::kTdm || term == ErrorTerm::kSdm) {
            // M = n n^T (+ sum_k SdmWeight(delta, kappa_k) T_k T_k^T for SDM) as rank-one terms.
            mine.AddDirection(x3, f.normals[0], weight, f.normals[0].dot(r));
            for (int k = 0; k < 2 && term == ErrorTerm::kSdm; ++k) {
              const auto uk = static_cast<std::size_t>(k);
              const double beta = SdmWeight(f.delta, f.curvatures[uk]);
              if (beta > 0) mine.AddDirection(x3, f.tangents[uk], weight * beta, f.tangents[uk].dot(r));
            }
          } else {
            mine.Add({x3, answer.foot, ErrorMatrix(term, f, 3), weight});
          }
          continue;
        }
        const VecS x = points.col(j);
        // The model is fixed and the points moved by one small rigid step: the previous feet are trusted.
        // Newton's geometry at the previous foot is reused only when that foot was exact.
        const bool reuse = warm != nullptr && !context.closed_form && (*warm_exact)[i] != 0;
        // Newton works in place in the kept geometry (no copy afterwards).
        LocalGeometry& g = use_field || !equations ? geo : out_geometry[i];
        if (reuse) g = (*warm_geometry)[i];
        out[i] =
            FootPointOf(context, x, warm != nullptr ? &(*warm)[i].t : nullptr, WarmStart::kTrusted, g, reuse);
        out_exact[i] = use_field ? 0 : 1;
        if (!equations) continue;
        if (context.closed_form) model.Evaluate(out[i].t, 2, g);
        if (surface && (term == ErrorTerm::kTdm || term == ErrorTerm::kSdm) &&
            AddSurfaceDirections(term, g, points.col(j), weight, mine))
          continue;
        const PrincipalFrame frame = ComputePrincipalFrame(g, x);
        mine.Add({points.col(j), To3(g.point), ErrorMatrix(term, frame, 3), weight});
      }
    }
    eq = RigidNormalEquations();
    for (const RigidNormalEquations& p : partial) eq.Add(p);
  };
  bool field_phase = field != nullptr;
  place(initial, current);
  std::vector<FootPoint> feet, trial_feet;
  std::vector<LocalGeometry> geometry, trial_geometry;
  std::vector<char> exact, trial_exact;
  RigidNormalEquations eq, trial_eq;
  feet_and_equations(current, nullptr, nullptr, nullptr, field_phase, true, feet, geometry, exact, eq);
  double mean_square = MeanSquare(feet);
  double lambda = options.damping ? 1e-6 : 0.0;
  int limit = options.max_iterations;
  // Leaves the field: exact feet at the current pose (warm from the field's parameters), then at most
  // exact_final_iterations exact iterations.
  auto switch_to_exact = [&] {
    field_phase = false;
    feet_and_equations(current, &feet, &geometry, &exact, false, true, trial_feet, trial_geometry,
                       trial_exact, trial_eq);
    feet.swap(trial_feet);
    geometry.swap(trial_geometry);
    exact.swap(trial_exact);
    std::swap(eq, trial_eq);
    mean_square = MeanSquare(feet);
    lambda = options.damping ? 1e-6 : 0.0;
    limit = std::min(options.max_iterations, result.iterations + std::max(0, options.exact_final_iterations));
    result.stop_reason = StopReason::kMaxIterations;
    if (options.target_rms > 0 && std::sqrt(mean_square) <= options.target_rms)
      result.stop_reason = StopReason::kTargetReached;
  };
  result.stop_reason = StopReason::kMaxIterations;
  if (options.target_rms > 0 && std::sqrt(mean_square) <= options.target_rms)
    result.stop_reason = StopReason::kTargetReached;

  while (true) {
    if (field_phase && (result.stop_reason != StopReason::kMaxIterations || result.iterations >= limit))
      switch_to_exact();
    if (result.stop_reason != StopReason::kMaxIterations || result.iterations >= limit) break;
    bool accepted = false;
    Eigen::Matrix<double, 6, 1> velocity;
    RigidMotion step;
    while (true) {
      velocity = SolveRigidVelocity(eq, lambda);
      step = RigidMotion::FromHelicalVelocity(velocity.head<3>(), velocity.tail<3>());
      const RigidMotion trial = step * result.model_T_scan;
      place(trial, moved);  // from the original scan: no drift
      // Whether this trial, if accepted, is the last of its phase (the iteration limit, or a step below the
      // tolerance, as tested after the iteration below): then its normal equations are never solved.
      const double tolerance = field_phase ? options.field_step_tolerance : 0.0;
      const bool last =
          result.iterations + 1 >= limit ||
          (step.angle() <= std::max(tolerance, options.rotation_tolerance) &&
           step.translation().norm() <= std::max(tolerance, options.translation_tolerance) * size);
      feet_and_equations(moved, &feet, &geometry, &exact, field_phase, !last, trial_feet, trial_geometry,
                         trial_exact, trial_eq);
      const double trial_mean_square = MeanSquare(trial_feet);
      if (!options.damping || trial_mean_square < mean_square) {
        result.model_T_scan = trial;
        current.swap(moved);
        feet.swap(trial_feet);
        geometry.swap(trial_geometry);
        exact.swap(trial_exact);
        std::swap(eq, trial_eq);
        mean_square = trial_mean_square;
        lambda = options.damping ? std::max(lambda * 0.1, 1e-12) : 0.0;
        accepted = true;
        break;
      }
      // The field's approximant no longer decreases: its fixed point is reached, the exact feet take over.
      if (field_phase) break;
      lambda *= 10.0;
      if (lambda > 1e12) break;
    }
    if (!accepted) {
      result.stop_reason = StopReason::kNoFurtherDecrease;
      if (field_phase) continue;
      break;
    }
    ++result.iterations;
    if (field_phase) ++result.field_iterations;
    IterationRecord rec;
    rec.iteration = result.iterations;
    rec.rms = std::sqrt(mean_square);
    for (const FootPoint& f : feet) rec.max_distance = std::max(rec.max_distance, f.distance);
    rec.objective = 0.5 * mean_square;
    rec.damping = lambda;
    rec.step_norm = velocity.norm();
    rec.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    result.history.push_back(rec);
    result.pose_history.push_back(result.model_T_scan);
    const double tolerance = field_phase ? options.field_step_tolerance : 0.0;
    if (options.target_rms > 0 && rec.rms <= options.target_rms) {
      result.stop_reason = StopReason::kTargetReached;
    } else if (step.angle() <= std::max(tolerance, options.rotation_tolerance) &&
               step.translation().norm() <= std::max(tolerance, options.translation_tolerance) * size) {
      result.stop_reason = StopReason::kStepTolerance;
    }
  }
  result.model_T_scan.normalize();
  Eigen::VectorXd d(static_cast<Eigen::Index>(feet.size()));
  for (std::size_t j = 0; j < feet.size(); ++j) d[static_cast<Eigen::Index>(j)] = feet[j].distance;
  result.residuals = ComputeResidualStatistics(d);
  return result;
}

std::vector<ModelRegistrationResult> RegisterScansToModel(const ParametricModel& model,
                                                          const RigidMotion& world_T_model, ScanSet& scans,
                                                          const ModelRegistrationOptions& options) {
  std::vector<ModelRegistrationResult> results;
  const RigidMotion model_T_world = world_T_model.inverse();
  for (Scan& scan : scans.scans) {
    ModelRegistrationResult r =
        RegisterToModel(model, scan.points, model_T_world * scan.world_T_scan, options);
    scan.world_T_scan = world_T_model * r.model_T_scan;
    results.push_back(std::move(r));
  }
  return results;
}

}  // namespace s2m
