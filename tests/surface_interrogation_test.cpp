// Surface interrogation (fitting/surface_interrogation.h) against closed forms: the curvatures of a torus and
// a sphere, isophotes on a sphere, Klass reflection lines on a plane and their kink across a G1 (not G2)
// join.

#include "fitting/surface_interrogation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <string>

#include "fitting/kinematic_surfaces.h"
#include "fitting/primitive_models.h"

namespace s2m {
namespace {

SurfacePointCurvature At(const ParametricModel& model, double u, double v) {
  LocalGeometry g;
  model.Evaluate({u, v, 0.0}, 2, g);
  return InterrogateSurfacePoint(g);
}

TEST(SurfaceInterrogation, TorusCurvaturesMatchClosedForms) {
  const double major = 3.0, minor = 0.8;
  Torus torus;
  torus.center = Eigen::Vector3d(0.3, -1.0, 2.0);
  torus.axis = Eigen::Vector3d(1.0, 2.0, 2.0).normalized();
  torus.major_radius = major;
  torus.minor_radius = minor;
  const TorusModel model(torus);
  int positive = 0, negative = 0;
  for (int i = 0; i < 7; ++i) {
    for (int j = 0; j < 13; ++j) {
      const double u = 0.4 + 2 * M_PI * i / 7, v = 0.1 + 2 * M_PI * j / 13;
      const SurfacePointCurvature c = At(model, u, v);
      ASSERT_TRUE(c.regular);
      // The parametrization's normal w_u x w_v points away from the tube's core circle: both circles of
      // curvature (the tube's, and the parallel's seen along the normal) have Fang's sign of cos v.
      const double w = major + minor * std::cos(v);
      const double k = std::cos(v) / (minor * w), h = (major + 2 * minor * std::cos(v)) / (2 * minor * w);
      const double k1 = 1.0 / minor, k2 = std::cos(v) / w;
      EXPECT_NEAR(c.gaussian, k, 1e-9 * std::abs(k)) << "u " << u << " v " << v;
      EXPECT_NEAR(c.mean, h, 1e-9 * std::abs(h)) << "u " << u << " v " << v;
      EXPECT_NEAR(c.kmax, std::max(k1, k2), 1e-9 * std::max(k1, std::abs(k2)));
      EXPECT_NEAR(c.kmin, std::min(k1, k2), 1e-9 * std::max(k1, std::abs(k2)));
      EXPECT_NEAR(c.absolute, std::abs(k1) + std::abs(k2), 1e-9 * (k1 + std::abs(k2)));
      // The principal direction of 1/minor is the tube's circle (w_v), the other the parallel (w_u).
      LocalGeometry g;
      model.Evaluate({u, v, 0.0}, 1, g);
      const Eigen::Vector3d along_tube = g.d1.col(1).normalized();
      const Eigen::Vector3d tube_direction = k1 >= k2 ? c.direction_max : c.direction_min;
      EXPECT_NEAR(std::abs(tube_direction.dot(along_tube)), 1.0, 1e-12);
      (c.gaussian > 0 ? positive : negative) += 1;
    }
  }
  // The sign regions: outer half (cos v > 0) elliptic, inner half hyperbolic.
  EXPECT_GT(positive, 0);
  EXPECT_GT(negative, 0);
}

TEST(SurfaceInterrogation, SphereIsUmbilic) {
  const double radius = 2.0;
  const SphereModel model(Sphere{Eigen::Vector3d(1, 2, 3), radius});
  for (const double v : {-1.2, 0.4, 1.5}) {
    const SurfacePointCurvature c = At(model, 0.7, v);
    ASSERT_TRUE(c.regular);
    EXPECT_NEAR(c.gaussian, 1 / (radius * radius), 1e-14);
    EXPECT_NEAR(c.mean, 1 / radius, 1e-14);  // outward n: the centre is on the other side
    EXPECT_NEAR(c.kmax, 1 / radius, 1e-14);
    EXPECT_NEAR(c.kmin, 1 / radius, 1e-14);
  }
}

TEST(SurfaceInterrogation, SingularPointsAreReportedNotComputed) {
  // A dome: the generatrix starts on the axis (r = 0 at u = 0), where w_v = 0.
  Eigen::Matrix2Xd profile(2, 4);
  profile << 0.0, 1.0, 2.0, 2.0, 3.0, 3.0, 2.0, 0.0;
  const KinematicSurface dome =
      KinematicSurface::Revolution(BSplineBasis::Clamped(4, {0, 0, 0, 0, 1, 1, 1, 1}), profile);
  const SurfacePointCurvature apex = At(dome, 0.0, 0.3);
  EXPECT_FALSE(apex.regular);
  EXPECT_TRUE(std::isnan(apex.gaussian));
  EXPECT_TRUE(std::isnan(apex.normal.x()));
  EXPECT_NEAR((apex.point - Eigen::Vector3d(0, 0, 3)).norm(), 0.0, 1e-15);
  EXPECT_TRUE(At(dome, 0.5, 0.3).regular);
  // Parallel derivatives.
  Eigen::Matrix<double, 3, 2> d1;
  d1 << 1, 2, 0, 0, 0, 0;
  EXPECT_FALSE(InterrogateSurfacePoint(Eigen::Vector3d::Zero(), d1, Eigen::Matrix3d::Identity()).regular);
}

TEST(SurfaceInterrogation, IsophotesOnASphereAreCirclesOfAngularRadiusAcosC) {
  const Eigen::Vector3d centre(1, 2, 3);
  const double radius = 2.0;
  const SphereModel model(Sphere{centre, radius});
  const Eigen::Vector3d light = Eigen::Vector3d(1.0, -2.0, 3.0).normalized();
  for (const double level : {-0.6, 0.0, 0.3, 0.8}) {
    // Along every meridian (u fixed), the crossing of N.L = c found by bisection on v; its point must lie at
    // angle acos(c) from L as seen from the centre.
    int found = 0;
    for (int i = 0; i < 24; ++i) {
      const double u = 2 * M_PI * i / 24;
      std::function<double(double)> f = [&](double v) {
        return IsophoteValue(At(model, u, v).normal, light) - level;
      };
      const int steps = 64;
      for (int k = 0; k < steps; ++k) {
        double lo = -M_PI / 2 + 1e-6 + (M_PI - 2e-6) * k / steps;
        double hi = -M_PI / 2 + 1e-6 + (M_PI - 2e-6) * (k + 1) / steps;
        if (f(lo) * f(hi) > 0) continue;
        for (int it = 0; it < 80; ++it) {
          const double mid = 0.5 * (lo + hi);
          (f(lo) * f(mid) <= 0 ? hi : lo) = mid;
        }
        LocalGeometry g;
        model.Evaluate({u, 0.5 * (lo + hi), 0.0}, 0, g);
        const Eigen::Vector3d radial = (To3(g.point) - centre).normalized();
        EXPECT_NEAR(std::acos(std::clamp(radial.dot(light), -1.0, 1.0)), std::acos(level), 1e-9)
            << "level " << level << " u " << u;
        ++found;
      }
    }
    EXPECT_GE(found, 24) << "level " << level;  // every meridian's great circle crosses every isophote
  }
}

TEST(SurfaceInterrogation, RevolvedLineIsACylinder) {
  // A surface of revolution whose generatrix is the segment r = 1.5 (a cylinder): K = 0, kmax = 1 / 1.5.
  Eigen::Matrix2Xd profile(2, 4);
  profile << 1.5, 1.5, 1.5, 1.5, 0.0, 1.0, 2.0, 3.0;
  const KinematicSurface cylinder =
      KinematicSurface::Revolution(BSplineBasis::Clamped(4, {0, 0, 0, 0, 1, 1, 1, 1}), profile);
  const SurfacePointCurvature c = At(cylinder, 0.37, 1.1);
  ASSERT_TRUE(c.regular);
  EXPECT_NEAR(c.gaussian, 0.0, 1e-14);
  EXPECT_NEAR(std::abs(c.mean), 0.5 / 1.5, 1e-14);
  EXPECT_NEAR(c.absolute, 1 / 1.5, 1e-14);
}

// A height field z = f(x) over the (x, y) plane, with exact derivatives.
struct Profile {
  std::function<double(double)> f, df, ddf;
};

void Evaluate(const Profile& p, double x, double y, Eigen::Vector3d& point, Eigen::Vector3d& normal) {
  point = Eigen::Vector3d(x, y, p.f(x));
  Eigen::Matrix<double, 3, 2> d1;
  d1 << 1, 0, 0, 1, p.df(x), 0;
  Eigen::Matrix3d d2 = Eigen::Matrix3d::Zero();
  d2(2, 0) = p.ddf(x);
  normal = InterrogateSurfacePoint(point, d1, d2).normal;
}

double Offset(const LightPlane& light, const Profile& p, double x, double y) {
  Eigen::Vector3d point, normal;
  Evaluate(p, x, y, point, normal);
  const ReflectionHit h = ReflectionLineParameter(light, point, normal);
  EXPECT_TRUE(h.hit);
  return h.offset;
}

// The y where the reflection line of offset `level` crosses x (secant iterations; the offset is monotone in y
// in this set-up).
double TraceY(const LightPlane& light, const Profile& p, double x, double level, double y0) {
  double a = y0 - 0.1, b = y0 + 0.1;
  double fa = Offset(light, p, x, a) - level, fb = Offset(light, p, x, b) - level;
  for (int it = 0; it < 60 && fb != fa && std::abs(fb) > 0; ++it) {
    const double c = b - fb * (b - a) / (fb - fa);
    a = b;
    fa = fb;
    b = c;
    fb = Offset(light, p, x, b) - level;
  }
  return b;
}

// The angle between the reflection line's one-sided tangents at x = 0, the join of the plane z = 0 (x <= 0)
// and `right` (x > 0), measured on the traced line (second-order one-sided differences, step h), and the one
// predicted from the one-sided gradients of the offset c(x, y): dy/dx = -c_x / c_y with c_x from each side's
// own formula continued across the join (central differences).
struct Kink {
  double measured = 0.0, predicted = 0.0;
};
Kink KinkAtJoin(const Profile& right) {
  const Profile plane{[](double) { return 0.0; }, [](double) { return 0.0; }, [](double) { return 0.0; }};
  const Profile joined{[&](double x) { return x <= 0 ? 0.0 : right.f(x); },
                       [&](double x) { return x <= 0 ? 0.0 : right.df(x); },
                       [&](double x) { return x <= 0 ? 0.0 : right.ddf(x); }};
  LightPlane light;
  light.origin = Eigen::Vector3d(0, 0, 3);
  light.direction = Eigen::Vector3d::UnitX();
  light.across = Eigen::Vector3d::UnitY();
  light.eye = Eigen::Vector3d(-0.5, -2.0, 2.0);
  const double y0 = 0.3, level = Offset(light, joined, 0.0, y0), h = 2.5e-4;
  auto slope = [&](double sign) {
    const double y1 = TraceY(light, joined, sign * h, level, y0),
                 y2 = TraceY(light, joined, sign * 2 * h, level, y0);
    return sign * (4 * y1 - y2 - 3 * y0) / (2 * h);
  };
  auto predicted_slope = [&](const Profile& side) {
    const double cx = (Offset(light, side, h, y0) - Offset(light, side, -h, y0)) / (2 * h);
    const double cy = (Offset(light, side, 0, y0 + h) - Offset(light, side, 0, y0 - h)) / (2 * h);
    return -cx / cy;
  };
  // Both sides have slope f'(0) = 0 at the join: the tangents are (1, dy/dx, 0).
  return {std::abs(std::atan(slope(1)) - std::atan(slope(-1))),
          std::abs(std::atan(predicted_slope(right)) - std::atan(predicted_slope(plane)))};
}

TEST(SurfaceInterrogation, ReflectionLinesOfAPlaneAreWhereTheMirroredEyeRaysMeetTheLights) {
  // Plane z = 0, lights in z = 3 along x, offsets along y, eye at height 2: the mirror image of light c is
  // the line (t, c, -3); the plane through it and the eye meets z = 0 where y = a_y + (c - a_y) a_z / (a_z +
  // 3).
  LightPlane light;
  light.origin = Eigen::Vector3d(0, 0, 3);
  light.eye = Eigen::Vector3d(-0.5, -2.0, 2.0);
  ASSERT_TRUE(light.IsValid(nullptr));
  for (const double y : {-1.0, 0.0, 0.4, 2.5}) {
    const ReflectionHit hit =
        ReflectionLineParameter(light, Eigen::Vector3d(0.7, y, 0), Eigen::Vector3d::UnitZ());
    ASSERT_TRUE(hit.hit);
    EXPECT_NEAR(hit.offset, -2.0 + (y + 2.0) * 5.0 / 2.0, 1e-13);
    // Either orientation of the normal mirrors the same ray.
    EXPECT_NEAR(ReflectionLineParameter(light, Eigen::Vector3d(0.7, y, 0), -Eigen::Vector3d::UnitZ()).offset,
                hit.offset, 1e-13);
  }
  // A point above the lights, seen from above: its reflected ray leaves the plane behind.
  light.eye = Eigen::Vector3d(0, 0, 5);
  EXPECT_FALSE(ReflectionLineParameter(light, Eigen::Vector3d(0, 0, 4), Eigen::Vector3d::UnitZ()).hit);
  std::string why;
  light.across = Eigen::Vector3d(1, 1, 0);
  EXPECT_FALSE(light.IsValid(&why));
  EXPECT_FALSE(why.empty());
}

TEST(SurfaceInterrogation, ReflectionLinesKinkAcrossAG1JoinButNotAcrossAG2Join) {
  // G1 only: the plane joined to a cylinder of radius 1 (curvature jumps from 0 to 1).
  const Kink g1 = KinkAtJoin({[](double x) { return 1.0 - std::sqrt(1.0 - x * x); },
                              [](double x) { return x / std::sqrt(1.0 - x * x); },
                              [](double x) { return std::pow(1.0 - x * x, -1.5); }});
  // G2: the plane joined to the cubic z = x^3 / 3 (curvature 0 at the join on both sides).
  const Kink g2 = KinkAtJoin({[](double x) { return x * x * x / 3; }, [](double x) { return x * x; },
                              [](double x) { return 2 * x; }});
  std::cout << "reflection line tangent jump: G1 join " << g1.measured << " rad (predicted " << g1.predicted
            << "), G2 join " << g2.measured << " rad (predicted " << g2.predicted << ")\n";
  // The differences are second order in h = 2.5e-4: errors ~6e-8 times the line's third derivatives.
  EXPECT_NEAR(g1.measured, g1.predicted, 1e-5);
  EXPECT_GT(g1.predicted, 100 * 1e-5);  // a kink well above the measurement's resolution
  EXPECT_NEAR(g2.predicted, 0.0, 1e-5);
  EXPECT_NEAR(g2.measured, 0.0, 1e-5);
}

TEST(SurfaceInterrogation, ZebraStripesAndContours) {
  EXPECT_EQ(ZebraStripe(0.2, 1.0), 0);
  EXPECT_EQ(ZebraStripe(1.2, 1.0), 1);
  EXPECT_EQ(ZebraStripe(-0.2, 1.0), 1);
  EXPECT_EQ(ZebraStripe(-1.2, 1.0), 0);
  EXPECT_DOUBLE_EQ(
      ContourHeight(Eigen::Vector3d(1, 2, 5), Eigen::Vector3d(0, 0, 1), Eigen::Vector3d::UnitZ()), 4.0);
  CurvatureKind kind;
  EXPECT_TRUE(ParseCurvatureKind("mean", kind));
  EXPECT_EQ(kind, CurvatureKind::kMean);
  EXPECT_FALSE(ParseCurvatureKind("gauss", kind));
}

}  // namespace
}  // namespace s2m
