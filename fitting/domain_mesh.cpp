// The domain polygon's checks, the finite-element topology of a triangulation (global edge orientation, local
// edge signs, adjacency) and the node numbering (docs/fe-surfaces.md section 1). The triangulation itself is
// in domain_triangulation.cpp, the only file that sees CGAL.

#include "fitting/domain_mesh.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <utility>

namespace s2m {
namespace {

constexpr double kEpsilon = std::numeric_limits<double>::epsilon();

// The polygon's rings: 0 the outer boundary, 1.. the holes.
std::vector<const Eigen::Matrix2Xd*> Rings(const DomainPolygon& polygon) {
  std::vector<const Eigen::Matrix2Xd*> rings{&polygon.outer};
  for (const Eigen::Matrix2Xd& hole : polygon.holes) rings.push_back(&hole);
  return rings;
}

std::string RingName(std::size_t ring) {
  return ring == 0 ? std::string("the outer boundary") : "hole " + std::to_string(ring - 1);
}

double Cross(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  return (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
}

int Sign(double x) {
  return (x > 0) - (x < 0);
}

// Whether point p on the line of segment ab lies within its closed extent.
bool OnSegment(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& p) {
  return std::min(a.x(), b.x()) <= p.x() && p.x() <= std::max(a.x(), b.x()) &&
         std::min(a.y(), b.y()) <= p.y() && p.y() <= std::max(a.y(), b.y());
}

// Closed segments ab and cd share a point (crossing, touching or overlapping).
bool SegmentsMeet(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c,
                  const Eigen::Vector2d& d) {
  const int o1 = Sign(Cross(a, b, c)), o2 = Sign(Cross(a, b, d)), o3 = Sign(Cross(c, d, a)),
            o4 = Sign(Cross(c, d, b));
  if (o1 * o2 < 0 && o3 * o4 < 0) return true;  // a proper crossing
  // An end on the other segment (touching, or collinear overlap).
  if (o1 == 0 && OnSegment(a, b, c)) return true;
  if (o2 == 0 && OnSegment(a, b, d)) return true;
  if (o3 == 0 && OnSegment(c, d, a)) return true;
  if (o4 == 0 && OnSegment(c, d, b)) return true;
  return false;
}

// Crossing number of p against a ring (half-open rule on v).
bool InsideRing(const Eigen::Matrix2Xd& ring, const Eigen::Vector2d& p) {
  bool inside = false;
  const Eigen::Index n = ring.cols();
  for (Eigen::Index i = 0, j = n - 1; i < n; j = i++) {
    const Eigen::Vector2d a = ring.col(j), b = ring.col(i);
    if ((a.y() > p.y()) != (b.y() > p.y())) {
      const double u = a.x() + (p.y() - a.y()) / (b.y() - a.y()) * (b.x() - a.x());
      if (p.x() < u) inside = !inside;
    }
  }
  return inside;
}

// Twice the signed area of a ring, and the bound on its rounding error (the shoelace terms' magnitudes).
double TwiceArea(const Eigen::Matrix2Xd& ring, double* rounding) {
  double sum = 0.0, magnitude = 0.0;
  const Eigen::Index n = ring.cols();
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Index j = (i + 1) % n;
    const double a = ring(0, i) * ring(1, j), b = ring(0, j) * ring(1, i);
    sum += a - b;
    magnitude += std::abs(a) + std::abs(b);
  }
  *rounding = static_cast<double>(n + 2) * kEpsilon * magnitude;
  return sum;
}

double PolygonScale(const DomainPolygon& polygon) {
  Eigen::Vector2d lo = polygon.outer.rowwise().minCoeff(), hi = polygon.outer.rowwise().maxCoeff();
  return (hi - lo).norm();
}

// Breadth-first level structure rooted at `root` (Fang section 5.4, docs/fe-surfaces.md eq. D6).
std::vector<std::vector<int>> RootedLevels(int root, const std::vector<int>& start,
                                           const std::vector<int>& adjacency, std::vector<int>& mark,
                                           int& stamp) {
  ++stamp;
  std::vector<std::vector<int>> levels{{root}};
  mark[static_cast<std::size_t>(root)] = stamp;
  while (true) {
    std::vector<int> next;
    for (const int x : levels.back()) {
      for (int k = start[static_cast<std::size_t>(x)]; k < start[static_cast<std::size_t>(x) + 1]; ++k) {
        const int y = adjacency[static_cast<std::size_t>(k)];
        if (mark[static_cast<std::size_t>(y)] == stamp) continue;
        mark[static_cast<std::size_t>(y)] = stamp;
        next.push_back(y);
      }
    }
    if (next.empty()) break;
    levels.push_back(std::move(next));
  }
  return levels;
}

int Width(const std::vector<std::vector<int>>& levels) {
  std::size_t w = 0;
  for (const std::vector<int>& level : levels) w = std::max(w, level.size());
  return static_cast<int>(w);
}

// Node bandwidth (eq. D4) and dof bandwidth (eq. D5) of a numbering over the node pairs.
void Bandwidths(const std::vector<std::pair<int, int>>& pairs, const Eigen::VectorXi& number,
                const Eigen::VectorXi& order, int vertex_count, int& node_bandwidth, int& dof_bandwidth) {
  const Eigen::Index n = number.size();
  Eigen::VectorXi offset(n), size(n);  // by new number
  int next = 0;
  for (Eigen::Index k = 0; k < n; ++k) {
    size(k) = order(k) < vertex_count ? 3 : 1;
    offset(k) = next;
    next += size(k);
  }
  node_bandwidth = 0;
  dof_bandwidth = n > 0 ? size.maxCoeff() - 1 : 0;  // a node's own dofs
  for (const auto& [a, b] : pairs) {
    int i = number(a), j = number(b);
    if (i > j) std::swap(i, j);
    node_bandwidth = std::max(node_bandwidth, j - i);
    dof_bandwidth = std::max(dof_bandwidth, offset(j) + size(j) - 1 - offset(i));
  }
}

}  // namespace

int DomainPolygon::vertex_count() const {
  Eigen::Index n = outer.cols();
  for (const Eigen::Matrix2Xd& hole : holes) n += hole.cols();
  return static_cast<int>(n);
}

int DomainPolygon::segment_count() const {
  return vertex_count();
}

void DomainPolygon::Validate() const {
  const std::vector<const Eigen::Matrix2Xd*> rings = Rings(*this);
  for (std::size_t r = 0; r < rings.size(); ++r) {
    const Eigen::Matrix2Xd& ring = *rings[r];
    const std::string name = RingName(r);
    if (ring.cols() < 3)
      throw std::invalid_argument("domain polygon: " + name + " has fewer than 3 vertices (" +
                                  std::to_string(ring.cols()) + ")");
    for (Eigen::Index i = 0; i < ring.cols(); ++i)
      if (!ring.col(i).allFinite())
        throw std::invalid_argument("domain polygon: " + name +
                                    " has a non-finite (NaN or infinite) coordinate at vertex " +
                                    std::to_string(i));
    for (Eigen::Index i = 0; i < ring.cols(); ++i) {
      const Eigen::Index j = (i + 1) % ring.cols();
      if (ring.col(i) == ring.col(j))
        throw std::invalid_argument("domain polygon: " + name + " repeats a vertex (vertices " +
                                    std::to_string(i) + " and " + std::to_string(j) +
                                    " coincide: a segment of zero length)");
    }
    double rounding = 0.0;
    const double twice_area = TwiceArea(ring, &rounding);
    if (std::abs(twice_area) <= rounding)
      throw std::invalid_argument("domain polygon: " + name + " has zero area (its vertices are collinear)");
    if (r == 0 && twice_area < 0)
      throw std::invalid_argument(
          "domain polygon: the outer boundary is clockwise; give it counter-clockwise");
  }
  // Every pair of segments: consecutive ones may share only their common vertex, others nothing.
  struct Segment {
    Eigen::Vector2d a, b;
    std::size_t ring;
    Eigen::Index index, ring_size;
  };
  std::vector<Segment> segments;
  for (std::size_t r = 0; r < rings.size(); ++r) {
    const Eigen::Matrix2Xd& ring = *rings[r];
    for (Eigen::Index i = 0; i < ring.cols(); ++i)
      segments.push_back({ring.col(i), ring.col((i + 1) % ring.cols()), r, i, ring.cols()});
  }
  for (std::size_t s = 0; s < segments.size(); ++s) {
    for (std::size_t t = s + 1; t < segments.size(); ++t) {
      const Segment& p = segments[s];
      const Segment& q = segments[t];
      bool meet;
      if (p.ring == q.ring &&
          (q.index == (p.index + 1) % p.ring_size || p.index == (q.index + 1) % p.ring_size)) {
        // Consecutive: x -> y -> z with y shared; they overlap beyond y only when folded back along one line.
        const bool q_follows = q.index == (p.index + 1) % p.ring_size;
        const Eigen::Vector2d x = q_follows ? p.a : q.a, y = q_follows ? p.b : q.b, z = q_follows ? q.b : p.b;
        meet = Cross(x, y, z) == 0 && (x - y).dot(z - y) > 0;
      } else {
        meet = SegmentsMeet(p.a, p.b, q.a, q.b);
      }
      if (meet)
        throw std::invalid_argument("domain polygon: self-intersecting boundary (segment " +
                                    std::to_string(p.index) + " of " + RingName(p.ring) + " meets segment " +
                                    std::to_string(q.index) + " of " + RingName(q.ring) + ")");
    }
  }
  // No segments meet, so one vertex decides where a hole lies.
  for (std::size_t h = 0; h < holes.size(); ++h) {
    const Eigen::Vector2d p = holes[h].col(0);
    if (!InsideRing(outer, p))
      throw std::invalid_argument("domain polygon: hole " + std::to_string(h) +
                                  " lies outside the outer boundary");
    for (std::size_t g = 0; g < holes.size(); ++g)
      if (g != h && InsideRing(holes[g], p))
        throw std::invalid_argument("domain polygon: hole " + std::to_string(h) + " lies inside hole " +
                                    std::to_string(g));
  }
}

double MaxGuaranteedMinAngleDegrees() {
  return std::asin(std::sqrt(0.125)) * 180.0 / M_PI;
}

bool DomainMeshOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& reason) {
    if (why) *why = reason;
    return false;
  };
  if (!(max_edge >= 0) || !std::isfinite(max_edge)) return fail("max_edge must be finite and >= 0 (0: none)");
  if (!(min_angle_degrees > 0) || min_angle_degrees > MaxGuaranteedMinAngleDegrees())
    return fail("min_angle_degrees must be in (0, " + std::to_string(MaxGuaranteedMinAngleDegrees()) +
                "] (the bound for which Delaunay refinement terminates)");
  if (max_vertices < 3) return fail("max_vertices must be at least 3");
  return true;
}

