// Chebyshev (minimum-zone) fits and the inscribed / circumscribed features (fitting/minimum_zone.h,
// docs/metrology.md sections 2-3), against independent solutions:
// - exhaustive ones on small point sets, from the characterizations of the optima: the thinnest slab is
//   fixed by a face-vertex or edge-edge pair (planes through 3 points, or parallel to 2 point pairs); the
//   minimum-zone circle by 4 points (3 on one circle and 1 on the other, or 2 and 2: circumcentres of
//   triples, crossings of two perpendicular bisectors); the minimum circumscribed circle by 2 or 3 points;
//   the maximum inscribed circle by 3 (an empty circumcircle centred inside the hull);
// - for cylinders and lines, the minimum over axis directions (a local search) of the exhaustive planar
//   solution of the points projected across the axis (a cylinder's zone seen along its axis is an annulus,
//   a line's a disc);
// - for spheres and cones, many local searches (Nelder-Mead on the exact criterion) from perturbed starts:
//   none may find a smaller zone;
// and on a cylinder with a constructed lobing form error (the cylindricity is twice the lobes' amplitude).

#include "fitting/minimum_zone.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <random>
#include <vector>

#include "fitting/primitive_compare.h"
#include "fitting/primitive_fit.h"

namespace s2m {
namespace {

Eigen::Vector3d RandomUnit(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
}

// ---- Exhaustive planar solutions

double Width(const Eigen::Matrix3Xd& p, const Eigen::Vector3d& normal) {
  const Eigen::VectorXd h = (normal.normalized().transpose() * p).transpose();
  return h.maxCoeff() - h.minCoeff();
}

// The global minimum width of a slab enclosing the points.
double ExhaustiveFlatness(const Eigen::Matrix3Xd& p) {
  const int n = static_cast<int>(p.cols());
  double best = std::numeric_limits<double>::infinity();
  auto consider = [&](const Eigen::Vector3d& normal) {
    if (normal.norm() > 1e-12) best = std::min(best, Width(p, normal));
  };
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j)
      for (int k = j + 1; k < n; ++k) consider((p.col(j) - p.col(i)).cross(p.col(k) - p.col(i)));
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j)
      for (int k = 0; k < n; ++k)
        for (int l = k + 1; l < n; ++l)
          if (k != i && k != j && l != i && l != j)
            consider((p.col(j) - p.col(i)).cross(p.col(l) - p.col(k)));
  return best;
}

bool Circumcentre(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c,
                  Eigen::Vector2d& centre) {
  Eigen::Matrix2d m;
  m.row(0) = (b - a).transpose();
  m.row(1) = (c - a).transpose();
  if (std::abs(m.determinant()) < 1e-14 * (b - a).squaredNorm() * (c - a).squaredNorm()) return false;
  centre = m.partialPivLu().solve(
      Eigen::Vector2d(0.5 * (b.squaredNorm() - a.squaredNorm()), 0.5 * (c.squaredNorm() - a.squaredNorm())));
  return true;
}

// Crossing of the perpendicular bisectors of (a, b) and (c, d).
bool BisectorCrossing(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c,
                      const Eigen::Vector2d& d, Eigen::Vector2d& centre) {
  Eigen::Matrix2d m;
  m.row(0) = (b - a).transpose();
  m.row(1) = (d - c).transpose();
  if (std::abs(m.determinant()) < 1e-14 * (b - a).squaredNorm() * (d - c).squaredNorm()) return false;
  centre = m.partialPivLu().solve(
      Eigen::Vector2d(0.5 * (b.squaredNorm() - a.squaredNorm()), 0.5 * (d.squaredNorm() - c.squaredNorm())));
  return true;
}

struct Annulus {
  double width = std::numeric_limits<double>::infinity();
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
};

Eigen::VectorXd Radii(const Eigen::Matrix2Xd& q, const Eigen::Vector2d& c) {
  return (q.colwise() - c).colwise().norm().transpose();
}

