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

// The reduced transformation of eq. P9: the step delta = T y whose columns span the null space of the
// constraint rows, so that every row keeps its value. The rows couple few unknowns (one dof's three
// coordinates, or one vertex's two slopes), so T is block-diagonal over the groups of dofs that rows link
// (union-find), each block the orthonormal null space of its rows by an SVD (rank to 1e-10 of the largest
// singular value); a dof in no row keeps its three columns of the identity. Columns follow the dofs' order.
Eigen::SparseMatrix<double> ReducedBasis(const std::vector<FeLinearConstraint>& rows, int dofs) {
  const int unknowns = 3 * dofs;
  std::vector<int> parent(static_cast<std::size_t>(dofs));
  for (int d = 0; d < dofs; ++d) parent[static_cast<std::size_t>(d)] = d;
  const auto root = [&parent](int d) {
    while (parent[static_cast<std::size_t>(d)] != d)
      d = parent[static_cast<std::size_t>(d)] =
          parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(d)])];
    return d;
  };
  for (const FeLinearConstraint& row : rows) {
    if (row.terms.empty())
      throw std::invalid_argument("finite-element surface fit: a constraint without terms");
    for (const auto& [unknown, coefficient] : row.terms) {
      if (unknown < 0 || unknown >= unknowns)
        throw std::invalid_argument("finite-element surface fit: a constraint on unknown " +
                                    std::to_string(unknown) + ", out of range (" + std::to_string(unknowns) +
                                    " unknowns)");
      if (!std::isfinite(coefficient))
        throw std::invalid_argument("finite-element surface fit: a constraint's coefficient is not finite");
    }
    const int first = root(row.terms.front().first / 3);
    for (const auto& term : row.terms) parent[static_cast<std::size_t>(root(term.first / 3))] = first;
  }
  // The rows and the dofs of every group.
  std::vector<std::vector<int>> group_rows(static_cast<std::size_t>(dofs)),
      group_dofs(static_cast<std::size_t>(dofs));
  for (std::size_t r = 0; r < rows.size(); ++r)
    group_rows[static_cast<std::size_t>(root(rows[r].terms.front().first / 3))].push_back(
        static_cast<int>(r));
  for (int d = 0; d < dofs; ++d) group_dofs[static_cast<std::size_t>(root(d))].push_back(d);

  std::vector<Eigen::Triplet<double>> triplets;
  std::vector<char> done(static_cast<std::size_t>(dofs), 0);
  int column = 0;
  for (int d = 0; d < dofs; ++d) {
    const int g = root(d);
    if (done[static_cast<std::size_t>(g)]) continue;
    done[static_cast<std::size_t>(g)] = 1;
    const std::vector<int>& members = group_dofs[static_cast<std::size_t>(g)];
    const std::vector<int>& mine = group_rows[static_cast<std::size_t>(g)];
    if (mine.empty()) {
      for (int c = 0; c < 3; ++c) triplets.emplace_back(3 * d + c, column++, 1.0);
      continue;
    }
    // Local unknown index of every global unknown of the group.
    const Eigen::Index local_count = 3 * static_cast<Eigen::Index>(members.size());
    const auto local = [&members](int unknown) {
      const auto at = std::lower_bound(members.begin(), members.end(), unknown / 3);
      return 3 * static_cast<Eigen::Index>(at - members.begin()) + unknown % 3;
    };
    Eigen::MatrixXd a = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(mine.size()), local_count);
    for (std::size_t r = 0; r < mine.size(); ++r) {
      const FeLinearConstraint& row = rows[static_cast<std::size_t>(mine[r])];
      for (const auto& [unknown, coefficient] : row.terms)
        a(static_cast<Eigen::Index>(r), local(unknown)) += coefficient;
      const double norm = a.row(static_cast<Eigen::Index>(r)).norm();
      if (!(norm > 0.0))
        throw std::invalid_argument(
            "finite-element surface fit: a constraint whose coefficients are all zero");
      a.row(static_cast<Eigen::Index>(r)) /= norm;
    }
    // The right singular vectors beyond the rows' rank span their null space.
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(a, Eigen::ComputeFullV);
    Eigen::Index rank = 0;
    for (Eigen::Index i = 0; i < svd.singularValues().size(); ++i)
      if (svd.singularValues()(i) > 1e-10 * svd.singularValues()(0)) ++rank;
    const Eigen::MatrixXd free = svd.matrixV().rightCols(local_count - rank);
    for (Eigen::Index j = 0; j < free.cols(); ++j, ++column)
      for (Eigen::Index i = 0; i < local_count; ++i)
        if (std::abs(free(i, j)) > 1e-15)
          triplets.emplace_back(3 * members[static_cast<std::size_t>(i / 3)] + static_cast<int>(i % 3),
                                column, free(i, j));
  }
  Eigen::SparseMatrix<double> t(unknowns, column);
  t.setFromTriplets(triplets.begin(), triplets.end());
  return t;
}

