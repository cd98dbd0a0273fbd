// Robust primitive fits (primitive_fit.h, robust_loss.h): a sphere and a cylinder scanned with 30 % gross
// outliers (uniform in the bounding box) and 5 % points of the plane the part stands on. With Tukey's or
// Cauchy's loss the radius error must lie within 3 reported standard uncertainties (a 3-sigma bound fails
// about 0.3 % of the time for a correct uncertainty: at least 95 of 100 seeds), while the plain least-squares
// radius is biased far outside them (beyond 3 of the robust fit's standard uncertainties for at least 95
// seeds).

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "fitting/primitive_fit.h"
#include "fitting/robust_loss.h"

namespace s2m {
namespace {

constexpr int kSeeds = 100;
constexpr double kNoise = 0.01;

// Inliers, then 30 % gross outliers uniform in the inliers' bounding box, then 5 % points on a plane through
// `plane_point` with normal `plane_normal` (uniform in a square of half-width `plane_half_width`).
Eigen::Matrix3Xd Contaminate(const Eigen::Matrix3Xd& inliers, int total, const Eigen::Vector3d& plane_point,
                             const Eigen::Vector3d& plane_normal, double plane_half_width,
                             std::mt19937_64& rng) {
  const int outliers = static_cast<int>(0.30 * total);
  const int plane_points = static_cast<int>(0.05 * total);
  Eigen::Matrix3Xd p(3, inliers.cols() + outliers + plane_points);
  p.leftCols(inliers.cols()) = inliers;
  const Eigen::Vector3d low = inliers.rowwise().minCoeff(), high = inliers.rowwise().maxCoeff();
  std::uniform_real_distribution<double> unit(0.0, 1.0), square(-plane_half_width, plane_half_width);
  for (int i = 0; i < outliers; ++i) {
    const Eigen::Vector3d u(unit(rng), unit(rng), unit(rng));
    p.col(inliers.cols() + i) = low + u.cwiseProduct(high - low);
  }
  const Eigen::Matrix3d frame = FrameWithAxis(plane_normal);
  for (int i = 0; i < plane_points; ++i)
    p.col(inliers.cols() + outliers + i) =
        plane_point + square(rng) * frame.col(0) + square(rng) * frame.col(1);
  return p;
}

// A sphere of radius 1 at (0.3, -0.2, 1), standing on the plane z = 0.
Eigen::Matrix3Xd ContaminatedSphere(int total, std::mt19937_64& rng, Sphere& truth) {
  truth = {Eigen::Vector3d(0.3, -0.2, 1.0), 1.0};
  const int n = total - static_cast<int>(0.30 * total) - static_cast<int>(0.05 * total);
  std::normal_distribution<double> gauss(0.0, 1.0), noise(0.0, kNoise);
  Eigen::Matrix3Xd inliers(3, n);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d u = Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
    inliers.col(i) = truth.center + (truth.radius + noise(rng)) * u;
  }
  return Contaminate(inliers, total, Eigen::Vector3d(0.3, -0.2, 0.0), Eigen::Vector3d::UnitZ(), 2.0, rng);
}

// A cylinder of radius 0.5 and length 3 along x, lying on the plane z = 0 and scanned from above (its upper
// half). The outliers of its bounding box then lie mostly inside it, which pulls least squares inwards.
Eigen::Matrix3Xd ContaminatedCylinder(int total, std::mt19937_64& rng, Cylinder& truth) {
  truth = {Eigen::Vector3d(0.0, 0.0, 0.5), Eigen::Vector3d::UnitX(), 0.5};
  const int n = total - static_cast<int>(0.30 * total) - static_cast<int>(0.05 * total);
  std::uniform_real_distribution<double> along(-1.5, 1.5), angle(0.0, M_PI);
  std::normal_distribution<double> noise(0.0, kNoise);
  Eigen::Matrix3Xd inliers(3, n);
  for (int i = 0; i < n; ++i) {
    const double a = angle(rng), r = truth.radius + noise(rng);
    inliers.col(i) = truth.axis_point + Eigen::Vector3d(along(rng), r * std::cos(a), r * std::sin(a));
  }
  return Contaminate(inliers, total, Eigen::Vector3d(0.0, 0.0, 0.0), Eigen::Vector3d::UnitZ(), 2.0, rng);
}

template <class Shape>
double RadiusUncertainty(const PrimitiveFit<Shape>& fit) {
  for (const ParameterUncertainty& u : fit.uncertainties)
    if (u.name == "radius") return u.standard_uncertainty;
  ADD_FAILURE() << "no radius uncertainty";
  return 0.0;
}

struct Tally {
  int robust_within = 0;     // robust radius error within 3 reported standard uncertainties
  int robust_rejecting = 0;  // robust fits that rejected (weight < 0.5) at least 20 % of the points
  int plain_outside = 0;     // least-squares radius error beyond 3 of the robust fit's standard uncertainties
  double worst_robust = 0.0;   // largest |error| / u of the robust fits
  double least_plain = 1e300;  // smallest |error| / u (the robust fit's u) of the least-squares fits
};

template <class Shape, class Make, class Fit>
Tally RunSeeds(const std::string& loss, int total, Make make, Fit fit_fn) {
  Tally t;
  PrimitiveFitOptions robust;
  robust.optimizer.loss = ParseRobustLoss(loss);
  robust.record_history = false;
  PrimitiveFitOptions plain;
  plain.record_history = false;
  for (int seed = 0; seed < kSeeds; ++seed) {
    std::mt19937_64 rng(static_cast<std::uint64_t>(1000 + seed));
    Shape truth;
    const Eigen::Matrix3Xd points = make(total, rng, truth);
    const PrimitiveFit<Shape> r = fit_fn(points, robust);
    const double robust_ratio = std::abs(r.shape.radius - truth.radius) / RadiusUncertainty(r);
    if (robust_ratio <= 3.0) ++t.robust_within;
    t.worst_robust = std::max(t.worst_robust, robust_ratio);
    EXPECT_GT(r.loss_scale, 0.0);
    // Most gross outliers (some fall near the surface by chance) and the plane's points far from the part.
    if (r.rejected >= static_cast<Eigen::Index>(0.2 * total)) ++t.robust_rejecting;

    const PrimitiveFit<Shape> p = fit_fn(points, plain);
    // Biased far outside the robust fit's uncertainty: the error against the robust fit's u (least squares's
    // own u, inflated by the outliers' residuals, says nothing about its bias).
    const double plain_ratio = std::abs(p.shape.radius - truth.radius) / RadiusUncertainty(r);
    if (plain_ratio > 3.0) ++t.plain_outside;
    t.least_plain = std::min(t.least_plain, plain_ratio);
    EXPECT_EQ(p.rejected, 0);
  }
  return t;
}

void Expect(const Tally& t, const std::string& what) {
  std::printf(
      "%s: %d of %d robust radii within 3 u (largest |error| / u %.2f), %d rejecting >= 20 %%; %d "
      "least-squares radii beyond 3 u (smallest |error| / u %.1f)\n",
      what.c_str(), t.robust_within, kSeeds, t.worst_robust, t.robust_rejecting, t.plain_outside,
      t.least_plain);
  EXPECT_GE(t.robust_within, 95) << what << ": worst |error| / u " << t.worst_robust;
  EXPECT_GE(t.robust_rejecting, 95) << what;
  EXPECT_GE(t.plain_outside, 95) << what << ": least |error| / u of least squares " << t.least_plain;
}

// Each robust loss on each contaminated shape: the robust radius within 3 of its uncertainties, least squares
// biased far outside them (Expect).
struct RobustCase {
  const char* name;
  const char* loss;
  bool sphere;
};

class RobustPrimitiveFitCases : public ::testing::TestWithParam<RobustCase> {};

TEST_P(RobustPrimitiveFitCases, RobustRadiusWithinItsUncertaintyLeastSquaresBiased) {
  const RobustCase& c = GetParam();
  const Tally t = c.sphere
                      ? RunSeeds<Sphere>(c.loss, 400, ContaminatedSphere,
                                         [](const auto& p, const auto& o) { return FitSphere(p, o); })
                      : RunSeeds<Cylinder>(c.loss, 400, ContaminatedCylinder,
                                           [](const auto& p, const auto& o) { return FitCylinder(p, o); });
  Expect(t, c.name);
}

INSTANTIATE_TEST_SUITE_P(RobustPrimitiveFit, RobustPrimitiveFitCases,
                         ::testing::Values(RobustCase{"sphere, tukey", "tukey", true},
                                           RobustCase{"sphere, cauchy", "cauchy", true},
                                           RobustCase{"cylinder, tukey", "tukey", false},
                                           RobustCase{"cylinder, cauchy", "cauchy", false}));

TEST(RobustPrimitiveFit, RejectsErrorTermsPrimitivesDoNotTake) {
  const Eigen::Matrix3Xd points = Eigen::Matrix3Xd::Random(3, 20);
  PrimitiveFitOptions options;
  options.error_term = ErrorTerm::kPdm;
  try {
    FitSphere(points, options);
    ADD_FAILURE() << "pdm accepted";
  } catch (const std::invalid_argument& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("tdm"), std::string::npos) << message;
    EXPECT_NE(message.find("sdm"), std::string::npos) << message;
  }
  options.error_term = ErrorTerm::kGn;
  EXPECT_THROW(FitCylinder(points, options), std::invalid_argument);
  EXPECT_THROW(FitPlane(points, options), std::invalid_argument);
}

