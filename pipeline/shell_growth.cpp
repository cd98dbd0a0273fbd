#include "pipeline/shell_growth.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "fitting/measurement_uncertainty.h"
#include "pipeline/output.h"
#include "pipeline/svg.h"

namespace s2m::pipeline {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

nlohmann::json MeasureJson(const Measure& m) {
  return {{"value", NumberOrNull(m.value)}, {"uncertainty", NumberOrNull(m.uncertainty)}};
}

// One cut of the coil by the section's plane: the generating curve at coiling angle `angle`, drawn at x = +r
// (right of the axis) or x = -r (left), z up; in the model's units.
struct SectionCut {
  double angle = 0.0;
  int whorls_from_last = 0;
  bool right = true;
  bool scanned = true;
  std::vector<Eigen::Vector2d> points;  // (x, z)
};

constexpr int kSectionSamples = 241;         // along the generating curve
constexpr int kMostExtrapolatedWhorls = 30;  // on either side of the axis

}  // namespace

double LastAngleUncertainty(const std::vector<double>& foot_angles, double angle_hi) {
  constexpr double kWindow = 0.2 * M_PI;  // a tenth of a turn
  const auto in_window = std::count_if(foot_angles.begin(), foot_angles.end(),
                                       [&](double v) { return v >= angle_hi - kWindow && v <= angle_hi; });
  return in_window > 0 ? kWindow / static_cast<double>(in_window) : kNaN;
}

double CurveEndUncertainty(const std::vector<double>& foot_parameters, double lo, double hi, bool at_hi) {
  const double window = 0.1 * (hi - lo);  // a tenth of the covered range, as eq. S7a's tenth of a turn
  if (!(window > 0)) return kNaN;
  const auto in_window = std::count_if(foot_parameters.begin(), foot_parameters.end(), [&](double u) {
    return at_hi ? u >= hi - window && u <= hi : u >= lo && u <= lo + window;
  });
  return in_window > 0 ? window / static_cast<double>(in_window) : kNaN;
}

ShellCoverage MeasureCoverage(const std::vector<FootPoint>& feet) {
  ShellCoverage c;
  std::vector<double> angles, parameters;
  for (const FootPoint& f : feet)
    if (!f.excluded && std::isfinite(f.t[0]) && std::isfinite(f.t[1])) {
      parameters.push_back(f.t[0]);
      angles.push_back(f.t[1]);
    }
  if (angles.empty()) return c;
  const auto [angle_lo, angle_hi] = std::minmax_element(angles.begin(), angles.end());
  const auto [curve_lo, curve_hi] = std::minmax_element(parameters.begin(), parameters.end());
  c.angle_lo = *angle_lo;
  c.angle_hi = *angle_hi;
  c.angle_uncertainty = LastAngleUncertainty(angles, c.angle_hi);
  c.curve_lo = *curve_lo;
  c.curve_hi = *curve_hi;
  c.curve_lo_uncertainty = CurveEndUncertainty(parameters, c.curve_lo, c.curve_hi, false);
  c.curve_hi_uncertainty = CurveEndUncertainty(parameters, c.curve_lo, c.curve_hi, true);
  return c;
}

ShellEnds EstimateEnds(const SpiralSurface& shell, const ShellCoverage& coverage) {
  auto spacing = [](double u) { return std::isfinite(u) && u > 0 ? u : 0.0; };
  ShellEnds e;
  e.angle = coverage.angle_hi + spacing(coverage.angle_uncertainty);
  e.curve_lo = shell.CurvePoint(coverage.curve_lo) -
               spacing(coverage.curve_lo_uncertainty) * shell.CurvePoint(coverage.curve_lo, 1);
  e.curve_hi = shell.CurvePoint(coverage.curve_hi) +
               spacing(coverage.curve_hi_uncertainty) * shell.CurvePoint(coverage.curve_hi, 1);
  return e;
}

