#include "bench/fitting_method_cases.h"

#include <cmath>
#include <cstdio>

#include "acquisition/glyph_outline.h"
#include "fitting/bspline_models.h"
#include "fitting/initial_models.h"

namespace s2m::bench {

std::vector<FittingCase> FittingCases(const std::filesystem::path& glyphs, bool with_surface) {
  std::vector<FittingCase> cases;
  Eigen::MatrixXd circle(2, 40);
  for (int i = 0; i < 40; ++i) {
    const double a = 2 * M_PI * std::pow((i + 0.5) / 40, 1.5);
    circle.col(i) << std::cos(a), std::sin(a);
  }
  cases.push_back({"circle (40 sparse non-uniform points, 8 control points)", circle,
                   [] {
                     Eigen::MatrixXd p(2, 8);
                     for (int i = 0; i < 8; ++i)
                       p.col(i) << 0.2 + 0.6 * std::cos(i * M_PI / 4), 0.6 * std::sin(i * M_PI / 4);
                     return std::make_unique<BSplineCurve>(UnitSpacedPeriodic(4, 8), p);
                   },
                   0.0, true});
  Eigen::MatrixXd square(2, 100);
  for (int i = 0, k = 0; i < 25; ++i) {
    const double s = -1 + 2.0 * i / 25;
    square.col(k++) << s, -1;
    square.col(k++) << 1, s;
    square.col(k++) << -s, 1;
    square.col(k++) << -1, -s;
  }
  cases.push_back({"square (100 points, 12 control points, one-sided start)", square,
                   [] {
                     Eigen::MatrixXd p(2, 12);
                     for (int i = 0; i < 12; ++i)
                       p.col(i) << 0.4 + 0.3 * std::cos(i * M_PI / 6), 0.3 + 0.3 * std::sin(i * M_PI / 6);
                     return std::make_unique<BSplineCurve>(UnitSpacedPeriodic(4, 12), p);
                   },
                   0.001, true});
  if (std::filesystem::is_directory(glyphs)) {
    for (const char* g : {"S_", "g"}) {
      const auto contours = ReadGlifContours(glyphs / (std::string(g) + ".glif"));
      const Eigen::Matrix2Xd c = contours.front();
      const int n = static_cast<int>(c.cols() / 8);
      cases.push_back(
          {std::string("glyph '") + g[0] + "' outer contour (" + std::to_string(c.cols()) + " samples, " +
               std::to_string(n) + " control points)",
           c, [c, n] { return std::make_unique<BSplineCurve>(InitialCurveFromQuadtree(c, n, 4, true)); },
           1e-4, true});
    }
  } else {
    std::fprintf(stderr, "fitting methods: %s absent, glyph cases skipped\n", glyphs.c_str());
  }
  if (with_surface) {
    // z = 0.3 sin(2x) cos(3y) on [-1, 1]^2 (a 20 x 20 grid), 6 x 6 control points from the flat start the
    // projection gives.
    Eigen::MatrixXd bumps(3, 400);
    for (int i = 0, k = 0; i < 20; ++i)
      for (int j = 0; j < 20; ++j, ++k) {
        const double x = -1 + 2.0 * i / 19, y = -1 + 2.0 * j / 19;
        bumps.col(k) << x, y, 0.3 * std::sin(2 * x) * std::cos(3 * y);
      }
    cases.push_back({"bumpy surface (400 points, 6x6 control points, flat start)", bumps,
                     [bumps] {
                       Eigen::Matrix3Xd flat = bumps;
                       flat.row(2).setZero();
                       return std::make_unique<BSplineSurface>(
                           InitialSurfaceByProjection(flat, 6, 6, 4, SurfaceProjection::kPlane));
                     },
                     1e-5, false});
  }
  return cases;
}

namespace {

// One error term on one case for the whole budget; empty when the fit fails (said on stderr).
std::vector<IterationRecord> History(const FittingCase& c, ErrorTerm term, int budget) {
  std::unique_ptr<ParametricModel> model = c.start();
  GeometricFitOptions o;
  o.error_term = term;
  o.fairness.bending = c.bending;
  o.optimizer.max_iterations = budget;
  o.optimizer.objective_tolerance = 0.0;  // run the full budget: we read the history
  try {
    return FitModel(*model, c.points, o).history;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s / %s: %s\n", c.name.c_str(), ToString(term), e.what());
    return {};
  }
}

}  // namespace

int IterationsToRms(const FittingCase& c, ErrorTerm term, int budget, double target_rms) {
  for (const IterationRecord& r : History(c, term, budget))
    if (r.rms <= target_rms) return r.iteration;
  return -1;
}

std::vector<MethodRow> RunFittingMethods(const FittingCase& c, int budget) {
  const ErrorTerm terms[] = {ErrorTerm::kPdm, ErrorTerm::kTdm,  ErrorTerm::kSdm,
                             ErrorTerm::kCdm, ErrorTerm::kGtdm, ErrorTerm::kGn};
  std::vector<std::vector<IterationRecord>> histories;
  double best = INFINITY;
  for (ErrorTerm t : terms) {
    histories.push_back(History(c, t, budget));
    for (const IterationRecord& r : histories.back()) best = std::min(best, r.rms);
  }
  std::vector<MethodRow> rows;
  for (std::size_t k = 0; k < histories.size(); ++k) {
    const auto& h = histories[k];
    MethodRow row;
    row.case_name = c.name;
    row.method = terms[k];
    row.target_rms = 1.05 * best;
    row.lowest_rms = INFINITY;
    row.iterations_run = static_cast<int>(h.size());
    for (const IterationRecord& r : h) {
      row.rms.push_back(r.rms);
      row.lowest_rms = std::min(row.lowest_rms, r.rms);
      if (row.iterations_to_target < 0 && r.rms <= row.target_rms) {
        row.iterations_to_target = r.iteration;
        row.seconds_to_target = r.seconds;
      }
    }
    row.seconds_per_iteration = h.empty() ? 0.0 : h.back().seconds / static_cast<double>(h.size());
    rows.push_back(row);
  }
  return rows;
}

int IterationsTo(const MethodRow& row, double target_rms) {
  for (std::size_t i = 0; i < row.rms.size(); ++i)
    if (row.rms[i] <= target_rms) return static_cast<int>(i) + 1;
  return -1;
}

}  // namespace s2m::bench
