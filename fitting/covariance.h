#pragma once
// The covariance of a least-squares estimate from its information matrix, with gauge freedom: one routine for
// the joint fit and the primitive fits (docs/method.md section 6 for the unobservable directions).

#include <Eigen/Core>
#include <vector>

namespace s2m {

struct CovarianceOptions {
  // Eigenvalues of the information matrix at most this fraction of its largest are null directions: no
  // information, hence no variance, along them (the pseudo-inverse's convention).
  double relative_null_threshold = 1e-10;
  // A parameter whose squared components along the null directions sum to more than this is touched by them:
  // its own standard uncertainty is undefined (NaN), as it can move freely.
  double touch_threshold = 1e-6;
};

struct CovarianceEstimate {
  // s^2 N^+ (N the information matrix, N^+ its pseudo-inverse); empty when there are no degrees of freedom.
  Eigen::MatrixXd covariance;
  // sqrt(diag(covariance)), NaN for the parameters a null direction touches; empty with the covariance.
  Eigen::VectorXd standard_uncertainty;
  // Unit eigenvectors of N spanning its null space, by ascending eigenvalue (computed whatever the degrees of
  // freedom: they are a property of N alone).
  std::vector<Eigen::VectorXd> null_directions;
  // Per parameter, the sum of its squared components along the null directions (0 when fully determined,
  // 1 when free); callers mapping parameters to other coordinates map this share with them.
  Eigen::VectorXd null_share;
  // The variance of unit weight s^2 = sum w d^2 / (n_eff - p) (NaN without degrees of freedom).
  double variance = 0.0;
  // n_eff - p, rounded down (p = the parameter count, the null directions included).
  int degrees_of_freedom = 0;
};

// The type A standard uncertainties (GUM, JCGM 100:2008, section 4.2) of the parameters of a Gauss-Newton
// problem at its solution: covariance s^2 (J^T W J)^-1 with the unbiased variance of unit weight s^2 = sum w
// d^2 / (n_eff - p) (Gauss-Markov; Bjorck, Numerical Methods for Least Squares Problems, 1996, section 1.1,
// its weighted form). `information`
// is J^T W J, `weighted_sum_of_squares` sum w d^2 and `effective_observations` n_eff: the point count for
// unit weights; for robust fits the caller passes W = the IRLS weights and n_eff = sum w. The inverse is the
// pseudo-inverse over the eigenvalues above options.relative_null_threshold of the largest (a gauge-free
// problem's: no variance along unobservable directions), so with an invertible, well-conditioned N it is N^-1
// to rounding.
CovarianceEstimate EstimateCovariance(const Eigen::MatrixXd& information, double weighted_sum_of_squares,
                                      double effective_observations, const CovarianceOptions& options = {});

}  // namespace s2m
