#include "fitting/triangle_mesh.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>
#include <utility>

namespace s2m {

std::string TriangleMesh::GroupName(int group) const {
  if (group_names.empty()) return "all";
  return group_names.at(static_cast<std::size_t>(group));
}

int TriangleMesh::FindGroup(const std::string& name) const {
  if (group_names.empty()) return name == "all" ? 0 : -1;
  for (std::size_t i = 0; i < group_names.size(); ++i)
    if (group_names[i] == name) return static_cast<int>(i);
  return -1;
}

bool TriangleMesh::IsValid(std::string* why) const {
  auto fail = [why](const std::string& text) {
    if (why != nullptr) *why = text;
    return false;
  };
  if (vertices.cols() == 0) return fail("the mesh has no vertices");
  if (triangles.cols() == 0) return fail("the mesh has no triangles");
  if (!vertices.allFinite()) return fail("a vertex coordinate is not finite");
  const Eigen::Index n = vertices.cols();
  bool some_area = false;
  for (Eigen::Index f = 0; f < triangles.cols(); ++f) {
    for (int k = 0; k < 3; ++k)
      if (triangles(k, f) < 0 || triangles(k, f) >= n)
        return fail("triangle " + std::to_string(f) + " refers to vertex " + std::to_string(triangles(k, f)) +
                    ", outside 0.." + std::to_string(n - 1));
    const Eigen::Vector3d a = vertices.col(triangles(0, f)), b = vertices.col(triangles(1, f)),
                          c = vertices.col(triangles(2, f));
    if ((b - a).cross(c - a).norm() > 0) some_area = true;
  }
  if (!some_area) return fail("every triangle has zero area");
  if (!groups.empty()) {
    if (static_cast<Eigen::Index>(groups.size()) != triangles.cols())
      return fail("the group list does not have one entry per triangle");
    for (int g : groups)
      if (g < 0 || g >= group_count()) return fail("a triangle's group index is out of range");
  }
  return true;
}

std::vector<double> TriangleMesh::GroupAreas() const {
  std::vector<double> areas(static_cast<std::size_t>(group_count()), 0.0);
  for (Eigen::Index f = 0; f < triangles.cols(); ++f) {
    const Eigen::Vector3d a = vertices.col(triangles(0, f)), b = vertices.col(triangles(1, f)),
                          c = vertices.col(triangles(2, f));
    areas[static_cast<std::size_t>(GroupOf(f))] += 0.5 * (b - a).cross(c - a).norm();
  }
  return areas;
}

Eigen::Vector3d ClosestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                       const Eigen::Vector3d& b, const Eigen::Vector3d& c, double& u,
                                       double& v, TriangleRegion& region) {
  // Ericson 2005, section 5.1.5: test the Voronoi regions of A, B, C, then of the edges, else the face.
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) {
    u = v = 0;
    region = TriangleRegion::kVertexA;
    return a;
  }
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) {
    u = 1;
    v = 0;
    region = TriangleRegion::kVertexB;
    return b;
  }
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    const double s = d1 / (d1 - d3);
    u = s;
    v = 0;
    region = TriangleRegion::kEdgeAB;
    return a + s * ab;
  }
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) {
    u = 0;
    v = 1;
    region = TriangleRegion::kVertexC;
    return c;
  }
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    const double s = d2 / (d2 - d6);
    u = 0;
    v = s;
    region = TriangleRegion::kEdgeCA;
    return a + s * ac;
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double s = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    u = 1 - s;
    v = s;
    region = TriangleRegion::kEdgeBC;
    return b + s * (c - b);
  }
  const double denom = va + vb + vc;
  if (!(std::abs(denom) > 0)) {  // a degenerate triangle: its nearest vertex
    const double da = (p - a).squaredNorm(), db = (p - b).squaredNorm(), dc = (p - c).squaredNorm();
    if (da <= db && da <= dc) {
      u = v = 0;
      region = TriangleRegion::kVertexA;
      return a;
    }
    if (db <= dc) {
      u = 1;
      v = 0;
      region = TriangleRegion::kVertexB;
      return b;
    }
    u = 0;
    v = 1;
    region = TriangleRegion::kVertexC;
    return c;
  }
  u = vb / denom;
  v = vc / denom;
  region = TriangleRegion::kFace;
  return a + u * ab + v * ac;
}

