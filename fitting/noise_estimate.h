#pragma once
// The scanner noise of a set of views estimated without a model, to judge a fit's adequacy (its RMS relative
// to the noise, docs/batch.md).

#include "registration/scan.h"

namespace s2m {

// The median of a chi-square variable with `dof` degrees of freedom: exact for 2 (2 ln 2), else the
// Wilson-Hilferty approximation k (1 - 2 / (9k))^3 (Wilson & Hilferty 1931, PNAS 17(12), the cube root of
// chi-square / k being nearly normal; relative error below 1e-3 for k >= 3).
double ChiSquareMedian(int dof);

// The scanner noise of the views, without a model: per view, local quadrics (registration/local_quadric.h)
// over the 8 nearest neighbours of up to 500 points spread over the view; each gives SS / dof scaled to have
// the noise variance as its median; the square root of the median over all of them (docs/batch.md). NaN when
// fewer than 10 neighbourhoods could be fitted.
double EstimateNoise(const ScanSet& set);

// The noise of points along a curve (2 or 3 rows), without a model: around up to 500 points spread over the
// data, the 8 nearest neighbours in the frame of their principal direction (the tangent), each normal
// coordinate fitted by a quadratic in the tangential one; SS / dof scaled to have the noise variance as its
// median (as EstimateNoise). Returned on the scale of an orthogonal distance: sqrt(codim) sigma, codim = 1
// for a plane curve and 2 for a space curve (the distance spans the normal plane), i.e. the RMS a perfect
// model leaves (docs/method.md section 17). NaN when fewer than 10 neighbourhoods could be fitted.
double EstimateCurveNoise(const Eigen::Ref<const Eigen::MatrixXd>& points);

}  // namespace s2m
