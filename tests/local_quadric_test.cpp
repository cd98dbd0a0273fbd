// Principal curvatures from local quadric fits (registration/local_quadric.h) against exact values on a
// sphere, a cylinder and a plane, noise-free and noisy; the shape operator with slopes against the derivative
// of the normal field; the SDM approximant against the exact squared distance to a sphere.

#include "registration/local_quadric.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>

#include "registration/nearest_index.h"
#include "registration/rigid_motion.h"

namespace s2m {
namespace {

// Points spread evenly over a sphere (Fibonacci lattice).
Eigen::Matrix3Xd SpherePoints(const Eigen::Vector3d& centre, double radius, int n) {
  Eigen::Matrix3Xd p(3, n);
  const double golden = M_PI * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < n; ++i) {
    const double z = 1.0 - 2.0 * (i + 0.5) / n, r = std::sqrt(1.0 - z * z), phi = golden * i;
    p.col(i) = centre + radius * Eigen::Vector3d(r * std::cos(phi), r * std::sin(phi), z);
  }
  return p;
}

// A cylinder of radius R about the axis through `base` along unit `axis`: a jittered (angle, height) grid.
Eigen::Matrix3Xd CylinderPoints(const Eigen::Vector3d& base, const Eigen::Vector3d& axis, double R,
                                int around, int along, double length, std::mt19937_64& rng) {
  const Eigen::Vector3d u = axis.unitOrthogonal(), v = axis.cross(u);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  Eigen::Matrix3Xd p(3, around * along);
  for (int i = 0; i < around; ++i)
    for (int j = 0; j < along; ++j) {
      const double theta = 2.0 * M_PI * (i + jitter(rng)) / around, h = length * (j + jitter(rng)) / along;
      p.col(i * along + j) = base + h * axis + R * (std::cos(theta) * u + std::sin(theta) * v);
    }
  return p;
}

struct Fitted {
  SurfacePoint at;
  double radius;  // of the neighbourhood
};

// Quadric fits at every `step`-th point over its k nearest neighbours, evaluated at the point's foot point.
std::vector<Fitted> FitAt(const Eigen::Matrix3Xd& points, int k, int step) {
  const NearestIndex index(points);
  std::vector<Fitted> out;
  for (Eigen::Index i = 0; i < points.cols(); i += step) {
    const std::vector<Eigen::Index> nn = index.KNearest(points.col(i), k);
    Eigen::Matrix3Xd hood(3, static_cast<Eigen::Index>(nn.size()));
    for (std::size_t j = 0; j < nn.size(); ++j) hood.col(static_cast<Eigen::Index>(j)) = points.col(nn[j]);
    const LocalQuadric q = LocalQuadric::Fit(hood, points.col(i));
    out.push_back({q.FootPoint(points.col(i)), q.radius()});
  }
  return out;
}

// Truncation bound for a surface of curvature radius R: over its tangent plane the height is rho^2/(2R) +
// rho^4/(8R^3) + O(rho^6). The quadric takes the first term exactly; the quartic leaks into the quadratic
// coefficients. Over a uniformly sampled disc of radius r the least-squares leak is r^2/(8R^3) per
// coefficient (s^2 ~ r^2 s - r^4/6 for s = rho^2 uniform on [0, r^2]), i.e. r^2/(4R^3) in kappa. k-nearest
// neighbourhoods are only roughly discs, so the tests allow four times that: r^2/R^3.
double TruncationBound(double r, double R) {
  return r * r / (R * R * R);
}

TEST(LocalQuadric, SphereNoiseFreeBothCurvaturesAreOneOverR) {
  const Eigen::Vector3d centre(0.3, -0.2, 1.0);
  const double R = 2.0;
  const Eigen::Matrix3Xd p = SpherePoints(centre, R, 20000);
  double worst = 0, worst_ratio = 0, sum_err = 0;
  const std::vector<Fitted> fits = FitAt(p, 20, 7);
  for (const Fitted& f : fits) {
    // Oriented towards the centre the sphere bends towards the normal: kappa = +1/R.
    const SurfacePoint s = f.at.normal.dot(centre - f.at.point) > 0 ? f.at : f.at.Flipped();
    const double err = std::max(std::abs(s.kappa1 - 1.0 / R), std::abs(s.kappa2 - 1.0 / R));
    EXPECT_LE(err, TruncationBound(f.radius, R));
    EXPECT_NEAR(std::abs(s.normal.dot((s.point - centre).normalized())), 1.0, 1e-9);
    worst = std::max(worst, err);
    worst_ratio = std::max(worst_ratio, err / TruncationBound(f.radius, R));
    sum_err += err;
  }
  std::printf("sphere R = %g, k = 20: worst |kappa - 1/R| = %.2e (%.2f of the bound), mean %.2e\n", R, worst,
              worst_ratio, sum_err / static_cast<double>(fits.size()));
  // The library function gives the same fits.
  const std::vector<SurfacePoint> all = EstimatePrincipalCurvatures(p, 20);
  ASSERT_EQ(all.size(), static_cast<std::size_t>(p.cols()));
  EXPECT_NEAR(all[7].kappa1, fits[1].at.kappa1, 1e-12);
  EXPECT_NEAR(all[7].kappa2, fits[1].at.kappa2, 1e-12);
  EXPECT_NEAR((all[7].normal - fits[1].at.normal).norm(), 0.0, 1e-12);
}

TEST(LocalQuadric, SphereErrorIsSecondOrderInTheNeighbourhoodRadius) {
  // Four times the neighbours: twice the radius, so the truncation error (r^2/(4R^3)) grows about 4 times.
  const Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  const double R = 1.0;
  const Eigen::Matrix3Xd p = SpherePoints(centre, R, 20000);
  double mean_err[2] = {0, 0}, mean_r2[2] = {0, 0};
  const int ks[2] = {20, 80};
  for (int t = 0; t < 2; ++t) {
    const std::vector<Fitted> fits = FitAt(p, ks[t], 11);
    for (const Fitted& f : fits) {
      const SurfacePoint s = f.at.normal.dot(centre - f.at.point) > 0 ? f.at : f.at.Flipped();
      mean_err[t] += 0.5 * (s.kappa1 + s.kappa2) - 1.0 / R;
      mean_r2[t] += f.radius * f.radius;
    }
    mean_err[t] /= static_cast<double>(fits.size());
    mean_r2[t] /= static_cast<double>(fits.size());
  }
  const double ratio = mean_err[1] / mean_err[0], r2_ratio = mean_r2[1] / mean_r2[0];
  std::printf("sphere: mean curvature error %.2e (k = 20), %.2e (k = 80): ratio %.2f, r^2 ratio %.2f\n",
              mean_err[0], mean_err[1], ratio, r2_ratio);
  // The leak is positive (the quartic term bends the fit more) and scales with r^2.
  EXPECT_GT(mean_err[0], 0.0);
  EXPECT_NEAR(ratio / r2_ratio, 1.0, 0.25);
}

TEST(LocalQuadric, CylinderNoiseFreeCurvaturesAndDirections) {
  std::mt19937_64 rng(7);
  const Eigen::Vector3d axis = Eigen::Vector3d(1, 2, 3).normalized(), base(0.1, 0.2, -0.3);
  const double R = 0.5;
  const Eigen::Matrix3Xd p = CylinderPoints(base, axis, R, 300, 150, 3.0, rng);
  int checked = 0;
  double worst_k = 0, worst_angle = 0;
  for (const Fitted& f : FitAt(p, 20, 13)) {
    const double h = axis.dot(f.at.point - base);
    if (h < 0.2 || h > 2.8) continue;  // away from the open ends
    const Eigen::Vector3d radial = (f.at.point - base - h * axis).normalized();
    const SurfacePoint s = f.at.normal.dot(radial) < 0 ? f.at : f.at.Flipped();  // normal towards the axis
    const double bound = TruncationBound(f.radius, R);
    EXPECT_NEAR(s.kappa1, 0.0, bound);      // along the axis: a ruling
    EXPECT_NEAR(s.kappa2, 1.0 / R, bound);  // around: the circle
    // Directions: the eigenvector turns by about (leak into b) / (kappa2 - kappa1) <= (r/R)^2 radians.
    const double angle = std::acos(std::min(1.0, std::abs(s.direction1.dot(axis))));
    EXPECT_LE(angle, f.radius * f.radius / (R * R));
    EXPECT_NEAR(std::abs(s.direction2.dot(axis.cross(radial))), 1.0, 1e-6);
    EXPECT_NEAR(s.direction1.cross(s.direction2).dot(s.normal), 1.0, 1e-12);
    worst_k = std::max({worst_k, std::abs(s.kappa1), std::abs(s.kappa2 - 1.0 / R)});
    worst_angle = std::max(worst_angle, angle);
    ++checked;
  }
  EXPECT_GT(checked, 2000);
  std::printf("cylinder R = %g, k = 20: worst curvature error %.2e, worst axis direction error %.2e rad\n", R,
              worst_k, worst_angle);
}

TEST(LocalQuadric, PlaneHasZeroCurvature) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  const Eigen::Vector3d n = Eigen::Vector3d(-0.3, 0.2, 1.0).normalized(), u = n.unitOrthogonal(),
                        v = n.cross(u);
  Eigen::Matrix3Xd p(3, 3000);
  for (Eigen::Index i = 0; i < p.cols(); ++i)
    p.col(i) = Eigen::Vector3d(5, -2, 1) + uni(rng) * u + uni(rng) * v;
  for (const SurfacePoint& s : EstimatePrincipalCurvatures(p, 20)) {
    // Noise-free: the fit is exact up to rounding of coordinates of size about 5 (spacing about 0.04).
    EXPECT_LT(std::abs(s.kappa1), 1e-9);
    EXPECT_LT(std::abs(s.kappa2), 1e-9);
    EXPECT_NEAR(std::abs(s.normal.dot(n)), 1.0, 1e-12);
  }
}

