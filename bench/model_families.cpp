#include "bench/model_families.h"

#include <Eigen/Geometry>
#include <cmath>
#include <map>
#include <stdexcept>

#include "fitting/bspline_models.h"
#include "fitting/initial_models.h"
#include "fitting/kinematic_surfaces.h"
#include "fitting/primitive_models.h"

namespace s2m::bench {
namespace {

constexpr double kDegree = M_PI / 180.0;

// The errors of the recorded poses of the families built here (the reference cases keep their own).
ViewOptions FamilyViewOptions() {
  ViewOptions vo;
  vo.noise = 0.02;
  vo.rotation_error = 0.5 * kDegree;
  vo.translation_error = 0.5;
  vo.seed = 5;
  return vo;
}

// The vase profile refined to 12 control points: a surface of revolution 150 mm tall.
KinematicSurface TwelvePointVase() {
  const KinematicSurface eight = KinematicSurface::Revolution(
      UnitSpacedClamped(4, 8),
      (Eigen::Matrix2Xd(2, 8) << 30, 42, 58, 66, 55, 38, 34, 41, 0, 20, 45, 70, 95, 120, 135, 150)
          .finished());
  Eigen::Matrix2Xd profile(2, 12);
  const double lo = eight.basis().lo(), hi = eight.basis().hi();
  for (int i = 0; i < 12; ++i) profile.col(i) = eight.ProfilePoint(lo + (hi - lo) * i / 11.0);
  return KinematicSurface::Revolution(UnitSpacedClamped(4, 12), profile);
}

// Points of `model` uniform in the box [u0, u1] x [v0, v1] of its parameters, normals turned by `orient`.
// SampleAroundAxis with the orientation given: the torus' inner side and the patch face other ways than
// away from the z axis, and which points a view sees depends on it.
template <typename Orient>
SurfaceSample SampleBox(const ParametricModel& model, double u0, double u1, double v0, double v1, int count,
                        std::uint64_t seed, Orient orient) {
  SurfaceSample s = SampleAroundAxis(model, u0, u1, v0, v1, count, seed);
  for (Eigen::Index j = 0; j < s.points.cols(); ++j) {
    const Eigen::Vector3d n = s.normals.col(j);
    if (n.dot(orient(Eigen::Vector3d(s.points.col(j)))) < 0) s.normals.col(j) = -n;
  }
  return s;
}

long long SeenPoints(const SyntheticViews& v) {
  long long seen = 0;
  for (const auto& scan : v.scans) seen += scan.cols();
  return seen;
}

// Views of a sampled family with about `points` points: a pilot sample of 4000 tells how many points the
// views see per sample (with repeats across views).
template <typename Sample>
SyntheticViews ViewsWithPoints(long long points, const std::vector<Eigen::Vector3d>& directions,
                               Sample sample) {
  const double per_sample =
      static_cast<double>(SeenPoints(ScanFromDirections(sample(4000, 3), directions, FamilyViewOptions()))) /
      4000.0;
  const int count = static_cast<int>(std::ceil(static_cast<double>(points) / per_sample));
  return ScanFromDirections(sample(count, 4), directions, FamilyViewOptions());
}

}  // namespace

std::vector<std::string> CostFamilyNames() {
  return {"sphere", "cylinder", "torus", "bspline-surface", "vase", "helical", "spiral", "part", "freeform"};
}

std::string FamilyDescription(const std::string& family) {
  static const std::map<std::string, std::string> kDescriptions = {
      {"revolution-12", "surface of revolution, 12 control points (the vase profile)"},
      {"sphere", "sphere, radius 25"},
      {"cylinder", "cylinder, radius 20, 80 long"},
      {"torus", "torus, radii 40 and 10"},
      {"bspline-surface", "bicubic B-spline patch 100 x 100, 10 x 10 control points"},
      {"vase", "surface of revolution, 8 control points (the vase case)"},
      {"helical", "helical surface, 6 control points (the screw case)"},
      {"spiral", "spiral surface, 6 control points (the shell case)"},
      {"part", "constrained part: 9 faces, 5 dimensions (the counterbored block)"},
      {"freeform", "constrained part: 6 faces, one a 4 x 4 B-spline patch (the free-form plate)"}};
  const auto it = kDescriptions.find(family);
  if (it == kDescriptions.end()) throw std::invalid_argument("unknown model family '" + family + "'");
  return it->second;
}

FamilyCase MakeFamilyCase(const std::string& family, long long points, int views) {
  if (points <= 0 || views <= 0) throw std::invalid_argument("a family case needs points and views");
  FamilyCase c;
  c.family = family;
  c.description = FamilyDescription(family);
  c.options.shared_motion_iterations = 0;  // per-view motions from the start
  const std::vector<Eigen::Vector3d> ring = RingOfDirections(views, 20 * kDegree);
  if (family == "revolution-12") {
    const KinematicSurface truth = TwelvePointVase();
    c.views = ViewsWithPoints(points, ring, [&](int count, std::uint64_t seed) {
      return SampleAroundAxis(truth, truth.basis().lo(), truth.basis().hi(), -M_PI, M_PI, count, seed);
    });
    c.start = std::make_unique<KinematicSurface>(
        KinematicSurface::Revolution(truth.basis(), truth.profile() * 1.01));
  } else if (family == "sphere") {
    const SphereModel truth(Sphere{Eigen::Vector3d::Zero(), 25.0});
    const auto outward = [](const Eigen::Vector3d& p) { return p; };
    c.views = ViewsWithPoints(points, ring, [&](int count, std::uint64_t seed) {
      return SampleBox(truth, 0.0, 2 * M_PI, -1.3, 1.3, count, seed, outward);
    });
    c.start = std::make_unique<SphereModel>(Sphere{Eigen::Vector3d::Zero(), 25.25});
  } else if (family == "cylinder") {
    const CylinderModel truth(Cylinder{Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), 20.0});
    const auto outward = [](const Eigen::Vector3d& p) { return Eigen::Vector3d(p.x(), p.y(), 0.0); };
    c.views = ViewsWithPoints(points, ring, [&](int count, std::uint64_t seed) {
      return SampleBox(truth, 0.0, 2 * M_PI, -40.0, 40.0, count, seed, outward);
    });
    c.start =
        std::make_unique<CylinderModel>(Cylinder{Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), 20.2});
  } else if (family == "torus") {
    const TorusModel truth(Torus{Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), 40.0, 10.0});
    // Away from the tube's centre circle.
    const auto outward = [](const Eigen::Vector3d& p) {
      const Eigen::Vector3d radial = Eigen::Vector3d(p.x(), p.y(), 0.0).normalized();
      return Eigen::Vector3d(p - 40.0 * radial);
    };
    c.views = ViewsWithPoints(points, ring, [&](int count, std::uint64_t seed) {
      return SampleBox(truth, 0.0, 2 * M_PI, 0.0, 2 * M_PI, count, seed, outward);
    });
    c.start =
        std::make_unique<TorusModel>(Torus{Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), 40.0, 10.1});
  } else if (family == "bspline-surface") {
    const BSplineSurface truth = BumpyPatch();
    const auto up = [](const Eigen::Vector3d&) { return Eigen::Vector3d(Eigen::Vector3d::UnitZ()); };
    const ParameterDomain d = truth.domain();
    c.views =
        ViewsWithPoints(points, RingOfDirections(views, 60 * kDegree), [&](int count, std::uint64_t seed) {
          return SampleBox(truth, d.lo[0], d.hi[0], d.lo[1], d.hi[1], count, seed, up);
        });
    auto start = std::make_unique<BSplineSurface>(truth);
    start->set_parameters(truth.parameters() * 1.01);
    c.start = std::move(start);
  } else {
    // The reference cases (throws for an unknown name): scaled to the requested size by a pilot at scale 1.
    const double seen = static_cast<double>(SeenPoints(MakeSyntheticCase(family).views));
    SyntheticCase reference = MakeSyntheticCase(family, static_cast<double>(points) / seen);
    c.views = std::move(reference.views);
    c.start = std::move(reference.start);
    c.options = reference.options;
    c.options.shared_motion_iterations = 0;
  }
  return c;
}

}  // namespace s2m::bench
