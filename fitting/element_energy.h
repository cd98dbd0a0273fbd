#pragma once
// Exact energy integrals of piecewise-polynomial bases (docs/fair-curves.md eqs. F5-F8): on one element (a
// Hermite element or a B-spline knot span) each basis function is a polynomial in a local coordinate y = (u -
// origin) / length, given by its power coefficients. The element matrix of the p-th derivative,
//   K_p(i, j) = integral over the element of phi_i^(p)(u) phi_j^(p)(u) du,
// is integrated exactly from the coefficients (no quadrature), and the row of p-th derivatives at one y gives
// the junction-jump vectors. One routine for the Hermite curves (fitting/hermite_curve.h) and the B-spline
// curves, surfaces and generatrices (fitting/bspline_models.h, fitting/kinematic_surfaces.h).

#include <Eigen/Core>

namespace s2m {

// The power coefficients of one element's basis: function i is sum_j coefficients(i, j) y^j, with y = (u -
// origin) / length over [y_lo, y_hi] (Hermite elements: [0, 1]; B-spline spans: [-1/2, 1/2]).
struct ElementBasis {
  Eigen::MatrixXd coefficients;  // functions x (degree + 1)
  double length = 1.0;           // du / dy
  double y_lo = 0.0, y_hi = 1.0;
};

// The power coefficients (in y) of the p-th derivative with respect to u: functions x (degree + 1), the
// columns above degree - p zero.
Eigen::MatrixXd DerivativeCoefficients(const ElementBasis& basis, int derivative);

// K_p = integral phi^(p) phi^(p)T du over the element, exact (functions x functions).
Eigen::MatrixXd ElementEnergyMatrix(const ElementBasis& basis, int derivative);

// phi_i^(p)(u) at local coordinate y, for every function i.
Eigen::VectorXd ElementDerivativeRow(const ElementBasis& basis, int derivative, double y);

}  // namespace s2m
