#include "fitting/polygon_closure.h"

#include <Eigen/Dense>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace s2m {

bool PolygonClosureOptions::IsValid(std::string* why) const {
  const auto fail = [why](const std::string& m) {
    if (why) *why = m;
    return false;
  };
  if (!(penalty > 0.0) || !std::isfinite(penalty)) return fail("penalty must be positive and finite");
  if (max_outer_iterations < 1) return fail("max_outer_iterations must be at least 1");
  if (!(tolerance > 0.0) || !std::isfinite(tolerance)) return fail("tolerance must be positive and finite");
  return true;
}

namespace {

// The constraints h(theta) of eq. P13: the closure vector over the perimeter (2) and sum(theta) - 2 pi, with
// their Jacobian. Side i heads phi_i = theta_0 + ... + theta_{i-1} (side 0 along +u).
void Constraints(const std::vector<double>& sides, const Eigen::VectorXd& theta, double perimeter,
                 Eigen::Vector3d& h, Eigen::MatrixXd& dh) {
  const Eigen::Index n = theta.size();
  h.setZero();
  dh.setZero(3, n);
  double phi = 0.0;
  for (Eigen::Index i = 0; i < n; ++i) {
    const double s = sides[static_cast<std::size_t>(i)] / perimeter;
    h(0) += s * std::cos(phi);
    h(1) += s * std::sin(phi);
    // d phi_i / d theta_j = 1 for j < i.
    for (Eigen::Index j = 0; j < i; ++j) {
      dh(0, j) -= s * std::sin(phi);
      dh(1, j) += s * std::cos(phi);
    }
    phi += theta(i);
  }
  h(2) = theta.sum() - 2.0 * M_PI;
  dh.row(2).setOnes();
}

}  // namespace

PolygonClosure ClosePolygon(const std::vector<double>& sides, const std::vector<double>& turning,
                            const PolygonClosureOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument("polygon closure: " + why);
  const std::size_t n = sides.size();
  if (n < 3)
    throw std::invalid_argument("polygon closure: " + std::to_string(n) + " sides (3 or more needed)");
  if (turning.size() != n)
    throw std::invalid_argument("polygon closure: " + std::to_string(turning.size()) + " turns for " +
                                std::to_string(n) + " sides");
  const double perimeter = std::accumulate(sides.begin(), sides.end(), 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    if (!(sides[i] > 0.0) || !std::isfinite(sides[i]))
      throw std::invalid_argument("polygon closure: side " + std::to_string(i) + " has length " +
                                  std::to_string(sides[i]));
    if (!(sides[i] < perimeter - sides[i]))
      throw std::invalid_argument("polygon closure: side " + std::to_string(i) + " (" +
                                  std::to_string(sides[i]) +
                                  ") is not shorter than the other sides together: no polygon closes");
    if (!std::isfinite(turning[i]))
      throw std::invalid_argument("polygon closure: the turn after side " + std::to_string(i) +
                                  " is not finite");
  }
  const Eigen::Index m = static_cast<Eigen::Index>(n);
  Eigen::VectorXd theta0(m), weight(m);
  for (Eigen::Index i = 0; i < m; ++i) {
    theta0(i) = turning[static_cast<std::size_t>(i)];
    weight(i) = std::max(std::abs(theta0(i)), 0.05);
  }
  // The method of multipliers (Fang 5.1.13-5.1.15): minimize f + R sum((h_k + tau_k)^2 - tau_k^2), then
  // tau <- h + tau. f and the penalty are sums of squares, so every inner minimization is a small nonlinear
  // least-squares problem, solved by Levenberg-Marquardt (residuals (theta - theta0) / w and sqrt(R)(h +
  // tau)).
  Eigen::VectorXd theta = theta0;
  Eigen::Vector3d tau = Eigen::Vector3d::Zero(), h;
  Eigen::MatrixXd dh;
  const double root_r = std::sqrt(options.penalty);
  PolygonClosure out;
  const auto residuals = [&](const Eigen::VectorXd& t, Eigen::VectorXd& r, Eigen::MatrixXd* j) {
    Eigen::Vector3d hh;
    Eigen::MatrixXd dhh;
    Constraints(sides, t, perimeter, hh, dhh);
    r.resize(m + 3);
    r.head(m) = (t - theta0).cwiseQuotient(weight);
    r.tail<3>() = root_r * (hh + tau);
    if (j) {
      j->setZero(m + 3, m);
      j->topRows(m).diagonal() = weight.cwiseInverse();
      j->bottomRows<3>() = root_r * dhh;
    }
  };
  for (int outer = 1; outer <= options.max_outer_iterations; ++outer) {
    double damping = 1e-6;
    Eigen::VectorXd r;
    Eigen::MatrixXd j;
    residuals(theta, r, &j);
    for (int inner = 0; inner < 100; ++inner) {
      const Eigen::MatrixXd normal = j.transpose() * j;
      const Eigen::VectorXd gradient = j.transpose() * r;
      Eigen::MatrixXd damped = normal;
      damped.diagonal() += damping * normal.diagonal();
      const Eigen::VectorXd step = damped.ldlt().solve(-gradient);
      Eigen::VectorXd trial_r;
      residuals(theta + step, trial_r, nullptr);
      if (trial_r.squaredNorm() < r.squaredNorm()) {
        theta += step;
        residuals(theta, r, &j);
        damping = std::max(damping * 0.1, 1e-12);
        if (step.norm() < 1e-15 * (1.0 + theta.norm())) break;
      } else {
        damping *= 10.0;
        if (damping > 1e12) break;
      }
    }
    Constraints(sides, theta, perimeter, h, dh);
    tau += h;
    out.outer_iterations = outer;
    if (h.cwiseAbs().maxCoeff() < options.tolerance) {
      out.converged = true;
      break;
    }
  }
  Constraints(sides, theta, perimeter, h, dh);
  out.closure_error = h.head<2>().norm();
  out.angle_sum_error = h(2);
  out.turning.assign(theta.data(), theta.data() + m);
  out.vertices.resize(2, m);
  Eigen::Vector2d p = Eigen::Vector2d::Zero();
  double phi = 0.0;
  for (Eigen::Index i = 0; i < m; ++i) {
    out.vertices.col(i) = p;
    p += sides[static_cast<std::size_t>(i)] * Eigen::Vector2d(std::cos(phi), std::sin(phi));
    phi += theta(i);
  }
  return out;
}

}  // namespace s2m
