// Automatic complexity of a part's free-form spline patches (fitting/part_complexity.h, docs/method.md
// section 18): knot insertion keeps the part exactly, renumbering every later parameter; the search grows a
// top the part file's net cannot hold until the fit reaches the noise.
#include "fitting/part_complexity.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "synthetic/synthetic_cases.h"

namespace s2m {
namespace {

// The largest distance from points sampled on faces `faces` of `before` to the part `after`.
double LargestDistance(const PartModel& before, const PartModel& after, const std::vector<int>& faces) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  double largest = 0.0;
  LocalGeometry g;
  for (int face : faces) {
    const SplinePatch& p = *before.definition().faces[static_cast<std::size_t>(face)].patch;
    for (int k = 0; k < 300; ++k) {
      const double u = p.u.lo() + uniform(rng) * (p.u.hi() - p.u.lo());
      const double v = p.v.lo() + uniform(rng) * (p.v.hi() - p.v.lo());
      before.Evaluate({u, v, static_cast<double>(face)}, 0, g);
      ParamT t{0.0, 0.0, 0.0};
      double distance = 0.0;
      bool boundary = false, ambiguous = false;
      after.ClosedFormFoot(VecS(g.point), t, distance, boundary, ambiguous);
      largest = std::max(largest, std::abs(distance));
    }
  }
  return largest;
}

// A plate with a second free-form patch after the top (its own block of displacements after the top's):
// refining the top renumbers the second patch's parameters, and both patches keep their shape.
TEST(PartComplexity, RefinePatchKeepsThePartAndRenumbersLaterParameters) {
  Eigen::MatrixXd bump(4, 5);
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 5; ++j) bump(i, j) = 0.6 * std::sin(1.1 * i + 0.3) * std::cos(0.8 * j - 0.2);
  PartDefinition d = FreeformPlate(50.0, 30.0, bump);
  // A second patch: the top lifted by 20 with its own displacements, u-major after the top's.
  PartFace second = d.faces[0];
  second.name = "lid";
  SplinePatch& lid = *second.patch;
  lid.first_displacement = static_cast<int>(d.parameters.size());
  for (std::size_t k = 0; k < lid.control_points.size(); ++k) {
    LinearExpression& z = lid.control_points[k][2];
    z.constant += 20.0;
    z.terms = {{lid.first_displacement + static_cast<int>(k), 1.0}};
    d.parameters.push_back(
        {"lid[" + std::to_string(k) + "]", 0.1 * std::cos(0.5 * static_cast<double>(k)), false});
  }
  d.faces.push_back(second);
  const PartModel before(d);
  const int lid_face = static_cast<int>(d.faces.size()) - 1;
  ASSERT_EQ(before.num_parameters(), 2 + 20 + 20);

  const PartDefinition refined_u = RefinePatch(d, before.parameters(), 0, 0, 0.37);
  const PartModel after_u(refined_u);
  EXPECT_EQ(after_u.num_parameters(), 2 + 25 + 20);  // a new row of 5 along u
  EXPECT_EQ(PatchControlPoints(refined_u), "top 5x5, lid 4x5");
  EXPECT_EQ(refined_u.parameters[2].name, "top[0,0]");
  EXPECT_EQ(refined_u.parameters[26].name, "top[4,4]");
  EXPECT_EQ(refined_u.parameters[27].name, "lid[0]");
  EXPECT_EQ(refined_u.faces[static_cast<std::size_t>(lid_face)].patch->first_displacement, 27);
  EXPECT_LT(LargestDistance(before, after_u, {0, lid_face}), 1e-9);

  // Then along v, on the lid: the top's block stays, the lid's grows.
  const PartDefinition refined_v =
      RefinePatch(refined_u, after_u.parameters(), static_cast<std::size_t>(lid_face), 1, 0.8);
  const PartModel after_v(refined_v);
  EXPECT_EQ(after_v.num_parameters(), 2 + 25 + 24);
  EXPECT_EQ(PatchControlPoints(refined_v), "top 5x5, lid 4x6");
  EXPECT_EQ(refined_v.parameters[27].name, "lid[0,0]");  // the refined block is named by (i, j)
  EXPECT_LT(LargestDistance(before, after_v, {0, lid_face}), 1e-9);

