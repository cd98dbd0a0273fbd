#pragma once
// Automatic model complexity for every spline and generatrix (docs/method.md section 18): start coarse,
// insert a knot where the residuals are largest (Wang, Pottmann, Liu, ACM TOG 25(2) 2006, section 6: control
// points are added where the fitting error is large), refit warm-started from the refined model (knot
// insertion keeps the shape exactly, Boehm 1980), and stop when the fit is adequate (its residual variance
// within the band the noise estimate allows, eq. 68) and further knots no longer pay by the Bayesian
// information criterion (Schwarz 1978, eq. 67). One strategy (ChooseComplexity) for every kind of spline fit;
// each kind supplies a RefinableFit: B-spline curves and surfaces (RefinableSplineFit) and the generatrices
// of surfaces of revolution, helical and spiral surfaces fitted jointly with their views' poses
// (RefinableGeneratrixFit, which also applies the generatrix end rule of eq. 70).

#include <Eigen/Core>
#include <array>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "fitting/bspline_basis.h"
#include "fitting/geometric_fit.h"
#include "fitting/joint_fit.h"
#include "fitting/parametric_model.h"
#include "registration/rigid_motion.h"

namespace s2m {

// A refined B-spline basis that represents the old spline exactly: knots inserted (Boehm's insertion keeps
// the shape, docs/method.md eq. 69), a clamped basis optionally trimmed to [lo, hi] (each end then a knot of
// full multiplicity), and the domain mapped affinely onto unit mean knot spacing, w = (u - lo) scale, so that
// the fairness weights keep the meaning they have for UnitSpacedClamped/UnitSpacedPeriodic.
struct BasisRefinement {
  BSplineBasis basis = BSplineBasis::ClampedUniform(2, 2);
  // new control points = old control points (columns) * transform^T: transform is n_new x n_old.
  Eigen::MatrixXd transform;
  double lo = 0.0, scale = 1.0;  // the parameter map w = (u - lo) * scale

