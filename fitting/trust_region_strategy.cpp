#include "fitting/trust_region_strategy.h"

#include <algorithm>
#include <cmath>

namespace s2m {

LevenbergMarquardtStrategy::LevenbergMarquardtStrategy(const DampingOptions& options) : options_(options) {
  Reset();
}

void LevenbergMarquardtStrategy::Reset() {
  lambda_ = options_.initial;
  nu_ = 2.0;
}

void LevenbergMarquardtStrategy::StepAccepted(double gain_ratio) {
  if (options_.update == DampingUpdate::kNielsen) {
    // Madsen, Nielsen, Tingleff (2004), eq. 3.16 (docs/method.md eq. 41).
    lambda_ *= std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * gain_ratio - 1.0, 3));
    nu_ = 2.0;
  } else {
    lambda_ *= options_.decrease;  // eq. 41
  }
  lambda_ = std::max(lambda_, options_.min);
}

void LevenbergMarquardtStrategy::StepRejected() {
  if (options_.update == DampingUpdate::kNielsen) {
    lambda_ *= nu_;
    nu_ *= 2.0;
  } else {
    // An undamped start (lambda 0) cannot grow by a factor: it starts over from the smallest damping.
    lambda_ = lambda_ > 0.0 ? lambda_ * options_.increase : std::max(options_.min, 1e-300);
  }
}

}  // namespace s2m
