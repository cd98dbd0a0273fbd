#pragma once
// The parameter domain of a triangular finite-element surface (L. Fang, MIT PhD thesis 1994, sections 4.2.1,
// 4.3 and 5.4; docs/fe-surfaces.md section 1): a polygon in the (u, v) plane triangulated by constrained
// Delaunay refinement with a size function, and the mesh's finite-element topology: unique edges in Fang's
// global orientation (eq. D2), each triangle's edges in the element's local order with their signs, and the
// nodes (vertices and mid-edge nodes) numbered for a small bandwidth (Gibbs-Poole-Stockmeyer start,
// Cuthill-McKee levels; eqs. D4-D6).
//
// The triangulation is CGAL's (2D Conforming Triangulations and Meshes); only domain_triangulation.cpp sees
// CGAL, this header is Eigen and the standard library.

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

namespace s2m {

// A domain polygon: the outer boundary counter-clockwise, and holes (either orientation) strictly inside it.
// Vertices are columns, the closing segment implied (the first vertex is not repeated). Segments are
// numbered outer first (segment k joins vertex k to k + 1), then each hole's the same way.
struct DomainPolygon {
  Eigen::Matrix2Xd outer;
  std::vector<Eigen::Matrix2Xd> holes;

  int vertex_count() const;   // outer and holes
  int segment_count() const;  // equals vertex_count()
  // Throws std::invalid_argument naming the first problem: fewer than 3 vertices in a ring, a non-finite
  // coordinate, a repeated vertex (a segment of zero length), zero area, a clockwise outer boundary, two
  // segments that intersect or touch (other than consecutive ones at their shared vertex), a hole outside
  // the outer boundary or inside another hole.
  void Validate() const;
};

// The largest minimum-angle bound for which Delaunay refinement is guaranteed to terminate (Shewchuk; CGAL's
// default shape bound B = sin^2(angle) = 0.125): asin(sqrt(0.125)) = 20.7048 degrees.
double MaxGuaranteedMinAngleDegrees();

struct DomainMeshOptions {
  // Bound on every triangle's longest edge (parameter units); 0: none.
  double max_edge = 0.0;
  // Optional local bound on the longest edge, evaluated at each triangle's centroid (must return a finite
  // positive value inside the domain); the triangle's bound is the smaller of this and max_edge.
  std::function<double(double u, double v)> size;
  // Triangles whose smallest angle is below this are refined (eq. D1) (degrees, in (0,
  // MaxGuaranteedMinAngleDegrees()]). Not guaranteed next to input angles below 60 degrees, nor next to the
  // boundary when it may not be split.
  double min_angle_degrees = 20.7;
  // true: boundary segments (outer and holes) may be split by new vertices where refinement needs it.
  // false: the boundary edges are exactly the input segments (e.g. when the boundary nodes are placed in
  // proportion to Hermite boundary curve elements, docs/fe-surfaces.md section 1.1); a triangle whose
  // refinement point would lie on the far side of, or encroach on, a boundary segment is then left as it is.
  bool split_boundary = true;
  // Refinement stops with std::invalid_argument when the mesh would exceed this many vertices.
  int max_vertices = 200000;