// The global minimum-zone annulus (roundness) of planar points.
Annulus ExhaustiveRoundness(const Eigen::Matrix2Xd& q) {
  const int n = static_cast<int>(q.cols());
  Annulus best;
  auto consider = [&](const Eigen::Vector2d& c) {
    const Eigen::VectorXd r = Radii(q, c);
    const double w = r.maxCoeff() - r.minCoeff();
    if (w < best.width) best = {w, c};
  };
  Eigen::Vector2d c;
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j) {
      for (int k = j + 1; k < n; ++k)
        if (Circumcentre(q.col(i), q.col(j), q.col(k), c)) consider(c);
      for (int k = 0; k < n; ++k)
        for (int l = k + 1; l < n; ++l)
          if (k != i && k != j && l != i && l != j &&
              BisectorCrossing(q.col(i), q.col(j), q.col(k), q.col(l), c))
            consider(c);
    }
  return best;
}

// The minimum circumscribed circle's radius.
double ExhaustiveCircumscribed(const Eigen::Matrix2Xd& q) {
  const int n = static_cast<int>(q.cols());
  double best = std::numeric_limits<double>::infinity();
  Eigen::Vector2d c;
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j) {
      best = std::min(best, Radii(q, 0.5 * (q.col(i) + q.col(j))).maxCoeff());
      for (int k = j + 1; k < n; ++k)
        if (Circumcentre(q.col(i), q.col(j), q.col(k), c)) best = std::min(best, Radii(q, c).maxCoeff());
    }
  return best;
}

// Whether c lies inside the convex hull of q (Andrew's monotone chain, then the half-planes of its edges).
bool InsideHull(const Eigen::Matrix2Xd& q, const Eigen::Vector2d& c) {
  std::vector<Eigen::Vector2d> pts;
  for (Eigen::Index i = 0; i < q.cols(); ++i) pts.push_back(q.col(i));
  std::sort(pts.begin(), pts.end(),
            [](const auto& a, const auto& b) { return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y()); });
  auto cross = [](const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return (a - o).x() * (b - o).y() - (a - o).y() * (b - o).x();
  };
  std::vector<Eigen::Vector2d> hull(2 * pts.size());
  std::size_t k = 0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], pts[i]) <= 0) --k;
    hull[k++] = pts[i];
  }
  for (std::size_t i = pts.size() - 1, t = k + 1; i > 0; --i) {
    while (k >= t && cross(hull[k - 2], hull[k - 1], pts[i - 1]) <= 0) --k;
    hull[k++] = pts[i - 1];
  }
  hull.resize(k - 1);
  for (std::size_t i = 0; i < hull.size(); ++i)
    if (cross(hull[i], hull[(i + 1) % hull.size()], c) < 0) return false;
  return true;
}

// The maximum inscribed circle's radius: the largest empty circumcircle centred inside the hull.
double ExhaustiveInscribed(const Eigen::Matrix2Xd& q) {
  const int n = static_cast<int>(q.cols());
  double best = 0.0;
  Eigen::Vector2d c;
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j)
      for (int k = j + 1; k < n; ++k)
        if (Circumcentre(q.col(i), q.col(j), q.col(k), c) && InsideHull(q, c))
          best = std::max(best, Radii(q, c).minCoeff());
  return best;
}

// ---- A derivative-free local search (Nelder-Mead) for the non-smooth criteria

