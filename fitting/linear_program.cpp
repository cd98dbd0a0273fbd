#include "fitting/linear_program.h"

#include <Eigen/LU>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace s2m {

bool LinearProgramOptions::IsValid(std::string* why) const {
  auto fail = [&](const char* text) {
    if (why) *why = text;
    return false;
  };
  if (max_iterations < 1) return fail("max_iterations must be at least 1");
  if (!(optimality_tolerance > 0.0 && optimality_tolerance < 1e-3))
    return fail("optimality_tolerance must be in (0, 1e-3)");
  if (!(pivot_tolerance > 0.0 && pivot_tolerance < 1e-3)) return fail("pivot_tolerance must be in (0, 1e-3)");
  if (degenerate_pivots_before_bland < 0) return fail("degenerate_pivots_before_bland must be >= 0");
  if (why) why->clear();
  return true;
}

const char* ToString(LinearProgramStatus status) {
  switch (status) {
    case LinearProgramStatus::kOptimal:
      return "optimal";
    case LinearProgramStatus::kInfeasible:
      return "infeasible";
    case LinearProgramStatus::kUnbounded:
      return "unbounded";
    case LinearProgramStatus::kIterationLimit:
      return "iteration-limit";
  }
  return "?";
}

namespace {

// The dual problem in standard form, min cost^T y subject to M y = rhs, y >= 0, with M = [S A^T | I]: the
// rows of A as columns (signs S chosen so that rhs = S (-c) >= 0), then one artificial column per equation.
class DualSimplex {
 public:
  DualSimplex(const Eigen::MatrixXd& A, const Eigen::VectorXd& b, const Eigen::VectorXd& c,
              const LinearProgramOptions& options)
      : A_(A), b_(b), options_(options), m_(A.rows()), n_(A.cols()) {
    sign_.resize(n_);
    rhs_.resize(n_);
    for (Eigen::Index k = 0; k < n_; ++k) {
      sign_[k] = -c[k] < 0 ? -1.0 : 1.0;
      rhs_[k] = -c[k] * sign_[k];
    }
    basis_.resize(static_cast<std::size_t>(n_));
    in_basis_.assign(static_cast<std::size_t>(m_ + n_), 0);
    for (Eigen::Index k = 0; k < n_; ++k) {
      basis_[static_cast<std::size_t>(k)] = m_ + k;
      in_basis_[static_cast<std::size_t>(m_ + k)] = 1;
    }
    b_scale_ = std::max(1.0, b_.size() > 0 ? b_.cwiseAbs().maxCoeff() : 0.0);
  }

  LinearProgramResult Solve() {
    LinearProgramResult result;
    // Phase 1: minimize the sum of the artificials; a positive minimum means A^T y = -c has no solution
    // y >= 0: then min c^T x has no finite value (unbounded, or infeasible as well).
    const Outcome phase1 = Iterate(/*phase=*/1, result.iterations);
    if (phase1 == Outcome::kIterationLimit) return result;
    Factorize();
    double artificial = 0.0;
    for (Eigen::Index i = 0; i < n_; ++i)
      if (basis_[static_cast<std::size_t>(i)] >= m_) artificial += x_b_[i];
    if (artificial > 1e-9 * std::max(1.0, rhs_.cwiseAbs().maxCoeff())) {
      result.status = LinearProgramStatus::kUnbounded;
      return result;
    }
    DriveOutArtificials();
    // Phase 2: minimize b^T y; an unbounded ray of the dual means the primal rows are inconsistent.
    const Outcome phase2 = Iterate(/*phase=*/2, result.iterations);
    if (phase2 == Outcome::kIterationLimit) return result;
    if (phase2 == Outcome::kUnbounded) {
      result.status = LinearProgramStatus::kInfeasible;
      return result;
    }
    Factorize();
    const Eigen::VectorXd pi = Multipliers(2);
    result.x = sign_.cwiseProduct(pi);
    result.duals = Eigen::VectorXd::Zero(m_);
    for (Eigen::Index i = 0; i < n_; ++i) {
      const Eigen::Index j = basis_[static_cast<std::size_t>(i)];
      if (j < m_) result.duals[j] = std::max(0.0, x_b_[i]);
    }
    result.objective = -rhs_.dot(pi);  // = c^T x by strong duality (docs/metrology.md eq. 10)
    result.status = LinearProgramStatus::kOptimal;
    return result;
  }

 private:
  enum class Outcome { kOptimal, kUnbounded, kIterationLimit };

  Eigen::VectorXd Column(Eigen::Index j) const {
    if (j < m_) return sign_.cwiseProduct(A_.row(j).transpose());
    return Eigen::VectorXd::Unit(n_, j - m_);
  }
  double Cost(int phase, Eigen::Index j) const {
    if (phase == 1) return j >= m_ ? 1.0 : 0.0;
    return j < m_ ? b_[j] : 0.0;
  }

  void Factorize() {
    Eigen::MatrixXd B(n_, n_);
    for (Eigen::Index i = 0; i < n_; ++i) B.col(i) = Column(basis_[static_cast<std::size_t>(i)]);
    lu_.compute(B);
    x_b_ = lu_.solve(rhs_);
  }

  // The simplex multipliers pi = B^-T cost_B.
  Eigen::VectorXd Multipliers(int phase) const {
    Eigen::VectorXd cost_b(n_);
    for (Eigen::Index i = 0; i < n_; ++i) cost_b[i] = Cost(phase, basis_[static_cast<std::size_t>(i)]);
    return lu_.transpose().solve(cost_b);
  }

