#include "fitting/primitive_detection.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numeric>
#include <random>
#include <stdexcept>

#include "fitting/noise_estimate.h"
#include "registration/nearest_index.h"

namespace s2m {

const char* ToString(PrimitiveKind kind) {
  switch (kind) {
    case PrimitiveKind::kPlane:
      return "plane";
    case PrimitiveKind::kSphere:
      return "sphere";
    case PrimitiveKind::kCylinder:
      return "cylinder";
    case PrimitiveKind::kCone:
      return "cone";
    case PrimitiveKind::kTorus:
      return "torus";
  }
  return "?";
}

PrimitiveKind PrimitiveKindFromString(const std::string& name) {
  if (name == "plane") return PrimitiveKind::kPlane;
  if (name == "sphere") return PrimitiveKind::kSphere;
  if (name == "cylinder") return PrimitiveKind::kCylinder;
  if (name == "cone") return PrimitiveKind::kCone;
  if (name == "torus") return PrimitiveKind::kTorus;
  throw std::invalid_argument("'" + name +
                              "' is not a detectable model: plane, sphere, cylinder, cone or torus");
}

bool DetectionOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& text) {
    if (why) *why = text;
    return false;
  };
  if (kinds.empty()) return fail("no model to detect");
  if (max_instances < 1) return fail("max_instances must be at least 1");
  if (min_support < 0) return fail("min_support must be >= 0");
  if (!(epsilon >= 0.0) || !std::isfinite(epsilon)) return fail("epsilon must be >= 0 and finite");
  if (!(epsilon_noise_factor > 0.0)) return fail("epsilon_noise_factor must be > 0");
  if (!(alpha >= 0.0 && alpha < M_PI / 2)) return fail("alpha must be in [0, pi/2)");
  if (!(min_alpha > 0.0 && min_alpha <= max_alpha && max_alpha < M_PI / 2))
    return fail("need 0 < min_alpha <= max_alpha < pi/2");
  if (!(cluster_cell >= 0.0) || !std::isfinite(cluster_cell)) return fail("cluster_cell must be >= 0");
  if (normal_neighbours < 5) return fail("normal_neighbours must be at least 5");
  if (!(miss_probability > 0.0 && miss_probability < 1.0)) return fail("miss_probability must be in (0, 1)");
  if (max_draws < 100) return fail("max_draws must be at least 100");
  if (score_subset < 100) return fail("score_subset must be at least 100");
  if (refit_rounds < 0) return fail("refit_rounds must be >= 0");
  if (!(max_radius >= 0.0)) return fail("max_radius must be >= 0");
  if (!(min_cone_half_angle > 0.0 && min_cone_half_angle < max_cone_half_angle &&
        max_cone_half_angle < M_PI / 2))
    return fail("need 0 < min_cone_half_angle < max_cone_half_angle < pi/2");
  if (why) why->clear();
  return true;
}

// ---- Normals (eq. 53) -------------------------------------------------------------------------------

