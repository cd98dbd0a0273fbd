#include "registration/scan_to_scan.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "registration/local_quadric.h"
#include "registration/nearest_index.h"
#include "registration/rigid_step.h"

namespace s2m {

namespace {

// The unit normal of the least-squares plane through `hood`: the direction of least spread (sign arbitrary).
Eigen::Vector3d PlaneNormal(const Eigen::Matrix3Xd& hood) {
  const Eigen::Vector3d mean = hood.rowwise().mean();
  const Eigen::Matrix3Xd centred = hood.colwise() - mean;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(centred * centred.transpose());
  return eig.eigenvectors().col(0);
}

// Views not linked to the fixed view through pairs of views with at least six pairs between them (fewer
// point pairs cannot fix the six motions of a relative pose): their poses relative to it are undetermined.
std::vector<std::size_t> UnconstrainedViews(const Eigen::MatrixXi& overlap, std::size_t fixed_view) {
  const Eigen::Index K = overlap.rows();
  std::vector<char> reached(static_cast<std::size_t>(K), 0);
  std::vector<Eigen::Index> stack = {static_cast<Eigen::Index>(fixed_view)};
  reached[fixed_view] = 1;
  while (!stack.empty()) {
    const Eigen::Index k = stack.back();
    stack.pop_back();
    for (Eigen::Index l = 0; l < K; ++l) {
      if (reached[static_cast<std::size_t>(l)] || overlap(k, l) + overlap(l, k) < 6) continue;
      reached[static_cast<std::size_t>(l)] = 1;
      stack.push_back(l);
    }
  }
  std::vector<std::size_t> out;
  for (Eigen::Index k = 0; k < K; ++k)
    if (!reached[static_cast<std::size_t>(k)]) out.push_back(static_cast<std::size_t>(k));
  return out;
}

}  // namespace

Eigen::Matrix3Xd EstimateNormals(const Eigen::Matrix3Xd& points, int neighbours) {
  const NearestIndex index(points);
  Eigen::Matrix3Xd normals(3, points.cols());
#pragma omp parallel for schedule(static)
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const std::vector<Eigen::Index> nn = index.KNearest(points.col(i), neighbours);
    Eigen::Matrix3Xd hood(3, static_cast<Eigen::Index>(nn.size()));
    for (std::size_t m = 0; m < nn.size(); ++m) hood.col(static_cast<Eigen::Index>(m)) = points.col(nn[m]);
    normals.col(i) = PlaneNormal(hood);
  }
  return normals;
}