namespace {

// Values f(shell, end_lo, end_hi) of a shell measured between the ends of its generating curve, and their
// variances: the shape covariance's share with the ends held where the data end (eq. S5a: a change of the
// curve that only slides it along itself, which the data do not see, moves no end), and each end's own
// share (eq. S7b), the end slid along the curve's tangent (central differences) times its uncertainty.
using HeldEndMeasures =
    std::function<Eigen::VectorXd(const SpiralSurface&, const Eigen::Vector2d&, const Eigen::Vector2d&)>;

// The step of the central differences along an end (the coil's angle, the curve's parameter).
constexpr double kEndStep = 1e-4;

// The variance an end's standard uncertainty `share` adds to values whose central differences over
// +-kEndStep along that end are `plus` and `minus`: (df/ds share)^2; zero without a finite positive share.
Eigen::ArrayXd EndShareVariance(const Eigen::VectorXd& plus, const Eigen::VectorXd& minus, double share) {
  if (!(std::isfinite(share) && share > 0)) return Eigen::ArrayXd::Zero(plus.size());
  return ((plus - minus).array() / (2 * kEndStep) * share).square();
}

struct HeldEndVariances {
  Eigen::ArrayXd shape, curve_lo, curve_hi;  // the shape covariance's share and each end's (eq. S7b)
  Eigen::ArrayXd Total() const { return shape + curve_lo + curve_hi; }
};
HeldEndVariances HeldEndVariance(const SpiralSurface& shell, const Eigen::MatrixXd& shape_covariance,
                                 const ShellCoverage& coverage, const ShellEnds& ends,
                                 const HeldEndMeasures& f) {
  const std::vector<LinearPropagation> u = PropagateLinear(
      [&](const Eigen::VectorXd& p) {
        SpiralSurface moved = shell;
        moved.set_parameters(p);
        return f(moved, ends.curve_lo, ends.curve_hi);
      },
      shell.parameters(), shape_covariance);
  const auto n = static_cast<Eigen::Index>(u.size());
  HeldEndVariances variance{Eigen::ArrayXd(n), Eigen::ArrayXd::Zero(n), Eigen::ArrayXd::Zero(n)};
  for (Eigen::Index i = 0; i < n; ++i)
    variance.shape[i] = std::pow(u[static_cast<std::size_t>(i)].standard_uncertainty, 2);
  // Each end slid along the curve's tangent.
  if (const double share = coverage.curve_lo_uncertainty; std::isfinite(share) && share > 0) {
    const Eigen::Vector2d step = kEndStep * shell.CurvePoint(coverage.curve_lo, 1);
    variance.curve_lo = EndShareVariance(f(shell, ends.curve_lo + step, ends.curve_hi),
                                         f(shell, ends.curve_lo - step, ends.curve_hi), share);
  }
  if (const double share = coverage.curve_hi_uncertainty; std::isfinite(share) && share > 0) {
    const Eigen::Vector2d step = kEndStep * shell.CurvePoint(coverage.curve_hi, 1);
    variance.curve_hi = EndShareVariance(f(shell, ends.curve_lo, ends.curve_hi + step),
                                         f(shell, ends.curve_lo, ends.curve_hi - step), share);
  }
  return variance;
}

}  // namespace

std::vector<WhorlMeasures> MeasureWhorls(const SpiralSurface& shell, const Eigen::MatrixXd& shape_covariance,
                                         const ShellCoverage& coverage, const std::string& units) {
  std::vector<WhorlMeasures> out;
  if (!coverage.covered()) return out;
  const bool propagate = shape_covariance.rows() == shell.num_parameters();
  // Where the shell ends (eq. S7c).
  const ShellEnds ends = EstimateEnds(shell, coverage);
  auto measures = [&](const SpiralSurface& s, double angle, const Eigen::Vector2d& lo,
                      const Eigen::Vector2d& hi) {
    const SpiralSurface::Whorl m =
        s.WhorlAt(angle, s.ExtentsBetween(coverage.curve_lo, coverage.curve_hi, lo, hi));
    Eigen::VectorXd y(4);
    y << m.height, m.width, m.umbilical_width, m.diameter;
    return y;
  };
  for (int k = 0; coverage.angle_hi - 2 * M_PI * k >= coverage.angle_lo; ++k) {
    WhorlMeasures w;
    w.whorls_from_last = k;
    w.angle = ends.angle - 2 * M_PI * k;
    const bool across = w.angle - M_PI >= coverage.angle_lo;  // the opposite side is in the data too
    const Eigen::VectorXd value = measures(shell, w.angle, ends.curve_lo, ends.curve_hi);
    Eigen::VectorXd uncertainty = Eigen::VectorXd::Constant(4, kNaN);
    Eigen::Matrix<double, 4, 3> end_shares = Eigen::Matrix<double, 4, 3>::Constant(kNaN);
    if (propagate) {
      const HeldEndVariances held =
          HeldEndVariance(shell, shape_covariance, coverage, ends,
                          [&](const SpiralSurface& s, const Eigen::Vector2d& lo, const Eigen::Vector2d& hi) {
                            return measures(s, w.angle, lo, hi);
                          });
      // Eq. S7a: all rows move with the coil's end; the measures' derivative along the coil (central
      // differences) times its uncertainty, in quadrature.
      const Eigen::ArrayXd coil = EndShareVariance(
          measures(shell, w.angle + kEndStep, ends.curve_lo, ends.curve_hi),
          measures(shell, w.angle - kEndStep, ends.curve_lo, ends.curve_hi), coverage.angle_uncertainty);
      uncertainty = (held.Total() + coil).sqrt().matrix();
      end_shares << coil.sqrt().matrix(), held.curve_lo.sqrt().matrix(), held.curve_hi.sqrt().matrix();
    }
    w.height = {value[0], uncertainty[0], units};
    w.width = {value[1], uncertainty[1], units};
    w.umbilical_width = across ? Measure{value[2], uncertainty[2], units} : Measure{kNaN, kNaN, units};
    w.diameter = across ? Measure{value[3], uncertainty[3], units} : Measure{kNaN, kNaN, units};
    if (!across) end_shares.bottomRows<2>().setConstant(kNaN);
    w.end_shares = end_shares;
    out.push_back(w);
  }
  return out;
}