PointNormals EstimatePointNormals(const Eigen::Matrix3Xd& points, int neighbours) {
  const Eigen::Index n = points.cols();
  if (n < neighbours || neighbours < 3)
    throw std::invalid_argument("normals need at least " + std::to_string(neighbours) + " points");
  const NearestIndex index(points);
  PointNormals out;
  out.normals.resize(3, n);
  out.tangential_spread.resize(n);
  out.plane_residual.resize(n);
  out.nearest_distance.resize(n);
  out.neighbours = neighbours;
  out.neighbour_indices.resize(static_cast<std::size_t>(n * neighbours));
#pragma omp parallel for schedule(dynamic, 256)
  for (Eigen::Index i = 0; i < n; ++i) {
    const std::vector<Eigen::Index> near = index.KNearest(points.col(i), neighbours);
    std::copy(near.begin(), near.end(), out.neighbour_indices.begin() + i * neighbours);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (Eigen::Index j : near) mean += points.col(j);
    mean /= static_cast<double>(near.size());
    Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
    for (Eigen::Index j : near) {
      const Eigen::Vector3d d = points.col(j) - mean;
      scatter += d * d.transpose();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
    eig.computeDirect(scatter);
    out.normals.col(i) = eig.eigenvectors().col(0).normalized();
    out.tangential_spread[i] = std::sqrt(std::max(0.0, eig.eigenvalues()[1]));
    out.plane_residual[i] = std::sqrt(std::max(0.0, eig.eigenvalues()[0]) /
                                      std::max(1.0, static_cast<double>(near.size()) - 3.0));
    double nearest = std::numeric_limits<double>::infinity();
    for (Eigen::Index j : near)
      if (j != i) nearest = std::min(nearest, (points.col(j) - points.col(i)).norm());
    out.nearest_distance[i] = nearest;
  }
  return out;
}

// ---- Candidates from minimal sets (eqs. 49-52) ----------------------------------------------------------

std::optional<Plane> PlaneFromPoints(const Eigen::Vector3d& p1, const Eigen::Vector3d& p2,
                                     const Eigen::Vector3d& p3) {
  const Eigen::Vector3d n = (p2 - p1).cross(p3 - p1);
  const double scale = std::max((p2 - p1).squaredNorm(), (p3 - p1).squaredNorm());
  if (!(n.norm() > 1e-9 * scale) || !(scale > 0.0)) return std::nullopt;
  return Plane{p1, n.normalized()};
}

// Eq. 50: the centre is the midpoint of the shortest segment between the normal lines p1 + s n1 and
// p2 + t n2; the radius the mean distance of the two points from it.
std::optional<Sphere> SphereFromPointNormals(const Eigen::Vector3d& p1, const Eigen::Vector3d& n1,
                                             const Eigen::Vector3d& p2, const Eigen::Vector3d& n2) {
  const double b = n1.dot(n2);
  const double denominator = 1.0 - b * b;
  if (denominator < 1e-6) return std::nullopt;  // (nearly) parallel normals: no intersection
  const Eigen::Vector3d w = p1 - p2;
  const double d = n1.dot(w), e = n2.dot(w);
  const double s = (b * e - d) / denominator;
  const double t = (e - b * d) / denominator;
  const Eigen::Vector3d centre = 0.5 * ((p1 + s * n1) + (p2 + t * n2));
  const double radius = 0.5 * ((p1 - centre).norm() + (p2 - centre).norm());
  if (!(radius > 0.0) || !std::isfinite(radius)) return std::nullopt;
  return Sphere{centre, radius};
}

// Eq. 51: the axis is n1 x n2; in the plane perpendicular to it the normal lines intersect at the axis.
std::optional<Cylinder> CylinderFromPointNormals(const Eigen::Vector3d& p1, const Eigen::Vector3d& n1,
                                                 const Eigen::Vector3d& p2, const Eigen::Vector3d& n2) {
  Eigen::Vector3d axis = n1.cross(n2);
  if (axis.norm() < 1e-3) return std::nullopt;
  axis.normalize();
  const Eigen::Matrix3d frame = FrameWithAxis(axis);
  const Eigen::Vector2d q1 = (frame.transpose() * p1).head<2>(), q2 = (frame.transpose() * p2).head<2>();
  const Eigen::Vector2d m1 = (frame.transpose() * n1).head<2>(), m2 = (frame.transpose() * n2).head<2>();
  Eigen::Matrix2d a;
  a << m1, -m2;
  if (std::abs(a.determinant()) < 1e-6 * m1.norm() * m2.norm()) return std::nullopt;
  const Eigen::Vector2d st = a.inverse() * (q2 - q1);
  const Eigen::Vector2d c = 0.5 * ((q1 + st[0] * m1) + (q2 + st[1] * m2));
  const double radius = 0.5 * ((q1 - c).norm() + (q2 - c).norm());
  if (!(radius > 0.0) || !std::isfinite(radius)) return std::nullopt;
  const double along = 0.5 * axis.dot(p1 + p2);  // the axis point nearest the sample points
  const Eigen::Vector3d point = frame * Eigen::Vector3d(c[0], c[1], along);
  return Cylinder{point, axis, radius};
}

// Eq. 52: the apex is the common point of the three tangent planes n_i.(x - p_i) = 0; the unit vectors from
// it to the p_i end on a circle of the unit sphere whose plane's normal is the axis; the half-angle is their
// mean angle with the axis.
std::optional<Cone> ConeFromPointNormals(const Eigen::Vector3d& p1, const Eigen::Vector3d& n1,
                                         const Eigen::Vector3d& p2, const Eigen::Vector3d& n2,
                                         const Eigen::Vector3d& p3, const Eigen::Vector3d& n3) {
  Eigen::Matrix3d a;
  a.row(0) = n1.transpose();
  a.row(1) = n2.transpose();
  a.row(2) = n3.transpose();
  const Eigen::FullPivLU<Eigen::Matrix3d> lu(a);
  if (lu.rank() < 3 || std::abs(a.determinant()) < 1e-6) return std::nullopt;
  const Eigen::Vector3d apex = lu.solve(Eigen::Vector3d(n1.dot(p1), n2.dot(p2), n3.dot(p3)));
  const Eigen::Vector3d u1 = (p1 - apex).normalized(), u2 = (p2 - apex).normalized(),
                        u3 = (p3 - apex).normalized();
  Eigen::Vector3d axis = (u2 - u1).cross(u3 - u1);
  if (!(axis.norm() > 1e-9) || !apex.allFinite()) return std::nullopt;
  axis.normalize();
  if (axis.dot(u1 + u2 + u3) < 0) axis = -axis;  // towards the points: increasing radius
  const double half_angle =
      (std::acos(std::clamp(axis.dot(u1), -1.0, 1.0)) + std::acos(std::clamp(axis.dot(u2), -1.0, 1.0)) +
       std::acos(std::clamp(axis.dot(u3), -1.0, 1.0))) /
      3.0;
  if (!(half_angle > 0.0 && half_angle < M_PI / 2)) return std::nullopt;
  const double along = axis.dot((p1 + p2 + p3) / 3.0 - apex);
  if (!(along > 0.0)) return std::nullopt;
  return Cone{apex + along * axis, axis, half_angle, along * std::tan(half_angle)};
}

// Eq. 78. A line with direction d and moment m = p x d meets a line (d_i, m_i) (or is parallel to it) iff
// d.m_i + m.d_i = 0: four linear equations in (d, m), whose solutions form a pencil v0 + t v1 (the null
// space), of which the lines are those on the Klein quadric d.m = 0: a quadratic in t.
std::vector<Torus> TorusFromPointNormals(const std::array<Eigen::Vector3d, 4>& points,
                                         const std::array<Eigen::Vector3d, 4>& normals) {
  // Work relative to the points' mean, so that the moments stay of the points' spread.
  const Eigen::Vector3d origin = 0.25 * (points[0] + points[1] + points[2] + points[3]);
  Eigen::Matrix<double, 4, 6> a;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3d d = normals[static_cast<std::size_t>(i)].normalized();
    const Eigen::Vector3d m = (points[static_cast<std::size_t>(i)] - origin).cross(d);
    a.row(i) << m.transpose(), d.transpose();
  }
  const Eigen::JacobiSVD<Eigen::Matrix<double, 4, 6>> svd(a, Eigen::ComputeFullV);
  if (!(svd.singularValues()[3] > 1e-9 * svd.singularValues()[0])) return {};  // the lines are dependent
  const Eigen::Matrix<double, 6, 1> v0 = svd.matrixV().col(4), v1 = svd.matrixV().col(5);
  auto klein = [](const Eigen::Matrix<double, 6, 1>& u, const Eigen::Matrix<double, 6, 1>& w) {
    return 0.5 * (u.head<3>().dot(w.tail<3>()) + w.head<3>().dot(u.tail<3>()));
  };
  // Q(x v0 + y v1) = qa x^2 + qb x y + qc y^2 = 0 with (x, y) a unit vector.
  const double qa = klein(v0, v0), qb = 2.0 * klein(v0, v1), qc = klein(v1, v1);
  const double discriminant = qb * qb - 4.0 * qa * qc;
  if (discriminant < 0.0) return {};
  std::vector<Eigen::Matrix<double, 6, 1>> lines;
  const double root = std::sqrt(discriminant);
  if (std::abs(qc) >= std::abs(qa)) {  // x = 1, y = t: qa + qb t + qc t^2 = 0
    for (const double sign : {1.0, -1.0}) {
      const double t = (-qb + sign * root) / (2.0 * qc);
      lines.push_back(v0 + t * v1);
    }
  } else {
    for (const double sign : {1.0, -1.0}) {  // y = 1, x = t: qa t^2 + qb t + qc = 0
      const double t = (-qb + sign * root) / (2.0 * qa);
      lines.push_back(t * v0 + v1);
    }
  }
  std::vector<Torus> out;
  for (const auto& line : lines) {
    const Eigen::Vector3d d = line.head<3>(), m = line.tail<3>();
    if (!(d.norm() > 1e-9 * line.norm())) continue;
    const Eigen::Vector3d axis = d.normalized();
    const Eigen::Vector3d foot = origin + d.cross(m) / d.squaredNorm();  // the axis point nearest the origin
    // Meridian coordinates (rho, z) of each point and its normal's components (along e_rho, along the axis);
    // the normal line rho-z crosses the tube's centre (R, z0): w_i . ((R, z0) - q_i) = 0, w_i its normal.
    Eigen::Matrix<double, 4, 2> rows;
    Eigen::Vector4d rhs;
    std::array<Eigen::Vector2d, 4> q;
    bool ok = true;
    for (int i = 0; i < 4 && ok; ++i) {
      const Eigen::Vector3d v = points[static_cast<std::size_t>(i)] - foot;
      const double z = axis.dot(v);
      const Eigen::Vector3d radial = v - z * axis;
      const double rho = radial.norm();
      if (!(rho > 0.0)) {
        ok = false;
        break;
      }
      const Eigen::Vector3d e = radial / rho;
      const Eigen::Vector3d n = normals[static_cast<std::size_t>(i)];
      const Eigen::Vector2d w(-n.dot(axis), n.dot(e));
      q[static_cast<std::size_t>(i)] = Eigen::Vector2d(rho, z);
      rows.row(i) = w.transpose();
      rhs[i] = w.dot(q[static_cast<std::size_t>(i)]);
    }
    if (!ok) continue;
    const Eigen::ColPivHouseholderQR<Eigen::Matrix<double, 4, 2>> qr(rows);
    if (qr.rank() < 2) continue;
    const Eigen::Vector2d centre = qr.solve(rhs);
    double minor = 0.0;
    for (const Eigen::Vector2d& qi : q) minor += 0.25 * (qi - centre).norm();
    if (!(centre[0] > 0.0) || !(minor > 0.0) || !std::isfinite(minor)) continue;
    out.push_back(Torus{foot + centre[1] * axis, axis, centre[0], minor});
  }
  return out;
}

