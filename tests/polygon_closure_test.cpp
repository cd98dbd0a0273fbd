// The n-sided patch's domain polygon closed by the method of multipliers (fitting/polygon_closure.h,
// docs/fe-surfaces.md eq. P13).
#include "fitting/polygon_closure.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <vector>

#include "fitting/domain_mesh.h"

namespace s2m {
namespace {

TEST(PolygonClosure, AClosedPolygonKeepsItsAngles) {
  const PolygonClosure c = ClosePolygon({2, 1, 2, 1}, {M_PI / 2, M_PI / 2, M_PI / 2, M_PI / 2});
  EXPECT_TRUE(c.converged);
  for (double t : c.turning) EXPECT_NEAR(t, M_PI / 2, 1e-12);
  EXPECT_NEAR(c.vertices(0, 2), 2.0, 1e-12);
  EXPECT_NEAR(c.vertices(1, 2), 1.0, 1e-12);
}

TEST(PolygonClosure, ATriangleClosesToTheOneItsSidesDetermine) {
  // Sides 3, 4, 5 fix the triangle whatever the starting angles: its exterior angles are pi minus the
  // interior ones (law of cosines), here pi - 90, pi - 36.87 and pi - 53.13 degrees in order.
  const PolygonClosure c = ClosePolygon({3, 4, 5}, {2.0, 2.0, 2.0});
  ASSERT_TRUE(c.converged);
  const double at_end_of_3 = M_PI - M_PI / 2;              // between the sides 3 and 4
  const double at_end_of_4 = M_PI - std::acos(4.0 / 5.0);  // between 4 and 5: opposite the side 3
  const double at_end_of_5 = M_PI - std::acos(3.0 / 5.0);  // between 5 and 3: opposite the side 4
  std::printf("3-4-5 triangle: turns %.12f %.12f %.12f after %d multiplier updates, closure %.1e\n",
              c.turning[0], c.turning[1], c.turning[2], c.outer_iterations, c.closure_error);
  EXPECT_NEAR(c.turning[0], at_end_of_3, 1e-9);
  EXPECT_NEAR(c.turning[1], at_end_of_4, 1e-9);
  EXPECT_NEAR(c.turning[2], at_end_of_5, 1e-9);
}

TEST(PolygonClosure, AnOpenPolygonClosesWithSmallAngleChangesAndValidates) {
  // A pentagon from measured curves: the sides' lengths and the angles between the curves do not quite agree
  // (the turns sum to 2 pi + 0.1 and the sides do not close); the closed polygon is valid for meshing and
  // its turns move by little.
  const std::vector<double> sides = {3.0, 2.2, 2.5, 2.9, 2.0};
  const std::vector<double> turns = {1.30, 1.20, 1.35, 1.25, 2 * M_PI + 0.1 - 5.10};
  const PolygonClosure c = ClosePolygon(sides, turns);
  ASSERT_TRUE(c.converged);
  EXPECT_LT(c.closure_error, 1e-12);
  EXPECT_LT(std::abs(c.angle_sum_error), 1e-12);
  double largest_change = 0;
  for (std::size_t i = 0; i < turns.size(); ++i)
    largest_change = std::max(largest_change, std::abs(c.turning[i] - turns[i]));
  std::printf("pentagon: %d multiplier updates, largest turn change %.4f rad\n", c.outer_iterations,
              largest_change);
  EXPECT_LT(largest_change, 0.5);
  // The side lengths are kept exactly.
  for (Eigen::Index i = 0; i < 5; ++i)
    EXPECT_NEAR((c.vertices.col((i + 1) % 5) - c.vertices.col(i)).norm(), sides[static_cast<std::size_t>(i)],
                1e-9);
  DomainPolygon polygon;
  polygon.outer = c.vertices;
  EXPECT_NO_THROW(polygon.Validate());
}

TEST(PolygonClosure, RefusesWhatNoPolygonHas) {
  EXPECT_THROW(ClosePolygon({1, 1}, {M_PI, M_PI}), std::invalid_argument);
  EXPECT_THROW(ClosePolygon({1, 1, 3}, {2, 2, 2}), std::invalid_argument);  // 3 >= 1 + 1
  EXPECT_THROW(ClosePolygon({1, 0, 1}, {2, 2, 2}), std::invalid_argument);
  EXPECT_THROW(ClosePolygon({1, 1, 1}, {2, NAN, 2}), std::invalid_argument);
  EXPECT_THROW(ClosePolygon({1, 1, 1}, {2, 2}), std::invalid_argument);
  PolygonClosureOptions bad;
  bad.penalty = 0;
  EXPECT_THROW(ClosePolygon({1, 1, 1}, {2, 2, 2}, bad), std::invalid_argument);
  try {
    ClosePolygon({1, 1, 3}, {2, 2, 2});
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("side 2"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace s2m
