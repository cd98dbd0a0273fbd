// The domain's triangulation by CGAL's 2D constrained Delaunay triangulation and Delaunay mesher (the 2D
// Conforming Triangulations and Meshes package; docs/fe-surfaces.md section 1.2): the only file that includes
// CGAL. CGAL is used header-only, without GMP (CGAL_DISABLE_GMP, set by fitting/CMakeLists.txt): the
// predicates' exact fallback is CGAL's own multiprecision floats, so nothing is added to the core's link
// line.

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Delaunay_mesh_criteria_2.h>
#include <CGAL/Delaunay_mesh_face_base_2.h>
#include <CGAL/Delaunay_mesh_vertex_base_2.h>
#include <CGAL/Delaunay_mesher_2.h>
#include <CGAL/Delaunay_mesher_no_edge_refinement_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <queue>
#include <stdexcept>
#include <utility>

#include "fitting/domain_mesh.h"

namespace s2m {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
struct VertexIndex {
  int index = -1;  // into DomainMesh::vertices; -1 until numbered
};
using VertexBase = CGAL::Triangulation_vertex_base_with_info_2<VertexIndex, Kernel,
                                                               CGAL::Delaunay_mesh_vertex_base_2<Kernel>>;
using FaceBase = CGAL::Delaunay_mesh_face_base_2<Kernel>;
using Tds = CGAL::Triangulation_data_structure_2<VertexBase, FaceBase>;
// Constraints must not intersect (DomainPolygon::Validate checks it first; CGAL throws otherwise).
using Cdt = CGAL::Constrained_Delaunay_triangulation_2<Kernel, Tds, CGAL::No_constraint_intersection_tag>;
using Point = Cdt::Point;

// The local bound on the longest edge: min(max_edge, size(u, v)), infinite when neither is given.
class SizeField {
 public:
  explicit SizeField(const DomainMeshOptions& options) : options_(options) {}
  double operator()(double u, double v) const {
    double h = options_.max_edge > 0 ? options_.max_edge : std::numeric_limits<double>::infinity();
    if (options_.size) {
      const double s = options_.size(u, v);
      if (!(s > 0) || !std::isfinite(s))
        throw std::invalid_argument("domain mesh: the size function returned " + std::to_string(s) + " at (" +
                                    std::to_string(u) + ", " + std::to_string(v) +
                                    "); it must be finite and positive");
      h = std::min(h, s);
    }
    return h;
  }

 private:
  const DomainMeshOptions& options_;
};

// Squared lengths of a triangle's longest and second longest edges, and twice its area.
struct TriangleMeasures {
  double longest_sq, second_sq, twice_area;
};
TriangleMeasures Measure(const Point& a, const Point& b, const Point& c) {
  std::array<double, 3> sq{CGAL::to_double(CGAL::squared_distance(b, c)),
                           CGAL::to_double(CGAL::squared_distance(c, a)),
                           CGAL::to_double(CGAL::squared_distance(a, b))};
  std::sort(sq.begin(), sq.end());
  return {sq[2], sq[1], 2 * CGAL::to_double(CGAL::area(a, b, c))};
}

// Criterion D1 of docs/fe-surfaces.md. Modelled on CGAL::Delaunay_mesh_size_criteria_2, with the size bound a
// function of the position (evaluated at the triangle's centroid). Quality: (squared sine of the smallest
// angle, squared longest edge over the squared local bound); a triangle is imperatively bad when too large,
// bad when too flat.
template <class Tr>
class SizeFieldCriteria : public CGAL::Delaunay_mesh_criteria_2<Tr> {
  using Base = CGAL::Delaunay_mesh_criteria_2<Tr>;
  using Traits = typename Tr::Geom_traits;

 public:
  using Face_handle = typename Tr::Face_handle;

  SizeFieldCriteria(double shape_bound, const SizeField* field) : Base(shape_bound), field_(field) {}

  struct Quality : public std::pair<double, double> {
    Quality() = default;
    Quality(double sine, double size) : std::pair<double, double>(sine, size) {}
    double sine() const { return first; }
    double size() const { return second; }
    // q1 < q2: q1 is refined first (the largest oversized triangle, then the flattest), as in CGAL's.
    bool operator<(const Quality& q) const {
      if (size() > 1) return q.size() > 1 ? size() > q.size() : true;
      if (q.size() > 1) return false;
      return sine() < q.sine();
    }
  };

  class Is_bad : public Base::Is_bad {
   public:
    Is_bad(double shape_bound, const SizeField* field, const Traits& geom_traits)
        : Base::Is_bad(shape_bound, geom_traits), field_(field) {}