// ---- Distances and normals of candidates -----------------------------------------------------------------

double Distance(const DetectedShape& shape, const Eigen::Vector3d& x) {
  return std::visit([&](const auto& s) { return SignedDistance(s, x); }, shape);
}

namespace {

Eigen::Vector3d NormalOf(const Plane& s, const Eigen::Vector3d&) {
  return s.normal;
}
Eigen::Vector3d NormalOf(const Sphere& s, const Eigen::Vector3d& x) {
  return (x - s.center).normalized();
}
Eigen::Vector3d NormalOf(const Cylinder& s, const Eigen::Vector3d& x) {
  const Eigen::Vector3d v = x - s.axis_point;
  return (v - s.axis_direction.dot(v) * s.axis_direction).normalized();
}
// The gradient of Forbes' cone distance rho cos(psi) - z sin(psi) - s (primitives.cpp).
Eigen::Vector3d NormalOf(const Cone& s, const Eigen::Vector3d& x) {
  const Eigen::Vector3d v = x - s.axis_point;
  const Eigen::Vector3d radial = (v - s.axis_direction.dot(v) * s.axis_direction).normalized();
  return std::cos(s.half_angle) * radial - std::sin(s.half_angle) * s.axis_direction;
}

// The gradient of the torus's distance sqrt((rho - R)^2 + z^2) - r (primitives.cpp).
Eigen::Vector3d NormalOf(const Torus& s, const Eigen::Vector3d& x) {
  const Eigen::Vector3d v = x - s.center;
  const double z = s.axis.dot(v);
  const Eigen::Vector3d radial = v - z * s.axis;
  const double rho = radial.norm();
  const Eigen::Vector3d e = rho > 0 ? Eigen::Vector3d(radial / rho) : Eigen::Vector3d::Zero();
  return ((rho - s.major_radius) * e + z * s.axis).normalized();
}

}  // namespace

Eigen::Vector3d SurfaceNormal(const DetectedShape& shape, const Eigen::Vector3d& x) {
  return std::visit([&](const auto& s) { return NormalOf(s, x); }, shape);
}

namespace {

// The inlier test of eq. 54: |d| <= epsilon and the angle between the point's (unsigned) normal and the
// shape's normal at its foot point at most alpha. Cones also need the point on the nappe the axis opens into
// (beyond the apex), where Forbes' distance is the orthogonal one.
struct InlierTest {
  double epsilon = 0.0;
  double cos_alpha = 1.0;