TriangleMeshModel::TriangleMeshModel(TriangleMesh mesh) : mesh_(std::move(mesh)) {
  std::string why;
  if (!mesh_.IsValid(&why)) throw std::invalid_argument("not a usable mesh: " + why);
  Build();
}

TriangleMeshModel::TriangleMeshModel(const TriangleMeshModel& other) = default;
TriangleMeshModel& TriangleMeshModel::operator=(const TriangleMeshModel& other) = default;
TriangleMeshModel::~TriangleMeshModel() = default;

std::unique_ptr<ParametricModel> TriangleMeshModel::Clone() const {
  return std::make_unique<TriangleMeshModel>(*this);
}

void TriangleMeshModel::CopyFrom(const ParametricModel& other) {
  *this = dynamic_cast<const TriangleMeshModel&>(other);
}

ParameterDomain TriangleMeshModel::domain() const {
  ParameterDomain d;
  d.dimension = 2;
  return d;
}

std::string TriangleMeshModel::parameter_name(int index) const {
  throw std::out_of_range("a mesh has no parameters (asked for " + std::to_string(index) + ")");
}

void TriangleMeshModel::set_parameters(const Eigen::VectorXd& p) {
  if (p.size() != 0) throw std::invalid_argument("a mesh has no parameters");
}

void TriangleMeshModel::ApplySimilarity(double scale, const VecS& offset) {
  mesh_.vertices = (scale * mesh_.vertices).colwise() + To3(offset);
  Build();
}

void TriangleMeshModel::Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const {
  const auto f = std::clamp<Eigen::Index>(static_cast<Eigen::Index>(t[2]), 0, mesh_.triangle_count() - 1);
  const Eigen::Vector3d a = mesh_.vertices.col(mesh_.triangles(0, f)),
                        b = mesh_.vertices.col(mesh_.triangles(1, f)),
                        c = mesh_.vertices.col(mesh_.triangles(2, f));
  out.point = a + t[0] * (b - a) + t[1] * (c - a);
  if (derivatives >= 1) {
    out.d1.resize(3, 2);
    out.d1.col(0) = b - a;
    out.d1.col(1) = c - a;
  }
  if (derivatives >= 2) out.d2 = MatS::Zero(3, 3);
}

void TriangleMeshModel::ShapeJacobian(const ParamT& /*t*/, bool /*with_dt*/,
                                      std::vector<JacobianEntry>& out) const {
  out.clear();
}

std::vector<ParamT> TriangleMeshModel::SampleParameters() const {
  std::vector<ParamT> out;
  out.reserve(static_cast<std::size_t>(mesh_.triangle_count()));
  for (Eigen::Index f = 0; f < mesh_.triangle_count(); ++f)
    out.push_back({1.0 / 3.0, 1.0 / 3.0, static_cast<double>(f)});
  return out;
}

bool TriangleMeshModel::ClosedFormFootPoint(const VecS& x, ParamT& t) const {
  const MeshFoot foot = Foot(To3(x));
  t = {foot.u, foot.v, static_cast<double>(foot.triangle)};
  return true;
}

bool TriangleMeshModel::ClosedFormFoot(const VecS& x, ParamT& t, double& distance, bool& on_boundary,
                                       bool& ambiguous) const {
  const MeshFoot foot = Foot(To3(x));
  t = {foot.u, foot.v, static_cast<double>(foot.triangle)};
  distance = foot.distance;
  on_boundary = false;
  ambiguous = false;
  return true;
}

