#include "fitting/robust_loss.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <optional>
#include <stdexcept>

#include "fitting/enum_names.h"

namespace s2m {

namespace {

constexpr std::array<EnumName<LossKind>, 4> kLossKindNames = {{
    {LossKind::kNone, "none"},
    {LossKind::kHuber, "huber"},
    {LossKind::kCauchy, "cauchy"},
    {LossKind::kTukey, "tukey"},
}};

}  // namespace

const char* ToString(LossKind kind) {
  return NameOf(kLossKindNames, kind);
}

RobustLoss ParseRobustLoss(const std::string& text) {
  const std::size_t colon = text.find(':');
  const std::string name = text.substr(0, colon);
  RobustLoss loss;
  const std::optional<LossKind> kind = FindValue(kLossKindNames, name);
  const std::string spellings =
      " (none, huber[:scale], cauchy[:scale], tukey[:scale]; scale > 0 in input units)";
  if (!kind) throw std::invalid_argument("unknown loss '" + text + "'" + spellings);
  loss.kind = *kind;
  if (colon != std::string::npos) {
    const std::string value = text.substr(colon + 1);
    std::size_t used = 0;
    double scale = 0.0;
    try {
      scale = std::stod(value, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (loss.kind == LossKind::kNone || used != value.size() || value.empty() || !(scale > 0.0) ||
        !std::isfinite(scale)) {
      throw std::invalid_argument("bad loss '" + text + "'" + spellings);
    }
    loss.scale = scale;
  }
  return loss;
}

std::string ToString(const RobustLoss& loss) {
  std::string out = ToString(loss.kind);
  if (loss.is_robust() && loss.scale > 0.0) {
    char buffer[64];
    std::snprintf(buffer, sizeof buffer, ":%.17g", loss.scale);
    out += buffer;
  }
  return out;
}

LossValue EvaluateLoss(LossKind kind, double c, double s) {
  LossValue v;
  const double c2 = c * c;
  switch (kind) {
    case LossKind::kNone:  // eq. 44
      v.rho = s;
      break;
    case LossKind::kHuber:  // eq. 44
      if (s <= c2) {
        v.rho = s;
      } else {
        const double root = std::sqrt(s);
        v.rho = 2.0 * c * root - c2;
        v.first = c / root;
        v.second = -0.5 * v.first / s;
      }
      break;
    case LossKind::kCauchy: {  // eq. 44
      const double u = 1.0 + s / c2;
      v.rho = c2 * std::log1p(s / c2);
      v.first = 1.0 / u;
      v.second = -1.0 / (c2 * u * u);
      break;
    }
    case LossKind::kTukey:  // eq. 44
      if (s <= c2) {
        const double u = 1.0 - s / c2;
        v.rho = c2 / 3.0 * (1.0 - u * u * u);
        v.first = u * u;
        v.second = -2.0 * u / c2;
      } else {
        v.rho = c2 / 3.0;
        v.first = 0.0;
        v.second = 0.0;
      }
      break;
  }
  return v;
}

double TuningConstant(LossKind kind) {
  switch (kind) {
    case LossKind::kNone:
      return 1.0;
    case LossKind::kHuber:
      return 1.345;
    case LossKind::kCauchy:
      return 2.3849;
    case LossKind::kTukey:
      return 4.6851;
  }
  return 1.0;
}

double MadSigma(const Eigen::Ref<const Eigen::VectorXd>& distances) {
  if (distances.size() == 0) return 0.0;
  std::vector<double> a(static_cast<std::size_t>(distances.size()));
  for (Eigen::Index i = 0; i < distances.size(); ++i) a[static_cast<std::size_t>(i)] = std::abs(distances[i]);
  const std::size_t mid = a.size() / 2;
  std::nth_element(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(mid), a.end());
  double median = a[mid];
  if (a.size() % 2 == 0) {
    median = 0.5 * (median + *std::max_element(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(mid)));
  }
  return 1.4826 * median;  // eq. 47: the consistency factor 1 / Phi^-1(3/4) of the normal distribution
}

void RobustWeighting::Update(const Eigen::Ref<const Eigen::VectorXd>& distances) {
  if (!loss_.scale_from_data()) return;
  const double largest = distances.size() > 0 ? distances.cwiseAbs().maxCoeff() : 0.0;
  const double sigma = std::max(MadSigma(distances), std::max(1e-12 * largest, 1e-300));
  sigma_ = sigma * unit_;
  scale_ = TuningConstant(loss_.kind) * sigma_;
}

double RobustWeighting::Rho(double d) const {
  if (!loss_.is_robust() || !(scale_ > 0.0)) return d * d;
  return EvaluateLoss(loss_.kind, working_scale(), d * d).rho;
}

double RobustWeighting::Weight(double d) const {
  if (!loss_.is_robust() || !(scale_ > 0.0)) return 1.0;
  return EvaluateLoss(loss_.kind, working_scale(), d * d).first;
}

Eigen::VectorXd RobustWeighting::Weights(const Eigen::Ref<const Eigen::VectorXd>& distances) const {
  Eigen::VectorXd w(distances.size());
  for (Eigen::Index j = 0; j < distances.size(); ++j) w[j] = Weight(distances[j]);
  return w;
}

}  // namespace s2m