  bool operator()(const DetectedShape& shape, const Eigen::Vector3d& x, const Eigen::Vector3d& n) const {
    if (const auto* cone = std::get_if<Cone>(&shape)) {
      if (cone->axis_direction.dot(x - cone->Apex()) <= 0.0) return false;
    }
    if (!(std::abs(Distance(shape, x)) <= epsilon)) return false;
    const Eigen::Vector3d m = SurfaceNormal(shape, x);
    return std::abs(m.dot(n)) >= cos_alpha;
  }
};

// Integer cell coordinates packed into one key (21 bits per axis).
constexpr int kKeyBits = 21;
constexpr std::int64_t kKeyCells = (std::int64_t{1} << kKeyBits) - 2;

struct CellGrid {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  double cell = 1.0;

  std::array<std::int64_t, 3> Coordinates(const Eigen::Vector3d& x) const {
    std::array<std::int64_t, 3> c;
    for (int a = 0; a < 3; ++a)
      c[static_cast<std::size_t>(a)] = std::clamp<std::int64_t>(
          static_cast<std::int64_t>(std::floor((x[a] - origin[a]) / cell)) + 1, 1, kKeyCells);
    return c;
  }
  static std::uint64_t KeyOf(const std::array<std::int64_t, 3>& c) {
    return (static_cast<std::uint64_t>(c[0]) << (2 * kKeyBits)) |
           (static_cast<std::uint64_t>(c[1]) << kKeyBits) | static_cast<std::uint64_t>(c[2]);
  }
  std::uint64_t Key(const Eigen::Vector3d& x) const { return KeyOf(Coordinates(x)); }
};

// A cell size no finer than the 21-bit keys allow over the extent.
double CoarsenToKeys(double cell, double extent) {
  return std::max(cell, extent / static_cast<double>(kKeyCells - 2));
}

// Eq. 56's connectivity: the largest 26-connected component of the points' grid cells (Schnabel et al.
// do it in the shape's parameter plane; the 3-D grid is the same test without a parametrization
// per kind). Ties go to the component with the lowest cell key, so the result does not depend on thread
// order. Returns indices of `candidates`' points, ascending.
std::vector<Eigen::Index> LargestComponent(const Eigen::Matrix3Xd& points,
                                           const std::vector<Eigen::Index>& candidates,
                                           const CellGrid& grid) {
  if (candidates.empty()) return {};
  std::vector<std::pair<std::uint64_t, Eigen::Index>> keyed(candidates.size());
  for (std::size_t i = 0; i < candidates.size(); ++i)
    keyed[i] = {grid.Key(Eigen::Vector3d(points.col(candidates[i]))), candidates[i]};
  std::sort(keyed.begin(), keyed.end());
  // Distinct cells and their point ranges.
  std::vector<std::uint64_t> cells;
  std::vector<std::size_t> begin;
  for (std::size_t i = 0; i < keyed.size(); ++i) {
    if (i == 0 || keyed[i].first != keyed[i - 1].first) {
      cells.push_back(keyed[i].first);
      begin.push_back(i);
    }
  }
  begin.push_back(keyed.size());
  const std::uint64_t mask = (std::uint64_t{1} << kKeyBits) - 1;
  std::vector<int> component(cells.size(), -1);
  std::vector<std::size_t> sizes;
  std::vector<std::size_t> stack;
  for (std::size_t start = 0; start < cells.size(); ++start) {
    if (component[start] >= 0) continue;
    const int id = static_cast<int>(sizes.size());
    sizes.push_back(0);
    component[start] = id;
    stack.assign(1, start);
    while (!stack.empty()) {
      const std::size_t c = stack.back();
      stack.pop_back();
      sizes[static_cast<std::size_t>(id)] += begin[c + 1] - begin[c];
      const std::int64_t cx = static_cast<std::int64_t>(cells[c] >> (2 * kKeyBits));
      const std::int64_t cy = static_cast<std::int64_t>((cells[c] >> kKeyBits) & mask);
      const std::int64_t cz = static_cast<std::int64_t>(cells[c] & mask);
      for (int dx = -1; dx <= 1; ++dx)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dz = -1; dz <= 1; ++dz) {
            if (dx == 0 && dy == 0 && dz == 0) continue;
            const std::uint64_t key = CellGrid::KeyOf({cx + dx, cy + dy, cz + dz});
            const auto it = std::lower_bound(cells.begin(), cells.end(), key);
            if (it == cells.end() || *it != key) continue;
            const auto k = static_cast<std::size_t>(it - cells.begin());
            if (component[k] >= 0) continue;
            component[k] = id;
            stack.push_back(k);
          }
    }
  }
  const auto largest = static_cast<int>(std::max_element(sizes.begin(), sizes.end()) - sizes.begin());
  std::vector<Eigen::Index> out;
  out.reserve(sizes[static_cast<std::size_t>(largest)]);
  for (std::size_t c = 0; c < cells.size(); ++c) {
    if (component[c] != largest) continue;
    for (std::size_t i = begin[c]; i < begin[c + 1]; ++i) out.push_back(keyed[i].second);
  }
  std::sort(out.begin(), out.end());
  return out;
}