double NelderMead(const std::function<double(const Eigen::VectorXd&)>& f, Eigen::VectorXd x, double step,
                  int iterations = 3000) {
  const Eigen::Index n = x.size();
  std::vector<Eigen::VectorXd> s(static_cast<std::size_t>(n + 1), x);
  std::vector<double> v(static_cast<std::size_t>(n + 1));
  for (Eigen::Index k = 0; k < n; ++k) s[static_cast<std::size_t>(k + 1)][k] += step;
  for (std::size_t i = 0; i < s.size(); ++i) v[i] = f(s[i]);
  for (int it = 0; it < iterations; ++it) {
    std::vector<std::size_t> order(s.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return v[a] < v[b]; });
    std::vector<Eigen::VectorXd> s2;
    std::vector<double> v2;
    for (std::size_t i : order) {
      s2.push_back(s[i]);
      v2.push_back(v[i]);
    }
    s = s2;
    v = v2;
    Eigen::VectorXd centroid = Eigen::VectorXd::Zero(n);
    for (std::size_t i = 0; i + 1 < s.size(); ++i) centroid += s[i] / static_cast<double>(n);
    const Eigen::VectorXd reflected = centroid + (centroid - s.back());
    const double fr = f(reflected);
    if (fr < v.front()) {
      const Eigen::VectorXd expanded = centroid + 2.0 * (centroid - s.back());
      const double fe = f(expanded);
      s.back() = fe < fr ? expanded : reflected;
      v.back() = std::min(fe, fr);
    } else if (fr < v[v.size() - 2]) {
      s.back() = reflected;
      v.back() = fr;
    } else {
      const Eigen::VectorXd contracted = centroid + 0.5 * (s.back() - centroid);
      const double fc = f(contracted);
      if (fc < v.back()) {
        s.back() = contracted;
        v.back() = fc;
      } else {
        for (std::size_t i = 1; i < s.size(); ++i) {
          s[i] = s[0] + 0.5 * (s[i] - s[0]);
          v[i] = f(s[i]);
        }
      }
    }
  }
  return *std::min_element(v.begin(), v.end());
}

// Unit direction from two angles about a base direction's frame.
Eigen::Vector3d Tilted(const Eigen::Matrix3d& frame, double a, double b) {
  return (frame.col(2) + a * frame.col(0) + b * frame.col(1)).normalized();
}

Eigen::Matrix2Xd Across(const Eigen::Matrix3Xd& p, const Eigen::Vector3d& axis) {
  return FrameWithAxis(axis).leftCols<2>().transpose() * p;
}

template <class Shape>
void ExpectContainsEveryPoint(const ChebyshevFit<Shape>& fit, const Eigen::Matrix3Xd& p, double scale) {
  const ChebyshevFit<Shape> about = ZoneAbout(p, fit.shape);
  EXPECT_NEAR(about.zone_width, fit.zone_width, 1e-12 * scale);
  EXPECT_NEAR(about.max_distance, fit.max_distance, 1e-12 * scale);
  EXPECT_NEAR(about.min_distance, fit.min_distance, 1e-12 * scale);
}

// ---- Tests

TEST(MinimumZone, FlatnessEqualsTheExhaustiveMinimumWidth) {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 40; ++trial) {
    const int n = 6 + trial % 6;
    const Eigen::Vector3d normal = RandomUnit(rng);
    const Eigen::Matrix3d f = FrameWithAxis(normal);
    Eigen::Matrix3Xd p(3, n);
    for (int i = 0; i < n; ++i)
      p.col(i) =
          Eigen::Vector3d(3, -2, 5) + 10 * u(rng) * f.col(0) + 10 * u(rng) * f.col(1) + 0.1 * u(rng) * normal;
    const auto lsq = FitPlane(p);
    const auto zone = MinimumZoneFit(p, lsq.shape);
    ASSERT_TRUE(zone.converged) << zone.stop_reason;
    const double exhaustive = ExhaustiveFlatness(p);
    EXPECT_NEAR(zone.zone_width, exhaustive, 1e-12 * 10) << "trial " << trial;
    EXPECT_LE(zone.zone_width, ZoneAbout(p, lsq.shape).zone_width + 1e-13);
    ExpectContainsEveryPoint(zone, p, 10.0);
    // 3 parameters plus the width: 4 contacts (face-vertex or edge-edge).
    EXPECT_GE(zone.contacts.size(), 4u) << "trial " << trial;
    for (const ZoneContact& c : zone.contacts)
      EXPECT_NEAR(std::abs(c.distance), 0.5 * zone.zone_width, 1e-12 * 10);
  }
}