bool IsGlobalEdgeDirection(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  return b.x() > a.x() || (b.x() == a.x() && b.y() < a.y());
}

DomainMesh BuildDomainMesh(const DomainPolygon& polygon, Eigen::Matrix2Xd vertices,
                           Eigen::Matrix3Xi triangles) {
  polygon.Validate();
  DomainMesh mesh;
  mesh.polygon_vertex_count = polygon.vertex_count();
  mesh.hole_count = static_cast<int>(polygon.holes.size());
  mesh.vertices = std::move(vertices);
  mesh.triangles = std::move(triangles);
  const int nv = mesh.vertex_count(), nt = mesh.triangle_count();
  if (nv < mesh.polygon_vertex_count)
    throw std::invalid_argument("domain mesh: fewer vertices than the polygon has");
  {
    int k = 0;
    for (const Eigen::Matrix2Xd* ring : Rings(polygon))
      for (Eigen::Index i = 0; i < ring->cols(); ++i, ++k)
        if (mesh.vertices.col(k) != ring->col(i))
          throw std::invalid_argument("domain mesh: vertex " + std::to_string(k) +
                                      " is not the polygon's vertex " + std::to_string(k));
  }
  if (nt == 0) throw std::invalid_argument("domain mesh: no triangles");
  for (int t = 0; t < nt; ++t) {
    for (int k = 0; k < 3; ++k)
      if (mesh.triangles(k, t) < 0 || mesh.triangles(k, t) >= nv)
        throw std::invalid_argument("domain mesh: triangle " + std::to_string(t) +
                                    " has a vertex index out of range");
    if (!(Cross(mesh.vertices.col(mesh.triangles(0, t)), mesh.vertices.col(mesh.triangles(1, t)),
                mesh.vertices.col(mesh.triangles(2, t))) > 0))
      throw std::invalid_argument("domain mesh: triangle " + std::to_string(t) +
                                  " is clockwise or degenerate (zero area)");
  }

  // Unique edges: every (triangle, local edge) keyed by its sorted vertex pair.
  struct HalfEdge {
    int lo, hi, triangle, local;
  };
  std::vector<HalfEdge> half(static_cast<std::size_t>(3 * nt));
  for (int t = 0; t < nt; ++t)
    for (int k = 0; k < 3; ++k) {
      const int a = mesh.triangles(k, t), b = mesh.triangles((k + 1) % 3, t);
      half[static_cast<std::size_t>(3 * t + k)] = {std::min(a, b), std::max(a, b), t, k};
    }
  std::sort(half.begin(), half.end(), [](const HalfEdge& x, const HalfEdge& y) {
    return std::tie(x.lo, x.hi, x.triangle) < std::tie(y.lo, y.hi, y.triangle);
  });
  std::vector<std::array<int, 2>> edges;
  std::vector<std::array<int, 2>> edge_triangles;
  mesh.triangle_edges.resize(3, nt);
  mesh.triangle_edge_signs.resize(3, nt);
  for (std::size_t i = 0; i < half.size();) {
    std::size_t j = i;
    while (j < half.size() && half[j].lo == half[i].lo && half[j].hi == half[i].hi) ++j;
    if (j - i > 2)
      throw std::invalid_argument("domain mesh: edge (" + std::to_string(half[i].lo) + ", " +
                                  std::to_string(half[i].hi) + ") is shared by more than two triangles");
    const int a = half[i].lo, b = half[i].hi;
    const bool forward = IsGlobalEdgeDirection(mesh.vertices.col(a), mesh.vertices.col(b));
    const std::array<int, 2> edge = forward ? std::array<int, 2>{a, b} : std::array<int, 2>{b, a};
    const int e = static_cast<int>(edges.size());
    edges.push_back(edge);
    std::array<int, 2> adjacent{-1, -1};
    int sign_sum = 0;
    for (std::size_t k = i; k < j; ++k) {
      const HalfEdge& h = half[k];
      // The element runs its local edge from triangles(local) to triangles(local + 1); its interior is on the
      // left. Along the global direction the global normal (the tangent turned counter-clockwise) then points
      // inwards: sign -1; against it, outwards: +1.
      const bool along = mesh.triangles(h.local, h.triangle) == edge[0];
      mesh.triangle_edges(h.local, h.triangle) = e;
      mesh.triangle_edge_signs(h.local, h.triangle) = along ? -1 : 1;
      sign_sum += along ? -1 : 1;
      adjacent[k - i] = h.triangle;
    }
    if (j - i == 2 && sign_sum != 0)
      throw std::invalid_argument("domain mesh: the two triangles on edge (" + std::to_string(a) + ", " +
                                  std::to_string(b) + ") overlap (they run the edge the same way)");
    edge_triangles.push_back(adjacent);
    i = j;
  }
  const int ne = static_cast<int>(edges.size());
  mesh.edges.resize(2, ne);
  mesh.edge_triangles.resize(2, ne);
  mesh.boundary_edge.assign(static_cast<std::size_t>(ne), false);
  mesh.boundary_vertex.assign(static_cast<std::size_t>(nv), false);
  mesh.edge_segment = Eigen::VectorXi::Constant(ne, -1);
  // Boundary edges lie on the polygon's segments: within 1e-9 of the domain's size, far above the rounding of
  // the points a mesher puts on a segment and far below any element size.
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> segments;
  for (const Eigen::Matrix2Xd* ring : Rings(polygon))
    for (Eigen::Index i = 0; i < ring->cols(); ++i)
      segments.emplace_back(ring->col(i), ring->col((i + 1) % ring->cols()));
  const double tolerance = 1e-9 * PolygonScale(polygon);
  auto distance_to_segment = [](const std::pair<Eigen::Vector2d, Eigen::Vector2d>& s,
                                const Eigen::Vector2d& p) {
    const Eigen::Vector2d d = s.second - s.first;
    const double t = std::clamp((p - s.first).dot(d) / d.squaredNorm(), 0.0, 1.0);
    return (s.first + t * d - p).norm();
  };
  for (int e = 0; e < ne; ++e) {
    mesh.edges(0, e) = edges[static_cast<std::size_t>(e)][0];
    mesh.edges(1, e) = edges[static_cast<std::size_t>(e)][1];
    mesh.edge_triangles(0, e) = edge_triangles[static_cast<std::size_t>(e)][0];
    mesh.edge_triangles(1, e) = edge_triangles[static_cast<std::size_t>(e)][1];
    if (mesh.edge_triangles(1, e) >= 0) continue;
    mesh.boundary_edge[static_cast<std::size_t>(e)] = true;
    const Eigen::Vector2d p = mesh.vertices.col(mesh.edges(0, e)), q = mesh.vertices.col(mesh.edges(1, e));
    mesh.boundary_vertex[static_cast<std::size_t>(mesh.edges(0, e))] = true;
    mesh.boundary_vertex[static_cast<std::size_t>(mesh.edges(1, e))] = true;
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t s = 0; s < segments.size(); ++s) {
      const double d = std::max(distance_to_segment(segments[s], p), distance_to_segment(segments[s], q));
      if (d < best) {
        best = d;
        mesh.edge_segment(e) = static_cast<int>(s);
      }
    }
    if (!(best <= tolerance))
      throw std::invalid_argument("domain mesh: boundary edge (" + std::to_string(mesh.edges(0, e)) + ", " +
                                  std::to_string(mesh.edges(1, e)) + ") lies on no polygon segment");
  }
  mesh.numbering = NumberNodes(mesh);
  return mesh;
}

