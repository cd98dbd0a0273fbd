#include "fitting/initial_models.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>

#include "fitting/foot_point.h"
#include "fitting/kinematic_surfaces.h"
#include "fitting/primitive_fit.h"

namespace s2m {

BSplineBasis UnitSpacedClamped(int order, int num_control) {
  return BSplineBasis::ClampedUniform(order, num_control, 0.0, num_control - order + 1);
}
BSplineBasis UnitSpacedPeriodic(int order, int num_control) {
  return BSplineBasis::PeriodicUniform(order, num_control, 0.0, num_control);
}

namespace {

// Centroids of the occupied cells of a uniform grid with 2^level cells per side over the bounding square.
std::vector<Eigen::Vector2d> OccupiedCells(const Eigen::Matrix2Xd& p, int level) {
  const Eigen::Vector2d lo = p.rowwise().minCoeff();
  const double side = std::max((p.rowwise().maxCoeff() - lo).maxCoeff(), 1e-300);
  const double cells = std::ldexp(1.0, level);
  std::map<std::pair<long, long>, std::pair<Eigen::Vector2d, int>> grid;
  for (Eigen::Index j = 0; j < p.cols(); ++j) {
    const auto ix = static_cast<long>(std::min(cells - 1, std::floor((p(0, j) - lo.x()) / side * cells)));
    const auto iy = static_cast<long>(std::min(cells - 1, std::floor((p(1, j) - lo.y()) / side * cells)));
    auto [it, inserted] = grid.try_emplace({ix, iy}, Eigen::Vector2d::Zero(), 0);
    auto& cell = it->second;
    cell.first += p.col(j);
    ++cell.second;
  }
  std::vector<Eigen::Vector2d> out;
  for (auto& [key, cell] : grid) out.push_back(cell.first / cell.second);
  return out;
}

// Orders the cell centroids into a chain by nearest neighbours, starting from an end of the point set.
std::vector<Eigen::Vector2d> Chain(std::vector<Eigen::Vector2d> cells) {
  auto farthest_from = [&](const Eigen::Vector2d& q) {
    return static_cast<std::size_t>(std::max_element(cells.begin(), cells.end(),
                                                     [&](const auto& a, const auto& b) {
                                                       return (a - q).squaredNorm() < (b - q).squaredNorm();
                                                     }) -
                                    cells.begin());
  };
  std::swap(cells[0],
            cells[farthest_from(cells[farthest_from(cells[0])])]);  // double sweep: an extreme cell first
  for (std::size_t i = 1; i < cells.size(); ++i) {
    std::size_t best = i;
    for (std::size_t k = i + 1; k < cells.size(); ++k) {
      if ((cells[k] - cells[i - 1]).squaredNorm() < (cells[best] - cells[i - 1]).squaredNorm()) best = k;
    }
    std::swap(cells[i], cells[best]);
  }
  return cells;
}

// n points at equal arc-length steps along a polyline (closed: including the closing segment, last point
// excluded).
Eigen::Matrix2Xd Resample(const std::vector<Eigen::Vector2d>& chain, int n, bool closed) {
  std::vector<double> s{0.0};
  const std::size_t segments = closed ? chain.size() : chain.size() - 1;
  for (std::size_t i = 0; i < segments; ++i)
    s.push_back(s.back() + (chain[(i + 1) % chain.size()] - chain[i]).norm());
  const double total = s.back();
  Eigen::Matrix2Xd out(2, n);
  std::size_t seg = 0;
  for (int k = 0; k < n; ++k) {
    const double target = closed ? total * k / n : total * k / (n - 1);
    while (seg + 1 < s.size() - 1 && s[seg + 1] < target) ++seg;
    const double len = s[seg + 1] - s[seg];
    const double a = len > 0 ? (target - s[seg]) / len : 0.0;
    out.col(k) = (1 - a) * chain[seg] + a * chain[(seg + 1) % chain.size()];
  }
  return out;
}

// Maps row `r` affinely onto [0, length].
void RescaleRow(Eigen::Matrix2Xd& uv, int r, double length) {
  Eigen::VectorXd row = uv.row(r).transpose();
  const double lo = row.minCoeff(), hi = row.maxCoeff();
  row = (row.array() - lo) / std::max(hi - lo, 1e-300) * length;
  uv.row(r) = row.transpose();
}

}  // namespace

BSplineCurve InitialCurveFromQuadtree(const Eigen::Matrix2Xd& points, int num_control, int order,
                                      bool closed) {
  if (points.cols() < 3) throw std::invalid_argument("an initial curve needs at least 3 data points");
  std::vector<Eigen::Vector2d> cells;
  for (int level = 1; level <= 16; ++level) {
    cells = OccupiedCells(points, level);
    if (static_cast<int>(cells.size()) >= 4 * num_control ||
        static_cast<Eigen::Index>(cells.size()) == points.cols())
      break;
  }
  if (cells.size() < 2) throw std::invalid_argument("the data points coincide: no initial curve");
  const Eigen::Matrix2Xd control = Resample(Chain(std::move(cells)), num_control, closed);
  return BSplineCurve(closed ? UnitSpacedPeriodic(order, num_control) : UnitSpacedClamped(order, num_control),
                      control);
}

BSplineSurface InitialSurfaceByProjection(const Eigen::Matrix3Xd& points, int nu, int nv, int order,
                                          SurfaceProjection projection) {
  const bool periodic = projection == SurfaceProjection::kCylinder;
  BSplineBasis bu = periodic ? UnitSpacedPeriodic(order, nu) : UnitSpacedClamped(order, nu);
  BSplineBasis bv = UnitSpacedClamped(order, nv);
  const Eigen::Index n = points.cols();
  if (n < 3) throw std::invalid_argument("an initial surface needs at least 3 data points");
  Eigen::Matrix2Xd uv(2, n);
  if (periodic) {
    const Cylinder cyl = FitCylinder(points).shape;
    const Eigen::Matrix3d frame = FrameWithAxis(cyl.axis_direction);
    for (Eigen::Index j = 0; j < n; ++j) {
      const Eigen::Vector3d q = frame.transpose() * (points.col(j) - cyl.axis_point);
      double angle = std::atan2(q.y(), q.x());
      if (angle < 0) angle += 2 * M_PI;
      uv(0, j) = angle / (2 * M_PI) * (bu.hi() - bu.lo());
      uv(1, j) = q.z();
    }
  } else {
    const Eigen::Vector3d c = points.rowwise().mean();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig((points.colwise() - c) *
                                                       (points.colwise() - c).transpose());
    uv.row(0) = eig.eigenvectors().col(2).transpose() * (points.colwise() - c);
    uv.row(1) = eig.eigenvectors().col(1).transpose() * (points.colwise() - c);
    RescaleRow(uv, 0, bu.hi() - bu.lo());
  }
  RescaleRow(uv, 1, bv.hi() - bv.lo());
  // Linear least squares for the control points: (B^T B + mu K) P = B^T X, shared by x, y and z.
  BSplineSurface surface(bu, bv, Eigen::Matrix3Xd::Zero(3, nu * nv));
  const int m = nu * nv;
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(m, m);
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(m, 3);
  std::vector<JacobianEntry> entries;
  for (Eigen::Index j = 0; j < n; ++j) {
    surface.ShapeJacobian({uv(0, j), uv(1, j)}, false, entries);
    for (const JacobianEntry& a : entries) {
      if (a.index % 3 != 0) continue;
      const double wa = a.column.x();
      b.row(a.index / 3) += wa * points.col(j).transpose();
      for (const JacobianEntry& c : entries) {
        if (c.index % 3 == 0) A(a.index / 3, c.index / 3) += wa * c.column.x();
      }
    }
  }
  const Eigen::MatrixXd K = surface.FairnessMatrix({0.0, 1.0});
  Eigen::MatrixXd k_scalar(m, m);
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j) k_scalar(i, j) = K(3 * i, 3 * j);
  const double mu = 1e-3 * A.trace() / std::max(k_scalar.trace(), 1e-300);
  const Eigen::MatrixXd control = (A + mu * k_scalar).ldlt().solve(b);
  return BSplineSurface(bu, bv, control.transpose());
}