// Planar points near a circle of radius 5 in a tilted plane, with a random radial form error.
Eigen::Matrix3Xd RoughCircle(std::mt19937_64& rng, int n, double form, const Circle3d& c) {
  std::uniform_real_distribution<double> u(-1.0, 1.0), angle(0, 2 * M_PI);
  const Eigen::Matrix3d f = FrameWithAxis(c.normal);
  Eigen::Matrix3Xd p(3, n);
  for (int i = 0; i < n; ++i) {
    const double a = 2 * M_PI * i / n + 0.3 * u(rng);
    const double r = c.radius + form * u(rng);
    p.col(i) = c.center + r * (std::cos(a) * f.col(0) + std::sin(a) * f.col(1));
  }
  return p;
}

TEST(MinimumZone, RoundnessAndTheCircumscribedAndInscribedCirclesMatchExhaustiveSolutions) {
  std::mt19937_64 rng(2);
  for (int trial = 0; trial < 30; ++trial) {
    const Circle3d truth{Eigen::Vector3d(1, 2, 3) + RandomUnit(rng), RandomUnit(rng), 5.0};
    const Eigen::Matrix3Xd p = RoughCircle(rng, 8 + trial % 8, 0.2, truth);
    const auto lsq = FitCircle(p);
    const Eigen::Matrix2Xd q = Across(p, lsq.shape.normal);
    const auto round = MinimumZoneFit(p, lsq.shape);
    const auto outer = CircumscribedFit(p, lsq.shape);
    const auto inner = InscribedFit(p, lsq.shape);
    ASSERT_TRUE(round.converged && outer.converged && inner.converged) << trial;
    EXPECT_NEAR(round.zone_width, ExhaustiveRoundness(q).width, 1e-11) << "trial " << trial;
    EXPECT_NEAR(outer.shape.radius, ExhaustiveCircumscribed(q), 1e-11) << "trial " << trial;
    EXPECT_NEAR(inner.shape.radius, ExhaustiveInscribed(q), 1e-11) << "trial " << trial;
    ExpectContainsEveryPoint(round, p, 5.0);
    EXPECT_NEAR(outer.max_distance, 0.0, 1e-12);  // every point inside, one on it
    EXPECT_NEAR(inner.min_distance, 0.0, 1e-12);  // every point outside, one on it
    EXPECT_LE(inner.shape.radius, lsq.shape.radius);
    EXPECT_LE(lsq.shape.radius, outer.shape.radius);
    EXPECT_LE(round.zone_width, ZoneAbout(p, lsq.shape).zone_width + 1e-13);
  }
}

TEST(MinimumZone, CylindricityEqualsTheBestAnnulusOverAxisDirections) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 6; ++trial) {
    const Cylinder truth{Eigen::Vector3d(1, -2, 0.5), RandomUnit(rng), 4.0};
    const Eigen::Matrix3d f = FrameWithAxis(truth.axis_direction);
    const int n = 14;
    Eigen::Matrix3Xd p(3, n);
    for (int i = 0; i < n; ++i) {
      const double a = 2 * M_PI * i / 7 + 0.2 * u(rng), r = truth.radius + 0.1 * u(rng);
      p.col(i) = truth.axis_point + 5 * u(rng) * truth.axis_direction +
                 r * (std::cos(a) * f.col(0) + std::sin(a) * f.col(1));
    }
    const auto lsq = FitCylinder(p);
    const auto zone = MinimumZoneFit(p, lsq.shape);
    ASSERT_TRUE(zone.converged) << zone.stop_reason;
    ExpectContainsEveryPoint(zone, p, 5.0);
    // Independent: the exhaustive annulus of the points seen along a direction, minimized over directions.
    const Eigen::Matrix3d g = FrameWithAxis(lsq.shape.axis_direction);
    auto annulus = [&](const Eigen::VectorXd& ab) {
      return ExhaustiveRoundness(Across(p, Tilted(g, ab[0], ab[1]))).width;
    };
    const double searched = NelderMead(annulus, Eigen::Vector2d::Zero(), 0.02, 300);
    // Along our own axis the exhaustive annulus is our zone (the median cylinder's axis is the annulus's
    // centre line), and no direction the search found does better.
    EXPECT_NEAR(ExhaustiveRoundness(Across(p, zone.shape.axis_direction)).width, zone.zone_width, 1e-10);
    EXPECT_LE(zone.zone_width, searched + 1e-10) << "trial " << trial;
    std::printf("cylindricity %.12f, searched %.12f, least-squares zone %.12f\n", zone.zone_width, searched,
                ZoneAbout(p, lsq.shape).zone_width);
  }
}

