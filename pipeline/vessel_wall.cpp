// `scan2model fit --model revolution --wall <views>`: a vessel's wall, its outer and inner surfaces of
// revolution fitted jointly with the views' poses about one axis (docs/archaeology.md section 10).

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <iomanip>
#include <limits>
#include <optional>
#include <sstream>

#include "acquisition/format_error.h"
#include "fitting/foot_point.h"
#include "fitting/initial_models.h"
#include "fitting/joint_fit.h"
#include "fitting/kinematic_starts.h"
#include "fitting/model_complexity.h"
#include "fitting/noise_estimate.h"
#include "fitting/residual_structure.h"
#include "fitting/revolution_wall.h"
#include "fitting/robust_loss.h"
#include "fitting/sherd_measures.h"
#include "fitting/signed_distance.h"
#include "pipeline/complexity.h"
#include "pipeline/domain_measures.h"
#include "pipeline/exit_code.h"
#include "pipeline/fit_option_table.h"
#include "pipeline/fit_options.h"
#include "pipeline/output.h"
#include "pipeline/views.h"
#include "registration/scan_to_scan.h"

namespace s2m::pipeline {
namespace {

// The two sheets' split of signed offsets e_j (one number per point): the threshold of the 1-D two-means
// (the split of the sorted values minimizing the within-group sum of squares, eq. A23) over the central 98 %
// of the values (a few far outliers must not make a group of their own), with each group's mean and robust
// spread.
struct SheetSplit {
  double threshold = 0.0;
  std::array<double, 2> mean{0.0, 0.0};    // low, high
  std::array<double, 2> spread{0.0, 0.0};  // MadSigma of each group
  std::array<Eigen::Index, 2> count{0, 0};
};

SheetSplit SplitInTwo(const std::vector<double>& values) {
  std::vector<double> v;
  for (double x : values)
    if (std::isfinite(x)) v.push_back(x);
  if (v.size() < 20) throw std::invalid_argument("too few points to split into two surfaces");
  std::sort(v.begin(), v.end());
  const auto trim = v.size() / 100;
  const std::vector<double> central(v.begin() + static_cast<std::ptrdiff_t>(trim),
                                    v.end() - static_cast<std::ptrdiff_t>(trim));
  const std::size_t n = central.size();
  std::vector<double> prefix(n + 1, 0.0), prefix2(n + 1, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    prefix[i + 1] = prefix[i] + central[i];
    prefix2[i + 1] = prefix2[i] + central[i] * central[i];
  }
  auto sse = [&](std::size_t a, std::size_t b) {  // of central[a, b)
    const double m = static_cast<double>(b - a), s = prefix[b] - prefix[a];
    return prefix2[b] - prefix2[a] - s * s / m;
  };
  std::size_t best = 1;
  double best_sse = std::numeric_limits<double>::infinity();
  for (std::size_t k = 1; k < n; ++k) {
    const double total = sse(0, k) + sse(k, n);
    if (total < best_sse) {
      best_sse = total;
      best = k;
    }
  }
  SheetSplit out;
  out.threshold = 0.5 * (central[best - 1] + central[best]);
  std::array<std::vector<double>, 2> groups;
  for (double x : v) groups[x > out.threshold ? 1 : 0].push_back(x);
  for (std::size_t g = 0; g < 2; ++g) {
    out.count[g] = static_cast<Eigen::Index>(groups[g].size());
    if (groups[g].empty()) continue;
    std::vector<double> sorted = groups[g];
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2),
                     sorted.end());
    out.mean[g] = sorted[sorted.size() / 2];  // the median: robust to the group's stragglers
    // The robust spread about that median (eq. 47 of the deviations from it).
    for (double& x : sorted) x -= out.mean[g];
    out.spread[g] =
        MadSigma(Eigen::Map<const Eigen::VectorXd>(sorted.data(), static_cast<Eigen::Index>(sorted.size())));
  }
  return out;
}

// Whether a generatrix folds back on itself (docs/archaeology.md eq. A21b): two of its points more than
// pi `band` apart along it and less than `band` apart in the meridian half-plane. Along a smooth curve two
// points at chord c are at most pi c / 2 apart (a half circle), so only a curve that turns and runs back
// within the band of itself passes; a scanned surface is not one sheet lying twice over itself.
bool FoldsBack(const KinematicSurface& face, double band) {
  const BSplineBasis& basis = face.basis();
  const int samples = 64 * basis.num_control();
  std::vector<Eigen::Vector2d> c(static_cast<std::size_t>(samples) + 1);
  std::vector<double> arc(c.size(), 0.0);
  for (int i = 0; i <= samples; ++i) {
    const auto k = static_cast<std::size_t>(i);
    c[k] = face.ProfilePoint(basis.lo() + (basis.hi() - basis.lo()) * i / samples);
    if (k > 0) arc[k] = arc[k - 1] + (c[k] - c[k - 1]).norm();
  }
  for (std::size_t i = 0; i < c.size(); ++i)
    for (std::size_t j = i + 1; j < c.size(); ++j)
      if (arc[j] - arc[i] > M_PI * band && (c[j] - c[i]).norm() < band) return true;
  return false;
}

// Each face trimmed by the generatrix end rule (docs/method.md eq. 70, face by face): to the parameter span
// the feet of its own points cover, cut where it folds back. A point is the face's own by the sheets' split
// (`sheet_of_point`: RevolutionWall::kOuter, kInner, or -1 for neither, then the nearer face's), not by
// which face is nearer now:
// near a rim a face's free end can curl towards the other sheet's points beyond the other face's end, and
// trimming the other face to the points still nearest to it would then shorten it step by step. A
// generatrix extending past its data is free along its end tangent and would carry a rim diameter or a
// volume beyond the scan. True when a face changed. With `parameter_map`, the linear map of the wall's
// parameters the trim applied (new = map * old), to carry a covariance along.
bool TrimFacesToFeet(RevolutionWall& wall, const Eigen::Matrix3Xd& registered,
                     const std::vector<int>& sheet_of_point, const std::vector<bool>& used, double rms,
                     Eigen::MatrixXd* parameter_map = nullptr) {
  std::array<std::vector<double>, 2> feet_u;
  {
    // The points of no sheet (beyond the heights both sheets reach) count for the face nearer to them.
    std::vector<Eigen::Index> unlabelled;
    for (std::size_t i = 0; i < used.size(); ++i)
      if (used[i] && sheet_of_point[i] < 0) unlabelled.push_back(static_cast<Eigen::Index>(i));
    const Eigen::MatrixXd points = registered(Eigen::all, unlabelled);
    std::vector<FootPoint> feet;
    ComputeFootPoints(wall, points, feet);
    for (const FootPoint& foot : feet) feet_u[static_cast<std::size_t>(foot.t[2])].push_back(foot.t[0]);
  }
  for (int f = 0; f < 2; ++f) {
    std::vector<Eigen::Index> own;
    for (std::size_t i = 0; i < used.size(); ++i)
      if (used[i] && sheet_of_point[i] == f) own.push_back(static_cast<Eigen::Index>(i));
    const Eigen::MatrixXd points = registered(Eigen::all, own);
    std::vector<FootPoint> feet;
    ComputeFootPoints(wall.face(f), points, feet);
    for (const FootPoint& foot : feet) feet_u[static_cast<std::size_t>(f)].push_back(foot.t[0]);
  }
  std::array<KinematicSurface, 2> faces{wall.face(0), wall.face(1)};
  std::array<Eigen::MatrixXd, 2> transforms;  // n_new x n_old per face
  bool changed = false;
  for (std::size_t f = 0; f < 2; ++f) {
    const BSplineBasis& basis = faces[f].basis();
    transforms[f] = Eigen::MatrixXd::Identity(basis.num_control(), basis.num_control());
    const std::array<double, 2> kept =
        GeneratrixEndRuleSpan(basis, faces[f].profile(), feet_u[f], 0.01 * std::max(rms, 1e-12));
    if (!(kept[1] > kept[0])) continue;
    // Only what is more than a hundredth of a span off (feet reach the ends of a well-fitted face).
    const double span = (basis.hi() - basis.lo()) / std::max(1, basis.num_control() - basis.order() + 1);
    const bool trim_lo = kept[0] > basis.lo() + 1e-2 * span, trim_hi = kept[1] < basis.hi() - 1e-2 * span;
    if (!trim_lo && !trim_hi) continue;
    const BasisRefinement r =
        RefineBasis(basis, {}, trim_lo ? kept[0] : basis.lo(), trim_hi ? kept[1] : basis.hi());
    faces[f] = KinematicSurface::Revolution(r.basis, faces[f].profile() * r.transform.transpose());
    transforms[f] = r.transform;
    changed = true;
  }
  if (!changed) return false;
  if (parameter_map) {
    // Each face's (r_k, z_k) interleaved map by its transform per coordinate, the faces as blocks in the
    // wall's order (RevolutionWall keeps the outer face first, whichever was given first).
    const auto rows = 2 * (transforms[0].rows() + transforms[1].rows());
    const auto cols = 2 * (transforms[0].cols() + transforms[1].cols());
    parameter_map->setZero(rows, cols);
    Eigen::Index row0 = 0, col0 = 0;
    for (const Eigen::MatrixXd& t : transforms) {
      for (Eigen::Index i = 0; i < t.rows(); ++i)
        for (Eigen::Index k = 0; k < t.cols(); ++k)
          for (int c = 0; c < 2; ++c) (*parameter_map)(row0 + 2 * i + c, col0 + 2 * k + c) = t(i, k);
      row0 += 2 * t.rows();
      col0 += 2 * t.cols();
    }
  }
  const double before = faces[0].profile().row(0).mean();
  wall = RevolutionWall(faces[0], faces[1]);
  // The trim cannot swap the faces (it keeps each face's own part): the map's block order holds.
  if (parameter_map && wall.face(RevolutionWall::kOuter).profile().row(0).mean() != before)
    throw std::logic_error("the wall's faces swapped in a trim");
  return true;
}

