#include "fitting/fe_surface_fit.h"

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "fitting/geometric_fit.h"

namespace s2m {
namespace {

double DomainArea(const FeSurface& surface) {
  double area = 0.0;
  for (int t = 0; t < surface.triangle_count(); ++t) area += surface.element(t).area();
  return area;
}

double DomainDiameter(const FeSurface& surface) {
  const Eigen::Matrix2Xd& uv = surface.mesh().uv;
  return (uv.rowwise().maxCoeff() - uv.rowwise().minCoeff()).norm();
}

// The reduced transformation of eq. P9 for constraints that fix components of single vector dofs: the step
// delta = T y with T block-diagonal, one 3 x m_d block per dof whose orthonormal columns span the complement
// of the dof's fixed directions (m_d = 3 for a free dof, 0 for a dof fixed in three independent directions).
Eigen::SparseMatrix<double> ReducedBasis(const std::vector<FeFixedDirection>& fixed, int dofs) {
  std::vector<std::vector<Eigen::Vector3d>> directions(static_cast<std::size_t>(dofs));
  for (const FeFixedDirection& f : fixed) {
    if (f.dof < 0 || f.dof >= dofs)
      throw std::invalid_argument("finite-element surface fit: a fixed direction of dof " +
                                  std::to_string(f.dof) + ", out of range (" + std::to_string(dofs) +
                                  " dofs)");
    if (!f.direction.allFinite() || !(f.direction.norm() > 0.0))
      throw std::invalid_argument("finite-element surface fit: a fixed direction of dof " +
                                  std::to_string(f.dof) + " is zero or not finite");
    directions[static_cast<std::size_t>(f.dof)].push_back(f.direction.normalized());
  }
  std::vector<Eigen::Triplet<double>> triplets;
  int column = 0;
  for (int d = 0; d < dofs; ++d) {
    const std::vector<Eigen::Vector3d>& mine = directions[static_cast<std::size_t>(d)];
    Eigen::Matrix3d free = Eigen::Matrix3d::Identity();
    int free_count = 3;
    if (!mine.empty()) {
      Eigen::Matrix3Xd a(3, static_cast<Eigen::Index>(mine.size()));
      for (std::size_t i = 0; i < mine.size(); ++i) a.col(static_cast<Eigen::Index>(i)) = mine[i];
      // The left singular vectors beyond the directions' rank span their orthogonal complement.
      const Eigen::JacobiSVD<Eigen::Matrix3Xd> svd(a, Eigen::ComputeFullU);
      int rank = 0;
      for (Eigen::Index i = 0; i < svd.singularValues().size(); ++i)
        if (svd.singularValues()(i) > 1e-10 * svd.singularValues()(0)) ++rank;
      free_count = 3 - rank;
      free.leftCols(free_count) = svd.matrixU().rightCols(free_count);
    }
    for (int j = 0; j < free_count; ++j, ++column)
      for (int c = 0; c < 3; ++c)
        if (free(c, j) != 0.0) triplets.emplace_back(3 * d + c, column, free(c, j));
  }
  Eigen::SparseMatrix<double> t(3 * dofs, column);
  t.setFromTriplets(triplets.begin(), triplets.end());
  return t;
}

}  // namespace

bool FeSurfaceFitOptions::IsValid(std::string* why) const {
  const auto fail = [why](const char* message) {
    if (why) *why = message;
    return false;
  };
  if (!(stretch >= 0.0) || !(bending >= 0.0) || !(jump >= 0.0) || !std::isfinite(stretch + bending + jump))
    return fail("fairness weights must be finite and non-negative");
  if (method != ErrorTerm::kPdm && method != ErrorTerm::kTdm && method != ErrorTerm::kSdm &&
      method != ErrorTerm::kCdm)
    return fail("the error term must be pdm, tdm, sdm or cdm");
  if (max_iterations < 1) return fail("max_iterations must be at least 1");
  if (!(tolerance > 0.0)) return fail("tolerance must be positive");
  return true;
}

FairnessWeights AbsoluteFairnessWeights(const FeSurfaceFitOptions& options, const FeSurface& surface,
                                        int point_count) {
  const double d = DomainDiameter(surface), a = DomainArea(surface), n = point_count;
  FairnessWeights w;
  w.stretch = options.stretch * n * d * d / a;
  w.bending = options.bending * n * std::pow(d, 4) / a;
  w.jump2 = options.jump * n * std::pow(d, 3);
  return w;
}

bool FeFootPoint(const FeSurface& surface, const Eigen::Vector3d& x, FeSurfacePoint& at) {
  const double scale = DomainDiameter(surface);
  bool inside = true;
  FeSurfaceGeometry g = surface.Evaluate(at);
  double distance2 = (x - g.point).squaredNorm();
  for (int iteration = 0; iteration < 30; ++iteration) {
    const Eigen::Vector3d r = x - g.point;
    const Eigen::Matrix2d jtj = g.d1.transpose() * g.d1;
    Eigen::Matrix2d h = jtj;
    h(0, 0) -= r.dot(g.d2.col(0));
    h(0, 1) -= r.dot(g.d2.col(1));
    h(1, 0) = h(0, 1);
    h(1, 1) -= r.dot(g.d2.col(2));
    if (!(h(0, 0) > 0.0 && h.determinant() > 0.0))
      h = jtj;  // Gauss-Newton where Newton's model is not convex
    Eigen::Vector2d step = h.ldlt().solve(g.d1.transpose() * r);
    if (!step.allFinite()) return inside;
    if (step.norm() > 0.25 * scale) step *= 0.25 * scale / step.norm();
    const Eigen::Vector2d uv = surface.ParameterOf(at);
    bool improved = false;
    for (int halving = 0; halving < 12 && !improved; ++halving, step *= 0.5) {
      FeSurfacePoint next = at;
      const bool next_inside = surface.Locate(uv + step, next);
      const FeSurfaceGeometry ng = surface.Evaluate(next);
      const double nd2 = (x - ng.point).squaredNorm();
      if (nd2 <= distance2) {
        const double moved = (surface.ParameterOf(next) - uv).norm();
        at = next;
        g = ng;
        distance2 = nd2;
        inside = next_inside;
        improved = true;
        if (moved < 1e-13 * scale) return inside;
      }
    }
    if (!improved) return inside;
  }
  return inside;
}

FeSurfaceFitResult FitFeSurface(const Eigen::Matrix3Xd& points, const Eigen::Matrix2Xd& start_uv,
                                const FeSurfaceFitOptions& options, FeSurface& surface,
                                const std::vector<FeFixedDirection>& fixed) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument("finite-element surface fit: " + why);
  if (points.cols() != start_uv.cols())
    throw std::invalid_argument("finite-element surface fit: " + std::to_string(points.cols()) +
                                " points but " + std::to_string(start_uv.cols()) + " start parameters");
  if (points.cols() < 3) throw std::invalid_argument("finite-element surface fit: fewer than 3 points");
  if (!points.allFinite() || !start_uv.allFinite())
    throw std::invalid_argument("finite-element surface fit: a point or start parameter is not finite");
  const int n = static_cast<int>(points.cols());
  const Eigen::SparseMatrix<double> reduced_basis = ReducedBasis(fixed, surface.dof_count());
  FeSurfaceFitResult result;
  result.weights = AbsoluteFairnessWeights(options, surface, n);
  const Eigen::SparseMatrix<double> k = surface.EnergyMatrix(result.weights);
  const int dofs = surface.dof_count();