void MeasureRaup(const SpiralSurface& shell, const Eigen::MatrixXd& shape_covariance,
                 const ShellCoverage& coverage, ShellMeasures& out) {
  const bool held = coverage.covered();
  const ShellEnds ends = held ? EstimateEnds(shell, coverage) : ShellEnds{};
  auto measures = [&](const SpiralSurface& s, const Eigen::Vector2d& lo, const Eigen::Vector2d& hi) {
    const SpiralSurface::Raup m =
        held ? s.RaupParameters(s.ExtentsBetween(coverage.curve_lo, coverage.curve_hi, lo, hi))
             : s.RaupParameters();
    const SpiralSurface::GrowingTube g = SpiralSurface::GrowingTubeFromRaup(m);
    Eigen::VectorXd y(5);
    y << m.d, m.t, g.expansion, g.curvature, g.torsion;
    return y;
  };
  const Eigen::VectorXd value = measures(shell, ends.curve_lo, ends.curve_hi);
  Eigen::VectorXd uncertainty = Eigen::VectorXd::Constant(5, kNaN);
  if (shape_covariance.rows() == shell.num_parameters())
    uncertainty = HeldEndVariance(shell, shape_covariance, coverage, ends, measures).Total().sqrt().matrix();
  out.raup_d = {value[0], uncertainty[0], ""};
  out.raup_t = {value[1], uncertainty[1], ""};
  out.tube_expansion = {value[2], uncertainty[2], ""};
  out.tube_curvature = {value[3], uncertainty[3], ""};
  out.tube_torsion = {value[4], uncertainty[4], ""};
}

nlohmann::json WhorlsJson(const std::vector<WhorlMeasures>& whorls) {
  nlohmann::json rows = nlohmann::json::array();
  for (const WhorlMeasures& w : whorls) {
    auto measure = [&](const Measure& m, Eigen::Index i) {
      nlohmann::json j = MeasureJson(m);
      j["end_shares"] = {{"coil", NumberOrNull(w.end_shares(i, 0))},
                         {"curve_lo", NumberOrNull(w.end_shares(i, 1))},
                         {"curve_hi", NumberOrNull(w.end_shares(i, 2))}};
      return j;
    };
    rows.push_back({{"whorls_from_last", w.whorls_from_last},
                    {"angle", w.angle},
                    {"height", measure(w.height, 0)},
                    {"width", measure(w.width, 1)},
                    {"umbilical_width", measure(w.umbilical_width, 2)},
                    {"diameter", measure(w.diameter, 3)}});
  }
  return rows;
}

