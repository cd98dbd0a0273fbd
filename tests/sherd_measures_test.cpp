// Sherds (docs/archaeology.md section 9). The core: the preserved arc's sampling correction and its spread
// (eq. A14) over many draws, its axis sensitivity (A15) against moved points, the edges' levelness (A12-A13)
// telling a rim from a break. Through the command's own path (ComputeFit, `fit --model revolution`):
// synthetic rim sherds of the demo vase (synthetic/synthetic_cases.h MakeSherd: 10, 20 and 40 % of the
// circumference, a wandering lower break, points on the fracture faces, placed rim down in the world),
// seeded: a rim that is claimed is never the wrong end, an inadequate fit marks its uncertainties untrusted,
// the text carries the sherd and axis lines, and the rim diameter's uncertainty grows as the fragment
// shrinks. The calibration statistics over the seeds are printed, and asserted with S2M_SHERD_STRICT (they
// do not all hold yet: docs/archaeology.md section 9).

#include "fitting/sherd_measures.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <nlohmann/json.hpp>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "fitting/kinematic_surfaces.h"
#include "one_cloud_fit.h"
#include "pipeline/batch.h"
#include "pipeline/domain_measures.h"
#include "pipeline/fit_options.h"
#include "registration/scan.h"
#include "synthetic/synthetic_cases.h"

