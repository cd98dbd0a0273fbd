#include "pipeline/shell_growth.h"

#include <Eigen/Cholesky>
#include <cmath>
#include <limits>

#include "fitting/measurement_uncertainty.h"
#include "pipeline/output.h"

namespace s2m::pipeline {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

nlohmann::json MeasureJson(const Measure& m) {
  return {{"value", NumberOrNull(m.value)}, {"uncertainty", NumberOrNull(m.uncertainty)}};
}

}  // namespace

std::vector<WhorlMeasures> MeasureWhorls(const SpiralSurface& shell, const Eigen::MatrixXd& shape_covariance,
                                         double angle_lo, double angle_hi, const std::string& units) {
  std::vector<WhorlMeasures> out;
  if (!(angle_hi >= angle_lo)) return out;
  const bool propagate = shape_covariance.rows() == shell.num_parameters();
  for (int k = 0; angle_hi - 2 * M_PI * k >= angle_lo; ++k) {
    WhorlMeasures w;
    w.whorls_from_last = k;
    w.angle = angle_hi - 2 * M_PI * k;
    const bool across = w.angle - M_PI >= angle_lo;  // the opposite side is in the data too
    auto measures = [&](const SpiralSurface& s) {
      const SpiralSurface::Whorl m = s.WhorlAt(w.angle);
      Eigen::VectorXd y(4);
      y << m.height, m.width, m.umbilical_width, m.diameter;
      return y;
    };
    const Eigen::VectorXd value = measures(shell);
    Eigen::VectorXd uncertainty = Eigen::VectorXd::Constant(4, kNaN);
    if (propagate) {
      const std::vector<LinearPropagation> u = PropagateLinear(
          [&](const Eigen::VectorXd& p) {
            SpiralSurface moved = shell;
            moved.set_parameters(p);
            return measures(moved);
          },
          shell.parameters(), shape_covariance);
      for (int i = 0; i < 4; ++i) uncertainty[i] = u[static_cast<std::size_t>(i)].standard_uncertainty;
    }
    w.height = {value[0], uncertainty[0], units};
    w.width = {value[1], uncertainty[1], units};
    w.umbilical_width = across ? Measure{value[2], uncertainty[2], units} : Measure{kNaN, kNaN, units};
    w.diameter = across ? Measure{value[3], uncertainty[3], units} : Measure{kNaN, kNaN, units};
    out.push_back(w);
  }
  return out;
}

nlohmann::json WhorlsJson(const std::vector<WhorlMeasures>& whorls) {
  nlohmann::json rows = nlohmann::json::array();
  for (const WhorlMeasures& w : whorls)
    rows.push_back({{"whorls_from_last", w.whorls_from_last},
                    {"angle", w.angle},
                    {"height", MeasureJson(w.height)},
                    {"width", MeasureJson(w.width)},
                    {"umbilical_width", MeasureJson(w.umbilical_width)},
                    {"diameter", MeasureJson(w.diameter)}});
  return rows;
}

SpiralSurface AllometricStart(const SpiralSurface& fitted) {
  return fitted.WithAllometry().WithAngleRange(fitted.v_lo() - M_PI / 2, fitted.v_hi() + M_PI / 2);
}