std::string ShellSectionSvg(const SpiralSurface& shell, double angle_lo, double angle_hi,
                            const std::string& units) {
  using svg::Line;
  using svg::Num;
  using svg::Text;
  if (!(std::isfinite(angle_lo) && std::isfinite(angle_hi) && angle_lo <= angle_hi))
    throw std::invalid_argument("the shell's section needs a finite range of coiling angles, lowest first");
  // The surface over every angle drawn: Evaluate holds v within the surface's range.
  const double lowest =
      std::min({shell.v_lo(), angle_lo, angle_hi - M_PI - 2 * M_PI * (kMostExtrapolatedWhorls + 1)});
  const SpiralSurface whole = shell.WithAngleRange(lowest, std::max(shell.v_hi(), angle_hi));
  auto size = [&](double v) {
    const SpiralSurface::Whorl w = whole.WhorlAt(v);
    return std::max(w.height, w.width);
  };
  const SpiralSurface::Whorl last = whole.WhorlAt(angle_hi);
  const double outermost = std::max(last.height, last.width);
  const double u_lo = whole.basis().lo(), u_hi = whole.basis().hi();
  std::vector<SectionCut> cuts;
  LocalGeometry g;
  for (const bool right : {true, false}) {
    int extrapolated = 0;
    for (int k = 0;; ++k) {
      SectionCut cut;
      cut.angle = angle_hi - (right ? 0.0 : M_PI) - 2 * M_PI * k;
      cut.whorls_from_last = k;
      cut.right = right;
      cut.scanned = cut.angle >= angle_lo;
      // Below the data, inner whorls while they are not too small to draw and still shrink towards the apex
      // (an allometric growth rate may turn negative far outside the data).
      if (!cut.scanned) {
        const double here = size(cut.angle);
        if (++extrapolated > kMostExtrapolatedWhorls || !(here > kSectionSmallestWhorl * outermost) ||
            !(here < size(cut.angle + M_PI)))
          break;
      }
      // The distance from the axis signed along the half-plane's direction (cos v, sin v): hypot(x, y) where
      // the generating curve keeps to its side of the axis, and a curve that crosses it is drawn across.
      const double c = std::cos(cut.angle), s = std::sin(cut.angle);
      for (int i = 0; i < kSectionSamples; ++i) {
        whole.Evaluate(ParamT{u_lo + (u_hi - u_lo) * i / (kSectionSamples - 1), cut.angle, 0.0}, 0, g);
        const double r = g.point[0] * c + g.point[1] * s;
        cut.points.emplace_back(right ? r : -r, g.point[2]);
      }
      cuts.push_back(std::move(cut));
    }
  }
  double x_min = 0, x_max = 0, z_min = std::numeric_limits<double>::infinity(), z_max = -z_min;
  for (const SectionCut& cut : cuts)
    for (const Eigen::Vector2d& p : cut.points) {
      x_min = std::min(x_min, p.x());
      x_max = std::max(x_max, p.x());
      z_min = std::min(z_min, p.y());
      z_max = std::max(z_max, p.y());
    }
  // The last whorl (the first cut, always in the data) and the one half a turn before it, left.
  const SectionCut& outer = cuts.front();
  const SectionCut* opposite = nullptr;
  for (const SectionCut& cut : cuts)
    if (!cut.right && cut.whorls_from_last == 0) opposite = &cut;
  auto extreme = [](const SectionCut& cut, int coordinate, bool largest) {
    auto less = [&](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
      return a[coordinate] < b[coordinate];
    };
    return largest ? *std::max_element(cut.points.begin(), cut.points.end(), less)
                   : *std::min_element(cut.points.begin(), cut.points.end(), less);
  };
  const Eigen::Vector2d inner_edge = extreme(outer, 0, false), outer_edge = extreme(outer, 0, true);
  const Eigen::Vector2d bottom = extreme(outer, 1, false), top = extreme(outer, 1, true);

  // Layout: the width of the last whorl above the drawing, its height right of it, the umbilicus, the scale
  // bar and the caption below it.
  constexpr double kWidth = 640, kLeft = 40, kRight = 120, kTop = 60, kBottom = 116, kTallest = 560;
  const double span_x = std::max(x_max - x_min, 1e-9), span_z = std::max(z_max - z_min, 1e-9);
  const double scale = std::min((kWidth - kLeft - kRight) / span_x, kTallest / span_z);
  const double height = std::ceil(kTop + scale * span_z + kBottom);
  const double x0 = kLeft + 0.5 * (kWidth - kLeft - kRight - scale * span_x);
  auto X = [&](double x) { return x0 + scale * (x - x_min); };
  auto Y = [&](double z) { return kTop + scale * (z_max - z); };
  const std::string u = " " + units;
  std::ostringstream s;
  s << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << Num(kWidth) << "\" height=\"" << Num(height)
    << "\" viewBox=\"0 0 " << Num(kWidth) << " " << Num(height)
    << "\" font-family=\"sans-serif\" font-size=\"12\">\n"
    << "<title>Shell section through the axis</title>\n<rect width=\"100%\" height=\"100%\" "
       "fill=\"white\"/>\n";
  // The axis (dash-dot), beyond the drawing at both ends.
  s << Line(X(0), Y(z_max) - 12, X(0), Y(z_min) + 12, "#000", 0.8,
            " class=\"axis\" stroke-dasharray=\"12 3 2 3\"");
  // The cuts, the inner (extrapolated) ones first so that the scanned ones are drawn over them.
  for (auto cut = cuts.rbegin(); cut != cuts.rend(); ++cut) {
    s << "<polyline class=\"section " << (cut->right ? "right" : "left")
      << (cut->scanned ? " scanned" : " extrapolated") << "\" points=\"";
    for (std::size_t i = 0; i < cut->points.size(); ++i)
      s << (i ? " " : "") << Num(X(cut->points[i].x())) << "," << Num(Y(cut->points[i].y()));
    s << "\" fill=\"none\" stroke=\""
      << (cut->scanned ? "#000\" stroke-width=\"1.8\"" : "#555\" stroke-width=\"1\" stroke-dasharray=\"5 3\"")
      << "><title>"
      << svg::Escape((cut->right ? "right" : "left") + std::string(", coiling angle ") +
                     Format(cut->angle, 5) + " rad, " + (cut->scanned ? "scanned" : "extrapolated"))
      << "</title></polyline>\n";
  }
  // Dimensions of the last whorl: thin extension lines from the section a little past the dimension line.
  const std::string extension = "#999";
  const double width_y = Y(z_max) - 22;
  s << Line(X(inner_edge.x()), Y(inner_edge.y()) - 3, X(inner_edge.x()), width_y - 5, extension, 0.6)
    << Line(X(outer_edge.x()), Y(outer_edge.y()) - 3, X(outer_edge.x()), width_y - 5, extension, 0.6)
    << Line(X(inner_edge.x()), width_y, X(outer_edge.x()), width_y, "#b2182b", 1.2,
            " class=\"dimension width\"")
    << Text(0.5 * (X(inner_edge.x()) + X(outer_edge.x())), width_y - 8,
            "last whorl width " + Format(last.width, 5) + u, "middle", " fill=\"#b2182b\"");
  const double height_x = X(x_max) + 22;
  s << Line(X(top.x()) + 3, Y(top.y()), height_x + 5, Y(top.y()), extension, 0.6)
    << Line(X(bottom.x()) + 3, Y(bottom.y()), height_x + 5, Y(bottom.y()), extension, 0.6)
    << Line(height_x, Y(top.y()), height_x, Y(bottom.y()), "#2166ac", 1.2, " class=\"dimension height\"")
    << "<text transform=\"translate(" << Num(height_x + 14) << "," << Num(0.5 * (Y(top.y()) + Y(bottom.y())))
    << ") rotate(-90)\" text-anchor=\"middle\" fill=\"#2166ac\">"
    << svg::Escape("last whorl height " + Format(last.height, 5) + u) << "</text>\n";
  // The umbilicus: between the inner edges of the last whorl and of the one half a turn before it.
  if (last.umbilical_width > 0 && opposite) {
    const Eigen::Vector2d left_edge = extreme(*opposite, 0, true);
    const double umbilicus_y = Y(z_min) + 24;
    s << Line(X(left_edge.x()), Y(left_edge.y()) + 3, X(left_edge.x()), umbilicus_y + 5, extension, 0.6,
              " stroke-dasharray=\"2 2\"")
      << Line(X(inner_edge.x()), Y(inner_edge.y()) + 3, X(inner_edge.x()), umbilicus_y + 5, extension, 0.6,
              " stroke-dasharray=\"2 2\"")
      << Line(X(left_edge.x()), umbilicus_y, X(inner_edge.x()), umbilicus_y, "#1b7837", 1.2,
              " class=\"dimension umbilicus\"")
      << Text(X(0), umbilicus_y + 16,
              "umbilicus " + Format(last.umbilical_width, 5) + u +
                  (opposite->scanned ? "" : " (one side extrapolated)"),
              "middle", " fill=\"#1b7837\"");
  }
  // Scale bar: a round length about a fifth of the drawing's width.
  const std::vector<double> ticks = svg::NiceTicks(0, span_x, 5);
  const double bar = ticks.size() > 1 ? ticks[1] - ticks[0] : span_x;
  const double bar_y = height - 40;
  s << "<rect class=\"scale-bar\" x=\"" << Num(kLeft) << "\" y=\"" << Num(bar_y - 6) << "\" width=\""
    << Num(scale * bar) << "\" height=\"6\" fill=\"#000\"/>\n"
    << Text(kLeft + scale * bar + 6, bar_y, Format(bar, 4) + u, "start", " class=\"scale-label\"")
    << Text(kWidth / 2, height - 12,
            "section through the axis at the last coiling angle; solid: scanned whorls, dashed: extrapolated",
            "middle", " class=\"caption\" font-size=\"11\"")
    << "</svg>\n";
  return s.str();
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