namespace s2m {
namespace {

using Covariance6 = Eigen::Matrix<double, 6, 6>;

// n points uniform in angle over [a0, a0 + L] on a cylinder of radius 50, heights uniform in [0, 20].
Eigen::Matrix3Xd ArcPoints(int n, double a0, double extent, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Eigen::Matrix3Xd p(3, n);
  for (int i = 0; i < n; ++i) {
    const double a = a0 + extent * unit(rng);
    p.col(i) << 50 * std::cos(a), 50 * std::sin(a), 20 * unit(rng);
  }
  return p;
}

TEST(SherdArc, CorrectedExtentIsUnbiasedWithTheStatedSpread) {
  std::mt19937_64 rng(7);
  const double extent = 0.3 * 2 * M_PI;
  const std::vector<int> view(200, 0);
  const std::vector<Covariance6> none(1, Covariance6::Zero());
  double sum = 0, sum2 = 0, stated = 0, central = 0;
  const int trials = 4000;
  for (int t = 0; t < trials; ++t) {
    const Eigen::Matrix3Xd p = ArcPoints(200, 5.5, extent, rng);  // across the angle 0 (wraps)
    const PreservedArc a = MeasureArc(p, view, none, -1, 21, 30);
    ASSERT_TRUE(std::isfinite(a.fraction));
    EXPECT_EQ(a.points, 200);
    EXPECT_EQ(a.axis_uncertainty, 0.0);
    sum += a.fraction - 0.3;
    sum2 += (a.fraction - 0.3) * (a.fraction - 0.3);
    stated += a.sampling_uncertainty / trials;
    central += a.central_fraction / trials;
  }
  // Eq. A14a: of 200 points uniform over the arc, the 11th and the 190th in order (ranks 0.05 x 199 and 0.95
  // x 199, rounded, plus one) lie at expected 11/201 and 190/201 of it; each scatters by about 0.005 of the
  // turn, their mean over the trials by about 1e-4.
  EXPECT_NEAR(central, 0.3 * (190 - 11) / 201.0, 5e-4);
  const double mean = sum / trials, sd = std::sqrt(sum2 / trials - mean * mean);
  std::printf("corrected arc: bias %.3g (standard error %.3g), spread %.4g, stated %.4g\n", mean,
              sd / std::sqrt(trials), sd, stated);
  EXPECT_LT(std::abs(mean), 4 * sd / std::sqrt(trials));
  EXPECT_NEAR(sd / stated, 1.0, 0.06);  // the spread's standard error over 4000 draws is about 1.1 %
  // Too few points in the band: no figure.
  EXPECT_TRUE(
      std::isnan(MeasureArc(ArcPoints(20, 0, 1, rng), std::vector<int>(20, 0), none, -1, 21, 30).fraction));
}

TEST(SherdArc, CentralFractionIsExactOnEvenlySpacedPointsAcrossTheWrap) {
  // 201 points 0.01 rad apart from 6.0 rad on, past the angle 0, in shuffled order: eq. A14a's ranks 10 and
  // 190 (0.05 and 0.95 of 200) lie 1.8 rad apart, whatever the order the points come in.
  std::vector<int> rank(201);
  std::iota(rank.begin(), rank.end(), 0);
  std::mt19937_64 rng(11);
  std::shuffle(rank.begin(), rank.end(), rng);
  Eigen::Matrix3Xd p(3, 201);
  for (int i = 0; i < 201; ++i) {
    const double a = 6.0 + 0.01 * rank[static_cast<std::size_t>(i)];
    p.col(i) << 50 * std::cos(a), 50 * std::sin(a), 10.0;
  }
  const PreservedArc a = MeasureArc(p, std::vector<int>(201, 0), {Covariance6::Zero()}, -1, 21, 30);
  EXPECT_NEAR(a.central_fraction, 1.8 / (2 * M_PI), 1e-12);
  EXPECT_NEAR(a.fraction, 2.0 * 202 / 200 / (2 * M_PI), 1e-12);  // eq. A14's (n + 1) / (n - 1) correction
}

TEST(SherdArc, AxisSensitivityMatchesMovedPoints) {
  // Eq. A15 against the arc of the points moved by a small motion x' = x + cbar + c x x (two views, each
  // holding one end of the arc).
  std::mt19937_64 rng(3);
  const Eigen::Matrix3Xd p = ArcPoints(300, 1.0, 1.2, rng);
  std::vector<int> view(300);
  for (int i = 0; i < 300; ++i)
    view[static_cast<std::size_t>(i)] = std::atan2(p(1, i), p(0, i)) < 1.6 ? 0 : 1;
  for (int view_moved = 0; view_moved < 2; ++view_moved)
    for (int c = 0; c < 6; ++c) {
      std::vector<Covariance6> covariance(2, Covariance6::Zero());
      covariance[static_cast<std::size_t>(view_moved)](c, c) = 1.0;
      const PreservedArc a = MeasureArc(p, view, covariance, -1, 21, 30);
      // Moved by h along component c: the change of the fraction over h is the gradient's component.
      const double h = 1e-6;
      Eigen::Matrix<double, 6, 1> m = Eigen::Matrix<double, 6, 1>::Zero();
      m[c] = h;
      Eigen::Matrix3Xd moved = p;
      for (int i = 0; i < 300; ++i)
        if (view[static_cast<std::size_t>(i)] == view_moved)
          moved.col(i) += m.tail<3>() + m.head<3>().cross(Eigen::Vector3d(p.col(i)));
      const std::vector<Covariance6> none(2, Covariance6::Zero());
      const double numeric = (MeasureArc(moved, view, none, -1, 21, 30).fraction -
                              MeasureArc(p, view, none, -1, 21, 30).fraction) /
                             h;
      EXPECT_NEAR(a.axis_uncertainty, std::abs(numeric), 1e-6 + 1e-4 * std::abs(numeric))
          << "view " << view_moved << " component " << c;
    }
}

TEST(SherdEdges, ALevelEdgeIsTheRim) {
  // A quarter of a cylinder, heights 0 to 30: the top level (a rim), the bottom wandering by 3 mm.
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 0.05);
  auto make = [&](bool top_level, bool bottom_level) {
    Eigen::Matrix3Xd p(3, 6000);
    for (Eigen::Index i = 0; i < p.cols();) {
      const double a = 0.5 * M_PI * unit(rng), z = 30 * unit(rng);
      const double wander = 1.5 + 1.5 * std::sin(7 * a + 1);
      if ((!bottom_level && z < wander) || (!top_level && z > 30 - wander)) continue;
      const double r = 50 + gauss(rng);
      p.col(i++) << r * std::cos(a), r * std::sin(a), z;
    }
    return p;
  };
  const std::vector<int> view(6000, 0);
  const std::vector<Covariance6> covariance(1, Covariance6::Identity() * 1e-8);
  const SherdMeasures rim_up = MeasureSherd(make(true, false), view, covariance, 0.05);
  EXPECT_EQ(rim_up.rim_side, 1) << rim_up.rim_reason;
  EXPECT_TRUE(rim_up.upper.level);
  EXPECT_FALSE(rim_up.lower.level);
  EXPECT_TRUE(rim_up.preserved_at_rim);
  EXPECT_NEAR(rim_up.preserved.fraction, 0.25, 3 * rim_up.preserved.uncertainty);
  EXPECT_NEAR(rim_up.covered_fraction, 0.25, 0.01);
  Eigen::Matrix3Xd flipped = make(true, false);
  flipped.row(2) *= -1;
  EXPECT_EQ(MeasureSherd(flipped, view, covariance, 0.05).rim_side, -1);
  const SherdMeasures both = MeasureSherd(make(true, true), view, covariance, 0.05);
  EXPECT_EQ(both.rim_side, 0);
  EXPECT_NE(both.rim_reason.find("both edges are level"), std::string::npos);
  const SherdMeasures body = MeasureSherd(make(false, false), view, covariance, 0.05);
  EXPECT_EQ(body.rim_side, 0);
  EXPECT_NE(body.rim_reason.find("neither edge"), std::string::npos);
  EXPECT_FALSE(body.preserved_at_rim);
  EXPECT_NEAR(body.preserved.fraction, 0.25, 3 * body.preserved.uncertainty);
  // A sparse body sherd (300 points: 15 in each of twenty bands, fewer than the 30 a band needs) is measured
  // in fewer, taller bands rather than not at all.
  const Eigen::Matrix3Xd sparse = make(false, false).leftCols(300);
  const SherdMeasures few = MeasureSherd(sparse, std::vector<int>(300, 0), covariance, 0.05);
  EXPECT_FALSE(few.preserved_at_rim);
  EXPECT_GE(few.preserved.points, 30);
  EXPECT_NEAR(few.preserved.fraction, 0.25, 3 * few.preserved.uncertainty);
  // Bad input: too few points, a view index without a covariance, invalid options.
  EXPECT_THROW(MeasureSherd(Eigen::Matrix3Xd::Zero(3, 5), std::vector<int>(5, 0), covariance, 0.05),
               std::invalid_argument);
  EXPECT_THROW(MeasureSherd(make(true, false), std::vector<int>(6000, 3), covariance, 0.05),
               std::invalid_argument);
  SherdMeasureOptions bad;
  bad.sectors = 1;
  EXPECT_THROW(MeasureSherd(make(true, false), view, covariance, 0.05, bad), std::invalid_argument);
}

TEST(SherdEdges, ALevelEdgeIsMissedAsOftenAsAskedAndAWanderingOneIsNot) {
  // Eq. A13a on point data rather than on its own model: a quarter of a cylinder of radius 50 with 1500
  // points uniform over heights 0 to 30 (noise-free, so the sector heights scatter by the sampling alone and
  // the model's exponential gaps are the whole story). Both edges are level; with a false-rejection rate of
  // 5 %, over 300 clouds (600 edges) about 30 edges are called not level (binomial sd 5.3).
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  SherdMeasureOptions options;
  options.level_false_rejection = 0.05;
  const std::vector<int> view(1500, 0);
  const std::vector<Covariance6> covariance(1, Covariance6::Identity() * 1e-8);
  int rejected = 0;
  const int clouds = 300;
  for (int c = 0; c < clouds; ++c) {
    Eigen::Matrix3Xd p(3, 1500);
    for (Eigen::Index i = 0; i < p.cols(); ++i) {
      const double a = 0.5 * M_PI * unit(rng);
      p.col(i) << 50 * std::cos(a), 50 * std::sin(a), 30 * unit(rng);
    }
    const SherdMeasures m = MeasureSherd(p, view, covariance, 0.0, options);
    rejected += !m.upper.level + !m.lower.level;
    EXPECT_GT(m.upper.limit, 0.0);
  }
  std::printf("level edges called not level: %d of %d (5 %% asked)\n", rejected, 2 * clouds);
  EXPECT_NEAR(rejected, 0.05 * 2 * clouds, 4 * std::sqrt(0.05 * 0.95 * 2 * clouds));
  // What the robust spread (A12) is built to ignore, and what it therefore cannot see: an edge level over
  // most of the arc but 1 mm lower in two of the eight sectors (a corner cut by a side break, or a break
  // level over most of its length, as the test sherds' breaks taken for rims were: docs/archaeology.md
  // section 9) reads level; lower in half of the sectors, it does not.
  auto dipped = [&](int sectors_dipped) {
    Eigen::Matrix3Xd p(3, 3000);
    for (Eigen::Index i = 0; i < p.cols();) {
      const double a = 0.5 * M_PI * unit(rng), z = 30 * unit(rng);
      const int sector = std::min(7, static_cast<int>(a / (0.5 * M_PI) * 8));
      if (sector < sectors_dipped && z > 29) continue;
      p.col(i++) << 50 * std::cos(a), 50 * std::sin(a), z;
    }
    return MeasureSherd(p, std::vector<int>(3000, 0), covariance, 0.05);
  };
  EXPECT_TRUE(dipped(2).upper.level);
  EXPECT_FALSE(dipped(4).upper.level);
}

TEST(SherdEdges, PointsOnTheGeneratrixContinuationBeyondItsEndsAreFound) {
  // A generatrix r = 40 + 0.01 z^2 over z in [0, 30] as a clamped cubic B-spline (a quadratic in u lies in
  // its space exactly, so the least-squares control points reproduce it and its second-order continuation
  // (eq. A12a) is the same quadratic): three spans, each 10 mm of height.
  const BSplineBasis basis = BSplineBasis::ClampedUniform(4, 6, 0.0, 1.0);
  auto radius = [](double z) { return 40 + 0.01 * z * z; };
  const int samples = 60;
  Eigen::MatrixXd collocation = Eigen::MatrixXd::Zero(samples, basis.num_control());
  Eigen::MatrixX2d target(samples, 2);
  BSplineBasis::Values v;
  for (int i = 0; i < samples; ++i) {
    const double u = i / (samples - 1.0);
    basis.Evaluate(u, 0, v);
    for (int k = 0; k < basis.order(); ++k)
      collocation(i, basis.ControlIndex(v.first, k)) = v.values[0][static_cast<std::size_t>(k)];
    target.row(i) << radius(30 * u), 30 * u;
  }
  const Eigen::Matrix2Xd profile = collocation.colPivHouseholderQr().solve(target).transpose();
  const KinematicSurface surface = KinematicSurface::Revolution(basis, profile);
  // The generatrix's derivatives the continuation is built from, at the top (u = 1, z = 30): dr/du = 30 x
  // 0.02 z, dz/du = 30, d2r/du2 = 900 x 0.02, d2z/du2 = 0.
  EXPECT_LT((surface.ProfilePoint(1.0, 1) - Eigen::Vector2d(18, 30)).norm(), 1e-9);
  EXPECT_LT((surface.ProfilePoint(1.0, 2) - Eigen::Vector2d(18, 0)).norm(), 1e-9);
  EXPECT_THROW(surface.ProfilePoint(1.0, 3), std::invalid_argument);
  auto at = [](double r, double z, double angle) {
    return Eigen::Vector3d(r * std::cos(angle), r * std::sin(angle), z);
  };
  // Columns: on the surface beyond the top by 5 mm and below the bottom by 8 mm (found); beyond the top by
  // 15 mm, past one span (not); a break's face across the wall 0.3 mm beyond the top, 2 mm in (not); on
  // the surface inside the ends (not: those are the surface's own, judged by their distance to it).
  Eigen::Matrix3Xd points(3, 5);
  points << at(radius(35), 35, 0.3), at(radius(-8), -8, 2.0), at(radius(45), 45, 1.0),
      at(radius(30.3) - 2, 30.3, 0.5), at(radius(15), 15, 0.0);
  const std::vector<bool> near = NearGeneratrixContinuation(surface, points, 0.05);
  EXPECT_EQ(near, (std::vector<bool>{true, true, false, false, false}));
  // With noise of 0.02 mm across the surface the points beyond the ends stay within a band of 4.7 sigma.
  std::mt19937_64 rng(11);
  std::normal_distribution<double> gauss(0.0, 0.02);
  std::uniform_real_distribution<double> beyond(0.0, 10.0), angle(0.0, 2 * M_PI);
  Eigen::Matrix3Xd noisy(3, 400);
  for (Eigen::Index i = 0; i < noisy.cols(); ++i) {
    const double z = i % 2 == 0 ? 30 + beyond(rng) : -beyond(rng);
    // Along the normal of the (r, z) curve: (1, -dr/dz) normalized.
    const Eigen::Vector2d normal = Eigen::Vector2d(1.0, -0.02 * z).normalized();
    const double e = gauss(rng);
    noisy.col(i) = at(radius(z) + e * normal.x(), z + e * normal.y(), angle(rng));
  }
  const std::vector<bool> found = NearGeneratrixContinuation(surface, noisy, 4.6851 * 0.02);
  const auto count = std::count(found.begin(), found.end(), true);
  EXPECT_GE(count, 398);  // a normal sample beyond 4.6851 sigma: 3 in a million
  // Bad input.
  EXPECT_THROW(NearGeneratrixContinuation(surface, points, 0.0), std::invalid_argument);
  EXPECT_THROW(NearGeneratrixContinuation(KinematicSurface::Helical(basis, profile, 1.0, 2.0), points, 0.05),
               std::invalid_argument);
}

// ---- through the command's path ----

struct SherdFitError {
  bool adequate = false;     // the fit's own verdict (docs/method.md section 17)
  bool rim_up = false;       // the rim found and drawn up
  bool rim_wrong = false;    // a rim claimed at the wrong end
  bool rim_claimed = false;  // a rim claimed (up_from "rim"), at either end
  double tilt_z = 0;         // the axis' direction error over its uncertainty (largest of two components)
  double offset_z = 0;       // the axis' offset at the data's middle height over its uncertainty (largest)
  double rim_z = 0;          // rim diameter error / u
  double fraction_z = 0;     // preserved fraction error / u
  double fraction = 0;       // the preserved fraction (NaN when not given)
  double fraction_u = 0;     // u of the preserved fraction
  double rim_u = 0;
};

// A number of the document, NaN where it is null (an uncertainty the fit could not give).
double Number(const nlohmann::json& j) {
  return j.is_number() ? j.get<double>() : std::nan("");
}

// Fits the sherd through ComputeFit and compares with the truth. The axis' errors are taken in the fitted
// model frame, against the pose's covariance there (docs/archaeology.md eq. A17).
SherdFitError FitSherd(const SherdSpec& spec, bool print) {
  const SherdTruth truth = MakeSherd(spec);
  const KinematicCloud& c = truth.cloud;
  const pipeline::FitOutcome outcome =
      pipeline::ComputeFit(test::OneCloudFitOptions(c.points, "sherd", "revolution"));
  const nlohmann::json& doc = outcome.document;
  EXPECT_TRUE(doc.contains("vessel")) << doc.dump().substr(0, 400);
  SherdFitError e;
  if (!doc.contains("vessel") || !doc["vessel"].contains("sherd")) return e;
  const nlohmann::json& v = doc["vessel"];
  const nlohmann::json& s = v["sherd"];
  if (std::getenv("S2M_SHERD_DEBUG"))
    std::printf("%s\n%s\n%s\n", s.dump().c_str(), doc["start"].dump().c_str(),
                doc["adequacy"].dump().c_str());
  auto vec = [](const nlohmann::json& j) {
    return Eigen::Vector3d(j[0].get<double>(), j[1].get<double>(), j[2].get<double>());
  };
  // The text says how the sherd was set up and what is preserved, and gives the axis' uncertainty.
  EXPECT_NE(outcome.text.find("  sherd             "), std::string::npos);
  EXPECT_NE(outcome.text.find("  axis uncertainty  tilt "), std::string::npos);
  // Under kCalibratedSherdFraction of the circumference the uncertainties are said to be lower bounds, in
  // the document and in a note; above it they are not.
  const double preserved = Number(s["preserved_fraction"]);
  if (std::isfinite(preserved)) {
    const bool small = preserved < pipeline::kCalibratedSherdFraction;
    EXPECT_EQ(s["uncertainties_calibrated"], !small) << preserved;
    bool noted = false;
    for (const std::string& note : outcome.notes) noted |= note.find("lower bounds") != std::string::npos;
    EXPECT_EQ(noted, small) << preserved;
  }
  e.adequate = doc["adequacy"]["adequate"] == true;
  e.fraction = preserved;
  e.rim_claimed = s["up_from"] == "rim";
  e.rim_up = spec.rim && e.rim_claimed && vec(v["up"]).dot(c.axis_direction) > 0;
  e.rim_wrong = spec.rim && e.rim_claimed && !e.rim_up;
  if (!e.rim_up && spec.rim)
    std::printf("  seed %2llu: rim not found: %s, %s\n", static_cast<unsigned long long>(spec.seed),
                s["up_reason"].get<std::string>().c_str(), s["edges"].dump().c_str());
  if (e.rim_claimed && !spec.rim)
    std::printf("  seed %2llu: a rim claimed on a body sherd: %s, %s\n",
                static_cast<unsigned long long>(spec.seed), s["up_reason"].get<std::string>().c_str(),
                s["edges"].dump().c_str());
  if (!e.adequate) {
    // Its uncertainties are marked untrustworthy (some may be null): not compared.
    EXPECT_EQ(v["uncertainty_trusted"], false);
    if (print)
      std::printf("  seed %2llu: NOT adequate (%s)\n", static_cast<unsigned long long>(spec.seed),
                  doc["adequacy"]["suggestions"].dump().substr(0, 200).c_str());
    return e;
  }
  // Axis: the truth in the frame of the fitted axis (z along the fitted direction, origin the fitted point).
  const Eigen::Vector3d point = vec(doc["axis"]["point"]), direction = vec(doc["axis"]["direction"]);
  const nlohmann::json& au = doc["axis"]["uncertainty"];
  const Eigen::Matrix3d R =
      Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), direction).toRotationMatrix();
  Eigen::Vector3d d = R.transpose() * c.axis_direction;
  if (d.z() < 0) d = -d;
  const Eigen::Vector3d a = R.transpose() * (c.axis_point - point);
  const double z0 = Number(au["at_height"]);
  const Eigen::Vector3d at = a + d * (z0 - a.z()) / d.z();
  // The fitted frame's x and y about its z are not the fit's model frame's; the uncertainty is given as a
  // 2x2 covariance in the plane across the axis (world-fixed basis of the fitted frame as written).
  const Eigen::Vector2d tilt = d.head<2>() / d.z(), offset = at.head<2>();
  Eigen::Matrix2d tilt_cov, offset_cov;
  for (int i = 0; i < 2; ++i)
    for (int k = 0; k < 2; ++k) {
      tilt_cov(i, k) =
          Number(au["tilt_covariance"][static_cast<std::size_t>(i)][static_cast<std::size_t>(k)]);
      offset_cov(i, k) =
          Number(au["offset_covariance"][static_cast<std::size_t>(i)][static_cast<std::size_t>(k)]);
    }
  // In the basis R's x and y: the document's basis is `au["basis"]` (two world vectors across the axis).
  const Eigen::Vector3d bx = vec(au["basis"][0]), by = vec(au["basis"][1]);
  Eigen::Matrix2d to_doc;
  to_doc << bx.dot(R.col(0)), bx.dot(R.col(1)), by.dot(R.col(0)), by.dot(R.col(1));
  const Eigen::Vector2d tilt_doc = to_doc * tilt, offset_doc = to_doc * offset;
  auto larger = [](double x, double y) {
    return std::isnan(x) || std::isnan(y) ? std::nan("") : std::max(x, y);
  };
  for (int i = 0; i < 2; ++i) {
    e.tilt_z = larger(e.tilt_z, std::abs(tilt_doc[i]) / std::sqrt(tilt_cov(i, i)));
    e.offset_z = larger(e.offset_z, std::abs(offset_doc[i]) / std::sqrt(offset_cov(i, i)));
  }
  // The rim diameter is the fitted surface's at the top of the data (docs/archaeology.md section 9): its
  // truth is the vase's diameter at that height.
  const Eigen::Vector3d base = vec(v["base_centre"]), up = vec(v["up"]);
  const RigidMotion model_T_world = c.world_T_model.inverse();
  const auto& surface = dynamic_cast<const KinematicSurface&>(*c.truth);
  const double rim_height = std::min((model_T_world * Eigen::Vector3d(base + Number(v["height"]) * up)).z(),
                                     surface.ProfilePoint(surface.basis().hi()).y() - 1e-9);
  const double true_rim = 2 * surface.RadiusAtHeight(rim_height);
  e.rim_u = Number(v["rim_diameter_uncertainty"]);
  e.rim_z = (Number(v["rim_diameter"]) - true_rim) / e.rim_u;
  // The preserved fraction's truth: the arc of the surface in the same band of heights (heights above the
  // base along the fitted up, mapped to the truth's profile parameter).
  const double lo = Number(s["band_height_lo"]), hi = Number(s["band_height_hi"]);
  const double z_lo = (model_T_world * Eigen::Vector3d(base + lo * up)).z(),
               z_hi = (model_T_world * Eigen::Vector3d(base + hi * up)).z();
  double arc_lo = 1e9, arc_hi = -1e9;
  for (int k = 0; k <= 2000; ++k) {
    const double u = truth.profile_lo + (truth.profile_hi - truth.profile_lo) * k / 2000.0;
    const double z = surface.ProfilePoint(u).y();
    if (z < std::min(z_lo, z_hi) || z > std::max(z_lo, z_hi)) continue;
    if (const auto arc = truth.arc(u)) {
      arc_lo = std::min(arc_lo, arc->first);
      arc_hi = std::max(arc_hi, arc->second);
    }
  }
  const double true_fraction = (arc_hi - arc_lo) / (2 * M_PI);
  e.fraction_u = Number(s["preserved_fraction_uncertainty"]);
  e.fraction_z = (Number(s["preserved_fraction"]) - true_fraction) / e.fraction_u;
  if (print)
    std::printf(
        "  seed %2llu: %s; rim %s; tilt %.2f u, offset %.2f u; rim diameter %.3f +- %.3f (truth %.3f at the "
        "data's top, %.3f at the vase's rim); preserved "
        "%.4f +- %.4f (axis %.4f, sampling %.4f; truth %.4f) over %.2f-%.2f mm\n",
        static_cast<unsigned long long>(spec.seed), e.adequate ? "adequate" : "NOT adequate",
        e.rim_up ? "up" : "NOT found", e.tilt_z, e.offset_z, Number(v["rim_diameter"]), e.rim_u, true_rim,
        truth.rim_diameter, Number(s["preserved_fraction"]), e.fraction_u,
        Number(s["preserved_fraction_axis_uncertainty"]),
        Number(s["preserved_fraction_sampling_uncertainty"]), true_fraction, lo, hi);
  return e;
}

