// The FE surface's parameter domain (fitting/domain_mesh.h, docs/fe-surfaces.md section 1): CGAL's
// constrained Delaunay refinement with a size function on the thesis' hexagon, an L-shaped domain and a
// domain with a hole; Fang's global edge orientation and the elements' edge signs; Euler's formula; the
// Gibbs-Poole-Stockmeyer / Cuthill-McKee node numbering's bandwidth; bad input.

#include "fitting/domain_mesh.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <set>
#include <stdexcept>

namespace s2m {
namespace {

// Fang's Gaussian-bump domain: a regular hexagon of circumradius 3, counter-clockwise.
DomainPolygon Hexagon(double radius = 3.0) {
  DomainPolygon p;
  p.outer.resize(2, 6);
  for (int k = 0; k < 6; ++k)
    p.outer.col(k) << radius * std::cos(k * M_PI / 3), radius * std::sin(k * M_PI / 3);
  return p;
}

// The hexagon with every side split into `parts` segments at uneven positions (as boundary nodes placed in
// proportion to curve elements of unequal parametric lengths would be).
DomainPolygon SubdividedHexagon(const std::vector<double>& fractions) {
  const DomainPolygon h = Hexagon();
  DomainPolygon p;
  p.outer.resize(2, static_cast<Eigen::Index>(6 * (fractions.size() + 1)));
  Eigen::Index k = 0;
  for (int side = 0; side < 6; ++side) {
    const Eigen::Vector2d a = h.outer.col(side), b = h.outer.col((side + 1) % 6);
    p.outer.col(k++) = a;
    for (const double f : fractions) p.outer.col(k++) = a + f * (b - a);
  }
  return p;
}

DomainPolygon LShape() {
  DomainPolygon p;
  p.outer.resize(2, 6);
  p.outer << 0, 2, 2, 1, 1, 0,  //
      0, 0, 1, 1, 2, 2;
  return p;
}

DomainPolygon SquareWithHole() {
  DomainPolygon p;
  p.outer.resize(2, 4);
  p.outer << -2, 2, 2, -2,  //
      -2, -2, 2, 2;
  Eigen::Matrix2Xd hole(2, 4);   // clockwise; either orientation is accepted
  hole << -0.5, -0.5, 0.5, 0.5,  //
      -0.5, 0.5, 0.5, -0.5;
  p.holes.push_back(hole);
  return p;
}

double TriangleArea(const DomainMesh& m, int t) {
  const Eigen::Vector2d a = m.vertices.col(m.triangles(0, t)), b = m.vertices.col(m.triangles(1, t)),
                        c = m.vertices.col(m.triangles(2, t));
  return 0.5 * ((b - a).x() * (c - a).y() - (b - a).y() * (c - a).x());
}

Eigen::Vector2d Centroid(const DomainMesh& m, int t) {
  return (m.vertices.col(m.triangles(0, t)) + m.vertices.col(m.triangles(1, t)) +
          m.vertices.col(m.triangles(2, t))) /
         3;
}

// Every topological property the element assembly relies on.
void ExpectConsistentTopology(const DomainPolygon& polygon, const DomainMesh& m) {
  // The polygon's vertices are the mesh's first ones.
  const int np = polygon.vertex_count();
  ASSERT_EQ(m.polygon_vertex_count, np);
  Eigen::Index k = 0;
  for (Eigen::Index i = 0; i < polygon.outer.cols(); ++i, ++k)
    EXPECT_EQ(m.vertices.col(k), polygon.outer.col(i));
  for (const Eigen::Matrix2Xd& hole : polygon.holes)
    for (Eigen::Index i = 0; i < hole.cols(); ++i, ++k) EXPECT_EQ(m.vertices.col(k), hole.col(i));
  // Euler's formula for a disc with holes: V - E + F = 1 - holes.
  EXPECT_EQ(m.vertex_count() - m.edge_count() + m.triangle_count(),
            1 - static_cast<int>(polygon.holes.size()));
  for (int t = 0; t < m.triangle_count(); ++t) EXPECT_GT(TriangleArea(m, t), 0) << "triangle " << t;
  // Local edges are the triangle's vertex pairs; the sign says which side the global normal is on.
  for (int t = 0; t < m.triangle_count(); ++t)
    for (int j = 0; j < 3; ++j) {
      const int e = m.triangle_edges(j, t), a = m.triangles(j, t), b = m.triangles((j + 1) % 3, t);
      const std::set<int> ends{m.edges(0, e), m.edges(1, e)};
      EXPECT_EQ(ends, (std::set<int>{a, b}));
      // Outward normal of a counter-clockwise triangle on a -> b: the tangent turned clockwise.
      const Eigen::Vector2d t_local = m.vertices.col(b) - m.vertices.col(a);
      const Eigen::Vector2d outward(t_local.y(), -t_local.x());
      const Eigen::Vector2d t_global = m.vertices.col(m.edges(1, e)) - m.vertices.col(m.edges(0, e));
      const Eigen::Vector2d normal(-t_global.y(), t_global.x());
      EXPECT_EQ(m.triangle_edge_signs(j, t), outward.dot(normal) > 0 ? 1 : -1);
    }
  // Fang's rule (eq. D2): normal with a positive v component, t x n > 0; edges parallel to v: normal along
  // +u.
  for (int e = 0; e < m.edge_count(); ++e) {
    const Eigen::Vector2d t = m.vertices.col(m.edges(1, e)) - m.vertices.col(m.edges(0, e));
    const Eigen::Vector2d n(-t.y(), t.x());
    EXPECT_GT(t.x() * n.y() - t.y() * n.x(), 0);
    EXPECT_TRUE(n.y() > 0 || (n.y() == 0 && n.x() > 0)) << "edge " << e;
  }
  // Interior edges: two triangles that see opposite signs, so both agree on the one global normal.
  int boundary_edges = 0;
  for (int e = 0; e < m.edge_count(); ++e) {
    const bool boundary = m.boundary_edge[static_cast<std::size_t>(e)];
    ASSERT_GE(m.edge_triangles(0, e), 0);
    EXPECT_EQ(boundary, m.edge_triangles(1, e) < 0);
    EXPECT_EQ(boundary, m.edge_segment(e) >= 0);
    boundary_edges += boundary;
    if (boundary) continue;
    int signs[2];
    for (int s = 0; s < 2; ++s) {
      const int t = m.edge_triangles(s, e);
      int j = 0;
      while (j < 3 && m.triangle_edges(j, t) != e) ++j;
      ASSERT_LT(j, 3);
      signs[s] = m.triangle_edge_signs(j, t);
    }
    EXPECT_EQ(signs[0], -signs[1]) << "edge " << e;
  }
  // Every polygon vertex is on the boundary, and each hole's area is left out.
  for (int i = 0; i < np; ++i) EXPECT_TRUE(m.boundary_vertex[static_cast<std::size_t>(i)]);
  EXPECT_GE(boundary_edges, polygon.segment_count());
  double area = 0;
  for (int t = 0; t < m.triangle_count(); ++t) area += TriangleArea(m, t);
  auto ring_area = [](const Eigen::Matrix2Xd& r) {
    double a = 0;
    for (Eigen::Index i = 0; i < r.cols(); ++i) {
      const Eigen::Index j = (i + 1) % r.cols();
      a += 0.5 * (r(0, i) * r(1, j) - r(0, j) * r(1, i));
    }
    return std::abs(a);
  };
  double expected = ring_area(polygon.outer);
  for (const Eigen::Matrix2Xd& hole : polygon.holes) expected -= ring_area(hole);
  EXPECT_NEAR(area, expected, 1e-12 * expected);
  // The numbering is a permutation.
  const NodeNumbering& n = m.numbering;
  ASSERT_EQ(n.number.size(), m.node_count());
  for (int i = 0; i < m.node_count(); ++i) EXPECT_EQ(n.order(n.number(i)), i);
}

// The angle and size bounds over every triangle: the smallest angle and the longest edge.
void ExpectBounds(const DomainMesh& m, const DomainMeshOptions& options, double* min_angle,
                  double* max_edge) {
  *min_angle = M_PI;
  *max_edge = 0;
  for (int t = 0; t < m.triangle_count(); ++t) {
    *min_angle = std::min(*min_angle, TriangleMinAngle(m, t));
    *max_edge = std::max(*max_edge, TriangleMaxEdge(m, t));
  }
  // The bound is checked by CGAL as sin^2(angle) >= sin^2(bound) in floating point: a few ulps of slack.
  EXPECT_GE(*min_angle, options.min_angle_degrees * M_PI / 180 * (1 - 1e-12));
  if (options.max_edge > 0) {
    EXPECT_LE(*max_edge, options.max_edge * (1 + 1e-9));
  }
  EXPECT_EQ(m.triangles_off_bounds, 0);
}

TEST(DomainMesh, HexagonUniformSizeMeetsTheAngleAndEdgeBounds) {
  const DomainPolygon hexagon = Hexagon();
  DomainMeshOptions options;
  options.max_edge = 0.5;
  // The default angle bound: 20.7 degrees, just below CGAL's 0.125 shape bound (20.705 degrees), for which
  // Delaunay refinement terminates.
  EXPECT_NEAR(MaxGuaranteedMinAngleDegrees(), 20.7048, 1e-4);
  const DomainMesh m = MeshDomain(hexagon, options);
  ExpectConsistentTopology(hexagon, m);
  double min_angle, max_edge;
  ExpectBounds(m, options, &min_angle, &max_edge);
  std::printf(
      "hexagon R=3, max_edge 0.5: %d vertices, %d edges, %d triangles; smallest angle %.2f deg (bound %.2f), "
      "longest edge %.4f\n",
      m.vertex_count(), m.edge_count(), m.triangle_count(), min_angle * 180 / M_PI, options.min_angle_degrees,
      max_edge);
  // Each triangle's area is at most that of the equilateral triangle of side max_edge: a floor on the count.
  EXPECT_GE(m.triangle_count(), static_cast<int>(23.38 / (std::sqrt(3.0) / 4 * 0.25)));
}

TEST(DomainMesh, SizeFunctionSmallerAtTheCentreGivesDenserVerticesThere) {
  const DomainPolygon hexagon = Hexagon();
  DomainMeshOptions graded;
  const double h_centre = 0.15, h_rim = 0.6;
  graded.size = [&](double u, double v) {
    return h_centre + (h_rim - h_centre) * std::min(1.0, std::hypot(u, v) / 2);
  };
  DomainMeshOptions uniform;
  uniform.max_edge = h_rim;
  const DomainMesh g = MeshDomain(hexagon, graded), m = MeshDomain(hexagon, uniform);
  ExpectConsistentTopology(hexagon, g);
  double min_angle, max_edge;
  ExpectBounds(g, graded, &min_angle, &max_edge);
  // Vertices per unit area in the disc r < 0.5 and in the annulus 2 < r < 2.5 (inside the hexagon, whose
  // inradius is 2.598).
  auto density = [](const DomainMesh& mesh, double r0, double r1) {
    int count = 0;
    for (int i = 0; i < mesh.vertex_count(); ++i) {
      const double r = mesh.vertices.col(i).norm();
      count += r >= r0 && r < r1;
    }
    return count / (M_PI * (r1 * r1 - r0 * r0));
  };
  const double centre = density(g, 0, 0.5), rim = density(g, 2, 2.5);
  std::printf(
      "graded (h %.2f at the centre to %.2f): %d vertices, %d triangles; vertices per unit area %.1f at the "
      "centre, %.1f at the rim; uniform h %.2f: %d vertices, %.1f at the centre\n",
      h_centre, h_rim, g.vertex_count(), g.triangle_count(), centre, rim, h_rim, m.vertex_count(),
      density(m, 0, 0.5));
  // Density scales like 1 / h^2 (16 here); asserted: more than the linear ratio h_rim / h_centre.
  EXPECT_GT(centre, h_rim / h_centre * rim);
  EXPECT_GT(centre, h_rim / h_centre * density(m, 0, 0.5));
}

TEST(DomainMesh, LShapedDomain) {
  const DomainPolygon l = LShape();
  DomainMeshOptions options;
  options.max_edge = 0.2;
  const DomainMesh m = MeshDomain(l, options);
  ExpectConsistentTopology(l, m);
  double min_angle, max_edge;
  ExpectBounds(m, options, &min_angle, &max_edge);
  std::printf("L-shape: %d vertices, %d triangles, smallest angle %.2f deg, longest edge %.4f\n",
              m.vertex_count(), m.triangle_count(), min_angle * 180 / M_PI, max_edge);
  // No triangle in the missing square (1, 2) x (1, 2).
  for (int t = 0; t < m.triangle_count(); ++t) {
    const Eigen::Vector2d c = Centroid(m, t);
    EXPECT_FALSE(c.x() > 1 && c.y() > 1) << "triangle " << t;
  }
}

TEST(DomainMesh, DomainWithAHole) {
  const DomainPolygon p = SquareWithHole();
  DomainMeshOptions options;
  options.max_edge = 0.4;
  const DomainMesh m = MeshDomain(p, options);
  ExpectConsistentTopology(p, m);
  double min_angle, max_edge;
  ExpectBounds(m, options, &min_angle, &max_edge);
  EXPECT_EQ(m.hole_count, 1);
  std::printf(
      "square with a hole: %d vertices, %d edges, %d triangles (V - E + F = %d), smallest angle %.2f deg\n",
      m.vertex_count(), m.edge_count(), m.triangle_count(),
      m.vertex_count() - m.edge_count() + m.triangle_count(), min_angle * 180 / M_PI);
  for (int t = 0; t < m.triangle_count(); ++t) {
    const Eigen::Vector2d c = Centroid(m, t);
    EXPECT_FALSE(std::abs(c.x()) < 0.5 && std::abs(c.y()) < 0.5) << "triangle " << t << " in the hole";
  }
  // Boundary edges lie on the hole's segments (4..7) as well as the outer ones (0..3).
  std::set<int> segments;
  for (int e = 0; e < m.edge_count(); ++e)
    if (m.boundary_edge[static_cast<std::size_t>(e)]) segments.insert(m.edge_segment(e));
  EXPECT_EQ(segments, (std::set<int>{0, 1, 2, 3, 4, 5, 6, 7}));
}

TEST(DomainMesh, BoundaryEdgesAreTheInputSegmentsWhenSplittingIsOff) {
  // Sides split at 0.2 and 0.55 of their length (uneven, as Hermite boundary elements would place them).
  const DomainPolygon p = SubdividedHexagon({0.2, 0.55});
  DomainMeshOptions options;
  options.max_edge = 0.4;  // shorter than the boundary segments (0.6 to 1.35): refinement would split them
  options.split_boundary = false;
  const DomainMesh m = MeshDomain(p, options);
  ExpectConsistentTopology(p, m);
  const int n = p.vertex_count();
  int boundary_edges = 0;
  for (int e = 0; e < m.edge_count(); ++e) {
    if (!m.boundary_edge[static_cast<std::size_t>(e)]) continue;
    ++boundary_edges;
    const int s = m.edge_segment(e);
    EXPECT_EQ((std::set<int>{m.edges(0, e), m.edges(1, e)}), (std::set<int>{s, (s + 1) % n}));
  }
  EXPECT_EQ(boundary_edges, n);
  for (int i = n; i < m.vertex_count(); ++i) EXPECT_FALSE(m.boundary_vertex[static_cast<std::size_t>(i)]);
  // The triangles on the unsplit segments are as long as the segments: reported, not hidden.
  EXPECT_GT(m.triangles_off_bounds, 0);
  std::printf(
      "boundary kept (%d segments): %d vertices, %d triangles, %d off the bounds (on the long segments)\n", n,
      m.vertex_count(), m.triangle_count(), m.triangles_off_bounds);
  // With splitting allowed the same mesh subdivides the boundary.
  options.split_boundary = true;
  const DomainMesh split = MeshDomain(p, options);
  int split_boundary_edges = 0;
  for (int e = 0; e < split.edge_count(); ++e)
    split_boundary_edges += split.boundary_edge[static_cast<std::size_t>(e)];
  EXPECT_GT(split_boundary_edges, n);
  EXPECT_EQ(split.triangles_off_bounds, 0);
}

TEST(DomainMesh, GlobalEdgeOrientationRule) {
  // Towards +u: global. Parallel to u: from lower to higher u (normal +v). Parallel to v: downwards (normal
  // +u).
  EXPECT_TRUE(IsGlobalEdgeDirection({0, 0}, {1, 0.5}));
  EXPECT_TRUE(IsGlobalEdgeDirection({0, 0}, {1, -0.5}));
  EXPECT_FALSE(IsGlobalEdgeDirection({1, 0.5}, {0, 0}));
  EXPECT_TRUE(IsGlobalEdgeDirection({0, 0}, {1, 0}));
  EXPECT_FALSE(IsGlobalEdgeDirection({1, 0}, {0, 0}));
  EXPECT_TRUE(IsGlobalEdgeDirection({0, 1}, {0, 0}));
  EXPECT_FALSE(IsGlobalEdgeDirection({0, 0}, {0, 1}));
  // The L-shape has edges parallel to both axes on its boundary.
  DomainMeshOptions options;
  options.max_edge = 0.5;
  const DomainMesh m = MeshDomain(LShape(), options);
  int parallel_to_u = 0, parallel_to_v = 0;
  for (int e = 0; e < m.edge_count(); ++e) {
    const Eigen::Vector2d t = m.vertices.col(m.edges(1, e)) - m.vertices.col(m.edges(0, e));
    if (t.y() == 0) {
      ++parallel_to_u;
      EXPECT_GT(t.x(), 0);
    }
    if (t.x() == 0) {
      ++parallel_to_v;
      EXPECT_LT(t.y(), 0);
    }
  }
  EXPECT_GT(parallel_to_u, 0);
  EXPECT_GT(parallel_to_v, 0);
}

TEST(DomainMesh, NodeRenumberingReducesTheBandwidth) {
  // A hexagon mesh near the size of Fang's initial Gaussian mesh (54 vertices, 129 edges, 76 triangles; dof
  // bandwidth 281 -> 74 for 291 dofs).
  DomainMeshOptions options;
  options.max_edge = 1.2;
  const DomainPolygon hexagon = Hexagon();
  const DomainMesh m = MeshDomain(hexagon, options);
  ExpectConsistentTopology(hexagon, m);
  const NodeNumbering& n = m.numbering;
  const int dofs = 3 * m.vertex_count() + m.edge_count();
  std::printf(
      "hexagon R=3, max_edge 1.2: %d vertices, %d edges, %d triangles, %d nodes, %d dofs; node bandwidth %d "
      "-> "
      "%d, dof bandwidth %d -> %d (level structure: %d levels, width %d)\n",
      m.vertex_count(), m.edge_count(), m.triangle_count(), m.node_count(), dofs, n.bandwidth_natural,
      n.bandwidth, n.dof_bandwidth_natural, n.dof_bandwidth, n.levels, n.level_width);
  EXPECT_LT(n.bandwidth, n.bandwidth_natural);
  EXPECT_LT(n.dof_bandwidth, n.dof_bandwidth_natural);
  EXPECT_LE(n.bandwidth, 2 * n.level_width - 1);
  // The same on a finer graded mesh, and on the domain with a hole.
  for (const DomainPolygon& p : {Hexagon(), SquareWithHole()}) {
    DomainMeshOptions fine;
    fine.max_edge = 0.3;
    const DomainMesh f = MeshDomain(p, fine);
    std::printf("  %d vertices, %d triangles: node bandwidth %d -> %d, dof bandwidth %d -> %d, width %d\n",
                f.vertex_count(), f.triangle_count(), f.numbering.bandwidth_natural, f.numbering.bandwidth,
                f.numbering.dof_bandwidth_natural, f.numbering.dof_bandwidth, f.numbering.level_width);
    EXPECT_LT(f.numbering.bandwidth, f.numbering.bandwidth_natural);
    EXPECT_LE(f.numbering.bandwidth, 2 * f.numbering.level_width - 1);
  }
}

TEST(DomainMesh, NumberingOfAHandMadeMesh) {
  // Two triangles on the unit square: 4 vertices, 5 edges, 9 nodes. The least degree (5) is that of the
  // corners 1 and 3 and the four boundary mid-edge nodes; rooted at any of them the level structure has 3
  // levels of sizes 1, 5 and 3.
  DomainPolygon square;
  square.outer.resize(2, 4);
  square.outer << 0, 1, 1, 0,  //
      0, 0, 1, 1;
  Eigen::Matrix3Xi triangles(3, 2);
  triangles << 0, 0,  //
      1, 2,           //
      2, 3;
  const DomainMesh m = BuildDomainMesh(square, square.outer, triangles);
  EXPECT_EQ(m.edge_count(), 5);
  EXPECT_EQ(m.node_count(), 9);
  ExpectConsistentTopology(square, m);
  EXPECT_EQ(m.numbering.levels, 3);
  EXPECT_EQ(m.numbering.level_width, 5);
  EXPECT_LE(m.numbering.bandwidth, 2 * m.numbering.level_width - 1);
  EXPECT_LE(m.numbering.bandwidth, m.numbering.bandwidth_natural);
  // The diagonal (0, 2) runs from lower u to higher u: its normal (-1, 1) / sqrt 2 points into triangle 1.
  int diagonal = -1;
  for (int e = 0; e < m.edge_count(); ++e)
    if (!m.boundary_edge[static_cast<std::size_t>(e)]) diagonal = e;
  ASSERT_GE(diagonal, 0);
  EXPECT_EQ(m.edges(0, diagonal), 0);
  EXPECT_EQ(m.edges(1, diagonal), 2);
  EXPECT_EQ(m.triangle_edge_signs(2, 0), 1);   // triangle 0 (0, 1, 2): local edge 2-0 runs against it
  EXPECT_EQ(m.triangle_edge_signs(0, 1), -1);  // triangle 1 (0, 2, 3): local edge 0-2 runs along it
}

TEST(DomainMesh, RefinementKeepsTheVerticesAndFollowsTheNewSize) {
  const DomainPolygon hexagon = Hexagon();
  DomainMeshOptions coarse;
  coarse.max_edge = 1.0;
  const DomainMesh m = MeshDomain(hexagon, coarse);
  DomainMeshOptions finer = coarse;
  // Smaller where a (stand-in) curvature is large: near the centre.
  finer.size = [](double u, double v) { return 0.2 + 0.3 * std::hypot(u, v); };
  const DomainMesh r = RefineDomainMesh(hexagon, m, finer);
  ExpectConsistentTopology(hexagon, r);
  double min_angle, max_edge;
  ExpectBounds(r, finer, &min_angle, &max_edge);
  ASSERT_GT(r.vertex_count(), m.vertex_count());
  EXPECT_EQ(r.vertices.leftCols(m.vertex_count()), m.vertices);
  std::printf("refined: %d -> %d vertices, %d -> %d triangles, smallest angle %.2f deg\n", m.vertex_count(),
              r.vertex_count(), m.triangle_count(), r.triangle_count(), min_angle * 180 / M_PI);
  // Where the size function asks for 0.2..0.35 (r < 0.5) every triangle is at most that large.
  for (int t = 0; t < r.triangle_count(); ++t) {
    const Eigen::Vector2d c = Centroid(r, t);
    EXPECT_LE(TriangleMaxEdge(r, t), finer.size(c.x(), c.y()) * (1 + 1e-9));
  }
}

// The call throws std::invalid_argument whose message contains `what`.
template <class F>
void ExpectInvalid(F f, const std::string& what) {
  try {
    f();
    ADD_FAILURE() << "no exception; expected one naming: " << what;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
  }
}

TEST(DomainMesh, BadInputThrowsAndNamesTheProblem) {
  DomainMeshOptions options;
  options.max_edge = 0.5;
  DomainPolygon two;
  two.outer.resize(2, 2);
  two.outer << 0, 1, 0, 0;
  ExpectInvalid([&] { MeshDomain(two, options); }, "fewer than 3 vertices");
  DomainPolygon flat;
  flat.outer.resize(2, 3);
  flat.outer << 0, 1, 2, 0, 1, 2;
  ExpectInvalid([&] { MeshDomain(flat, options); }, "zero area");
  DomainPolygon nan = Hexagon();
  nan.outer(1, 2) = std::numeric_limits<double>::quiet_NaN();
  ExpectInvalid([&] { MeshDomain(nan, options); }, "non-finite");
  DomainPolygon inf = Hexagon();
  inf.outer(0, 4) = std::numeric_limits<double>::infinity();
  ExpectInvalid([&] { MeshDomain(inf, options); }, "non-finite");
  DomainPolygon bowtie;  // the last segment crosses the first; counter-clockwise by its signed area
  bowtie.outer.resize(2, 5);
  bowtie.outer << 0, 4, 4, 0, 2,  //
      0, 0, 4, 4, -1;
  ExpectInvalid([&] { MeshDomain(bowtie, options); }, "self-intersecting");
  DomainPolygon touching;  // a vertex on a non-adjacent segment
  touching.outer.resize(2, 5);
  touching.outer << 0, 2, 2, 1, 0,  //
      0, 0, 2, 0, 2;
  ExpectInvalid([&] { MeshDomain(touching, options); }, "self-intersecting");
  DomainPolygon repeated = Hexagon();
  repeated.outer.col(3) = repeated.outer.col(2);
  ExpectInvalid([&] { MeshDomain(repeated, options); }, "repeats a vertex");
  DomainPolygon clockwise = Hexagon();
  clockwise.outer = clockwise.outer.rowwise().reverse().eval();
  ExpectInvalid([&] { MeshDomain(clockwise, options); }, "clockwise");
  DomainPolygon outside = Hexagon();
  Eigen::Matrix2Xd far(2, 3);
  far << 10, 11, 10, 10, 10, 11;
  outside.holes.push_back(far);
  ExpectInvalid([&] { MeshDomain(outside, options); }, "hole 0 lies outside the outer boundary");
  DomainPolygon crossing = Hexagon();
  Eigen::Matrix2Xd across(2, 3);
  across << 0, 5, 0, 0, 0, 1;
  crossing.holes.push_back(across);
  ExpectInvalid([&] { MeshDomain(crossing, options); }, "self-intersecting");
  DomainPolygon nested = SquareWithHole();
  Eigen::Matrix2Xd inner(2, 3);
  inner << -0.1, 0.1, 0, -0.1, -0.1, 0.1;
  nested.holes.push_back(inner);
  ExpectInvalid([&] { MeshDomain(nested, options); }, "hole 1 lies inside hole 0");

  // Options and size functions.
  DomainMeshOptions steep = options;
  steep.min_angle_degrees = 30;
  ExpectInvalid([&] { MeshDomain(Hexagon(), steep); }, "min_angle_degrees");
  DomainMeshOptions negative = options;
  negative.max_edge = -1;
  ExpectInvalid([&] { MeshDomain(Hexagon(), negative); }, "max_edge");
  DomainMeshOptions bad_size = options;
  bad_size.size = [](double u, double) { return u; };  // negative on half the domain
  ExpectInvalid([&] { MeshDomain(Hexagon(), bad_size); }, "size function returned");
  // A size function that would ask for about 10^13 vertices stops at the guard.
  DomainMeshOptions billions;
  billions.size = [](double, double) { return 1e-6; };
  billions.max_vertices = 5000;
  ExpectInvalid([&] { MeshDomain(Hexagon(), billions); }, "max_vertices = 5000");
  // A mesh that is not of this polygon cannot be refined.
  const DomainMesh square_mesh = MeshDomain(SquareWithHole(), options);
  ExpectInvalid([&] { RefineDomainMesh(Hexagon(), square_mesh, options); }, "not a mesh of this polygon");
}

}  // namespace
}  // namespace s2m