// A fixed direction as a constraint row (eq. P9).
std::vector<FeLinearConstraint> AsRows(const std::vector<FeFixedDirection>& fixed, int dofs) {
  std::vector<FeLinearConstraint> rows;
  for (const FeFixedDirection& f : fixed) {
    if (f.dof < 0 || f.dof >= dofs)
      throw std::invalid_argument("finite-element surface fit: a fixed direction of dof " +
                                  std::to_string(f.dof) + ", out of range (" + std::to_string(dofs) +
                                  " dofs)");
    if (!f.direction.allFinite() || !(f.direction.norm() > 0.0))
      throw std::invalid_argument("finite-element surface fit: a fixed direction of dof " +
                                  std::to_string(f.dof) + " is zero or not finite");
    FeLinearConstraint row;
    for (int c = 0; c < 3; ++c)
      if (f.direction(c) != 0.0) row.terms.emplace_back(3 * f.dof + c, f.direction(c));
    rows.push_back(std::move(row));
  }
  return rows;
}

// K (x) I3: the scalar dofs' matrix acting on x, y and z alike (unknown 3 dof + c), as the energy decouples.
Eigen::SparseMatrix<double> ForEachCoordinate(const Eigen::SparseMatrix<double>& k) {
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<std::size_t>(k.nonZeros()) * 3);
  for (int outer = 0; outer < k.outerSize(); ++outer)
    for (Eigen::SparseMatrix<double>::InnerIterator it(k, outer); it; ++it)
      for (int c = 0; c < 3; ++c)
        triplets.emplace_back(3 * static_cast<int>(it.row()) + c, 3 * static_cast<int>(it.col()) + c,
                              it.value());
  Eigen::SparseMatrix<double> full(3 * k.rows(), 3 * k.cols());
  full.setFromTriplets(triplets.begin(), triplets.end());
  return full;
}

using ElementBlock = Eigen::Matrix<double, 36, 36>;

// Per-triangle 36 x 36 blocks (the element's 12 dofs x 3 coordinates) summed into the global sparse matrix.
Eigen::SparseMatrix<double> FromElementBlocks(const FeSurface& surface,
                                              const std::vector<ElementBlock>& blocks) {
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(blocks.size() * 36 * 36);
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
  Eigen::SparseMatrix<double> full(3 * surface.dof_count(), 3 * surface.dof_count());
  full.setFromTriplets(triplets.begin(), triplets.end());
  return full;
}

Eigen::VectorXd Stacked(const Eigen::MatrixX3d& q) {
  Eigen::VectorXd v(3 * q.rows());
  for (Eigen::Index d = 0; d < q.rows(); ++d) v.segment<3>(3 * d) = q.row(d).transpose();
  return v;
}

Eigen::MatrixX3d Unstacked(const Eigen::VectorXd& v) {
  Eigen::MatrixX3d q(v.size() / 3, 3);
  for (Eigen::Index d = 0; d < q.rows(); ++d) q.row(d) = v.segment<3>(3 * d).transpose();
  return q;
}