// Seeds per case: S2M_SHERD_SEEDS (default 10, about 30 s per size; the statistic is over 50:
// `S2M_SHERD_SEEDS=50 S2M_SHERD_STRICT=1 build/tests/sherd_measures_test --gtest_filter=SherdFit*`).
// The first seed: S2M_SHERD_FIRST_SEED (default 1000), to look again at one seed a run printed.
std::uint64_t FirstSeed() {
  const char* env = std::getenv("S2M_SHERD_FIRST_SEED");
  return env ? std::strtoull(env, nullptr, 10) : 1000;
}
int Seeds() {
  const char* env = std::getenv("S2M_SHERD_SEEDS");
  return env ? std::max(1, std::atoi(env)) : 10;
}

// Over the seeds of one case. The fit judges itself (docs/method.md section 17): a fit it calls inadequate
// marks its uncertainties untrustworthy (checked in FitSherd), and the statistics are over the others.
// Always asserted: a rim that is claimed is the true rim (a sherd drawn upside down as if sure would be a
// confident wrong answer). With S2M_SHERD_STRICT the calibration the issue asks is asserted too: the rim
// found in every adequate fit, every fit adequate, and the standardized errors of the axis, the rim diameter
// and the preserved fraction as standard uncertainties should be (at most 2 in 50 beyond 3, a root mean
// square between 0.6 and 1.4); on rim sherds the standardized errors' criteria hold at 10, 20 and 40 %, the
// first two do not (docs/archaeology.md section 9 gives the measured figures). A body sherd has no rim: any
// rim it claims is a level break taken for one, counted and printed (not yet asserted: it happens, section 9
// says how often).
struct CaseSummary {
  double mean_fraction_u = 0;  // relative: u(f) / f
  double mean_rim_u = 0;       // over the fits that give one
};
CaseSummary CheckSherdCase(SherdSpec spec, const char* name) {
  const int seeds = Seeds();
  const bool strict = std::getenv("S2M_SHERD_STRICT") != nullptr;
  std::printf("%s (%.0f %% of the circumference, noise %.3g mm, %d seeds):\n", name, 100 * spec.arc_fraction,
              spec.noise, seeds);
  std::vector<double> rim, fraction;
  int adequate = 0, rim_found = 0, rim_wrong = 0, beyond = 0, axis_beyond = 0, rim_u_count = 0;
  int rim_compared = 0, rim_claimed = 0;
  CaseSummary summary;
  for (int k = 0; k < seeds; ++k) {
    spec.seed = FirstSeed() + static_cast<std::uint64_t>(k);
    const SherdFitError e = FitSherd(spec, k < 3 || std::getenv("S2M_SHERD_DEBUG") != nullptr);
    rim_wrong += e.rim_wrong;
    rim_claimed += e.rim_claimed;
    if (!e.adequate) continue;
    ++adequate;
    rim_found += e.rim_up;
    // The rim diameter is a rim's only where the rim was found; an uncertainty the fit could not give (NaN:
    // the profile runs across the axis at its end) counts as beyond.
    if (e.rim_up && std::isfinite(e.rim_z)) rim.push_back(e.rim_z);
    rim_compared += e.rim_up;
    fraction.push_back(e.fraction_z);
    const int beyond_here = (e.rim_up && !(std::abs(e.rim_z) <= 3)) + !(std::abs(e.fraction_z) <= 3);
    if (beyond_here > 0)
      std::printf("  seed %llu: beyond 3 u: rim diameter %.2f u, preserved fraction %.2f u (%.4f +- %.4f)\n",
                  static_cast<unsigned long long>(spec.seed), e.rim_z, e.fraction_z, e.fraction,
                  e.fraction_u);
    beyond += beyond_here;
    axis_beyond += !(e.tilt_z <= 3) + !(e.offset_z <= 3);
    summary.mean_fraction_u += e.fraction_u / e.fraction;
    if (e.rim_up && std::isfinite(e.rim_u)) {
      summary.mean_rim_u += e.rim_u;
      ++rim_u_count;
    }
  }
  summary.mean_fraction_u /= std::max(1, adequate);
  summary.mean_rim_u /= std::max(1, rim_u_count);
  auto rms = [](const std::vector<double>& v) {
    double s = 0;
    for (const double x : v) s += x * x;
    return std::sqrt(s / static_cast<double>(std::max<std::size_t>(1, v.size())));
  };
  std::printf(
      "  adequate %d of %d; of those: rim found and up %d; standardized errors RMS: rim diameter %.2f (%zu "
      "of "
      "%d with an uncertainty), preserved fraction %.2f; beyond 3 u: %d (diameter and fraction), %d (axis "
      "components); mean u: relative of the fraction %.4f, rim diameter %.3f mm\n",
      adequate, seeds, rim_found, rms(rim), rim.size(), rim_compared, rms(fraction), beyond, axis_beyond,
      summary.mean_fraction_u, summary.mean_rim_u);
  if (spec.rim) {
    EXPECT_EQ(rim_wrong, 0);
  } else {
    std::printf("  a rim claimed (a level break taken for one) in %d of %d fits\n", rim_claimed, seeds);
  }
  EXPECT_GT(adequate, 0);
  // The count criterion (at most 2 in 50 beyond 3 u) holds for the axis of every sherd measured and
  // for a rim sherd's rim diameter and preserved fraction (docs/archaeology.md section 9): asserted always.
  const int allowed = std::max(1, 2 * seeds / 50);
  EXPECT_LE(axis_beyond, 2 * allowed);  // two components each of tilt and offset
  if (spec.rim) {
    EXPECT_LE(beyond, allowed);
  }
  if (strict) {
    EXPECT_EQ(adequate, seeds);
    if (spec.rim) {
      EXPECT_EQ(rim_found, adequate);
    }
    EXPECT_LE(beyond, allowed);
    EXPECT_GT(rms(rim), 0.6);
    EXPECT_LT(rms(rim), 1.4);
    EXPECT_GT(rms(fraction), 0.6);
    EXPECT_LT(rms(fraction), 1.4);
  }
  return summary;
}

