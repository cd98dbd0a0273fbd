#include "fitting/covariance.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>

namespace s2m {

CovarianceEstimate EstimateCovariance(const Eigen::MatrixXd& information, double weighted_sum_of_squares,
                                      double effective_observations, const CovarianceOptions& options) {
  const Eigen::Index p = information.rows();
  CovarianceEstimate out;
  out.null_share = Eigen::VectorXd::Zero(p);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double dof = effective_observations - static_cast<double>(p);
  out.degrees_of_freedom = dof > 0 ? static_cast<int>(std::floor(dof)) : 0;
  out.variance = dof > 0 ? weighted_sum_of_squares / dof : nan;
  if (p == 0) return out;
  // N = V diag(lambda) V^T; N^+ = V diag(1/lambda, 0 on the null directions) V^T (Golub & Van Loan, Matrix
  // Computations, 4th ed., section 5.5.2, the symmetric case of the SVD's pseudo-inverse).
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(information);
  const Eigen::VectorXd& values = eig.eigenvalues();
  const Eigen::MatrixXd& vectors = eig.eigenvectors();
  const double top = std::max(values.cwiseAbs().maxCoeff(), 1e-300);
  Eigen::VectorXd inverse = Eigen::VectorXd::Zero(p);
  for (Eigen::Index i = 0; i < p; ++i) {
    if (values[i] > options.relative_null_threshold * top) {
      inverse[i] = 1.0 / values[i];
    } else {
      out.null_directions.push_back(vectors.col(i));
      out.null_share += vectors.col(i).cwiseAbs2();
    }
  }
  if (!(dof > 0)) return out;
  out.covariance = out.variance * vectors * inverse.asDiagonal() * vectors.transpose();
  out.standard_uncertainty.resize(p);
  for (Eigen::Index i = 0; i < p; ++i) {
    out.standard_uncertainty[i] =
        out.null_share[i] > options.touch_threshold ? nan : std::sqrt(std::max(out.covariance(i, i), 0.0));
  }
  return out;
}

}  // namespace s2m
