#include "fitting/sherd_measures.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <stdexcept>

namespace s2m {
namespace {

constexpr double kTwoPi = 2 * M_PI;
constexpr double kMadToSigma = 1.4826;  // sigma of a normal sample = 1.4826 x its median absolute deviation

// Angle about the z axis in [0, 2 pi).
double AngleOf(const Eigen::Vector3d& p) {
  const double a = std::atan2(p.y(), p.x());
  return a < 0 ? a + kTwoPi : a;
}

// The arc the angles cover: the turn less its largest gap between angularly neighbouring points. Returns the
// indices (into `angles`) of the first point after the gap and of the last point before it, the arc, and the
// points in angular order with the first point's rank in it (so that the points along the arc, from its
// first to its last, are order[first_rank], order[first_rank + 1], ... cyclically: no second sort).
struct Arc {
  std::size_t first = 0, last = 0;
  double extent = 0.0;
  std::vector<std::size_t> order;
  std::size_t first_rank = 0;
};
Arc CoveredArc(const std::vector<double>& angles) {
  Arc arc;
  arc.order.resize(angles.size());
  std::vector<std::size_t>& order = arc.order;
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return angles[a] < angles[b]; });
  // The wrap-around gap first (from the last angle round to the first).
  double largest = angles[order.front()] + kTwoPi - angles[order.back()];
  arc.first = order.front();
  arc.last = order.back();
  for (std::size_t i = 1; i < order.size(); ++i) {
    const double gap = angles[order[i]] - angles[order[i - 1]];
    if (gap > largest) {
      largest = gap;
      arc.first = order[i];
      arc.last = order[i - 1];
      arc.first_rank = i;
    }
  }
  arc.extent = kTwoPi - largest;
  return arc;
}

double Median(std::vector<double> v) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  if (v.size() % 2 == 1) return *mid;
  return 0.5 * (*mid + *std::max_element(v.begin(), mid));
}

// Eq. A12: 1.4826 x the median absolute deviation from the median.
double RobustSpread(const std::vector<double>& heights) {
  const double centre = Median(heights);
  std::vector<double> deviation;
  deviation.reserve(heights.size());
  for (const double h : heights) deviation.push_back(std::abs(h - centre));
  return kMadToSigma * Median(deviation);
}

// Eq. A13a: the (1 - alpha) quantile of the robust spread of a level edge's sector heights, each the edge
// less an exponential gap of its sector's mean `gaps[s]` plus normal noise `sigma`, by `draws` draws from a
// fixed seed (the same data give the same verdict).
double LevelSpreadQuantile(const std::vector<double>& gaps, double sigma, double alpha, int draws) {
  std::mt19937_64 rng(20261207);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<double> spreads(static_cast<std::size_t>(draws)), heights(gaps.size());
  for (double& spread : spreads) {
    for (std::size_t s = 0; s < gaps.size(); ++s) {
      const double gap = gaps[s] > 0 ? std::exponential_distribution<double>(1.0 / gaps[s])(rng) : 0.0;
      heights[s] = -gap + (sigma > 0 ? sigma * noise(rng) : 0.0);
    }
    spread = RobustSpread(heights);
  }
  const auto k = std::min(spreads.size() - 1,
                          static_cast<std::size_t>(std::ceil((1 - alpha) * static_cast<double>(draws))) - 1);
  std::nth_element(spreads.begin(), spreads.begin() + static_cast<std::ptrdiff_t>(k), spreads.end());
  return spreads[k];
}

// d theta / d(c, cbar) of a point p under x' = x + cbar + c x x (docs/archaeology.md eq. A15):
// rho^2 d theta = -x z c_x - y z c_y + rho^2 c_z - y cbar_x + x cbar_y.
Eigen::Matrix<double, 6, 1> AngleGradient(const Eigen::Vector3d& p) {
  const double rho2 = p.x() * p.x() + p.y() * p.y();
  Eigen::Matrix<double, 6, 1> g;
  g << -p.x() * p.z(), -p.y() * p.z(), rho2, -p.y(), p.x(), 0.0;
  return g / rho2;
}

}  // namespace

