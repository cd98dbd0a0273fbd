#include "fitting/linear_solver.h"

#include <Eigen/QR>
#include <algorithm>
#include <cmath>

namespace s2m {

void AddDamping(Eigen::MatrixXd& a, double lambda, double diagonal_floor) {
  if (a.size() == 0 || lambda == 0.0) return;
  const Eigen::VectorXd diagonal = a.diagonal().cwiseAbs();
  const double floor = diagonal_floor * diagonal.maxCoeff() + 1e-300;
  a.diagonal() += lambda * diagonal.cwiseMax(floor);
}

namespace {

// max_k |g_k| / sqrt(2 cost H_kk) over the columns with H_kk > 0 (eq. 42).
double LargestCosine(const Eigen::VectorXd& g, const Eigen::VectorXd& diagonal, double cost) {
  const double residual_norm = std::sqrt(std::max(2.0 * cost, 0.0));
  if (!(residual_norm > 0.0)) return 0.0;
  double largest = 0.0;
  for (Eigen::Index k = 0; k < g.size(); ++k) {
    if (diagonal[k] > 0.0)
      largest = std::max(largest, std::abs(g[k]) / (std::sqrt(diagonal[k]) * residual_norm));
  }
  return largest;
}

}  // namespace

// ---- DenseNormalEquations

void DenseNormalEquations::Resize(Eigen::Index n) {
  h_.setZero(n, n);
  g_.setZero(n);
}

bool DenseNormalEquations::Solve(double lambda, Eigen::VectorXd& step) {
  Eigen::MatrixXd a = h_;
  AddDamping(a, lambda, floor_);
  step = a.ldlt().solve(-g_);
  return step.allFinite();
}

double DenseNormalEquations::ModelChange(const Eigen::VectorXd& step) const {
  return g_.dot(step) + 0.5 * step.dot(h_ * step);
}

double DenseNormalEquations::GradientMeasure(double cost) const {
  return LargestCosine(g_, h_.diagonal().cwiseAbs(), cost);
}

// ---- DenseJacobianSystem

bool DenseJacobianSystem::Solve(double lambda, Eigen::VectorXd& step) {
  const Eigen::Index m = j_.rows(), n = j_.cols();
  // min |J dx + r|^2 + lambda |D dx|^2 = |[J; sqrt(lambda) D] dx + [r; 0]|^2 (eq. 38 in least-squares
  // form).
  augmented_.resize(m + n, n);
  augmented_.topRows(m) = j_;
  augmented_.bottomRows(n) = std::sqrt(lambda) * d_.asDiagonal();
  rhs_.resize(m + n);
  rhs_.head(m) = -r_;
  rhs_.tail(n).setZero();
  step = augmented_.colPivHouseholderQr().solve(rhs_);
  return step.allFinite();
}

double DenseJacobianSystem::ModelChange(const Eigen::VectorXd& step) const {
  return 0.5 * ((j_ * step + r_).squaredNorm() - r_.squaredNorm());
}

double DenseJacobianSystem::GradientMeasure(double /*cost*/) const {
  const double column_max = j_.colwise().norm().maxCoeff();
  const double residual_norm = r_.norm();
  if (!(column_max > 0.0 && residual_norm > 0.0)) return 0.0;
  return (j_.transpose() * r_).cwiseAbs().maxCoeff() / (column_max * residual_norm);
}

// ---- BlockArrowSystem

Eigen::Index BlockArrowSystem::block_offset(std::size_t b) const {
  Eigen::Index offset = shape_size();
  for (std::size_t i = 0; i < b; ++i) offset += h_bb[i].rows();
  return offset;
}

Eigen::Index BlockArrowSystem::num_parameters() const {
  return block_offset(h_bb.size());
}

bool BlockArrowSystem::Solve(double lambda, Eigen::VectorXd& step) {
  const std::size_t blocks = h_bb.size();
  const Eigen::Index r = shape_size();
  step.setZero(num_parameters());
  std::vector<Eigen::LDLT<Eigen::MatrixXd>> inverse(blocks);
  for (std::size_t b = 0; b < blocks; ++b) {
    Eigen::MatrixXd a = h_bb[b];
    AddDamping(a, lambda, floor_);
    inverse[b].compute(a);
  }
  Eigen::VectorXd step_d = Eigen::VectorXd::Zero(r);
  if (unknowns == Unknowns::kAll) {
    // Schur complement S = H_dd - sum H_db H_bb^-1 H_db^T (docs/method.md eq. 21): eliminate every motion
    // block, solve for the shape, back-substitute.
    Eigen::MatrixXd s = h_dd;
    AddDamping(s, lambda, floor_);
    Eigen::VectorXd rhs = -g_d;
    for (std::size_t b = 0; b < blocks; ++b) {
      if (h_bb[b].size() == 0)
        continue;  // a scan whose every motion is gauge (a model carrying its own pose)
      s.noalias() -= h_db[b] * inverse[b].solve(h_db[b].transpose());
      rhs.noalias() += h_db[b] * inverse[b].solve(g_b[b]);
    }
    step_d = s.ldlt().solve(rhs);
  } else if (unknowns == Unknowns::kShape) {
    Eigen::MatrixXd a = h_dd;
    AddDamping(a, lambda, floor_);
    step_d = a.ldlt().solve(-g_d);
  }
  step.head(r) = step_d;
  for (std::size_t b = 0; b < blocks; ++b) {
    if (unknowns == Unknowns::kShape || h_bb[b].size() == 0) continue;
    step.segment(block_offset(b), h_bb[b].rows()) = inverse[b].solve(-g_b[b] - h_db[b].transpose() * step_d);
  }
  return step.allFinite();
}

Eigen::VectorXd BlockArrowSystem::Gradient() const {
  Eigen::VectorXd g(num_parameters());
  g.head(shape_size()) = g_d;
  for (std::size_t b = 0; b < h_bb.size(); ++b) g.segment(block_offset(b), g_b[b].size()) = g_b[b];
  return g;
}

Eigen::VectorXd BlockArrowSystem::Multiply(const Eigen::VectorXd& x) const {
  const Eigen::Index r = shape_size();
  Eigen::VectorXd y = Eigen::VectorXd::Zero(x.size());
  y.head(r) = h_dd * x.head(r);
  for (std::size_t b = 0; b < h_bb.size(); ++b) {
    const Eigen::Index o = block_offset(b), q = h_bb[b].rows();
    y.head(r) += h_db[b] * x.segment(o, q);
    y.segment(o, q) = h_db[b].transpose() * x.head(r) + h_bb[b] * x.segment(o, q);
  }
  return y;
}

double BlockArrowSystem::Slope(const Eigen::VectorXd& step) const {
  return Gradient().dot(step);
}

double BlockArrowSystem::ModelChange(const Eigen::VectorXd& step) const {
  return Gradient().dot(step) + 0.5 * step.dot(Multiply(step));
}

double BlockArrowSystem::GradientMeasure(double cost) const {
  Eigen::VectorXd diagonal(num_parameters());
  diagonal.head(shape_size()) = h_dd.diagonal();
  for (std::size_t b = 0; b < h_bb.size(); ++b)
    diagonal.segment(block_offset(b), h_bb[b].rows()) = h_bb[b].diagonal();
  return LargestCosine(Gradient(), diagonal.cwiseAbs(), cost);
}

Eigen::MatrixXd BlockArrowSystem::FullMatrix() const {
  const Eigen::Index dim = num_parameters(), r = shape_size();
  Eigen::MatrixXd full = Eigen::MatrixXd::Zero(dim, dim);
  full.topLeftCorner(r, r) = h_dd;
  for (std::size_t b = 0; b < h_bb.size(); ++b) {
    const Eigen::Index o = block_offset(b), q = h_bb[b].rows();
    full.block(o, o, q, q) = h_bb[b];
    full.block(0, o, r, q) = h_db[b];
    full.block(o, 0, q, r) = h_db[b].transpose();
  }
  return full;
}

}  // namespace s2m