// The octree of localized sampling (Schnabel et al., localized sampling), as one sorted cell list per level:
// level l has cells of side extent / 2^l; a minimal set is the first point plus points drawn from its cell at
// a level drawn uniformly.
class SamplingLevels {
 public:
  SamplingLevels(const Eigen::Matrix3Xd& points, double spacing) {
    const Eigen::Vector3d lo = points.rowwise().minCoeff(), hi = points.rowwise().maxCoeff();
    const double extent = std::max((hi - lo).maxCoeff(), 1e-300);
    // The finest level still holds tens of points of a surface: cells of at least 10 spacings.
    for (int l = 0; l < 16; ++l) {
      const double cell = extent / std::pow(2.0, l);
      if (l > 0 && cell < 10.0 * spacing) break;
      Level level;
      level.grid.origin = lo;
      level.grid.cell = l == 0 ? 2.0 * extent : CoarsenToKeys(cell, extent);
      level.keyed.resize(static_cast<std::size_t>(points.cols()));
      for (Eigen::Index i = 0; i < points.cols(); ++i)
        level.keyed[static_cast<std::size_t>(i)] = {level.grid.Key(Eigen::Vector3d(points.col(i))), i};
      std::sort(level.keyed.begin(), level.keyed.end());
      levels_.push_back(std::move(level));
    }
  }
  int count() const { return static_cast<int>(levels_.size()); }
  // The points sharing x's cell at `level`: a range of (key, index) pairs.
  std::pair<const std::pair<std::uint64_t, Eigen::Index>*, const std::pair<std::uint64_t, Eigen::Index>*>
  Cell(int level, const Eigen::Vector3d& x) const {
    const Level& l = levels_[static_cast<std::size_t>(level)];
    const std::uint64_t key = l.grid.Key(x);
    const auto lo = std::lower_bound(l.keyed.begin(), l.keyed.end(), std::make_pair(key, Eigen::Index{0}));
    const auto hi = std::lower_bound(lo, l.keyed.end(), std::make_pair(key + 1, Eigen::Index{0}));
    return {&*l.keyed.begin() + (lo - l.keyed.begin()), &*l.keyed.begin() + (hi - l.keyed.begin())};
  }

 private:
  struct Level {
    CellGrid grid;
    std::vector<std::pair<std::uint64_t, Eigen::Index>> keyed;
  };
  std::vector<Level> levels_;
};

int MinimalSetSize(PrimitiveKind kind) {
  if (kind == PrimitiveKind::kTorus) return 4;
  return kind == PrimitiveKind::kSphere || kind == PrimitiveKind::kCylinder ? 2 : 3;
}

// Eq. 57: the probability that one localized draw finds a shape of n points among N remaining, with d levels
// and a minimal set of k points: P(n) = n / (N d 2^(k-1)); after s draws it was missed with (1 - P)^s.
double MissProbability(double n, double remaining, int levels, int k, double draws) {
  const double p = std::min(1.0, n / (remaining * levels * std::pow(2.0, k - 1)));
  if (p >= 1.0) return 0.0;
  return std::exp(draws * std::log1p(-p));
}

struct Candidate {
  PrimitiveKind kind;
  DetectedShape shape;
};

struct Scored {
  Candidate candidate;
  std::vector<Eigen::Index> inliers;  // largest component, ascending
};

class Detector {
 public:
  Detector(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals, const PointNormals& graph,
           const DetectionOptions& options, DetectionResult& result, double extent)
      : points_(points),
        normals_(normals),
        graph_(graph),
        options_(options),
        result_(result),
        test_{result.epsilon, std::cos(result.alpha)},
        levels_(points, result.point_spacing),
        max_radius_(options.max_radius > 0 ? options.max_radius : extent),
        rng_(options.seed) {
    grid_.origin = points.rowwise().minCoeff();
    grid_.cell = result.cluster_cell > 0 ? CoarsenToKeys(result.cluster_cell, extent) : 0.0;
    result_.octree_levels = levels_.count();
    for (PrimitiveKind k : options.kinds) max_k_ = std::max(max_k_, MinimalSetSize(k));
  }

  void Run() {
    const Eigen::Index n = points_.cols();
    active_.assign(static_cast<std::size_t>(n), 1);
    position_.assign(static_cast<std::size_t>(n), -1);
    for (Eigen::Index i = 0; i < n; ++i) remaining_.push_back(i);
    result_.stop_reason = "max-instances";
    while (static_cast<int>(result_.instances.size()) < options_.max_instances) {
      if (static_cast<Eigen::Index>(remaining_.size()) < std::max<Eigen::Index>(result_.min_support, 3)) {
        result_.stop_reason = "too-few-points";
        break;
      }
      if (!ExtractOne()) break;
    }
    for (Eigen::Index i = 0; i < n; ++i)
      if (active_[static_cast<std::size_t>(i)]) result_.rejected.push_back(i);
  }

 private:
  Eigen::Vector3d P(Eigen::Index i) const { return points_.col(i); }
  Eigen::Vector3d N(Eigen::Index i) const { return normals_.col(i); }
  bool Passes(const DetectedShape& s, Eigen::Index i) const { return test_(s, P(i), N(i)); }

  // A curved candidate's size limits (the options' max_radius and cone half-angles).
  bool Plausible(const DetectedShape& shape) const {
    if (const auto* s = std::get_if<Sphere>(&shape)) return s->radius <= max_radius_;
    if (const auto* c = std::get_if<Cylinder>(&shape)) return c->radius <= max_radius_;
    if (const auto* c = std::get_if<Cone>(&shape)) {
      return c->half_angle >= options_.min_cone_half_angle && c->half_angle <= options_.max_cone_half_angle &&
             c->radius <= max_radius_;
    }
    if (const auto* t = std::get_if<Torus>(&shape))
      return t->major_radius > 0 && t->minor_radius > 0 && t->major_radius + t->minor_radius <= max_radius_;
    return true;
  }

  // One localized draw: a remaining point, a level, and two more remaining points of its cell there (three
  // more when a torus is sought).
  bool DrawMinimalSet(std::array<Eigen::Index, 4>& set) {
    const int count = std::max(3, max_k_);
    std::uniform_int_distribution<std::size_t> pick(0, remaining_.size() - 1);
    set[0] = remaining_[pick(rng_)];
    const int level = std::uniform_int_distribution<int>(0, levels_.count() - 1)(rng_);
    const auto [lo, hi] = levels_.Cell(level, P(set[0]));
    const auto size = static_cast<std::size_t>(hi - lo);
    if (size < static_cast<std::size_t>(count)) return false;
    std::uniform_int_distribution<std::size_t> in_cell(0, size - 1);
    for (int slot = 1; slot < count; ++slot) {
      bool found = false;
      for (int attempt = 0; attempt < 16 && !found; ++attempt) {
        const Eigen::Index j = lo[in_cell(rng_)].second;
        if (!active_[static_cast<std::size_t>(j)] ||
            std::find(set.begin(), set.begin() + slot, j) != set.begin() + slot)
          continue;
        set[static_cast<std::size_t>(slot)] = j;
        found = true;
      }
      if (!found) return false;
    }
    return true;
  }