  double Map(double u) const { return (u - lo) * scale; }
};
// `insert`: old parameters strictly inside the domain (not on an existing knot). Clamped bases only may be
// trimmed: lo < hi inside the old domain (NaN: keep the old ends). Throws std::invalid_argument for knots
// outside the domain, a trim of a periodic basis, or an empty trimmed domain.
BasisRefinement RefineBasis(const BSplineBasis& basis, const std::vector<double>& insert,
                            double lo = std::numeric_limits<double>::quiet_NaN(),
                            double hi = std::numeric_limits<double>::quiet_NaN());

// The generatrix end rule (docs/method.md eq. 70): the parameter span [lo, hi] a generatrix (a plane
// B-spline curve) keeps, from its data's foot parameters `feet_u`: their extent, cut where the curve turns
// back along its principal direction by more than `tolerance` (a fold or a curl at an end) unless that cut
// would drop more than a quarter of its length. The whole domain when there are no feet.
std::array<double, 2> GeneratrixEndRuleSpan(const BSplineBasis& basis, const Eigen::Matrix2Xd& profile,
                                            std::vector<double> feet_u, double tolerance);

// The knot spans of `basis` (distinct breakpoints) and the sum of the squared residuals of the points whose
// foot parameter lies in each (the insertion rule of eq. 69).
struct SpanResiduals {
  std::vector<double> breakpoints;  // spans [breakpoints[i], breakpoints[i + 1]]
  std::vector<double> sum_squares;  // one per span
  std::vector<Eigen::Index> points;
};
SpanResiduals ResidualsPerSpan(const BSplineBasis& basis, const std::vector<double>& parameters,
                               const std::vector<double>& squared_residuals);

// The Bayesian information criterion of a least-squares fit with Gaussian errors of unknown variance:
// n ln(SS / n) + p ln n (eq. 67).
double InformationCriterion(double sum_squares, double points, int parameters);
// The upper (1 - alpha) quantile of the F distribution with (d1, d2) degrees of freedom, by Paulson's
// normal approximation of the cube roots (eq. 68; exact to about 1e-3 for d1, d2 >= 30).
double FQuantile(double alpha, double d1, double d2);
// The upper quantile z_(1-alpha) of the standard normal distribution (Acklam's rational approximation,
// relative error below 1.2e-9).
double NormalQuantile(double p);

struct ComplexityOptions {
  // Model-free noise estimate (standard deviation, the distances' units; fitting/noise_estimate.h) and its
  // degrees of freedom (NoiseEstimate::dof); NaN noise: unknown, only the information criterion decides.
  double noise = std::numeric_limits<double>::quiet_NaN();
  double noise_dof = std::numeric_limits<double>::infinity();
  double significance = 0.01;  // alpha of the adequacy band (eq. 68)
  // Insertions in a row without a new lowest criterion before the search stops: when the fit is adequate
  // (or the noise unknown), and when it is not (more knots keep being tried while the fit is not adequate).
  int patience_adequate = 2;
  int patience_inadequate = 4;
};

// One fitted complexity and the criterion's values.
struct ComplexityStep {
  std::string control_points;  // "12", "8x6"
  int parameters = 0;          // the shape parameters (poses excluded)
  double points = 0;           // n (robust fits: the sum of the IRLS weights)
  double sum_squares = 0.0;
  double rms = 0.0;
  double bic = 0.0;                                            // eq. 67
  double band_rms = std::numeric_limits<double>::quiet_NaN();  // the largest adequate RMS (eq. 68)
  std::optional<bool> adequate;                                // empty when the noise is unknown
  int iterations = 0;
  bool valid = true;  // RefinableFit::Outcome::valid; invalid steps are never chosen
};

struct ComplexityChoice {
  std::vector<ComplexityStep> steps;
  std::size_t chosen = 0;   // index into steps
  std::string stop_reason;  // why the search ended
  // "auto" when chosen by ChooseComplexity, "fixed" for a given count (one step).
  std::string mode = "auto";
};

// A fit whose complexity can grow.
class RefinableFit {
 public:
  virtual ~RefinableFit() = default;
  struct Outcome {
    double sum_squares = 0.0;  // robust fits: sum w_j d_j^2 with the final IRLS weights
    double points = 0;         // robust fits: sum w_j
    int shape_parameters = 0;
    int other_parameters = 0;  // fitted alongside (poses), for the degrees of freedom n - p
    int iterations = 0;
    // False when the fitted model is not a usable answer (a generatrix that folds back along itself: two
    // sheets fit the noise band of rough data better than one, so the criterion would reward the fold).
    bool valid = true;
  };
  // Fits at the current complexity, warm-started from the current state.
  virtual Outcome Fit() = 0;
  virtual std::string ControlPoints() const = 0;
  // Inserts a knot where the last fit's residuals are largest; false when no knot can be added (the
  // maximum reached, no span with data).
  virtual bool Refine() = 0;
  // Keeps the current state (model and results) as step `index`; Restore brings a kept state back.
  virtual void Keep(std::size_t index) = 0;
  virtual void Restore(std::size_t index) = 0;
};

// The strategy of docs/method.md section 18: fit, record, stop or refine, then restore the chosen step.
ComplexityChoice ChooseComplexity(RefinableFit& fit, const ComplexityOptions& options);
// One fit at the given complexity, recorded like a step of ChooseComplexity (mode "fixed"). With
// `refine_to` > 0 (curves and generatrices) the fit starts at the model's coarser count and inserts knots
// where the residuals are largest up to that count, then fits again: a fresh fit with many control points
// from a rough start can snake along the surface (measured on the synthetic vase at 16: the generatrix
// doubles back three times), the coarse fit cannot.
ComplexityChoice FitFixedComplexity(RefinableFit& fit, const ComplexityOptions& options, int refine_to = 0);

// B-spline curves (open or closed, 2D or 3D) and surfaces fitted by FitModel.
class RefinableSplineFit final : public RefinableFit {
 public:
  // `model` (a BSplineCurve or BSplineSurface) is updated in place; `max_control_points` bounds a curve's
  // count, or each direction of a surface.
  RefinableSplineFit(ParametricModel& model, const Eigen::MatrixXd& points, GeometricFitOptions options,
                     int max_control_points);
  Outcome Fit() override;
  std::string ControlPoints() const override;
  bool Refine() override;
  void Keep(std::size_t index) override;
  void Restore(std::size_t index) override;
  const GeometricFitResult& result() const { return result_; }
  // Total iterations over all fits (the cost of the search).
  int total_iterations() const { return total_iterations_; }