// Fang's generalized spring forces (thesis eqs. 5.1.5-5.1.6 and 5.1.11; docs/fe-surfaces.md eq. P15): the
// force r_i = P_i - w(foot_i) is spread over the foot's host triangle as the linear load
// p(L) = (3 / area) (Lbar_i . L) r_i (Lbar_i the foot's barycentric coordinates), whose integral is r_i, and
// F_a = integral over the triangle of p N_a, by the element's quadrature: with the rule's weights w_q summing
// to 1/2 (area 1/2 of the reference triangle), F_a = sum_q 6 w_q (Lbar_i . L_q) N_a(L_q) r_i.
class SpringForces {
 public:
  explicit SpringForces(const FeSurface& surface) : surface_(surface), rule_(CollapsedGaussRule(4)) {
    shapes_.reserve(static_cast<std::size_t>(surface.triangle_count()));
    for (int t = 0; t < surface.triangle_count(); ++t) {
      Eigen::Matrix<double, 12, Eigen::Dynamic> at(12, static_cast<Eigen::Index>(rule_.weights.size()));
      for (std::size_t q = 0; q < rule_.weights.size(); ++q)
        at.col(static_cast<Eigen::Index>(q)) = surface.element(t).Evaluate(rule_.barycentric[q]).value;
      shapes_.push_back(std::move(at));
    }
  }

  Eigen::VectorXd operator()(const Eigen::Matrix3Xd& points, const std::vector<FeSurfacePoint>& feet) const {
    Eigen::VectorXd forces = Eigen::VectorXd::Zero(3 * surface_.dof_count());
    for (Eigen::Index i = 0; i < points.cols(); ++i) {
      const FeSurfacePoint& foot = feet[static_cast<std::size_t>(i)];
      const Eigen::Vector3d r = points.col(i) - surface_.Evaluate(foot).point;
      const auto& element_dofs = surface_.element_dofs(foot.triangle);
      const auto& shapes = shapes_[static_cast<std::size_t>(foot.triangle)];
      Eigen::Matrix<double, 12, 1> work = Eigen::Matrix<double, 12, 1>::Zero();
      for (std::size_t q = 0; q < rule_.weights.size(); ++q)
        work += (6.0 * rule_.weights[q] * foot.barycentric.dot(rule_.barycentric[q])) *
                shapes.col(static_cast<Eigen::Index>(q));
      for (int a = 0; a < 12; ++a)
        forces.segment<3>(3 * element_dofs[static_cast<std::size_t>(a)]) += work(a) * r;
    }
    return forces;
  }

 private:
  const FeSurface& surface_;
  TriangleQuadrature rule_;
  std::vector<Eigen::Matrix<double, 12, Eigen::Dynamic>> shapes_;
};

}  // namespace

