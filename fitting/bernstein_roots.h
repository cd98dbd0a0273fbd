#pragma once
// Real roots of a polynomial on [0, 1] by Bernstein-form root isolation (docs/fair-curves.md section 4; L.
// Fang's point-to-curve distance, after Lane & Riesenfeld's subdivision): the number of roots in an interval
// is at most the number of sign changes of the Bernstein coefficients (variation diminishing), so an interval
// without a sign change has none, one with exactly one change has exactly one (found by safeguarded Newton on
// a bracket), and the others are split in half by de Casteljau's algorithm.

#include <Eigen/Core>
#include <vector>

namespace s2m {

// Bernstein coefficients b_i (degree M = size - 1) of the polynomial sum_k a_k t^k on [0, 1]:
// b_i = sum_{k <= i} C(i, k) / C(M, k) a_k.
Eigen::VectorXd PowerToBernstein(const Eigen::VectorXd& power);

// Appends to `roots` every root t in [0, 1] of the polynomial with Bernstein coefficients `bernstein`, in
// increasing order. A multiple root (a touching zero, where no sign change brackets it) is reported as the
// midpoint of an interval no wider than `resolution`. The polynomial identically zero has no isolated roots:
// none are reported.
void BernsteinRoots(const Eigen::VectorXd& bernstein, std::vector<double>& roots, double resolution = 1e-10);

}  // namespace s2m
