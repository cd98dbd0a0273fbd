#include "fitting/primitive_fit.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <random>
#include <type_traits>

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

// ---- The ISO 10360-6 primitives beside plane, sphere, cylinder and cone: the 3-D line, the 3-D circle and
// the torus (docs/metrology.md section 1). Jacobians against central differences; noise-free data to the
// double-precision floor (full and partial arcs); Monte-Carlo efficiency against sigma / sqrt(N) (full
// figures, where sigma / sqrt(N) is the first-order standard deviation) and against the fit's own type-A
// uncertainty (partial arcs, where the parameters correlate); robust losses; bad input.
// ------------------------------------------------------------------------------------------------------------

// Isotropic Gaussian noise of standard deviation sigma per coordinate.
Eigen::Vector3d Noise(std::mt19937_64& rng, double sigma) {
  std::normal_distribution<double> n(0.0, sigma);
  return sigma > 0 ? Eigen::Vector3d(n(rng), n(rng), n(rng)) : Eigen::Vector3d::Zero();
}

Eigen::Matrix3Xd SampleLine(const Line3d& s, double length, int n, double sigma, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> t(-0.5 * length, 0.5 * length);
  Eigen::Matrix3Xd p(3, n);
  for (int i = 0; i < n; ++i) p.col(i) = s.point + t(rng) * s.direction + Noise(rng, sigma);
  return p;
}

// Points on an arc of `arc` radians of the circle.
Eigen::Matrix3Xd SampleCircle(const Circle3d& s, double arc, int n, double sigma, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> angle(0.0, arc);
  const Eigen::Matrix3d f = FrameWithAxis(s.normal);
  Eigen::Matrix3Xd p(3, n);
  for (int i = 0; i < n; ++i) {
    const double a = angle(rng);
    p.col(i) = s.center + s.radius * (std::cos(a) * f.col(0) + std::sin(a) * f.col(1)) + Noise(rng, sigma);
  }
  return p;
}

// Points uniform in (theta, phi) over theta in [0, arc_theta), phi in [phi0, phi1), noise along the normal.
Eigen::Matrix3Xd SampleTorus(const Torus& s, double arc_theta, double phi0, double phi1, int n, double sigma,
                             std::mt19937_64& rng) {
  std::uniform_real_distribution<double> theta(0.0, arc_theta), phi(phi0, phi1);
  std::normal_distribution<double> noise(0.0, sigma);
  const Eigen::Matrix3d f = FrameWithAxis(s.axis);
  Eigen::Matrix3Xd p(3, n);
  for (int i = 0; i < n; ++i) {
    const double t = theta(rng), u = phi(rng);
    const double r = s.minor_radius + (sigma > 0 ? noise(rng) : 0.0);
    const Eigen::Vector3d radial = std::cos(t) * f.col(0) + std::sin(t) * f.col(1);
    p.col(i) = s.center + (s.major_radius + r * std::cos(u)) * radial + r * std::sin(u) * s.axis;
  }
  return p;
}

double LineOffset(const Line3d& fit, const Line3d& truth, const Eigen::Vector3d& at) {
  // The distance between the lines at the station `at` (projected onto each).
  const Eigen::Vector3d a = fit.point + fit.direction.dot(at - fit.point) * fit.direction;
  const Eigen::Vector3d b = truth.point + truth.direction.dot(at - truth.point) * truth.direction;
  return (a - b).norm();
}

// ---- Jacobians: the rows of primitive_local_models.h against central differences. For the torus the rows
// are d(distance); for the curves they are the rows of the 2-vector across the curve, whose components depend
// on the frame chosen across it (any rotation of it is as good a residual), so the invariant checked is the
// distance's derivative r^T J / |r| (docs/metrology.md eqs. 1-3).

template <class Shape>
Eigen::MatrixXd DistanceRows(const Shape& shape, const Eigen::Matrix3Xd& points) {
  const Eigen::MatrixXd J = DistanceJacobian(shape, points);
  if constexpr (std::is_same_v<Shape, Torus>) {
    return J;
  } else {
    const Eigen::VectorXd r = ResidualVector(shape, points);
    Eigen::MatrixXd g(points.cols(), J.cols());
    for (Eigen::Index i = 0; i < points.cols(); ++i)
      g.row(i) = r.segment<2>(2 * i).transpose() * J.middleRows<2>(2 * i) / r.segment<2>(2 * i).norm();
    return g;
  }
}