TEST(MinimumZone, StraightnessEqualsTheBestEnclosingDiscOverDirections) {
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 6; ++trial) {
    const Line3d truth{Eigen::Vector3d(3, 1, -2), RandomUnit(rng)};
    const Eigen::Matrix3d f = FrameWithAxis(truth.direction);
    Eigen::Matrix3Xd p(3, 12);
    for (int i = 0; i < 12; ++i)
      p.col(i) =
          truth.point + 10 * u(rng) * truth.direction + 0.05 * u(rng) * f.col(0) + 0.05 * u(rng) * f.col(1);
    const auto lsq = FitLine(p);
    const auto zone = MinimumZoneFit(p, lsq.shape);
    ASSERT_TRUE(zone.converged) << zone.stop_reason;
    ExpectContainsEveryPoint(zone, p, 10.0);
    const Eigen::Matrix3d g = FrameWithAxis(lsq.shape.direction);
    auto disc = [&](const Eigen::VectorXd& ab) {
      return 2.0 * ExhaustiveCircumscribed(Across(p, Tilted(g, ab[0], ab[1])));
    };
    const double searched = NelderMead(disc, Eigen::Vector2d::Zero(), 0.002, 300);
    EXPECT_NEAR(2.0 * ExhaustiveCircumscribed(Across(p, zone.shape.direction)), zone.zone_width, 1e-11);
    EXPECT_LE(zone.zone_width, searched + 1e-11) << "trial " << trial;
    EXPECT_LE(zone.zone_width, ZoneAbout(p, lsq.shape).zone_width + 1e-13);
  }
}

// Spheres and cones: many local searches of the exact criterion from perturbed starts find no smaller zone.
TEST(MinimumZone, SphericityAndConicityAreNotImprovedByLocalSearches) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int trial = 0; trial < 4; ++trial) {
    const Sphere truth{Eigen::Vector3d(1, 2, 3), 6.0};
    Eigen::Matrix3Xd p(3, 20);
    for (int i = 0; i < 20; ++i) p.col(i) = truth.center + (truth.radius + 0.1 * u(rng)) * RandomUnit(rng);
    const auto zone = MinimumZoneFit(p, FitSphere(p).shape);
    ASSERT_TRUE(zone.converged);
    ExpectContainsEveryPoint(zone, p, 6.0);
    auto width = [&](const Eigen::VectorXd& c) {
      const Eigen::VectorXd r = (p.colwise() - Eigen::Vector3d(c)).colwise().norm().transpose();
      return r.maxCoeff() - r.minCoeff();
    };
    for (int start = 0; start < 10; ++start) {
      const Eigen::Vector3d c0 = zone.shape.center + 0.05 * Eigen::Vector3d(g(rng), g(rng), g(rng));
      EXPECT_GE(NelderMead(width, c0, 0.02), zone.zone_width - 1e-11) << "sphere trial " << trial;
    }
  }
  for (int trial = 0; trial < 3; ++trial) {
    const Cone truth{Eigen::Vector3d(0, 1, 2), RandomUnit(rng), 0.4, 3.0};
    const Eigen::Matrix3d f = FrameWithAxis(truth.axis_direction);
    Eigen::Matrix3Xd p(3, 24);
    for (int i = 0; i < 24; ++i) {
      const double z = 4 * u(rng), a = M_PI * u(rng);
      const double r = truth.radius + z * std::tan(truth.half_angle) + 0.05 * u(rng);
      p.col(i) =
          truth.axis_point + z * truth.axis_direction + r * (std::cos(a) * f.col(0) + std::sin(a) * f.col(1));
    }
    const auto lsq = FitCone(p);
    const auto zone = MinimumZoneFit(p, lsq.shape);
    ASSERT_TRUE(zone.converged) << zone.stop_reason;
    ExpectContainsEveryPoint(zone, p, 5.0);
    EXPECT_LE(zone.zone_width, ZoneAbout(p, lsq.shape).zone_width + 1e-13);
    // Cone parameters about the zone's: axis point across the axis (2), tilts (2), half angle; the width
    // does not depend on the size parameter.
    const Eigen::Matrix3d h = FrameWithAxis(zone.shape.axis_direction);
    auto width = [&](const Eigen::VectorXd& x) {
      Cone c = zone.shape;
      c.axis_point += x[0] * h.col(0) + x[1] * h.col(1);
      c.axis_direction = Tilted(h, x[2], x[3]);
      c.half_angle += x[4];
      const Eigen::VectorXd d = SignedDistances(c, p);
      return d.maxCoeff() - d.minCoeff();
    };
    for (int start = 0; start < 10; ++start) {
      Eigen::VectorXd x0(5);
      for (int k = 0; k < 5; ++k) x0[k] = 0.01 * g(rng);
      EXPECT_GE(NelderMead(width, x0, 0.01), zone.zone_width - 1e-11) << "cone trial " << trial;
    }
  }
}