  EXPECT_THROW(RefinePatch(d, before.parameters(), 1, 0, 0.5), std::invalid_argument);  // a plane
  EXPECT_THROW(RefinePatch(d, before.parameters(), 0, 2, 0.5), std::invalid_argument);
  EXPECT_THROW(RefinePatch(d, before.parameters(), 0, 0, 1.5), std::invalid_argument);
}

// The file's top is a flat 4 x 4 net (one Bezier patch); the true top has a relief that needs 7 x 5 control
// points (clamped uniform: inner knots at 1/4, 1/2, 3/4 along u and 1/2 along v, which insertion at span
// middles reaches, so the search can end exactly in the truth's space). At the file's count the fit is not
// adequate; the automatic search adds control points until it is, and the relief comes out at a fraction of
// the fixed count's error.
TEST(PartComplexity, AutomaticSearchGrowsATopTheFileCannotHold) {
  const PartModel truth(ReliefPlate());
  const SyntheticViews views = ReliefPlateViews();

  JointFitOptions options;
  options.error_term = ErrorTerm::kSdm;
  ComplexityOptions complexity;
  complexity.noise = 0.02;  // the views' noise (the command uses its model-free estimate)
  complexity.noise_dof = 1e4;

  // The top's relief error: the largest height difference between the fitted and the true top over a grid
  // of (x, y), each relative to the centre (the plate's absolute height is the case's gauge).
  const auto relief_error = [&](const PartModel& fitted) {
    double largest = 0.0;
    // x = (s - 1/2) width with s the top's parameter mapped onto [0, 1] (refinement rescales the domain).
    const auto top = [](const PartModel& m, double x, double y) {
      const double w = m.parameters()[0], dpt = m.parameters()[1];
      const SplinePatch& p = *m.definition().faces[0].patch;
      LocalGeometry g;
      m.Evaluate({p.u.lo() + (x / w + 0.5) * (p.u.hi() - p.u.lo()),
                  p.v.lo() + (y / dpt + 0.5) * (p.v.hi() - p.v.lo()), 0.0},
                 0, g);
      return g.point.z();
    };
    const double centre_fit = top(fitted, 0, 0), centre_true = top(truth, 0, 0);
    for (double x = -22; x <= 22; x += 4)
      for (double y = -12; y <= 12; y += 4)
        largest =
            std::max(largest, std::abs((top(fitted, x, y) - centre_fit) - (top(truth, x, y) - centre_true)));
    return largest;
  };

  PartModel fixed(FreeformPlate(50.5, 30.5, Eigen::MatrixXd::Zero(4, 4)));
  RefinablePartFit fixed_fit(fixed, views.scans, views.model_T_scan_recorded, options, 4);
  const ComplexityChoice fixed_choice = FitFixedComplexity(fixed_fit, complexity);
  ASSERT_EQ(fixed_choice.steps.size(), 1u);
  EXPECT_FALSE(fixed_choice.steps[0].adequate.value_or(true));
  const double fixed_error = relief_error(fixed);

  PartModel searched(FreeformPlate(50.5, 30.5, Eigen::MatrixXd::Zero(4, 4)));
  RefinablePartFit search(searched, views.scans, views.model_T_scan_recorded, options, 12);
  const ComplexityChoice choice = ChooseComplexity(search, complexity);
  const ComplexityStep& chosen = choice.steps[choice.chosen];
  const double searched_error = relief_error(searched);
  for (const ComplexityStep& step : choice.steps)
    std::printf("[ part     ] %-10s RMS %.5f band %.5f %s\n", step.control_points.c_str(), step.rms,
                step.band_rms, step.adequate.value_or(false) ? "adequate" : "not adequate");
  std::printf("[ part     ] fixed 4x4: relief error %.4f mm; auto %s: %.4f mm (%s)\n", fixed_error,
              chosen.control_points.c_str(), searched_error, choice.stop_reason.c_str());
  EXPECT_TRUE(chosen.adequate.value_or(false)) << choice.stop_reason;
  EXPECT_EQ(searched.definition().parameters[0].name, "width");
  EXPECT_NEAR(searched.parameters()[0], 50.0, 0.05);
  EXPECT_NEAR(searched.parameters()[1], 30.0, 0.05);
  EXPECT_LT(searched_error, 0.25 * fixed_error);
}

}  // namespace
}  // namespace s2m