// Noise of standard deviation sigma along the normal over a disc of k points and radius r: the least-squares
// covariance of (a, c) is sigma^2/(k r^4) [[18, 6], [6, 18]] (the disc's moments E[x^4] = r^4/8, E[x^2 y^2] =
// r^4/24, E[x^2] = r^2/4 give the partial covariance r^4 [[1/16, -1/48], [-1/48, 1/16]] of x^2, y^2 after the
// constant), so the mean curvature a + c has standard deviation sigma sqrt(48/k)/r^2, and b (variance
// sigma^2 24/(k r^4)) turns a principal direction by b/(kappa2 - kappa1).
double MeanCurvatureSd(double sigma, int k, double r) {
  return sigma * std::sqrt(48.0 / k) / (r * r);
}

TEST(LocalQuadric, NoisySphereReachesTheLeastSquaresNoiseLevel) {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const double R = 1.0, sigma = 0.002 * R;
  const Eigen::Vector3d centre(1, 2, 3);
  Eigen::Matrix3Xd p = SpherePoints(centre, R, 40000);
  for (Eigen::Index i = 0; i < p.cols(); ++i) p.col(i) += sigma * gauss(rng) * (p.col(i) - centre) / R;
  const int k = 200;
  double sum_sq = 0, sum_pred = 0, sum_err = 0;
  const std::vector<Fitted> fits = FitAt(p, k, 40);
  for (const Fitted& f : fits) {
    const SurfacePoint s = f.at.normal.dot(centre - f.at.point) > 0 ? f.at : f.at.Flipped();
    const double err = 0.5 * (s.kappa1 + s.kappa2) - 1.0 / R;
    const double bias = 0.25 * f.radius * f.radius / (R * R * R);  // the uniform-disc leak (above)
    const double sd = MeanCurvatureSd(sigma, k, f.radius);
    sum_sq += err * err;
    sum_pred += bias * bias + sd * sd;
    sum_err += err;
  }
  const double n = static_cast<double>(fits.size());
  const double rms = std::sqrt(sum_sq / n), predicted = std::sqrt(sum_pred / n);
  std::printf(
      "noisy sphere (sigma = %.3g R, k = %d): RMS mean-curvature error %.3e, predicted %.3e, mean %.2e\n",
      sigma / R, k, rms, predicted, sum_err / n);
  // The estimator is as good as least squares allows on these neighbourhoods, within the rough disc model.
  EXPECT_LT(rms, 1.25 * predicted);
  EXPECT_GT(rms, 0.5 * predicted);
}

