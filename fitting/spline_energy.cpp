#include "fitting/spline_energy.h"

#include <cmath>
#include <vector>

#include "fitting/element_energy.h"

namespace s2m {
namespace {

// The spans of the domain in order (one per interval between breakpoints, zero-length spans of repeated knots
// skipped), each as an ElementBasis: its order functions in y = (t - mid) / length over [-1/2, 1/2].
struct Span {
  int index = 0;
  ElementBasis basis;
};
std::vector<Span> Spans(const BSplineBasis& b) {
  const std::vector<double> breaks = b.Breakpoints();
  const int k = b.order();
  std::vector<Span> out;
  for (std::size_t q = 0; q + 1 < breaks.size(); ++q) {
    double y = 0.0, inv_length = 0.0;
    Span span;
    span.index = b.LocateSpan(0.5 * (breaks[q] + breaks[q + 1]), y, inv_length);
    span.basis.coefficients.resize(k, k);
    for (int i = 0; i < k; ++i)
      for (int j = 0; j < k; ++j) span.basis.coefficients(i, j) = b.TaylorCoefficient(span.index, 0, j, i);
    span.basis.length = 1.0 / inv_length;
    span.basis.y_lo = -0.5;
    span.basis.y_hi = 0.5;
    out.push_back(span);
  }
  return out;
}

}  // namespace

Eigen::MatrixXd SplineEnergyMatrix(const BSplineBasis& b, int derivative) {
  const int n = b.num_control(), k = b.order();
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(n, n);
  for (const Span& span : Spans(b)) {
    const Eigen::MatrixXd ke = ElementEnergyMatrix(span.basis, derivative);  // docs/fair-curves.md eq. F5
    const int first = b.FirstFunction(span.index);
    for (int i = 0; i < k; ++i)
      for (int j = 0; j < k; ++j) g(b.ControlIndex(first, i), b.ControlIndex(first, j)) += ke(i, j);
  }
  return g;
}

Eigen::MatrixXd SplineJumpMatrix(const BSplineBasis& b, int derivative) {
  const int n = b.num_control(), k = b.order();
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(n, n);
  // The non-empty spans in order; consecutive ones meet at a junction (and, periodic, the last meets the
  // first).
  const std::vector<Span> spans = Spans(b);
  const std::size_t count = spans.size();
  const std::size_t junctions = b.periodic() ? count : (count > 0 ? count - 1 : 0);
  for (std::size_t q = 0; q < junctions; ++q) {
    const Span &left = spans[q], &right = spans[(q + 1) % count];
    // kbar = B^(p) of the right span at its start minus the left span's at its end (eq. F7).
    Eigen::VectorXd jump = Eigen::VectorXd::Zero(n);
    const Eigen::VectorXd r = ElementDerivativeRow(right.basis, derivative, -0.5),
                          l = ElementDerivativeRow(left.basis, derivative, 0.5);
    for (int i = 0; i < k; ++i) {
      jump[b.ControlIndex(b.FirstFunction(right.index), i)] += r[i];
      jump[b.ControlIndex(b.FirstFunction(left.index), i)] -= l[i];
    }
    out += jump * jump.transpose();
  }
  return out;
}

}  // namespace s2m
