#include "fitting/primitive_fit.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <random>

#include "fitting/primitive_compare.h"

namespace s2m {
namespace {

Eigen::Vector3d RandomUnit(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
}

// Points on a shape (up to an optional Gaussian offset along the normal), for each primitive family.
Eigen::Matrix3Xd SampleSphere(const Sphere& s, int n, double sigma, std::mt19937_64& rng) {
  std::normal_distribution<double> noise(0.0, sigma);
  Eigen::Matrix3Xd p(3, n);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d u = RandomUnit(rng);
    p.col(i) = s.center + (s.radius + (sigma > 0 ? noise(rng) : 0.0)) * u;
  }
  return p;
}

Eigen::Matrix3Xd SampleCylinder(const Cylinder& s, double length, int n, double sigma, std::mt19937_64& rng) {
  std::normal_distribution<double> noise(0.0, sigma);
  std::uniform_real_distribution<double> t(-0.5 * length, 0.5 * length), angle(0.0, 2 * M_PI);
  const Eigen::Matrix3d f = FrameWithAxis(s.axis_direction);
  Eigen::Matrix3Xd p(3, n);
  for (int i = 0; i < n; ++i) {
    const double a = angle(rng);
    const double r = s.radius + (sigma > 0 ? noise(rng) : 0.0);
    p.col(i) =
        s.axis_point + t(rng) * s.axis_direction + r * (std::cos(a) * f.col(0) + std::sin(a) * f.col(1));
  }
  return p;
}

Eigen::Matrix3Xd SampleCone(const Cone& s, double z0, double z1, double arc, int n, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> t(z0, z1), angle(0.0, arc);
  const Eigen::Matrix3d f = FrameWithAxis(s.axis_direction);
  Eigen::Matrix3Xd p(3, n);
  for (int i = 0; i < n; ++i) {
    const double z = t(rng), a = angle(rng);
    const double r = s.radius + z * std::tan(s.half_angle);
    p.col(i) = s.axis_point + z * s.axis_direction + r * (std::cos(a) * f.col(0) + std::sin(a) * f.col(1));
  }
  return p;
}

// ---- Property test shared by the family: analytic distance Jacobians against central differences
// ------------

template <class Shape>
struct Family;
template <>
struct Family<Sphere> {
  static Sphere Make(std::mt19937_64& rng) { return {RandomUnit(rng), 2.0}; }
};
template <>
struct Family<Cylinder> {
  static Cylinder Make(std::mt19937_64& rng) { return {RandomUnit(rng), RandomUnit(rng), 1.5}; }
};
template <>
struct Family<Cone> {
  static Cone Make(std::mt19937_64& rng) { return {RandomUnit(rng), RandomUnit(rng), 0.4, 1.5}; }
};

template <class Shape>
class PrimitiveFamily : public ::testing::Test {};
using Shapes = ::testing::Types<Sphere, Cylinder, Cone>;
TYPED_TEST_SUITE(PrimitiveFamily, Shapes);

TYPED_TEST(PrimitiveFamily, DistanceJacobianMatchesCentralDifferences) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  for (int trial = 0; trial < 20; ++trial) {
    const TypeParam shape = Family<TypeParam>::Make(rng);
    Eigen::Matrix3Xd points(3, 25);
    for (Eigen::Index i = 0; i < points.cols(); ++i) points.col(i) = Eigen::Vector3d(u(rng), u(rng), u(rng));
    const Eigen::MatrixXd J = DistanceJacobian(shape, points);
    const double h = 1e-6;
    for (Eigen::Index k = 0; k < J.cols(); ++k) {
      Eigen::VectorXd step = Eigen::VectorXd::Zero(J.cols());
      step[k] = h;
      const Eigen::VectorXd numeric = (SignedDistances(ApplyIncrement(shape, step), points) -
                                       SignedDistances(ApplyIncrement(shape, -step), points)) /
                                      (2 * h);
      EXPECT_LT((numeric - J.col(k)).cwiseAbs().maxCoeff(), 1e-7) << "parameter " << k << ", trial " << trial;
    }
  }
}

TYPED_TEST(PrimitiveFamily, ZeroIncrementIsTheIdentity) {
  std::mt19937_64 rng(3);
  const TypeParam shape = Family<TypeParam>::Make(rng);
  Eigen::Matrix3Xd points = Eigen::Matrix3Xd::Random(3, 10) * 3.0;
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(DistanceJacobian(shape, points).cols());
  EXPECT_LT((SignedDistances(ApplyIncrement(shape, zero), points) - SignedDistances(shape, points)).norm(),
            1e-13);
}