  bool IsValid(std::string* why = nullptr) const;
};

// Node numbering for the assembled system (docs/fe-surfaces.md section 1.4). Natural node order: vertex i is
// node i, the mid-edge node of edge e is node vertex_count + e.
struct NodeNumbering {
  Eigen::VectorXi number;         // natural node -> new number (0-based)
  Eigen::VectorXi order;          // new number -> natural node
  int bandwidth_natural = 0;      // max |i - j| over adjacent nodes, natural order (eq. D4)
  int bandwidth = 0;              // the same, new numbering
  int dof_bandwidth_natural = 0;  // dofs numbered node by node: 3 per vertex, 1 per mid-edge node (eq. D5)
  int dof_bandwidth = 0;
  int level_width = 0;  // width of the root's level structure: bandwidth <= 2 level_width - 1 (eq. D6)
  int levels = 0;       // its depth (number of levels); largest over components
};

struct DomainMesh {
  Eigen::Matrix2Xd vertices;   // (u, v); the polygon's vertices first, in DomainPolygon's order
  Eigen::Matrix3Xi triangles;  // counter-clockwise vertex triples
  // Unique edges, each (start, end) in the global orientation of eq. D2: end - start has a positive u
  // component, or (parallel to the v axis) a negative v component; the edge normal is the tangent turned
  // counter-clockwise, so its v component is positive (its u component positive for edges parallel to v).
  Eigen::Matrix2Xi edges;
  // Per triangle, its edges in the element's local order (vertex 0-1, 1-2, 2-0) and their signs (eq. D3): +1
  // when the global edge normal is the element's outward normal on that edge, -1 when it points into it.
  Eigen::Matrix3Xi triangle_edges;
  Eigen::Matrix3Xi triangle_edge_signs;
  Eigen::Matrix2Xi edge_triangles;  // the 1 or 2 triangles on each edge (-1: none, boundary edges)
  std::vector<bool> boundary_vertex, boundary_edge;
  // Per edge, the input polygon segment it lies on (DomainPolygon's numbering), -1 for interior edges.
  Eigen::VectorXi edge_segment;
  int polygon_vertex_count = 0;  // vertices [0, polygon_vertex_count) are the polygon's
  int hole_count = 0;
  NodeNumbering numbering;
  // Triangles that do not meet the options' angle or size bound (MeshDomain and RefineDomainMesh; edges 1e-9
  // relative above the bound tolerated): none unless split_boundary is false or the polygon has input angles
  // below 60 degrees.
  int triangles_off_bounds = 0;

  int vertex_count() const { return static_cast<int>(vertices.cols()); }
  int triangle_count() const { return static_cast<int>(triangles.cols()); }
  int edge_count() const { return static_cast<int>(edges.cols()); }
  int node_count() const { return vertex_count() + edge_count(); }
};

// The edge's global tangent for vertices a and b: true when a -> b is the global direction (eq. D2).
bool IsGlobalEdgeDirection(const Eigen::Vector2d& a, const Eigen::Vector2d& b);

// Triangulates the polygon (DomainPolygon::Validate first; std::invalid_argument on bad input or options, or
// when refinement would exceed max_vertices) and builds the topology and the node numbering.
DomainMesh MeshDomain(const DomainPolygon& polygon, const DomainMeshOptions& options);

// Refines an existing mesh of the polygon with new options (typically a size function from the fitted
// surface's curvature): every vertex of `mesh` is kept with its index, new vertices follow; the current
// boundary edges are the constraints (split again only when options.split_boundary).
DomainMesh RefineDomainMesh(const DomainPolygon& polygon, const DomainMesh& mesh,
                            const DomainMeshOptions& options);

// The topology of a triangulation of the polygon's domain: vertices (the polygon's first), counter-clockwise
// triangles; fills edges, signs, adjacency, boundary flags, segments and the numbering. Throws
// std::invalid_argument when the triangles are not a valid mesh (an edge shared by more than 2 triangles, a
// boundary edge on no polygon segment, a clockwise or degenerate triangle).
DomainMesh BuildDomainMesh(const DomainPolygon& polygon, Eigen::Matrix2Xd vertices,
                           Eigen::Matrix3Xi triangles);

// Gibbs-Poole-Stockmeyer pseudo-diameter root and Cuthill-McKee level numbering of the node graph in which
// the 6 nodes of each triangle (3 vertices, 3 mid-edge nodes) are mutually adjacent.
NodeNumbering NumberNodes(const DomainMesh& mesh);

// Smallest interior angle of triangle t (radians) and its longest edge.
double TriangleMinAngle(const DomainMesh& mesh, int t);
double TriangleMaxEdge(const DomainMesh& mesh, int t);

}  // namespace s2m
