#include "fitting/fe_triangle.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "fitting/domain_mesh.h"

namespace s2m {
namespace {

// A function of (u, v) with its gradient and Hessian, propagated through the arithmetic of the shape
// functions (forward-mode second-order differentiation): the shape functions are written once, in barycentric
// coordinates, and their (u, v) derivatives of first and second order come out exact to rounding.
struct Jet {
  double v = 0.0;
  double gu = 0.0, gv = 0.0;
  double huu = 0.0, huv = 0.0, hvv = 0.0;
};

Jet operator+(const Jet& a, const Jet& b) {
  return {a.v + b.v, a.gu + b.gu, a.gv + b.gv, a.huu + b.huu, a.huv + b.huv, a.hvv + b.hvv};
}
Jet operator-(const Jet& a, const Jet& b) {
  return {a.v - b.v, a.gu - b.gu, a.gv - b.gv, a.huu - b.huu, a.huv - b.huv, a.hvv - b.hvv};
}
Jet operator*(double s, const Jet& a) {
  return {s * a.v, s * a.gu, s * a.gv, s * a.huu, s * a.huv, s * a.hvv};
}
Jet operator*(const Jet& a, const Jet& b) {
  return {a.v * b.v,
          a.gu * b.v + a.v * b.gu,
          a.gv * b.v + a.v * b.gv,
          a.huu * b.v + 2.0 * a.gu * b.gu + a.v * b.huu,
          a.huv * b.v + a.gu * b.gv + a.gv * b.gu + a.v * b.huv,
          a.hvv * b.v + 2.0 * a.gv * b.gv + a.v * b.hvv};
}
Jet Reciprocal(const Jet& b) {
  const double r = 1.0 / b.v, r2 = r * r, r3 = r2 * r;
  return {r,
          -b.gu * r2,
          -b.gv * r2,
          -b.huu * r2 + 2.0 * b.gu * b.gu * r3,
          -b.huv * r2 + 2.0 * b.gu * b.gv * r3,
          -b.hvv * r2 + 2.0 * b.gv * b.gv * r3};
}

// Zienkiewicz's 9-dof shape functions (eq. T3) for the vertex i (0-based) with j, k the next ones cyclically:
//   f_i = L_i + L_i^2 L_j + L_i^2 L_k - L_i L_j^2 - L_i L_k^2,
//   f_ij = L_i^2 L_j + L_1 L_2 L_3 / 2,   f_ik = L_i^2 L_k + L_1 L_2 L_3 / 2,
//   value: f_i,  u-slope: c_k f_ij - c_j f_ik,  v-slope: -b_k f_ij + b_j f_ik.
// The half bubble makes the element reproduce every quadratic exactly.
void NineDofJets(const std::array<Jet, 3>& L, const std::array<double, 3>& b, const std::array<double, 3>& c,
                 std::array<Jet, 12>& n) {
  const Jet bubble = 0.5 * (L[0] * L[1] * L[2]);
  for (std::size_t i = 0; i < 3; ++i) {
    const std::size_t j = (i + 1) % 3, k = (i + 2) % 3;
    const Jet ii = L[i] * L[i];
    const Jet f = L[i] + ii * L[j] + ii * L[k] - L[i] * L[j] * L[j] - L[i] * L[k] * L[k];
    const Jet fij = ii * L[j] + bubble;
    const Jet fik = ii * L[k] + bubble;
    n[3 * i] = f;
    n[3 * i + 1] = c[k] * fij - c[j] * fik;
    n[3 * i + 2] = (-b[k]) * fij + b[j] * fik;
  }
  for (std::size_t e = 9; e < 12; ++e) n[e] = Jet{};
}

std::array<Jet, 3> BarycentricJets(const Eigen::Vector3d& L, const std::array<double, 3>& b,
                                   const std::array<double, 3>& c, double twice_area) {
  std::array<Jet, 3> out;
  for (std::size_t i = 0; i < 3; ++i)
    out[i] = {L(static_cast<Eigen::Index>(i)), b[i] / twice_area, c[i] / twice_area, 0.0, 0.0, 0.0};
  return out;
}

}  // namespace

EdgeFrame GlobalEdgeFrame(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  // Eq. T2: the direction of docs/fe-surfaces.md eq. D2 (one definition, fitting/domain_mesh.h); b - a and a
  // - b are exact negatives, so both orders of the end points give bit-identical frames.
  const Eigen::Vector2d t =
      (IsGlobalEdgeDirection(a, b) ? Eigen::Vector2d(b - a) : Eigen::Vector2d(a - b)).normalized();
  return {t, Eigen::Vector2d(-t.y(), t.x())};
}

ConformingTriangle::ConformingTriangle(const Eigen::Vector2d& p1, const Eigen::Vector2d& p2,
                                       const Eigen::Vector2d& p3)
    : vertices_{p1, p2, p3} {
  for (const auto& p : vertices_)
    if (!p.allFinite()) throw std::invalid_argument("triangle element: a vertex is not finite");
  twice_area_ = (p2.x() - p1.x()) * (p3.y() - p1.y()) - (p3.x() - p1.x()) * (p2.y() - p1.y());
  const double longest =
      std::max({(p2 - p1).squaredNorm(), (p3 - p2).squaredNorm(), (p1 - p3).squaredNorm()});
  if (!(twice_area_ > 2e-14 * longest))
    throw std::invalid_argument(twice_area_ < 0 ? "triangle element: vertices are clockwise"
                                                : "triangle element: degenerate (zero-area) triangle");
  // Eq. T1: L_i = (a_i + b_i u + c_i v) / (2 area), b_i = v_j - v_k, c_i = u_k - u_j.
  for (std::size_t i = 0; i < 3; ++i) {
    const std::size_t j = (i + 1) % 3, k = (i + 2) % 3;
    b_[i] = vertices_[j].y() - vertices_[k].y();
    c_[i] = vertices_[k].x() - vertices_[j].x();
  }
  for (std::size_t k = 0; k < 3; ++k) frames_[k] = GlobalEdgeFrame(vertices_[k], vertices_[(k + 1) % 3]);

  // Eqs. T5-T6: the 9-dof field's normal slope at each edge's middle, and the normal slope of the
  // barycentric coordinate of the opposite vertex.
  for (int k = 0; k < 3; ++k) {
    Eigen::Vector3d mid = Eigen::Vector3d::Zero();
    mid(k) = 0.5;
    mid((k + 1) % 3) = 0.5;
    std::array<Jet, 12> n;
    NineDofJets(BarycentricJets(mid, b_, c_, twice_area_), b_, c_, n);
    const Eigen::Vector2d& normal = frames_[static_cast<std::size_t>(k)].normal;
    for (int j = 0; j < 9; ++j)
      mid_edge_slopes_(k, j) =
          normal.x() * n[static_cast<std::size_t>(j)].gu + normal.y() * n[static_cast<std::size_t>(j)].gv;
    const std::size_t opposite = static_cast<std::size_t>((k + 2) % 3);
    opposite_slope_[static_cast<std::size_t>(k)] =
        (normal.x() * b_[opposite] + normal.y() * c_[opposite]) / twice_area_;
  }
}

Eigen::Vector3d ConformingTriangle::Barycentric(const Eigen::Vector2d& uv) const {
  Eigen::Vector3d L;
  for (std::size_t i = 0; i < 3; ++i) {
    const std::size_t j = (i + 1) % 3, k = (i + 2) % 3;
    const double a = vertices_[j].x() * vertices_[k].y() - vertices_[k].x() * vertices_[j].y();
    L(static_cast<Eigen::Index>(i)) = (a + b_[i] * uv.x() + c_[i] * uv.y()) / twice_area_;
  }
  return L;
}

TriangleShape ConformingTriangle::Evaluate(const Eigen::Vector3d& barycentric) const {
  return EvaluateImpl(barycentric, true);
}

TriangleShape ConformingTriangle::EvaluateNineDof(const Eigen::Vector3d& barycentric) const {
  return EvaluateImpl(barycentric, false);
}

TriangleShape ConformingTriangle::EvaluateImpl(const Eigen::Vector3d& barycentric,
                                               bool with_correction) const {
  const std::array<Jet, 3> L = BarycentricJets(barycentric, b_, c_, twice_area_);
  std::array<Jet, 12> n;
  NineDofJets(L, b_, c_, n);
  if (with_correction) {
    // Eqs. T8-T9: for edge k from vertex i to vertex j, opposite vertex o, the correction function
    //   e_k = L_o L_i^2 L_j^2 / ((L_o + L_i)(L_o + L_j))
    // is zero with its tangential slope on all three edges, and its normal slope on edge k is d_k L_i L_j
    // (d_k = dL_o/dn_k), zero on the other two; so 4 e_k / d_k carries a unit normal slope at edge k's
    // middle, parabolic along the edge. It replaces the 9-dof field's mid-edge slope by the dof w_nk.
    for (std::size_t k = 0; k < 3; ++k) {
      const std::size_t i = k, j = (k + 1) % 3, o = (k + 2) % 3;
      const Jet oi = L[o] + L[i], oj = L[o] + L[j];
      Jet e;  // zero, with zero first derivatives, at the vertices i and j where it is 0/0
      if (oi.v > 1e-300 && oj.v > 1e-300) e = L[o] * L[i] * L[i] * L[j] * L[j] * Reciprocal(oi * oj);
      const Jet correction = (4.0 / opposite_slope_[k]) * e;
      for (std::size_t d = 0; d < 9; ++d)
        n[d] =
            n[d] - mid_edge_slopes_(static_cast<Eigen::Index>(k), static_cast<Eigen::Index>(d)) * correction;
      n[9 + k] = correction;
    }
  }
  TriangleShape out;
  for (std::size_t d = 0; d < 12; ++d) {
    const Eigen::Index col = static_cast<Eigen::Index>(d);
    out.value(col) = n[d].v;
    out.du(col) = n[d].gu;
    out.dv(col) = n[d].gv;
    out.duu(col) = n[d].huu;
    out.duv(col) = n[d].huv;
    out.dvv(col) = n[d].hvv;
  }
  return out;
}

Eigen::Matrix<double, 12, 12> ConformingTriangle::Stiffness(double stretch, double bending,
                                                            const TriangleQuadrature& rule) const {
  // Eq. T7: K = integral of stretch (N_u^T N_u + N_v^T N_v) + bending (N_uu^T N_uu + 2 N_uv^T N_uv + N_vv^T
  // N_vv) over the triangle: the membrane and the rotation-invariant thin-plate energies of each coordinate.
  Eigen::Matrix<double, 12, 12> k = Eigen::Matrix<double, 12, 12>::Zero();
  for (std::size_t q = 0; q < rule.weights.size(); ++q) {
    const TriangleShape s = Evaluate(rule.barycentric[q]);
    const double w = rule.weights[q] * twice_area_;
    if (stretch != 0.0) k.noalias() += (w * stretch) * (s.du.transpose() * s.du + s.dv.transpose() * s.dv);
    if (bending != 0.0)
      k.noalias() += (w * bending) * (s.duu.transpose() * s.duu + 2.0 * s.duv.transpose() * s.duv +
                                      s.dvv.transpose() * s.dvv);
  }
  return k;
}

void GaussLegendre01(int order, std::vector<double>& nodes, std::vector<double>& weights) {
  if (order < 1) throw std::invalid_argument("Gauss-Legendre rule: order must be at least 1");
  // Golub-Welsch: the nodes on [-1, 1] are the eigenvalues of the Jacobi matrix of the Legendre recurrence,
  // beta_k = k / sqrt(4 k^2 - 1); the weights are 2 times the squared first components of the eigenvectors.
  Eigen::MatrixXd jacobi = Eigen::MatrixXd::Zero(order, order);
  for (int k = 1; k < order; ++k) {
    const double beta = k / std::sqrt(4.0 * k * k - 1.0);
    jacobi(k, k - 1) = jacobi(k - 1, k) = beta;
  }
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(jacobi);
  nodes.resize(static_cast<std::size_t>(order));
  weights.resize(static_cast<std::size_t>(order));
  for (int i = 0; i < order; ++i) {
    nodes[static_cast<std::size_t>(i)] = 0.5 * (solver.eigenvalues()(i) + 1.0);
    const double first = solver.eigenvectors()(0, i);
    weights[static_cast<std::size_t>(i)] = first * first;  // 2 first^2 on [-1, 1], halved on [0, 1]
  }
}

TriangleQuadrature CollapsedGaussRule(int order) {
  std::vector<double> x, w;
  GaussLegendre01(order, x, w);
  TriangleQuadrature rule;
  // Four sub-triangles (the three corners and the middle one of the mid-edge split). Each corner triangle is
  // the image of [0, 1]^2 under P(s, t) = A + s ((B - A) + t (C - B)), collapsed at its vertex A (Jacobian
  // proportional to s): the element's second derivatives near a vertex depend on the direction only (the
  // correction functions are homogeneous there), so in (s, t) they are smooth and the product rule converges
  // fast. Each sub-triangle has a quarter of the reference area 1/2, so a point's weight is w_s w_t s / 4.
  const Eigen::Matrix3d corners = Eigen::Matrix3d::Identity();
  const auto mid = [&corners](int i, int j) {
    return Eigen::Vector3d(0.5 * (corners.col(i) + corners.col(j)));
  };
  const std::array<std::array<Eigen::Vector3d, 3>, 4> pieces = {{{corners.col(0), mid(0, 1), mid(2, 0)},
                                                                 {corners.col(1), mid(1, 2), mid(0, 1)},
                                                                 {corners.col(2), mid(2, 0), mid(1, 2)},
                                                                 {mid(0, 1), mid(1, 2), mid(2, 0)}}};
  for (const auto& piece : pieces)
    for (std::size_t i = 0; i < x.size(); ++i)
      for (std::size_t j = 0; j < x.size(); ++j) {
        rule.barycentric.push_back(piece[0] + x[i] * ((piece[1] - piece[0]) + x[j] * (piece[2] - piece[1])));
        rule.weights.push_back(0.25 * w[i] * w[j] * x[i]);
      }
  return rule;
}

}  // namespace s2m