    CGAL::Mesh_2::Face_badness operator()(const Quality q) const {
      if (q.size() > 1) return CGAL::Mesh_2::IMPERATIVELY_BAD;
      return q.sine() < this->B ? CGAL::Mesh_2::BAD : CGAL::Mesh_2::NOT_BAD;
    }

    CGAL::Mesh_2::Face_badness operator()(const Face_handle& fh, Quality& q) const {
      const Point& a = fh->vertex(0)->point();
      const Point& b = fh->vertex(1)->point();
      const Point& c = fh->vertex(2)->point();
      const TriangleMeasures m = Measure(a, b, c);
      const double h = (*field_)((a.x() + b.x() + c.x()) / 3, (a.y() + b.y() + c.y()) / 3);
      q.second = std::isinf(h) ? 0.0 : m.longest_sq / (h * h);
      q.first = q.second > 1 ? 1.0 : m.twice_area * m.twice_area / (m.longest_sq * m.second_sq);
      return (*this)(q);
    }

   private:
    const SizeField* field_;
  };

  Is_bad is_bad_object() const { return Is_bad(this->bound(), field_, this->traits); }

 private:
  const SizeField* field_;
};
using Criteria = SizeFieldCriteria<Cdt>;

// Faces inside the domain: those reached from the infinite face by crossing an odd number of constraints (the
// outer boundary once, a hole's boundary twice).
void MarkDomain(Cdt& cdt) {
  std::map<Cdt::Face_handle, int> nesting;
  std::vector<std::pair<Cdt::Face_handle, int>> border{{cdt.infinite_face(), 0}};
  while (!border.empty()) {
    const auto [start, depth] = border.back();
    border.pop_back();
    if (nesting.count(start)) continue;
    std::queue<Cdt::Face_handle> queue;
    queue.push(start);
    nesting[start] = depth;
    while (!queue.empty()) {
      const Cdt::Face_handle f = queue.front();
      queue.pop();
      f->set_in_domain(depth % 2 == 1);
      for (int i = 0; i < 3; ++i) {
        const Cdt::Face_handle g = f->neighbor(i);
        if (nesting.count(g)) continue;
        if (cdt.is_constrained(Cdt::Edge(f, i))) {
          border.emplace_back(g, depth + 1);
        } else {
          nesting[g] = depth;
          queue.push(g);
        }
      }
    }
  }
}

template <class Mesher>
void Refine(Cdt& cdt, const Criteria& criteria, int max_vertices) {
  Mesher mesher(cdt, criteria);
  mesher.init(/*domain_specified=*/true);
  while (!mesher.is_refinement_done()) {
    mesher.step_by_step_refine_mesh();
    if (cdt.number_of_vertices() > static_cast<std::size_t>(max_vertices))
      throw std::invalid_argument(
          "domain mesh: refinement would exceed max_vertices = " + std::to_string(max_vertices) +
          " (the size function or max_edge asks for finer elements)");
  }
}

// Triangulates the given vertices (the polygon's first) with the given constraints, refines, and builds the
// mesh's topology.
DomainMesh Triangulate(const DomainPolygon& polygon, const Eigen::Matrix2Xd& vertices,
                       const std::vector<std::array<int, 2>>& constraints, const DomainMeshOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument("domain mesh options: " + why);
  if (vertices.cols() > options.max_vertices)
    throw std::invalid_argument(
        "domain mesh: " + std::to_string(vertices.cols()) +
        " vertices given, more than max_vertices = " + std::to_string(options.max_vertices));
  Cdt cdt;
  std::vector<Cdt::Vertex_handle> handles;
  for (Eigen::Index i = 0; i < vertices.cols(); ++i) {
    Cdt::Vertex_handle h = cdt.insert(Point(vertices(0, i), vertices(1, i)));
    if (h->info().index >= 0)
      throw std::invalid_argument("domain mesh: vertices " + std::to_string(h->info().index) + " and " +
                                  std::to_string(i) + " coincide");
    h->info().index = static_cast<int>(i);
    handles.push_back(h);
  }
  try {
    for (const std::array<int, 2>& c : constraints)
      cdt.insert_constraint(handles[static_cast<std::size_t>(c[0])], handles[static_cast<std::size_t>(c[1])]);
  } catch (const CGAL::Failure_exception& e) {
    throw std::invalid_argument(std::string("domain mesh: boundary segments intersect (") + e.what() + ")");
  }
  MarkDomain(cdt);

  const SizeField field(options);
  const double shape_bound = std::pow(std::sin(options.min_angle_degrees * M_PI / 180.0), 2);
  const Criteria criteria(shape_bound, &field);
  if (options.split_boundary)
    Refine<CGAL::Delaunay_mesher_2<Cdt, Criteria>>(cdt, criteria, options.max_vertices);
  else
    Refine<CGAL::Delaunay_mesher_no_edge_refinement_2<Cdt, Criteria>>(cdt, criteria, options.max_vertices);

  int next = static_cast<int>(vertices.cols());
  for (Cdt::Finite_vertices_iterator v = cdt.finite_vertices_begin(); v != cdt.finite_vertices_end(); ++v)
    if (v->info().index < 0) v->info().index = next++;
  Eigen::Matrix2Xd uv(2, next);
  for (Cdt::Finite_vertices_iterator v = cdt.finite_vertices_begin(); v != cdt.finite_vertices_end(); ++v)
    uv.col(v->info().index) << v->point().x(), v->point().y();
  std::vector<std::array<int, 3>> faces;
  for (Cdt::Finite_faces_iterator f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f)
    if (f->is_in_domain())
      faces.push_back({f->vertex(0)->info().index, f->vertex(1)->info().index, f->vertex(2)->info().index});
  Eigen::Matrix3Xi triangles(3, static_cast<Eigen::Index>(faces.size()));
  for (std::size_t t = 0; t < faces.size(); ++t)
    triangles.col(static_cast<Eigen::Index>(t)) << faces[t][0], faces[t][1], faces[t][2];

  DomainMesh mesh = BuildDomainMesh(polygon, std::move(uv), std::move(triangles));
  // The bounds the result meets, measured as the criteria measure them (edges 1e-9 relative above the bound
  // tolerated: the bound is checked on squared lengths in floating point).
  for (int t = 0; t < mesh.triangle_count(); ++t) {
    const Point a(mesh.vertices(0, mesh.triangles(0, t)), mesh.vertices(1, mesh.triangles(0, t)));
    const Point b(mesh.vertices(0, mesh.triangles(1, t)), mesh.vertices(1, mesh.triangles(1, t)));
    const Point c(mesh.vertices(0, mesh.triangles(2, t)), mesh.vertices(1, mesh.triangles(2, t)));
    const TriangleMeasures m = Measure(a, b, c);
    const double h = field((a.x() + b.x() + c.x()) / 3, (a.y() + b.y() + c.y()) / 3);
    const bool too_flat = m.twice_area * m.twice_area / (m.longest_sq * m.second_sq) < shape_bound;
    const bool too_large = std::sqrt(m.longest_sq) > h * (1 + 1e-9);
    if (too_flat || too_large) ++mesh.triangles_off_bounds;
  }
  return mesh;
}

// The polygon's vertices in DomainPolygon's order, and its segments as vertex pairs.
Eigen::Matrix2Xd PolygonVertices(const DomainPolygon& polygon, std::vector<std::array<int, 2>>* segments) {
  Eigen::Matrix2Xd vertices(2, polygon.vertex_count());
  int k = 0;
  for (std::size_t r = 0; r <= polygon.holes.size(); ++r) {
    const Eigen::Matrix2Xd& ring = r == 0 ? polygon.outer : polygon.holes[r - 1];
    const int first = k, n = static_cast<int>(ring.cols());
    for (int i = 0; i < n; ++i, ++k) {
      vertices.col(k) = ring.col(i);
      if (segments) segments->push_back({k, first + (i + 1) % n});
    }
  }
  return vertices;
}

}  // namespace

DomainMesh MeshDomain(const DomainPolygon& polygon, const DomainMeshOptions& options) {
  polygon.Validate();
  std::vector<std::array<int, 2>> segments;
  const Eigen::Matrix2Xd vertices = PolygonVertices(polygon, &segments);
  return Triangulate(polygon, vertices, segments, options);
}

DomainMesh RefineDomainMesh(const DomainPolygon& polygon, const DomainMesh& mesh,
                            const DomainMeshOptions& options) {
  polygon.Validate();
  const Eigen::Matrix2Xd corners = PolygonVertices(polygon, nullptr);
  if (mesh.polygon_vertex_count != corners.cols() || mesh.vertex_count() < corners.cols() ||
      mesh.vertices.leftCols(corners.cols()) != corners)
    throw std::invalid_argument("domain mesh: the mesh to refine is not a mesh of this polygon");
  std::vector<std::array<int, 2>> constraints;
  for (int e = 0; e < mesh.edge_count(); ++e)
    if (mesh.boundary_edge[static_cast<std::size_t>(e)])
      constraints.push_back({mesh.edges(0, e), mesh.edges(1, e)});
  return Triangulate(polygon, mesh.vertices, constraints, options);
}

}  // namespace s2m