// r(theta) = R + A cos(3 theta) at every z, sampled where the lobes peak and dip, with an uneven angular
// density so that least squares tilts and shifts its axis: the minimum zone is the true axis with width 2A
// exactly (the 6 extremes per section alternate, more than the 5 the zone needs), while the least-squares
// zone is wider.
TEST(MinimumZone, CylindricityOfALobedCylinderIsTheConstructedValue) {
  const Cylinder truth{Eigen::Vector3d(10, -5, 3), Eigen::Vector3d(0.3, -0.2, 1).normalized(), 25.0};
  const double amplitude = 0.015;
  const Eigen::Matrix3d f = FrameWithAxis(truth.axis_direction);
  std::vector<Eigen::Vector3d> pts;
  for (int level = 0; level < 5; ++level) {
    const double z = -20 + 10 * level;
    for (int i = 0; i < 72; ++i) {
      const double a = 2 * M_PI * i / 72;  // includes the peaks (multiples of 120 deg) and dips (+60 deg)
      // Uneven density: the first quadrant twice as dense as the rest, which pulls least squares across.
      if (a >= M_PI / 2 && i % 2 == 1) continue;
      const double r = truth.radius + amplitude * std::cos(3 * a);
      pts.push_back(truth.axis_point + z * truth.axis_direction +
                    r * (std::cos(a) * f.col(0) + std::sin(a) * f.col(1)));
    }
  }
  Eigen::Matrix3Xd p(3, static_cast<Eigen::Index>(pts.size()));
  for (std::size_t i = 0; i < pts.size(); ++i) p.col(static_cast<Eigen::Index>(i)) = pts[i];
  const auto lsq = FitCylinder(p);
  const auto zone = MinimumZoneFit(p, lsq.shape);
  ASSERT_TRUE(zone.converged) << zone.stop_reason;
  const double lsq_zone = ZoneAbout(p, lsq.shape).zone_width;
  std::printf(
      "lobed cylinder: cylindricity %.15f (constructed %.15f), least-squares zone %.15f, %d iterations\n",
      zone.zone_width, 2 * amplitude, lsq_zone, zone.iterations);
  // The floor: rounding of coordinates of size ~40 (ulp 7e-15) in distances of a fit to 1e-13 of the unit
  // box.
  EXPECT_NEAR(zone.zone_width, 2 * amplitude, 1e-11);
  EXPECT_GT(lsq_zone, 2 * amplitude + 1e-6) << "least squares should be off the true axis here";
  EXPECT_NEAR(zone.shape.radius, truth.radius, 1e-11);
  EXPECT_LT(LineAngle(zone.shape.axis_direction, truth.axis_direction), 1e-12);
}