TEST(RobustPrimitiveFit, PlaneWithTukeyIgnoresTheOutliers) {
  // 300 points of the plane z = 0.5 and 150 uniform in the cube [-1, 1]^3, which pull the least-squares plane
  // towards z = 1/3.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, kNoise);
  Eigen::Matrix3Xd points(3, 450);
  for (Eigen::Index i = 0; i < 300; ++i) points.col(i) << u(rng), u(rng), 0.5 + noise(rng);
  for (Eigen::Index i = 300; i < points.cols(); ++i) points.col(i) << u(rng), u(rng), u(rng);
  PrimitiveFitOptions options;
  options.optimizer.loss = ParseRobustLoss("tukey");
  const PrimitiveFit<Plane> robust = FitPlane(points, options);
  const PrimitiveFit<Plane> plain = FitPlane(points);
  const auto height = [](const Plane& p) { return p.normal.dot(p.point) / p.normal.z(); };
  EXPECT_LT(std::acos(std::min(1.0, std::abs(robust.shape.normal.z()))), 5e-3);
  EXPECT_NEAR(height(robust.shape), 0.5, 3e-3);
  EXPECT_GT(std::abs(height(plain.shape) - 0.5), 0.1);  // least squares is pulled away
  EXPECT_GT(robust.rejected, 100);
  ASSERT_EQ(robust.uncertainties.size(), 2u);
  EXPECT_LT(robust.uncertainties[0].standard_uncertainty, 3e-3);
}

}  // namespace
}  // namespace s2m