template <class Shape>
void ExpectJacobianMatchesDifferences(const Shape& shape, const Eigen::Matrix3Xd& points) {
  const Eigen::MatrixXd J = DistanceRows(shape, points);
  const double h = 1e-6;
  for (Eigen::Index k = 0; k < J.cols(); ++k) {
    Eigen::VectorXd step = Eigen::VectorXd::Zero(J.cols());
    step[k] = h;
    const Eigen::VectorXd numeric = (SignedDistances(ApplyIncrement(shape, step), points) -
                                     SignedDistances(ApplyIncrement(shape, -step), points)) /
                                    (2 * h);
    // Central differences: truncation O(h^2) times third derivatives of size ~1 here, rounding 1e-16 / h.
    EXPECT_LT((numeric - J.col(k)).cwiseAbs().maxCoeff(), 1e-7) << "parameter " << k;
  }
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(J.cols());
  EXPECT_LT((SignedDistances(ApplyIncrement(shape, zero), points) - SignedDistances(shape, points)).norm(),
            1e-13);
}

TEST(IsoPrimitives, JacobiansMatchCentralDifferences) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::Matrix3Xd points(3, 25);
    for (Eigen::Index i = 0; i < points.cols(); ++i) points.col(i) = Eigen::Vector3d(u(rng), u(rng), u(rng));
    SCOPED_TRACE(trial);
    ExpectJacobianMatchesDifferences(Line3d{RandomUnit(rng), RandomUnit(rng)}, points);
    ExpectJacobianMatchesDifferences(Circle3d{RandomUnit(rng), RandomUnit(rng), 1.7}, points);
    ExpectJacobianMatchesDifferences(Torus{RandomUnit(rng), RandomUnit(rng), 2.5, 0.7}, points);
  }
}

// ---- Noise-free data: the double-precision floor

TEST(IsoPrimitives, RecoversAnExactLine) {
  std::mt19937_64 rng(1);
  const Line3d truth{{100.0, -40.0, 7.0}, Eigen::Vector3d(0.3, 0.9, -0.2).normalized()};
  const Eigen::Matrix3Xd p = SampleLine(truth, 50.0, 100, 0.0, rng);
  const auto fit = FitLine(p);
  EXPECT_EQ(fit.stop_reason, StopReason::kClosedForm);
  const double position = LineOffset(fit.shape, truth, p.rowwise().mean());
  const double direction = LineAngle(fit.shape.direction, truth.direction);
  std::printf("line floor: position %.2e (rel. %.2e), direction %.2e rad\n", position, position / 50.0,
              direction);
  EXPECT_LT(position, 1e-12 * 150.0);  // relative to the coordinates' size
  EXPECT_LT(direction, 1e-14);
  EXPECT_LT(fit.residuals.max_abs, 1e-12);
}

TEST(IsoPrimitives, RecoversExactCirclesFromFullAndPartialArcs) {
  std::mt19937_64 rng(2);
  const Circle3d truth{{10.0, -20.0, 30.0}, Eigen::Vector3d(1.0, -2.0, 0.5).normalized(), 12.5};
  for (const double arc : {2 * M_PI, M_PI / 2, M_PI / 6}) {
    const auto fit = FitCircle(SampleCircle(truth, arc, 60, 0.0, rng));
    const double center = (fit.shape.center - truth.center).norm();
    const double normal = LineAngle(fit.shape.normal, truth.normal);
    const double radius = std::abs(fit.shape.radius - truth.radius);
    std::printf("circle floor, arc %.0f deg: centre %.2e, normal %.2e rad, radius %.2e (%d iterations)\n",
                arc * 180 / M_PI, center, normal, radius, fit.iterations);
    // The floor: rounding of coordinates of size ~40 (ulp 7e-15) amplified by the arc's conditioning, which
    // grows as the arc shortens (a 30-degree arc: about 1 / (1 - cos 15 deg) ~ 30).
    const double floor = (arc > 6 ? 1e-12 : 1e-10) * truth.radius;
    EXPECT_LT(center, floor) << arc;
    EXPECT_LT(normal, floor / truth.radius) << arc;
    EXPECT_LT(radius, floor) << arc;
  }
}