  // Candidates of every requested kind from one minimal set, kept when the set's own points pass eq. 54.
  void AddCandidates(const std::array<Eigen::Index, 4>& set, std::vector<Candidate>& out) const {
    const Eigen::Vector3d p1 = P(set[0]), p2 = P(set[1]), p3 = P(set[2]);
    const Eigen::Vector3d n1 = N(set[0]), n2 = N(set[1]), n3 = N(set[2]);
    auto keep = [&](PrimitiveKind kind, const DetectedShape& shape) {
      if (!Plausible(shape)) return;
      const int k = MinimalSetSize(kind);
      for (int m = 0; m < k; ++m)
        if (!Passes(shape, set[static_cast<std::size_t>(m)])) return;
      out.push_back({kind, shape});
    };
    for (PrimitiveKind kind : options_.kinds) {
      if (kind == PrimitiveKind::kTorus) {
        for (const Torus& t : TorusFromPointNormals({p1, p2, p3, P(set[3])}, {n1, n2, n3, N(set[3])}))
          keep(kind, t);
        continue;
      }
      std::optional<DetectedShape> shape;
      switch (kind) {
        case PrimitiveKind::kPlane:
          if (auto s = PlaneFromPoints(p1, p2, p3)) shape = *s;
          break;
        case PrimitiveKind::kSphere:
          if (auto s = SphereFromPointNormals(p1, n1, p2, n2)) shape = *s;
          break;
        case PrimitiveKind::kCylinder:
          if (auto s = CylinderFromPointNormals(p1, n1, p2, n2)) shape = *s;
          break;
        case PrimitiveKind::kCone:
          if (auto s = ConeFromPointNormals(p1, n1, p2, n2, p3, n3)) shape = *s;
          break;
        case PrimitiveKind::kTorus:
          break;
      }
      if (shape) keep(kind, *shape);
    }
  }

  // Every remaining point passing eq. 54, then the largest connected component (eq. 56).
  std::vector<Eigen::Index> CollectInliers(const DetectedShape& shape) const {
    return CollectInliers(shape, test_);
  }
  std::vector<Eigen::Index> CollectInliers(const DetectedShape& shape, const InlierTest& test) const {
    std::vector<char> pass(remaining_.size(), 0);
#pragma omp parallel for schedule(static)
    for (std::size_t r = 0; r < remaining_.size(); ++r)
      pass[r] = test(shape, P(remaining_[r]), N(remaining_[r])) ? 1 : 0;
    std::vector<Eigen::Index> inliers;
    for (std::size_t r = 0; r < remaining_.size(); ++r)
      if (pass[r]) inliers.push_back(remaining_[r]);
    if (grid_.cell > 0) return LargestComponent(points_, inliers, grid_);
    return LargestGraphComponent(inliers);
  }

  // The certified least-squares refit with the robust loss (primitive_fit.h), started at the candidate.
  std::optional<std::pair<DetectedShape, std::vector<ParameterUncertainty>>> Refit(
      const DetectedShape& shape, const std::vector<Eigen::Index>& inliers) const {
    Eigen::Matrix3Xd y(3, static_cast<Eigen::Index>(inliers.size()));
    for (std::size_t i = 0; i < inliers.size(); ++i) y.col(static_cast<Eigen::Index>(i)) = P(inliers[i]);
    PrimitiveFitOptions fit_options;
    fit_options.optimizer.loss = options_.refit_loss;
    fit_options.optimizer.max_iterations = 100;
    fit_options.record_history = false;
    try {
      return std::visit(
          [&](const auto& s) -> std::optional<std::pair<DetectedShape, std::vector<ParameterUncertainty>>> {
            using S = std::decay_t<decltype(s)>;
            if constexpr (std::is_same_v<S, Plane>) {
              const auto fit = FitPlane(y, fit_options);
              return std::make_pair(DetectedShape(fit.shape), fit.uncertainties);
            } else if constexpr (std::is_same_v<S, Sphere>) {
              const auto fit = RefineSphere(y, s, fit_options);
              return std::make_pair(DetectedShape(fit.shape), fit.uncertainties);
            } else if constexpr (std::is_same_v<S, Cylinder>) {
              const auto fit = RefineCylinder(y, s, fit_options);
              return std::make_pair(DetectedShape(fit.shape), fit.uncertainties);
            } else if constexpr (std::is_same_v<S, Cone>) {
              const auto fit = RefineCone(y, s, fit_options);
              return std::make_pair(DetectedShape(fit.shape), fit.uncertainties);
            } else {
              const auto fit = RefineTorus(y, s, fit_options);
              return std::make_pair(DetectedShape(fit.shape), fit.uncertainties);
            }
          },
          shape);
    } catch (const FitError&) {
      return std::nullopt;
    } catch (const std::invalid_argument&) {
      return std::nullopt;
    }
  }

