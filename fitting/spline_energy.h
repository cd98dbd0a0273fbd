#pragma once
// Fang's fairness energies for B-spline bases (docs/fair-curves.md section 8): the energy matrices of the
// p-th derivative (p = 1..3) and of the jumps of the p-th derivative at the knots, from the basis' per-span
// power form by the one element-integration routine of fitting/element_energy.h.

#include <Eigen/Core>

#include "fitting/bspline_basis.h"

namespace s2m {

// G_ij = integral over the domain of B_i^(p) B_j^(p) (num_control x num_control), exact for any p.
Eigen::MatrixXd SplineEnergyMatrix(const BSplineBasis& basis, int derivative);

// J = sum over the junctions (interior breakpoints; every breakpoint of a periodic basis) of kbar kbar^T,
// kbar_i the jump of B_i^(p) across the junction (right limit minus left limit). Zero for p below the
// continuity order at simple knots (a cubic's jumps start at p = 3).
Eigen::MatrixXd SplineJumpMatrix(const BSplineBasis& basis, int derivative);

}  // namespace s2m