Eigen::VectorXd FangSpringForces(const FeSurface& surface, const Eigen::Matrix3Xd& points,
                                 const std::vector<FeSurfacePoint>& feet) {
  if (static_cast<std::size_t>(points.cols()) != feet.size())
    throw std::invalid_argument("spring forces: " + std::to_string(points.cols()) + " points but " +
                                std::to_string(feet.size()) + " feet");
  for (const FeSurfacePoint& foot : feet)
    if (foot.triangle < 0 || foot.triangle >= surface.triangle_count())
      throw std::invalid_argument("spring forces: a foot in triangle " + std::to_string(foot.triangle) +
                                  ", out of range");
  return SpringForces(surface)(points, feet);
}

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
      // Near the foot the squared distance is stationary: a Newton step that gains less than its rounding
      // would be refused by a strict comparison, leaving the residual's tangential part at about
      // sqrt(machine epsilon) of the distance; a tie within rounding is taken as progress.
      if (nd2 <= distance2 * (1.0 + 1e-14)) {
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
                                const std::vector<FeFixedDirection>& fixed,
                                const std::vector<FeLinearConstraint>& linear) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument("finite-element surface fit: " + why);
  if (points.cols() != start_uv.cols())
    throw std::invalid_argument("finite-element surface fit: " + std::to_string(points.cols()) +
                                " points but " + std::to_string(start_uv.cols()) + " start parameters");
  if (points.cols() < 3) throw std::invalid_argument("finite-element surface fit: fewer than 3 points");
  if (!points.allFinite() || !start_uv.allFinite())
    throw std::invalid_argument("finite-element surface fit: a point or start parameter is not finite");
  const int n = static_cast<int>(points.cols());
  std::vector<FeLinearConstraint> rows = AsRows(fixed, surface.dof_count());
  rows.insert(rows.end(), linear.begin(), linear.end());
  const Eigen::SparseMatrix<double> reduced_basis = ReducedBasis(rows, surface.dof_count());
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

  const Eigen::SparseMatrix<double> plate = ForEachCoordinate(k);
  if (options.solver == FeSolver::kFangSprings) {
    // Fang's SQP (thesis 5.1.3-5.1.4; docs/fe-surfaces.md eq. P16): the step d minimizes g^T d + d^T H d with
    // g / 2 = (K (x) I3) q - F, F the distributed spring forces (eq. P15), and H the plate's stiffness (plus
    // the springs' at the first feet); H does not change, so it is factored once.
    Eigen::SparseMatrix<double> model = plate;
    if (options.spring_hessian == FeSpringHessian::kPlateOnSprings) {
      std::vector<ElementBlock> blocks(static_cast<std::size_t>(surface.triangle_count()),
                                       ElementBlock::Zero());
      for (int i = 0; i < n; ++i) {
        const FeSurfacePoint& foot = result.feet[static_cast<std::size_t>(i)];
        const TriangleShape shape = surface.element(foot.triangle).Evaluate(foot.barycentric);
        auto& block = blocks[static_cast<std::size_t>(foot.triangle)];
        for (int a = 0; a < 12; ++a)
          for (int b = 0; b < 12; ++b)
            block.block<3, 3>(3 * a, 3 * b).diagonal().array() += shape.value(a) * shape.value(b);
      }
      model += FromElementBlocks(surface, blocks);
    }
    const Eigen::SparseMatrix<double> reduced_model =
        Eigen::SparseMatrix<double>(reduced_basis.transpose() * model * reduced_basis);
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(reduced_model);
    if (solver.info() != Eigen::Success ||
        !(solver.vectorD().minCoeff() > 1e-12 * solver.vectorD().cwiseAbs().maxCoeff()))
      throw std::invalid_argument(
          "finite-element surface fit: the plate alone does not hold the surface with these constraints "
          "(Fang's quadratic model is singular): hold the boundary on curves, or let the springs' stiffness "
          "into the model");
    const SpringForces spring_forces(surface);
    double objective = fairness(surface.dofs());
    for (int i = 0; i < n; ++i)
      objective +=
          (points.col(i) - surface.Evaluate(result.feet[static_cast<std::size_t>(i)]).point).squaredNorm();
    result.objective.push_back(objective);
    for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
      const Eigen::MatrixX3d q0 = surface.dofs();
      const Eigen::VectorXd half_gradient = plate * Stacked(q0) - spring_forces(points, result.feet);
      const Eigen::VectorXd step =
          reduced_basis * Eigen::VectorXd(solver.solve(-(reduced_basis.transpose() * half_gradient)));
      if (!step.allFinite()) break;
      // The thesis takes the full step; halving it until the objective falls keeps the iteration from
      // diverging where the springs are stiffer than the plate (measured in docs/fe-surfaces.md section 4b).
      bool accepted = false;
      double length = 1.0;
      for (int attempt = 0; attempt < 12 && !accepted; ++attempt, length *= 0.5) {
        surface.set_dofs(q0 + length * Unstacked(step));
        std::vector<FeSurfacePoint> feet = result.feet;
        std::vector<char> in = inside;
        const double trial = closeness(feet, in) + fairness(surface.dofs());
        if (trial < objective) {
          accepted = true;
          const double previous = objective;
          objective = trial;
          result.feet = std::move(feet);
          inside = std::move(in);
          result.objective.push_back(objective);
          result.step_lengths.push_back(length);
          result.iterations = iteration + 1;
          if (previous - objective <= options.tolerance * previous) result.converged = true;
        }
      }
      if (!accepted) {
        // No step along Fang's direction lowers the objective: the springs' equilibrium, to the resolution of
        // the distributed loads (they are not the exact gradient of the point distances).
        surface.set_dofs(q0);
        result.converged = true;
      }
      if (result.converged) break;
    }
  } else {
    double objective = std::numeric_limits<double>::infinity();
    result.objective.push_back(objective);
    double damping = 1e-9;
    for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
      // Eq. P7: the normal equations of the step delta (3 dofs x, y, z per scalar dof, index 3 dof + c),
      //   (sum_i (N_i^T N_i) (x) M_i + K (x) I3 + damping diag) delta
      //     = sum_i N_i^T (x) M_i r_i - (K (x) I3) q,
      // M_i the point's error matrix (PDM: I; TDM: n n^T; SDM: Pottmann-Hofer's, docs/method.md eq. 5); feet
      // on the boundary use PDM (their residual is not along the normal).
      std::vector<ElementBlock> blocks(static_cast<std::size_t>(surface.triangle_count()),
                                       ElementBlock::Zero());
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
      const Eigen::SparseMatrix<double> full = FromElementBlocks(surface, blocks) + plate;
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
        // Marquardt damping with a floor: the step is unique even where the dofs are unobservable (a
        // tangential drift of a flat region changes neither TDM's residuals nor the bending energy).
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

std::vector<FeLinearConstraint> SetBoundaryConformity(FeSurface& surface, const FeBoundaryTrace& trace) {
  const int vertices = surface.vertex_count();
  std::vector<std::vector<int>> boundary_edges(static_cast<std::size_t>(vertices));
  for (int e = 0; e < surface.edge_count(); ++e)
    if (surface.boundary_edge(e))
      for (int v : surface.edge(e)) boundary_edges[static_cast<std::size_t>(v)].push_back(e);
  const Eigen::Matrix2Xd& uv = surface.mesh().uv;
  Eigen::MatrixX3d q = surface.dofs();
  std::vector<FeLinearConstraint> rows;
  const auto fix = [&rows](int dof, const Eigen::Vector2d& weights, int dof2) {
    for (int c = 0; c < 3; ++c) {
      FeLinearConstraint row;
      if (weights(0) != 0.0) row.terms.emplace_back(3 * dof + c, weights(0));
      if (dof2 >= 0 && weights(1) != 0.0) row.terms.emplace_back(3 * dof2 + c, weights(1));
      rows.push_back(std::move(row));
    }
  };
  for (int v = 0; v < vertices; ++v) {
    const std::vector<int>& edges = boundary_edges[static_cast<std::size_t>(v)];
    if (edges.empty()) continue;
    const Eigen::Vector2d at = uv.col(v);
    const auto where = [&at] { return "(" + std::to_string(at.x()) + ", " + std::to_string(at.y()) + ")"; };
    // Eq. P12: the curve's point, and its slope along every boundary edge from the vertex.
    const Eigen::Index k = static_cast<Eigen::Index>(edges.size());
    Eigen::MatrixX2d directions(k, 2);
    Eigen::MatrixX3d slopes(k, 3);
    Eigen::Vector3d point = Eigen::Vector3d::Zero();
    for (Eigen::Index i = 0; i < k; ++i) {
      const auto& ends = surface.edge(edges[static_cast<std::size_t>(i)]);
      const int other = ends[0] == v ? ends[1] : ends[0];
      const Eigen::Vector2d d = (uv.col(other) - at).normalized();
      Eigen::Vector3d p, slope;
      trace(at, d, p, slope);
      if (!p.allFinite() || !slope.allFinite())
        throw std::invalid_argument("boundary conformity: the boundary curve at " + where() +
                                    " is not finite");
      if (i == 0) point = p;
      if ((p - point).norm() > 1e-9 * (1.0 + point.norm()))
        throw std::invalid_argument(
            "boundary conformity: the boundary curves do not meet at the domain vertex " + where() + " (" +
            std::to_string((p - point).norm()) + " apart)");
      directions.row(i) = d.transpose();
      slopes.row(i) = slope.transpose();
    }
    q.row(surface.vertex_dof(v, 0)) = point.transpose();
    for (int c = 0; c < 3; ++c) rows.push_back({{{3 * surface.vertex_dof(v, 0) + c, 1.0}}});

    // The slopes w_u, w_v (rows of g) with directions g = slopes (Fang's eqs. 4.3.2-4.3.4): a corner (edges
    // in two directions) fixes both; a vertex inside a straight side fixes their combination along the side.
    const int du = surface.vertex_dof(v, 1), dv = surface.vertex_dof(v, 2);
    Eigen::Matrix<double, 2, 3> g;
    g.row(0) = q.row(du);
    g.row(1) = q.row(dv);
    const Eigen::JacobiSVD<Eigen::MatrixX2d> svd(directions, Eigen::ComputeFullV);
    const bool corner = svd.singularValues()(1) > 1e-8 * svd.singularValues()(0);
    if (corner) {
      g = directions.colPivHouseholderQr().solve(slopes);
      fix(du, Eigen::Vector2d(1, 0), -1);
      fix(dv, Eigen::Vector2d(1, 0), -1);
    } else {
      const Eigen::Vector2d d = directions.row(0).transpose();
      Eigen::RowVector3d along = slopes.row(0);
      g += d * (along - d.transpose() * g);
      fix(du, d, dv);
    }
    const double mismatch = (directions * g - slopes).norm();
    if (mismatch > 1e-8 * (1.0 + slopes.norm()))
      throw std::invalid_argument(
          "boundary conformity: the boundary's slopes at the domain vertex " + where() + " disagree by " +
          std::to_string(mismatch) +
          (corner ? " (the directions at a corner over-determine them)"
                  : " (along a straight side the curve's parametric speed must be proportional to the side's "
                    "length: Fang's consistency condition)"));
    q.row(du) = g.row(0);
    q.row(dv) = g.row(1);
  }
  surface.set_dofs(q);
  return rows;
}

void FairFill(FeSurface& surface, const std::vector<FeLinearConstraint>& rows) {
  // Eq. P14: minimize the thin-plate energy trace(Q^T K Q) over Q = Q0 + T y (the rows keep their values):
  // (T^T (K (x) I3) T) y = -T^T (K (x) I3) Q0.
  FairnessWeights thin_plate;
  thin_plate.bending = 1.0;
  const Eigen::SparseMatrix<double> k = surface.EnergyMatrix(thin_plate);
  const int dofs = surface.dof_count();
  const Eigen::SparseMatrix<double> full = ForEachCoordinate(k);
  const Eigen::SparseMatrix<double> t = ReducedBasis(rows, dofs);
  const Eigen::VectorXd q0 = Stacked(surface.dofs());
  const Eigen::SparseMatrix<double> reduced = Eigen::SparseMatrix<double>(t.transpose() * full * t);
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(reduced);
  const Eigen::VectorXd y = solver.info() == Eigen::Success
                                ? Eigen::VectorXd(solver.solve(-(t.transpose() * (full * q0))))
                                : Eigen::VectorXd();
  if (y.size() != reduced.rows() || !y.allFinite() || solver.vectorD().minCoeff() <= 0.0)
    throw std::invalid_argument(
        "fair fill: the thin-plate energy with these constraints has no unique minimum (the constraints do "
        "not hold the surface: too few fixed values?)");
  surface.set_dofs(Unstacked(q0 + t * y));
}

}  // namespace s2m
