#include "fitting/measurement_uncertainty.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace s2m {

UncertaintyMethod UncertaintyMethod::FromString(const std::string& text) {
  UncertaintyMethod m;
  if (text == "none") {
    m.kind = Kind::kNone;
    return m;
  }
  if (text == "linear") {
    m.kind = Kind::kLinear;
    return m;
  }
  const std::string prefix = "monte-carlo:";
  if (text.rfind(prefix, 0) == 0) {
    const std::string n = text.substr(prefix.size());
    std::size_t used = 0;
    int trials = 0;
    try {
      trials = std::stoi(n, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != n.size() || trials < 20 || trials > 1000000)
      throw std::invalid_argument(
          "--uncertainty monte-carlo:N needs a whole number of trials N in [20, 1e6], got '" + n + "'");
    m.kind = Kind::kMonteCarlo;
    m.trials = trials;
    return m;
  }
  throw std::invalid_argument("unknown uncertainty method '" + text + "' (none, linear, monte-carlo:N)");
}

std::string UncertaintyMethod::ToString() const {
  switch (kind) {
    case Kind::kNone:
      return "none";
    case Kind::kLinear:
      return "linear";
    case Kind::kMonteCarlo:
      return "monte-carlo:" + std::to_string(trials);
  }
  return "none";
}

std::vector<LinearPropagation> PropagateLinear(
    const std::function<Eigen::VectorXd(const Eigen::VectorXd&)>& f, const Eigen::VectorXd& p,
    const Eigen::MatrixXd& covariance, double relative_step, double absolute_step) {
  if (covariance.rows() != p.size() || covariance.cols() != p.size())
    throw std::invalid_argument("PropagateLinear: the covariance is not square of the parameters' size");
  const Eigen::VectorXd y = f(p);
  const Eigen::Index m = y.size();
  Eigen::MatrixXd c = Eigen::MatrixXd::Zero(p.size(), m);
  for (Eigen::Index k = 0; k < p.size(); ++k) {
    const double variance = covariance(k, k);
    if (!(variance > 0) && covariance.row(k).cwiseAbs().maxCoeff() == 0) continue;  // untouched
    const double h = variance > 0 ? relative_step * std::sqrt(variance) : absolute_step;
    Eigen::VectorXd plus = p, minus = p;
    plus[k] += h;
    minus[k] -= h;
    c.row(k) = ((f(plus) - f(minus)) / (2 * h)).transpose();
  }
  std::vector<LinearPropagation> out(static_cast<std::size_t>(m));
  for (Eigen::Index i = 0; i < m; ++i) {
    LinearPropagation& o = out[static_cast<std::size_t>(i)];
    o.value = y[i];
    o.sensitivities = c.col(i);
    const double variance = o.sensitivities.dot(covariance * o.sensitivities);  // JCGM 100:2008 eq. 13
    o.standard_uncertainty = std::sqrt(std::max(variance, 0.0));
  }
  return out;
}

LinearPropagation PropagateLinear(const std::function<double(const Eigen::VectorXd&)>& f,
                                  const Eigen::VectorXd& p, const Eigen::MatrixXd& covariance,
                                  double relative_step, double absolute_step) {
  return PropagateLinear([&f](const Eigen::VectorXd& q) { return Eigen::VectorXd::Constant(1, f(q)); }, p,
                         covariance, relative_step, absolute_step)[0];
}

MonteCarloSummary SummarizeMonteCarlo(std::vector<double> values, int failed_trials,
                                      double coverage_probability) {
  MonteCarloSummary s;
  s.failed_trials = failed_trials;
  s.coverage_probability = coverage_probability;
  std::erase_if(values, [](double v) { return !std::isfinite(v); });
  s.trials = static_cast<int>(values.size());
  if (values.size() < 2) return s;
  double sum = 0;
  for (double v : values) sum += v;
  s.mean = sum / static_cast<double>(values.size());
  double ss = 0;
  for (double v : values) ss += (v - s.mean) * (v - s.mean);
  s.standard_uncertainty = std::sqrt(ss / static_cast<double>(values.size() - 1));  // JCGM 101 eq. 13
  std::sort(values.begin(), values.end());
  // JCGM 101:2008, 7.7.2: the probabilistically symmetric interval, from the ((1 - p)/2) M-th and
  // ((1 + p)/2) M-th sorted values (rounded to the nearest whole numbers, at least 1 and at most M).
  const double m = static_cast<double>(values.size());
  auto at = [&](double rank) {
    const auto i = static_cast<std::size_t>(std::clamp(std::round(rank), 1.0, m)) - 1;
    return values[i];
  };
  s.interval_low = at((1 - coverage_probability) / 2 * m);
  s.interval_high = at((1 + coverage_probability) / 2 * m);
  return s;
}

std::vector<MonteCarloSummary> RunMonteCarlo(
    int trials, std::uint64_t seed,
    const std::function<std::optional<Eigen::VectorXd>(int trial, std::mt19937_64& random)>& trial) {
  if (trials < 2) throw std::invalid_argument("Monte Carlo needs at least 2 trials");
  std::vector<std::vector<double>> values;
  std::vector<int> failed;
  int outputs = -1;
  int failures = 0;
  for (int t = 0; t < trials; ++t) {
    std::seed_seq seq{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32),
                      static_cast<std::uint32_t>(t), 0x5eedu};
    std::mt19937_64 random(seq);
    const std::optional<Eigen::VectorXd> y = trial(t, random);
    if (!y) {
      ++failures;
      continue;
    }
    if (outputs < 0) {
      outputs = static_cast<int>(y->size());
      values.resize(static_cast<std::size_t>(outputs));
      failed.assign(static_cast<std::size_t>(outputs), 0);
    }
    if (y->size() != outputs) throw std::invalid_argument("Monte Carlo trials returned different sizes");
    for (int i = 0; i < outputs; ++i) {
      const double v = (*y)[i];
      if (std::isfinite(v))
        values[static_cast<std::size_t>(i)].push_back(v);
      else
        ++failed[static_cast<std::size_t>(i)];
    }
  }
  std::vector<MonteCarloSummary> out;
  for (int i = 0; i < std::max(outputs, 0); ++i)
    out.push_back(SummarizeMonteCarlo(values[static_cast<std::size_t>(i)],
                                      failures + failed[static_cast<std::size_t>(i)]));
  return out;
}

