#pragma once
// Linear-solver strategies of the minimizer (minimizer.h; docs/method.md section 14): each holds one
// linearization of a fit at its current state (frozen foot points) and solves the damped step
//   (H + lambda D^2) dx = -g                                              (docs/method.md eq. 38)
// in the way its structure calls for: dense LDLT of the normal equations (geometric and primitive fits,
// registration), QR of the damped Jacobian (the general least-squares core, which keeps the digits of
// ill-conditioned problems), or Schur elimination of the block-arrow joint system (one motion block per
// scan).

#include <Eigen/Core>
#include <Eigen/Dense>
#include <vector>

namespace s2m {

class LinearSystem {
 public:
  virtual ~LinearSystem() = default;
  virtual Eigen::Index num_parameters() const = 0;
  // The damped step for damping lambda >= 0 (0: the undamped Gauss-Newton step). False when the solve fails
  // (a non-finite step).
  virtual bool Solve(double lambda, Eigen::VectorXd& step) = 0;
  // g . dx and the linear model's change of the objective g . dx + 1/2 dx^T H dx (its predicted decrease is
  // the negative).
  virtual double Slope(const Eigen::VectorXd& step) const = 0;
  virtual double ModelChange(const Eigen::VectorXd& step) const = 0;
  // The scale-free first-order optimality measure: the largest cosine between the residual vector (norm
  // sqrt(2 cost)) and a Jacobian column (norm sqrt(H_kk)), |g_k| / sqrt(2 cost H_kk) (eq. 42).
  virtual double GradientMeasure(double cost) const = 0;
};

// Dense normal equations H dx = -g, damped by lambda max(|diag H|, floor max |diag H|) and solved by LDLT.
class DenseNormalEquations : public LinearSystem {
 public:
  explicit DenseNormalEquations(double diagonal_floor = 1e-6) : floor_(diagonal_floor) {}
  Eigen::MatrixXd& H() { return h_; }
  Eigen::VectorXd& g() { return g_; }
  const Eigen::MatrixXd& H() const { return h_; }
  const Eigen::VectorXd& g() const { return g_; }
  void Resize(Eigen::Index n);  // zero H and g of size n
  void set_diagonal_floor(double floor) { floor_ = floor; }

  Eigen::Index num_parameters() const override { return g_.size(); }
  bool Solve(double lambda, Eigen::VectorXd& step) override;
  double Slope(const Eigen::VectorXd& step) const override { return g_.dot(step); }
  double ModelChange(const Eigen::VectorXd& step) const override;
  double GradientMeasure(double cost) const override;

 private:
  Eigen::MatrixXd h_;
  Eigen::VectorXd g_;
  double floor_;
};

// lambda max(|diag A|, floor max |diag A|) added to A's diagonal: the damping of one block (eq. 38).
void AddDamping(Eigen::MatrixXd& a, double lambda, double diagonal_floor);

// A dense Jacobian J and residual r: min |J dx + r|^2 + lambda |D dx|^2 as one least-squares problem solved
// by column-pivoting QR (never the normal equations, so ill-conditioned problems keep their digits). D is set
// by the caller (least_squares.h: Levenberg's isotropic or Marquardt's per-column scaling).
class DenseJacobianSystem : public LinearSystem {
 public:
  Eigen::MatrixXd& J() { return j_; }
  Eigen::VectorXd& r() { return r_; }
  Eigen::VectorXd& D() { return d_; }
  const Eigen::MatrixXd& J() const { return j_; }
  const Eigen::VectorXd& r() const { return r_; }
  const Eigen::VectorXd& D() const { return d_; }

  Eigen::Index num_parameters() const override { return j_.cols(); }
  bool Solve(double lambda, Eigen::VectorXd& step) override;
  double Slope(const Eigen::VectorXd& step) const override { return (j_.transpose() * r_).dot(step); }
  double ModelChange(const Eigen::VectorXd& step) const override;
  // max |J^T r| / (max_k |J_k| |r|): the cosine against the largest column, which does not let a column that
  // vanishes at a degenerate limit hold the fit open.
  double GradientMeasure(double cost) const override;

 private:
  Eigen::MatrixXd j_;
  Eigen::VectorXd r_, d_;
  Eigen::MatrixXd augmented_;
  Eigen::VectorXd rhs_;
};

// The block-arrow normal equations of the joint fit (docs/method.md section 6, eq. 20): a shape block
// (h_dd, g_d), one motion block per scan (h_bb, g_b, in gauge-reduced coordinates) and their coupling h_db.
// The step is [d; b_1; ...; b_K]. Solving eliminates every motion block by its Schur complement, solves the
// shape, and back-substitutes (cost linear in the number of scans). `unknowns` selects the joint step or one
// of the alternating baseline's half-steps.
class BlockArrowSystem : public LinearSystem {
 public:
  enum class Unknowns { kAll, kMotions, kShape };
  explicit BlockArrowSystem(double diagonal_floor = 1e-9) : floor_(diagonal_floor) {}
  Eigen::MatrixXd h_dd;
  Eigen::VectorXd g_d;
  std::vector<Eigen::MatrixXd> h_bb, h_db;
  std::vector<Eigen::VectorXd> g_b;
  Unknowns unknowns = Unknowns::kAll;

  Eigen::Index shape_size() const { return g_d.size(); }
  Eigen::Index block_offset(std::size_t b) const;  // of motion block b in the step
  Eigen::Index num_parameters() const override;
  bool Solve(double lambda, Eigen::VectorXd& step) override;
  double Slope(const Eigen::VectorXd& step) const override;
  double ModelChange(const Eigen::VectorXd& step) const override;
  double GradientMeasure(double cost) const override;
  // The whole matrix as one dense symmetric matrix (shape block first, then the motion blocks in order).
  Eigen::MatrixXd FullMatrix() const;

 private:
  Eigen::VectorXd Multiply(const Eigen::VectorXd& x) const;  // H x
  Eigen::VectorXd Gradient() const;
  double floor_;
};

}  // namespace s2m