  // Feet at the start parameters (outside points clamp to the boundary).
  result.feet.assign(static_cast<std::size_t>(n), FeSurfacePoint{});
  std::vector<char> inside(static_cast<std::size_t>(n), 1);
  FeSurfacePoint walker;
  for (int i = 0; i < n; ++i) {
    inside[static_cast<std::size_t>(i)] = surface.Locate(start_uv.col(i), walker) ? 1 : 0;
    result.feet[static_cast<std::size_t>(i)] = walker;
  }
  bool fixed_start = true;  // the first step fits with the points held at their start parameters

  const auto fairness = [&k](const Eigen::MatrixX3d& q) { return (q.transpose() * (k * q)).trace(); };
  const auto closeness = [&](std::vector<FeSurfacePoint>& feet, std::vector<char>& in) {
    double sum = 0.0;
#pragma omp parallel for reduction(+ : sum) schedule(static)
    for (int i = 0; i < n; ++i) {
      in[static_cast<std::size_t>(i)] =
          FeFootPoint(surface, points.col(i), feet[static_cast<std::size_t>(i)]) ? 1 : 0;
      sum += (points.col(i) - surface.Evaluate(feet[static_cast<std::size_t>(i)]).point).squaredNorm();
    }
    return sum;
  };

  double objective = std::numeric_limits<double>::infinity();
  result.objective.push_back(objective);
  double damping = 1e-9;
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    // Eq. P7: the normal equations of the step delta (3 dofs x, y, z per scalar dof, index 3 dof + c):
    //   (sum_i (N_i^T N_i) (x) M_i + K (x) I3 + damping diag) delta = sum_i N_i^T (x) M_i r_i - (K (x) I3) q,
    // M_i the point's error matrix (PDM: I; TDM: n n^T; SDM: Pottmann-Hofer's, docs/method.md eq. 5); feet on
    // the boundary use PDM (their residual is not along the normal).
    std::vector<Eigen::Matrix<double, 36, 36>> blocks(static_cast<std::size_t>(surface.triangle_count()),
                                                      Eigen::Matrix<double, 36, 36>::Zero());
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(3 * dofs);
    for (int i = 0; i < n; ++i) {
      const FeSurfacePoint& foot = result.feet[static_cast<std::size_t>(i)];
      const TriangleShape s = surface.element(foot.triangle).Evaluate(foot.barycentric);
      const FeSurfaceGeometry g = surface.Evaluate(foot);
      const Eigen::Vector3d r = points.col(i) - g.point;
      Eigen::Matrix3d m = Eigen::Matrix3d::Identity();
      if (options.method != ErrorTerm::kPdm && inside[static_cast<std::size_t>(i)] && !fixed_start) {
        // The engine's error matrices (fitting/geometric_fit.h, docs/method.md section 2) in the principal
        // frame at the foot, oriented towards the point.
        LocalGeometry local;
        local.point = g.point;
        local.d1 = g.d1;
        local.d2 = g.d2;
        m = ErrorMatrix(options.method, ComputePrincipalFrame(local, VecS(points.col(i))), 3);
      }
      auto& block = blocks[static_cast<std::size_t>(foot.triangle)];
      const auto& element_dofs = surface.element_dofs(foot.triangle);
      const Eigen::Vector3d mr = m * r;
      for (int a = 0; a < 12; ++a) {
        const double na = s.value(a);
        if (na == 0.0) continue;
        rhs.segment<3>(3 * element_dofs[static_cast<std::size_t>(a)]) += na * mr;
        for (int b = 0; b < 12; ++b) block.block<3, 3>(3 * a, 3 * b) += (na * s.value(b)) * m;
      }
    }
    std::vector<Eigen::Triplet<double>> triplets;
    triplets.reserve(blocks.size() * 36 * 36 + static_cast<std::size_t>(k.nonZeros()) * 3);
    for (int t = 0; t < surface.triangle_count(); ++t) {
      const auto& element_dofs = surface.element_dofs(t);
      const auto& block = blocks[static_cast<std::size_t>(t)];
      for (int a = 0; a < 36; ++a)
        for (int b = 0; b < 36; ++b)
          if (block(a, b) != 0.0) {
            const int row = 3 * element_dofs[static_cast<std::size_t>(a / 3)] + a % 3;
            const int col = 3 * element_dofs[static_cast<std::size_t>(b / 3)] + b % 3;
            triplets.emplace_back(row, col, block(a, b));
          }
    }
    for (int outer = 0; outer < k.outerSize(); ++outer)
      for (Eigen::SparseMatrix<double>::InnerIterator it(k, outer); it; ++it)
        for (int c = 0; c < 3; ++c)
          triplets.emplace_back(3 * static_cast<int>(it.row()) + c, 3 * static_cast<int>(it.col()) + c,
                                it.value());
    Eigen::SparseMatrix<double> full(3 * dofs, 3 * dofs);
    full.setFromTriplets(triplets.begin(), triplets.end());
    const Eigen::MatrixX3d kq = k * surface.dofs();
    for (int d = 0; d < dofs; ++d) rhs.segment<3>(3 * d) -= kq.row(d).transpose();
    // Eq. P9: the step is delta = T y; y solves T^T N T y = T^T g.
    const Eigen::SparseMatrix<double> normal =
        Eigen::SparseMatrix<double>(reduced_basis.transpose() * full * reduced_basis);
    const Eigen::VectorXd reduced_rhs = reduced_basis.transpose() * rhs;
    const Eigen::Index unknowns = normal.rows();
    const Eigen::VectorXd diagonal = normal.diagonal();
    const double diagonal_scale = std::max(diagonal.maxCoeff(), 1e-300);