void TriangleMeshModel::Build() {
  const Eigen::Index m = mesh_.triangle_count();
  face_normals_.resize(3, m);
  edge_normals_ = Eigen::Matrix3Xd::Zero(3, 3 * m);
  vertex_normals_ = Eigen::Matrix3Xd::Zero(3, mesh_.vertices.cols());
  // Edges shared by faces: the sum of their normals (one entry per undirected edge).
  std::map<std::pair<int, int>, Eigen::Vector3d> edge_sum;
  for (Eigen::Index f = 0; f < m; ++f) {
    const Eigen::Vector3d a = mesh_.vertices.col(mesh_.triangles(0, f)),
                          b = mesh_.vertices.col(mesh_.triangles(1, f)),
                          c = mesh_.vertices.col(mesh_.triangles(2, f));
    Eigen::Vector3d n = (b - a).cross(c - a);
    const double norm = n.norm();
    n = norm > 0 ? Eigen::Vector3d(n / norm) : Eigen::Vector3d::Zero();
    face_normals_.col(f) = n;
    const std::array<Eigen::Vector3d, 3> p{a, b, c};
    for (int k = 0; k < 3; ++k) {
      const int i = mesh_.triangles(k, f), j = mesh_.triangles((k + 1) % 3, f);
      auto [it, inserted] = edge_sum.try_emplace({std::min(i, j), std::max(i, j)}, Eigen::Vector3d::Zero());
      it->second += n;
      // The angle at vertex k.
      const Eigen::Vector3d e1 = p[static_cast<std::size_t>((k + 1) % 3)] - p[static_cast<std::size_t>(k)],
                            e2 = p[static_cast<std::size_t>((k + 2) % 3)] - p[static_cast<std::size_t>(k)];
      const double angle = std::atan2(e1.cross(e2).norm(), e1.dot(e2));
      vertex_normals_.col(mesh_.triangles(k, f)) += angle * n;
    }
  }
  for (Eigen::Index f = 0; f < m; ++f)
    for (int k = 0; k < 3; ++k) {
      const int i = mesh_.triangles(k, f), j = mesh_.triangles((k + 1) % 3, f);
      edge_normals_.col(3 * f + k) = edge_sum.at({std::min(i, j), std::max(i, j)});
    }
  order_.resize(static_cast<std::size_t>(m));
  for (Eigen::Index f = 0; f < m; ++f) order_[static_cast<std::size_t>(f)] = static_cast<int>(f);
  nodes_.clear();
  nodes_.reserve(static_cast<std::size_t>(2 * m));
  BuildNode(0, static_cast<int>(m));
}

// A binary tree of axis-aligned boxes: split at the median of the triangles' centroids along the box's
// longest axis, leaves of at most 4 triangles.
int TriangleMeshModel::BuildNode(int begin, int end) {
  const int index = static_cast<int>(nodes_.size());
  nodes_.emplace_back();
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  Eigen::Vector3d clo = lo, chi = hi;
  auto centroid = [this](int f) {
    return Eigen::Vector3d((mesh_.vertices.col(mesh_.triangles(0, f)) +
                            mesh_.vertices.col(mesh_.triangles(1, f)) +
                            mesh_.vertices.col(mesh_.triangles(2, f))) /
                           3.0);
  };
  for (int i = begin; i < end; ++i) {
    const int f = order_[static_cast<std::size_t>(i)];
    for (int k = 0; k < 3; ++k) {
      lo = lo.cwiseMin(mesh_.vertices.col(mesh_.triangles(k, f)));
      hi = hi.cwiseMax(mesh_.vertices.col(mesh_.triangles(k, f)));
    }
    clo = clo.cwiseMin(centroid(f));
    chi = chi.cwiseMax(centroid(f));
  }
  nodes_[static_cast<std::size_t>(index)].lo = lo;
  nodes_[static_cast<std::size_t>(index)].hi = hi;
  if (end - begin <= 4) {
    nodes_[static_cast<std::size_t>(index)].begin = begin;
    nodes_[static_cast<std::size_t>(index)].end = end;
    return index;
  }
  int axis = 0;
  (chi - clo).maxCoeff(&axis);
  const int mid = begin + (end - begin) / 2;
  std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                   [&](int f, int g) { return centroid(f)[axis] < centroid(g)[axis]; });
  const int left = BuildNode(begin, mid);
  const int right = BuildNode(mid, end);
  nodes_[static_cast<std::size_t>(index)].left = left;
  nodes_[static_cast<std::size_t>(index)].right = right;
  return index;
}