TEST(IsoPrimitives, RecoversExactToriFromWholeAndPartialSurfaces) {
  std::mt19937_64 rng(3);
  const Torus truth{{5.0, -3.0, 8.0}, Eigen::Vector3d(0.2, 0.4, 1.0).normalized(), 20.0, 4.0};
  struct Patch {
    const char* name;
    double theta, phi0, phi1;
  };
  for (const Patch& patch :
       {Patch{"whole", 2 * M_PI, 0, 2 * M_PI}, Patch{"quarter ring", M_PI / 2, 0, 2 * M_PI},
        Patch{"outer half of a third", 2 * M_PI / 3, -M_PI / 2, M_PI / 2}}) {
    const auto fit = FitTorus(SampleTorus(truth, patch.theta, patch.phi0, patch.phi1, 400, 0.0, rng));
    const double center = (fit.shape.center - truth.center).norm();
    const double axis = LineAngle(fit.shape.axis, truth.axis);
    const double major = std::abs(fit.shape.major_radius - truth.major_radius);
    const double minor = std::abs(fit.shape.minor_radius - truth.minor_radius);
    std::printf("torus floor, %s: centre %.2e, axis %.2e rad, R %.2e, r %.2e (%d iterations)\n", patch.name,
                center, axis, major, minor, fit.iterations);
    const double floor = 1e-10 * truth.major_radius;
    EXPECT_LT(center, floor) << patch.name;
    EXPECT_LT(axis, floor / truth.major_radius) << patch.name;
    EXPECT_LT(major, floor) << patch.name;
    EXPECT_LT(minor, floor) << patch.name;
  }
}

// ---- Statistical efficiency

TEST(IsoPrimitives, LineIsStatisticallyEfficient) {
  // Across the line each of the two coordinates of the fitted position at the centroid has standard
  // deviation sigma / sqrt(N) to first order.
  std::mt19937_64 rng(2026);
  const int trials = 300, n = 200;
  const double sigma = 0.01;
  double sum_sq = 0.0;
  for (int t = 0; t < trials; ++t) {
    const Line3d truth{RandomUnit(rng) * 50.0, RandomUnit(rng)};
    const Eigen::Matrix3Xd p = SampleLine(truth, 20.0, n, sigma, rng);
    const auto fit = FitLine(p);
    sum_sq += std::pow(LineOffset(fit.shape, truth, p.rowwise().mean()), 2) / 2.0;
  }
  const double ratio = std::sqrt(sum_sq / trials) / (sigma / std::sqrt(n));
  std::printf("line position RMSE per coordinate = %.3f sigma/sqrt(N) over %d trials\n", ratio, trials);
  EXPECT_LE(ratio, 1.3);
  EXPECT_GE(ratio, 0.7) << "suspiciously small: is the noise applied?";
}

TEST(IsoPrimitives, CircleRadiusIsStatisticallyEfficient) {
  std::mt19937_64 rng(2027);
  const int trials = 300, n = 200;
  const double sigma = 0.01;
  double sum_sq = 0.0;
  for (int t = 0; t < trials; ++t) {
    const Circle3d truth{RandomUnit(rng) * 50.0, RandomUnit(rng), 5.0};
    sum_sq +=
        std::pow(FitCircle(SampleCircle(truth, 2 * M_PI, n, sigma, rng)).shape.radius - truth.radius, 2);
  }
  const double ratio = std::sqrt(sum_sq / trials) / (sigma / std::sqrt(n));
  std::printf("circle radius RMSE = %.3f sigma/sqrt(N) over %d trials\n", ratio, trials);
  EXPECT_LE(ratio, 1.3);
  EXPECT_GE(ratio, 0.7);
}