    bool accepted = false;
    const Eigen::MatrixX3d q0 = surface.dofs();
    for (int attempt = 0; attempt < 12 && !accepted; ++attempt) {
      // Marquardt damping with a floor: the step is unique even where the dofs are unobservable (a tangential
      // drift of a flat region changes neither TDM's residuals nor the bending energy).
      Eigen::SparseMatrix<double> damped = normal;
      for (Eigen::Index d = 0; d < unknowns; ++d)
        damped.coeffRef(d, d) += damping * std::max(diagonal(d), 1e-12 * diagonal_scale);
      Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(damped);
      const Eigen::VectorXd y =
          solver.info() == Eigen::Success ? Eigen::VectorXd(solver.solve(reduced_rhs)) : Eigen::VectorXd();
      if (y.size() == 0 || !y.allFinite()) {
        damping *= 10.0;
        continue;
      }
      const Eigen::VectorXd delta = reduced_basis * y;
      Eigen::MatrixX3d q = q0;
      for (int d = 0; d < dofs; ++d) q.row(d) += delta.segment<3>(3 * d).transpose();
      surface.set_dofs(q);
      std::vector<FeSurfacePoint> feet = result.feet;
      std::vector<char> in = inside;
      const double trial = closeness(feet, in) + fairness(q);
      if (trial <= objective) {
        accepted = true;
        const double previous = objective;
        objective = trial;
        result.feet = std::move(feet);
        inside = std::move(in);
        damping = std::max(damping / 100.0, 1e-12);
        result.objective.push_back(objective);
        result.iterations = iteration + 1;
        fixed_start = false;
        if (std::isfinite(previous) && previous - objective <= options.tolerance * previous)
          result.converged = true;
      } else {
        surface.set_dofs(q0);
        damping *= 10.0;
      }
    }
    if (!accepted) {
      result.converged = true;  // no step lowers the objective: a minimum to the damping's resolution
      break;
    }
    if (result.converged) break;
  }
  result.distances.resize(static_cast<std::size_t>(n));
  double sum = 0.0;
  result.boundary_feet = 0;
  for (int i = 0; i < n; ++i) {
    const double d =
        (points.col(i) - surface.Evaluate(result.feet[static_cast<std::size_t>(i)]).point).norm();
    result.distances[static_cast<std::size_t>(i)] = d;
    sum += d * d;
    result.max_distance = std::max(result.max_distance, d);
    if (!inside[static_cast<std::size_t>(i)]) ++result.boundary_feet;
  }
  result.rms = std::sqrt(sum / n);
  result.energy = surface.Energy(result.weights);
  return result;
}

