#pragma once
// Foot points on parametric models (METHOD.md section 10): a seed from the nearest model sample or the
// previous parameter, then safeguarded Newton on the orthogonality condition C_t^T (C - X) = 0 that stays in
// the domain, wraps periodic seams and stops on a boundary when the closest point is there.

#include <vector>

#include "fitting/parametric_model.h"
#include "registration/nearest_index.h"

namespace s2m {

struct FootPoint {
  ParamT t{0.0, 0.0};
  double distance = 0.0;     // |C(t) - X|
  bool on_boundary = false;  // the closest point lies on an open boundary (e.g. an end of an open curve)
  bool excluded = false;     // the model cannot tell which of its pieces the point belongs to: left out
};

// Newton from t0. `scratch` avoids allocations on the hot path.
FootPoint RefineFootPoint(const ParametricModel& model, const ParameterDomain& domain, const VecS& x,
                          ParamT t0, LocalGeometry& scratch);

// True when t lies on an open end of domain `d` and C(t) - x (C(t) and its first derivatives in `g`) is not
// orthogonal to the model there: the foot point is the boundary's, not an orthogonal projection.
bool IsBoundaryFootPoint(const ParameterDomain& d, const ParamT& t, const LocalGeometry& g, const VecS& x);

// Samples of the current model in a k-d tree.
class FootPointSeeds {
 public:
  explicit FootPointSeeds(const ParametricModel& model);
  ParamT Nearest(const VecS& x) const;

 private:
  std::vector<ParamT> params_;
  NearestIndex index_;
};

// Foot points of all data points (columns of `points`), in parallel. With `warm` (one parameter per point)
// the better of the warm start and the nearest sample seeds Newton.
void ComputeFootPoints(const ParametricModel& model, const Eigen::MatrixXd& points,
                       std::vector<FootPoint>& feet, const std::vector<FootPoint>* warm = nullptr);

}  // namespace s2m