TEST(LocalQuadric, NoisyCylinderCurvaturesAndAxisDirection) {
  std::mt19937_64 rng(5);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const Eigen::Vector3d axis = Eigen::Vector3d(-1, 0.5, 2).normalized(), base = Eigen::Vector3d::Zero();
  const double R = 1.0, sigma = 0.002 * R;
  Eigen::Matrix3Xd p = CylinderPoints(base, axis, R, 400, 100, 4.0, rng);
  for (Eigen::Index i = 0; i < p.cols(); ++i) {
    const Eigen::Vector3d radial = (p.col(i) - base - axis.dot(p.col(i) - base) * axis).normalized();
    p.col(i) += sigma * gauss(rng) * radial;
  }
  const int k = 200;
  double sq_k1 = 0, sq_k2 = 0, sq_angle = 0, pred_k = 0, pred_angle = 0;
  int n = 0;
  for (const Fitted& f : FitAt(p, k, 23)) {
    const double h = axis.dot(f.at.point - base);
    if (h < 0.8 || h > 3.2) continue;
    const Eigen::Vector3d radial = (f.at.point - base - h * axis).normalized();
    const SurfacePoint s = f.at.normal.dot(radial) < 0 ? f.at : f.at.Flipped();
    sq_k1 += s.kappa1 * s.kappa1;
    sq_k2 += (s.kappa2 - 1.0 / R) * (s.kappa2 - 1.0 / R);
    const double angle = std::acos(std::min(1.0, std::abs(s.direction1.dot(axis))));
    sq_angle += angle * angle;
    // Each principal curvature is 2a or 2c (zero slope), sd 2 sigma sqrt(18/k)/r^2 (Var a above); the axis
    // direction turns by sd(b)/(kappa2 - kappa1) = sd(b) R.
    const double r4 = std::pow(f.radius, 4);
    const double bias = 0.25 * f.radius * f.radius / (R * R * R);
    pred_k += 4.0 * 18.0 * sigma * sigma / (k * r4) + bias * bias;
    pred_angle += 24.0 * sigma * sigma / (k * r4) * R * R;
    ++n;
  }
  ASSERT_GT(n, 500);
  const double rms_k1 = std::sqrt(sq_k1 / n), rms_k2 = std::sqrt(sq_k2 / n),
               rms_angle = std::sqrt(sq_angle / n);
  const double p_k = std::sqrt(pred_k / n), p_angle = std::sqrt(pred_angle / n);
  std::printf(
      "noisy cylinder (sigma = %.3g R, k = %d): RMS kappa1 error %.3e, kappa2 %.3e (predicted %.3e), "
      "axis direction %.3e rad (predicted %.3e)\n",
      sigma / R, k, rms_k1, rms_k2, p_k, rms_angle, p_angle);
  EXPECT_LT(rms_k1, 1.25 * p_k);
  EXPECT_LT(rms_k2, 1.25 * p_k);
  EXPECT_LT(rms_angle, 1.25 * p_angle);
}