 private:
  ParametricModel& model_;
  Eigen::MatrixXd points_;  // a copy: callers pass fixed-row matrices that convert to a temporary
  GeometricFitOptions options_;
  int max_control_points_;
  GeometricFitResult result_;
  int total_iterations_ = 0;
  std::vector<std::pair<std::unique_ptr<ParametricModel>, GeometricFitResult>> kept_;
};

// The generatrix of a surface of revolution or helical surface (KinematicSurface) or of a spiral surface
// (SpiralSurface), fitted jointly with the views' poses (FitJointly). Every Fit applies the generatrix end
// rule (eq. 70): the generatrix is trimmed to the parameter span its data's feet support and cut where it
// folds back along its principal direction, then refitted; knots are re-inserted if trimming dropped a span,
// so the count is kept.
class RefinableGeneratrixFit final : public RefinableFit {
 public:
  RefinableGeneratrixFit(ParametricModel& model, const std::vector<Eigen::Matrix3Xd>& scans,
                         std::vector<RigidMotion> model_T_scan, JointFitOptions options,
                         int max_control_points);
  Outcome Fit() override;
  std::string ControlPoints() const override;
  bool Refine() override;
  void Keep(std::size_t index) override;
  void Restore(std::size_t index) override;
  const JointFitResult& result() const { return result_; }
  int total_iterations() const { return total_iterations_; }
  // How often the end rule trimmed or cut the generatrix (over all fits).
  int end_rule_cuts() const { return end_rule_cuts_; }

 private:
  void ComputeFeet();  // feet_u_, feet_d2_ of the registered points on the current model
  // True when the generatrix changed; `transform` (n_new x n_old) then maps the old profile's control
  // points to the new ones (columns: new = old * transform^T).
  bool ApplyEndRule(Eigen::MatrixXd* transform = nullptr, double tolerance_in_rms = 0.01);
  Eigen::MatrixXd InsertKnotAtLargestResidual();  // returns the transform
  // After a cut without a refit: residual statistics of the feet, the covariance mapped by `transform`.
  void UpdateResultAfterCut(const Eigen::MatrixXd& transform);
  // True when the generatrix turns back along its principal direction by more than a tenth of the RMS.
  bool Folded() const;

  ParametricModel& model_;
  const std::vector<Eigen::Matrix3Xd>& scans_;
  std::vector<RigidMotion> model_T_scan_;
  JointFitOptions options_;
  int max_control_points_;
  JointFitResult result_;
  std::vector<double> feet_u_, feet_d2_;  // of the points used (not left out), scan after scan
  std::vector<Eigen::Index> used_per_scan_;
  int total_iterations_ = 0;
  int end_rule_cuts_ = 0;
  struct KeptState {
    std::unique_ptr<ParametricModel> model;
    JointFitResult result;
    std::vector<RigidMotion> poses;
  };
  std::vector<KeptState> kept_;
};

// The generatrix of a kinematic or spiral surface with a new basis and profile (the same pitch, turns,
// growth and angle range); throws std::invalid_argument for other models.
std::unique_ptr<ParametricModel> WithGeneratrix(const ParametricModel& model, BSplineBasis basis,
                                                Eigen::Matrix2Xd profile);
// The generatrix's basis and profile of a KinematicSurface or SpiralSurface (nullptr pair otherwise).
const BSplineBasis* GeneratrixBasis(const ParametricModel& model);
const Eigen::Matrix2Xd* GeneratrixProfile(const ParametricModel& model);

}  // namespace s2m