ExpandedUncertainty ExpandLinear(double standard_uncertainty, double coverage_factor) {
  ExpandedUncertainty e;
  e.standard_uncertainty = standard_uncertainty;
  e.coverage_factor = coverage_factor;
  e.expanded = coverage_factor * standard_uncertainty;
  e.coverage_probability = 0.95;
  e.method = "linear";
  return e;
}

ExpandedUncertainty ExpandMonteCarlo(const MonteCarloSummary& summary) {
  ExpandedUncertainty e;
  e.standard_uncertainty = summary.standard_uncertainty;
  e.coverage_probability = summary.coverage_probability;
  e.expanded = 0.5 * (summary.interval_high - summary.interval_low);
  e.coverage_factor = summary.standard_uncertainty > 0 ? e.expanded / summary.standard_uncertainty
                                                       : std::numeric_limits<double>::quiet_NaN();
  e.method = "monte-carlo";
  return e;
}

bool Specification::IsValid(std::string* why) const {
  auto fail = [why](const char* text) {
    if (why != nullptr) *why = text;
    return false;
  };
  if (!lower && !upper) return fail("a specification needs a lower or an upper limit");
  if ((lower && !std::isfinite(*lower)) || (upper && !std::isfinite(*upper)))
    return fail("a specification limit is not finite");
  if (lower && upper && *lower > *upper) return fail("the lower specification limit exceeds the upper one");
  return true;
}

const char* ToString(ConformityDecision decision) {
  switch (decision) {
    case ConformityDecision::kConforms:
      return "conforms";
    case ConformityDecision::kDoesNotConform:
      return "does not conform";
    case ConformityDecision::kNotDecidable:
      return "not decidable";
  }
  return "not decidable";
}

ConformityDecision DecideConformity(double value, double expanded_uncertainty, const Specification& spec) {
  std::string why;
  if (!spec.IsValid(&why)) throw std::invalid_argument(why);
  if (!std::isfinite(value)) return ConformityDecision::kNotDecidable;
  // An unknown U proves neither (ISO 14253-1:2017, 5.4: the uncertainty range is unbounded).
  const double u = std::isfinite(expanded_uncertainty) ? std::max(expanded_uncertainty, 0.0)
                                                       : std::numeric_limits<double>::infinity();
  if ((spec.lower && value < *spec.lower - u) || (spec.upper && value > *spec.upper + u))
    return ConformityDecision::kDoesNotConform;
  const bool above_lower = !spec.lower || value >= *spec.lower + u;
  const bool below_upper = !spec.upper || value <= *spec.upper - u;
  if (above_lower && below_upper) return ConformityDecision::kConforms;
  return ConformityDecision::kNotDecidable;
}

const char* PlainVerdict(double value, const Specification& spec) {
  const bool ok =
      std::isfinite(value) && (!spec.lower || value >= *spec.lower) && (!spec.upper || value <= *spec.upper);
  return ok ? "pass" : "fail";
}

}  // namespace s2m