Eigen::Vector3d TriangleMeshModel::PseudoNormal(Eigen::Index f, TriangleRegion region) const {
  switch (region) {
    case TriangleRegion::kFace:
      return face_normals_.col(f);
    case TriangleRegion::kEdgeAB:
      return edge_normals_.col(3 * f);
    case TriangleRegion::kEdgeBC:
      return edge_normals_.col(3 * f + 1);
    case TriangleRegion::kEdgeCA:
      return edge_normals_.col(3 * f + 2);
    case TriangleRegion::kVertexA:
      return vertex_normals_.col(mesh_.triangles(0, f));
    case TriangleRegion::kVertexB:
      return vertex_normals_.col(mesh_.triangles(1, f));
    case TriangleRegion::kVertexC:
      return vertex_normals_.col(mesh_.triangles(2, f));
  }
  return face_normals_.col(f);
}

MeshFoot TriangleMeshModel::Foot(const Eigen::Vector3d& x) const {
  MeshFoot best;
  double best_d2 = std::numeric_limits<double>::infinity();
  // Depth-first, nearer child first, boxes farther than the best foot so far skipped.
  int stack[128];
  int top = 0;
  stack[top++] = 0;
  auto box_d2 = [&x](const Node& n) {
    const Eigen::Vector3d d = (n.lo - x).cwiseMax(x - n.hi).cwiseMax(0.0);
    return d.squaredNorm();
  };
  while (top > 0) {
    const Node& node = nodes_[static_cast<std::size_t>(stack[--top])];
    if (box_d2(node) >= best_d2) continue;
    if (node.left < 0) {
      for (int i = node.begin; i < node.end; ++i) {
        const int f = order_[static_cast<std::size_t>(i)];
        double u = 0, v = 0;
        TriangleRegion region = TriangleRegion::kFace;
        const Eigen::Vector3d p = ClosestPointOnTriangle(
            x, mesh_.vertices.col(mesh_.triangles(0, f)), mesh_.vertices.col(mesh_.triangles(1, f)),
            mesh_.vertices.col(mesh_.triangles(2, f)), u, v, region);
        const double d2 = (p - x).squaredNorm();
        if (d2 < best_d2) {
          best_d2 = d2;
          best.point = p;
          best.triangle = f;
          best.u = u;
          best.v = v;
          best.region = region;
        }
      }
      continue;
    }
    const Node& l = nodes_[static_cast<std::size_t>(node.left)];
    const Node& r = nodes_[static_cast<std::size_t>(node.right)];
    const double dl = box_d2(l), dr = box_d2(r);
    // Push the farther child first so the nearer one is searched first. The depth is at most about
    // log2(triangles / 4) + 1, far below the stack's size for any mesh that fits in memory.
    if (dl < dr) {
      if (dr < best_d2) stack[top++] = node.right;
      if (dl < best_d2) stack[top++] = node.left;
    } else {
      if (dl < best_d2) stack[top++] = node.left;
      if (dr < best_d2) stack[top++] = node.right;
    }
  }
  best.distance = std::sqrt(best_d2);
  const double side = PseudoNormal(best.triangle, best.region).dot(x - best.point);
  best.signed_distance = side < 0 ? -best.distance : best.distance;
  return best;
}

}  // namespace s2m