  // The largest connected component of `inliers` (ascending) in the k-nearest-neighbour graph (eq. 56): union
  // by the lower index, so the components and the tie-break (the component with the lowest point) do not
  // depend on threads.
  std::vector<Eigen::Index> LargestGraphComponent(const std::vector<Eigen::Index>& inliers) const {
    if (inliers.empty()) return {};
    std::vector<int> parent(inliers.size());
    std::iota(parent.begin(), parent.end(), 0);
    auto find = [&](int a) {
      while (parent[static_cast<std::size_t>(a)] != a) {
        parent[static_cast<std::size_t>(a)] =
            parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(a)])];
        a = parent[static_cast<std::size_t>(a)];
      }
      return a;
    };
    for (std::size_t r = 0; r < inliers.size(); ++r)
      position_[static_cast<std::size_t>(inliers[r])] = static_cast<int>(r);
    const auto k = static_cast<std::size_t>(graph_.neighbours);
    for (std::size_t r = 0; r < inliers.size(); ++r) {
      const std::size_t base = static_cast<std::size_t>(inliers[r]) * k;
      for (std::size_t m = 0; m < k; ++m) {
        const int q = position_[static_cast<std::size_t>(graph_.neighbour_indices[base + m])];
        if (q < 0) continue;
        const int a = find(static_cast<int>(r)), b = find(q);
        if (a != b) parent[static_cast<std::size_t>(std::max(a, b))] = std::min(a, b);
      }
    }
    std::vector<std::size_t> size(inliers.size(), 0);
    for (std::size_t r = 0; r < inliers.size(); ++r)
      ++size[static_cast<std::size_t>(find(static_cast<int>(r)))];
    const auto largest = static_cast<int>(std::max_element(size.begin(), size.end()) - size.begin());
    std::vector<Eigen::Index> out;
    out.reserve(size[static_cast<std::size_t>(largest)]);
    for (std::size_t r = 0; r < inliers.size(); ++r)
      if (find(static_cast<int>(r)) == largest) out.push_back(inliers[r]);
    for (Eigen::Index i : inliers) position_[static_cast<std::size_t>(i)] = -1;
    return out;
  }

  // The instance's own epsilon (eq. 59): real scans deviate from a surface at scales the local noise
  // estimate does not see (a stereo or depth camera's waviness, calibration), so the first refit's shape
  // takes the MAD sigma of the normal-compatible remaining points within 4 epsilon of it, and the instance
  // collects within 3 of those sigmas, between epsilon and 4 epsilon.
  InlierTest InstanceTest(const DetectedShape& shape) const {
    InlierTest window{4.0 * test_.epsilon, test_.cos_alpha};
    std::vector<double> d(remaining_.size(), std::numeric_limits<double>::quiet_NaN());
#pragma omp parallel for schedule(static)
    for (std::size_t r = 0; r < remaining_.size(); ++r) {
      if (window(shape, P(remaining_[r]), N(remaining_[r]))) d[r] = Distance(shape, P(remaining_[r]));
    }
    std::vector<double> kept;
    for (double v : d)
      if (!std::isnan(v)) kept.push_back(v);
    if (kept.size() < 10) return test_;
    const double sigma =
        MadSigma(Eigen::Map<const Eigen::VectorXd>(kept.data(), static_cast<Eigen::Index>(kept.size())));
    InlierTest adapted = test_;
    adapted.epsilon = std::clamp(options_.epsilon_noise_factor * sigma, test_.epsilon, 4.0 * test_.epsilon);
    return adapted;
  }

  // Draws candidates until the best one is certain enough (eq. 57), refits it and removes its points.
  // Returns false when the search is over.
  bool ExtractOne() {
    const auto remaining = static_cast<double>(remaining_.size());
    // The scoring subset (eq. 58): a random sample of the remaining points.
    std::vector<Eigen::Index> subset = remaining_;
    const std::size_t m = std::min(subset.size(), static_cast<std::size_t>(options_.score_subset));
    for (std::size_t i = 0; i < m; ++i) {
      std::uniform_int_distribution<std::size_t> pick(i, subset.size() - 1);
      std::swap(subset[i], subset[pick(rng_)]);
    }
    subset.resize(m);
    const double expand = remaining / static_cast<double>(m);

    std::optional<Scored> best;
    int draws = 0;
    constexpr int kBatch = 100;
    constexpr int kFullPerBatch = 3;
    double miss = 1.0;
    bool certain = false;
    std::vector<Candidate> candidates;
    while (draws < options_.max_draws) {
      candidates.clear();
      for (int b = 0; b < kBatch; ++b) {
        std::array<Eigen::Index, 4> set{};
        if (DrawMinimalSet(set)) AddCandidates(set, candidates);
      }
      draws += kBatch;
      std::vector<int> estimate(candidates.size(), 0);
#pragma omp parallel for schedule(dynamic, 4)
      for (std::size_t c = 0; c < candidates.size(); ++c) {
        int count = 0;
        for (Eigen::Index i : subset) count += Passes(candidates[c].shape, i) ? 1 : 0;
        estimate[c] = count;
      }
      std::vector<std::size_t> order(candidates.size());
      std::iota(order.begin(), order.end(), std::size_t{0});
      std::stable_sort(order.begin(), order.end(),
                       [&](std::size_t a, std::size_t b) { return estimate[a] > estimate[b]; });
      for (std::size_t r = 0; r < order.size() && r < static_cast<std::size_t>(kFullPerBatch); ++r) {
        const std::size_t c = order[r];
        // An upper confidence bound of the full score from the subset's count (eq. 58).
        const double e = estimate[c];
        const double upper = (e + 2.0 * std::sqrt(e) + 1.0) * expand;
        if (upper < static_cast<double>(result_.min_support)) break;
        if (best && upper <= static_cast<double>(best->inliers.size())) break;
        std::vector<Eigen::Index> inliers = CollectInliers(candidates[c].shape);
        if (!best || inliers.size() > best->inliers.size()) best = Scored{candidates[c], std::move(inliers)};
      }
      const bool big_enough = best && static_cast<Eigen::Index>(best->inliers.size()) >= result_.min_support;
      if (big_enough) {
        miss = MissProbability(static_cast<double>(best->inliers.size()), remaining, levels_.count(),
                               MinimalSetSize(best->candidate.kind), draws);
        if (miss < options_.miss_probability) {
          certain = true;
          break;
        }
      } else {
        result_.final_miss_probability = MissProbability(static_cast<double>(result_.min_support), remaining,
                                                         levels_.count(), max_k_, draws);
        if (result_.final_miss_probability < options_.miss_probability) {
          result_.stop_reason = "no-shape-left";
          return false;
        }
      }
    }
    if (!best || static_cast<Eigen::Index>(best->inliers.size()) < result_.min_support) {
      result_.stop_reason = "draw-limit";
      result_.final_miss_probability = MissProbability(static_cast<double>(result_.min_support), remaining,
                                                       levels_.count(), max_k_, draws);
      return false;
    }
    (void)certain;

    // Refit and re-collect (Schnabel et al.; here the certified fits with a robust loss).
    DetectedPrimitive instance;
    instance.kind = best->candidate.kind;
    instance.shape = best->candidate.shape;
    instance.inliers = std::move(best->inliers);
    instance.draws = draws;
    instance.miss_probability = miss;
    bool fitted = false;
    InlierTest instance_test = test_;
    for (int round = 0; round <= options_.refit_rounds; ++round) {
      auto fit = Refit(instance.shape, instance.inliers);
      if (!fit) break;
      instance.shape = fit->first;
      instance.uncertainties = fit->second;
      fitted = true;
      if (round == options_.refit_rounds) break;  // the last fit is on the final inliers
      if (round == 0 && options_.adapt_epsilon) instance_test = InstanceTest(instance.shape);
      std::vector<Eigen::Index> again = CollectInliers(instance.shape, instance_test);
      if (static_cast<Eigen::Index>(again.size()) < result_.min_support) {
        fitted = false;
        break;
      }
      instance.inliers = std::move(again);
    }
    // The candidate's points leave the search either way: a candidate whose refit fails or shrinks below the
    // minimum would otherwise be drawn again and again.
    for (Eigen::Index i : instance.inliers) active_[static_cast<std::size_t>(i)] = 0;
    remaining_.erase(std::remove_if(remaining_.begin(), remaining_.end(),
                                    [&](Eigen::Index i) { return !active_[static_cast<std::size_t>(i)]; }),
                     remaining_.end());
    if (fitted && Plausible(instance.shape)) {
      double sum = 0.0;
      for (Eigen::Index i : instance.inliers) {
        const double d = Distance(instance.shape, P(i));
        sum += d * d;
      }
      instance.rms = std::sqrt(sum / static_cast<double>(instance.inliers.size()));
      instance.epsilon = instance_test.epsilon;
      result_.instances.push_back(std::move(instance));
    }
    return true;
  }

  const Eigen::Matrix3Xd& points_;
  const Eigen::Matrix3Xd& normals_;
  const PointNormals& graph_;
  const DetectionOptions& options_;
  DetectionResult& result_;
  InlierTest test_;
  SamplingLevels levels_;
  CellGrid grid_;
  double max_radius_;
  int max_k_ = 2;
  std::mt19937_64 rng_;
  std::vector<char> active_;
  mutable std::vector<int> position_;  // scratch of LargestGraphComponent: a point's place in the inliers
  std::vector<Eigen::Index> remaining_;
};

