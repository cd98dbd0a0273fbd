#pragma once
// Uncertainty of derived quantities (docs/metrology.md sections 6-8): the GUM's law of propagation of
// uncertainty (JCGM 100:2008, section 5.1, eqs. 10 and 13) from a fit's covariance, with sensitivity
// coefficients by central differences (section 5.1.3, note 2); the Monte Carlo method of GUM Supplement 1
// (JCGM 101:2008, sections 7.2-7.7) over trial values the caller produces (refits of perturbed or resampled
// data); the expanded uncertainty U = k u (JCGM 100:2008, section 6); and decision rules for conformity
// with a specification (ISO 14253-1:2017, sections 5-6: conformance and non-conformance zones narrowed and
// widened by U, and the zone between them where neither can be proven).

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <random>
#include <string>
#include <vector>

namespace s2m {

// How uncertainties of derived quantities are evaluated: none, the law of propagation (linear), or Monte
// Carlo with `trials` trials.
struct UncertaintyMethod {
  enum class Kind { kNone, kLinear, kMonteCarlo } kind = Kind::kLinear;
  int trials = 0;  // Monte Carlo
  std::uint64_t seed = 1;
  // "none", "linear" or "monte-carlo:N" (N >= 20: fewer trials cannot give a 95 % interval, JCGM 101 7.2.2).
  // Throws std::invalid_argument naming the accepted spellings.
  static UncertaintyMethod FromString(const std::string& text);
  std::string ToString() const;
};

// The law of propagation of uncertainty for y = f(p) (JCGM 100:2008, eq. 13: u^2(y) = c^T V c with the
// sensitivity coefficients c_k = df/dp_k): c by central differences with the step h_k = relative_step x
// sqrt(V_kk) (absolute_step where V_kk is 0). Parameters the covariance does not touch need no step.
struct LinearPropagation {
  double value = 0.0;
  double standard_uncertainty = std::numeric_limits<double>::quiet_NaN();
  Eigen::VectorXd sensitivities;
};
LinearPropagation PropagateLinear(const std::function<double(const Eigen::VectorXd&)>& f,
                                  const Eigen::VectorXd& p, const Eigen::MatrixXd& covariance,
                                  double relative_step = 1e-3, double absolute_step = 1e-9);
// The same for several outputs at once (one column of sensitivities per output): u_i = sqrt(c_i^T V c_i).
std::vector<LinearPropagation> PropagateLinear(
    const std::function<Eigen::VectorXd(const Eigen::VectorXd&)>& f, const Eigen::VectorXd& p,
    const Eigen::MatrixXd& covariance, double relative_step = 1e-3, double absolute_step = 1e-9);

// One output of a Monte Carlo propagation (JCGM 101:2008, section 7.6): the estimate (the mean of the trial
// values), its standard uncertainty (their standard deviation), and the probabilistically symmetric coverage
// interval (section 7.7: the (1-p)/2 and (1+p)/2 quantiles of the sorted values).
struct MonteCarloSummary {
  int trials = 0;         // trial values used (finite)
  int failed_trials = 0;  // trials whose refit failed or gave a non-finite value (left out)
  double mean = std::numeric_limits<double>::quiet_NaN();
  double standard_uncertainty = std::numeric_limits<double>::quiet_NaN();
  double coverage_probability = 0.95;
  double interval_low = std::numeric_limits<double>::quiet_NaN();
  double interval_high = std::numeric_limits<double>::quiet_NaN();
};
MonteCarloSummary SummarizeMonteCarlo(std::vector<double> values, int failed_trials = 0,
                                      double coverage_probability = 0.95);

// Runs `trials` trials, each trial a fresh generator seeded from (seed, trial), so the result does not depend
// on the order or the thread count; `trial` returns the outputs (one per derived quantity; all of one size)
// or nullopt when the trial failed. One summary per output.
std::vector<MonteCarloSummary> RunMonteCarlo(
    int trials, std::uint64_t seed,
    const std::function<std::optional<Eigen::VectorXd>(int trial, std::mt19937_64& random)>& trial);

// An expanded uncertainty (JCGM 100:2008, section 6.2): U = k u with the coverage factor k, and the coverage
// probability it is meant for. Linear propagation: k = 2 (about 95 % for a normal distribution, section
// 6.3.3). Monte Carlo: U is the half-width of the 95 % probabilistically symmetric interval (JCGM 101, 7.7)
// and k = U / u is stated.
struct ExpandedUncertainty {
  double standard_uncertainty = std::numeric_limits<double>::quiet_NaN();
  double coverage_factor = 2.0;
  double expanded = std::numeric_limits<double>::quiet_NaN();  // U
  double coverage_probability = 0.95;
  std::string method;  // "linear" or "monte-carlo"
};
ExpandedUncertainty ExpandLinear(double standard_uncertainty, double coverage_factor = 2.0);
ExpandedUncertainty ExpandMonteCarlo(const MonteCarloSummary& summary);

// A specification: lower and upper specification limits (LSL, USL) of the characteristic's value; either may
// be absent (one-sided: e.g. a form error has only an upper limit).
struct Specification {
  std::optional<double> lower, upper;
  bool IsValid(std::string* why = nullptr) const;
};

// ISO 14253-1:2017 decision rule for the measured value y with expanded uncertainty U:
//   conformance is proven when  LSL + U <= y <= USL - U  (the conformance zone, section 5.2);
//   non-conformance is proven when y < LSL - U or y > USL + U  (section 5.3);
//   otherwise neither is proven: the uncertainty range about a limit (section 5.4): not decidable.
// An unknown U (NaN) proves nothing: always not decidable. A specification zone no wider than 2U has no
// conformance zone left (only non-conformance can be proven).
enum class ConformityDecision { kConforms, kDoesNotConform, kNotDecidable };
const char* ToString(ConformityDecision decision);  // "conforms", "does not conform", "not decidable"
ConformityDecision DecideConformity(double value, double expanded_uncertainty, const Specification& spec);
// The plain verdict ignoring the uncertainty (value within the limits): "pass" or "fail".
const char* PlainVerdict(double value, const Specification& spec);

}  // namespace s2m
