#include "fitting/element_energy.h"

#include <cmath>
#include <stdexcept>

namespace s2m {

Eigen::MatrixXd DerivativeCoefficients(const ElementBasis& basis, int derivative) {
  if (derivative < 0) throw std::invalid_argument("negative derivative order");
  Eigen::MatrixXd c = basis.coefficients;
  const Eigen::Index terms = c.cols();
  // d/du = (1 / length) d/dy; d/dy of y^j is j y^(j-1).
  for (int p = 0; p < derivative; ++p) {
    Eigen::MatrixXd next = Eigen::MatrixXd::Zero(c.rows(), terms);
    for (Eigen::Index j = 1; j < terms; ++j)
      next.col(j - 1) = static_cast<double>(j) * c.col(j) / basis.length;
    c = next;
  }
  return c;
}

Eigen::MatrixXd ElementEnergyMatrix(const ElementBasis& basis, int derivative) {
  const Eigen::MatrixXd c = DerivativeCoefficients(basis, derivative);
  const Eigen::Index terms = c.cols();
  // integral_{y_lo}^{y_hi} y^(a+b) dy * length (du = length dy): the moments of the element, exact.
  Eigen::MatrixXd moments(terms, terms);
  for (Eigen::Index a = 0; a < terms; ++a)
    for (Eigen::Index b = 0; b < terms; ++b) {
      const double e = static_cast<double>(a + b + 1);
      moments(a, b) = basis.length * (std::pow(basis.y_hi, e) - std::pow(basis.y_lo, e)) / e;
    }
  return c * moments * c.transpose();
}

Eigen::VectorXd ElementDerivativeRow(const ElementBasis& basis, int derivative, double y) {
  const Eigen::MatrixXd c = DerivativeCoefficients(basis, derivative);
  Eigen::VectorXd out = Eigen::VectorXd::Zero(c.rows());
  for (Eigen::Index j = c.cols() - 1; j >= 0; --j) out = out * y + c.col(j);  // Horner
  return out;
}

}  // namespace s2m