// Both faces with a knot inserted in the middle of every span (the spans halved).
RevolutionWall Refined(const RevolutionWall& wall) {
  std::array<KinematicSurface, 2> faces{wall.face(0), wall.face(1)};
  for (KinematicSurface& face : faces) {
    const std::vector<double> breaks = face.basis().Breakpoints();
    std::vector<double> insert;
    for (std::size_t s = 0; s + 1 < breaks.size(); ++s) insert.push_back(0.5 * (breaks[s] + breaks[s + 1]));
    const BasisRefinement r = RefineBasis(face.basis(), insert);
    face = KinematicSurface::Revolution(r.basis, face.profile() * r.transform.transpose());
  }
  return RevolutionWall(faces[0], faces[1]);
}

int ControlPoints(const RevolutionWall& wall) {
  return std::max(wall.face(0).basis().num_control(), wall.face(1).basis().num_control());
}

nlohmann::json FaceJson(const KinematicSurface& face, Eigen::Index points, double rms) {
  std::vector<std::vector<double>> cp;
  for (Eigen::Index i = 0; i < face.profile().cols(); ++i)
    cp.push_back({face.profile()(0, i), face.profile()(1, i)});
  return {{"order", face.basis().order()},
          {"knots", face.basis().knots()},
          {"control_points_radius_height", cp},
          {"points", points},
          {"rms", NumberOrNull(rms)}};
}

// The points split into the two sheets about one candidate axis (eq. A23), in that axis' frame (`local`,
// with the points' unit normals `local_normals`), with the start of each sheet's surface and how tightly
// the sheets lie about them. A base (eq. A23b) is split by its own chart.
struct Sheets {
  std::vector<bool> across;  // normals far from the mean profile's: a break or a lip, on neither surface
  std::vector<bool> level;   // the base's points (eq. A23b), split by their axial offsets
  SheetSplit split;
  std::optional<SheetSplit> base_split;                   // eq. A23b's, when a base was found
  std::array<std::vector<Eigen::Index>, 2> members;       // by offset: [0] the inner, [1] the outer
  std::optional<std::array<KinematicSurface, 2>> starts;  // none when a group is too small (`why`)
  std::string why;
  std::array<double, 2> own_spread{std::numeric_limits<double>::infinity(),
                                   std::numeric_limits<double>::infinity()};
  double gap = 0.0;  // the median radial distance of a group's points from the other group's start
  // Two surfaces, not one spread out: each group lies near its own start much closer than to the other's.
  bool Separated() const { return starts && gap > 6 * std::max(own_spread[0], own_spread[1]); }
  // Lower is better: the sheets' larger spread relative to their gap.
  double Score() const {
    return starts && gap > 0 ? std::max(own_spread[0], own_spread[1]) / gap
                             : std::numeric_limits<double>::infinity();
  }
};

// The value at fraction q of the values' order (q in [0, 1]).
double QuantileOf(std::vector<double> values, double q) {
  const auto k = static_cast<std::ptrdiff_t>(q * static_cast<double>(values.size() - 1));
  std::nth_element(values.begin(), values.begin() + k, values.end());
  return values[static_cast<std::size_t>(k)];
}

// The points of a scanned base (eq. A23b): normals within 45 degrees of the axis, at the heights of those
// near the axis (within a quarter of all points' median radius; between their 1 % and 99 % height quantiles,
// widened by that span on each side, which takes in the foot's turn), at least 200. A sherd's level breaks
// and a shoulder stay far from the axis, and so do a rim's points whose normals the estimate took across the
// wall (its neighbourhoods hold both surfaces there).
std::vector<bool> BasePoints(const Eigen::Matrix3Xd& local, const Eigen::Matrix3Xd& local_normals) {
  const Eigen::Index n = local.cols();
  std::vector<bool> level(static_cast<std::size_t>(n), false);
  std::vector<double> radii(static_cast<std::size_t>(n));
  for (Eigen::Index j = 0; j < n; ++j) {
    radii[static_cast<std::size_t>(j)] = std::hypot(local(0, j), local(1, j));
    level[static_cast<std::size_t>(j)] = std::abs(local_normals(2, j)) > std::cos(45.0 * M_PI / 180);
  }
  const double near_axis = 0.25 * QuantileOf(radii, 0.5);
  std::vector<double> near_heights;
  for (Eigen::Index j = 0; j < n; ++j)
    if (level[static_cast<std::size_t>(j)] && radii[static_cast<std::size_t>(j)] < near_axis)
      near_heights.push_back(local(2, j));
  std::size_t count = 0;
  if (near_heights.size() >= 20) {
    const double lo = QuantileOf(near_heights, 0.01), hi = QuantileOf(near_heights, 0.99), span = hi - lo;
    for (Eigen::Index j = 0; j < n; ++j) {
      const std::size_t i = static_cast<std::size_t>(j);
      level[i] = level[i] && local(2, j) >= lo - span && local(2, j) <= hi + span;
      count += level[i] ? 1 : 0;
    }
  }
  if (count < 200) level.assign(level.size(), false);
  return level;
}