// The test sherds: 3000 points on the surface with 0.05 mm noise (S2M_SHERD_NOISE: another level, in mm;
// the issue asks 0.02-0.1), the breaks' faces scanned; a rim sherd placed rim down in the world, a body
// sherd as cut.
SherdSpec TestSherd(bool rim) {
  SherdSpec spec;
  spec.rim = rim;
  spec.fracture_faces = true;
  spec.upside_down = rim;
  spec.count = 3000;
  const char* noise = std::getenv("S2M_SHERD_NOISE");
  spec.noise = noise ? std::atof(noise) : 0.05;
  return spec;
}

TEST(SherdFit, RimSherdsWithBreaksFoundUpsideDown) {
  SherdSpec spec = TestSherd(true);
  std::vector<CaseSummary> by_size;
  for (const double fraction : {0.4, 0.2, 0.1}) {
    spec.arc_fraction = fraction;
    by_size.push_back(CheckSherdCase(spec, "rim sherd with breaks"));
  }
  // The smaller the fragment, the less its points say about the axis: the rim diameter's uncertainty grows
  // (measured over 50 seeds: 0.027, 0.094, 0.38 mm). The preserved fraction's relative uncertainty is mostly
  // the sampling of the breaks in the band below the rim (eq. A14), which holds about as many points at every
  // size: it stays near 2 % (docs/archaeology.md section 9), and is not compared.
  EXPECT_LT(by_size[0].mean_rim_u, by_size[1].mean_rim_u);
  EXPECT_LT(by_size[1].mean_rim_u, by_size[2].mean_rim_u);
}