// ---- Exact recovery from noise-free data, both methods
// --------------------------------------------------------

class BothMethods : public ::testing::TestWithParam<ErrorTerm> {
 protected:
  PrimitiveFitOptions Options() const {
    PrimitiveFitOptions o;
    o.error_term = GetParam();
    return o;
  }
};
INSTANTIATE_TEST_SUITE_P(Methods, BothMethods, ::testing::Values(ErrorTerm::kTdm, ErrorTerm::kSdm),
                         [](const auto& param_info) { return std::string(ToString(param_info.param)); });

TEST_P(BothMethods, RecoversAnExactSphereFromAHemisphere) {
  std::mt19937_64 rng(1);
  const Sphere truth{{10.0, -20.0, 5.0}, 7.5};
  Eigen::Matrix3Xd p = SampleSphere(truth, 300, 0.0, rng);
  for (Eigen::Index i = 0; i < p.cols(); ++i) {
    if (p(2, i) < truth.center.z()) p(2, i) = 2 * truth.center.z() - p(2, i);  // keep the upper half only
  }
  const auto fit = FitSphere(p, Options());
  const PrimitiveDeviation d = Compare(fit.shape, truth);
  EXPECT_LT(d.position, 1e-10);
  EXPECT_LT(d.size, 1e-10);
  EXPECT_LT(fit.residuals.rms, 1e-10);
}

TEST_P(BothMethods, RecoversAnExactCylinder) {
  std::mt19937_64 rng(2);
  const Cylinder truth{{100.0, 50.0, -30.0}, Eigen::Vector3d(0.2, -0.5, 1.0).normalized(), 12.0};
  const auto fit = FitCylinder(SampleCylinder(truth, 40.0, 200, 0.0, rng), Options());
  const PrimitiveDeviation d = Compare(fit.shape, truth);
  EXPECT_LT(d.position, 1e-9);
  EXPECT_LT(d.direction, 1e-10);
  EXPECT_LT(d.size, 1e-9);
}

TEST_P(BothMethods, RecoversAnExactConeFromAQuarterArc) {
  std::mt19937_64 rng(3);
  const Cone truth{{5.0, 5.0, 5.0}, Eigen::Vector3d(1.0, 1.0, -0.3).normalized(), 0.3, 8.0};
  const auto fit = FitCone(SampleCone(truth, -5.0, 10.0, M_PI / 2, 300, rng), Options());
  const PrimitiveDeviation d = Compare(fit.shape, truth);
  EXPECT_LT(d.position, 1e-8);
  EXPECT_LT(d.direction, 1e-9);
  EXPECT_LT(d.angle, 1e-9);
  EXPECT_LT(d.size, 1e-8);
}

TEST(PrimitiveFit, ExactPlaneIsClosedForm) {
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-10.0, 10.0);
  const Plane truth{{1.0, 2.0, 3.0}, Eigen::Vector3d(0.3, -0.4, 0.8).normalized()};
  const Eigen::Matrix3d f = FrameWithAxis(truth.normal);
  Eigen::Matrix3Xd p(3, 50);
  for (int i = 0; i < 50; ++i) p.col(i) = truth.point + u(rng) * f.col(0) + u(rng) * f.col(1);
  const auto fit = FitPlane(p);
  EXPECT_EQ(fit.stop_reason, StopReason::kClosedForm);
  EXPECT_LT(Compare(fit.shape, truth).direction, 1e-14);
  EXPECT_LT(Compare(fit.shape, truth).position, 1e-12);
}

// ---- Statistical efficiency: Monte Carlo against sigma / sqrt(N)
// ------------------------------------------------ For N points with independent N(0, sigma^2) errors along
// the normal, covering the whole sphere or cylinder, the least-squares radius has standard deviation sigma /
// sqrt(N) to first order; an efficient estimator stays close.

