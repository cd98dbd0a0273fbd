#include "synthetic/synthetic_cases.h"

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <stdexcept>

#include "fitting/initial_models.h"
#include "fitting/kinematic_surfaces.h"
#include "fitting/part_model.h"
#include "fitting/primitives.h"

namespace s2m {
namespace {

constexpr double kDegree = M_PI / 180.0;

Eigen::Vector3d RandomUnit(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Vector3d v;
  do {
    v = Eigen::Vector3d(n(rng), n(rng), n(rng));
  } while (v.norm() < 1e-6);
  return v.normalized();
}

// The rotation vector and translation of a motion (small rotations: components of the motion's velocity to
// first order).
Motion6 Components(const RigidMotion& m) {
  const Eigen::AngleAxisd aa(m.rotation());
  Motion6 out;
  out << aa.angle() * aa.axis(), m.translation();
  return out;
}

// Index of the only non-zero entry of g, or -1 when g mixes components (a screw).
int SingleComponent(const Motion6& g) {
  int index = -1;
  for (int i = 0; i < 6; ++i) {
    if (std::abs(g[i]) > 1e-12 * g.norm()) {
      if (index >= 0) return -1;
      index = i;
    }
  }
  return index;
}

// The height-indexed radius of a surface of revolution or helical surface at `height` in the truth's frame,
// measured on the fitted model whose frame is shifted along the axis by `shift`.
MeasuredQuantity RadiusAt(const KinematicSurface& truth, const KinematicSurface& fitted,
                          const JointFitResult& r, double height, double shift) {
  Eigen::VectorXd gradient;
  MeasuredQuantity q;
  q.name = "radius at height " + std::to_string(static_cast<int>(std::lround(height)));
  q.truth = truth.RadiusAtHeight(height);
  q.value = fitted.RadiusAtHeight(height + shift, &gradient);
  q.uncertainty =
      r.shape_covariance.size() > 0 ? std::sqrt(gradient.dot(r.shape_covariance * gradient)) : std::nan("");
  return q;
}

int ParameterIndex(const ParametricModel& m, const std::string& name) {
  for (int i = 0; i < m.num_parameters(); ++i)
    if (m.parameter_name(i) == name) return i;
  throw std::logic_error("no parameter " + name);
}

MeasuredQuantity Parameter(const ParametricModel& truth, const ParametricModel& fitted,
                           const JointFitResult& r, const std::string& name) {
  const int i = ParameterIndex(fitted, name);
  return {name, truth.parameters()[i], fitted.parameters()[i],
          r.shape_uncertainty.size() > i ? r.shape_uncertainty[i] : std::nan("")};
}

// The axial offset of the fitted model frame from the truth's, as seen through scan 0 (whose axial gauge
// components the solver keeps fixed): for a helical surface a rotation phi about the axis equals an axial
// shift of -pitch * phi.
double AxialShift(const RigidMotion& fitted0, const RigidMotion& truth0, double pitch) {
  const Motion6 e = Components(fitted0 * truth0.inverse());
  return e[5] - pitch * e[2];
}

ViewOptions StandardErrors(std::uint64_t seed) {
  ViewOptions o;
  o.noise = 0.02;  // mm
  o.rotation_error = 2.0 * kDegree;
  o.translation_error = 2.0;  // mm
  o.seed = seed;
  return o;
}

// A plane face n . x = offset of a part (n: the outward unit normal).
PartFace PlaneFace(const std::string& name, const Eigen::Vector3d& normal, LinearExpression offset) {
  PartFace f;
  f.name = name;
  f.frame = FrameWithAxis(normal);
  f.offset = std::move(offset);
  return f;
}

// The free-form plate's top lies at kPlateHeight + the free displacements (synthetic_cases.h).
constexpr double kPlateHeight = 10.0;

// The plate's top height at (x, y) (part frame) over its height at the centre, on a fitted plate, with the
// uncertainty from the gradient w.r.t. the parameters. The top at (x, y) is z(u, v) at u = x / width + 1/2,
// v = y / depth + 1/2, so d/dwidth = z_u * (-x / width^2); the displacements enter by their basis products.
// A difference of heights: the plate's absolute height is the case's gauge (see "freeform" below).
MeasuredQuantity PlateTopRelief(const PartModel& truth, const PartModel& fitted, const JointFitResult& r,
                                double x, double y) {
  auto height = [](const PartModel& m, double px, double py, Eigen::VectorXd& gradient) {
    const double w = m.parameters()[0], d = m.parameters()[1];
    const ParamT t{px / w + 0.5, py / d + 0.5, 0.0};
    LocalGeometry g;
    m.Evaluate(t, 1, g);
    gradient = Eigen::VectorXd::Zero(m.num_parameters());
    gradient[0] = g.d1(2, 0) * (-px / (w * w));
    gradient[1] = g.d1(2, 1) * (-py / (d * d));
    std::vector<JacobianEntry> entries;
    m.ShapeJacobian(t, false, entries);
    for (const JacobianEntry& e : entries)
      if (e.index >= 2) gradient[e.index] += e.column.z();
    return g.point.z();
  };
  Eigen::VectorXd at_point, at_centre;
  MeasuredQuantity q;
  q.name = "top at (" + std::to_string(static_cast<int>(x)) + ", " + std::to_string(static_cast<int>(y)) +
           ") over centre";
  q.truth = height(truth, x, y, at_point) - height(truth, 0.0, 0.0, at_centre);
  q.value = height(fitted, x, y, at_point) - height(fitted, 0.0, 0.0, at_centre);
  const Eigen::VectorXd gradient = at_point - at_centre;
  q.uncertainty =
      r.shape_covariance.size() > 0 ? std::sqrt(gradient.dot(r.shape_covariance * gradient)) : std::nan("");
  return q;
}

// A part lying on a table seen by 8 views: 6 from 45 degrees above, 2 from 70 (the bottom is never seen).
std::vector<Eigen::Vector3d> TableViewDirections() {
  std::vector<Eigen::Vector3d> directions = RingOfDirections(6, 45 * kDegree, 30 * kDegree);
  for (const Eigen::Vector3d& steep : RingOfDirections(2, 70 * kDegree, 0.0)) directions.push_back(steep);
  return directions;
}

}  // namespace

PartDefinition FreeformPlate(double width, double depth, const Eigen::MatrixXd& displacement) {
  PartDefinition d;
  d.name = "plate with a free-form top";
  d.parameters = {{"width", width, false}, {"depth", depth, false}};
  const int nu = static_cast<int>(displacement.rows()), nv = static_cast<int>(displacement.cols());
  if (nu < 4 || nv < 4) throw std::invalid_argument("FreeformPlate: at least 4 x 4 control points");
  SplinePatch patch{BSplineBasis::ClampedUniform(4, nu), BSplineBasis::ClampedUniform(4, nv), {}};
  patch.free_along = Eigen::Vector3d::UnitZ();
  patch.first_displacement = static_cast<int>(d.parameters.size());
  // Control points at the Greville abscissae (the mean of a control point's `order - 1` inner knots): a
  // B-spline reproduces a linear function from them, so x = (u - 1/2) width and y = (v - 1/2) depth exactly.
  const auto greville = [](const BSplineBasis& b, int i) {
    const std::vector<double>& t = b.knots();
    return (t[static_cast<std::size_t>(i) + 1] + t[static_cast<std::size_t>(i) + 2] +
            t[static_cast<std::size_t>(i) + 3]) /
           3.0;
  };
  for (int i = 0; i < nu; ++i) {
    for (int j = 0; j < nv; ++j) {
      const int index = static_cast<int>(d.parameters.size());
      d.parameters.push_back(
          {"top[" + std::to_string(i) + "," + std::to_string(j) + "]", displacement(i, j), false});
      patch.control_points.push_back({LinearExpression{0.0, {{0, greville(patch.u, i) - 0.5}}},
                                      LinearExpression{0.0, {{1, greville(patch.v, j) - 0.5}}},
                                      LinearExpression{kPlateHeight, {{index, 1.0}}}});
    }
  }
  PartFace top;
  top.name = "top";
  top.type = FaceType::kSplinePatch;
  top.patch = std::move(patch);
  d.faces = {top,
             PlaneFace("bottom", -Eigen::Vector3d::UnitZ(), {0.0, {}}),
             PlaneFace("right", Eigen::Vector3d::UnitX(), {0.0, {{0, 0.5}}}),
             PlaneFace("left", -Eigen::Vector3d::UnitX(), {0.0, {{0, 0.5}}}),
             PlaneFace("back", Eigen::Vector3d::UnitY(), {0.0, {{1, 0.5}}}),
             PlaneFace("front", -Eigen::Vector3d::UnitY(), {0.0, {{1, 0.5}}})};
  return d;
}

// The plate's surface, sampled about uniformly by area: the top by its (u, v) (its slopes are small), the
// sides up to the top's border, the bottom.
SurfaceSample SampleFreeformPlate(const PartModel& plate, int count, std::uint64_t seed) {
  const double width = plate.parameters()[0], depth = plate.parameters()[1];
  std::discrete_distribution<int> face({width * depth, width * depth, depth * kPlateHeight,
                                        depth * kPlateHeight, width * kPlateHeight, width * kPlateHeight});
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  SurfaceSample s{Eigen::Matrix3Xd(3, count), Eigen::Matrix3Xd(3, count)};
  LocalGeometry g;
  for (int j = 0; j < count; ++j) {
    const int k = face(rng);
    const double a = uniform(rng), b = uniform(rng);
    Eigen::Vector3d p, n;
    if (k == 0) {
      plate.Evaluate({a, b, 0.0}, 1, g);
      p = g.point;
      n = Eigen::Vector3d(g.d1.col(0)).cross(Eigen::Vector3d(g.d1.col(1))).normalized();
      if (n.z() < 0) n = -n;
    } else if (k == 1) {
      p = {(a - 0.5) * width, (b - 0.5) * depth, 0.0};
      n = -Eigen::Vector3d::UnitZ();
    } else {
      // A side: the top's border curve above it bounds it.
      const bool along_y = k <= 3;  // right/left: x = +-width/2, running along y
      const double sign = (k % 2 == 0) ? 1.0 : -1.0;
      const ParamT border =
          along_y ? ParamT{sign > 0 ? 1.0 : 0.0, a, 0.0} : ParamT{a, sign > 0 ? 1.0 : 0.0, 0.0};
      plate.Evaluate(border, 0, g);
      p = g.point;
      p.z() *= b;
      n = sign * (along_y ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY());
    }
    s.points.col(j) = p;
    s.normals.col(j) = n;
  }
  return s;
}

PartDefinition ReliefPlate() {
  Eigen::MatrixXd relief(7, 5);
  for (int i = 0; i < 7; ++i)
    for (int j = 0; j < 5; ++j) relief(i, j) = 0.5 * std::sin(1.7 * i + 0.4) * std::cos(1.3 * j - 0.3);
  return FreeformPlate(50.0, 30.0, relief);
}

SyntheticViews ReliefPlateViews() {
  ViewOptions options;
  options.noise = 0.02;
  options.rotation_error = 1.0 * kDegree;
  options.translation_error = 1.0;
  options.seed = 62;
  return ScanFromDirections(SampleFreeformPlate(PartModel(ReliefPlate()), 8000, 61), TableViewDirections(),
                            options);
}

SurfaceSample SampleAroundAxis(const ParametricModel& model, double u0, double u1, double v0, double v1,
                               int count, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  SurfaceSample s{Eigen::Matrix3Xd(3, count), Eigen::Matrix3Xd(3, count), Eigen::Matrix2Xd(2, count)};
  LocalGeometry g;
  for (int j = 0; j < count; ++j) {
    const double u = u0 + (u1 - u0) * uniform(rng), v = v0 + (v1 - v0) * uniform(rng);
    s.parameters.col(j) << u, v;
    model.Evaluate({u, v, 0.0}, 1, g);
    Eigen::Vector3d n = Eigen::Vector3d(g.d1.col(0)).cross(Eigen::Vector3d(g.d1.col(1))).normalized();
    const Eigen::Vector3d p = g.point;
    if (n.x() * p.x() + n.y() * p.y() < 0) n = -n;
    s.points.col(j) = p;
    s.normals.col(j) = n;
  }
  return s;
}

SurfaceSample SampleCounterboredBlock(const Eigen::VectorXd& v, int count, std::uint64_t seed) {
  if (v.size() != 6) throw std::invalid_argument("the counterbored block has six parameters");
  const double W = v[0], D = v[1], H = v[2], rb = v[3] / 2, rc = v[4] / 2, depth = v[5];
  if (!(rb > 0 && rc > rb && 2 * rc < std::min(W, D) && depth > 0 && depth < H))
    throw std::invalid_argument("inconsistent counterbored block dimensions");
  // Faces and their areas: top (minus the counterbore), bottom (minus the bore), four sides, counterbore
  // floor (annulus), counterbore wall, bore wall.
  const std::vector<double> area = {W * D - M_PI * rc * rc,
                                    W * D - M_PI * rb * rb,
                                    D * H,
                                    D * H,
                                    W * H,
                                    W * H,
                                    M_PI * (rc * rc - rb * rb),
                                    2 * M_PI * rc * depth,
                                    2 * M_PI * rb * (H - depth)};
  std::discrete_distribution<int> face(area.begin(), area.end());
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  SurfaceSample s{Eigen::Matrix3Xd(3, count), Eigen::Matrix3Xd(3, count)};
  for (int j = 0; j < count; ++j) {
    Eigen::Vector3d p, n;
    const int f = face(rng);
    const double a = uniform(rng), b = uniform(rng);
    const double angle = 2 * M_PI * a;
    const Eigen::Vector3d radial(std::cos(angle), std::sin(angle), 0.0);
    switch (f) {
      case 0:
      case 1: {  // rejection sampling outside the hole
        const double hole = f == 0 ? rc : rb;
        do {
          p = Eigen::Vector3d((uniform(rng) - 0.5) * W, (uniform(rng) - 0.5) * D, f == 0 ? H : 0.0);
        } while (std::hypot(p.x(), p.y()) < hole);
        n = f == 0 ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d(-Eigen::Vector3d::UnitZ());
        break;
      }
      case 2:
      case 3:
        p = Eigen::Vector3d(f == 2 ? W / 2 : -W / 2, (a - 0.5) * D, b * H);
        n = Eigen::Vector3d(f == 2 ? 1.0 : -1.0, 0.0, 0.0);
        break;
      case 4:
      case 5:
        p = Eigen::Vector3d((a - 0.5) * W, f == 4 ? D / 2 : -D / 2, b * H);
        n = Eigen::Vector3d(0.0, f == 4 ? 1.0 : -1.0, 0.0);
        break;
      case 6:  // annulus, uniform by area
        p = std::sqrt(rb * rb + b * (rc * rc - rb * rb)) * radial + Eigen::Vector3d(0, 0, H - depth);
        n = Eigen::Vector3d::UnitZ();
        break;
      case 7:  // walls face the axis (the material is outside)
        p = rc * radial + Eigen::Vector3d(0, 0, H - depth + b * depth);
        n = -radial;
        break;
      default:
        p = rb * radial + Eigen::Vector3d(0, 0, b * (H - depth));
        n = -radial;
        break;
    }
    s.points.col(j) = p;
    s.normals.col(j) = n;
  }
  return s;
}

std::vector<Eigen::Vector3d> RingOfDirections(int count, double elevation, double azimuth0) {
  std::vector<Eigen::Vector3d> out;
  for (int k = 0; k < count; ++k) {
    const double az = azimuth0 + 2 * M_PI * k / count;
    out.emplace_back(std::cos(elevation) * std::cos(az), std::cos(elevation) * std::sin(az),
                     std::sin(elevation));
  }
  return out;
}

SyntheticViews ScanFromDirections(const SurfaceSample& surface,
                                  const std::vector<Eigen::Vector3d>& directions, const ViewOptions& o) {
  std::mt19937_64 rng(o.seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  const Eigen::Vector3d target = surface.points.rowwise().mean();
  SyntheticViews out;
  for (const Eigen::Vector3d& direction : directions) {
    const Eigen::Vector3d d = direction.normalized();
    // The scanner looks along -d at the target; its z axis is the viewing direction.
    const Eigen::Matrix3d frame = FrameWithAxis(-d);
    const RigidMotion model_T_scan(frame, target + o.scanner_distance * d);
    std::vector<Eigen::Vector3d> seen;
    for (Eigen::Index j = 0; j < surface.points.cols(); ++j) {
      if (surface.normals.col(j).dot(d) <= o.min_facing_cosine) continue;
      seen.push_back(surface.points.col(j) + o.noise * noise(rng) * surface.normals.col(j));
    }
    if (seen.empty()) throw std::invalid_argument("a view direction sees no point of the surface");
    Eigen::Matrix3Xd model_points(3, static_cast<Eigen::Index>(seen.size()));
    for (std::size_t i = 0; i < seen.size(); ++i) model_points.col(static_cast<Eigen::Index>(i)) = seen[i];
    out.scans.push_back(model_T_scan.inverse().apply(model_points));
    out.model_T_scan_true.push_back(model_T_scan);
    const RigidMotion error(Eigen::AngleAxisd(o.rotation_error, RandomUnit(rng)).toRotationMatrix(),
                            o.translation_error * RandomUnit(rng));
    out.model_T_scan_recorded.push_back(error * model_T_scan);
  }
  return out;
}

ScanSet RecordedViews(const SyntheticCase& c) {
  ScanSet set;
  set.name = "synthetic " + c.name + ", " + std::to_string(c.views.scans.size()) + " views";
  for (std::size_t k = 0; k < c.views.scans.size(); ++k) {
    Scan scan;
    scan.points = c.views.scans[k];
    scan.units = "mm";
    scan.world_T_scan = c.views.model_T_scan_recorded[k];
    set.scans.push_back(scan);
  }
  return set;
}

std::vector<Motion6> ObservablePoseErrors(const ParametricModel& model,
                                          const std::vector<RigidMotion>& fitted,
                                          const std::vector<RigidMotion>& truth) {
  if (fitted.size() != truth.size() || fitted.empty()) throw std::invalid_argument("one pose per scan");
  std::array<bool, 6> free_per_scan{}, common{};
  for (const Motion6& g : model.InvariantMotions()) {
    for (int i = 0; i < 6; ++i) free_per_scan[static_cast<std::size_t>(i)] |= std::abs(g[i]) > 0;
  }
  for (const Motion6& g : model.CommonMotionsAbsorbedByShape()) {
    const int i = SingleComponent(g);
    for (int c = 0; c < 6; ++c) {
      if (std::abs(g[c]) > 0) {
        // A common screw, or a component also free per scan: not comparable at all.
        if (i < 0) free_per_scan[static_cast<std::size_t>(c)] = true;
        common[static_cast<std::size_t>(c)] = true;
      }
    }
  }
  std::vector<Motion6> errors;
  for (std::size_t k = 0; k < fitted.size(); ++k)
    errors.push_back(Components(fitted[k] * truth[k].inverse()));
  const Motion6 first = errors[0];
  for (Motion6& e : errors) {
    for (int i = 0; i < 6; ++i) {
      const auto c = static_cast<std::size_t>(i);
      if (free_per_scan[c]) {
        e[i] = std::numeric_limits<double>::quiet_NaN();
      } else if (common[c]) {
        e[i] -= first[i];
      }
    }
  }
  return errors;
}

std::vector<std::string> SyntheticCaseNames() {
  return {"vase", "helical", "spiral", "part", "freeform"};
}

SyntheticCase MakeSyntheticCase(const std::string& name, double sample_scale) {
  if (!(sample_scale > 0.0) || !std::isfinite(sample_scale))
    throw std::invalid_argument("the sample scale must be a positive number");
  // The surface samples' sizes; the views see a part of each.
  const auto samples = [sample_scale](int count) {
    return static_cast<int>(std::lround(count * sample_scale));
  };
  SyntheticCase c;
  c.name = name;
  c.noise = 0.02;
  c.options.error_term = ErrorTerm::kTdm;
  c.options.optimizer.max_iterations = 100;
  if (name == "vase") {
    // The demo's vase (recordings/README.md), 150 mm tall; 8 views at 20 degrees elevation.
    Eigen::Matrix2Xd profile(2, 8);
    profile << 30, 42, 58, 66, 55, 38, 34, 41,  //
        0, 20, 45, 70, 95, 120, 135, 150;
    auto truth =
        std::make_unique<KinematicSurface>(KinematicSurface::Revolution(UnitSpacedClamped(4, 8), profile));
    const SurfaceSample s =
        SampleAroundAxis(*truth, truth->basis().lo(), truth->basis().hi(), -M_PI, M_PI, samples(8000), 11);
    c.views = ScanFromDirections(s, RingOfDirections(8, 20 * kDegree), StandardErrors(12));
    // The automatic initial model of `scan2model fit --model revolution`: axis and profile from the views
    // merged at their recorded poses.
    std::vector<Eigen::Matrix3Xd> merged;
    Eigen::Index total = 0;
    for (std::size_t k = 0; k < c.views.scans.size(); ++k) {
      merged.push_back(c.views.model_T_scan_recorded[k].apply(c.views.scans[k]));
      total += merged.back().cols();
    }
    Eigen::Matrix3Xd all(3, total);
    Eigen::Index at = 0;
    for (const auto& m : merged) {
      all.middleCols(at, m.cols()) = m;
      at += m.cols();
    }
    c.start = std::make_unique<KinematicSurface>(InitialRevolution(all, 8, 4));
    // SDM here: from 2-degree pose errors TDM stalls 12 % above the noise (measured: RMS 0.0224 for noise
    // 0.02 after 100 iterations), SDM reaches the noise.
    c.options.error_term = ErrorTerm::kSdm;
    c.options.optimizer.max_iterations = 150;
    const KinematicSurface true_vase = *truth;
    const std::vector<RigidMotion> true_poses = c.views.model_T_scan_true;
    c.measure = [true_vase, true_poses](const ParametricModel& m, const JointFitResult& r) {
      const auto& fitted = dynamic_cast<const KinematicSurface&>(m);
      const double shift = AxialShift(r.model_T_scan[0], true_poses[0], 0.0);
      return std::vector<MeasuredQuantity>{RadiusAt(true_vase, fitted, r, 20, shift),
                                           RadiusAt(true_vase, fitted, r, 70, shift),
                                           RadiusAt(true_vase, fitted, r, 120, shift)};
    };
    c.truth = std::move(truth);
  } else if (name == "helical") {
    // A screw-like helical surface, 60 mm across, pitch 4 mm per radian (25 mm per turn), two turns. The data
    // stop 1 rad (4 mm along the axis) inside the model's angle range: a common axial shift of the views is
    // gauge (the profile absorbs it: a shift is a rotation for a helical surface), and it must not push data
    // off the model's ends.
    Eigen::Matrix2Xd profile(2, 6);
    profile << 18, 26, 30, 29, 24, 17,  //
        -6, -4, -1, 1, 4, 6;
    auto truth = std::make_unique<KinematicSurface>(
        KinematicSurface::Helical(UnitSpacedClamped(4, 6), profile, 4.0, 2.0));
    const SurfaceSample s = SampleAroundAxis(*truth, truth->basis().lo(), truth->basis().hi(),
                                             -2 * M_PI + 1.0, 2 * M_PI - 1.0, samples(12000), 21);
    // Views from above and below: the thread's flanks face both ways.
    std::vector<Eigen::Vector3d> directions = RingOfDirections(3, 30 * kDegree);
    for (const Eigen::Vector3d& below : RingOfDirections(3, -30 * kDegree, 60 * kDegree))
      directions.push_back(below);
    c.views = ScanFromDirections(s, directions, StandardErrors(22));
    c.start = std::make_unique<KinematicSurface>(
        KinematicSurface::Helical(UnitSpacedClamped(4, 6), profile * 1.02, 3.9, 2.0));
    // Per-view motions from the start (measured: with 5 shared-motion iterations first the fit stalls at RMS
    // 0.034 for noise 0.02; without, it reaches the noise in 15 iterations).
    c.options.shared_motion_iterations = 0;
    const KinematicSurface true_screw = *truth;
    const std::vector<RigidMotion> true_poses = c.views.model_T_scan_true;
    c.measure = [true_screw, true_poses](const ParametricModel& m, const JointFitResult& r) {
      const auto& fitted = dynamic_cast<const KinematicSurface&>(m);
      const double shift = AxialShift(r.model_T_scan[0], true_poses[0], fitted.pitch());
      return std::vector<MeasuredQuantity>{Parameter(true_screw, fitted, r, "pitch"),
                                           RadiusAt(true_screw, fitted, r, -3, shift),
                                           RadiusAt(true_screw, fitted, r, 3, shift)};
    };
    c.truth = std::move(truth);
  } else if (name == "spiral") {
    // A shell: whorl cross-section 20 mm across at v = 0, growth 0.12 per radian (x 2.1 per whorl). The data
    // stop 0.2 rad inside the model's angle range: a common rotation (the gauge the profile's scale absorbs)
    // must not push data off the model's ends.
    // Three spans: a two-span cubic's control points can move along the curve as (u - 1) C'(u), which
    // stays a cubic spline (C''' jumps only at the knot u = 1, where the factor vanishes) and only extends
    // the curve at its ends: an exact null direction of the normal matrix (measured: eigenvalue 4e-18 of the
    // largest).
    Eigen::Matrix2Xd whorl(2, 6);
    whorl << 20, 25, 30, 31, 26, 19,  //
        -8, -6, -2, 2, 6, 8;
    auto truth = std::make_unique<SpiralSurface>(UnitSpacedClamped(4, 6), whorl, 0.12, -2.0, 6.0);
    const SurfaceSample s =
        SampleAroundAxis(*truth, truth->basis().lo(), truth->basis().hi(), -1.8, 5.8, samples(12000), 31);
    // From above and below: the whorl's cross-section opens both ways.
    std::vector<Eigen::Vector3d> directions = RingOfDirections(3, 30 * kDegree);
    for (const Eigen::Vector3d& below : RingOfDirections(3, -30 * kDegree, 60 * kDegree))
      directions.push_back(below);
    c.views = ScanFromDirections(s, directions, StandardErrors(32));
    c.start = std::make_unique<SpiralSurface>(UnitSpacedClamped(4, 6), whorl * 0.98, 0.115, -2.0, 6.0);
    // Per-view motions from the start (measured: after 5 shared-motion iterations on the mis-registered
    // cloud the whorl profile is distorted and the fit stalls above the noise).
    c.options.shared_motion_iterations = 0;
    const SpiralSurface true_shell = *truth;
    c.measure = [true_shell](const ParametricModel& m, const JointFitResult& r) {
      const auto& fitted = dynamic_cast<const SpiralSurface&>(m);
      MeasuredQuantity growth = Parameter(true_shell, fitted, r, "growth");
      MeasuredQuantity rate{"whorl expansion rate", true_shell.WhorlExpansionRate(),
                            fitted.WhorlExpansionRate(),
                            2 * M_PI * fitted.WhorlExpansionRate() * growth.uncertainty};
      return std::vector<MeasuredQuantity>{growth, rate};
    };
    c.truth = std::move(truth);
  } else if (name == "part") {
    // docs/examples/counterbored_block.part.json; 6 views from above, 2 from below.
    PartDefinition d;
    d.name = "block with a through bore and a counterbore";
    // The height is fixed (as in the part file): views from above never see the bottom, so nothing relates
    // the top to it (the solver would report the height unobservable).
    const std::vector<std::string> names = {"width", "depth", "bore_diameter", "counterbore_diameter",
                                            "counterbore_depth"};
    const Eigen::VectorXd free_values = (Eigen::VectorXd(5) << 60, 40, 10, 18, 6).finished();
    const double height = 20.0;
    for (int i = 0; i < 5; ++i)
      d.parameters.push_back({names[static_cast<std::size_t>(i)], free_values[i], false});
    const Eigen::VectorXd values = (Eigen::VectorXd(6) << 60, 40, height, 10, 18, 6).finished();
    auto bore = [](const std::string& n, int diameter) {
      PartFace f;
      f.name = n;
      f.type = FaceType::kCylinder;
      f.radius = {0.0, {{diameter, 0.5}}};
      return f;
    };
    d.faces = {PlaneFace("top", Eigen::Vector3d::UnitZ(), {height, {}}),
               PlaneFace("bottom", -Eigen::Vector3d::UnitZ(), {0.0, {}}),
               PlaneFace("right", Eigen::Vector3d::UnitX(), {0.0, {{0, 0.5}}}),
               PlaneFace("left", -Eigen::Vector3d::UnitX(), {0.0, {{0, 0.5}}}),
               PlaneFace("back", Eigen::Vector3d::UnitY(), {0.0, {{1, 0.5}}}),
               PlaneFace("front", -Eigen::Vector3d::UnitY(), {0.0, {{1, 0.5}}}),
               bore("bore", 2),
               bore("counterbore", 3),
               PlaneFace("counterbore floor", Eigen::Vector3d::UnitZ(), {height, {{4, -1.0}}})};
    auto truth = std::make_unique<PartModel>(d);
    const SurfaceSample s = SampleCounterboredBlock(values, samples(16000), 41);
    // The block lies on a table: 6 views from 45 degrees above, 2 from 70 degrees; the bottom is never seen.
    const std::vector<Eigen::Vector3d> directions = TableViewDirections();
    c.views = ScanFromDirections(s, directions, StandardErrors(42));
    // The nominal design, off by 0.5 mm in every dimension, as a drawing would start it.
    PartDefinition start = d;
    for (PartParameter& p : start.parameters) p.value += 0.5;
    c.start = std::make_unique<PartModel>(start);
    auto true_part = std::make_shared<PartModel>(d);
    c.measure = [true_part](const ParametricModel& m, const JointFitResult& r) {
      std::vector<MeasuredQuantity> out;
      for (int i = 0; i < m.num_parameters(); ++i)
        out.push_back(Parameter(*true_part, m, r, m.parameter_name(i)));
      return out;
    };
    c.truth = std::move(truth);
  } else if (name == "freeform") {
    // A 50 x 30 mm plate, 10 mm thick, whose top is a free-form bicubic patch (up to 0.8 mm off flat) with a
    // free displacement per control point. It lies on a table: 6 views from 45 degrees above, 2 from 70.
    // Nothing seen relates the top to the bottom (the sides are vertical), so a common vertical shift of
    // the views trades with a common displacement of the control points: one unobservable direction, by
    // design. What the data determine are the width, the depth and the top's relief (heights relative to
    // one another).
    Eigen::Matrix4d bump;
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) bump(i, j) = 0.8 * std::sin(1.3 * i + 0.7) * std::cos(0.9 * j - 0.4);
    const PartDefinition d = FreeformPlate(50.0, 30.0, bump);
    auto truth = std::make_unique<PartModel>(d);
    const SurfaceSample s = SampleFreeformPlate(*truth, samples(12000), 51);
    const std::vector<Eigen::Vector3d> directions = TableViewDirections();
    c.views = ScanFromDirections(s, directions, StandardErrors(52));
    c.gauge_directions = 1;
    // The design: a flat top, the plate 0.5 mm off in width and depth.
    c.start = std::make_unique<PartModel>(FreeformPlate(50.5, 30.5, Eigen::Matrix4d::Zero()));
    auto true_plate = std::make_shared<PartModel>(d);
    c.measure = [true_plate](const ParametricModel& m, const JointFitResult& r) {
      const auto& fitted = dynamic_cast<const PartModel&>(m);
      return std::vector<MeasuredQuantity>{Parameter(*true_plate, m, r, "width"),
                                           Parameter(*true_plate, m, r, "depth"),
                                           PlateTopRelief(*true_plate, fitted, r, 12.0, 6.0),
                                           PlateTopRelief(*true_plate, fitted, r, -20.0, -10.0),
                                           PlateTopRelief(*true_plate, fitted, r, 22.0, -12.0)};
    };
    c.truth = std::move(truth);
  } else {
    throw std::invalid_argument("unknown synthetic case '" + name +
                                "' (vase, helical, spiral, part, freeform)");
  }
  return c;
}

namespace {

// Gaussian noise along the normals, then the axis frame placed in the world: tilted by 35 degrees about
// (1, 2, 0) and moved to (12, -7, 40).
void PlaceCloud(KinematicCloud& c, const SurfaceSample& s, double noise, std::mt19937_64& rng) {
  std::normal_distribution<double> gauss(0.0, 1.0);
  Eigen::Matrix3Xd p = s.points;
  for (Eigen::Index j = 0; j < p.cols(); ++j) p.col(j) += noise * gauss(rng) * s.normals.col(j);
  c.world_T_model =
      RigidMotion(Eigen::AngleAxisd(35 * kDegree, Eigen::Vector3d(1, 2, 0).normalized()).toRotationMatrix(),
                  Eigen::Vector3d(12, -7, 40));
  c.points = c.world_T_model.apply(p);
  c.axis_point = c.world_T_model.translation();
  c.axis_direction = c.world_T_model.rotation().col(2);
}

// The cloud of a kinematic surface's points over its whole generatrix and the coiling angles [v0, v1], with
// normal noise, placed in the world (PlaceCloud); the caller sets the truth's pitch or growth.
template <class Surface>
KinematicCloud CloudAroundAxis(std::unique_ptr<Surface> truth, double v0, double v1, double noise, int count,
                               std::uint64_t seed) {
  const SurfaceSample s =
      SampleAroundAxis(*truth, truth->basis().lo(), truth->basis().hi(), v0, v1, count, seed);
  KinematicCloud c;
  std::mt19937_64 rng(seed + 1);
  PlaceCloud(c, s, noise, rng);
  c.surface_points = c.points.cols();
  c.surface_parameters = s.parameters;
  c.truth = std::move(truth);
  return c;
}

}  // namespace

KinematicCloud ShallowThreadCloud(double relief, double noise, int count, std::uint64_t seed) {
  const double pitch = 4.0, lead = 2 * M_PI * pitch;
  const int m = 12;
  Eigen::Matrix2Xd profile(2, m);
  for (int k = 0; k < m; ++k) {
    const double z = -0.5 * lead + lead * k / (m - 1);
    profile.col(k) << 28.0 + 0.5 * relief * std::cos(2 * M_PI * z / lead), z;
  }
  auto truth = std::make_unique<KinematicSurface>(
      KinematicSurface::Helical(UnitSpacedClamped(4, m), profile, pitch, 3.5));
  // Three turns of data, inside the model's 3.5 (a gauge shift must not push data off its ends).
  KinematicCloud c = CloudAroundAxis(std::move(truth), -3 * M_PI, 3 * M_PI, noise, count, seed);
  c.pitch = pitch;
  return c;
}

KinematicCloud ConicalShellCloud(double ripple_amplitude, double noise, int count, std::uint64_t seed) {
  const double growth = 0.05, period = 2 * M_PI * growth, slope = -60 * kDegree;
  const int m = 10;
  Eigen::Matrix2Xd profile(2, m);
  for (int k = 0; k < m; ++k) {
    const double t = static_cast<double>(k) / (m - 1);  // one whorl: sizes 20 to 20 e^{2 pi g}
    const double size = 20.0 * std::exp(period * t), ripple = ripple_amplitude * std::sin(2 * M_PI * t);
    profile.col(k) << size * std::cos(slope) - ripple * std::sin(slope),
        size * std::sin(slope) + ripple * std::cos(slope);
  }
  auto truth = std::make_unique<SpiralSurface>(UnitSpacedClamped(4, m), profile, growth, -2.2 * 2 * M_PI,
                                               2.2 * 2 * M_PI);
  KinematicCloud c = CloudAroundAxis(std::move(truth), -4 * M_PI, 4 * M_PI, noise, count, seed);
  c.growth = growth;
  return c;
}

KinematicCloud AllometricShellCloud(double growth_change, double axial_excess, double noise, int count,
                                    std::uint64_t seed) {
  Eigen::Matrix2Xd whorl(2, 6);
  whorl << 20, 25, 30, 31, 26, 19,  //
      -8, -6, -2, 2, 6, 8;
  const double growth = 0.12;
  auto truth = std::make_unique<SpiralSurface>(
      SpiralSurface(UnitSpacedClamped(4, 6), whorl, growth, -M_PI - 0.2, 3 * M_PI + 0.2)
          .WithAllometry(growth_change, axial_excess));
  KinematicCloud c = CloudAroundAxis(std::move(truth), -M_PI, 3 * M_PI, noise, count, seed);
  c.growth = growth;
  return c;
}

KinematicCloud SherdCloud(double arc_fraction, bool fracture_faces, double noise, int count,
                          std::uint64_t seed) {
  if (!(arc_fraction > 0 && arc_fraction <= 1)) throw std::invalid_argument("an arc fraction in (0, 1]");
  Eigen::Matrix2Xd vase(2, 8);
  vase << 30, 42, 58, 66, 55, 38, 34, 41,  //
      0, 20, 45, 70, 95, 120, 135, 150;
  auto truth =
      std::make_unique<KinematicSurface>(KinematicSurface::Revolution(UnitSpacedClamped(4, 8), vase));
  const double span = arc_fraction * 2 * M_PI, thickness = 6.0;
  const double u0 = 1.0, u1 = 3.4;  // profile parameter (heights about 30 to 110 mm)
  // The side breaks slant: theta from side_lo(u) to side_hi(u).
  auto side_lo = [&](double u) { return 0.08 * span * (u - u0) / (u1 - u0); };
  auto side_hi = [&](double u) { return span - 0.06 * span * (u1 - u) / (u1 - u0); };
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::vector<Eigen::Vector3d> pts, nrm;
  LocalGeometry g;
  auto outward = [&](const LocalGeometry& geo) {
    Eigen::Vector3d n = To3(geo.d1.col(0)).cross(To3(geo.d1.col(1))).normalized();
    if (n.x() * geo.point.x() + n.y() * geo.point.y() < 0) n = -n;
    return n;
  };
  while (static_cast<int>(pts.size()) < count) {
    const double u = u0 + (u1 - u0) * uniform(rng), v = span * uniform(rng);
    if (v < side_lo(u) || v > side_hi(u)) continue;
    truth->Evaluate({u, v, 0.0}, 1, g);
    pts.push_back(To3(g.point));
    nrm.push_back(outward(g));
  }
  const auto on_surface = static_cast<Eigen::Index>(pts.size());
  if (fracture_faces) {
    // Points on the breaks: along the outline (arc length measured on the surface), then inwards along the
    // surface normal by up to the wall's thickness; the face's normal is across the outline and the
    // surface normal. As dense per area as the surface: estimate the surface's area by its samples' cells.
    struct Edge {
      std::function<ParamT(double)> at;  // t in [0, 1] along the edge
    };
    const std::vector<Edge> edges = {{[&](double t) {
                                       return ParamT{u0, side_lo(u0) + t * (side_hi(u0) - side_lo(u0)), 0.0};
                                     }},
                                     {[&](double t) {
                                       return ParamT{u1, side_lo(u1) + t * (side_hi(u1) - side_lo(u1)), 0.0};
                                     }},
                                     {[&](double t) {
                                       return ParamT{u0 + t * (u1 - u0), side_lo(u0 + t * (u1 - u0)), 0.0};
                                     }},
                                     {[&](double t) {
                                       return ParamT{u0 + t * (u1 - u0), side_hi(u0 + t * (u1 - u0)), 0.0};
                                     }}};
    // Lengths of the edges and the area of the surface (a grid sum of |S_u x S_v|).
    std::vector<double> lengths;
    for (const Edge& e : edges) {
      double len = 0.0;
      Eigen::Vector3d prev;
      for (int i = 0; i <= 200; ++i) {
        truth->Evaluate(e.at(i / 200.0), 0, g);
        if (i > 0) len += (To3(g.point) - prev).norm();
        prev = To3(g.point);
      }
      lengths.push_back(len);
    }
    double area = 0.0;
    for (int i = 0; i < 100; ++i) {
      const double u = u0 + (u1 - u0) * (i + 0.5) / 100;
      truth->Evaluate({u, 0.5 * span, 0.0}, 1, g);
      const double width = side_hi(u) - side_lo(u);
      area += To3(g.d1.col(0)).cross(To3(g.d1.col(1))).norm() * width * (u1 - u0) / 100;
    }
    const double total_length = std::accumulate(lengths.begin(), lengths.end(), 0.0);
    const auto fracture_count = static_cast<int>(count * total_length * thickness / area);
    std::discrete_distribution<int> pick(lengths.begin(), lengths.end());
    for (int i = 0; i < fracture_count; ++i) {
      const Edge& e = edges[static_cast<std::size_t>(pick(rng))];
      const double t = uniform(rng), h = 1e-4;
      truth->Evaluate(e.at(t), 1, g);
      const Eigen::Vector3d n = outward(g), p = To3(g.point);
      truth->Evaluate(e.at(std::min(t + h, 1.0)), 0, g);
      const Eigen::Vector3d ahead = To3(g.point);
      truth->Evaluate(e.at(std::max(t - h, 0.0)), 0, g);
      const Eigen::Vector3d tangent = (ahead - To3(g.point)).normalized();
      pts.push_back(p - thickness * uniform(rng) * n);
      nrm.push_back(tangent.cross(n).normalized());
    }
  }
  SurfaceSample s{Eigen::Matrix3Xd(3, static_cast<Eigen::Index>(pts.size())),
                  Eigen::Matrix3Xd(3, static_cast<Eigen::Index>(pts.size()))};
  for (std::size_t i = 0; i < pts.size(); ++i) {
    s.points.col(static_cast<Eigen::Index>(i)) = pts[i];
    s.normals.col(static_cast<Eigen::Index>(i)) = nrm[i];
  }
  KinematicCloud c;
  std::mt19937_64 noise_rng(seed + 1);
  PlaceCloud(c, s, noise, noise_rng);
  c.surface_points = on_surface;
  c.truth = std::move(truth);
  return c;
}

WallTruth MakeTwoSurfaceVessel(double noise, int count, std::uint64_t seed, bool with_base) {
  if (count < 1 || !(noise >= 0)) throw std::invalid_argument("a positive count, a noise >= 0");
  Eigen::Matrix2Xd vase(2, 8);
  vase << 30, 42, 58, 66, 55, 38, 34, 41,  //
      0, 20, 45, 70, 95, 120, 135, 150;
  // A pot with its base: the generatrix starts on the axis, runs level out to the foot, turns up (its
  // tightest turn has a radius of 7.8 mm, so the inside's offset by 6 mm stays a smooth curve, turning at
  // 1.8 mm) and rises straight to the rim. A fifth of its area faces within 45 degrees of the axis.
  Eigen::Matrix2Xd pot(2, 8);
  pot << 0, 11, 22, 30, 39, 42, 42, 42,  //
      0, 0, 0, 0, 3, 13, 46, 80;
  auto truth = std::make_unique<KinematicSurface>(
      KinematicSurface::Revolution(UnitSpacedClamped(4, 8), with_base ? pot : vase));
  const double thickness = 6.0, u0 = with_base ? 0.0 : 0.3, u1 = 5.0;
  // The generatrix's unit normal in the meridian plane, pointing away from the axis' side of the wall
  // (outwards): (z', -r') / |(r', z')| for a profile rising with u.
  auto offset_point = [&](double u) {
    LocalGeometry g;
    truth->Evaluate({u, 0.0, 0.0}, 1, g);
    const Eigen::Vector2d tangent(g.d1(0, 0), g.d1(2, 0));
    const Eigen::Vector2d normal = Eigen::Vector2d(tangent.y(), -tangent.x()).normalized();
    return Eigen::Vector2d(Eigen::Vector2d(g.point[0], g.point[2]) - thickness * normal);
  };
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  // Area-uniform samples: u drawn in proportion to r(u) |C'(u)| by rejection against its maximum.
  auto sample = [&](bool inner, std::vector<Eigen::Vector3d>& pts, std::vector<Eigen::Vector3d>& nrm) {
    const double h = 1e-6;
    auto weight = [&](double u) {
      if (!inner) {
        LocalGeometry g;
        truth->Evaluate({u, 0.0, 0.0}, 1, g);
        return g.point[0] * std::hypot(g.d1(0, 0), g.d1(2, 0));
      }
      return offset_point(u).x() * (offset_point(u + h) - offset_point(u - h)).norm() / (2 * h);
    };
    double top = 0.0;
    for (int i = 0; i <= 400; ++i) top = std::max(top, weight(u0 + (u1 - u0) * i / 400.0));
    top *= 1.1;
    while (static_cast<int>(pts.size()) < count) {
      const double u = u0 + (u1 - u0) * uniform(rng), v = 2 * M_PI * uniform(rng);
      if (uniform(rng) * top > weight(u)) continue;
      Eigen::Vector2d rz, dir;
      if (inner) {
        rz = offset_point(u);
        const Eigen::Vector2d t = offset_point(u + h) - offset_point(u - h);
        dir = Eigen::Vector2d(-t.y(), t.x()).normalized();  // towards the axis
      } else {
        LocalGeometry g;
        truth->Evaluate({u, 0.0, 0.0}, 1, g);
        rz << g.point[0], g.point[2];
        dir = Eigen::Vector2d(g.d1(2, 0), -g.d1(0, 0)).normalized();  // outwards
      }
      pts.emplace_back(rz.x() * std::cos(v), rz.x() * std::sin(v), rz.y());
      nrm.emplace_back(dir.x() * std::cos(v), dir.x() * std::sin(v), dir.y());
    }
  };
  std::vector<Eigen::Vector3d> pts, nrm;
  sample(false, pts, nrm);
  const auto outer_count = static_cast<Eigen::Index>(pts.size());
  pts.reserve(2 * pts.size());
  std::vector<Eigen::Vector3d> inner_pts, inner_nrm;
  sample(true, inner_pts, inner_nrm);
  pts.insert(pts.end(), inner_pts.begin(), inner_pts.end());
  nrm.insert(nrm.end(), inner_nrm.begin(), inner_nrm.end());
  SurfaceSample s{Eigen::Matrix3Xd(3, static_cast<Eigen::Index>(pts.size())),
                  Eigen::Matrix3Xd(3, static_cast<Eigen::Index>(pts.size()))};
  for (std::size_t i = 0; i < pts.size(); ++i) {
    s.points.col(static_cast<Eigen::Index>(i)) = pts[i];
    s.normals.col(static_cast<Eigen::Index>(i)) = nrm[i];
  }
  WallTruth out;
  std::mt19937_64 noise_rng(seed + 1);
  PlaceCloud(out.cloud, s, noise, noise_rng);
  out.cloud.surface_points = outer_count;
  out.inner_points = static_cast<Eigen::Index>(inner_pts.size());
  out.thickness = thickness;
  // The capacity: pi integral r^2 dz along the offset generatrix (composite Simpson over u, 20000 steps;
  // the offset never descends with u, so the integral is the volume between its end heights).
  const int steps = 20000;
  double integral = 0.0;
  const double du = (u1 - u0) / steps, h = 1e-6;
  for (int i = 0; i <= steps; ++i) {
    const double u = u0 + du * i;
    const Eigen::Vector2d q = offset_point(u);
    const double dz = (offset_point(u + h).y() - offset_point(u - h).y()) / (2 * h);
    const double w = (i == 0 || i == steps) ? 1.0 : (i % 2 == 1 ? 4.0 : 2.0);
    integral += w * q.x() * q.x() * dz;
  }
  out.capacity = M_PI * integral * du / 3.0;
  out.inner_lo = offset_point(u0).y();
  out.inner_hi = offset_point(u1).y();
  out.cloud.truth = std::move(truth);
  return out;
}

SherdTruth MakeSherd(const SherdSpec& spec) {
  if (!(spec.arc_fraction > 0 && spec.arc_fraction <= 1))
    throw std::invalid_argument("an arc fraction in (0, 1]");
  if (spec.count < 1 || !(spec.noise >= 0)) throw std::invalid_argument("a positive count, a noise >= 0");
  Eigen::Matrix2Xd vase(2, 8);
  vase << 30, 42, 58, 66, 55, 38, 34, 41,  //
      0, 20, 45, 70, 95, 120, 135, 150;
  auto truth =
      std::make_unique<KinematicSurface>(KinematicSurface::Revolution(UnitSpacedClamped(4, 8), vase));
  const double span = spec.arc_fraction * 2 * M_PI, thickness = 6.0;
  // Profile parameters: the rim is u = 5 (150 mm); a body sherd spans heights of about 30 to 110 mm.
  const double u0 = spec.rim ? 3.6 : 1.0, u1 = spec.rim ? 5.0 : 3.4;
  auto side_lo = [=](double u) { return 0.08 * span * (u - u0) / (u1 - u0); };
  auto side_hi = [=](double u) { return span - 0.06 * span * (u1 - u) / (u1 - u0); };
  std::mt19937_64 rng(spec.seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  // A break's wander along the arc: three sines of random phase, scaled into [0, 1]; 0.3 in u is about
  // 6 mm of height on this vase.
  const double wander = spec.irregular_breaks ? 0.3 : 0.0;
  auto make_wander = [&]() {
    const std::array<double, 3> phase = {2 * M_PI * uniform(rng), 2 * M_PI * uniform(rng),
                                         2 * M_PI * uniform(rng)};
    return [phase](double s) {
      return 0.5 + (std::sin(2 * M_PI * 1.3 * s + phase[0]) + std::sin(2 * M_PI * 2.7 * s + phase[1]) +
                    std::sin(2 * M_PI * 4.1 * s + phase[2])) /
                       6.0;
    };
  };
  const auto bottom_wander = make_wander(), top_wander = make_wander();
  const bool rim = spec.rim;
  auto bottom = [=](double v) { return u0 + wander * bottom_wander(v / span); };
  auto top = [=](double v) { return rim ? u1 : u1 - wander * top_wander(v / span); };
  auto inside = [&](double u, double v) {
    return v >= side_lo(u) && v <= side_hi(u) && u >= bottom(v) && u <= top(v);
  };
  LocalGeometry g;
  auto outward = [&](const LocalGeometry& geo) {
    Eigen::Vector3d n = To3(geo.d1.col(0)).cross(To3(geo.d1.col(1))).normalized();
    if (n.x() * geo.point.x() + n.y() * geo.point.y() < 0) n = -n;
    return n;
  };
  std::vector<Eigen::Vector3d> pts, nrm;
  std::vector<std::pair<double, double>> params;
  while (static_cast<int>(pts.size()) < spec.count) {
    const double u = u0 + (u1 - u0) * uniform(rng), v = span * uniform(rng);
    if (!inside(u, v)) continue;
    truth->Evaluate({u, v, 0.0}, 1, g);
    pts.push_back(To3(g.point));
    nrm.push_back(outward(g));
    params.emplace_back(u, v);
  }
  const auto outer_count = static_cast<Eigen::Index>(pts.size());
  if (spec.inner_surface) {
    // The inside: the same parameter region offset by the wall along the normal, facing the axis. The same
    // count over a slightly smaller area: about as dense.
    for (Eigen::Index i = 0; i < outer_count; ++i) {
      const auto [u, v] = params[static_cast<std::size_t>(i)];
      truth->Evaluate({u, v, 0.0}, 1, g);
      const Eigen::Vector3d n = outward(g);
      pts.push_back(To3(g.point) - thickness * n);
      nrm.push_back(-n);
    }
  }
  const auto surface_count = static_cast<Eigen::Index>(pts.size());
  if (spec.fracture_faces) {
    // The faces across the wall along the outline: the two side breaks, the bottom edge and the top edge
    // (a break, or the rim's lip when asked), each sampled along its length (points outside the sherd's
    // outline are skipped) and then across the wall, as dense per area as the outer surface.
    using Edge = std::function<std::pair<double, double>(double)>;  // t in [0, 1] -> (u, v)
    std::vector<Edge> edges = {[&](double t) {
                                 return std::pair{u0 + t * (u1 - u0), side_lo(u0 + t * (u1 - u0))};
                               },
                               [&](double t) {
                                 return std::pair{u0 + t * (u1 - u0), side_hi(u0 + t * (u1 - u0))};
                               },
                               [&](double t) {
                                 return std::pair{bottom(t * span), t * span};
                               }};
    if (!spec.rim || spec.lip) edges.push_back([&](double t) { return std::pair{top(t * span), t * span}; });
    const double tolerance = 1e-9;
    auto on_outline = [&](const std::pair<double, double>& uv) {
      const auto [u, v] = uv;
      return v >= side_lo(u) - tolerance && v <= side_hi(u) + tolerance && u >= bottom(v) - tolerance &&
             u <= top(v) + tolerance;
    };
    std::vector<double> lengths;
    for (const Edge& e : edges) {
      double length = 0.0;
      Eigen::Vector3d previous = Eigen::Vector3d::Zero();
      bool previous_on = false;
      for (int i = 0; i <= 400; ++i) {
        const auto uv = e(i / 400.0);
        const bool on = on_outline(uv);
        truth->Evaluate({uv.first, uv.second, 0.0}, 0, g);
        if (on && previous_on) length += (To3(g.point) - previous).norm();
        previous = To3(g.point);
        previous_on = on;
      }
      lengths.push_back(length);
    }
    // The outer surface's area: its parameter region's share of the sampling rectangle times a grid sum of
    // |S_u x S_v| over the rectangle.
    double area = 0.0;
    const int grid = 200;
    for (int i = 0; i < grid; ++i)
      for (int k = 0; k < grid; ++k) {
        const double u = u0 + (u1 - u0) * (i + 0.5) / grid, v = span * (k + 0.5) / grid;
        if (!inside(u, v)) continue;
        truth->Evaluate({u, v, 0.0}, 1, g);
        area += To3(g.d1.col(0)).cross(To3(g.d1.col(1))).norm() * (u1 - u0) * span / (grid * grid);
      }
    const double total_length = std::accumulate(lengths.begin(), lengths.end(), 0.0);
    const auto face_count = static_cast<int>(spec.count * total_length * thickness / area);
    std::discrete_distribution<int> pick(lengths.begin(), lengths.end());
    for (int placed = 0; placed < face_count;) {
      const Edge& e = edges[static_cast<std::size_t>(pick(rng))];
      const double t = uniform(rng), h = 1e-4;
      const auto uv = e(t);
      if (!on_outline(uv)) continue;
      truth->Evaluate({uv.first, uv.second, 0.0}, 1, g);
      const Eigen::Vector3d n = outward(g), p = To3(g.point);
      const auto ahead = e(std::min(t + h, 1.0)), behind = e(std::max(t - h, 0.0));
      truth->Evaluate({ahead.first, ahead.second, 0.0}, 0, g);
      const Eigen::Vector3d a = To3(g.point);
      truth->Evaluate({behind.first, behind.second, 0.0}, 0, g);
      const Eigen::Vector3d tangent = (a - To3(g.point)).normalized();
      pts.push_back(p - thickness * uniform(rng) * n);
      nrm.push_back(tangent.cross(n).normalized());
      ++placed;
    }
  }
  SurfaceSample s{Eigen::Matrix3Xd(3, static_cast<Eigen::Index>(pts.size())),
                  Eigen::Matrix3Xd(3, static_cast<Eigen::Index>(pts.size()))};
  const Eigen::Matrix3d flip = spec.upside_down
                                   ? Eigen::Matrix3d(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()))
                                   : Eigen::Matrix3d::Identity();
  for (std::size_t i = 0; i < pts.size(); ++i) {
    s.points.col(static_cast<Eigen::Index>(i)) = flip * pts[i];
    s.normals.col(static_cast<Eigen::Index>(i)) = flip * nrm[i];
  }
  SherdTruth out;
  std::mt19937_64 noise_rng(spec.seed + 1);
  PlaceCloud(out.cloud, s, spec.noise, noise_rng);
  // The cloud was placed as if its frame were the axis frame; the flip makes the axis frame's z point down.
  out.cloud.world_T_model = out.cloud.world_T_model * RigidMotion(flip, Eigen::Vector3d::Zero());
  out.cloud.axis_direction = out.cloud.world_T_model.rotation().col(2);
  out.cloud.surface_points = outer_count;
  out.cloud.surface_parameters.resize(2, outer_count);
  for (Eigen::Index i = 0; i < outer_count; ++i)
    out.cloud.surface_parameters.col(i) << params[static_cast<std::size_t>(i)].first,
        params[static_cast<std::size_t>(i)].second;
  out.inner_points = surface_count - outer_count;
  out.wall_thickness = thickness;
  out.profile_lo = u0;
  out.profile_hi = u1;
  out.rim_diameter = 2 * truth->ProfilePoint(u1).x();
  out.cloud.truth = std::move(truth);
  out.arc = [=](double u) -> std::optional<std::pair<double, double>> {
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    const int steps = 4000;
    for (int k = 0; k <= steps; ++k) {
      const double v = span * k / steps;
      if (v >= side_lo(u) && v <= side_hi(u) && u >= bottom(v) && u <= top(v)) {
        lo = std::min(lo, v);
        hi = std::max(hi, v);
      }
    }
    if (lo > hi) return std::nullopt;
    return std::pair{lo, hi};
  };
  return out;
}

BSplineSurface BumpyPatch(double x_tilt) {
  const int n = 10;
  Eigen::Matrix3Xd control(3, n * n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const double x = -50 + 100.0 * i / (n - 1), y = -50 + 100.0 * j / (n - 1);
      control.col(i * n + j) << x, y,
          10 * std::sin(0.07 * x + 0.4) * std::cos(0.05 * y - 0.3) + 0.002 * x * y + x_tilt * x;
    }
  return BSplineSurface(UnitSpacedClamped(4, n), UnitSpacedClamped(4, n), control);
}

}  // namespace s2m