KinematicSurface InitialRevolution(const Eigen::Matrix3Xd& p, int num_control, int order, double margin) {
  return InitialRevolutionAlong(p, p.row(2).transpose(), num_control, order, margin);
}

KinematicSurface InitialRevolutionAlong(const Eigen::Matrix3Xd& p, const Eigen::VectorXd& along,
                                        int num_control, int order, double margin) {
  if (p.cols() < num_control) throw std::invalid_argument("fewer points than profile control points");
  if (along.size() != p.cols()) throw std::invalid_argument("one position along the profile per point");
  const BSplineBasis basis = UnitSpacedClamped(order, num_control);
  const double data_lo = along.minCoeff(), data_hi = along.maxCoeff();
  if (!(data_hi > data_lo)) throw std::invalid_argument("the points have no extent along the profile");
  const double lo = data_lo - margin * (data_hi - data_lo), hi = data_hi + margin * (data_hi - data_lo);
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(num_control, num_control);
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(num_control, 2);
  BSplineBasis::Values v;
  for (Eigen::Index j = 0; j < p.cols(); ++j) {
    const double u = (along[j] - lo) / (hi - lo) * (basis.hi() - basis.lo()) + basis.lo();
    basis.Evaluate(u, 0, v);
    const Eigen::Vector2d rz(std::hypot(p(0, j), p(1, j)), p(2, j));
    for (int i = 0; i < basis.order(); ++i) {
      const int ci = basis.ControlIndex(v.first, i);
      b.row(ci) += v.values[0][static_cast<std::size_t>(i)] * rz.transpose();
      for (int k = 0; k < basis.order(); ++k) {
        A(ci, basis.ControlIndex(v.first, k)) +=
            v.values[0][static_cast<std::size_t>(i)] * v.values[0][static_cast<std::size_t>(k)];
      }
    }
  }
  const std::vector<double> g = basis.GramMatrix(2);
  const Eigen::MatrixXd K =
      Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
          g.data(), num_control, num_control);
  const double mu = 1e-3 * A.trace() / std::max(K.trace(), 1e-300);
  const Eigen::MatrixXd control = (A + mu * K).ldlt().solve(b);
  return KinematicSurface::Revolution(basis, control.transpose());
}