TEST(LocalQuadric, NoisyPlaneCurvaturesAreAtTheNoiseLevel) {
  std::mt19937_64 rng(13);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const Eigen::Vector3d n = Eigen::Vector3d(0.5, -0.1, 1.0).normalized(), u = n.unitOrthogonal(),
                        v = n.cross(u);
  const double sigma = 0.002;
  Eigen::Matrix3Xd p(3, 20000);
  for (Eigen::Index i = 0; i < p.cols(); ++i) p.col(i) = uni(rng) * u + uni(rng) * v + sigma * gauss(rng) * n;
  const int k = 200;
  double sq = 0, pred = 0, sq_normal = 0;
  int count = 0;
  for (const Fitted& f : FitAt(p, k, 17)) {
    if (std::abs(f.at.point.dot(u)) > 0.8 || std::abs(f.at.point.dot(v)) > 0.8) continue;  // full discs only
    sq += f.at.kappa1 * f.at.kappa1 + f.at.kappa2 * f.at.kappa2;
    pred += 192.0 * sigma * sigma / (k * std::pow(f.radius, 4));
    sq_normal += (f.at.normal.cross(n)).squaredNorm();
    ++count;
  }
  ASSERT_GT(count, 500);
  const double rms = std::sqrt(sq / (2 * count)), predicted = std::sqrt(pred / (2 * count));
  std::printf(
      "noisy plane (sigma = %.3g, k = %d): RMS kappa %.3e (predicted %.3e), RMS normal "
      "error %.2e rad\n",
      sigma, k, rms, predicted, std::sqrt(sq_normal / count));
  // kappa1^2 + kappa2^2 is the squared Frobenius norm of [[2a, b], [b, 2c]] (zero slope), whose expectation
  // is (4 * 18 + 2 * 24 + 4 * 18) sigma^2 / (k r^4) = 192 sigma^2 / (k r^4) in the disc model.
  EXPECT_LT(rms, 1.25 * predicted);
}