// Body sherds (between about 30 and 110 mm of the vase's height, both breaks wandering, their faces scanned):
// the axis and the preserved fraction (the widest of ten bands) against the truth, as for the rim sherds.
TEST(SherdFit, BodySherdsWithBreaks) {
  SherdSpec spec = TestSherd(false);
  for (const double fraction : {0.4, 0.2, 0.1}) {
    spec.arc_fraction = fraction;
    CheckSherdCase(spec, "body sherd with breaks");
  }
}

// Rim sherds smaller than any whose uncertainties were measured (5 and 7 % of the circumference, about 0.045
// and 0.065 preserved at the rim): no output presents its uncertainties as calibrated. Either the fit judges
// itself not adequate (its uncertainties marked untrustworthy, checked in FitSherd: on these seeds the axis
// is lost, the short arc's breaks outweighing its curvature) or its preserved fraction is under
// kCalibratedSherdFraction and the flag and the note say they are lower bounds (also checked in FitSherd).
TEST(SherdFit, UnderTheMeasuredSizesNoUncertaintyIsPresentedAsCalibrated) {
  SherdSpec spec = TestSherd(true);
  spec.seed = 1000;
  for (const double fraction : {0.05, 0.07}) {
    spec.arc_fraction = fraction;
    const SherdFitError e = FitSherd(spec, true);
    EXPECT_TRUE(!e.adequate || e.fraction < pipeline::kCalibratedSherdFraction) << fraction;
    EXPECT_FALSE(e.rim_wrong) << fraction;
  }
}

}  // namespace
}  // namespace s2m
