#include "fitting/fe_surface.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>

namespace s2m {
namespace {

// The rows of the three second derivatives (w_uu, sqrt(2) w_uv, w_vv) at one point: the squared norm of their
// product with the dofs is the squared Frobenius norm of the Hessian, invariant under rotations of (u, v).
Eigen::Matrix<double, 3, 12> HessianRows(const TriangleShape& s) {
  Eigen::Matrix<double, 3, 12> rows;
  rows.row(0) = s.duu;
  rows.row(1) = std::sqrt(2.0) * s.duv;
  rows.row(2) = s.dvv;
  return rows;
}

}  // namespace

FeSurface::FeSurface(FeMesh mesh, int quadrature_order)
    : mesh_(std::move(mesh)), quadrature_(CollapsedGaussRule(quadrature_order)) {
  if (mesh_.triangles.empty())
    throw std::invalid_argument("finite-element surface: the mesh has no triangles");
  if (!mesh_.uv.allFinite())
    throw std::invalid_argument("finite-element surface: a mesh vertex is not finite");
  const int vertices = static_cast<int>(mesh_.uv.cols());
  std::map<std::pair<int, int>, int> edge_index;
  elements_.reserve(mesh_.triangles.size());
  for (std::size_t t = 0; t < mesh_.triangles.size(); ++t) {
    const auto& tri = mesh_.triangles[t];
    for (int v : tri)
      if (v < 0 || v >= vertices)
        throw std::invalid_argument("finite-element surface: triangle " + std::to_string(t) +
                                    " refers to vertex " + std::to_string(v) + " of " +
                                    std::to_string(vertices));
    try {
      elements_.emplace_back(mesh_.uv.col(tri[0]), mesh_.uv.col(tri[1]), mesh_.uv.col(tri[2]));
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("finite-element surface: triangle " + std::to_string(t) + ": " + e.what());
    }
    std::array<int, 3> local_edges{};
    for (std::size_t k = 0; k < 3; ++k) {
      const int a = tri[k], b = tri[(k + 1) % 3];
      const auto key = std::make_pair(std::min(a, b), std::max(a, b));
      auto found = edge_index.find(key);
      if (found == edge_index.end()) {
        found = edge_index.emplace(key, static_cast<int>(edges_.size())).first;
        edges_.push_back({key.first, key.second});
        edge_triangles_.push_back({static_cast<int>(t), -1});
      } else {
        auto& sides = edge_triangles_[static_cast<std::size_t>(found->second)];
        if (sides[1] >= 0)
          throw std::invalid_argument("finite-element surface: edge " + std::to_string(a) + "-" +
                                      std::to_string(b) + " is shared by more than two triangles");
        sides[1] = static_cast<int>(t);
      }
      local_edges[k] = found->second;
    }
    triangle_edges_.push_back(local_edges);
  }
  for (std::size_t t = 0; t < mesh_.triangles.size(); ++t) {
    std::array<int, 12> dofs{};
    for (std::size_t i = 0; i < 3; ++i)
      for (int which = 0; which < 3; ++which)
        dofs[3 * i + static_cast<std::size_t>(which)] = vertex_dof(mesh_.triangles[t][i], which);
    for (std::size_t k = 0; k < 3; ++k) dofs[9 + k] = edge_dof(triangle_edges_[t][k]);
    element_dofs_.push_back(dofs);
  }
  dofs_ = Eigen::MatrixX3d::Zero(dof_count(), 3);
}

int FeSurface::neighbour(int t, int k) const {
  const auto& sides = edge_triangles_[static_cast<std::size_t>(
      triangle_edges_[static_cast<std::size_t>(t)][static_cast<std::size_t>(k)])];
  return sides[0] == t ? sides[1] : sides[0];
}

void FeSurface::set_dofs(const Eigen::MatrixX3d& dofs) {
  if (dofs.rows() != dof_count())
    throw std::invalid_argument("finite-element surface: " + std::to_string(dofs.rows()) + " dofs given, " +
                                std::to_string(dof_count()) + " expected");
  dofs_ = dofs;
}

FeSurfaceGeometry FeSurface::Evaluate(const FeSurfacePoint& at) const {
  const TriangleShape s = element(at.triangle).Evaluate(at.barycentric);
  Eigen::Matrix<double, 12, 3> a;
  const auto& dofs = element_dofs(at.triangle);
  for (std::size_t d = 0; d < 12; ++d) a.row(static_cast<Eigen::Index>(d)) = dofs_.row(dofs[d]);
  FeSurfaceGeometry g;
  g.point = (s.value * a).transpose();
  g.d1.col(0) = (s.du * a).transpose();
  g.d1.col(1) = (s.dv * a).transpose();
  g.d2.col(0) = (s.duu * a).transpose();
  g.d2.col(1) = (s.duv * a).transpose();
  g.d2.col(2) = (s.dvv * a).transpose();
  return g;
}

Eigen::Vector2d FeSurface::ParameterOf(const FeSurfacePoint& at) const {
  const ConformingTriangle& e = element(at.triangle);
  return at.barycentric(0) * e.vertex(0) + at.barycentric(1) * e.vertex(1) + at.barycentric(2) * e.vertex(2);
}

bool FeSurface::Locate(const Eigen::Vector2d& uv, FeSurfacePoint& at) const {
  int t = std::clamp(at.triangle, 0, triangle_count() - 1);
  // Lawson's walk: step across the edge opposite the most negative barycentric coordinate. It terminates on
  // Delaunay meshes; on others it may cycle, so it is bounded and falls back to visiting every triangle.
  for (int step = 0; step <= triangle_count(); ++step) {
    const Eigen::Vector3d L = element(t).Barycentric(uv);
    int worst = 0;
    L.minCoeff(&worst);
    if (L(worst) >= -1e-12) {
      at.triangle = t;
      at.barycentric = L.cwiseMax(0.0) / L.cwiseMax(0.0).sum();
      return true;
    }
    // The edge opposite vertex i is local edge (i + 1) % 3; prefer a negative side that has a neighbour.
    int next = neighbour(t, (worst + 1) % 3);
    if (next < 0)
      for (int i = 0; i < 3 && next < 0; ++i)
        if (L(i) < -1e-12) next = neighbour(t, (i + 1) % 3);
    if (next < 0) {
      // Outside the domain: the nearest point of this triangle's boundary edges on the negative sides.
      double best = std::numeric_limits<double>::infinity();
      for (int i = 0; i < 3; ++i) {
        if (L(i) >= -1e-12) continue;
        const int k = (i + 1) % 3;
        const Eigen::Vector2d a = element(t).vertex(k), b = element(t).vertex((k + 1) % 3);
        const double s = std::clamp((uv - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
        const double distance = (a + s * (b - a) - uv).squaredNorm();
        if (distance < best) {
          best = distance;
          at.triangle = t;
          at.barycentric.setZero();
          at.barycentric(k) = 1.0 - s;
          at.barycentric((k + 1) % 3) = s;
        }
      }
      return false;
    }
    t = next;
  }
  double best = -std::numeric_limits<double>::infinity();
  for (int c = 0; c < triangle_count(); ++c) {
    const Eigen::Vector3d L = element(c).Barycentric(uv);
    if (L.minCoeff() > best) best = L.minCoeff(), at.triangle = c;
  }
  if (best >= -1e-12) {
    const Eigen::Vector3d L = element(at.triangle).Barycentric(uv).cwiseMax(0.0);
    at.barycentric = L / L.sum();
    return true;
  }
  FeSurfacePoint start{at.triangle, Eigen::Vector3d::Constant(1.0 / 3.0)};
  at = start;
  return Locate(uv, at);
}

Eigen::SparseMatrix<double> FeSurface::JumpMatrix() const {
  // Eq. P4: the integral along every interior edge of |Hessian_alpha - Hessian_beta|^2 (Frobenius norm) over
  // arc length, by Gauss-Legendre points strictly inside the edge (the elements' second derivatives are
  // singular at the vertices).
  std::vector<double> x, w;
  GaussLegendre01(6, x, w);
  std::vector<Eigen::Triplet<double>> triplets;
  for (int e = 0; e < edge_count(); ++e) {
    const auto& sides = edge_triangles(e);
    if (sides[1] < 0) continue;
    const Eigen::Vector2d a = mesh_.uv.col(edge(e)[0]), b = mesh_.uv.col(edge(e)[1]);
    const double length = (b - a).norm();
    Eigen::Matrix<double, 24, 24> block = Eigen::Matrix<double, 24, 24>::Zero();
    for (std::size_t q = 0; q < x.size(); ++q) {
      const Eigen::Vector2d p = a + x[q] * (b - a);
      Eigen::Matrix<double, 3, 24> rows;
      rows.leftCols<12>() = HessianRows(element(sides[0]).Evaluate(element(sides[0]).Barycentric(p)));
      rows.rightCols<12>() = -HessianRows(element(sides[1]).Evaluate(element(sides[1]).Barycentric(p)));
      block.noalias() += (w[q] * length) * rows.transpose() * rows;
    }
    for (int i = 0; i < 24; ++i)
      for (int j = 0; j < 24; ++j) {
        const int di =
            element_dofs(sides[static_cast<std::size_t>(i / 12)])[static_cast<std::size_t>(i % 12)];
        const int dj =
            element_dofs(sides[static_cast<std::size_t>(j / 12)])[static_cast<std::size_t>(j % 12)];
        triplets.emplace_back(di, dj, block(i, j));
      }
  }
  Eigen::SparseMatrix<double> k(dof_count(), dof_count());
  k.setFromTriplets(triplets.begin(), triplets.end());
  return k;
}

Eigen::SparseMatrix<double> FeSurface::EnergyMatrix(const FairnessWeights& weights) const {
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<std::size_t>(triangle_count()) * 144);
  if (weights.stretch != 0.0 || weights.bending != 0.0)
    for (int t = 0; t < triangle_count(); ++t) {
      const Eigen::Matrix<double, 12, 12> k =
          element(t).Stiffness(weights.stretch, weights.bending, quadrature_);
      const auto& dofs = element_dofs(t);
      for (int i = 0; i < 12; ++i)
        for (int j = 0; j < 12; ++j)
          triplets.emplace_back(dofs[static_cast<std::size_t>(i)], dofs[static_cast<std::size_t>(j)],
                                k(i, j));
    }
  Eigen::SparseMatrix<double> k(dof_count(), dof_count());
  k.setFromTriplets(triplets.begin(), triplets.end());
  if (weights.jump2 != 0.0) k += weights.jump2 * JumpMatrix();
  return k;
}

FeSurfaceEnergy FeSurface::Energy(const FairnessWeights& weights) const {
  const auto quadratic = [this](const Eigen::SparseMatrix<double>& k) {
    return (dofs_.transpose() * (k * dofs_)).trace();
  };
  FeSurfaceEnergy e;
  FairnessWeights only;
  if (weights.stretch != 0.0) {
    only = {};
    only.stretch = weights.stretch;
    e.stretch = quadratic(EnergyMatrix(only));
  }
  if (weights.bending != 0.0) {
    only = {};
    only.bending = weights.bending;
    e.bending = quadratic(EnergyMatrix(only));
  }
  if (weights.jump2 != 0.0) e.jump = weights.jump2 * quadratic(JumpMatrix());
  return e;
}

std::vector<FeSurfacePoint> FeSurface::SamplePoints(int per_edge) const {
  std::vector<FeSurfacePoint> out;
  const int n = std::max(per_edge, 1);
  for (int t = 0; t < triangle_count(); ++t)
    for (int i = 0; i <= n; ++i)
      for (int j = 0; i + j <= n; ++j) out.push_back({t, Eigen::Vector3d(n - i - j, i, j) / n});
  return out;
}

}  // namespace s2m
