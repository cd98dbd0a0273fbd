#include "fitting/squared_distance_field.h"

#include <omp.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include "fitting/foot_point.h"

namespace s2m {
namespace {

// Cells per block edge. Built whole, blocks far from the model are skipped at once by one foot of their
// centre, and the cells of a block warm-start from each other. Built lazily, a block is the unit computed on
// demand: single cells, each from the exact foot of its own centre, since larger blocks mostly compute cells
// the scan never visits (measured on the benchmark's registration at 100k points, docs/registration.md: about
// 11,000 cells with blocks of 1, 20,000 with blocks of 2 and 36,000 with blocks of 4, in the least time).
constexpr int kBlockWhole = 4;
constexpr int kBlockLazy = 1;

}  // namespace

SquaredDistanceField::SquaredDistanceField(const ParametricModel& model, const Options& options)
    : options_(options), model_(model), domain_(model.domain()) {
  const auto start = std::chrono::steady_clock::now();
  if (model.ambient_dimension() != 3 || domain_.dimension != 2)
    throw std::invalid_argument("squared distance field: the model (" + model.name() +
                                ") is not a surface in 3D");
  const double h = options_.cell_size;
  if (!(h > 0) || !std::isfinite(h))
    throw std::invalid_argument("squared distance field: cell size must be > 0");
  if (!(options_.band >= 0) || !std::isfinite(options_.band))
    throw std::invalid_argument("squared distance field: band must be >= 0");
  Eigen::Vector3d lo = options_.box_min, hi = options_.box_max;
  if ((lo.array() > hi.array()).any()) {
    lo.setConstant(INFINITY);
    hi.setConstant(-INFINITY);
    LocalGeometry g;
    for (const ParamT& t : model.SampleParameters()) {
      model.Evaluate(t, 0, g);
      lo = lo.cwiseMin(To3(g.point));
      hi = hi.cwiseMax(To3(g.point));
    }
    lo.array() -= options_.band + h;
    hi.array() += options_.band + h;
  }
  if (!lo.allFinite() || !hi.allFinite())
    throw std::invalid_argument("squared distance field: the box is not finite");
  origin_ = lo;
  inverse_cell_ = 1.0 / h;
  double total = 1.0;
  for (int a = 0; a < 3; ++a) {
    dims_[static_cast<std::size_t>(a)] =
        std::max<std::int64_t>(1, static_cast<std::int64_t>(std::ceil((hi[a] - lo[a]) / h)));
    total *= static_cast<double>(dims_[static_cast<std::size_t>(a)]);
  }
  if (total > options_.max_grid_cells)
    throw std::invalid_argument("squared distance field: " + std::to_string(total) +
                                " grid cells exceed the limit " + std::to_string(options_.max_grid_cells) +
                                " (larger cells or a smaller box)");
  index_.assign(static_cast<std::size_t>(total), -1);
  block_edge_ = options_.lazy ? kBlockLazy : kBlockWhole;
  for (std::size_t a = 0; a < 3; ++a) blocks_[a] = (dims_[a] + block_edge_ - 1) / block_edge_;
  const std::int64_t block_count = blocks_[0] * blocks_[1] * blocks_[2];
  block_built_.assign(static_cast<std::size_t>(block_count), 0);
  context_ = std::make_unique<FootPointContext>(model);
  if (!options_.lazy) {
    std::vector<std::int64_t> every(static_cast<std::size_t>(block_count));
    for (std::int64_t b = 0; b < block_count; ++b) every[static_cast<std::size_t>(b)] = b;
    BuildBlocks(every);
    context_.reset();  // the seeds are needed again only for lazy cells; the model may now go
  }
  build_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void SquaredDistanceField::Prepare(const Eigen::Matrix3Xd& points) {
  if (!options_.lazy) return;
  const auto start = std::chrono::steady_clock::now();
  std::vector<std::int64_t> wanted;
  for (Eigen::Index j = 0; j < points.cols(); ++j) {
    const Eigen::Vector3d g = (points.col(j) - origin_) * inverse_cell_;
    if (!(g.minCoeff() >= 0.0)) continue;  // outside the box (or NaN): Query answers no there
    std::array<std::int64_t, 3> c{};
    bool inside = true;
    for (int a = 0; a < 3; ++a) {
      c[static_cast<std::size_t>(a)] = static_cast<std::int64_t>(g[a]);
      inside = inside && c[static_cast<std::size_t>(a)] < dims_[static_cast<std::size_t>(a)];
    }
    if (!inside) continue;
    const std::int64_t b =
        ((c[2] / block_edge_) * blocks_[1] + c[1] / block_edge_) * blocks_[0] + c[0] / block_edge_;
    std::uint8_t& built = block_built_[static_cast<std::size_t>(b)];
    if (built) continue;
    built = 1;
    wanted.push_back(b);
  }
  if (!wanted.empty()) BuildBlocks(wanted);
  build_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

void SquaredDistanceField::BuildBlocks(const std::vector<std::int64_t>& wanted) {
  const ParametricModel& model = model_;
  const FootPointContext& context = *context_;
  const double h = options_.cell_size;
  const auto wanted_count = static_cast<std::int64_t>(wanted.size());
  std::vector<std::vector<Cell>> block_cells(wanted.size());
  std::vector<std::vector<std::int64_t>> block_index(wanted.size());
  std::vector<std::size_t> block_untrusted(wanted.size(), 0);
  const double keep = options_.band + 0.5 * std::sqrt(3.0) * h;  // every point within `band` finds its cell
#pragma omp parallel
  {
    LocalGeometry g;
#pragma omp for schedule(dynamic, 8)
    for (std::int64_t w = 0; w < wanted_count; ++w) {
      const std::int64_t b = wanted[static_cast<std::size_t>(w)];
      block_built_[static_cast<std::size_t>(b)] = 1;
      const std::array<std::int64_t, 3> bi{b % blocks_[0], (b / blocks_[0]) % blocks_[1],
                                           b / (blocks_[0] * blocks_[1])};
      std::array<std::int64_t, 3> c0{}, c1{};
      for (std::size_t a = 0; a < 3; ++a) {
        c0[a] = bi[a] * block_edge_;
        c1[a] = std::min(c0[a] + block_edge_, dims_[a]);
      }
      const Eigen::Vector3d centre = origin_ + 0.5 * h *
                                                   Eigen::Vector3d(static_cast<double>(c0[0] + c1[0]),
                                                                   static_cast<double>(c0[1] + c1[1]),
                                                                   static_cast<double>(c0[2] + c1[2]));
      const double radius = 0.5 * h * std::sqrt(3.0) * block_edge_;
      const FootPoint block_foot = FootPointOf(context, centre, nullptr, WarmStart::kVerified, g);
      if (block_foot.distance - radius > keep) continue;  // distance is 1-Lipschitz: no cell of it is kept
      ParamT previous = block_foot.t;
      const auto ub = static_cast<std::size_t>(w);
      for (std::int64_t k = c0[2]; k < c1[2]; ++k)
        for (std::int64_t j = c0[1]; j < c1[1]; ++j)
          for (std::int64_t i = c0[0]; i < c1[0]; ++i) {
            const Eigen::Vector3d x =
                origin_ + h * Eigen::Vector3d(static_cast<double>(i) + 0.5, static_cast<double>(j) + 0.5,
                                              static_cast<double>(k) + 0.5);
            // Newton from the neighbouring cell's foot: adjacent centres have nearby feet.
            const FootPoint f = FootPointOf(context, x, &previous, WarmStart::kTrusted, g);
            if (f.distance > keep) continue;
            previous = f.t;
            if (context.closed_form) model.Evaluate(f.t, 2, g);
            bool trusted = !f.on_boundary && !f.excluded;
            // Near an open boundary the paraboloid's foot may leave the model: exact feet there.
            for (int a = 0; a < 2 && trusted; ++a) {
              const auto ua = static_cast<std::size_t>(a);
              if (domain_.periodic[ua]) continue;
              const double speed = g.d1.col(a).norm();
              if ((f.t[ua] - domain_.lo[ua]) * speed < 2 * h || (domain_.hi[ua] - f.t[ua]) * speed < 2 * h)
                trusted = false;
            }
            const PrincipalFrame frame = ComputePrincipalFrame(g, x);
            // Near a focal point (1 - kappa d -> 0) d^2 is not smooth and the paraboloid's foot is unstable.
            if (std::max(std::abs(frame.curvatures[0]), std::abs(frame.curvatures[1])) * (f.distance + h) >=
                0.5)
              trusted = false;
            Eigen::Matrix<double, 3, 2> J;
            J.col(0) = To3(g.d1.col(0));
            J.col(1) = To3(g.d1.col(1));
            const Eigen::Matrix2d jtj = J.transpose() * J;
            if (!(jtj.determinant() > 1e-12 * jtj.trace() * jtj.trace())) trusted = false;
            if (!trusted) {
              ++block_untrusted[ub];
              continue;
            }
            Cell cell;
            cell.p = To3(g.point);
            cell.n = frame.normals[0];
            cell.e1 = frame.tangents[0];
            cell.e2 = frame.normals[0].cross(frame.tangents[0]);  // right-handed; e2 = +-tangents[1]
            cell.k1 = frame.curvatures[0];
            cell.k2 = frame.curvatures[1];
            cell.t_of_x = jtj.inverse() * J.transpose();
            for (int c2 = 0; c2 < 3; ++c2) cell.t_second.col(c2) = cell.t_of_x * To3(g.d2.col(c2));
            cell.t = f.t;
            block_cells[ub].push_back(cell);
            block_index[ub].push_back((k * dims_[1] + j) * dims_[0] + i);
          }
    }
  }
  std::size_t count = cells_.size();
  for (const auto& v : block_cells) count += v.size();
  // Geometric growth: a lazy field grows by a few cells per Prepare, which exact reserves would copy each
  // time.
  if (count > cells_.capacity()) cells_.reserve(std::max(count, 2 * cells_.capacity()));
  for (std::size_t b = 0; b < block_cells.size(); ++b) {
    untrusted_ += block_untrusted[b];
    for (std::size_t c = 0; c < block_cells[b].size(); ++c) {
      index_[static_cast<std::size_t>(block_index[b][c])] = static_cast<std::int32_t>(cells_.size());
      cells_.push_back(block_cells[b][c]);
    }
  }
}

bool SquaredDistanceField::Query(const Eigen::Vector3d& y, Answer& out, bool tangents) const {
  const Eigen::Vector3d g = (y - origin_) * inverse_cell_;
  if (!(g.minCoeff() >= 0.0)) return false;  // also rejects NaN
  const auto i = static_cast<std::int64_t>(g.x()), j = static_cast<std::int64_t>(g.y()),
             k = static_cast<std::int64_t>(g.z());
  if (i >= dims_[0] || j >= dims_[1] || k >= dims_[2]) return false;
  const std::int32_t at = index_[static_cast<std::size_t>((k * dims_[1] + j) * dims_[0] + i)];
  if (at < 0) return false;
  const Cell& c = cells_[static_cast<std::size_t>(at)];
  // y in the principal frame of the cell centre's foot p: (a, b, w).
  const Eigen::Vector3d r = y - c.p;
  const double a = r.dot(c.e1), b = r.dot(c.e2), w = r.dot(c.n);
  // Foot on the osculating paraboloid z = (k1 u^2 + k2 v^2) / 2: the orthogonality conditions
  // u (1 + k1 (z - w)) = a, v (1 + k2 (z - w)) = b, solved by fixed-point sweeps from z = 0 (each sweep gains
  // a factor of about |k| |u| in u; the distance is stationary in the foot, so two leave an error far below
  // the paraboloid's own: measured, the same maximum errors as with three).
  double u = 0.0, v = 0.0, z = 0.0;
  for (int sweep = 0; sweep < 2; ++sweep) {
    const double d1 = 1.0 + c.k1 * (z - w), d2 = 1.0 + c.k2 * (z - w);
    if (d1 < 0.25 || d2 < 0.25) return false;  // near a focal point of this cell's paraboloid
    u = a / d1;
    v = b / d2;
    z = 0.5 * (c.k1 * u * u + c.k2 * v * v);
  }
  out.foot = c.p + u * c.e1 + v * c.e2 + z * c.n;
  // The paraboloid's normal and first tangent at (u, v): (-k1 u, -k2 v, 1) and (1, 0, k1 u) in the cell's
  // frame.
  Eigen::Vector3d normal = (c.n - c.k1 * u * c.e1 - c.k2 * v * c.e2).normalized();
  const Eigen::Vector3d t1 = c.e1 + c.k1 * u * c.n;
  const Eigen::Vector3d offset = y - out.foot;
  double delta = offset.dot(normal), k1 = c.k1, k2 = c.k2;
  if (delta < 0) {  // docs/method.md section 2: n towards the data point, delta >= 0, kappa signed w.r.t. n
    normal = -normal;
    delta = -delta;
    k1 = -k1;
    k2 = -k2;
  }
  PrincipalFrame& f = out.frame;
  f.tangent_count = 2;
  f.normal_count = 1;
  f.normals[0] = normal;
  if (tangents) {
    f.tangents[0] = (t1 - t1.dot(normal) * normal).normalized();
    f.tangents[1] = normal.cross(f.tangents[0]);
  }
  f.curvatures = {k1, k2};
  f.delta = delta;
  out.squared_distance = offset.squaredNorm();
  // The parameter of the approximate foot: s = A (q - p), then the parametrization's second-order term
  // C(t + s) = p + C_t s + C_tt[s, s] / 2 removed (one fixed-point step; the residual is third order in |s|,
  // so exact Newton from out.t typically needs one step fewer).
  Eigen::Vector2d dt = c.t_of_x * (out.foot - c.p);
  dt -= 0.5 * (c.t_second.col(0) * (dt[0] * dt[0]) + c.t_second.col(1) * (2.0 * dt[0] * dt[1]) +
               c.t_second.col(2) * (dt[1] * dt[1]));
  out.t = c.t;
  for (int a2 = 0; a2 < 2; ++a2) {
    const auto ua = static_cast<std::size_t>(a2);
    out.t[ua] += dt[a2];
    if (!domain_.periodic[ua]) out.t[ua] = std::clamp(out.t[ua], domain_.lo[ua], domain_.hi[ua]);
  }
  return true;
}

}  // namespace s2m
