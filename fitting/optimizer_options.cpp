#include "fitting/optimizer_options.h"

#include <array>
#include <cmath>

#include "fitting/enum_names.h"

namespace s2m {
namespace {

bool Fail(std::string* why, const std::string& message) {
  if (why) *why = message;
  return false;
}

bool Positive(double v) {
  return std::isfinite(v) && v > 0.0;
}
bool NonNegative(double v) {
  return std::isfinite(v) && v >= 0.0;
}

constexpr std::array<EnumName<DampingUpdate>, 2> kDampingUpdateNames = {{
    {DampingUpdate::kMultiplicative, "multiplicative"},
    {DampingUpdate::kNielsen, "nielsen"},
}};

constexpr std::array<EnumName<StepStrategy>, 3> kStepStrategyNames = {{
    {StepStrategy::kTrustRegion, "levenberg-marquardt"},
    {StepStrategy::kFullStep, "none"},
    {StepStrategy::kArmijo, "armijo"},
}};

}  // namespace

const char* ToString(DampingUpdate update) {
  return NameOf(kDampingUpdateNames, update);
}

const char* ToString(StepStrategy strategy) {
  return NameOf(kStepStrategyNames, strategy);
}

bool DampingOptions::IsValid(std::string* why) const {
  if (!NonNegative(initial)) return Fail(why, "damping.initial must be finite and >= 0");
  if (!NonNegative(min)) return Fail(why, "damping.min must be finite and >= 0");
  if (!(max > 0.0) || std::isnan(max)) return Fail(why, "damping.max must be > 0");
  if (min > max) return Fail(why, "damping.min must not exceed damping.max");
  if (update == DampingUpdate::kMultiplicative) {
    if (!(increase > 1.0) || !std::isfinite(increase)) return Fail(why, "damping.increase must be > 1");
    if (!(decrease > 0.0 && decrease < 1.0)) return Fail(why, "damping.decrease must be in (0, 1)");
  }
  if (!NonNegative(diagonal_floor)) return Fail(why, "damping.diagonal_floor must be finite and >= 0");
  return true;
}

bool OptimizerOptions::IsValid(std::string* why) const {
  if (max_iterations < 0) return Fail(why, "max_iterations must be >= 0");
  if (!NonNegative(objective_tolerance)) return Fail(why, "objective_tolerance must be finite and >= 0");
  if (!NonNegative(step_tolerance)) return Fail(why, "step_tolerance must be finite and >= 0");
  if (!NonNegative(gradient_tolerance)) return Fail(why, "gradient_tolerance must be finite and >= 0");
  if (!NonNegative(target_rms)) return Fail(why, "target_rms must be finite and >= 0");
  if (!Positive(armijo_c) || armijo_c >= 1.0) return Fail(why, "armijo_c must be in (0, 1)");
  if (loss.is_robust() && (std::isnan(loss.scale) || loss.scale < 0.0 || std::isinf(loss.scale)))
    return Fail(why, "the loss scale must be finite and >= 0 (0: from the data)");
  return damping.IsValid(why);
}

}  // namespace s2m
