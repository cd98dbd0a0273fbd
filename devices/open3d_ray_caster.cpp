// The only translation unit that sees Open3D (issue 5: Open3D headers at the edge, in one .cpp): the ray
// caster's acceleration structure (t::geometry::RaycastingScene, Embree) and the PLY mesh reader.

#include <open3d/core/Tensor.h>
#include <open3d/geometry/TriangleMesh.h>
#include <open3d/io/TriangleMeshIO.h>
#include <open3d/t/geometry/RaycastingScene.h>

#include <cmath>
#include <stdexcept>

#include "acquisition/format_error.h"
#include "devices/virtual_scanner.h"

namespace s2m {

namespace o3c = open3d::core;

namespace {

// Newton's method for the ray o + s d meeting the surface S(u, v) (face 0 of the model): solves
// S(u, v) - o - s d = 0 for (u, v, s) with the Jacobian [S_u, S_v, -d]. Converges quadratically from the
// tessellation's hit; false when it does not converge (a ray grazing the patch's boundary, where Evaluate
// clamps the parameters) or the step leaves the domain by more than a sliver.
bool RefineOnSurface(const ParametricModel& model, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                     Eigen::Vector2d uv, double s, double scale, Eigen::Vector3d& point, Eigen::Vector3d& normal,
                     double& distance) {
  const ParameterDomain domain = model.domain();
  LocalGeometry g;
  for (int iteration = 0; iteration < 30; ++iteration) {
    model.Evaluate({uv[0], uv[1], 0.0}, 1, g);
    const Eigen::Vector3d S = To3(g.point);
    const Eigen::Vector3d F = S - o - s * d;
    Eigen::Matrix3d J;
    J.col(0) = To3(g.d1.col(0));
    J.col(1) = To3(g.d1.col(1));
    J.col(2) = -d;
    if (F.norm() <= 1e-13 * scale) {
      point = S;
      normal = J.col(0).cross(J.col(1)).normalized();
      if (normal.dot(d) > 0) normal = -normal;
      distance = s;
      return std::isfinite(distance) && distance > 0;
    }
    const Eigen::Vector3d step = J.partialPivLu().solve(-F);
    if (!step.allFinite()) return false;
    uv += step.head<2>();
    s += step[2];
    for (int k = 0; k < 2; ++k) {
      if (domain.periodic[static_cast<std::size_t>(k)]) continue;
      const double lo = domain.lo[static_cast<std::size_t>(k)], hi = domain.hi[static_cast<std::size_t>(k)];
      if (uv[k] < lo - 1e-9 * (hi - lo) || uv[k] > hi + 1e-9 * (hi - lo)) return false;  // off the patch
    }
  }
  return false;
}

// The ray o + s d meeting the cylinder |(x - p) - ((x - p).a) a| = r, nearest root beyond 0 closest to the
// guess s0 (the faceted prism's hit).
bool RefineOnCylinder(const SceneMesh::Patch& c, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double s0,
                      Eigen::Vector3d& point, Eigen::Vector3d& normal, double& distance) {
  const Eigen::Vector3d a = c.axis_direction.normalized();
  const Eigen::Vector3d w = o - c.axis_point;
  const Eigen::Vector3d dp = d - d.dot(a) * a, wp = w - w.dot(a) * a;
  const double A = dp.squaredNorm(), B = 2 * dp.dot(wp), C = wp.squaredNorm() - c.radius * c.radius;
  const double disc = B * B - 4 * A * C;
  if (A <= 0 || disc < 0) return false;
  // Stable roots (Numerical Recipes 5.6).
  const double q = -0.5 * (B + std::copysign(std::sqrt(disc), B));
  const double r1 = q / A, r2 = q != 0 ? C / q : r1;
  double best = std::numeric_limits<double>::infinity();
  for (double r : {r1, r2}) {
    if (r > 0 && std::abs(r - s0) < std::abs(best - s0)) best = r;
  }
  if (!std::isfinite(best)) return false;
  distance = best;
  point = o + best * d;
  const Eigen::Vector3d radial = (point - c.axis_point) - (point - c.axis_point).dot(a) * a;
  normal = radial.normalized();
  if (normal.dot(d) > 0) normal = -normal;
  return true;
}

}  // namespace

struct RayCaster::Impl {
  open3d::t::geometry::RaycastingScene scene;
  double scale = 1.0;  // the scene's bounding diagonal: tolerances are relative to it
};

RayCaster::RayCaster(const SceneMesh& mesh) : mesh_(mesh), impl_(std::make_unique<Impl>()) {
  if (mesh_.vertices.cols() == 0 || mesh_.triangles.cols() == 0)
    throw std::invalid_argument("ray caster: the scene has no triangles");
  if (!mesh_.triangle_patch.empty() && mesh_.triangle_patch.size() != static_cast<std::size_t>(mesh_.triangles.cols()))
    throw std::invalid_argument("ray caster: triangle_patch must have one entry per triangle");
  std::vector<float> vertices(static_cast<std::size_t>(mesh_.vertices.size()));
  for (Eigen::Index i = 0; i < mesh_.vertices.size(); ++i)
    vertices[static_cast<std::size_t>(i)] = static_cast<float>(mesh_.vertices.data()[i]);
  std::vector<std::uint32_t> triangles(static_cast<std::size_t>(mesh_.triangles.size()));
  for (Eigen::Index i = 0; i < mesh_.triangles.size(); ++i) {
    const int v = mesh_.triangles.data()[i];
    if (v < 0 || v >= mesh_.vertices.cols()) throw std::invalid_argument("ray caster: triangle index out of range");
    triangles[static_cast<std::size_t>(i)] = static_cast<std::uint32_t>(v);
  }
  const o3c::Tensor v(vertices, {mesh_.vertices.cols(), 3}, o3c::Float32);
  const o3c::Tensor t(triangles, {mesh_.triangles.cols(), 3}, o3c::UInt32);
  impl_->scene.AddTriangles(v, t);
  impl_->scale = (mesh_.vertices.rowwise().maxCoeff() - mesh_.vertices.rowwise().minCoeff()).norm();
}

RayCaster::~RayCaster() = default;

std::vector<RayHit> RayCaster::Cast(const Eigen::Matrix3Xd& origins, const Eigen::Matrix3Xd& directions) const {
  const Eigen::Index n = origins.cols();
  if (directions.cols() != n) throw std::invalid_argument("ray caster: origins and directions differ in count");
  std::vector<RayHit> hits(static_cast<std::size_t>(n));
  if (n == 0) return hits;
  std::vector<float> rays(static_cast<std::size_t>(6 * n));
  Eigen::Matrix3Xd unit(3, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    unit.col(i) = directions.col(i).normalized();
    for (int k = 0; k < 3; ++k) {
      rays[static_cast<std::size_t>(6 * i + k)] = static_cast<float>(origins(k, i));
      rays[static_cast<std::size_t>(6 * i + 3 + k)] = static_cast<float>(unit(k, i));
    }
  }
  auto result = impl_->scene.CastRays(o3c::Tensor(rays, {n, 6}, o3c::Float32));
  const std::vector<float> t_hit = result["t_hit"].ToFlatVector<float>();
  const std::vector<std::uint32_t> ids = result["primitive_ids"].ToFlatVector<std::uint32_t>();
  const std::vector<float> uvs = result["primitive_uvs"].ToFlatVector<float>();
  const std::uint32_t invalid = open3d::t::geometry::RaycastingScene::INVALID_ID();
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto si = static_cast<std::size_t>(i);
    if (ids[si] == invalid || !std::isfinite(t_hit[si])) continue;
    const int tri = static_cast<int>(ids[si]);
    const Eigen::Vector3d o = origins.col(i), d = unit.col(i);
    const auto idx = mesh_.triangles.col(tri);
    const Eigen::Vector3d a = mesh_.vertices.col(idx[0]), b = mesh_.vertices.col(idx[1]),
                          c = mesh_.vertices.col(idx[2]);
    const int patch = mesh_.triangle_patch.empty() ? -1 : mesh_.triangle_patch[static_cast<std::size_t>(tri)];
    RayHit& h = hits[si];
    if (patch < 0) {
      // The triangle's plane in double precision: exact for a plain mesh and for planar faces.
      Eigen::Vector3d normal = (b - a).cross(c - a);
      const double denominator = normal.dot(d);
      if (normal.norm() == 0 || denominator == 0) continue;
      h.distance = normal.dot(a - o) / denominator;
      if (!(h.distance > 0)) continue;
      h.point = o + h.distance * d;
      normal.normalize();
      h.normal = normal.dot(d) > 0 ? Eigen::Vector3d(-normal) : normal;
      h.hit = true;
      continue;
    }
    const SceneMesh::Patch& p = mesh_.patches.at(static_cast<std::size_t>(patch));
    if (p.type == SceneMesh::Patch::Type::kCylinder) {
      h.hit = RefineOnCylinder(p, o, d, t_hit[si], h.point, h.normal, h.distance);
      continue;
    }
    // Barycentric (Open3D: point = (1 - u - v) a + u b + v c) interpolation of the vertices' parameters.
    const double bu = uvs[2 * si], bv = uvs[2 * si + 1];
    const Eigen::Vector2d uv = (1 - bu - bv) * mesh_.vertex_parameters.col(idx[0]) +
                               bu * mesh_.vertex_parameters.col(idx[1]) + bv * mesh_.vertex_parameters.col(idx[2]);
    h.hit = RefineOnSurface(*p.model, o, d, uv, t_hit[si], impl_->scale, h.point, h.normal, h.distance);
  }
  return hits;
}