KinematicAxis KinematicAxisFromNormals(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                                       KinematicKind kind) {
  return KinematicAxisFromNormals(points, normals, kind, Eigen::VectorXd());
}

KinematicAxis KinematicAxisFromNormals(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& normals,
                                       KinematicKind kind, const Eigen::VectorXd& weights) {
  if (points.cols() != normals.cols()) throw std::invalid_argument("one normal per point is needed");
  if (weights.size() != 0 && weights.size() != points.cols())
    throw std::invalid_argument("one weight per point is needed");
  if (points.cols() < 8) throw std::invalid_argument("too few points for an axis from normals");
  if (!points.allFinite() || !normals.allFinite())
    throw std::invalid_argument("non-finite points or normals");
  // Centre the data: conditioning, and the moments x_j x n_j stay of the data's size.
  const Eigen::Vector3d centre = points.rowwise().mean();
  const bool spiral = kind == KinematicKind::kSpiral;
  const int q = spiral ? 4 : 3;  // eliminated unknowns: cbar (and gamma)
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::MatrixXd B = Eigen::MatrixXd::Zero(3, q), C = Eigen::MatrixXd::Zero(q, q);
  double total_weight = 0.0;
  for (Eigen::Index j = 0; j < points.cols(); ++j) {
    const double w = weights.size() != 0 ? weights[j] : 1.0;
    if (!(w > 0.0)) continue;
    total_weight += w;
    const Eigen::Vector3d x = points.col(j) - centre;
    const Eigen::Vector3d n = normals.col(j).normalized();
    const Eigen::Vector3d m = x.cross(n);
    Eigen::VectorXd e(q);
    e.head<3>() = n;
    if (spiral) e[3] = n.dot(x);
    A += w * m * m.transpose();
    B += w * m * e.transpose();
    C += w * e * e.transpose();
  }
  if (!(total_weight > 0.0)) throw std::invalid_argument("no point carries weight for an axis from normals");
  const Eigen::LDLT<Eigen::MatrixXd> c_ldlt(C);
  if (c_ldlt.info() != Eigen::Success || !(C.eigenvalues().real().minCoeff() > 1e-9 * C.trace()))
    throw std::invalid_argument("the normals do not span all directions: no axis can be found from them");
  const Eigen::Matrix3d S = A - B * c_ldlt.solve(B.transpose());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(S);
  const Eigen::Vector3d c = eig.eigenvectors().col(0);
  const Eigen::VectorXd rest = -c_ldlt.solve(B.transpose() * c);  // (cbar, gamma) given c
  const Eigen::Vector3d cbar = rest.head<3>();
  KinematicAxis axis;
  axis.direction = c;
  axis.residual = std::sqrt(std::max(eig.eigenvalues()[0], 0.0) / total_weight);
  if (spiral) {
    axis.growth = rest[3];
    // The centre: v(x0) = cbar + c x x0 + gamma x0 = 0, i.e. (gamma I + [c]x) x0 = -cbar.
    Eigen::Matrix3d M = axis.growth * Eigen::Matrix3d::Identity();
    M(0, 1) -= c.z();
    M(0, 2) += c.y();
    M(1, 0) += c.z();
    M(1, 2) -= c.x();
    M(2, 0) -= c.y();
    M(2, 1) += c.x();
    axis.point = centre + M.colPivHouseholderQr().solve(-cbar);
  } else {
    axis.pitch = c.dot(cbar);
    axis.point = centre + c.cross(cbar);  // where v is parallel to c (|c| = 1)
  }
  return axis;
}

