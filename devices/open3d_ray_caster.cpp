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
                     Eigen::Vector2d uv, double s, double scale, Eigen::Vector3d& point,
                     Eigen::Vector3d& normal, double& distance) {
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
bool RefineOnCylinder(const SceneMesh::Patch& c, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                      double s0, Eigen::Vector3d& point, Eigen::Vector3d& normal, double& distance) {
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
  double scale = 1.0;      // the scene's bounding diagonal: tolerances are relative to it
  Eigen::Vector3d lo, hi;  // the scene's bounding box
  // Whether RaycastingScene::CastRays finds hits. Debian's Open3D 0.16 (libopen3d-dev 0.16.1+ds-2, linked to
  // Debian's Embree 3.13.5) returns no hit for any ray, even a ray straight at a single triangle, while its
  // point queries (ComputeClosestPoints, ComputeDistance) are right; measured in this project, cause not
  // established (a ray-mask mismatch between the two builds would explain it). So the caster probes CastRays
  // once and, when it misses, finds the first hits by sphere tracing on ComputeClosestPoints instead.
  bool cast_rays_works = false;
};

namespace {

// The first stage's answer for one ray: which triangle, where in it, how far.
struct Candidate {
  int triangle = -1;
  double u = 0, v = 0;  // barycentric: point = (1 - u - v) a + u b + v c
  double t = 0;         // approximate distance along the unit direction
};

}  // namespace

// The double-precision hit on the triangle's exact surface; false when the ray does not meet it there, or
// meets it farther than `window` from the first stage's distance.
static bool Refine(const SceneMesh& mesh, double scale, const Candidate& c, const Eigen::Vector3d& o,
                   const Eigen::Vector3d& d, double window, RayHit& h) {
  const auto idx = mesh.triangles.col(c.triangle);
  const Eigen::Vector3d a = mesh.vertices.col(idx[0]), b = mesh.vertices.col(idx[1]),
                        p2 = mesh.vertices.col(idx[2]);
  const int patch =
      mesh.triangle_patch.empty() ? -1 : mesh.triangle_patch[static_cast<std::size_t>(c.triangle)];
  bool ok = false;
  if (patch < 0) {
    // Moeller-Trumbore in double precision: exact for a plain mesh and for planar faces. A small tolerance on
    // the barycentric coordinates: a ray through an edge counts for both triangles.
    const Eigen::Vector3d e1 = b - a, e2 = p2 - a, pv = d.cross(e2);
    const double det = e1.dot(pv);
    if (std::abs(det) <= 1e-300) return false;
    const Eigen::Vector3d tv = o - a, qv = tv.cross(e1);
    const double bu = tv.dot(pv) / det, bv = d.dot(qv) / det, t = e2.dot(qv) / det;
    constexpr double kEdge = 1e-9;
    if (bu < -kEdge || bv < -kEdge || bu + bv > 1 + kEdge || !(t > 0)) return false;
    h.distance = t;
    h.point = o + t * d;
    Eigen::Vector3d n = e1.cross(e2).normalized();
    h.normal = n.dot(d) > 0 ? Eigen::Vector3d(-n) : n;
    ok = true;
  } else {
    const SceneMesh::Patch& p = mesh.patches.at(static_cast<std::size_t>(patch));
    if (p.type == SceneMesh::Patch::Type::kCylinder) {
      ok = RefineOnCylinder(p, o, d, c.t, h.point, h.normal, h.distance);
    } else {
      const Eigen::Vector2d uv = (1 - c.u - c.v) * mesh.vertex_parameters.col(idx[0]) +
                                 c.u * mesh.vertex_parameters.col(idx[1]) +
                                 c.v * mesh.vertex_parameters.col(idx[2]);
      ok = RefineOnSurface(*p.model, o, d, uv, c.t, scale, h.point, h.normal, h.distance);
    }
  }
  h.hit = ok && std::abs(h.distance - c.t) <= window;
  return h.hit;
}

RayCaster::RayCaster(const SceneMesh& mesh) : mesh_(mesh), impl_(std::make_unique<Impl>()) {
  if (mesh_.vertices.cols() == 0 || mesh_.triangles.cols() == 0)
    throw std::invalid_argument("ray caster: the scene has no triangles");
  if (!mesh_.triangle_patch.empty() &&
      mesh_.triangle_patch.size() != static_cast<std::size_t>(mesh_.triangles.cols()))
    throw std::invalid_argument("ray caster: triangle_patch must have one entry per triangle");
  if (!mesh_.vertices.allFinite()) throw std::invalid_argument("ray caster: a vertex is not finite");
  std::vector<float> vertices(static_cast<std::size_t>(mesh_.vertices.size()));
  for (Eigen::Index i = 0; i < mesh_.vertices.size(); ++i)
    vertices[static_cast<std::size_t>(i)] = static_cast<float>(mesh_.vertices.data()[i]);
  std::vector<std::uint32_t> triangles(static_cast<std::size_t>(mesh_.triangles.size()));
  for (Eigen::Index i = 0; i < mesh_.triangles.size(); ++i) {
    const int v = mesh_.triangles.data()[i];
    if (v < 0 || v >= mesh_.vertices.cols())
      throw std::invalid_argument("ray caster: triangle index out of range");
    triangles[static_cast<std::size_t>(i)] = static_cast<std::uint32_t>(v);
  }
  const o3c::Tensor v(vertices, {mesh_.vertices.cols(), 3}, o3c::Float32);
  const o3c::Tensor t(triangles, {mesh_.triangles.cols(), 3}, o3c::UInt32);
  impl_->scene.AddTriangles(v, t);
  impl_->lo = mesh_.vertices.rowwise().minCoeff();
  impl_->hi = mesh_.vertices.rowwise().maxCoeff();
  impl_->scale = (impl_->hi - impl_->lo).norm();
  // The probe: a ray from outside the scene straight at the centroid of the largest triangle.
  Eigen::Index largest = 0;
  double area = -1;
  for (Eigen::Index k = 0; k < mesh_.triangles.cols(); ++k) {
    const auto idx = mesh_.triangles.col(k);
    const double ak = (mesh_.vertices.col(idx[1]) - mesh_.vertices.col(idx[0]))
                          .cross(mesh_.vertices.col(idx[2]) - mesh_.vertices.col(idx[0]))
                          .norm();
    if (ak > area) {
      area = ak;
      largest = k;
    }
  }
  const auto idx = mesh_.triangles.col(largest);
  const Eigen::Vector3d a = mesh_.vertices.col(idx[0]), b = mesh_.vertices.col(idx[1]),
                        c = mesh_.vertices.col(idx[2]);
  const Eigen::Vector3d centroid = (a + b + c) / 3, normal = (b - a).cross(c - a).normalized();
  const Eigen::Vector3d origin = centroid + 2 * impl_->scale * normal;
  const std::vector<float> probe = {static_cast<float>(origin.x()),  static_cast<float>(origin.y()),
                                    static_cast<float>(origin.z()),  static_cast<float>(-normal.x()),
                                    static_cast<float>(-normal.y()), static_cast<float>(-normal.z())};
  auto result = impl_->scene.CastRays(o3c::Tensor(probe, {1, 6}, o3c::Float32));
  impl_->cast_rays_works = std::isfinite(result["t_hit"].ToFlatVector<float>()[0]);
}

RayCaster::~RayCaster() = default;

std::vector<RayHit> RayCaster::Cast(const Eigen::Matrix3Xd& origins,
                                    const Eigen::Matrix3Xd& directions) const {
  const Eigen::Index n = origins.cols();
  if (directions.cols() != n)
    throw std::invalid_argument("ray caster: origins and directions differ in count");
  std::vector<RayHit> hits(static_cast<std::size_t>(n));
  if (n == 0) return hits;
  Eigen::Matrix3Xd unit(3, n);
  for (Eigen::Index i = 0; i < n; ++i) unit.col(i) = directions.col(i).normalized();
  const double scale = impl_->scale;

  if (impl_->cast_rays_works) {
    std::vector<float> rays(static_cast<std::size_t>(6 * n));
    for (Eigen::Index i = 0; i < n; ++i) {
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
      const Candidate c{static_cast<int>(ids[si]), uvs[2 * si], uvs[2 * si + 1], t_hit[si]};
      // Embree's triangle, refined in double precision. A ray through an edge that lands just outside it in
      // double precision (beyond the 1e-9 barycentric tolerance) stays a miss: a rare dropout, never a wrong
      // point. (Not exercised on Debian's build, where CastRays finds no hits; see Impl.)
      Refine(mesh_, scale, c, origins.col(i), unit.col(i), std::numeric_limits<double>::infinity(), hits[si]);
    }
    return hits;
  }

  // Sphere tracing (Hart, The Visual Computer 12(10), 1996) on the unsigned distance to the mesh: from the
  // ray's entry into the scene's bounding box, step by the distance to the nearest triangle (never past a
  // surface); within `converged` of a triangle, refine on its exact surface. A ray that only passes close by
  // (the refinement finds no crossing there) steps on by `converged`.
  const double converged = 1e-4 * scale, window = 4 * converged;
  std::vector<double> t(static_cast<std::size_t>(n)), t_end(static_cast<std::size_t>(n));
  std::vector<Eigen::Index> active;
  const Eigen::Vector3d lo = impl_->lo - Eigen::Vector3d::Constant(2 * converged),
                        hi = impl_->hi + Eigen::Vector3d::Constant(2 * converged);
  for (Eigen::Index i = 0; i < n; ++i) {
    // Slabs (Kay and Kajiya, SIGGRAPH 1986).
    double t0 = 0, t1 = std::numeric_limits<double>::infinity();
    bool miss = false;
    for (int k = 0; k < 3 && !miss; ++k) {
      const double o = origins(k, i), d = unit(k, i);
      if (std::abs(d) < 1e-300) {
        miss = o < lo[k] || o > hi[k];
        continue;
      }
      double a = (lo[k] - o) / d, b = (hi[k] - o) / d;
      if (a > b) std::swap(a, b);
      t0 = std::max(t0, a);
      t1 = std::min(t1, b);
      miss = t0 > t1;
    }
    if (miss) continue;
    t[static_cast<std::size_t>(i)] = t0;
    t_end[static_cast<std::size_t>(i)] = t1;
    active.push_back(i);
  }
  constexpr int kMaxSteps = 400;
  for (int step = 0; step < kMaxSteps && !active.empty(); ++step) {
    const auto m = static_cast<std::int64_t>(active.size());
    std::vector<float> query(static_cast<std::size_t>(3 * m));
    for (std::size_t j = 0; j < active.size(); ++j) {
      const Eigen::Index i = active[j];
      const Eigen::Vector3d q = origins.col(i) + t[static_cast<std::size_t>(i)] * unit.col(i);
      for (int k = 0; k < 3; ++k) query[3 * j + static_cast<std::size_t>(k)] = static_cast<float>(q[k]);
    }
    auto result = impl_->scene.ComputeClosestPoints(o3c::Tensor(query, {m, 3}, o3c::Float32));
    const std::vector<float> closest = result["points"].ToFlatVector<float>();
    const std::vector<std::uint32_t> ids = result["primitive_ids"].ToFlatVector<std::uint32_t>();
    const std::vector<float> uvs = result["primitive_uvs"].ToFlatVector<float>();
    std::vector<Eigen::Index> still;
    for (std::size_t j = 0; j < active.size(); ++j) {
      const Eigen::Index i = active[j];
      const auto si = static_cast<std::size_t>(i);
      const Eigen::Vector3d q = origins.col(i) + t[si] * unit.col(i);
      const Eigen::Vector3d c(closest[3 * j], closest[3 * j + 1], closest[3 * j + 2]);
      const double distance = (c - q).norm();
      if (distance < converged) {
        const Candidate cand{static_cast<int>(ids[j]), uvs[2 * j], uvs[2 * j + 1], t[si]};
        if (Refine(mesh_, scale, cand, origins.col(i), unit.col(i), window, hits[si])) continue;
        hits[si] = RayHit{};
        t[si] += converged;
      } else {
        // Single-precision distances: step a hair short so that rounding never carries the ray through.
        t[si] += distance - 1e-6 * scale;
      }
      if (t[si] <= t_end[si]) still.push_back(i);
    }
    active.swap(still);
  }
  return hits;
}

std::vector<bool> RayCaster::Visible(const Eigen::Matrix3Xd& points, const Eigen::Vector3d& viewpoint,
                                     double tolerance) const {
  const Eigen::Index n = points.cols();
  const Eigen::Matrix3Xd origins = viewpoint.replicate(1, n);
  const Eigen::Matrix3Xd directions = points - origins;
  const std::vector<RayHit> hits = Cast(origins, directions);
  std::vector<bool> visible(static_cast<std::size_t>(n));
  for (Eigen::Index i = 0; i < n; ++i) {
    const RayHit& h = hits[static_cast<std::size_t>(i)];
    visible[static_cast<std::size_t>(i)] = !h.hit || h.distance >= directions.col(i).norm() - tolerance;
  }
  return visible;
}

SceneMesh ReadMeshPly(const std::filesystem::path& path, const std::string& units) {
  const std::string file = path.string();
  if (!std::filesystem::is_regular_file(path)) throw FormatError(file, "", "no such mesh file");
  open3d::geometry::TriangleMesh mesh;
  open3d::io::ReadTriangleMeshOptions options;
  options.print_progress = false;
  if (!open3d::io::ReadTriangleMesh(file, mesh, options))
    throw FormatError(file, "", "Open3D cannot read this mesh");
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
        throw FormatError(file, "face " + std::to_string(i),
                          "vertex index " + std::to_string(v) + " out of range");
    }
    out.triangles.col(static_cast<Eigen::Index>(i)) = mesh.triangles_[i];
  }
  return out;
}

}  // namespace s2m
