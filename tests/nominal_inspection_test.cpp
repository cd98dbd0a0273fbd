// Inspection against a nominal mesh (docs/metrology.md section 5): the triangle-mesh model's feet and signed
// distances against brute force, and a synthetic part with a 0.2 mm bump on one face scanned from 8
// directions with known pose errors: the registration recovers the poses, the deviation map finds the bump
// with its amplitude and the other faces stay within the noise.

#include "fitting/nominal_inspection.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "fitting/triangle_mesh.h"
#include "synthetic/synthetic_cases.h"
#include "test_meshes.h"

namespace s2m {
namespace {

constexpr double kPi = 3.14159265358979323846;

// The box [-a, a] x [-b, b] x [0, c], one group per face (test_meshes.h), in millimetres.
TriangleMesh Box(double a, double b, double c) {
  TriangleMesh m = test::BoxMesh(a, b, c);
  m.units = "mm";
  return m;
}

TEST(TriangleMeshModel, FeetAndSignsMatchBruteForce) {
  const TriangleMeshModel model(Box(30, 20, 20));
  std::mt19937_64 random(3);
  std::uniform_real_distribution<double> u(-40, 40);
  for (int trial = 0; trial < 2000; ++trial) {
    const Eigen::Vector3d x(u(random), u(random), u(random) * 0.5 + 10);
    double best = 1e300;
    for (Eigen::Index f = 0; f < model.mesh().triangle_count(); ++f) {
      double a, b;
      TriangleRegion region;
      const Eigen::Vector3d p =
          ClosestPointOnTriangle(x, model.mesh().vertices.col(model.mesh().triangles(0, f)),
                                 model.mesh().vertices.col(model.mesh().triangles(1, f)),
                                 model.mesh().vertices.col(model.mesh().triangles(2, f)), a, b, region);
      best = std::min(best, (p - x).norm());
    }
    const MeshFoot foot = model.Foot(x);
    EXPECT_NEAR(foot.distance, best, 1e-12);
    // The box's own signed distance: inside negative.
    const bool inside = std::abs(x.x()) < 30 && std::abs(x.y()) < 20 && x.z() > 0 && x.z() < 20;
    EXPECT_EQ(foot.signed_distance < 0, inside) << x.transpose();
    // The model evaluates its own foot.
    LocalGeometry g;
    model.Evaluate({foot.u, foot.v, static_cast<double>(foot.triangle)}, 2, g);
    EXPECT_LT((To3(g.point) - foot.point).norm(), 1e-12);
  }
}

TEST(TriangleMeshModel, RejectsInvalidMeshes) {
  TriangleMesh m = Box(1, 1, 1);
  m.triangles(0, 3) = 99;
  EXPECT_THROW(TriangleMeshModel{m}, std::invalid_argument);
  TriangleMesh empty;
  EXPECT_THROW(TriangleMeshModel{empty}, std::invalid_argument);
}

// The part as made: the box with a smooth bump of `height` (cos^2 profile, radius R) on the +x face centred
// at (y, z) = (0, 10), sampled uniformly by area with outward normals.
SurfaceSample BumpedBox(double height, double radius, int count, std::uint64_t seed) {
  const double a = 30, b = 20, c = 20;
  std::mt19937_64 random(seed);
  std::uniform_real_distribution<double> unit(0, 1);
  const double areas[6] = {2 * b * c, 2 * b * c, 2 * a * c, 2 * a * c, 4 * a * b, 4 * a * b};
  double total = 0;
  for (double x : areas) total += x;
  SurfaceSample s;
  s.points.resize(3, count);
  s.normals.resize(3, count);
  for (int i = 0; i < count; ++i) {
    double pick = unit(random) * total;
    int f = 0;
    while (f < 5 && pick > areas[f]) pick -= areas[f++];
    const double p = unit(random), q = unit(random);
    Eigen::Vector3d x, n;
    switch (f) {
      case 0: {
        const double y = -b + 2 * b * p, z = c * q, rho = std::hypot(y, z - 10);
        const double bump =
            rho < radius ? height * std::pow(std::cos(kPi * rho / (2 * radius)), 2) : 0.0;  // = Bump
        x << a + bump, y, z;
        n = Eigen::Vector3d::UnitX();
        break;
      }
      case 1:
        x << -a, -b + 2 * b * p, c * q;
        n = -Eigen::Vector3d::UnitX();
        break;
      case 2:
        x << -a + 2 * a * p, b, c * q;
        n = Eigen::Vector3d::UnitY();
        break;
      case 3:
        x << -a + 2 * a * p, -b, c * q;
        n = -Eigen::Vector3d::UnitY();
        break;
      case 4:
        x << -a + 2 * a * p, -b + 2 * b * q, c;
        n = Eigen::Vector3d::UnitZ();
        break;
      default:
        x << -a + 2 * a * p, -b + 2 * b * q, 0;
        n = -Eigen::Vector3d::UnitZ();
    }
    s.points.col(i) = x;
    s.normals.col(i) = n;
  }
  return s;
}

struct BumpCase {
  SyntheticViews views;
  double noise = 0.01;
};

// Views from 8 directions (4 above, 4 below, each seeing three faces). `independent`: each view's recorded
// pose is off by its own 2 degrees and 2 mm (a turntable's errors); otherwise the views are mutually exact
// and all off by one placement error of 2 degrees and 2 mm (a merged scan placed anywhere).
BumpCase ScanBumpedBox(bool independent) {
  BumpCase c;
  const SurfaceSample part = BumpedBox(0.2, 8.0, 16000, 11);
  std::vector<Eigen::Vector3d> directions = RingOfDirections(4, 0.5, kPi / 4);
  for (const Eigen::Vector3d& d : RingOfDirections(4, -0.6, kPi / 4)) directions.push_back(d);
  ViewOptions o;
  o.noise = c.noise;
  o.rotation_error = independent ? 2 * kPi / 180 : 0.0;  // 2 degrees
  o.translation_error = independent ? 2.0 : 0.0;         // mm
  o.seed = 5;
  c.views = ScanFromDirections(part, directions, o);
  if (!independent) {
    const RigidMotion placement(RotationAboutAxis(Eigen::Vector3d(1, 2, 3).normalized(), 2 * kPi / 180),
                                Eigen::Vector3d(1.2, -1.0, 1.2));
    for (RigidMotion& pose : c.views.model_T_scan_recorded) pose = placement * pose;
  }
  return c;
}

double Bump(double y, double z) {
  const double rho = std::hypot(y, z - 10);
  return rho < 8.0 ? 0.2 * std::pow(std::cos(kPi * rho / 16.0), 2) : 0.0;
}

void ExpectBumpFound(const NominalInspection& r, double noise, double flat_mean_bound) {
  // The bump: points within 2 mm of its centre on the +x face lie outside the nominal by the bump's height
  // there (its mean over those points: at least 0.2 cos^2(pi / 8) = 0.17).
  double sum = 0, expected = 0;
  int n = 0;
  for (Eigen::Index i = 0; i < r.points.cols(); ++i) {
    const Eigen::Vector3d x = r.points.col(i);
    if (r.group[static_cast<std::size_t>(i)] == 0 && std::hypot(x.y(), x.z() - 10) < 2.0) {
      sum += r.deviations[i];
      expected += Bump(x.y(), x.z());
      ++n;
    }
  }
  ASSERT_GT(n, 20);
  std::printf("bump: %d points, mean deviation %.4f (expected %.4f); +x max %.4f\n", n, sum / n, expected / n,
              r.regions[0].max);
  for (const RegionDeviation& g : r.regions)
    std::printf("  %-7s %6ld points, mean %+.5f, sd %.5f\n", g.name.c_str(), static_cast<long>(g.count),
                g.mean, g.standard_deviation);
  EXPECT_NEAR(sum / n, expected / n, 4 * noise / std::sqrt(n) + flat_mean_bound) << n << " points";
  // The +x region's largest deviation is the bump's top plus at most a few noise sigmas.
  EXPECT_NEAR(r.regions[0].max, 0.2, 5 * noise);
  // Every other face: mean within the bound, spread of the noise.
  for (int g = 1; g < 6; ++g) {
    const RegionDeviation& region = r.regions[static_cast<std::size_t>(g)];
    ASSERT_GT(region.count, 1000) << region.name;  // every face seen by several views
    EXPECT_LT(std::abs(region.mean), flat_mean_bound) << region.name;
    EXPECT_NEAR(region.standard_deviation, noise, 0.15 * noise) << region.name;
    EXPECT_LT(std::max(-region.min, region.max), 6 * noise) << region.name;
  }
}

TEST(NominalInspection, FindsABumpOfTwoTenthsAlignedOnDatums) {
  const BumpCase c = ScanBumpedBox(false);
  const TriangleMeshModel nominal(Box(30, 20, 20));
  const std::vector<RigidMotion>& recorded = c.views.model_T_scan_recorded;
  EXPECT_GT((recorded[0].translation() - c.views.model_T_scan_true[0].translation()).norm(), 1.0);
  // Aligned on the faces without the bump (datums): the poses to the noise, the bump's full height. A view
  // that sees two datum planes only keeps the common pose (exact here: the views are mutually exact).
  NominalInspectionOptions datum;
  datum.datum_groups = {1, 2, 3, 4, 5};
  const NominalInspection r = InspectAgainstNominal(nominal, c.views.scans, recorded, datum);
  EXPECT_GT(r.views_on_common_pose, 0);
  for (std::size_t k = 0; k < recorded.size(); ++k) {
    const RigidMotion error = r.nominal_T_scan[k] * c.views.model_T_scan_true[k].inverse();
    EXPECT_LT(error.angle(), 1e-4) << "view " << k;
    EXPECT_LT(error.translation().norm(), 3e-3) << "view " << k;
  }
  // Each face's mean: within 4 standard errors of 0 (its points' noise, n >= 1000) plus the poses' error.
  ExpectBumpFound(r, c.noise, 4 * c.noise / std::sqrt(1000.0) + 1e-3);
  // The poses' share of each deviation's uncertainty is far below the noise.
  const Eigen::VectorXd u = PoseDeviationUncertainty(r);
  EXPECT_LT(u.maxCoeff(), 0.2 * c.noise);
  EXPECT_GT(u.minCoeff(), 0.0);
}

TEST(NominalInspection, FindsABumpOfTwoTenthsWithEveryViewOffOnItsOwn) {
  const BumpCase c = ScanBumpedBox(true);
  const TriangleMeshModel nominal(Box(30, 20, 20));
  const std::vector<RigidMotion>& recorded = c.views.model_T_scan_recorded;
  // Aligned on every face, least squares: each view that sees the bumped face is pulled towards the bump by
  // its volume over that face's area (0.2 x 201 x 0.297 / 800 = 0.015 mm), more than the noise. With a
  // robust loss (Tukey, scale from the data) the bump's points are rejected and every face stays within the
  // noise.
  NominalInspectionOptions robust;
  robust.registration.optimizer.loss = RobustLoss{LossKind::kTukey, 0.0};
  const NominalInspection r = InspectAgainstNominal(nominal, c.views.scans, recorded, robust);
  for (std::size_t k = 0; k < recorded.size(); ++k) {
    const RigidMotion error = r.nominal_T_scan[k] * c.views.model_T_scan_true[k].inverse();
    EXPECT_LT(error.angle(), 1e-3) << "view " << k;
    EXPECT_LT(error.translation().norm(), 0.01) << "view " << k;
  }
  ExpectBumpFound(r, c.noise, c.noise);
}

}  // namespace
}  // namespace s2m