namespace {

// Values taken modulo `period`, shifted so that they form one contiguous run: the circle is cut at the
// largest gap between them.
std::vector<double> UnwrapAtLargestGap(const std::vector<double>& values, double period) {
  std::vector<double> w(values.size());
  for (std::size_t j = 0; j < values.size(); ++j) {
    w[j] = std::fmod(values[j], period);
    if (w[j] < 0) w[j] += period;
  }
  std::vector<double> sorted = w;
  std::sort(sorted.begin(), sorted.end());
  double cut = sorted.front(), gap = sorted.front() + period - sorted.back();  // the wrap-around gap
  for (std::size_t i = 0; i + 1 < sorted.size(); ++i) {
    if (sorted[i + 1] - sorted[i] > gap) {
      gap = sorted[i + 1] - sorted[i];
      cut = sorted[i + 1];
    }
  }
  for (double& v : w) {
    if (v < cut) v += period;
  }
  return w;
}

}  // namespace

KinematicSurface InitialHelical(const Eigen::Matrix3Xd& p, double pitch, int num_control, int order,
                                double margin) {
  if (!(std::abs(pitch) > 0)) throw std::invalid_argument("a helical surface needs a non-zero pitch");
  const double lead = 2 * M_PI * std::abs(pitch);
  std::vector<double> heights(static_cast<std::size_t>(p.cols())), theta(heights.size());
  for (Eigen::Index j = 0; j < p.cols(); ++j) {
    theta[static_cast<std::size_t>(j)] = std::atan2(p(1, j), p(0, j));
    heights[static_cast<std::size_t>(j)] = p(2, j) - pitch * theta[static_cast<std::size_t>(j)];
  }
  const std::vector<double> unwrapped = UnwrapAtLargestGap(heights, lead);
  Eigen::Matrix3Xd on_half_plane(3, p.cols());
  double v_max = 0.0;
  for (Eigen::Index j = 0; j < p.cols(); ++j) {
    const auto i = static_cast<std::size_t>(j);
    on_half_plane.col(j) << std::hypot(p(0, j), p(1, j)), 0.0, unwrapped[i];
    v_max = std::max(v_max, std::abs(theta[i] + (heights[i] - unwrapped[i]) / pitch));
  }
  const KinematicSurface profile = InitialRevolution(on_half_plane, num_control, order);
  return KinematicSurface::Helical(profile.basis(), profile.profile(), pitch, (v_max + margin) / M_PI);
}