Sheets SplitSheets(const Eigen::Matrix3Xd& local, const Eigen::Matrix3Xd& local_normals, int order,
                   int first_count) {
  Sheets sheets;
  const Eigen::Index n = local.cols();
  std::vector<bool>& level = sheets.level;
  level = BasePoints(local, local_normals);
  const bool base = std::find(level.begin(), level.end(), true) != level.end();
  std::vector<Eigen::Index> steep;  // the wall's points, radius a function of height
  for (Eigen::Index j = 0; j < n; ++j)
    if (!level[static_cast<std::size_t>(j)]) steep.push_back(j);
  if (steep.size() < 20) {
    sheets.why = std::to_string(steep.size()) + " points off the base";
    return sheets;
  }
  // The two sheets (eq. A23): a mid generatrix, the radius as a function of height through the wall's
  // points, and each point's radial offset from it; its two groups are the two surfaces.
  const KinematicSurface mid = InitialRevolution(local(Eigen::all, steep), 8, order);
  // Points on neither surface (a sherd's breaks, across the wall; a lip) have normals far from the mean
  // profile's at their height (more than 45 degrees, as in eq. 77): they take no part in the split and
  // start left out of the joint fit (eq. 77 decides again at its solution).
  std::vector<bool>& across = sheets.across;
  across.assign(static_cast<std::size_t>(n), false);
  for (const Eigen::Index j : steep) {
    try {
      const double z = local(2, j), h = 0.5;
      const double slope = (mid.RadiusAtHeight(z + h) - mid.RadiusAtHeight(z - h)) / (2 * h);  // dr/dz
      const double phi = std::atan2(local(1, j), local(0, j));
      const Eigen::Vector3d meridian_normal =
          Eigen::Vector3d(std::cos(phi), std::sin(phi), -slope).normalized();
      if (std::abs(meridian_normal.dot(local_normals.col(j))) < std::cos(45.0 * M_PI / 180))
        across[static_cast<std::size_t>(j)] = true;
    } catch (const std::domain_error&) {  // near the mean profile's ends: judged by the split alone
    }
  }
  // Radial offsets from a mean profile, for the wall's points between heights lo and hi (NaN elsewhere).
  auto offsets_from = [&](const KinematicSurface& mean_profile, double lo, double hi) {
    std::vector<double> offsets(static_cast<std::size_t>(n), std::nan(""));
    for (const Eigen::Index j : steep) {
      if (across[static_cast<std::size_t>(j)] || local(2, j) < lo || local(2, j) > hi) continue;
      try {
        offsets[static_cast<std::size_t>(j)] =
            std::hypot(local(0, j), local(1, j)) - mean_profile.RadiusAtHeight(local(2, j));
      } catch (const std::domain_error&) {
      }
    }
    return offsets;
  };
  auto groups_of = [&](const std::vector<double>& e, SheetSplit* split) {
    *split = SplitInTwo(e);
    std::array<std::vector<Eigen::Index>, 2> groups;
    for (Eigen::Index j = 0; j < n; ++j) {
      const double x = e[static_cast<std::size_t>(j)];
      if (std::isfinite(x)) groups[x > split->threshold ? 1 : 0].push_back(j);
    }
    return groups;
  };
  // The range of a coordinate both groups span (their 1 % to 99 % quantiles); empty when a group has
  // fewer than 100 points.
  auto common_range = [&](const std::array<std::vector<Eigen::Index>, 2>& groups,
                          const std::function<double(Eigen::Index)>& coordinate) {
    std::array<std::array<double, 2>, 2> range;
    for (std::size_t g = 0; g < 2; ++g) {
      std::vector<double> values;
      for (const Eigen::Index j : groups[g]) values.push_back(coordinate(j));
      if (values.size() < 100) return std::optional<std::array<double, 2>>();
      std::sort(values.begin(), values.end());
      range[g] = {values[values.size() / 100], values[values.size() - 1 - values.size() / 100]};
    }
    const double lo = std::max(range[0][0], range[1][0]), hi = std::min(range[0][1], range[1][1]);
    return hi > lo ? std::optional<std::array<double, 2>>({lo, hi}) : std::nullopt;
  };
  auto height = [&](Eigen::Index j) { return local(2, j); };
  auto radius = [&](Eigen::Index j) { return std::hypot(local(0, j), local(1, j)); };
  const double infinity = std::numeric_limits<double>::infinity();
  SheetSplit& split = sheets.split;
  std::array<std::vector<Eigen::Index>, 2>& members = sheets.members;
  members = groups_of(offsets_from(mid, -infinity, infinity), &split);
  // Where only one sheet reaches (above the outside's rim the inside rises on along its slant; a break cut
  // at a slant), the mean profile follows that sheet alone and its points' offsets straddle the threshold.
  // So again, from a mean profile over the heights both groups span, only for the points between those
  // heights; the others belong to no sheet in what follows (they still join the fit through their nearer
  // face).
  if (const std::optional<std::array<double, 2>> range = common_range(members, height)) {
    std::vector<Eigen::Index> between;
    for (const Eigen::Index j : steep)
      if (!across[static_cast<std::size_t>(j)] && local(2, j) >= (*range)[0] && local(2, j) <= (*range)[1])
        between.push_back(j);
    if (between.size() >= 20)
      members = groups_of(
          offsets_from(InitialRevolution(local(Eigen::all, between), 8, order), (*range)[0], (*range)[1]),
          &split);
  }
  // The base (eq. A23b): there the radius is no function of height, the height is one of the radius. Its
  // points are split by their axial offsets from a mean height profile z_m(rho) as the wall's by their radial
  // ones (two-means, then again over the radii both groups span); the group away from the wall is the
  // outside's underside, the other the inside's floor. The mean height profile is InitialRevolution's with
  // the coordinates swapped (its "height" the radius, its "radius" the height above the lowest point + 1).
  double base_height = 0.0, wall_height = 0.0;  // the base's and the wall's median heights
  if (base) {
    std::vector<Eigen::Index> flat;
    for (Eigen::Index j = 0; j < n; ++j)
      if (level[static_cast<std::size_t>(j)]) flat.push_back(j);
    auto axial_offsets = [&](const std::vector<Eigen::Index>& through, double lo, double hi) {
      double z_min = infinity;
      for (const Eigen::Index j : through) z_min = std::min(z_min, local(2, j));
      Eigen::Matrix3Xd swapped(3, static_cast<Eigen::Index>(through.size()));
      for (std::size_t i = 0; i < through.size(); ++i)
        swapped.col(static_cast<Eigen::Index>(i)) << local(2, through[i]) - z_min + 1, 0, radius(through[i]);
      const KinematicSurface mean_height = InitialRevolution(swapped, 8, order);
      std::vector<double> offsets(static_cast<std::size_t>(n), std::nan(""));
      for (const Eigen::Index j : flat) {
        if (radius(j) < lo || radius(j) > hi) continue;
        try {
          offsets[static_cast<std::size_t>(j)] =
              local(2, j) - (mean_height.RadiusAtHeight(radius(j)) + z_min - 1);
        } catch (const std::domain_error&) {
        }
      }
      return offsets;
    };
    SheetSplit base_split;
    std::array<std::vector<Eigen::Index>, 2> floors =
        groups_of(axial_offsets(flat, -infinity, infinity), &base_split);
    if (const std::optional<std::array<double, 2>> range = common_range(floors, radius)) {
      std::vector<Eigen::Index> between;
      for (const Eigen::Index j : flat)
        if (radius(j) >= (*range)[0] && radius(j) <= (*range)[1]) between.push_back(j);
      if (between.size() >= 20)
        floors = groups_of(axial_offsets(between, (*range)[0], (*range)[1]), &base_split);
    }
    std::vector<double> wall_heights, base_heights;
    for (const std::vector<Eigen::Index>& m : members)
      for (const Eigen::Index j : m) wall_heights.push_back(local(2, j));
    for (const Eigen::Index j : flat) base_heights.push_back(local(2, j));
    if (wall_heights.empty()) {
      sheets.why = "no wall above the base";
      return sheets;
    }
    wall_height = QuantileOf(wall_heights, 0.5);
    base_height = QuantileOf(base_heights, 0.5);
    const bool wall_above = wall_height > base_height;
    // Two surfaces, as eq. A23 judges the wall's: the groups' medians more than 6 of their robust spreads
    // apart. Otherwise the base shows one surface (the floor not scanned through a narrow opening, or the
    // underside not scanned on a table), and all its points belong to one face: the inside's floor ends where
    // the inner wall begins, so its rim (its 5 % of points farthest from the axis) lies at about the height
    // where both walls begin (the heights both wall groups span), while the underside's rim lies farther
    // down, by about the wall's thickness along the 45-degree normal there (0.7 of it). The floor when that
    // height difference is under half the walls' radial gap, else the underside.
    const bool two =
        base_split.mean[1] - base_split.mean[0] > 6 * std::max(base_split.spread[0], base_split.spread[1]);
    if (two) {
      // floors[0] lies lower (smaller axial offsets): the underside when the wall rises above the base.
      for (std::size_t g = 0; g < 2; ++g) {
        std::vector<Eigen::Index>& to = members[wall_above ? 1 - g : g];
        to.insert(to.end(), floors[g].begin(), floors[g].end());
      }
      sheets.base_split = base_split;
    } else if (const std::optional<std::array<double, 2>> walls = common_range(members, height)) {
      std::vector<Eigen::Index> by_radius = flat;
      std::sort(by_radius.begin(), by_radius.end(),
                [&](Eigen::Index a, Eigen::Index b) { return radius(a) > radius(b); });
      const std::size_t rim_count = std::max<std::size_t>(1, by_radius.size() / 20);
      double rim_height = 0.0;
      for (std::size_t i = 0; i < rim_count; ++i) rim_height += local(2, by_radius[i]);
      rim_height /= static_cast<double>(rim_count);
      const double walls_begin = wall_above ? (*walls)[0] : (*walls)[1];
      const bool floor = std::abs(walls_begin - rim_height) < 0.5 * (split.mean[1] - split.mean[0]);
      std::vector<Eigen::Index>& to = members[floor ? 0 : 1];
      to.insert(to.end(), flat.begin(), flat.end());
    }
    for (std::vector<Eigen::Index>& m : members) std::sort(m.begin(), m.end());
  }
  for (const std::vector<Eigen::Index>& m : members)
    if (static_cast<int>(m.size()) < 4 * first_count) {
      sheets.why = std::to_string(members[0].size()) + " and " + std::to_string(members[1].size()) +
                   " points in the two groups of radial offsets";
      return sheets;
    }
  // Each sheet's start, its generatrix parametrized by height; across a base by the position along the
  // profile: the height up (or down) the wall, continued from where the base meets the wall (its points'
  // largest radius, at their median height) by the radius in towards the axis.
  auto start_of = [&](const std::vector<Eigen::Index>& m) {
    Eigen::VectorXd along(static_cast<Eigen::Index>(m.size()));
    std::vector<double> rim_radii, rim_heights;
    for (const Eigen::Index j : m)
      if (level[static_cast<std::size_t>(j)]) {
        rim_radii.push_back(radius(j));
        rim_heights.push_back(local(2, j));
      }
    const double join_radius = rim_radii.empty() ? 0.0 : QuantileOf(rim_radii, 0.99);
    const double join_height = rim_heights.empty() ? 0.0 : QuantileOf(rim_heights, 0.5);
    const double towards_axis = base_height > wall_height ? 1.0 : -1.0;
    for (std::size_t i = 0; i < m.size(); ++i) {
      const Eigen::Index j = m[i];
      along[static_cast<Eigen::Index>(i)] = level[static_cast<std::size_t>(j)]
                                                ? join_height + towards_axis * (join_radius - radius(j))
                                                : local(2, j);
    }
    return InitialRevolutionAlong(local(Eigen::all, m), along, first_count, order);
  };
  sheets.starts = std::array<KinematicSurface, 2>{start_of(members[0]), start_of(members[1])};
  // Two surfaces, not one spread out: each group lies near its own start (robust spread of the radial
  // residuals) much closer than to the other's (the median radial gap), eq. A23; over the wall's points.
  std::vector<double> gaps;
  for (std::size_t g = 0; g < 2; ++g) {
    std::vector<double> own;
    for (const Eigen::Index j : members[g]) {
      if (level[static_cast<std::size_t>(j)]) continue;
      const double rho = std::hypot(local(0, j), local(1, j));
      try {
        own.push_back(rho - (*sheets.starts)[g].RadiusAtHeight(local(2, j)));
        gaps.push_back(std::abs(rho - (*sheets.starts)[1 - g].RadiusAtHeight(local(2, j))));
      } catch (const std::domain_error&) {
      }
    }
    sheets.own_spread[g] =
        own.empty()
            ? std::numeric_limits<double>::infinity()
            : MadSigma(Eigen::Map<const Eigen::VectorXd>(own.data(), static_cast<Eigen::Index>(own.size())));
  }
  if (!gaps.empty()) {
    std::nth_element(gaps.begin(), gaps.begin() + static_cast<std::ptrdiff_t>(gaps.size() / 2), gaps.end());
    sheets.gap = gaps[gaps.size() / 2];
  }
  return sheets;
}

}  // namespace