bool SherdMeasureOptions::IsValid(std::string* why) const {
  auto fail = [&](const char* message) {
    if (why) *why = message;
    return false;
  };
  if (sectors < 3) return fail("sectors must be at least 3");
  if (!(level_false_rejection > 0 && level_false_rejection < 1))
    return fail("level_false_rejection must be in (0, 1)");
  if (null_draws < 100) return fail("null_draws must be at least 100");
  if (!(rim_band_depth > 0 && rim_band_depth <= 1)) return fail("rim_band_depth must be in (0, 1]");
  if (bands < 1) return fail("bands must be at least 1");
  if (min_band_points < 3) return fail("min_band_points must be at least 3");
  return true;
}

PreservedArc MeasureArc(const Eigen::Matrix3Xd& points, const std::vector<int>& view_of_point,
                        const std::vector<Eigen::Matrix<double, 6, 6>>& pose_covariance, double height_lo,
                        double height_hi, int min_points) {
  PreservedArc out;
  out.height_lo = height_lo;
  out.height_hi = height_hi;
  std::vector<Eigen::Index> inside;
  std::vector<double> angles;
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const Eigen::Vector3d p = points.col(i);
    if (!(p.z() >= height_lo && p.z() <= height_hi) || p.head<2>().squaredNorm() == 0) continue;
    inside.push_back(i);
    angles.push_back(AngleOf(p));
  }
  out.points = static_cast<Eigen::Index>(inside.size());
  if (out.points < std::max(min_points, 3)) return out;
  const Arc arc = CoveredArc(angles);
  // Eq. A14a: the range of the central 90 % of the points, by their angles from the arc's first point.
  {
    const std::size_t count = arc.order.size();
    const auto at = [&](double q) {
      const auto rank = static_cast<std::size_t>(std::lround(q * static_cast<double>(count - 1)));
      const double a = angles[arc.order[(arc.first_rank + rank) % count]] - angles[arc.first];
      return a < 0 ? a + kTwoPi : a;
    };
    out.central_fraction = (at(0.95) - at(0.05)) / kTwoPi;
  }
  // Eq. A14: n points spread uniformly over an arc L leave a range of expected length L (n - 1) / (n + 1),
  // with variance 2 (n - 1) L^2 / ((n + 1)^2 (n + 2)) (order statistics of the uniform distribution), so
  // L = R (n + 1) / (n - 1) is unbiased with standard deviation L sqrt(2 / ((n - 1) (n + 2))).
  const double n = static_cast<double>(out.points);
  const double correction = (n + 1) / (n - 1);
  const double extent = std::min(kTwoPi, arc.extent * correction);
  const double sampling = extent * std::sqrt(2 / ((n - 1) * (n + 2)));
  // Eq. A15: the arc's end points move about the axis when a view's pose does (the axis moves relative to
  // the points); views independent.
  std::vector<Eigen::Matrix<double, 6, 1>> gradient(pose_covariance.size(),
                                                    Eigen::Matrix<double, 6, 1>::Zero());
  const Eigen::Index first = inside[arc.first], last = inside[arc.last];
  const auto view = [&](Eigen::Index i) {
    const int k = view_of_point[static_cast<std::size_t>(i)];
    if (k < 0 || static_cast<std::size_t>(k) >= pose_covariance.size())
      throw std::invalid_argument("a point's view has no pose covariance");
    return static_cast<std::size_t>(k);
  };
  gradient[view(last)] += correction * AngleGradient(points.col(last));
  gradient[view(first)] -= correction * AngleGradient(points.col(first));
  double axis_variance = 0.0;
  for (std::size_t k = 0; k < gradient.size(); ++k)
    axis_variance += gradient[k].dot(pose_covariance[k] * gradient[k]);
  out.fraction = extent / kTwoPi;
  out.axis_uncertainty = std::sqrt(std::max(0.0, axis_variance)) / kTwoPi;
  out.sampling_uncertainty = sampling / kTwoPi;
  // Eq. A16.
  out.uncertainty = std::hypot(out.axis_uncertainty, out.sampling_uncertainty);
  return out;
}