namespace {

// RMS of the foot-point distances of the points to a model.
double FootPointRms(const ParametricModel& model, const Eigen::Matrix3Xd& p) {
  std::vector<FootPoint> feet;
  ComputeFootPoints(model, p, feet);
  double sum = 0.0;
  for (const FootPoint& f : feet) sum += f.distance * f.distance;
  return std::sqrt(sum / static_cast<double>(feet.size()));
}

// The value in value0 (1 +- 20 %) whose initial model lies closest to the points: a scan in 2.5 % steps, then
// a parabola through the best three.
template <class Build>
double SearchParameter(double value0, const Eigen::Matrix3Xd& p, const Build& build) {
  const int steps = 8;
  const double step = 0.025 * value0;
  std::vector<double> rms(2 * steps + 1);
  int best = steps;
  for (int i = 0; i <= 2 * steps; ++i) {
    rms[static_cast<std::size_t>(i)] = FootPointRms(build(value0 + (i - steps) * step), p);
    if (rms[static_cast<std::size_t>(i)] < rms[static_cast<std::size_t>(best)]) best = i;
  }
  double refined = value0 + (best - steps) * step;
  if (best > 0 && best < 2 * steps) {
    const double a = rms[static_cast<std::size_t>(best - 1)], b = rms[static_cast<std::size_t>(best)],
                 c = rms[static_cast<std::size_t>(best + 1)];
    const double curvature = a - 2 * b + c;
    if (curvature > 0) refined += 0.5 * step * (a - c) / curvature;
  }
  return refined;
}

}  // namespace

KinematicSurface InitialHelicalWithPitchSearch(const Eigen::Matrix3Xd& p, double pitch, int num_control,
                                               int order) {
  const auto build = [&](double candidate) { return InitialHelical(p, candidate, num_control, order); };
  return build(SearchParameter(pitch, p, build));
}

SpiralSurface InitialSpiralWithGrowthSearch(const Eigen::Matrix3Xd& p, double growth, int num_control,
                                            int order) {
  const auto build = [&](double candidate) { return InitialSpiral(p, candidate, num_control, order); };
  return build(SearchParameter(growth, p, build));
}

SpiralSurface InitialSpiral(const Eigen::Matrix3Xd& p, double growth, int num_control, int order,
                            double margin) {
  if (!(std::abs(growth) > 0)) throw std::invalid_argument("a spiral surface needs a non-zero growth");
  const double period = 2 * M_PI * std::abs(growth);
  std::vector<double> log_size(static_cast<std::size_t>(p.cols())), theta(log_size.size());
  for (Eigen::Index j = 0; j < p.cols(); ++j) {
    const double size = p.col(j).norm();
    if (!(size > 0)) throw std::invalid_argument("a point lies at the spiral's centre");
    theta[static_cast<std::size_t>(j)] = std::atan2(p(1, j), p(0, j));
    log_size[static_cast<std::size_t>(j)] = std::log(size) - growth * theta[static_cast<std::size_t>(j)];
  }
  const std::vector<double> unwrapped = UnwrapAtLargestGap(log_size, period);
  Eigen::Matrix3Xd on_generatrix(3, p.cols());
  double v_lo = INFINITY, v_hi = -INFINITY;
  for (Eigen::Index j = 0; j < p.cols(); ++j) {
    const auto i = static_cast<std::size_t>(j);
    const double v = theta[i] + (log_size[i] - unwrapped[i]) / growth;  // theta + 2 pi k
    v_lo = std::min(v_lo, v);
    v_hi = std::max(v_hi, v);
    on_generatrix.col(j) << std::exp(-growth * v) * std::hypot(p(0, j), p(1, j)), 0.0,
        std::exp(-growth * v) * p(2, j);
  }
  const KinematicSurface profile = InitialRevolution(on_generatrix, num_control, order);
  return SpiralSurface(profile.basis(), profile.profile(), growth, v_lo - margin, v_hi + margin);
}

}  // namespace s2m