TEST(PrimitiveFit, SphereRadiusIsStatisticallyEfficient) {
  std::mt19937_64 rng(2026);
  const int trials = 300, n = 500;
  const double sigma = 0.01;
  double sum_sq = 0.0;
  for (int t = 0; t < trials; ++t) {
    const Sphere truth{RandomUnit(rng) * 50.0, 10.0};
    const auto fit = FitSphere(SampleSphere(truth, n, sigma, rng));
    sum_sq += std::pow(fit.shape.radius - truth.radius, 2);
  }
  const double rmse = std::sqrt(sum_sq / trials);
  std::printf("sphere radius RMSE %.3g = %.3f sigma/sqrt(N) over %d trials\n", rmse,
              rmse / (sigma / std::sqrt(n)), trials);
  EXPECT_LE(rmse, 1.3 * sigma / std::sqrt(n)) << "radius RMSE " << rmse;
  EXPECT_GE(rmse, 0.7 * sigma / std::sqrt(n)) << "suspiciously small: is the noise applied?";
}

TEST(PrimitiveFit, CylinderRadiusIsStatisticallyEfficient) {
  std::mt19937_64 rng(2027);
  const int trials = 300, n = 500;
  const double sigma = 0.01;
  double sum_sq = 0.0;
  for (int t = 0; t < trials; ++t) {
    const Cylinder truth{RandomUnit(rng) * 50.0, RandomUnit(rng), 5.0};
    const auto fit = FitCylinder(SampleCylinder(truth, 20.0, n, sigma, rng));
    sum_sq += std::pow(fit.shape.radius - truth.radius, 2);
  }
  const double rmse = std::sqrt(sum_sq / trials);
  std::printf("cylinder radius RMSE %.3g = %.3f sigma/sqrt(N) over %d trials\n", rmse,
              rmse / (sigma / std::sqrt(n)), trials);
  EXPECT_LE(rmse, 1.3 * sigma / std::sqrt(n)) << "radius RMSE " << rmse;
  EXPECT_GE(rmse, 0.7 * sigma / std::sqrt(n));
}

TEST(PrimitiveFit, ReportedUncertaintyMatchesTheScatter) {
  // The type-A radius uncertainty of one fit predicts the Monte-Carlo scatter (within sampling error).
  std::mt19937_64 rng(99);
  const Sphere truth{{0, 0, 0}, 10.0};
  const auto fit = FitSphere(SampleSphere(truth, 500, 0.01, rng));
  ASSERT_EQ(fit.uncertainties.size(), 4u);
  EXPECT_EQ(fit.uncertainties[3].name, "radius");
  EXPECT_NEAR(fit.uncertainties[3].standard_uncertainty, 0.01 / std::sqrt(500.0),
              0.1 * 0.01 / std::sqrt(500.0));
}

// ---- Bad input: clear errors, no crash
// ---------------------------------------------------------------------------

TEST(PrimitiveFit, RejectsTooFewPoints) {
  const Eigen::Matrix3Xd three = Eigen::Matrix3Xd::Random(3, 3);
  EXPECT_THROW(FitSphere(three), FitError);
  EXPECT_THROW(FitCylinder(Eigen::Matrix3Xd::Random(3, 4)), FitError);
  EXPECT_THROW(FitCone(Eigen::Matrix3Xd::Random(3, 5)), FitError);
  EXPECT_THROW(FitPlane(Eigen::Matrix3Xd::Random(3, 2)), FitError);
  try {
    FitCone(Eigen::Matrix3Xd::Random(3, 5));
  } catch (const FitError& e) {
    EXPECT_NE(std::string(e.what()).find("at least 6 points"), std::string::npos) << e.what();
  }
}

TEST(PrimitiveFit, RejectsNonFiniteAndDegenerateData) {
  Eigen::Matrix3Xd p = Eigen::Matrix3Xd::Random(3, 20);
  p(1, 7) = std::nan("");
  EXPECT_THROW(FitSphere(p), FitError);
  EXPECT_THROW(FitPlane(Eigen::Matrix3Xd::Zero(3, 10)), FitError);  // all points coincide
  Eigen::Matrix3Xd line(3, 10);
  for (int i = 0; i < 10; ++i) line.col(i) = Eigen::Vector3d(1, 2, 3) * i;
  EXPECT_THROW(FitPlane(line), FitError);
  Eigen::Matrix3Xd flat = Eigen::Matrix3Xd::Random(3, 20);
  flat.row(2).setZero();
  EXPECT_THROW(FitSphere(flat), FitError);  // coplanar points determine no sphere
}

}  // namespace
}  // namespace s2m