NodeNumbering NumberNodes(const DomainMesh& mesh) {
  const int nv = mesh.vertex_count(), n = mesh.node_count();
  // Node graph: the 6 nodes of each triangle mutually adjacent (docs/fe-surfaces.md section 1.4).
  std::vector<std::pair<int, int>> pairs;
  pairs.reserve(static_cast<std::size_t>(30 * mesh.triangle_count()));
  for (int t = 0; t < mesh.triangle_count(); ++t) {
    std::array<int, 6> nodes{};
    for (int k = 0; k < 3; ++k) {
      nodes[static_cast<std::size_t>(k)] = mesh.triangles(k, t);
      nodes[static_cast<std::size_t>(k) + 3] = nv + mesh.triangle_edges(k, t);
    }
    for (std::size_t i = 0; i < 6; ++i)
      for (std::size_t j = 0; j < 6; ++j)
        if (i != j) pairs.emplace_back(nodes[i], nodes[j]);
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  std::vector<int> start(static_cast<std::size_t>(n) + 1, 0), adjacency(pairs.size());
  for (const auto& [a, b] : pairs) ++start[static_cast<std::size_t>(a) + 1];
  std::partial_sum(start.begin(), start.end(), start.begin());
  for (std::size_t k = 0; k < pairs.size(); ++k) adjacency[k] = pairs[k].second;  // sorted by first
  auto degree = [&](int x) {
    return start[static_cast<std::size_t>(x) + 1] - start[static_cast<std::size_t>(x)];
  };

  NodeNumbering numbering;
  numbering.number = Eigen::VectorXi::Constant(n, -1);
  numbering.order.resize(n);
  std::vector<int> mark(static_cast<std::size_t>(n), 0);
  int stamp = 0, next = 0;
  auto by_degree = [&](int x, int y) { return std::make_pair(degree(x), x) < std::make_pair(degree(y), y); };
  while (next < n) {
    // A. Pseudo-diameter root (Gibbs, Poole and Stockmeyer 1976) in the component of an unnumbered node of
    // least degree.
    int v = -1;
    for (int x = 0; x < n; ++x)
      if (numbering.number(x) < 0 && (v < 0 || degree(x) < degree(v))) v = x;
    std::vector<std::vector<int>> levels_v = RootedLevels(v, start, adjacency, mark, stamp);
    std::vector<int> last;
    std::vector<std::vector<std::vector<int>>> candidates;
    while (true) {
      last = levels_v.back();
      std::sort(last.begin(), last.end(), by_degree);
      candidates.clear();
      bool deeper = false;
      for (const int s : last) {
        candidates.push_back(RootedLevels(s, start, adjacency, mark, stamp));
        if (candidates.back().size() > levels_v.size()) {
          v = s;
          levels_v = std::move(candidates.back());
          deeper = true;
          break;
        }
      }
      if (!deeper) break;
    }
    // Among v and its last level's nodes, the root whose level structure is narrowest.
    std::vector<std::vector<int>>* levels = &levels_v;
    for (std::vector<std::vector<int>>& c : candidates)
      if (Width(c) < Width(*levels)) levels = &c;
    numbering.level_width = std::max(numbering.level_width, Width(*levels));
    numbering.levels = std::max(numbering.levels, static_cast<int>(levels->size()));
    // B. Cuthill-McKee (1969) level by level: sorted by the lowest number of a numbered neighbour in the
    // previous level, then by ascending degree.
    for (std::size_t l = 0; l < levels->size(); ++l) {
      std::vector<std::array<int, 3>> keyed;
      for (const int x : (*levels)[l]) {
        int lowest = std::numeric_limits<int>::max();
        for (int k = start[static_cast<std::size_t>(x)]; k < start[static_cast<std::size_t>(x) + 1]; ++k) {
          const int y = numbering.number(adjacency[static_cast<std::size_t>(k)]);
          if (y >= 0) lowest = std::min(lowest, y);
        }
        keyed.push_back({l == 0 ? 0 : lowest, degree(x), x});
      }
      std::sort(keyed.begin(), keyed.end());
      for (const std::array<int, 3>& k : keyed) {
        numbering.number(k[2]) = next;
        numbering.order(next) = k[2];
        ++next;
      }
    }
  }
  Eigen::VectorXi identity(n);
  std::iota(identity.data(), identity.data() + n, 0);
  Bandwidths(pairs, identity, identity, nv, numbering.bandwidth_natural, numbering.dof_bandwidth_natural);
  Bandwidths(pairs, numbering.number, numbering.order, nv, numbering.bandwidth, numbering.dof_bandwidth);
  return numbering;
}

double TriangleMinAngle(const DomainMesh& mesh, int t) {
  double smallest = M_PI;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector2d p = mesh.vertices.col(mesh.triangles(k, t));
    const Eigen::Vector2d a = mesh.vertices.col(mesh.triangles((k + 1) % 3, t)) - p;
    const Eigen::Vector2d b = mesh.vertices.col(mesh.triangles((k + 2) % 3, t)) - p;
    smallest = std::min(smallest, std::atan2(std::abs(a.x() * b.y() - a.y() * b.x()), a.dot(b)));
  }
  return smallest;
}

double TriangleMaxEdge(const DomainMesh& mesh, int t) {
  double longest = 0.0;
  for (int k = 0; k < 3; ++k)
    longest = std::max(
        longest,
        (mesh.vertices.col(mesh.triangles((k + 1) % 3, t)) - mesh.vertices.col(mesh.triangles(k, t))).norm());
  return longest;
}

}  // namespace s2m
