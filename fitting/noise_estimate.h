#pragma once
// The scanner noise of a set of views estimated without a model, to judge a fit's adequacy (its RMS relative
// to the noise, docs/batch.md).

#include <Eigen/Core>

#include "registration/scan.h"

namespace s2m {

// The median of a chi-square variable with `dof` degrees of freedom: exact for 2 (2 ln 2), else the
// Wilson-Hilferty approximation k (1 - 2 / (9k))^3 (Wilson & Hilferty 1931, PNAS 17(12), the cube root of
// chi-square / k being nearly normal; relative error below 1e-3 for k >= 3).
double ChiSquareMedian(int dof);

// The scanner noise of the views, without a model: per view, local quadrics (registration/local_quadric.h)
// over the 8 nearest neighbours of up to 500 points spread over the view; each gives SS / dof scaled to have
// the noise variance as its median; the square root of the median over all of them (docs/batch.md). On
// layered data (depth quantized into steps: more than 5 % of those quadrics fit exactly) over the 40 nearest
// neighbours instead (docs/method.md section 17). NaN when fewer than 10 neighbourhoods could be fitted.
double EstimateNoise(const ScanSet& set);

// EstimateNoise with what its precision depends on: the number of neighbourhoods m whose median it is, and
// the equivalent degrees of freedom of sigma^2, nu = 8 m (x f(x))^2 at the median x of the neighbourhoods'
// chi-square (f its density; 0.96 m for 2 degrees of freedom): the variance of a sample median is
// 1 / (4 m f^2) (Cramer 1946, section 28.5), and 2 / nu is that of sigma^2 / sigma^2 for a chi-square
// estimate with nu degrees of freedom (docs/method.md eq. 68).
struct NoiseEstimate {
  double sigma = 0.0;  // NaN when unknown
  int neighbourhoods = 0;
  double dof = 0.0;
  // The neighbourhoods' size (8, or 40 for layered data) and the fraction of 8-point neighbourhoods the
  // quadric fitted exactly; `layered` when that fraction says the data are quantized into layers (depth
  // cameras) and the estimate came from the larger neighbourhoods (EstimateNoiseWithDof).
  int neighbours = 8;
  double exact_fraction = 0.0;
  bool layered = false;
};
NoiseEstimate EstimateNoiseWithDof(const ScanSet& set);

// The noise of points along a curve (2 or 3 rows), without a model: around up to 1000 points spread over the
// data, the 7 nearest neighbours in the frame of their principal direction (the tangent), each normal
// coordinate fitted by a parabola in the tangential one (3 coefficients: k = codim (7 - 3) degrees of
// freedom per neighbourhood); SS / median(chi-square_k), the square root of the median over the
// neighbourhoods (as EstimateNoise; small neighbourhoods keep the curve's cubic terms out). `sigma` is on the
// scale of an orthogonal distance: sqrt(codim) times the per-coordinate noise, codim = 1 for a plane curve
// and 2 for a space curve (the distance spans the normal plane), i.e. the RMS a perfect model leaves
// (docs/method.md section 17); `dof` that of the per-coordinate variance (eq. 68). NaN sigma when fewer than
// 10 neighbourhoods could be fitted. One estimate for the adequacy verdict and the complexity band.
NoiseEstimate EstimateCurveNoise(const Eigen::Ref<const Eigen::MatrixXd>& points);

}  // namespace s2m