TEST(LocalQuadric, ShapeOperatorWithSlopesMatchesTheNormalFieldDerivative) {
  // A tilted quadric with non-zero slopes: Weingarten's equation dN(T_k) = -kappa_k T_k at the principal
  // directions, checked by central differences of the normal field, which does not use the formula I^{-1} II.
  const Eigen::Matrix3d frame = RotationAboutAxis(Eigen::Vector3d(0.3, -0.5, 0.8).normalized(), 0.7);
  Eigen::Matrix<double, 6, 1> c;
  c << 0.8, -0.6, -0.3, 0.4, -0.25, 0.05;
  const LocalQuadric q(Eigen::Vector3d(1, -1, 2), frame, c, 1.0, true);
  for (const Eigen::Vector2d& xy :
       {Eigen::Vector2d(0, 0), Eigen::Vector2d(0.3, -0.2), Eigen::Vector2d(-0.5, 0.4)}) {
    const SurfacePoint s = q.At(xy.x(), xy.y());
    EXPECT_NEAR(
        (s.point - q.origin() - frame * Eigen::Vector3d(xy.x(), xy.y(), q.Height(xy.x(), xy.y()))).norm(),
        0.0, 1e-14);
    for (int kk = 0; kk < 2; ++kk) {
      const Eigen::Vector3d t = kk == 0 ? s.direction1 : s.direction2;
      const double kappa = kk == 0 ? s.kappa1 : s.kappa2;
      const Eigen::Vector3d tl = frame.transpose() * t;  // T = w1 X_x + w2 X_y, so w = (T_x, T_y) locally
      const double eps = 1e-5;
      const Eigen::Vector3d dn = (q.At(xy.x() + eps * tl.x(), xy.y() + eps * tl.y()).normal -
                                  q.At(xy.x() - eps * tl.x(), xy.y() - eps * tl.y()).normal) /
                                 (2 * eps);
      EXPECT_NEAR((dn + kappa * t).norm(), 0.0, 1e-8) << "direction " << kk;
      EXPECT_NEAR(t.dot(s.normal), 0.0, 1e-14);
    }
    EXPECT_NEAR(s.direction1.dot(s.direction2), 0.0, 1e-14);
  }
}

TEST(LocalQuadric, FootPointIsAnOrthogonalProjection) {
  Eigen::Matrix<double, 6, 1> c;
  c << 0.5, 0.2, -0.4, 0.1, 0.05, 0.0;
  const LocalQuadric q(Eigen::Vector3d::Zero(), Eigen::Matrix3d::Identity(), c, 1.0, true);
  for (const Eigen::Vector3d& x : {Eigen::Vector3d(0.2, 0.1, 0.3), Eigen::Vector3d(-0.3, 0.4, -0.2)}) {
    const SurfacePoint s = q.FootPoint(x);
    const Eigen::Vector3d l = s.point;
    EXPECT_NEAR(l.z(), q.Height(l.x(), l.y()), 1e-15);
    EXPECT_NEAR((x - s.point).cross(s.normal).norm(), 0.0, 1e-13);
  }
}