namespace {

// The vertices on the domain's boundary.
std::vector<char> BoundaryVertices(const FeSurface& surface) {
  std::vector<char> boundary(static_cast<std::size_t>(surface.vertex_count()), 0);
  for (int e = 0; e < surface.edge_count(); ++e)
    if (surface.boundary_edge(e))
      for (int v : surface.edge(e)) boundary[static_cast<std::size_t>(v)] = 1;
  return boundary;
}

}  // namespace

std::vector<FeFixedDirection> SetPlanarChart(FeSurface& surface) {
  surface.Interpolate([](const Eigen::Vector2d& p) {
    Eigen::Matrix3d f;
    f.col(0) = Eigen::Vector3d(p.x(), p.y(), 0.0);
    f.col(1) = Eigen::Vector3d::UnitX();
    f.col(2) = Eigen::Vector3d::UnitY();
    return f;
  });
  // Eq. P8: x and y of every boundary dof.
  std::vector<FeFixedDirection> fixed;
  const auto pin = [&fixed](int dof) {
    fixed.push_back({dof, Eigen::Vector3d::UnitX()});
    fixed.push_back({dof, Eigen::Vector3d::UnitY()});
  };
  for (int e = 0; e < surface.edge_count(); ++e)
    if (surface.boundary_edge(e)) pin(surface.edge_dof(e));
  const std::vector<char> boundary = BoundaryVertices(surface);
  for (int v = 0; v < surface.vertex_count(); ++v)
    if (boundary[static_cast<std::size_t>(v)])
      for (int which = 0; which < 3; ++which) pin(surface.vertex_dof(v, which));
  return fixed;
}