double Quantile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  const auto k = static_cast<std::size_t>(q * static_cast<double>(values.size() - 1));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

}  // namespace

DetectionResult DetectPrimitives(const Eigen::Matrix3Xd& points, const DetectionOptions& options,
                                 const Eigen::Matrix3Xd& normals) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument("invalid detection options: " + why);
  if (!points.allFinite()) throw std::invalid_argument("detection: the points contain NaN or inf");
  const Eigen::Index n = points.cols();
  if (n < 2 * options.normal_neighbours) {
    throw std::invalid_argument("detection needs at least " + std::to_string(2 * options.normal_neighbours) +
                                " points, got " + std::to_string(n));
  }
  if (normals.cols() != 0 && (normals.cols() != n || !normals.allFinite()))
    throw std::invalid_argument("detection: normals must be finite, one per point");

  DetectionResult result;
  PointNormals estimated = EstimatePointNormals(points, options.normal_neighbours);
  const Eigen::Matrix3Xd& used_normals = normals.cols() == n ? normals : estimated.normals;

  // Thresholds from the data (eqs. 53-55).
  std::vector<double> nearest(estimated.nearest_distance.data(), estimated.nearest_distance.data() + n);
  result.point_spacing = Quantile(nearest, 0.5);
  ScanSet set;
  set.scans.emplace_back();
  set.scans.back().points = points;
  result.noise_sigma = EstimateNoise(set);
  if (options.epsilon > 0.0) {
    result.epsilon = options.epsilon;
  } else {
    if (!std::isfinite(result.noise_sigma) || !(result.noise_sigma > 0.0))
      throw std::invalid_argument(
          "detection: the noise could not be estimated from the points; give epsilon");
    result.epsilon = options.epsilon_noise_factor * result.noise_sigma;
  }
  const double sigma = result.epsilon / options.epsilon_noise_factor;
  if (options.alpha > 0.0) {
    result.alpha = options.alpha;
  } else {
    std::vector<double> normal_sigma(static_cast<std::size_t>(n));
    for (Eigen::Index i = 0; i < n; ++i)
      normal_sigma[static_cast<std::size_t>(i)] = estimated.tangential_spread[i] > 0
                                                      ? sigma / estimated.tangential_spread[i]
                                                      : std::numeric_limits<double>::infinity();
    result.alpha = std::clamp(3.0 * Quantile(normal_sigma, 0.5), options.min_alpha, options.max_alpha);
  }
  result.cluster_cell = options.cluster_cell;
  result.min_support = options.min_support > 0 ? options.min_support : std::max<Eigen::Index>(30, n / 1000);
  const double extent = ComputeBounds(points).diagonal();
  Detector(points, used_normals, estimated, options, result, extent).Run();
  return result;
}

}  // namespace s2m