TEST(MinimumZone, InscribedAndCircumscribedCylindersBracketLeastSquares) {
  std::mt19937_64 rng(6);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Cylinder truth{Eigen::Vector3d(1, 1, 1), RandomUnit(rng), 3.0};
  const Eigen::Matrix3d f = FrameWithAxis(truth.axis_direction);
  Eigen::Matrix3Xd p(3, 400);
  for (int i = 0; i < 400; ++i) {
    const double a = M_PI * u(rng), r = truth.radius + noise(rng);
    p.col(i) = truth.axis_point + 4 * u(rng) * truth.axis_direction +
               r * (std::cos(a) * f.col(0) + std::sin(a) * f.col(1));
  }
  const auto lsq = FitCylinder(p);
  const auto inner = InscribedFit(p, lsq.shape);
  const auto outer = CircumscribedFit(p, lsq.shape);
  ASSERT_TRUE(inner.converged && outer.converged);
  EXPECT_LE(inner.shape.radius, lsq.shape.radius);
  EXPECT_LE(lsq.shape.radius, outer.shape.radius);
  EXPECT_GE(inner.min_distance, -1e-12);
  EXPECT_LE(outer.max_distance, 1e-12);
  const auto sphere_points = [&] {
    Eigen::Matrix3Xd s(3, 300);
    for (int i = 0; i < 300; ++i) s.col(i) = (2.0 + noise(rng)) * RandomUnit(rng);
    return s;
  }();
  const auto ls = FitSphere(sphere_points);
  EXPECT_LE(InscribedFit(sphere_points, ls.shape).shape.radius, ls.shape.radius);
  EXPECT_GE(CircumscribedFit(sphere_points, ls.shape).shape.radius, ls.shape.radius);
}

TEST(MinimumZone, DegenerateInputGivesClearErrors) {
  auto message = [](auto&& f) {
    try {
      f();
    } catch (const FitError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  Eigen::Matrix3Xd collinear(3, 10);
  for (int i = 0; i < 10; ++i) collinear.col(i) = Eigen::Vector3d(1, 2, 0) * i;
  const Circle3d circle{{0, 0, 0}, {0, 0, 1}, 1.0};
  EXPECT_NE(message([&] { MinimumZoneFit(collinear, circle); }).find("collinear"), std::string::npos);
  EXPECT_NE(message([&] { InscribedFit(collinear, circle); }).find("collinear"), std::string::npos);
  EXPECT_NE(
      message([] { MinimumZoneFit(Eigen::Matrix3Xd::Random(3, 2), Plane{}); }).find("at least 3 points"),
      std::string::npos);
  EXPECT_NE(
      message([] { MinimumZoneFit(Eigen::Matrix3Xd::Random(3, 4), Cylinder{}); }).find("at least 5 points"),
      std::string::npos);
  Eigen::Matrix3Xd nan = Eigen::Matrix3Xd::Random(3, 10);
  nan(2, 2) = std::nan("");
  EXPECT_NE(message([&] { MinimumZoneFit(nan, Sphere{}); }).find("NaN"), std::string::npos);
  // A quarter arc does not surround an inscribed circle: said plainly, not a huge radius.
  Eigen::Matrix3Xd arc(3, 20);
  for (int i = 0; i < 20; ++i) arc.col(i) << 5 * std::cos(0.08 * i), 5 * std::sin(0.08 * i), 0;
  EXPECT_NE(message([&] { InscribedFit(arc, FitCircle(arc).shape); }).find("do not surround"),
            std::string::npos);
  EXPECT_EQ(FitCriterionFromString("minzone"), FitCriterion::kMinimumZone);
  EXPECT_THROW(FitCriterionFromString("chebyshev"), std::invalid_argument);
}

}  // namespace
}  // namespace s2m