TEST(LocalQuadric, SdmMatrixIsTheSecondOrderSquaredDistanceOfASphere) {
  // Outside a sphere the normal towards x points away from the centre, kappa = -1/R, and the tangential
  // weight is delta/(delta + R) (Pottmann & Hofer 2003); between the sphere and its centre it is clamped to
  // 0.
  const Eigen::Vector3d centre(0.1, 0.2, 0.3);
  const double R = 1.5;
  const Eigen::Matrix3Xd p = SpherePoints(centre, R, 4000);
  const NearestIndex index(p);
  const Eigen::Vector3d dir = Eigen::Vector3d(1, 1, 1).normalized();
  for (const double delta : {0.3, -0.3}) {
    const Eigen::Vector3d x = centre + (R + delta) * dir;
    // The exact sphere geometry at the foot point (to check the formula, not the estimate).
    SurfacePoint exact;
    exact.point = centre + R * dir;
    exact.normal = dir;
    exact.direction1 = dir.unitOrthogonal();
    exact.direction2 = dir.cross(exact.direction1);
    exact.kappa1 = exact.kappa2 = -1.0 / R;
    const Eigen::Matrix3d m = SdmErrorMatrix(exact, x);
    const double beta = delta > 0 ? delta / (delta + R) : 0.0;
    const Eigen::Matrix3d expected =
        beta * (Eigen::Matrix3d::Identity() - dir * dir.transpose()) + dir * dir.transpose();
    EXPECT_NEAR((m - expected).norm(), 0.0, 1e-14);
    // The same from estimated geometry, as the registration builds it: a quadric over the neighbours of the
    // nearest sample and x's foot point on it. The curvature error (at most the truncation bound) moves the
    // weight by |d beta / d kappa| = |delta| / (delta kappa - 1)^2 per tangential direction.
    const std::vector<Eigen::Index> nn = index.KNearest(p.col(index.Nearest(x)), 30);
    Eigen::Matrix3Xd hood(3, 30);
    for (int j = 0; j < 30; ++j) hood.col(j) = p.col(nn[static_cast<std::size_t>(j)]);
    const LocalQuadric q = LocalQuadric::Fit(hood, hood.col(0));
    const double sensitivity = delta > 0 ? delta / std::pow(-delta / R - 1.0, 2) : 0.0;
    EXPECT_NEAR(
        (SdmErrorMatrix(q.FootPoint(x), x) - expected).norm(), 0.0,
        std::sqrt(2.0) * sensitivity * TruncationBound(q.radius(), R) + TruncationBound(q.radius(), R));
    if (delta > 0) {
      // Second-order agreement with the exact squared distance for small displacements (error O(h^3)).
      for (const double h : {1e-2, 1e-3}) {
        const Eigen::Vector3d y = x + h * Eigen::Vector3d(0.3, -0.8, 0.5).normalized();
        const double exact_sq = std::pow((y - centre).norm() - R, 2);
        const double approx = (y - exact.point).dot(m * (y - exact.point));
        EXPECT_LT(std::abs(approx - exact_sq), 10 * h * h * h) << h;
      }
    }
  }
}

TEST(LocalQuadric, DegenerateAndBadInput) {
  Eigen::Matrix3Xd line(3, 10);
  for (int i = 0; i < 10; ++i) line.col(i) << 0.1 * i, 0.05 * i, 0.0;
  const LocalQuadric q = LocalQuadric::Fit(line, line.col(3));
  EXPECT_FALSE(q.quadratic());
  EXPECT_EQ(q.At(0, 0).kappa1, 0.0);
  EXPECT_EQ(q.At(0, 0).kappa2, 0.0);
  EXPECT_THROW(LocalQuadric::Fit(line.leftCols(5), line.col(0)), std::invalid_argument);
  Eigen::Matrix3Xd bad = SpherePoints(Eigen::Vector3d::Zero(), 1.0, 50);
  bad(1, 7) = std::nan("");
  EXPECT_THROW(LocalQuadric::Fit(bad, Eigen::Vector3d::Zero()), std::invalid_argument);
  EXPECT_THROW(EstimatePrincipalCurvatures(bad, 10), std::invalid_argument);
  EXPECT_THROW(EstimatePrincipalCurvatures(SpherePoints(Eigen::Vector3d::Zero(), 1.0, 50), 5),
               std::invalid_argument);
  EXPECT_THROW(EstimatePrincipalCurvatures(SpherePoints(Eigen::Vector3d::Zero(), 1.0, 8), 10),
               std::invalid_argument);
}

}  // namespace
}  // namespace s2m
