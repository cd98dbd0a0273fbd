#pragma once
// Robust losses of the squared residual (the meaning of Ceres' LossFunction): a point whose orthogonal
// distance is d contributes 1/2 rho(s) with s = d^2 to the objective instead of 1/2 s. The fits apply them by
// iteratively reweighted least squares: each point's error matrix is weighted by rho'(s) at the current foot
// points (docs/method.md section 15, eqs. 43-47; Triggs, McLauchlan, Hartley, Fitzgibbon, "Bundle
// adjustment - a modern synthesis", 2000, section 4.3, in its first-order form). The scale c is a distance in
// input units: given by the user, or c = k sigma from the data with sigma the MAD estimate of the normal
// distances (eq. 47) and k the loss's 95 %-efficiency constant.

#include <Eigen/Core>
#include <string>
#include <vector>

namespace s2m {

enum class LossKind {
  kNone,    // rho(s) = s: plain least squares
  kHuber,   // quadratic inside c, linear in |d| outside: bounded influence, no rejection
  kCauchy,  // logarithmic: influence decays as 1/|d|
  kTukey,   // biweight: constant outside c, i.e. points farther than c are rejected (weight 0)
};
const char* ToString(LossKind kind);

struct RobustLoss {
  LossKind kind = LossKind::kNone;
  // c, a distance in input units; 0: estimated from the data at every linearization (eq. 47).
  double scale = 0.0;
  bool is_robust() const { return kind != LossKind::kNone; }
  bool scale_from_data() const { return is_robust() && !(scale > 0.0); }
};

// "none", "huber", "huber:0.1", "cauchy[:c]", "tukey[:c]" (c > 0 in input units). Throws
// std::invalid_argument naming the accepted spellings.
RobustLoss ParseRobustLoss(const std::string& text);
std::string ToString(const RobustLoss& loss);  // the spelling ParseRobustLoss reads back

// rho(s), rho'(s) and rho''(s) at a squared residual s >= 0 for scale c > 0 (eq. 44).
struct LossValue {
  double rho = 0.0;
  double first = 1.0;   // rho'(s): the IRLS weight
  double second = 0.0;  // rho''(s)
};
LossValue EvaluateLoss(LossKind kind, double c, double s);

// k of c = k sigma: Huber 1.345, Cauchy 2.3849, Tukey 4.6851 (95 % asymptotic efficiency at the normal
// distribution; Holland & Welsch 1977). 1 for kNone.
double TuningConstant(LossKind kind);

// sigma = 1.4826 median |d_j| (eq. 47): the normal distances of a fitted surface scatter about zero, so the
// median absolute deviation is taken about zero, not about the median. 0 for no distances.
double MadSigma(const Eigen::Ref<const Eigen::VectorXd>& distances);

// A loss with its scale fixed for one linearization: what a fit evaluates per point. `Update` re-estimates
// the scale from the current distances when the loss takes it from the data (a floor keeps it positive on
// exact data: a relative 1e-12 of the largest distance, or 1e-300).
class RobustWeighting {
 public:
  RobustWeighting() = default;
  explicit RobustWeighting(const RobustLoss& loss) : loss_(loss), scale_(loss.scale) {}
  void Update(const Eigen::Ref<const Eigen::VectorXd>& distances);
  // In the fit's working units (the fits scale their data into the unit box: divide by that scale).
  void set_units(double length_unit) { unit_ = length_unit; }
  bool is_robust() const { return loss_.is_robust(); }
  // The scale in input units (what a report shows) and sigma of the last update (0 when given by the user).
  double scale() const { return scale_; }
  double sigma() const { return sigma_; }
  // rho(d^2) and rho'(d^2) for a distance d in working units (1/2 rho summed is the objective).
  double Rho(double d) const;
  double Weight(double d) const;
  // Weight of every distance (all 1 for plain least squares).
  Eigen::VectorXd Weights(const Eigen::Ref<const Eigen::VectorXd>& distances) const;
  const RobustLoss& loss() const { return loss_; }

 private:
  double working_scale() const { return scale_ / unit_; }
  RobustLoss loss_;
  double scale_ = 0.0;
  double sigma_ = 0.0;
  double unit_ = 1.0;
};

}  // namespace s2m