SherdMeasures MeasureSherd(const Eigen::Matrix3Xd& points, const std::vector<int>& view_of_point,
                           const std::vector<Eigen::Matrix<double, 6, 6>>& pose_covariance, double noise,
                           const SherdMeasureOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument("sherd measure options: " + why);
  if (static_cast<Eigen::Index>(view_of_point.size()) != points.cols())
    throw std::invalid_argument("one view index per point is needed");
  if (points.cols() < options.min_band_points)
    throw std::invalid_argument("a sherd needs at least " + std::to_string(options.min_band_points) +
                                " points on its surface, got " + std::to_string(points.cols()));
  SherdMeasures m;
  std::vector<double> angles(static_cast<std::size_t>(points.cols()));
  for (Eigen::Index i = 0; i < points.cols(); ++i)
    angles[static_cast<std::size_t>(i)] = AngleOf(points.col(i));
  const Arc arc = CoveredArc(angles);
  m.covered_fraction = arc.extent / kTwoPi;
  const double start = angles[arc.first];

  // The edges sector by sector (eq. A12): the highest and the lowest point of each sector of the arc.
  const int S = options.sectors;
  std::vector<double> top(static_cast<std::size_t>(S), -std::numeric_limits<double>::infinity()),
      bottom(static_cast<std::size_t>(S), std::numeric_limits<double>::infinity());
  std::vector<int> count(static_cast<std::size_t>(S), 0);
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    double a = angles[static_cast<std::size_t>(i)] - start;
    if (a < 0) a += kTwoPi;
    const int s = std::clamp(static_cast<int>(a / arc.extent * S), 0, S - 1);
    const auto k = static_cast<std::size_t>(s);
    top[k] = std::max(top[k], points(2, i));
    bottom[k] = std::min(bottom[k], points(2, i));
    ++count[k];
  }
  // Eq. A13: in a sector of n points spread over a height H, the extreme point lies about H / (n + 1) short
  // of the edge (an exponential gap: its standard deviation is its mean), and the noise moves it by up to
  // sigma: a level edge varies from sector to sector by about sqrt(mean (H / (n + 1))^2 + sigma^2). The
  // verdict takes the spread's own distribution under that model (A13a).
  auto levelness = [&](const std::vector<double>& edge) {
    EdgeLevelness e;
    std::vector<double> heights, gaps;
    double gap2 = 0.0;
    for (int s = 0; s < S; ++s) {
      const auto k = static_cast<std::size_t>(s);
      if (count[k] < 3) continue;
      heights.push_back(edge[k]);
      gaps.push_back((top[k] - bottom[k]) / (count[k] + 1));
      gap2 += gaps.back() * gaps.back();
    }
    e.sectors = static_cast<int>(heights.size());
    if (e.sectors < 3) return e;
    e.height = Median(heights);
    e.spread = RobustSpread(heights);
    e.expected = std::sqrt(gap2 / e.sectors + noise * noise);
    e.limit = LevelSpreadQuantile(gaps, noise, options.level_false_rejection, options.null_draws);
    e.level = e.spread <= e.limit;
    return e;
  };
  m.upper = levelness(top);
  m.lower = levelness(bottom);
  if (m.upper.sectors < 3) {
    m.rim_reason = "too few points per sector to trace the edges";
  } else if (m.upper.level && !m.lower.level) {
    m.rim_side = 1;
    m.rim_reason = "the upper edge is level across the axis, the lower one is not";
  } else if (m.lower.level && !m.upper.level) {
    m.rim_side = -1;
    m.rim_reason = "the lower edge is level across the axis, the upper one is not";
  } else if (m.upper.level) {
    m.rim_reason = "both edges are level across the axis: a rim cannot be told from a level break";
  } else {
    m.rim_reason =
        "neither edge is level across the axis: a body sherd, whose way up its shape does not tell";
  }

  const double z_lo = points.row(2).minCoeff(), z_hi = points.row(2).maxCoeff(), height = z_hi - z_lo;
  if (m.rim_side != 0) {
    // The band below the rim (eq. A14 in it), deepened until it holds enough points.
    const double rim = m.rim_side > 0 ? m.upper.height : m.lower.height;
    const double infinity = std::numeric_limits<double>::infinity();
    for (double depth = options.rim_band_depth * height;; depth *= 2) {
      m.preserved = m.rim_side > 0 ? MeasureArc(points, view_of_point, pose_covariance, rim - depth, infinity,
                                                options.min_band_points)
                                   : MeasureArc(points, view_of_point, pose_covariance, -infinity,
                                                rim + depth, options.min_band_points);
      if (std::isfinite(m.preserved.fraction) || depth >= height) break;
    }
    // The band's far end is the data's, not infinity.
    m.preserved.height_lo = std::max(m.preserved.height_lo, z_lo);
    m.preserved.height_hi = std::min(m.preserved.height_hi, z_hi);
    m.preserved_at_rim = std::isfinite(m.preserved.fraction);
  }
  if (!m.preserved_at_rim) {
    // A body sherd: the widest of `bands` bands of equal height, told by the range of its central points
    // (eq. A14a): the widest by (A14) itself would be the one whose end points happened to fall closest to
    // its ends, biased up by the choice. The two end bands are left out when there are more: the breaks
    // across the profile run through them, and where a break's face was scanned and the fitted generatrix
    // turned the corner onto it (a level break's face is itself a surface of revolution) their points
    // are the face's.
    // A sparse sherd whose inner bands all hold fewer than `min_band_points` points is cut into half as many.
    for (int bands = options.bands; bands >= 1 && !std::isfinite(m.preserved.fraction); bands /= 2) {
      const int first_band = bands >= 3 ? 1 : 0, last_band = bands - first_band;
      for (int b = first_band; b < last_band; ++b) {
        const double lo = z_lo + height * b / bands, hi = z_lo + height * (b + 1) / bands;
        const PreservedArc a =
            MeasureArc(points, view_of_point, pose_covariance, lo, hi, options.min_band_points);
        if (std::isfinite(a.fraction) && !(a.central_fraction <= m.preserved.central_fraction))
          m.preserved = a;
      }
    }
  }
  return m;
}