FitOutcome ComputeWallFit(const FitOptions& given) {
  FitOptions o = given;
  try {
    if (o.model != "revolution") throw FitFailure(kUsage, "--wall applies to --model revolution");
    if (o.uncertainty != "linear" && o.uncertainty != "none" && !o.uncertainty.empty())
      throw FitFailure(kUsage, "--wall: the uncertainties are the linear propagation's (--uncertainty " +
                                   o.uncertainty + " is not available for a wall)");
    ScanSet storage;
    const ScanSet& set = InputViews(o, storage);
    ResolveDefaultLoss(o, ClassifyInput(o.file, set.scans.empty() ? "" : set.scans.front().metadata.device));
    const std::size_t K = set.scans.size();
    const std::string units = o.units.empty() ? set.scans[0].units : o.units;
    const auto start_time = std::chrono::steady_clock::now();
    auto progress = [&](const std::string& what) {
      if (o.progress) o.progress(what);
    };
    const Eigen::Matrix3Xd merged = set.MergedWorldPoints();
    const NoiseEstimate noise = EstimateNoiseWithDof(set);
    const int order = o.order;
    const ControlPointRequest request = ParseControlPoints(o.control_points, false);
    const int first_count = request.automatic ? std::max(order + 2, 8) : request.first;
    const int max_count = request.automatic ? (request.max > 0 ? request.max : 40) : request.first;
    // The axis (eq. A23): both surfaces are surfaces of revolution about it. Candidates: the robust axis
    // from all points' normals (eqs. 26, 71), which holds on a whole vessel, and those of the direction
    // search of a single surface (eqs. 75-76), which a small sherd needs; each is judged by how tightly the
    // two sheets it splits the points into lie about their own profiles relative to their distance, the
    // tightest kept.
    progress("wall: the axis");
    const Eigen::Matrix3Xd normals = EstimateNormals(merged, 12);
    std::vector<std::pair<RigidMotion, std::string>> axes;
    std::optional<Sheets> best;
    RigidMotion world_T_axis;
    std::string axis_source;
    auto consider = [&](const RigidMotion& frame, const std::string& source) {
      axes.emplace_back(frame, source);
      Sheets candidate = SplitSheets(frame.inverse().apply(merged), frame.rotation().transpose() * normals,
                                     order, first_count);
      if (!best || candidate.Score() < best->Score()) {
        best = std::move(candidate);
        world_T_axis = frame;
        axis_source = source;
      }
    };
    {
      const KinematicAxis axis = RobustKinematicAxisFromNormals(merged, normals, KinematicKind::kRevolution);
      consider(RigidMotion(FrameWithAxis(axis.direction), axis.point), "normals");
    }
    // The direction search unless the sheets about the normals' axis lie as tightly about their starts as
    // the views' noise allows (within 3 sigma: no axis can do better; the search costs seconds).
    const double tight = 3 * (std::isfinite(noise.sigma) ? noise.sigma : 0.0);
    if (!(best->starts && std::max(best->own_spread[0], best->own_spread[1]) <= tight)) {
      progress("wall: searching the axis' direction");
      try {
        for (const AxisCandidate& c : RevolutionAxisCandidates(merged, normals))
          consider(RigidMotion(FrameWithAxis(c.direction), c.point), c.source);
      } catch (const std::invalid_argument&) {  // the normals' axis stands alone
      }
      // On a small sherd the two surfaces together collapse onto no single generatrix about any axis (the
      // wall's thickness dominates the combined profile's residuals, eq. 75), so the search above can miss
      // the axis. Each sheet of the best split so far is one surface, whose own search is the one-surface
      // sherd's (eqs. 75-76): its candidates are judged like the others.
      if (best->starts) {
        const std::array<std::vector<Eigen::Index>, 2> sheet_members = best->members;
        for (const int group : {1, 0}) {  // Sheets::members: [1] the outer surface, [0] the inner
          const std::vector<Eigen::Index>& m = sheet_members[static_cast<std::size_t>(group)];
          const std::string surface = group == 1 ? "outer surface" : "inner surface";
          progress("wall: searching the axis' direction of the " + surface + " alone");
          try {
            for (const AxisCandidate& c :
                 RevolutionAxisCandidates(merged(Eigen::all, m), normals(Eigen::all, m)))
              consider(RigidMotion(FrameWithAxis(c.direction), c.point), c.source + ", " + surface);
          } catch (const std::invalid_argument&) {  // this sheet carries no axis: the others stand
          }
        }
      }
    }
    const Eigen::Matrix3Xd local = world_T_axis.inverse().apply(merged);
    const Sheets& sheets = *best;
    const std::array<std::vector<Eigen::Index>, 2>& members = sheets.members;
    const SheetSplit& split = sheets.split;
    if (!sheets.starts)
      throw FitFailure(kFitError, o.file + ": --wall: the points do not show two surfaces about one axis (" +
                                      sheets.why + ")");
    if (!sheets.Separated())
      throw FitFailure(kFitError,
                       o.file +
                           ": --wall: the points do not show two surfaces about one axis (the two "
                           "groups of radial offsets lie " +
                           Format(sheets.gap, 4) + " " + units + " apart with spreads " +
                           Format(sheets.own_spread[0], 3) + " and " + Format(sheets.own_spread[1], 3) +
                           " about their own profiles); fit one surface without --wall, or crop the "
                           "data to the vessel");
    const std::vector<bool>& across = sheets.across;
    RevolutionWall wall((*sheets.starts)[0], (*sheets.starts)[1]);
    // Each point's sheet by the split, as the wall's face index (the group of larger radial offsets is the
    // outer surface).
    std::vector<int> sheet_of_point(static_cast<std::size_t>(local.cols()), -1);
    for (const Eigen::Index j : members[1])
      sheet_of_point[static_cast<std::size_t>(j)] = RevolutionWall::kOuter;
    for (const Eigen::Index j : members[0])
      sheet_of_point[static_cast<std::size_t>(j)] = RevolutionWall::kInner;

    std::vector<Eigen::Matrix3Xd> scans;
    std::vector<RigidMotion> poses;
    for (const Scan& s : set.scans) {
      scans.push_back(s.points);
      poses.push_back(world_T_axis.inverse() * s.world_T_scan);
    }
    JointFitOptions options = JointOptions(o);
    options.fairness =
        FairnessWeights{o.stretch, o.bending, o.alpha3_given ? o.alpha3 : 0.0, o.beta2, o.beta3};
    std::vector<std::vector<bool>> masks(K);
    {
      std::size_t at = 0;
      for (std::size_t k = 0; k < K; ++k)
        for (Eigen::Index p = 0; p < scans[k].cols(); ++p) masks[k].push_back(across[at++]);
    }
    auto fit = [&](RevolutionWall& w, const std::vector<RigidMotion>& from) {
      JointFitOptions opts = options;
      opts.left_out = masks;
      return FitJointly(w, scans, from, opts);
    };
    auto registered_of = [&](const JointFitResult& r) {
      Eigen::Matrix3Xd all(3, static_cast<Eigen::Index>(set.TotalPoints()));
      Eigen::Index at = 0;
      for (std::size_t k = 0; k < K; ++k) {
        all.middleCols(at, scans[k].cols()) = r.model_T_scan[k].apply(scans[k]);
        at += scans[k].cols();
      }
      return all;
    };
    auto used_points = [&]() {
      std::vector<bool> used;
      for (std::size_t k = 0; k < K; ++k)
        for (Eigen::Index p = 0; p < scans[k].cols(); ++p)
          used.push_back(masks.empty() || !masks[k][static_cast<std::size_t>(p)]);
      return used;
    };
    // Fit, then the end rule with one refit when it trimmed a face.
    auto fit_and_trim = [&](RevolutionWall& w, const std::vector<RigidMotion>& from) {
      JointFitResult r = fit(w, from);
      if (TrimFacesToFeet(w, registered_of(r), sheet_of_point, used_points(), r.residuals.rms)) {
        const int iterations = r.iterations;
        r = fit(w, r.model_T_scan);
        r.iterations += iterations;
      }
      return r;
    };
    progress("wall: fitting both surfaces at " + std::to_string(first_count) + " control points");
    JointFitResult result = fit_and_trim(wall, poses);
    int total_iterations = result.iterations;
    // The count (docs/archaeology.md section 10): every span halved while that lowers the Bayesian
    // information criterion N ln(RSS / N) + P ln N over the points used (eq. A25): a bias of the profile
    // below the noise (an inner surface the coarse spline cannot follow) shows in the RSS of thousands of
    // points long before it shows in the RMS.
    auto criterion = [&](const JointFitResult& r, const RevolutionWall& w) {
      const double rss = r.residuals.rms * r.residuals.rms * static_cast<double>(r.residuals.count);
      const double n = static_cast<double>(r.residuals.count);
      return n * std::log(rss / n) + w.num_parameters() * std::log(n);
    };
    std::string count_reason = request.automatic ? "" : "given";
    nlohmann::json steps = nlohmann::json::array();
    auto record_step = [&](const RevolutionWall& w, const JointFitResult& r) {
      steps.push_back(
          {{"control_points", std::to_string(w.face(RevolutionWall::kOuter).basis().num_control()) + " + " +
                                  std::to_string(w.face(RevolutionWall::kInner).basis().num_control())},
           {"parameters", w.num_parameters()},
           {"points", r.residuals.count},
           {"rms", r.residuals.rms},
           {"bic", criterion(r, w)}});
    };
    record_step(wall, result);
    while (request.automatic) {
      RevolutionWall finer = Refined(wall);
      if (ControlPoints(finer) > max_count) {
        count_reason = "the next refinement exceeds " + std::to_string(max_count) + " control points";
        break;
      }
      progress("wall: refining to " + std::to_string(ControlPoints(finer)) + " control points");
      JointFitResult r = fit_and_trim(finer, result.model_T_scan);
      total_iterations += r.iterations;
      record_step(finer, r);
      if (!(criterion(r, finer) < criterion(result, wall))) {
        count_reason = "halving the spans does not lower the information criterion";
        break;
      }
      wall = finer;
      result = r;
    }
    // The points off the surfaces (eq. 77) decided again at the solution (a lip, breaks, a stand, flying
    // pixels), with one refit when they changed.
    const std::vector<Eigen::Matrix3Xd> view_normals = ViewNormals(set);
    {
      std::vector<std::vector<bool>> off(K);
      Eigen::Index count = 0;
      // A fragment's normal limit from its normals' spread (eq. 77a), for the creases along its breaks.
      OffSurfaceTest test;
      test.angle_from_spread = CoveredTurnFraction(registered_of(result), Eigen::Vector3d::Zero(),
                                                   Eigen::Vector3d::UnitZ()) < kFragmentTurn;
      for (std::size_t k = 0; k < K; ++k) {
        off[k] =
            PointsOffTheSurface(wall, result.model_T_scan[k].apply(scans[k]),
                                view_normals[k].cols() == scans[k].cols()
                                    ? Eigen::Matrix3Xd(result.model_T_scan[k].rotation() * view_normals[k])
                                    : Eigen::Matrix3Xd(),
                                test);
        count += std::count(off[k].begin(), off[k].end(), true);
      }
      if (off != masks) {
        masks = off;
        progress("wall: refitting with the " + std::to_string(count) + " points off the surfaces left out");
        result = fit_and_trim(wall, result.model_T_scan);
        total_iterations += result.iterations;
      }
    }
    result.iterations = total_iterations;
    // A free end can fold back again in the last refit (two sheets fit the noise band better than one, or
    // an end curls towards the other face's points near a rim): the end rule once more, without a refit,
    // the shape covariance carried by the cut's linear map.
    {
      Eigen::MatrixXd map;
      if (TrimFacesToFeet(wall, registered_of(result), sheet_of_point, used_points(), result.residuals.rms,
                          &map) &&
          result.shape_covariance.cols() == map.cols())
        result.shape_covariance = map * result.shape_covariance * map.transpose();
    }
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_time).count();

    // ---- Measures
    std::vector<std::string> outcome_notes;
    const RigidMotion world_T_model = PlaceModelInWorld(set, result.model_T_scan);
    const Eigen::Vector3d axis_point = world_T_model.translation();
    const Eigen::Vector3d axis_direction = world_T_model.rotation().col(2);
    // The way up: the end higher in the world, unless the points cover a fragment whose level edge tells
    // the rim (docs/archaeology.md section 9, measured on the outer surface's points).
    double up_sign = axis_direction.z() < 0 ? -1.0 : 1.0;
    const Eigen::Matrix3Xd registered = registered_of(result);
    const std::vector<bool> used = used_points();
    const Eigen::Index left_out = static_cast<Eigen::Index>(used.size()) -
                                  static_cast<Eigen::Index>(std::count(used.begin(), used.end(), true));
    std::vector<FootPoint> feet;
    ComputeFootPoints(wall, registered, feet);
    std::array<Eigen::Index, 2> face_points{0, 0};
    std::array<double, 2> face_sum_squares{0.0, 0.0};
    for (std::size_t i = 0; i < feet.size(); ++i) {
      if (!used[i]) continue;
      const auto f = static_cast<std::size_t>(feet[i].t[2]);
      ++face_points[f];
      face_sum_squares[f] += feet[i].distance * feet[i].distance;
    }
    const double covered_turn =
        CoveredTurnFraction(registered, Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ());
    std::optional<SherdMeasures> sherd;
    if (covered_turn < kFragmentTurn && result.pose_uncertainty.size() == K) {
      // The outer surface's points within Tukey's 4.6851 robust standard deviations of it (as for one
      // surface, pipeline/multiview_fit.cpp).
      std::vector<double> distances;
      for (std::size_t i = 0; i < feet.size(); ++i)
        if (used[i]) distances.push_back(feet[i].distance);
      const double near = TuningConstant(LossKind::kTukey) *
                          MadSigma(Eigen::Map<const Eigen::VectorXd>(
                              distances.data(), static_cast<Eigen::Index>(distances.size())));
      // With those on the outer generatrix's continuation beyond its ends (eq. A12a).
      std::vector<bool> take =
          NearGeneratrixContinuation(wall.face(RevolutionWall::kOuter), registered, near);
      for (std::size_t i = 0; i < feet.size(); ++i)
        if (feet[i].t[2] == RevolutionWall::kOuter && feet[i].distance <= near) take[i] = true;
      std::vector<Eigen::Index> view_sizes;
      for (const Eigen::Matrix3Xd& scan : scans) view_sizes.push_back(scan.cols());
      std::vector<Eigen::Matrix<double, 6, 6>> pose_covariance;
      for (const ScanPoseUncertainty& u : result.pose_uncertainty) pose_covariance.push_back(u.covariance);
      sherd = MeasureSherdOfPoints(registered, view_sizes, take, pose_covariance,
                                   std::isfinite(noise.sigma) ? noise.sigma : result.residuals.rms,
                                   outcome_notes);
      if (sherd && sherd->rim_side != 0) up_sign = sherd->rim_side;
    }
    const Eigen::MatrixXd& covariance = result.shape_covariance;
    const bool have_covariance = covariance.rows() == wall.num_parameters();
    auto uncertainty_of = [&](const Eigen::VectorXd& gradient) {
      return have_covariance ? std::sqrt(std::max(0.0, gradient.dot(covariance * gradient))) : std::nan("");
    };
    const KinematicSurface& outer = wall.face(RevolutionWall::kOuter);
    const KinematicSurface& inner = wall.face(RevolutionWall::kInner);
    // Heights along the axis in the model frame; "up" heights are up_sign times them.
    auto end_heights = [](const KinematicSurface& f) {
      return std::array<double, 2>{f.ProfilePoint(f.basis().lo()).y(), f.ProfilePoint(f.basis().hi()).y()};
    };
    const std::array<double, 2> outer_ends = end_heights(outer), inner_ends = end_heights(inner);
    auto lower = [&](const std::array<double, 2>& e) {
      return up_sign > 0 ? std::min(e[0], e[1]) : std::max(e[0], e[1]);
    };
    auto upper = [&](const std::array<double, 2>& e) {
      return up_sign > 0 ? std::max(e[0], e[1]) : std::min(e[0], e[1]);
    };
    const double z_base = lower(outer_ends);
    const double z_rim = up_sign > 0 ? std::max(upper(outer_ends), upper(inner_ends))
                                     : std::min(upper(outer_ends), upper(inner_ends));
    const double z_inner_bottom = lower(inner_ends);
    auto above_base = [&](double z) { return up_sign * (z - z_base); };

    // The outer surface's vessel measures (the drawing's outline, rim and base diameters).
    std::vector<Eigen::Vector2d> height_radius;
    std::vector<double> radius_uncertainty;
    for (int i = 0; i <= 50; ++i) {
      const Eigen::Vector2d rz =
          outer.ProfilePoint(outer.basis().lo() + (outer.basis().hi() - outer.basis().lo()) * i / 50);
      height_radius.emplace_back(up_sign * rz.y(), rz.x());
      double u = std::nan("");
      try {
        Eigen::VectorXd g;
        outer.RadiusAtHeight(rz.y(), &g);
        Eigen::VectorXd full = Eigen::VectorXd::Zero(wall.num_parameters());
        full.head(g.size()) = g;
        u = uncertainty_of(full);
      } catch (const std::domain_error&) {
      }
      radius_uncertainty.push_back(u);
    }
    VesselMeasures vessel =
        MeasureVessel(axis_point, up_sign * axis_direction, height_radius, radius_uncertainty, units);
    // The inner surface sampled as the outer (for the drawing's section through the wall).
    for (int i = 0; i <= 50; ++i) {
      const Eigen::Vector2d rz =
          inner.ProfilePoint(inner.basis().lo() + (inner.basis().hi() - inner.basis().lo()) * i / 50);
      vessel.inner_profile.push_back({above_base(rz.y()), rz.x(), std::nan("")});
    }
    // From its lower end up, as the outer profile (the generatrix may run either way along the axis).
    if (vessel.inner_profile.front().height_above_base > vessel.inner_profile.back().height_above_base)
      std::reverse(vessel.inner_profile.begin(), vessel.inner_profile.end());
    vessel.covered_turn = covered_turn;
    if (sherd) vessel.sherd = SummarizeSherd(*sherd, up_sign, up_sign * z_base);
    const std::string cubic = units + "^3";
    // Volumes between planes across the axis (eqs. A1-A4 on each face), with the planes' own uncertainty: a
    // plane through a generatrix's end lies where the scan ends, known to about the views' noise (eq. A24).
    const double plane_u = std::isfinite(noise.sigma) ? noise.sigma : result.residuals.rms;
    auto radius_at = [](const KinematicSurface& f, double z) {
      try {
        return f.RadiusAtHeight(z);
      } catch (const std::domain_error&) {
        return std::nan("");
      }
    };
    auto volume = [&](int face, double z_a, double z_b, Eigen::VectorXd* gradient) {
      const double lo = std::min(z_a, z_b), hi = std::max(z_a, z_b);
      return wall.EnclosedVolume(face, lo, hi, gradient);
    };
    Eigen::VectorXd g_outer, g_inner;
    const double v_outer = volume(RevolutionWall::kOuter, z_base, z_rim, &g_outer);
    const double v_inner = volume(RevolutionWall::kInner, z_inner_bottom, z_rim, &g_inner);
    const double r_out_rim = radius_at(outer, upper(outer_ends)),
                 r_in_rim = radius_at(inner, upper(inner_ends));
    const double r_out_base = radius_at(outer, z_base), r_in_bottom = radius_at(inner, z_inner_bottom);
    auto plane_term = [&](double radius) {
      return std::isfinite(radius) ? M_PI * radius * radius * plane_u : 0.0;
    };
    auto combine = [](double a, double b) { return std::sqrt(a * a + b * b); };
    const Measure capacity{
        v_inner, combine(uncertainty_of(g_inner), combine(plane_term(r_in_rim), plane_term(r_in_bottom))),
        cubic};
    const Measure outer_volume{
        v_outer, combine(uncertainty_of(g_outer), combine(plane_term(r_out_rim), plane_term(r_out_base))),
        cubic};
    // The material: the rim plane's term is the annulus between the faces (pi (r_o^2 - r_i^2) u).
    const double annulus = std::isfinite(r_out_rim) && std::isfinite(r_in_rim)
                               ? M_PI * std::abs(r_out_rim * r_out_rim - r_in_rim * r_in_rim) * plane_u
                               : 0.0;
    const Measure material{
        v_outer - v_inner,
        combine(uncertainty_of(g_outer - g_inner),
                combine(annulus, combine(plane_term(r_out_base), plane_term(r_in_bottom)))),
        cubic};
    vessel.volume = outer_volume;
    std::optional<Measure> fill;
    if (o.fill_height > above_base(z_rim)) {
      // Said, as for one surface: the capacity to the rim is there.
      outcome_notes.push_back("--fill-height " + Format(o.fill_height, 6) + " is above the rim (" +
                              Format(above_base(z_rim), 6) + " " + units +
                              " above the base): no filled capacity, only the capacity to the rim");
    } else if (o.fill_height > 0) {
      Eigen::VectorXd g;
      const double z_fill = z_base + up_sign * o.fill_height;
      if (up_sign * (z_fill - z_inner_bottom) <= 0) {
        fill = Measure{0.0, 0.0, cubic};
      } else {
        const double v = volume(RevolutionWall::kInner, z_inner_bottom, z_fill, &g);
        fill = Measure{v, combine(uncertainty_of(g), plane_term(r_in_bottom)), cubic};
      }
    }
    // The thickness along the height, at 11 heights spread over those both faces reach and both sheets'
    // own points cover (eqs. A21-A22). Beyond a sheet's own points a face rests only on the points of no
    // sheet that the fit took back (eq. 77) and gave to the nearer face, or on its end tangent: where the
    // breaks meet the wall that face is not observed as a surface, and a thickness there measures the fit's
    // end, not the wall.
    nlohmann::json thickness_rows = nlohmann::json::array();
    double t_min = std::numeric_limits<double>::infinity(), t_max = -t_min, t_sum = 0.0;
    int t_count = 0;
    std::array<double, 2> common = wall.CommonHeights();
    for (int f = 0; f < 2; ++f) {
      double lo = std::numeric_limits<double>::infinity(), hi = -lo;
      for (std::size_t i = 0; i < used.size(); ++i)
        if (used[i] && sheet_of_point[i] == f) {
          lo = std::min(lo, registered(2, static_cast<Eigen::Index>(i)));
          hi = std::max(hi, registered(2, static_cast<Eigen::Index>(i)));
        }
      common = {std::max(common[0], lo), std::min(common[1], hi)};
    }
    // A row counts only where each face is observed by its own sheet at the row's two points (eq. A21a):
    // of the sheet's points within half a row's spacing of the point's height, at least half kept by eq. 77,
    // and a kept one within the face's band of the point in the meridian half-plane (Tukey's 4.6851 robust
    // spreads of the kept points' distances to the face, eq. 47), widened by the gap the kept points leave
    // along the height (on data with little or no noise the band alone is narrower than the gaps between
    // the points, and the nearest is that far away wherever the face is observed). A face bent along a
    // break's points by its free end leaves its own points there outside eq. 77's band; a fold of the
    // generatrix, which the breaks' points can carry into the wall, has none of its sheet's points on it.
    const double half_spacing = 0.5 * 0.096 * (common[1] - common[0]);
    struct SheetPoints {
      std::vector<Eigen::Vector2d> radius_height;
      std::vector<bool> kept;
      double band = 0.0;
    };
    std::array<SheetPoints, 2> sheet_points;
    for (int f = 0; f < 2; ++f) {
      SheetPoints& s = sheet_points[static_cast<std::size_t>(f)];
      std::vector<double> kept_distances;  // from the wall's feet: a kept point of a sheet lies on its face
      for (std::size_t i = 0; i < used.size(); ++i) {
        if (sheet_of_point[i] != f) continue;
        const Eigen::Vector3d x = registered.col(static_cast<Eigen::Index>(i));
        s.radius_height.emplace_back(x.head<2>().norm(), x.z());
        s.kept.push_back(used[i]);
        if (used[i] && static_cast<int>(feet[i].t[2]) == f) kept_distances.push_back(feet[i].distance);
      }
      s.band = TuningConstant(LossKind::kTukey) *
               MadSigma(Eigen::Map<const Eigen::VectorXd>(kept_distances.data(),
                                                          static_cast<Eigen::Index>(kept_distances.size())));
    }
    auto observed = [&](int f, const Eigen::Vector2d& radius_height) {
      const SheetPoints& s = sheet_points[static_cast<std::size_t>(f)];
      std::size_t near = 0, kept = 0;
      double nearest = std::numeric_limits<double>::infinity();
      for (std::size_t j = 0; j < s.kept.size(); ++j) {
        if (std::abs(s.radius_height[j].y() - radius_height.y()) > half_spacing) continue;
        ++near;
        if (!s.kept[j]) continue;
        ++kept;
        nearest = std::min(nearest, (s.radius_height[j] - radius_height).norm());
      }
      // The gap about a given height that kept points spread at random over 2h leave with probability
      // 1e-3: (2h / N_kept) ln 1000.
      const double gap =
          2 * half_spacing / static_cast<double>(std::max<std::size_t>(kept, 1)) * std::log(1000.0);
      return kept > 0 && 2 * kept >= near && nearest <= s.band + gap;
    };
    int unobserved_rows = 0;
    for (int i = 0; i <= 10 && common[1] > common[0]; ++i) {
      const double z = common[0] + (common[1] - common[0]) * (0.02 + 0.96 * i / 10.0);
      try {
        Eigen::VectorXd g;
        Eigen::Vector2d inner_foot;
        const double t = wall.ThicknessAtHeight(z, &g, &inner_foot);
        if (!observed(RevolutionWall::kOuter, Eigen::Vector2d(outer.RadiusAtHeight(z), z)) ||
            !observed(RevolutionWall::kInner, inner_foot)) {
          ++unobserved_rows;
          continue;
        }
        thickness_rows.push_back({above_base(z), t, NumberOrNull(uncertainty_of(g))});
        t_min = std::min(t_min, t);
        t_max = std::max(t_max, t);
        t_sum += t;
        ++t_count;
      } catch (const std::domain_error&) {
      }
    }
    if (unobserved_rows > 0)
      outcome_notes.push_back(
          std::to_string(unobserved_rows) +
          " of the wall's thickness rows left out: a face is not observed there by its own surface's points "
          "(docs/archaeology.md eq. A21a)");
    std::sort(thickness_rows.begin(), thickness_rows.end(),
              [](const nlohmann::json& a, const nlohmann::json& b) {
                return a[0].get<double>() < b[0].get<double>();
              });
    // The base's thickness (eq. A21c): where both generatrices come in to the axis (their ends nearer it
    // within a tenth of the outer surface's largest radius of it), eq. A21 from the outer generatrix's
    // point Q at the larger of the two ends' radii, a hundredth of that radius further out at a time while
    // the inner foot is the inner generatrix's end (at most ten steps). Q is found along the outer generatrix
    // from its base end, and the thickness taken at Q's parameter (the radius is no function of height
    // there). The end rule (eq. 70) put both ends where their own points' feet end, so both faces are
    // observed there.
    struct BaseThickness {
      double value = 0, uncertainty = 0, radius = 0;
    };
    std::optional<BaseThickness> base_thickness;
    {
      // The end nearer the axis (whichever way up the vessel stands in the world).
      auto base_end = [&](const KinematicSurface& f) {
        const double lo = f.basis().lo(), hi = f.basis().hi();
        return f.ProfilePoint(lo).x() <= f.ProfilePoint(hi).x() ? lo : hi;
      };
      const int samples = 64 * outer.basis().num_control();
      double max_radius = 0.0;
      for (int i = 0; i <= samples; ++i)
        max_radius = std::max(
            max_radius,
            outer.ProfilePoint(outer.basis().lo() + (outer.basis().hi() - outer.basis().lo()) * i / samples)
                .x());
      const double u_end = base_end(outer),
                   u_far = u_end == outer.basis().lo() ? outer.basis().hi() : outer.basis().lo();
      const double r_outer = std::max(0.0, outer.ProfilePoint(u_end).x());
      const double r_inner = std::max(0.0, inner.ProfilePoint(base_end(inner)).x());
      for (int step = 0;
           step < 10 && !base_thickness && r_outer < 0.1 * max_radius && r_inner < 0.1 * max_radius; ++step) {
        const double r_b = std::max(r_outer, r_inner) + 0.01 * max_radius * step;
        // The first sample from the base end reaching r_b, then bisection on r(u) = r_b.
        double a = u_end, b = u_end;
        bool found = false;
        for (int i = 1; i <= samples && !found; ++i) {
          a = b;
          b = u_end + (u_far - u_end) * i / samples;
          found = outer.ProfilePoint(b).x() >= r_b;
        }
        if (!found) break;
        for (int it = 0; it < 60; ++it) {
          const double m = 0.5 * (a + b);
          (outer.ProfilePoint(m).x() >= r_b ? b : a) = m;
        }
        try {
          Eigen::VectorXd g;
          const double t = wall.ThicknessAtOuterParameter(b, &g);
          base_thickness = BaseThickness{t, uncertainty_of(g), r_b};
        } catch (const std::domain_error&) {  // the inner foot is its end: a step further out
        }
      }
    }

    // Adequacy over both faces: the RMS against the views' noise and the residuals' structure along the
    // height.
    Eigen::Matrix3Xd foot_points;
    const Eigen::VectorXd deviations = SignedDistancesAroundAxis(wall, registered, &foot_points, &feet);
    std::vector<Eigen::Index> kept;
    for (std::size_t i = 0; i < used.size(); ++i)
      if (used[i]) kept.push_back(static_cast<Eigen::Index>(i));
    const Eigen::VectorXd judged = deviations(kept);
    const Eigen::Matrix3Xd judged_feet = foot_points(Eigen::all, kept);
    AdequacyEvidence evidence;
    evidence.family = ModelFamily::kMultiView;
    evidence.model = "revolution wall";
    evidence.control_points =
        std::to_string(outer.basis().num_control()) + " + " + std::to_string(inner.basis().num_control());
    evidence.fit_rms = result.residuals.rms;
    evidence.noise_estimate = noise.sigma;
    evidence.residuals = judged;
    evidence.points = judged_feet;
    evidence.order = OrderByParameter(judged_feet.row(2).transpose());
    evidence.order_description = "the height along the axis";
    evidence.weights = RobustWeightsAt(o.loss, result.loss_scale, judged);
    evidence.extent = ComputeBounds(registered).diagonal();
    Adequacy adequacy = AssessAdequacy(evidence);
    for (int f = 0; f < 2; ++f)
      if (FoldsBack(wall.face(f), sheet_points[static_cast<std::size_t>(f)].band)) {
        adequacy.adequate = false;
        adequacy.suggestions.push_back(
            std::string("the ") + (f == RevolutionWall::kOuter ? "outer" : "inner") +
            " surface's generatrix folds back on itself (docs/archaeology.md eq. A21b): points of neither "
            "surface (a sherd's breaks, a lip, a base or foot the split did not separate) carried it into "
            "the wall; crop them, or read the wall's thickness and volumes as unsure");
      }
    const std::optional<bool> trusted = adequacy.uncertainty_trusted();

    FitOutcome outcome;
    outcome.notes = outcome_notes;
    nlohmann::json& j = outcome.document;
    j = MultiViewDocumentHead(o, set, options, result.loss_scale, axis_point, axis_direction, units);
    j["start"] = {
        {"mode", "wall"},
        {"searched", axes.size() > 1},
        {"reason",
         "--wall: the axis whose two sheets lie tightest about their own profiles (eq. A23), the "
         "surfaces split by their radial offsets from a mean profile"},
        {"normals_adequate", nullptr},
        {"turn_fraction", covered_turn},
        {"fairness", {{"stretch", options.fairness.stretch}, {"bending", options.fairness.bending}}},
        {"source", axis_source},
        {"tried", axes.size()},
        {"left_out_points", left_out}};
    j["complexity"] = {{"mode", request.automatic ? "auto" : "fixed"},
                       {"chosen", std::to_string(outer.basis().num_control()) + " + " +
                                      std::to_string(inner.basis().num_control())},
                       {"stop_reason", count_reason},
                       {"steps", steps}};
    {
      std::vector<std::vector<double>> cp;
      for (Eigen::Index i = 0; i < outer.profile().cols(); ++i)
        cp.push_back({outer.profile()(0, i), outer.profile()(1, i)});
      std::vector<std::vector<double>> samples;
      for (const Eigen::Vector2d& hr : height_radius) samples.push_back({up_sign * hr.x(), hr.y()});
      j["profile"] = {{"order", outer.basis().order()},
                      {"knots", outer.basis().knots()},
                      {"control_points_radius_height", cp},
                      {"samples_height_radius", samples},
                      {"surface", "outer"}};
      j["profile"]["samples_radius_uncertainty"] = nlohmann::json::array();
      for (double u : radius_uncertainty)
        j["profile"]["samples_radius_uncertainty"].push_back(NumberOrNull(u));
    }
    std::vector<RigidMotion> corrected;
    for (std::size_t k = 0; k < K; ++k) corrected.push_back(world_T_model * result.model_T_scan[k]);
    j["views"] = ViewsJson(set, corrected, result);
    AddSolverJson(j, result, seconds);
    j["deviations"] = DeviationsJson(world_T_model.apply(registered), deviations, {},
                                     RobustWeightsAt(o.loss, result.loss_scale, deviations));
    j["adequacy"] = adequacy.ToJson();
    j["vessel"] = vessel.ToJson();
    auto measure_json = [](const Measure& m) {
      return nlohmann::json{
          {"value", m.value}, {"uncertainty", NumberOrNull(m.uncertainty)}, {"unit", m.unit}};
    };
    j["wall"] = {{"outer", FaceJson(outer, face_points[0],
                                    face_points[0] > 0
                                        ? std::sqrt(face_sum_squares[0] / static_cast<double>(face_points[0]))
                                        : std::nan(""))},
                 {"inner", FaceJson(inner, face_points[1],
                                    face_points[1] > 0
                                        ? std::sqrt(face_sum_squares[1] / static_cast<double>(face_points[1]))
                                        : std::nan(""))},
                 {"control_points_reason", count_reason},
                 {"left_out", left_out},
                 {"thickness",
                  {{"columns", {"height_above_base", "thickness", "uncertainty"}},
                   {"rows", thickness_rows},
                   {"min", t_count > 0 ? NumberOrNull(t_min) : nullptr},
                   {"max", t_count > 0 ? NumberOrNull(t_max) : nullptr},
                   {"mean", t_count > 0 ? NumberOrNull(t_sum / t_count) : nullptr},
                   {"unobserved_rows", unobserved_rows},
                   {"method",
                    "square to the wall: from the outer surface's point at each height to the inner "
                    "generatrix (docs/archaeology.md eq. A21)"}}},
                 {"base_thickness",
                  base_thickness ? nlohmann::json{{"value", base_thickness->value},
                                                  {"uncertainty", NumberOrNull(base_thickness->uncertainty)},
                                                  {"unit", units},
                                                  {"radius", base_thickness->radius}}
                                 : nlohmann::json()},
                 {"fragment", vessel.IsFragment()},
                 {"rim_height_above_base", above_base(z_rim)},
                 {"inner_bottom_height_above_base", above_base(z_inner_bottom)},
                 {"capacity", measure_json(capacity)},
                 {"outer_volume", measure_json(outer_volume)},
                 {"material_volume", measure_json(material)},
                 {"plane_uncertainty", plane_u},
                 {"split",
                  {{"threshold", split.threshold},
                   {"offsets", {split.mean[0], split.mean[1]}},
                   {"spreads", {split.spread[0], split.spread[1]}},
                   {"points", {split.count[0], split.count[1]}}}}};
    // The base's split by axial offsets (eq. A23b); offsets and threshold in the height's direction.
    j["wall"]["split"]["base"] = nullptr;
    if (const std::optional<SheetSplit>& b = sheets.base_split)
      j["wall"]["split"]["base"] = {{"threshold", b->threshold},
                                    {"offsets", {b->mean[0], b->mean[1]}},
                                    {"spreads", {b->spread[0], b->spread[1]}},
                                    {"points", {b->count[0], b->count[1]}}};
    if (fill) {
      j["wall"]["fill_height"] = o.fill_height;
      j["wall"]["fill_capacity"] = measure_json(*fill);
    }
    MarkUncertainties(j, trusted);
    WriteRequestedFiles(o, j, result);
    if (!o.output.empty()) WriteProfileFiles(o.output, vessel);

    std::ostringstream text;
    text << "scan2model fit: " << wall.name() << " to " << K << " views (" << set.TotalPoints()
         << " points) of " << o.file << " (units " << units << ")\n\n"
         << UntrustedUncertaintiesLine(trusted) << "  solver            "
         << SolverSummary(options, result, seconds) << "\n"
         << "  loss              " << ToString(o.loss) << "; " << o.loss_reason << "\n"
         << "  axis point        " << Format(axis_point) << "\n"
         << "  axis direction    " << Format(axis_direction) << "\n"
         << "  surfaces          outer " << face_points[0] << " points, " << outer.basis().num_control()
         << " control points; inner " << face_points[1] << " points, " << inner.basis().num_control()
         << " control points (" << count_reason << ")";
    if (left_out > 0) text << "; " << left_out << " points off both left out";
    if (sheets.base_split)
      text << "; the base split into underside and floor by "
           << sheets.base_split->count[0] + sheets.base_split->count[1]
           << " level points (docs/archaeology.md eq. A23b)";
    text << "\n  residuals         RMS " << Format(result.residuals.rms, 6) << ", max "
         << Format(result.residuals.max_abs, 6) << "\n";
    text << ViewsTable(j["views"]) << UnobservableText(result);
    if (o.verbose) text << HistoryTable(result.history);
    text << vessel.Text(trusted);
    text << "  wall              thickness "
         << (t_count > 0 ? Format(t_min, 4) + " to " + Format(t_max, 4) : "-") << " " << units
         << " square to the wall (mean " << (t_count > 0 ? Format(t_sum / t_count, 4) : "-") << ")\n";
    for (const nlohmann::json& row : thickness_rows)
      text << "  " << std::setw(14) << Format(row[0].get<double>(), 6) << " above the base  " << std::setw(10)
           << Format(row[1].get<double>(), 5) << " +- "
           << UncertaintyText(row[2].is_number() ? row[2].get<double>() : std::nan(""), trusted, 2) << "\n";
    if (base_thickness)
      text << "  base              thickness " << Format(base_thickness->value, 5) << " +- "
           << UncertaintyText(base_thickness->uncertainty, trusted, 2) << " " << units << " at "
           << Format(base_thickness->radius, 3) << " " << units
           << " from the axis (underside to floor, square to the base)\n";
    auto measure_line = [&](const char* label, const Measure& m, const std::string& what) {
      text << "  " << label << Format(m.value, 7) << " +- " << UncertaintyText(m.uncertainty, trusted, 2)
           << " " << m.unit << " (" << what << ")\n";
    };
    measure_line("capacity          ", capacity,
                 vessel.IsFragment() ? "inside the inner surface between its ends: a fragment, so only the "
                                       "preserved height band, closed by planes"
                                     : "inside the inner surface, its bottom to the rim plane");
    if (fill)
      measure_line("filled capacity   ", *fill,
                   "inside the inner surface up to " + Format(o.fill_height, 6) + " above the base");
    measure_line("outer volume      ", outer_volume, "inside the outer surface, base plane to rim plane");
    measure_line("material volume   ", material, "between the surfaces");
    text << adequacy.Text();
    outcome.text = text.str();
    return outcome;
  } catch (const FormatError& e) {
    throw FitFailure(kInputError, e.what());
  } catch (const FitFailure&) {
    throw;
  } catch (const std::exception& e) {
    throw FitFailure(kFitError, o.file + ": --wall: " + e.what());
  }
}

}  // namespace s2m::pipeline
