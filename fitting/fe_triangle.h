#pragma once
// L. Fang's C1-conforming 12-dof triangle (docs/fe-surfaces.md section 2, eqs. T1-T9; Fang 1994, sec. 4.2.2,
// after Zienkiewicz's 9-dof cubic triangle and Celniker's mid-edge correction): a vector field w(u, v) over a
// triangle of the parameter plane, interpolating at each vertex the value w and the slopes w_u, w_v, and at
// each edge's middle the slope w_n along the edge's GLOBALLY oriented normal (eq. T2), so that two triangles
// sharing an edge agree on the value and on the normal slope along the whole edge. The element is the
// building block of the fair finite-element surfaces (fitting/fe_surface.h): its shape functions, their first
// and second derivatives in (u, v), the element stiffness of the membrane and thin-plate energies, and the
// second-derivative rows used by the curvature-jump term across edges.

#include <Eigen/Core>
#include <array>
#include <vector>

namespace s2m {

// The global orientation of an edge of the parameter plane (eq. T2): the unit tangent t and the normal n =
// (-t_v, t_u) with t x n = +1, chosen so that n has a positive v component, or n = (1, 0) for an edge
// parallel to v. Both triangles on an edge compute the same frame from the edge's two end points, in either
// order.
struct EdgeFrame {
  Eigen::Vector2d tangent;
  Eigen::Vector2d normal;
};
EdgeFrame GlobalEdgeFrame(const Eigen::Vector2d& a, const Eigen::Vector2d& b);

// The shape functions of the 12 element dofs (order: w1, w1_u, w1_v, w2, w2_u, w2_v, w3, w3_u, w3_v, w_n12,
// w_n23, w_n31) and their derivatives in (u, v) at one point of the triangle.
struct TriangleShape {
  using Row = Eigen::Matrix<double, 1, 12>;
  Row value, du, dv, duu, duv, dvv;
};

// Gauss points of a triangle, all strictly inside it (the 12-dof element's second derivatives are singular at
// the vertices): barycentric coordinates and weights that sum to 1/2, the reference triangle's area (an
// integral over a triangle of area A is 2 A sum_q weight_q f(L_q)).
struct TriangleQuadrature {
  std::vector<Eigen::Vector3d> barycentric;
  std::vector<double> weights;
};

class ConformingTriangle {
 public:
  // The triangle's vertices in the parameter plane, counter-clockwise; throws std::invalid_argument for a
  // clockwise or degenerate (area below 1e-14 of the squared longest edge) triangle.
  ConformingTriangle(const Eigen::Vector2d& p1, const Eigen::Vector2d& p2, const Eigen::Vector2d& p3);

  const Eigen::Vector2d& vertex(int i) const { return vertices_[static_cast<std::size_t>(i)]; }
  double area() const { return 0.5 * twice_area_; }
  // Edge k joins vertex k to vertex (k + 1) % 3 (edges 12, 23, 31).
  const EdgeFrame& edge_frame(int k) const { return frames_[static_cast<std::size_t>(k)]; }

  // Shape functions at barycentric coordinates L (L1 + L2 + L3 = 1). At a vertex the mid-edge corrections
  // vanish with their first derivatives; their second derivatives have no limit there and are set to zero.
  TriangleShape Evaluate(const Eigen::Vector3d& barycentric) const;
  // The 9-dof (Zienkiewicz) element alone: columns 9-11 zero. For tests and for the documentation's claims.
  TriangleShape EvaluateNineDof(const Eigen::Vector3d& barycentric) const;

  Eigen::Vector3d Barycentric(const Eigen::Vector2d& uv) const;

  // The element matrix of stretch * membrane + bending * thin-plate energy (eq. T7), by the quadrature.
  Eigen::Matrix<double, 12, 12> Stiffness(double stretch, double bending,
                                          const TriangleQuadrature& rule) const;

 private:
  TriangleShape EvaluateImpl(const Eigen::Vector3d& barycentric, bool with_correction) const;

  std::array<Eigen::Vector2d, 3> vertices_;
  std::array<EdgeFrame, 3> frames_;
  double twice_area_ = 0.0;
  std::array<double, 3> b_{}, c_{};  // eq. T1: grad L_i = (b_i, c_i) / (2 area)
  // Z (eq. T5): the 9-dof field's normal slope at each edge's middle, per 9-dof dof; d (eq. T6): the normal
  // slope of the barycentric coordinate opposite each edge.
  Eigen::Matrix<double, 3, 9> mid_edge_slopes_ = Eigen::Matrix<double, 3, 9>::Zero();
  std::array<double, 3> opposite_slope_{};
};

// A collapsed (Duffy) Gauss-Legendre product rule of order x order points on the reference triangle, mapped
// to barycentric coordinates; exact for polynomials of degree 2 order - 2 and strictly interior.
TriangleQuadrature CollapsedGaussRule(int order);

// Gauss-Legendre nodes and weights on [0, 1].
void GaussLegendre01(int order, std::vector<double>& nodes, std::vector<double>& weights);

}  // namespace s2m
