#pragma once
// A fair finite-element surface after L. Fang (docs/fe-surfaces.md section 3; Fang 1994, sec. 4.2): a C1
// vector field w(u, v) in R^3 over a triangulated domain of the parameter plane, one 12-dof conforming
// triangle (fitting/fe_triangle.h) per face. Global dofs: three vector dofs per vertex (w, w_u, w_v in the
// global (u, v)) and one per edge (the slope along the edge's globally oriented normal), eq. P1; each is a
// point of R^3, so the dofs form a dof_count x 3 matrix and the fairness energy decouples into x, y and z.

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <array>
#include <string>
#include <vector>

#include "fitting/fe_triangle.h"
#include "fitting/parametric_model.h"

namespace s2m {

struct FeMesh {
  Eigen::Matrix2Xd uv;                        // vertices in the parameter plane
  std::vector<std::array<int, 3>> triangles;  // counter-clockwise vertex indices
};

// A point of the surface's domain: the host triangle and the barycentric coordinates in it.
struct FeSurfacePoint {
  int triangle = 0;
  Eigen::Vector3d barycentric = Eigen::Vector3d::Constant(1.0 / 3.0);
};

// The point and its (u, v) derivatives: d2 columns w_uu, w_uv, w_vv (as ParametricModel's LocalGeometry).
struct FeSurfaceGeometry {
  Eigen::Vector3d point;
  Eigen::Matrix<double, 3, 2> d1;
  Eigen::Matrix3d d2;
};

// The energy terms of eq. P3, each the sum over x, y and z.
struct FeSurfaceEnergy {
  double stretch = 0.0, bending = 0.0, jump = 0.0;
};

class FeSurface {
 public:
  // Throws std::invalid_argument naming the problem: no triangles, an index out of range, a non-finite
  // vertex, a clockwise or degenerate triangle, an edge shared by more than two triangles.
  explicit FeSurface(FeMesh mesh, int quadrature_order = 6);

  const FeMesh& mesh() const { return mesh_; }
  int vertex_count() const { return static_cast<int>(mesh_.uv.cols()); }
  int edge_count() const { return static_cast<int>(edges_.size()); }
  int triangle_count() const { return static_cast<int>(mesh_.triangles.size()); }
  int dof_count() const { return 3 * vertex_count() + edge_count(); }
  // Global dof numbers: vertex i's w, w_u, w_v are 3i, 3i + 1, 3i + 2; edge e's slope is 3 vertex_count + e.
  int vertex_dof(int vertex, int which) const { return 3 * vertex + which; }
  int edge_dof(int edge) const { return 3 * vertex_count() + edge; }
  const std::array<int, 2>& edge(int e) const { return edges_[static_cast<std::size_t>(e)]; }
  // The triangles on each side of an edge (the second is -1 on the boundary).
  const std::array<int, 2>& edge_triangles(int e) const {
    return edge_triangles_[static_cast<std::size_t>(e)];
  }
  bool boundary_edge(int e) const { return edge_triangles(e)[1] < 0; }
  const ConformingTriangle& element(int t) const { return elements_[static_cast<std::size_t>(t)]; }
  // The 12 global dofs of triangle t in the element's order (fitting/fe_triangle.h).
  const std::array<int, 12>& element_dofs(int t) const { return element_dofs_[static_cast<std::size_t>(t)]; }
  // The triangle across local edge k of triangle t (-1 on the boundary).
  int neighbour(int t, int k) const;

  const Eigen::MatrixX3d& dofs() const { return dofs_; }
  void set_dofs(const Eigen::MatrixX3d& dofs);

  FeSurfaceGeometry Evaluate(const FeSurfacePoint& at) const;
  Eigen::Vector2d ParameterOf(const FeSurfacePoint& at) const;
  // Walks from `at` to the triangle containing uv (Lawson's visibility walk). Returns false when uv is
  // outside the domain: `at` is then the nearest point of the boundary edge the walk left through.
  bool Locate(const Eigen::Vector2d& uv, FeSurfacePoint& at) const;

  // K of eq. P3 (dof_count square, symmetric): stretch * membrane + bending * thin plate + jump * C2-jump.
  Eigen::SparseMatrix<double> EnergyMatrix(const FairnessWeights& weights) const;
  FeSurfaceEnergy Energy(const FairnessWeights& weights) const;

  // Sets the dofs to interpolate a field given by its value and first derivatives at a parameter point (the
  // vertex dofs from the derivatives there, the edge dofs from the slope along the edge normal at the
  // middle).
  template <typename Field>  // Field: (const Eigen::Vector2d&) -> Eigen::Matrix<double, 3, 3> [w w_u w_v]
  void Interpolate(const Field& field);

  // Every triangle's barycentric grid with per_edge + 1 points along each side (points on shared edges
  // repeat).
  std::vector<FeSurfacePoint> SamplePoints(int per_edge) const;

 private:
  Eigen::SparseMatrix<double> JumpMatrix() const;

  FeMesh mesh_;
  TriangleQuadrature quadrature_;
  std::vector<ConformingTriangle> elements_;
  std::vector<std::array<int, 2>> edges_;
  std::vector<std::array<int, 2>> edge_triangles_;
  std::vector<std::array<int, 3>> triangle_edges_;  // local edge k -> global edge
  std::vector<std::array<int, 12>> element_dofs_;
  Eigen::MatrixX3d dofs_;
};

template <typename Field>
void FeSurface::Interpolate(const Field& field) {
  Eigen::MatrixX3d q(dof_count(), 3);
  for (int i = 0; i < vertex_count(); ++i) {
    const Eigen::Matrix3d f = field(Eigen::Vector2d(mesh_.uv.col(i)));
    for (int which = 0; which < 3; ++which) q.row(vertex_dof(i, which)) = f.col(which).transpose();
  }
  for (int e = 0; e < edge_count(); ++e) {
    const Eigen::Vector2d a = mesh_.uv.col(edges_[static_cast<std::size_t>(e)][0]);
    const Eigen::Vector2d b = mesh_.uv.col(edges_[static_cast<std::size_t>(e)][1]);
    const Eigen::Matrix3d f = field(Eigen::Vector2d(0.5 * (a + b)));
    const Eigen::Vector2d n = GlobalEdgeFrame(a, b).normal;
    q.row(edge_dof(e)) = (n.x() * f.col(1) + n.y() * f.col(2)).transpose();
  }
  set_dofs(q);
}

}  // namespace s2m