  void Pivot(Eigen::Index position, Eigen::Index entering) {
    in_basis_[static_cast<std::size_t>(basis_[static_cast<std::size_t>(position)])] = 0;
    basis_[static_cast<std::size_t>(position)] = entering;
    in_basis_[static_cast<std::size_t>(entering)] = 1;
  }

  Outcome Iterate(int phase, int& iterations) {
    int degenerate_run = 0;
    const double tolerance = options_.optimality_tolerance * (phase == 1 ? 1.0 : b_scale_);
    while (true) {
      Factorize();
      const Eigen::VectorXd pi = Multipliers(phase);
      // Reduced costs of the data columns: cost_j - (S a_j).pi = cost_j - a_j.(S pi). Artificials never
      // re-enter once they have left the basis.
      const Eigen::VectorXd priced = A_ * sign_.cwiseProduct(pi);
      const bool bland = degenerate_run >= options_.degenerate_pivots_before_bland;
      Eigen::Index entering = -1;
      double most_negative = -tolerance;
      for (Eigen::Index j = 0; j < m_; ++j) {
        if (in_basis_[static_cast<std::size_t>(j)]) continue;
        const double reduced = Cost(phase, j) - priced[j];
        if (reduced < most_negative) {
          entering = j;
          most_negative = reduced;
          if (bland) break;  // the lowest index with a negative reduced cost
        }
      }
      if (entering < 0) return Outcome::kOptimal;
      if (iterations >= options_.max_iterations) return Outcome::kIterationLimit;
      ++iterations;

      const Eigen::VectorXd u = lu_.solve(Column(entering));
      const double pivot_floor = options_.pivot_tolerance * std::max(1.0, u.cwiseAbs().maxCoeff());
      // Ratio test in two passes: the smallest ratio, then among the rows that tie with it the lowest
      // variable index (Bland) or the largest pivot (stability).
      double best_ratio = std::numeric_limits<double>::infinity();
      for (Eigen::Index i = 0; i < n_; ++i)
        if (u[i] > pivot_floor) best_ratio = std::min(best_ratio, std::max(0.0, x_b_[i]) / u[i]);
      Eigen::Index leaving = -1;
      const double tie = best_ratio + 1e-12 * (1.0 + best_ratio);
      for (Eigen::Index i = 0; i < n_ && std::isfinite(best_ratio); ++i) {
        if (!(u[i] > pivot_floor) || std::max(0.0, x_b_[i]) / u[i] > tie) continue;
        if (leaving < 0) {
          leaving = i;
        } else if (bland ? basis_[static_cast<std::size_t>(i)] < basis_[static_cast<std::size_t>(leaving)]
                         : u[i] > u[leaving]) {
          leaving = i;
        }
      }
      if (leaving < 0) return Outcome::kUnbounded;
      degenerate_run = best_ratio <= 0.0 ? degenerate_run + 1 : 0;
      Pivot(leaving, entering);
    }
  }

  // Artificials still basic (at zero) after phase 1 are exchanged for data columns; one that no data column
  // can replace belongs to a redundant equation and stays at zero.
  void DriveOutArtificials() {
    for (Eigen::Index i = 0; i < n_; ++i) {
      if (basis_[static_cast<std::size_t>(i)] < m_) continue;
      Factorize();
      const Eigen::VectorXd row = lu_.transpose().solve(Eigen::VectorXd::Unit(n_, i));  // e_i^T B^-1
      const Eigen::VectorXd along = A_ * sign_.cwiseProduct(row);
      Eigen::Index best = -1;
      double largest = options_.pivot_tolerance;
      for (Eigen::Index j = 0; j < m_; ++j) {
        if (in_basis_[static_cast<std::size_t>(j)]) continue;
        if (std::abs(along[j]) > largest) {
          largest = std::abs(along[j]);
          best = j;
        }
      }
      if (best >= 0) Pivot(i, best);
    }
  }

  const Eigen::MatrixXd& A_;
  const Eigen::VectorXd& b_;
  const LinearProgramOptions& options_;
  const Eigen::Index m_, n_;
  Eigen::VectorXd sign_, rhs_, x_b_;
  std::vector<Eigen::Index> basis_;
  std::vector<char> in_basis_;
  Eigen::PartialPivLU<Eigen::MatrixXd> lu_;
  double b_scale_ = 1.0;
};

}  // namespace

LinearProgramResult SolveLinearProgram(const Eigen::MatrixXd& A, const Eigen::VectorXd& b,
                                       const Eigen::VectorXd& c, const LinearProgramOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument("invalid linear program options: " + why);
  if (A.rows() != b.size() || A.cols() != c.size())
    throw std::invalid_argument("linear program: A is " + std::to_string(A.rows()) + " x " +
                                std::to_string(A.cols()) + ", b has " + std::to_string(b.size()) + " and c " +
                                std::to_string(c.size()) + " entries");
  if (A.cols() == 0) throw std::invalid_argument("linear program: no unknowns");
  if (!A.allFinite() || !b.allFinite() || !c.allFinite())
    throw std::invalid_argument("linear program: non-finite coefficients");
  return DualSimplex(A, b, c, options).Solve();
}

}  // namespace s2m