TEST(IsoPrimitives, TorusMinorRadiusIsStatisticallyEfficient) {
  // Points uniform in (theta, phi): the minor radius's column (-1) is orthogonal to the others on average,
  // so its first-order standard deviation is sigma / sqrt(N).
  std::mt19937_64 rng(2028);
  const int trials = 200, n = 400;
  const double sigma = 0.01;
  double sum_sq = 0.0;
  for (int t = 0; t < trials; ++t) {
    const Torus truth{RandomUnit(rng) * 20.0, RandomUnit(rng), 10.0, 3.0};
    const auto fit = FitTorus(SampleTorus(truth, 2 * M_PI, 0, 2 * M_PI, n, sigma, rng));
    sum_sq += std::pow(fit.shape.minor_radius - truth.minor_radius, 2);
  }
  const double ratio = std::sqrt(sum_sq / trials) / (sigma / std::sqrt(n));
  std::printf("torus minor radius RMSE = %.3f sigma/sqrt(N) over %d trials\n", ratio, trials);
  EXPECT_LE(ratio, 1.3);
  EXPECT_GE(ratio, 0.7);
}

// On partial arcs the centre and the radius correlate and sigma / sqrt(N) no longer bounds the radius; the
// type-A uncertainty of each fit (the covariance) predicts the scatter instead.
TEST(IsoPrimitives, PartialArcScatterMatchesTheReportedUncertainty) {
  std::mt19937_64 rng(2029);
  const int trials = 300, n = 200;
  const double sigma = 0.01;
  double circle_sq = 0.0, circle_u = 0.0, torus_sq = 0.0, torus_u = 0.0;
  for (int t = 0; t < trials; ++t) {
    const Circle3d circle{RandomUnit(rng) * 50.0, RandomUnit(rng), 5.0};
    const auto c = FitCircle(SampleCircle(circle, M_PI / 2, n, sigma, rng));
    circle_sq += std::pow(c.shape.radius - circle.radius, 2);
    circle_u += std::pow(c.uncertainties.back().standard_uncertainty, 2);
    const Torus torus{RandomUnit(rng) * 20.0, RandomUnit(rng), 10.0, 3.0};
    const auto f = FitTorus(SampleTorus(torus, M_PI / 2, -M_PI / 2, M_PI / 2, n, sigma, rng));
    torus_sq += std::pow(f.shape.major_radius - torus.major_radius, 2);
    torus_u += std::pow(f.uncertainties[4].standard_uncertainty, 2);
  }
  const double circle_ratio = std::sqrt(circle_sq / circle_u), torus_ratio = std::sqrt(torus_sq / torus_u);
  std::printf("partial arcs: circle radius RMSE / reported u = %.3f, torus major radius = %.3f (%d trials)\n",
              circle_ratio, torus_ratio, trials);
  // 300 trials: the ratio of an RMSE to its expectation has a relative standard error of about
  // 1 / sqrt(2 * 300) = 0.04; [0.8, 1.25] is five of those.
  EXPECT_GT(circle_ratio, 0.8);
  EXPECT_LT(circle_ratio, 1.25);
  EXPECT_GT(torus_ratio, 0.8);
  EXPECT_LT(torus_ratio, 1.25);
}

// ---- Reporting, robust losses, bad input

TEST(IsoPrimitives, ReportsNamedUncertainties) {
  std::mt19937_64 rng(5);
  const auto line = FitLine(SampleLine({{0, 0, 0}, {0, 0, 1}}, 10, 50, 0.01, rng));
  ASSERT_EQ(line.uncertainties.size(), 2u);
  EXPECT_EQ(line.uncertainties[0].name, "position");
  EXPECT_EQ(line.uncertainties[1].name, "direction");
  const auto circle = FitCircle(SampleCircle({{0, 0, 0}, {0, 0, 1}, 3}, 2 * M_PI, 50, 0.01, rng));
  ASSERT_EQ(circle.uncertainties.size(), 5u);
  EXPECT_EQ(circle.uncertainties[4].name, "radius");
  // Full circle, isotropic noise: the radius's type-A uncertainty is sigma / sqrt(N) within sampling error.
  EXPECT_NEAR(circle.uncertainties[4].standard_uncertainty, 0.01 / std::sqrt(50.0),
              0.3 * 0.01 / std::sqrt(50.0));
  const auto torus =
      FitTorus(SampleTorus({{0, 0, 0}, {0, 0, 1}, 5, 1}, 2 * M_PI, 0, 2 * M_PI, 200, 0.01, rng));
  ASSERT_EQ(torus.uncertainties.size(), 6u);
  EXPECT_EQ(torus.uncertainties[5].name, "minor_radius");
}

