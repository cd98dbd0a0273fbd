#include "registration/scan_to_scan.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "registration/nearest_index.h"

namespace s2m {

Eigen::Matrix3Xd EstimateNormals(const Eigen::Matrix3Xd& points, int neighbours) {
  const NearestIndex index(points);
  Eigen::Matrix3Xd normals(3, points.cols());
#pragma omp parallel for schedule(static)
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const std::vector<Eigen::Index> nn = index.KNearest(points.col(i), neighbours);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (Eigen::Index j : nn) mean += points.col(j);
    mean /= static_cast<double>(nn.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (Eigen::Index j : nn) cov += (points.col(j) - mean) * (points.col(j) - mean).transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
    normals.col(i) = eig.eigenvectors().col(0);  // direction of least spread
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
  for (const auto& s : scans) {
    if (s.cols() < options.normal_neighbours) throw std::invalid_argument("a view has too few points");
    if (!s.allFinite()) throw std::invalid_argument("a view contains NaN or inf coordinates");
  }
  // Targets: every view's points with normals, searched in that view's own coordinates.
  std::vector<NearestIndex> index;
  std::vector<Eigen::Matrix3Xd> normals;
  double extent = 0.0;
  for (const auto& s : scans) {
    index.emplace_back(s);
    normals.push_back(EstimateNormals(s, options.normal_neighbours));
    extent = std::max(extent, (s.rowwise().maxCoeff() - s.rowwise().minCoeff()).norm());
  }
  ScanToScanResult result;
  result.world_T_scan = std::move(world_T_scan);
  struct Pair {
    std::size_t k = 0, l = 0;  // source view, target view
    Eigen::Vector3d x = Eigen::Vector3d::Zero(), target = Eigen::Vector3d::Zero(),
                    normal = Eigen::Vector3d::UnitZ();
    double distance = std::numeric_limits<double>::infinity();
  };
  const Eigen::Index dim = 6 * static_cast<Eigen::Index>(K);
  for (int sweep = 0; sweep < options.max_sweeps; ++sweep) {
    std::vector<RigidMotion> scan_T_world(K);
    for (std::size_t l = 0; l < K; ++l) scan_T_world[l] = result.world_T_scan[l].inverse();
    // Pairs: every view's samples with their nearest point over all other views (the view they overlap).
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(dim, dim);
    Eigen::VectorXd g = Eigen::VectorXd::Zero(dim);
    double sum_sq = 0.0;
    std::size_t pairs_total = 0;
    for (std::size_t k = 0; k < K; ++k) {
      const Eigen::Index n = scans[k].cols();
      const Eigen::Index stride = std::max<Eigen::Index>(1, n / options.samples_per_view);
      const Eigen::Index samples = (n + stride - 1) / stride;
      std::vector<Pair> pairs(static_cast<std::size_t>(samples));
#pragma omp parallel for schedule(static)
      for (Eigen::Index i = 0; i < samples; ++i) {
        Pair best;
        best.k = k;
        best.x = result.world_T_scan[k] * Eigen::Vector3d(scans[k].col(i * stride));
        for (std::size_t l = 0; l < K; ++l) {
          if (l == k) continue;
          const Eigen::Index j = index[l].Nearest(scan_T_world[l] * best.x);
          const Eigen::Vector3d target = result.world_T_scan[l] * Eigen::Vector3d(scans[l].col(j));
          const double d = (best.x - target).norm();
          if (d < best.distance) {
            best.l = l;
            best.target = target;
            best.normal = result.world_T_scan[l].rotation() * normals[l].col(j);
            best.distance = d;
          }
        }
        pairs[static_cast<std::size_t>(i)] = best;
      }
      double threshold = options.max_correspondence;
      if (threshold <= 0) {
        std::vector<double> d;
        for (const Pair& p : pairs) d.push_back(p.distance);
        std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
        threshold = 3.0 * d[d.size() / 2];
      }
      // Point-to-plane residual n.(x - t) with both views moving: x' = x + A(x) m_k, t' = t + A(t) m_l,
      // A(y) = [-[y]x  I] (METHOD.md section 5); the whole set of poses is solved at once.
      for (const Pair& p : pairs) {
        if (!(p.distance <= threshold)) continue;
        Eigen::Matrix<double, 1, 6> jk, jl;
        jk << p.x.cross(p.normal).transpose(), p.normal.transpose();
        jl << -p.target.cross(p.normal).transpose(), -p.normal.transpose();
        const double residual = p.normal.dot(p.x - p.target);
        const Eigen::Index bk = 6 * static_cast<Eigen::Index>(p.k), bl = 6 * static_cast<Eigen::Index>(p.l);
        H.block<6, 6>(bk, bk) += jk.transpose() * jk;
        H.block<6, 6>(bl, bl) += jl.transpose() * jl;
        H.block<6, 6>(bk, bl) += jk.transpose() * jl;
        H.block<6, 6>(bl, bk) += jl.transpose() * jk;
        g.segment<6>(bk) += jk.transpose() * residual;
        g.segment<6>(bl) += jl.transpose() * residual;
        sum_sq += residual * residual;
        ++pairs_total;
      }
    }
    // The fixed view anchors the gauge (its block is removed); tiny damping keeps weakly constrained views
    // stable.
    const Eigen::Index fixed = 6 * static_cast<Eigen::Index>(options.fixed_view);
    for (Eigen::Index i = 0; i < 6; ++i) {
      H.row(fixed + i).setZero();
      H.col(fixed + i).setZero();
      H(fixed + i, fixed + i) = 1.0;
      g[fixed + i] = 0.0;
    }
    H.diagonal() += 1e-9 * H.diagonal();
    const Eigen::VectorXd v = H.ldlt().solve(-g);
    double max_angle = 0.0, max_shift = 0.0;
    for (std::size_t k = 0; k < K; ++k) {
      const Eigen::Matrix<double, 6, 1> vk = v.segment<6>(6 * static_cast<Eigen::Index>(k));
      const RigidMotion step = RigidMotion::FromHelicalVelocity(vk.head<3>(), vk.tail<3>());
      result.world_T_scan[k] = step * result.world_T_scan[k];
      result.world_T_scan[k].normalize();
      max_angle = std::max(max_angle, step.angle());
      max_shift = std::max(max_shift, step.translation().norm());
    }
    result.sweeps = sweep + 1;
    result.rms_per_sweep.push_back(pairs_total ? std::sqrt(sum_sq / static_cast<double>(pairs_total)) : 0.0);
    if (max_angle <= options.rotation_tolerance && max_shift <= options.translation_tolerance * extent) {
      result.converged = true;
      break;
    }
  }
  return result;
}

}  // namespace s2m