std::vector<FeFixedDirection> SetCylindricalChart(FeSurface& surface, double radius) {
  if (!(radius > 0.0) || !std::isfinite(radius))
    throw std::invalid_argument("cylindrical chart: the radius must be positive and finite");
  const Eigen::Matrix2Xd& uv = surface.mesh().uv;
  const double width = uv.row(0).maxCoeff() - uv.row(0).minCoeff();
  if (!(width < 2.0 * M_PI * radius))
    throw std::invalid_argument("cylindrical chart: the domain is " + std::to_string(width) +
                                " wide round the axis, the cylinder's circumference " +
                                std::to_string(2.0 * M_PI * radius));
  // Eq. P8c: w = R e_r(u/R) + v e_z, w_u = e_theta(u/R), w_v = e_z.
  const auto radial = [radius](double u) {
    return Eigen::Vector3d(std::cos(u / radius), std::sin(u / radius), 0);
  };
  const auto around = [radius](double u) {
    return Eigen::Vector3d(-std::sin(u / radius), std::cos(u / radius), 0);
  };
  surface.Interpolate([&](const Eigen::Vector2d& p) {
    Eigen::Matrix3d f;
    f.col(0) = radius * radial(p.x()) + p.y() * Eigen::Vector3d::UnitZ();
    f.col(1) = around(p.x());
    f.col(2) = Eigen::Vector3d::UnitZ();
    return f;
  });
  std::vector<FeFixedDirection> fixed;
  const std::vector<char> boundary = BoundaryVertices(surface);
  for (int v = 0; v < surface.vertex_count(); ++v) {
    if (!boundary[static_cast<std::size_t>(v)]) continue;
    const Eigen::Vector3d e_theta = around(uv(0, v));
    for (int which : {0, 2}) {
      fixed.push_back({surface.vertex_dof(v, which), e_theta});
      fixed.push_back({surface.vertex_dof(v, which), Eigen::Vector3d::UnitZ()});
    }
    fixed.push_back({surface.vertex_dof(v, 1), Eigen::Vector3d::UnitZ()});
  }
  for (int e = 0; e < surface.edge_count(); ++e)
    if (surface.boundary_edge(e)) fixed.push_back({surface.edge_dof(e), Eigen::Vector3d::UnitZ()});
  return fixed;
}

}  // namespace s2m
