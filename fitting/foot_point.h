#pragma once
// Foot points on parametric models (docs/method.md section 10): a seed from the nearest model sample or the
// previous parameter, then safeguarded Newton on the orthogonality condition C_t^T (C - X) = 0 that stays in
// the domain, wraps periodic seams and stops on a boundary when the closest point is there.

#include <mutex>
#include <optional>
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

// Newton from t0. `scratch` avoids allocations on the hot path; on return it holds C and its first and
// second derivatives at the returned foot. With `g_at_t0`, `scratch` already holds them at t0 (a parameter
// inside the domain, e.g. the previous foot on the same model): the first evaluation is skipped, with the
// same result.
FootPoint RefineFootPoint(const ParametricModel& model, const ParameterDomain& domain, const VecS& x,
                          ParamT t0, LocalGeometry& scratch, bool g_at_t0 = false);

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

// The sample tree built on first use, once, by whichever thread needs it first: warm starts need it only for
// the few points they fall back on, and closed-form models never.
class LazyFootPointSeeds {
 public:
  explicit LazyFootPointSeeds(const ParametricModel& model) : model_(model) {}
  const FootPointSeeds& get() const;

 private:
  const ParametricModel& model_;
  mutable std::once_flag once_;
  mutable std::optional<FootPointSeeds> seeds_;
};

// What every foot point of one model needs: its domain, whether it has closed-form feet (everywhere or
// nowhere), its seeds, and the reduction of its feet to a simpler model's when it has one
// (ParametricModel::MakeFootPointReduction), with that model's domain and seeds.
struct FootPointContext {
  explicit FootPointContext(const ParametricModel& model);
  const ParametricModel& model;
  ParameterDomain domain;
  bool closed_form = false;
  LazyFootPointSeeds seeds;
  std::unique_ptr<FootPointReduction> reduction;  // null: none
  ParameterDomain reduced_domain;
  std::optional<LazyFootPointSeeds> reduced_seeds;  // set with `reduction`
};

// How a warm start (the previous foot's parameter) is used.
enum class WarmStart {
  // Newton from the better of the previous parameter and the nearest model sample (the one whose model point
  // is closer to x). Safe when the model itself changed since the previous feet (fits: a large shape step can
  // move the basin of a point's foot, e.g. near the ends of an open curve).
  kVerified,
  // Newton straight from the previous parameter, no sample search; only a foot ending on an open boundary
  // (where Newton stops at a bound even if a closer interior foot exists) falls back to the nearest sample,
  // keeping the closer foot. For a fixed model and points that moved a little (rigid registration steps).
  kTrusted,
};

// The foot point of one data point x. Closed-form models answer directly (ParametricModel::ClosedFormFoot).
// Others run Newton: cold (`previous` null) from the nearest model sample, warm as `mode` says; models with a
// FootPointReduction run it on the reduced model (its samples, the leading entries of `previous`) and lift
// the foot, or, where the reduction does not hold, on the full model. On return
// `g` holds C and its first and second derivatives at the foot's t for Newton models; for closed-form models
// it is unspecified.
// With `g_at_previous` (trusted warm starts only), `g` holds the model's geometry at `previous` on entry
// (RefineFootPoint's `g_at_t0`).
FootPoint FootPointOf(const FootPointContext& context, const VecS& x, const ParamT* previous, WarmStart mode,
                      LocalGeometry& g, bool g_at_previous = false);

// Foot points of all data points (columns of `points`; any column-major storage binds without a copy), in
// parallel, by FootPointOf. With `warm` (one foot per point) each starts from its previous parameter.
void ComputeFootPoints(const ParametricModel& model, const Eigen::Ref<const Eigen::MatrixXd>& points,
                       std::vector<FootPoint>& feet, const std::vector<FootPoint>* warm = nullptr,
                       WarmStart mode = WarmStart::kVerified);

// The feet's distances |C(t_j) - X_j| as one vector (robust scales, residual statistics).
Eigen::VectorXd FootPointDistances(const std::vector<FootPoint>& feet);

}  // namespace s2m