ScanToScanResult RegisterScansToEachOther(const std::vector<Eigen::Matrix3Xd>& scans,
                                          std::vector<RigidMotion> world_T_scan,
                                          const ScanToScanOptions& options) {
  const std::size_t K = scans.size();
  if (K < 2) throw std::invalid_argument("scan-to-scan registration needs at least two views");
  if (world_T_scan.size() != K) throw std::invalid_argument("one initial pose per view is needed");
  if (options.fixed_view >= K) throw std::invalid_argument("the fixed view does not exist");
  if (options.samples_per_view < 1) throw std::invalid_argument("samples_per_view must be positive");
  if (options.normal_neighbours < 3)
    throw std::invalid_argument("a local plane fit needs at least 3 neighbours");
  const bool sdm = options.error_term == ScanErrorTerm::kSdm;
  const bool quadric = sdm || (options.error_term == ScanErrorTerm::kTdm && options.tdm_to_quadric);
  if (quadric && options.quadric_neighbours < 6)
    throw std::invalid_argument("a local quadric fit needs at least 6 neighbours");
  const int needed =
      quadric ? std::max(options.normal_neighbours, options.quadric_neighbours) : options.normal_neighbours;
  for (const auto& s : scans) {
    if (s.cols() < needed) throw std::invalid_argument("a view has too few points");
    if (!s.allFinite()) throw std::invalid_argument("a view contains NaN or inf coordinates");
  }
  // Targets: every view's points, searched in that view's own coordinates. The local plane (normal) or
  // quadric of a target point depends on that view alone, so each is fitted once, when a pair first uses it,
  // and kept for later sweeps.
  std::vector<NearestIndex> index(K);
#pragma omp parallel for schedule(dynamic, 1)
  for (std::size_t l = 0; l < K; ++l) index[l] = NearestIndex(scans[l]);
  double extent = 0.0;
  for (const auto& s : scans)
    extent = std::max(extent, (s.rowwise().maxCoeff() - s.rowwise().minCoeff()).norm());
  struct TargetGeometry {
    std::vector<int> slot;                 // per point: -1, or its entry in `normals` / `quadrics`
    std::vector<Eigen::Vector3d> normals;  // PDM, TDM (to the local plane)
    std::vector<LocalQuadric> quadrics;    // SDM, TDM to the quadric
  };
  std::vector<TargetGeometry> geometry(K);
  for (std::size_t l = 0; l < K; ++l) geometry[l].slot.assign(static_cast<std::size_t>(scans[l].cols()), -1);
  ScanToScanResult result;
  result.world_T_scan = std::move(world_T_scan);
  struct Pair {
    std::size_t k = 0, l = 0;  // source view, target view
    Eigen::Index j = -1;       // target point in view l; -1 before the first sweep
    Eigen::Vector3d x = Eigen::Vector3d::Zero(), target = Eigen::Vector3d::Zero();
    Eigen::Matrix3d M = Eigen::Matrix3d::Identity();            // the error term's matrix, world coordinates
    double distance = std::numeric_limits<double>::infinity();  // |x - nearest sample|: pairing and rejection
    double surface_distance = 0.0;                              // to the local plane or quadric: the RMS
    Eigen::Vector3d normal = Eigen::Vector3d::Zero();           // PDM: the target's plane normal (world)
  };
  // Every view's samples with their pairs of the previous sweep: the previous partner bounds the search for
  // the new one (a warm start), and the views are searched with the best distance found so far, so a view
  // that does not overlap the sample costs one bounding-box test.
  std::vector<std::vector<Pair>> pairs_of_view(K);
  std::vector<Eigen::Index> stride_of_view(K);
  for (std::size_t k = 0; k < K; ++k) {
    const Eigen::Index n = scans[k].cols();
    stride_of_view[k] = std::max<Eigen::Index>(1, n / options.samples_per_view);
    pairs_of_view[k].resize(static_cast<std::size_t>((n + stride_of_view[k] - 1) / stride_of_view[k]));
  }
  const Eigen::Index dim = 6 * static_cast<Eigen::Index>(K);
  const bool pdm = options.error_term == ScanErrorTerm::kPdm;
  // The step of all poses from a sweep's normal equations: the fixed view anchors the gauge (its block is
  // removed), the views left out are held the same way, and tiny damping keeps weakly constrained views
  // stable. Returns the largest rotation (rad) and displacement of the step's motions in `angle`, `shift`.
  const auto solve_step = [&](Eigen::MatrixXd& H, Eigen::VectorXd& g, const std::vector<char>& excluded,
                              std::vector<RigidMotion>& steps, double& angle, double& shift) {
    for (std::size_t k = 0; k < K; ++k) {
      if (k != options.fixed_view && !excluded[k]) continue;
      const Eigen::Index b = 6 * static_cast<Eigen::Index>(k);
      for (Eigen::Index i = 0; i < 6; ++i) {
        H.row(b + i).setZero();
        H.col(b + i).setZero();
        H(b + i, b + i) = 1.0;
        g[b + i] = 0.0;
      }
    }
    H.diagonal() += 1e-9 * H.diagonal();
    const Eigen::VectorXd v = H.ldlt().solve(-g);
    steps.resize(K);
    angle = shift = 0.0;
    for (std::size_t k = 0; k < K; ++k) {
      const Eigen::Matrix<double, 6, 1> vk = v.segment<6>(6 * static_cast<Eigen::Index>(k));
      steps[k] = RigidMotion::FromHelicalVelocity(vk.head<3>(), vk.tail<3>());
      angle = std::max(angle, steps[k].angle());
      shift = std::max(shift, steps[k].translation().norm());
    }
  };
  const auto within_tolerances = [&](double angle, double shift) {
    return angle <= options.rotation_tolerance && shift <= options.translation_tolerance * extent;
  };
  for (int sweep = 0; sweep < options.max_sweeps; ++sweep) {
    std::vector<RigidMotion> scan_T_world(K);
    for (std::size_t l = 0; l < K; ++l) scan_T_world[l] = result.world_T_scan[l].inverse();
    // Pairs: every view's samples with their nearest point over all other views (the view they overlap).
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(dim, dim);
    Eigen::VectorXd g = Eigen::VectorXd::Zero(dim);
    // PDM: the point-to-plane system of the same pairs beside it (the stall check of pending_plane_angle).
    Eigen::MatrixXd H_plane = pdm ? Eigen::MatrixXd::Zero(dim, dim) : Eigen::MatrixXd();
    Eigen::VectorXd g_plane = pdm ? Eigen::VectorXd::Zero(dim) : Eigen::VectorXd();
    double sum_sq = 0.0;
    std::size_t pairs_total = 0;
    std::vector<ScanToScanViewResidual> view_residuals(K);
    Eigen::MatrixXi overlap =
        Eigen::MatrixXi::Zero(static_cast<Eigen::Index>(K), static_cast<Eigen::Index>(K));
    for (std::size_t k = 0; k < K; ++k) {
      const Eigen::Index stride = stride_of_view[k];
      std::vector<Pair>& pairs = pairs_of_view[k];
      const Eigen::Index samples = static_cast<Eigen::Index>(pairs.size());
#pragma omp parallel for schedule(static)
      for (Eigen::Index i = 0; i < samples; ++i) {
        Pair& pair = pairs[static_cast<std::size_t>(i)];
        pair.k = k;
        pair.x = result.world_T_scan[k] * Eigen::Vector3d(scans[k].col(i * stride));
        std::size_t best_l = 0;
        Eigen::Index best_j = -1;
        double best_d2 = std::numeric_limits<double>::infinity();
        if (pair.j >= 0) {  // warm start: the previous partner, at the current poses
          best_l = pair.l;
          best_j = pair.j;
          best_d2 = (scan_T_world[best_l] * pair.x - scans[best_l].col(best_j)).squaredNorm();
          index[best_l].NearestWithin(scan_T_world[best_l] * pair.x, best_j, best_d2);
        }
        for (std::size_t l = 0; l < K; ++l) {
          if (l == k || (pair.j >= 0 && l == pair.l)) continue;
          if (index[l].NearestWithin(scan_T_world[l] * pair.x, best_j, best_d2)) best_l = l;
        }
        pair.l = best_l;
        pair.j = best_j;
        pair.distance = std::sqrt(best_d2);
        pair.target = result.world_T_scan[best_l] * Eigen::Vector3d(scans[best_l].col(best_j));
      }
      // The local geometry of the targets met for the first time.
      std::vector<std::pair<std::size_t, Eigen::Index>> missing;
      for (const Pair& p : pairs) {
        int& slot = geometry[p.l].slot[static_cast<std::size_t>(p.j)];
        if (slot >= 0) continue;
        slot = static_cast<int>(quadric ? geometry[p.l].quadrics.size() : geometry[p.l].normals.size());
        if (quadric)
          geometry[p.l].quadrics.emplace_back();
        else
          geometry[p.l].normals.emplace_back();
        missing.emplace_back(p.l, p.j);
      }
#pragma omp parallel for schedule(dynamic, 16)
      for (std::size_t m = 0; m < missing.size(); ++m) {
        const auto [l, j] = missing[m];
        const int neighbours = quadric ? options.quadric_neighbours : options.normal_neighbours;
        const std::vector<Eigen::Index> nn = index[l].KNearest(scans[l].col(j), neighbours);
        Eigen::Matrix3Xd hood(3, static_cast<Eigen::Index>(nn.size()));
        for (std::size_t q = 0; q < nn.size(); ++q)
          hood.col(static_cast<Eigen::Index>(q)) = scans[l].col(nn[q]);
        const std::size_t slot = static_cast<std::size_t>(geometry[l].slot[static_cast<std::size_t>(j)]);
        if (quadric)
          geometry[l].quadrics[slot] = LocalQuadric::Fit(hood, scans[l].col(j));
        else
          geometry[l].normals[slot] = PlaneNormal(hood);
      }
#pragma omp parallel for schedule(static)
      for (Eigen::Index i = 0; i < samples; ++i) {
        Pair& best = pairs[static_cast<std::size_t>(i)];
        const Eigen::Matrix3d& rotation = result.world_T_scan[best.l].rotation();
        const std::size_t slot =
            static_cast<std::size_t>(geometry[best.l].slot[static_cast<std::size_t>(best.j)]);
        if (quadric) {
          // The other view's surface near the target: a quadric over the target's neighbours (in view l's
          // coordinates); x's foot point s on it, and there the approximant of the squared distance (SDM) or
          // the tangent plane (TDM).
          const LocalQuadric& fit = geometry[best.l].quadrics[slot];
          const Eigen::Vector3d x_l = scan_T_world[best.l] * best.x;
          const SurfacePoint foot = fit.FootPoint(x_l);
          best.target = result.world_T_scan[best.l] * foot.point;
          const Eigen::Matrix3d m =
              sdm ? SdmErrorMatrix(foot, x_l) : Eigen::Matrix3d(foot.normal * foot.normal.transpose());
          best.M = rotation * m * rotation.transpose();
          best.surface_distance = std::abs(foot.normal.dot(x_l - foot.point));
        } else {
          const Eigen::Vector3d normal = rotation * geometry[best.l].normals[slot];
          best.M = options.error_term == ScanErrorTerm::kTdm ? Eigen::Matrix3d(normal * normal.transpose())
                                                             : Eigen::Matrix3d::Identity();
          best.normal = normal;
          best.surface_distance = std::abs(normal.dot(best.x - best.target));
        }
      }
    }
    // Rejection: pairs farther than 3 x the median pair distance of their view or than a quarter of the
    // largest view's extent (starts are within a few degrees and a few per cent of the part's size: a pair
    // farther apart cannot be a correspondence). A view that overlaps nothing, whose pairs are all far, is
    // then left without pairs instead of being pulled onto whatever lies nearest. (A bound from the median
    // over all views would starve a view whose pairs are legitimately longer, e.g. one seen from another
    // elevation, and let it drift.)
    std::vector<double> thresholds(K, options.max_correspondence);
    if (options.max_correspondence <= 0) {
      for (std::size_t k = 0; k < K; ++k) {
        std::vector<double> d;
        for (const Pair& p : pairs_of_view[k]) d.push_back(p.distance);
        std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
        thresholds[k] = std::min(3.0 * d[d.size() / 2], 0.25 * extent);
      }
    }
    // The overlap graph of the accepted pairs; views it does not link to the fixed view are left out of the
    // step (their few pairs cannot place them, and would only disturb the views they touch).
    for (std::size_t k = 0; k < K; ++k) {
      for (const Pair& p : pairs_of_view[k])
        if (p.distance <= thresholds[k])
          ++overlap(static_cast<Eigen::Index>(k), static_cast<Eigen::Index>(p.l));
    }
    std::vector<char> excluded(K, 0);
    for (std::size_t k : UnconstrainedViews(overlap, options.fixed_view)) excluded[k] = 1;
    for (std::size_t k = 0; k < K; ++k) {
      const std::vector<Pair>& pairs = pairs_of_view[k];
      const double threshold = thresholds[k];
      // Residual r = x - t with both views moving (docs/method.md section 5): x' = x + A(x) m_k, A(y) =
      // [-[y]x I], error r'^T M r' with M frozen; all poses are solved at once. PDM and TDM move the target
      // with view l, t' = t + A(t) m_l (Chen & Medioni's plane kept parallel). The quadric terms instead take
      // the step of x relative to view l, whose surface (with s and M) stays fixed in l's frame: x' - s = r +
      // A(x) (m_k - m_l), exactly the model-registration step, so SDM's approximant stays exact to second
      // order in l's frame (M frozen in world while s moves would drop terms delta n^T [w_l]x (M - I) dx of
      // the order of the curvature terms). At a foot point (r parallel to n) the two agree for the normal
      // term.
      ScanToScanViewResidual& residual_k = view_residuals[k];
      residual_k.samples = static_cast<Eigen::Index>(pairs.size());
      residual_k.correspondence_distance = threshold;
      for (const Pair& p : pairs) {
        if (!(p.distance <= threshold)) continue;
        ++residual_k.pairs;
        residual_k.rms += p.surface_distance * p.surface_distance;
        residual_k.max = std::max(residual_k.max, p.surface_distance);
        if (excluded[p.k] || excluded[p.l]) continue;
        const Eigen::Matrix<double, 3, 6> jk = MotionJacobian(p.x);
        const Eigen::Matrix<double, 3, 6> jl = -MotionJacobian(quadric ? p.x : p.target);
        const Eigen::Vector3d residual = p.x - p.target;
        const Eigen::Index bk = 6 * static_cast<Eigen::Index>(p.k), bl = 6 * static_cast<Eigen::Index>(p.l);
        // The pair's terms r'^T M r' in the system (H, g) of both views' motions.
        const auto add_pair = [&](Eigen::MatrixXd& H_to, Eigen::VectorXd& g_to, const Eigen::Matrix3d& M) {
          const Eigen::Matrix<double, 6, 3> mk = jk.transpose() * M, ml = jl.transpose() * M;
          H_to.block<6, 6>(bk, bk) += mk * jk;
          H_to.block<6, 6>(bl, bl) += ml * jl;
          H_to.block<6, 6>(bk, bl) += mk * jl;
          H_to.block<6, 6>(bl, bk) += ml * jk;
          g_to.segment<6>(bk) += mk * residual;
          g_to.segment<6>(bl) += ml * residual;
        };
        add_pair(H, g, p.M);
        if (pdm) add_pair(H_plane, g_plane, p.normal * p.normal.transpose());  // TDM's M, same pairs
        sum_sq += p.surface_distance * p.surface_distance;
        ++pairs_total;
      }
      if (residual_k.pairs > 0)
        residual_k.rms = std::sqrt(residual_k.rms / static_cast<double>(residual_k.pairs));
    }
    std::vector<RigidMotion> steps;
    solve_step(H, g, excluded, steps, result.last_step_angle, result.last_step_shift);
    for (std::size_t k = 0; k < K; ++k) {
      result.world_T_scan[k] = steps[k] * result.world_T_scan[k];
      result.world_T_scan[k].normalize();
    }
    bool plane_step_small = true;
    if (pdm) {
      std::vector<RigidMotion> plane_steps;
      solve_step(H_plane, g_plane, excluded, plane_steps, result.pending_plane_angle,
                 result.pending_plane_shift);
      plane_step_small = within_tolerances(result.pending_plane_angle, result.pending_plane_shift);
    }
    result.sweeps = sweep + 1;
    result.rms_per_sweep.push_back(pairs_total ? std::sqrt(sum_sq / static_cast<double>(pairs_total)) : 0.0);
    result.poses_per_sweep.push_back(result.world_T_scan);
    result.view_residuals = std::move(view_residuals);
    result.overlap = std::move(overlap);
    if (options.progress) options.progress(result.sweeps, result.rms_per_sweep.back());
    if (within_tolerances(result.last_step_angle, result.last_step_shift)) {
      // Settled: converged, or (PDM) stalled where more sweeps would not move it.
      result.converged = plane_step_small;
      result.stalled = !plane_step_small;
      break;
    }
  }
  result.unconstrained_views = UnconstrainedViews(result.overlap, options.fixed_view);
  return result;
}

}  // namespace s2m