std::vector<bool> RayCaster::Visible(const Eigen::Matrix3Xd& points, const Eigen::Vector3d& viewpoint,
                                     double tolerance) const {
  const Eigen::Index n = points.cols();
  std::vector<bool> visible(static_cast<std::size_t>(n), false);
  if (n == 0) return visible;
  std::vector<float> rays(static_cast<std::size_t>(6 * n));
  std::vector<double> length(static_cast<std::size_t>(n));
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Vector3d d = points.col(i) - viewpoint;
    length[static_cast<std::size_t>(i)] = d.norm();
    for (int k = 0; k < 3; ++k) {
      rays[static_cast<std::size_t>(6 * i + k)] = static_cast<float>(viewpoint[k]);
      rays[static_cast<std::size_t>(6 * i + 3 + k)] = static_cast<float>(d[k] / d.norm());
    }
  }
  auto result = impl_->scene.CastRays(o3c::Tensor(rays, {n, 6}, o3c::Float32));
  const std::vector<float> t_hit = result["t_hit"].ToFlatVector<float>();
  for (std::size_t i = 0; i < static_cast<std::size_t>(n); ++i) visible[i] = t_hit[i] >= length[i] - tolerance;
  return visible;
}

SceneMesh ReadMeshPly(const std::filesystem::path& path, const std::string& units) {
  const std::string file = path.string();
  if (!std::filesystem::is_regular_file(path)) throw FormatError(file, "", "no such mesh file");
  open3d::geometry::TriangleMesh mesh;
  open3d::io::ReadTriangleMeshOptions options;
  options.print_progress = false;
  if (!open3d::io::ReadTriangleMesh(file, mesh, options)) throw FormatError(file, "", "Open3D cannot read this mesh");
  if (mesh.triangles_.empty()) throw FormatError(file, "", "the mesh has no triangles");
  SceneMesh out;
  out.units = units;
  out.vertices.resize(3, static_cast<Eigen::Index>(mesh.vertices_.size()));
  for (std::size_t i = 0; i < mesh.vertices_.size(); ++i) {
    if (!mesh.vertices_[i].allFinite())
      throw FormatError(file, "vertex " + std::to_string(i), "coordinate is not finite");
    out.vertices.col(static_cast<Eigen::Index>(i)) = mesh.vertices_[i];
  }
  out.triangles.resize(3, static_cast<Eigen::Index>(mesh.triangles_.size()));
  for (std::size_t i = 0; i < mesh.triangles_.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.triangles_[i][k];
      if (v < 0 || v >= out.vertices.cols())
        throw FormatError(file, "face " + std::to_string(i), "vertex index " + std::to_string(v) + " out of range");
    }
    out.triangles.col(static_cast<Eigen::Index>(i)) = mesh.triangles_[i];
  }
  return out;
}

}  // namespace s2m