AllometryTest TestAllometry(const SpiralSurface& nested, const Eigen::MatrixXd& shape_covariance,
                            double rms_allometric, double rms_logarithmic,
                            std::optional<bool> logarithmic_trusted, double noise) {
  AllometryTest test;
  test.rms_logarithmic = rms_logarithmic;
  test.rms_allometric = rms_allometric;
  const int q_index = nested.num_parameters() - 2, a_index = nested.num_parameters() - 1;
  const double q = nested.growth_change(), a = nested.axial_excess();
  test.growth_change = {q, kNaN, "1/rad^2"};
  test.axial_excess = {a, kNaN, "1/rad"};
  // Eqs. S9-S10: the changes per whorl, u by the first-order propagation of q's and a's.
  const double per_whorl_w = std::exp(4 * M_PI * M_PI * q), per_whorl_shape = std::exp(2 * M_PI * a);
  test.expansion_rate_change_per_whorl = {per_whorl_w, kNaN, ""};
  test.shape_change_per_whorl = {per_whorl_shape, kNaN, ""};
  if (shape_covariance.rows() != nested.num_parameters()) {
    test.reason = "the allometric fit reports no covariance (too few points for its parameters)";
    return test;
  }
  const Eigen::Matrix2d V = shape_covariance({q_index, a_index}, {q_index, a_index});
  test.growth_change.uncertainty = std::sqrt(std::max(0.0, V(0, 0)));
  test.axial_excess.uncertainty = std::sqrt(std::max(0.0, V(1, 1)));
  test.expansion_rate_change_per_whorl.uncertainty =
      4 * M_PI * M_PI * per_whorl_w * test.growth_change.uncertainty;
  test.shape_change_per_whorl.uncertainty = 2 * M_PI * per_whorl_shape * test.axial_excess.uncertainty;
  const Eigen::LDLT<Eigen::Matrix2d> ldlt(V);
  if (ldlt.info() != Eigen::Success || !(V.determinant() > 0) || !std::isfinite(V.sum())) {
    test.reason =
        "q and a are not both observable from these data (their covariance is singular): the scan does not "
        "cover enough of the coil";
    return test;
  }
  // Eq. S8: the Wald statistic of theta = (q, a) against 0, chi-square with 2 degrees of freedom under the
  // logarithmic model, whose tail is exp(-chi2 / 2).
  const Eigen::Vector2d theta(q, a);
  test.chi2 = theta.dot(ldlt.solve(theta));
  test.p_value = std::exp(-0.5 * test.chi2);
  const bool significant = test.p_value < kAllometryAlpha;
  // When the logarithmic fit is not adequate, its residuals are not the noise alone and the covariance the
  // statistic divides by is not trusted; the allometric growth is still told when the nested model explains
  // the misfit, its RMS back within the noise band of the adequacy verdict.
  const bool explained =
      significant && std::isfinite(noise) && noise > 0 && test.rms_allometric <= kAdequacyThreshold * noise;
  if (logarithmic_trusted == false && !explained) {
    test.verdict = "inconclusive";
    test.reason =
        "the logarithmic fit is not adequate (its residuals are not the noise alone) and the allometric one "
        "does not bring the RMS (" +
        Format(test.rms_allometric, 4) +
        ") within the noise band: something "
        "else than allometric growth is wrong";
    return test;
  }
  if (significant) {
    test.verdict = "does not hold";
    test.reason = "allometric growth: the whorl expansion rate changes by a factor " +
                  Format(per_whorl_w, 4) + " per whorl and the generating curve's height-to-width ratio by " +
                  Format(per_whorl_shape, 4) + " (chi2 " + Format(test.chi2, 4) + ", p " +
                  Format(test.p_value, 2) + ")";
  } else {
    test.verdict = "holds";
    test.reason = "no allometric growth at the data's precision (chi2 " + Format(test.chi2, 4) + ", p " +
                  Format(test.p_value, 2) + ")";
  }
  return test;
}

nlohmann::json AllometryTest::ToJson() const {
  return {{"growth_change", MeasureJson(growth_change)},
          {"axial_excess", MeasureJson(axial_excess)},
          {"expansion_rate_change_per_whorl", MeasureJson(expansion_rate_change_per_whorl)},
          {"shape_change_per_whorl", MeasureJson(shape_change_per_whorl)},
          {"chi2", chi2},
          {"p_value", p_value},
          {"alpha", kAllometryAlpha},
          {"rms_logarithmic", rms_logarithmic},
          {"rms_allometric", rms_allometric},
          {"verdict", verdict},
          {"reason", reason},
          {"method",
           "the allometric spiral (docs/shells.md eq. S1) refitted jointly from the logarithmic fit; Wald "
           "test of q = a = 0 with 2 degrees of freedom"}};
}

}  // namespace s2m::pipeline