std::vector<bool> NearGeneratrixContinuation(const KinematicSurface& surface, const Eigen::Matrix3Xd& points,
                                             double band) {
  const BSplineBasis& basis = surface.basis();
  if (surface.helical())
    throw std::invalid_argument("a generatrix's continuation needs a surface of revolution");
  if (basis.periodic()) throw std::invalid_argument("a generatrix's continuation needs a clamped basis");
  if (!(band > 0)) throw std::invalid_argument("the band about the continuation must be positive");
  std::vector<bool> near(static_cast<std::size_t>(points.cols()), false);
  const std::vector<double> breakpoints = basis.Breakpoints();
  const std::size_t last = breakpoints.size() - 1;
  // Eq. A12a: C(t_end + delta) = C + C' delta + C'' delta^2 / 2 for delta over one end span (outwards),
  // as a polyline fine enough that its chords stay well inside the band.
  constexpr int kSegments = 64;
  for (const int end : {-1, 1}) {
    const double t = end < 0 ? basis.lo() : basis.hi();
    const double span = end < 0 ? breakpoints[1] - breakpoints[0] : breakpoints[last] - breakpoints[last - 1];
    const Eigen::Vector2d c0 = surface.ProfilePoint(t), c1 = surface.ProfilePoint(t, 1),
                          c2 = surface.ProfilePoint(t, 2);
    Eigen::Matrix2Xd line(2, kSegments + 1);
    for (int i = 0; i <= kSegments; ++i) {
      const double delta = end * span * i / kSegments;
      line.col(i) = c0 + c1 * delta + 0.5 * c2 * delta * delta;
    }
    // Most points lie nowhere near an end: the polyline's box grown by the band rules them out cheaply.
    const Eigen::Vector2d box_lo = line.rowwise().minCoeff().array() - band,
                          box_hi = line.rowwise().maxCoeff().array() + band;
    for (Eigen::Index j = 0; j < points.cols(); ++j) {
      if (near[static_cast<std::size_t>(j)]) continue;
      const Eigen::Vector2d q(points.col(j).head<2>().norm(), points(2, j));
      if ((q.array() < box_lo.array()).any() || (q.array() > box_hi.array()).any()) continue;
      for (int i = 0; i < kSegments; ++i) {
        const Eigen::Vector2d a = line.col(i), ab = line.col(i + 1) - a;
        const double length2 = ab.squaredNorm();
        const double s = length2 > 0 ? std::clamp((q - a).dot(ab) / length2, 0.0, 1.0) : 0.0;
        if ((q - a - s * ab).squaredNorm() <= band * band) {
          near[static_cast<std::size_t>(j)] = true;
          break;
        }
      }
    }
  }
  return near;
}

}  // namespace s2m