// 20 % gross outliers uniform in a box around the data.
TEST(IsoPrimitives, RobustLossesRejectGrossOutliers) {
  std::mt19937_64 rng(6);
  std::uniform_real_distribution<double> box(-15.0, 15.0);
  PrimitiveFitOptions robust;
  robust.optimizer.loss = RobustLoss{LossKind::kTukey, 0.0};
  const Circle3d circle{{1, 2, 3}, Eigen::Vector3d(0.1, 0.2, 1).normalized(), 8.0};
  Eigen::Matrix3Xd c = SampleCircle(circle, 2 * M_PI, 300, 0.01, rng);
  const Torus torus{{1, 2, 3}, Eigen::Vector3d(0.1, 0.2, 1).normalized(), 8.0, 2.0};
  Eigen::Matrix3Xd t = SampleTorus(torus, 2 * M_PI, 0, 2 * M_PI, 600, 0.01, rng);
  const Line3d line{{1, 2, 3}, Eigen::Vector3d(1, 1, 0).normalized()};
  Eigen::Matrix3Xd l = SampleLine(line, 20, 300, 0.01, rng);
  // 20 % gross outliers, uniform in a box around the data.
  for (Eigen::Matrix3Xd* p : {&c, &t, &l})
    for (Eigen::Index i = 0; i < p->cols() / 5; ++i)
      p->col(i) = Eigen::Vector3d(box(rng), box(rng), box(rng));
  const auto fc = FitCircle(c, robust);
  const auto fl = FitLine(l, robust);
  // The torus's automatic starts use every point's normal and are not robust to gross outliers (documented in
  // docs/metrology.md): a robust torus is refined from a start, as `fit --robust` and `detect` do with their
  // RANSAC candidate; here a start 5 % off in every parameter.
  const Torus start{torus.center + Eigen::Vector3d(0.3, -0.2, 0.1),
                    Eigen::Vector3d(0.15, 0.15, 1).normalized(), 8.4, 1.9};
  const auto ft = RefineTorus(t, start, robust);
  // Within 10 sigma / sqrt(N) of the truth: least squares would be off by a fraction of the box.
  EXPECT_NEAR(fc.shape.radius, circle.radius, 0.01);
  EXPECT_NEAR(ft.shape.minor_radius, torus.minor_radius, 0.01);
  EXPECT_NEAR(ft.shape.major_radius, torus.major_radius, 0.01);
  EXPECT_LT(LineAngle(fl.shape.direction, line.direction), 1e-3);
  EXPECT_GE(fc.rejected, 50);
  EXPECT_LT(std::abs(FitCircle(c).shape.radius - circle.radius), 100.0);  // (least squares runs, badly)
}

TEST(IsoPrimitives, BadInputGivesClearErrors) {
  auto message = [](auto&& f) {
    try {
      f();
    } catch (const FitError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message([] { FitLine(Eigen::Matrix3Xd::Random(3, 1)); }).find("at least 2 points"),
            std::string::npos);
  EXPECT_NE(message([] { FitCircle(Eigen::Matrix3Xd::Random(3, 2)); }).find("at least 3 points"),
            std::string::npos);
  EXPECT_NE(message([] { FitTorus(Eigen::Matrix3Xd::Random(3, 6)); }).find("at least 7 points"),
            std::string::npos);
  Eigen::Matrix3Xd collinear(3, 10);
  for (int i = 0; i < 10; ++i) collinear.col(i) = Eigen::Vector3d(1, 2, 3) * i;
  EXPECT_NE(message([&] { FitCircle(collinear); }).find("collinear"), std::string::npos);
  EXPECT_NE(message([] { FitLine(Eigen::Matrix3Xd::Zero(3, 5)); }).find("coincide"), std::string::npos);
  Eigen::Matrix3Xd nan = Eigen::Matrix3Xd::Random(3, 20);
  nan(0, 3) = std::nan("");
  EXPECT_NE(message([&] { FitTorus(nan); }).find("NaN"), std::string::npos);
  PrimitiveFitOptions sdm;
  sdm.error_term = ErrorTerm::kSdm;
  EXPECT_THROW(FitCircle(Eigen::Matrix3Xd::Random(3, 20), sdm), std::invalid_argument);
  EXPECT_THROW(FitTorus(Eigen::Matrix3Xd::Random(3, 20), sdm), std::invalid_argument);
}

}  // namespace
}  // namespace s2m
