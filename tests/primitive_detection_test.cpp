// Robust extraction (fitting/primitive_detection.h, docs/method.md "Robust extraction"): the minimal-set
// constructions on exact data, the issue-22 terrestrial scan of a 50 mm sphere on a stand with a floor and a
// wall (radius within 0.3 mm and centre within 0.5 mm over 20 seeds with no cropping, where plain least
// squares is asserted to fail), several spheres and a cylinder on a floor (all found, none spurious), and
// determinism for a seed.

#include "fitting/primitive_detection.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "fitting/primitive_compare.h"
#include "synthetic/clutter_scenes.h"

namespace s2m {
namespace {

TEST(PrimitiveDetection, MinimalSetsGiveTheExactShapes) {
  const Sphere sphere{{1, 2, 3}, 4};
  const Eigen::Vector3d n1 = Eigen::Vector3d(1, 0.2, -0.3).normalized(),
                        n2 = Eigen::Vector3d(-0.4, 1, 0.5).normalized();
  const auto s = SphereFromPointNormals(sphere.center + 4 * n1, n1, sphere.center + 4 * n2, -n2);
  ASSERT_TRUE(s);
  EXPECT_LT((s->center - sphere.center).norm(), 1e-12);
  EXPECT_NEAR(s->radius, 4, 1e-12);

  const Cylinder cylinder{{1, 0, 0}, Eigen::Vector3d(0.3, 0.1, 1).normalized(), 2};
  const Eigen::Matrix3d f = FrameWithAxis(cylinder.axis_direction);
  const Eigen::Vector3d r1 = f.col(0), r2 = (f.col(0) + 2 * f.col(1)).normalized();
  const auto c = CylinderFromPointNormals(cylinder.axis_point + 2 * r1 + 0.5 * f.col(2), r1,
                                          cylinder.axis_point + 2 * r2 - 1.5 * f.col(2), -r2);
  ASSERT_TRUE(c);
  EXPECT_NEAR(std::abs(c->axis_direction.dot(cylinder.axis_direction)), 1, 1e-12);
  EXPECT_NEAR(c->radius, 2, 1e-12);
  EXPECT_LT(std::abs(SignedDistance(*c, cylinder.axis_point + 2 * f.col(1))), 1e-12);

  const Cone cone{{0, 0, 1}, Eigen::Vector3d(0.1, -0.2, 1).normalized(), 0.4, 1.5};
  const Eigen::Matrix3d g = FrameWithAxis(cone.axis_direction);
  Eigen::Vector3d p[3], n[3];
  const double angles[3] = {0.1, 2.0, 4.0}, heights[3] = {0.0, 1.0, -0.5};
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d radial = std::cos(angles[k]) * g.col(0) + std::sin(angles[k]) * g.col(1);
    const double rho = cone.radius + heights[k] * std::tan(cone.half_angle);
    p[k] = cone.axis_point + heights[k] * cone.axis_direction + rho * radial;
    n[k] = std::cos(cone.half_angle) * radial - std::sin(cone.half_angle) * cone.axis_direction;
  }
  const auto k = ConeFromPointNormals(p[0], n[0], p[1], -n[1], p[2], n[2]);
  ASSERT_TRUE(k);
  EXPECT_NEAR(k->axis_direction.dot(cone.axis_direction), 1, 1e-12);
  EXPECT_NEAR(k->half_angle, cone.half_angle, 1e-12);
  EXPECT_LT((k->Apex() - cone.Apex()).norm(), 1e-10);

  EXPECT_FALSE(SphereFromPointNormals({0, 0, 0}, {0, 0, 1}, {1, 0, 0}, {0, 0, 1}));  // parallel normals
  EXPECT_EQ(PrimitiveKindFromString("torus"), PrimitiveKind::kTorus);
  EXPECT_THROW(PrimitiveKindFromString("helix"), std::invalid_argument);
}

// Four points with normals of a torus give it back (one of at most two candidates; docs/method.md eq. 78).
TEST(PrimitiveDetection, FourPointsWithNormalsGiveTheTorus) {
  const Torus torus{{1, -2, 3}, Eigen::Vector3d(0.2, 0.3, 1).normalized(), 6.0, 1.5};
  const Eigen::Matrix3d f = FrameWithAxis(torus.axis);
  std::array<Eigen::Vector3d, 4> tp, tn;
  const double angles[4][2] = {{0.1, 0.4}, {1.3, -0.8}, {2.9, 2.2}, {4.4, 1.0}};
  for (int i = 0; i < 4; ++i) {
    const double t = angles[i][0], u = angles[i][1];
    const Eigen::Vector3d e = std::cos(t) * f.col(0) + std::sin(t) * f.col(1);
    tn[static_cast<std::size_t>(i)] = std::cos(u) * e + std::sin(u) * torus.axis;
    tp[static_cast<std::size_t>(i)] =
        torus.center + torus.major_radius * e + torus.minor_radius * tn[static_cast<std::size_t>(i)];
  }
  const std::vector<Torus> candidates = TorusFromPointNormals(tp, tn);
  bool found = false;
  for (const Torus& c : candidates) {
    if (std::abs(std::abs(c.axis.dot(torus.axis)) - 1) < 1e-10 && (c.center - torus.center).norm() < 1e-9 &&
        std::abs(c.major_radius - torus.major_radius) < 1e-9 &&
        std::abs(c.minor_radius - torus.minor_radius) < 1e-9)
      found = true;
  }
  EXPECT_TRUE(found) << candidates.size() << " candidates";
}

// Issue 22: a 50 mm sphere as a terrestrial scanner sees it (one side, noise 0.1-0.3 mm, range 6-8 m) on a
// post, with a floor and a wall behind, 40-70 % of the points not on the sphere. The thresholds are the
// issue's: radius within 0.3 mm, centre within 0.5 mm, every one of 20 seeds, no cropping. `flying_pixels`:
// the probability that a ray straddling two objects returns a mixed range (clutter_scenes.h).
void DetectTheSphereOnAStandOverTwentySeeds(double flying_pixels) {
  double worst_radius = 0, worst_centre = 0, best_plain_radius = 1e300;
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    const double noise = 0.1 + 0.2 * static_cast<double>(seed - 1) / 19.0;
    const double range = 6000 + 2000 * static_cast<double>((seed * 7) % 20) / 19.0;
    const SphereOnStandScene scene = MakeSphereOnStandScene(range, noise, seed, flying_pixels);
    const Eigen::Index n = scene.cloud.points.cols();
    Eigen::Index on_sphere = 0, flying = 0;
    for (int label : scene.cloud.labels) {
      on_sphere += label == 0;
      flying += label == kFlyingPixel;
    }
    const double clutter = 1.0 - static_cast<double>(on_sphere) / static_cast<double>(n);
    ASSERT_GE(clutter, 0.4) << "seed " << seed;
    ASSERT_LE(clutter, 0.7) << "seed " << seed;
    if (flying_pixels > 0) {
      ASSERT_GT(flying, 0) << "seed " << seed;
    }

    DetectionOptions options;
    options.kinds = {PrimitiveKind::kSphere};
    options.max_instances = 1;
    options.seed = seed;
    const DetectionResult result = DetectPrimitives(scene.cloud.points, options);
    ASSERT_EQ(result.instances.size(), 1u) << "seed " << seed << ": " << result.stop_reason;
    const Sphere& found = std::get<Sphere>(result.instances[0].shape);
    const double radius_error = std::abs(found.radius - scene.truth.radius);
    const double centre_error = (found.center - scene.truth.center).norm();
    worst_radius = std::max(worst_radius, radius_error);
    worst_centre = std::max(worst_centre, centre_error);
    EXPECT_LT(radius_error, 0.3) << "seed " << seed;
    EXPECT_LT(centre_error, 0.5) << "seed " << seed;

    // Plain least squares on the same points, uncropped: the failure.
    const PrimitiveFit<Sphere> plain = FitSphere(scene.cloud.points);
    const double plain_error = std::abs(plain.shape.radius - scene.truth.radius);
    best_plain_radius = std::min(best_plain_radius, plain_error);
    EXPECT_GT(plain_error, 0.3) << "seed " << seed;
    if (seed == 1) {
      std::printf(
          "[ sphere scene ] %ld points (%ld flying pixels), %.0f %% clutter, epsilon %.3f mm, alpha %.3f "
          "rad, "
          "%zu inliers\n",
          static_cast<long>(n), static_cast<long>(flying), 100 * clutter, result.epsilon, result.alpha,
          result.instances[0].inliers.size());
    }
  }
  std::printf(
      "[ sphere scene ] 20 seeds: worst radius error %.4f mm, worst centre error %.4f mm; "
      "plain least squares: smallest radius error %.2f mm\n",
      worst_radius, worst_centre, best_plain_radius);
}

TEST(PrimitiveDetection, SphereOnAStandWithFloorAndWallOverTwentySeeds) {
  DetectTheSphereOnAStandOverTwentySeeds(0.0);
}

// The same with flying pixels: every ray whose footprint straddles the sphere's silhouette and the wall,
// floor or post behind it returns a range between the two (probability 1, the worst case), a halo of points
// in the 40 mm between the sphere and the wall.
TEST(PrimitiveDetection, SphereOnAStandWithFlyingPixelsOverTwentySeeds) {
  DetectTheSphereOnAStandOverTwentySeeds(1.0);
}

// Which object an instance is: the truth object of the same kind its parameters match within 1 mm (the
// scene's noise is 0.3 mm; radius and centre uncertainties of a few hundred points are far below 1 mm).
std::string Describe(const DetectedShape& shape) {
  char text[200];
  if (const auto* s = std::get_if<Sphere>(&shape)) {
    std::snprintf(text, sizeof text, "centre %.2f %.2f %.2f radius %.2f", s->center.x(), s->center.y(),
                  s->center.z(), s->radius);
  } else if (const auto* c = std::get_if<Cylinder>(&shape)) {
    std::snprintf(text, sizeof text, "axis point %.2f %.2f %.2f direction %.3f %.3f %.3f radius %.2f",
                  c->axis_point.x(), c->axis_point.y(), c->axis_point.z(), c->axis_direction.x(),
                  c->axis_direction.y(), c->axis_direction.z(), c->radius);
  } else {
    const Plane& p = std::get<Plane>(shape);
    std::snprintf(text, sizeof text, "plane through %.2f %.2f %.2f normal %.3f %.3f %.3f", p.point.x(),
                  p.point.y(), p.point.z(), p.normal.x(), p.normal.y(), p.normal.z());
  }
  return text;
}

int MatchObject(const DetectedPrimitive& instance, const std::vector<SceneObject>& objects) {
  for (std::size_t k = 0; k < objects.size(); ++k) {
    if (const auto* s = std::get_if<Sphere>(&objects[k]); s && instance.kind == PrimitiveKind::kSphere) {
      const Sphere& f = std::get<Sphere>(instance.shape);
      if ((f.center - s->center).norm() < 1 && std::abs(f.radius - s->radius) < 1) return static_cast<int>(k);
    }
    if (const auto* c = std::get_if<FiniteCylinder>(&objects[k]);
        c && instance.kind == PrimitiveKind::kCylinder) {
      Cylinder f = std::get<Cylinder>(instance.shape);
      MoveAxisPointNear(f, c->cylinder.axis_point);
      if ((f.axis_point - c->cylinder.axis_point).norm() < 1 && std::abs(f.radius - c->cylinder.radius) < 1 &&
          std::abs(f.axis_direction.dot(c->cylinder.axis_direction)) > std::cos(0.01))
        return static_cast<int>(k);
    }
    if (const auto* p = std::get_if<Plane>(&objects[k]); p && instance.kind == PrimitiveKind::kPlane) {
      const Plane& f = std::get<Plane>(instance.shape);
      if (std::abs(f.normal.dot(p->normal)) > std::cos(0.01) && std::abs(SignedDistance(*p, f.point)) < 1)
        return static_cast<int>(k);
    }
  }
  return -1;
}

void DetectSpheresAndACylinder(double flying_pixels) {
  const SpheresAndCylinderScene scene = MakeSpheresAndCylinderScene(3, flying_pixels);
  ASSERT_LE(scene.cloud.points.cols(), 50000);
  DetectionOptions options;
  options.kinds = {PrimitiveKind::kPlane, PrimitiveKind::kSphere, PrimitiveKind::kCylinder};
  options.seed = 5;
  const DetectionResult result = DetectPrimitives(scene.cloud.points, options);
  std::vector<int> found(scene.objects.size(), 0);
  for (const DetectedPrimitive& instance : result.instances) {
    const int k = MatchObject(instance, scene.objects);
    std::printf("[ scene ] %s: %zu inliers, RMS %.3f mm -> object %d\n", ToString(instance.kind),
                instance.inliers.size(), instance.rms, k);
    EXPECT_GE(k, 0) << "a spurious " << ToString(instance.kind) << " of " << instance.inliers.size()
                    << " points: " << Describe(instance.shape);
    if (k >= 0) ++found[static_cast<std::size_t>(k)];
  }
  for (std::size_t k = 0; k < scene.objects.size(); ++k) EXPECT_EQ(found[k], 1) << "object " << k;
  std::printf("[ scene ] %ld points, stop: %s, epsilon %.3f, alpha %.3f, min support %ld\n",
              static_cast<long>(scene.cloud.points.cols()), result.stop_reason.c_str(), result.epsilon,
              result.alpha, static_cast<long>(result.min_support));
}

TEST(PrimitiveDetection, SeveralSpheresAndACylinderOnAFloorAllFoundNoneSpurious) {
  DetectSpheresAndACylinder(0.0);
}

// With flying pixels at every silhouette (probability 1): still all found, none spurious.
TEST(PrimitiveDetection, SeveralSpheresAndACylinderWithFlyingPixels) {
  DetectSpheresAndACylinder(1.0);
}

// Objects cut in two by an occluder: a sphere (radius 50 mm) and a column (radius 40 mm), each behind a
// vertical bar (radius 14 mm) that hides a vertical strip about 35 mm wide in the middle of it from the
// scanner, so that each is seen as two disconnected patches (eq. 56; with a strip of 20 mm a few points where
// the strip meets the silhouette still had neighbours across it among their 40 nearest). Merged by the F-test
// of eq. 81 they are one instance each, with two components, matching the truth; without merging each comes
// out as two instances.
TEST(PrimitiveDetection, ObjectsCutInTwoByABarAreOneInstanceEach) {
  std::vector<SceneObject> objects;
  objects.push_back(Sphere{{-90, 0, 50}, 50.0});
  objects.push_back(FiniteCylinder{Cylinder{{90, 0, -200}, Eigen::Vector3d::UnitZ(), 40.0}, 500.0});
  // At y = -300 the lines of sight from the scanner to the objects' axes pass x = -72 and x = 72.
  objects.push_back(FiniteCylinder{Cylinder{{-72, -300, -400}, Eigen::Vector3d::UnitZ(), 14.0}, 1000.0});
  objects.push_back(FiniteCylinder{Cylinder{{72, -300, -400}, Eigen::Vector3d::UnitZ(), 14.0}, 1000.0});
  RayGrid grid;
  grid.origin = Eigen::Vector3d(0, -1500, 50);
  grid.look_at = Eigen::Vector3d(0, 0, 50);
  grid.step = 1.5e-3;
  grid.half_width = 0.12;
  grid.half_height = 0.08;
  grid.range_noise = 0.3;
  grid.seed = 9;
  const LabelledCloud cloud = CastRays(objects, grid);
  for (const bool merge : {true, false}) {
    DetectionOptions options;
    options.kinds = {PrimitiveKind::kSphere, PrimitiveKind::kCylinder};
    options.seed = 3;
    options.merge_split_instances = merge;
    const DetectionResult result = DetectPrimitives(cloud.points, options);
    std::vector<int> instances(objects.size(), 0), components(objects.size(), 0);
    for (const DetectedPrimitive& instance : result.instances) {
      const int k = MatchObject(instance, objects);
      std::printf(
          "[ occluded, merge %s ] %s: %zu inliers, %d components (F %.3g), RMS %.3f mm -> object %d\n",
          merge ? "on" : "off", ToString(instance.kind), instance.inliers.size(), instance.components,
          instance.merge_f, instance.rms, k);
      if (k < 0) continue;
      ++instances[static_cast<std::size_t>(k)];
      components[static_cast<std::size_t>(k)] += instance.components;
    }
    for (std::size_t k = 0; k < 2; ++k) {
      // Each object is seen as two patches, and every patch is found: merged into one instance, or not.
      EXPECT_EQ(components[k], 2) << "object " << k << (merge ? " merged" : " apart");
      EXPECT_EQ(instances[k], merge ? 1 : 2) << "object " << k << (merge ? " merged" : " apart");
    }
  }
}

// A ring torus (R 40 mm, r 12 mm) lying on a floor among uniform clutter (15 % of the points), 0.1 mm noise
// along the normals: found once, with its radii within 5 of the refit's own standard uncertainties, beside
// the floor; nothing spurious.
TEST(PrimitiveDetection, TorusOnAFloorAmongClutter) {
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> unit(0.0, 1.0), side(-100.0, 100.0), height(0.0, 60.0);
  std::normal_distribution<double> noise(0.0, 0.1);
  const Torus truth{{0, 0, 12}, {0, 0, 1}, 40.0, 12.0};
  std::vector<Eigen::Vector3d> pts;
  while (pts.size() <
         6000) {  // uniform over the area: accept (theta, phi) with probability (R + r cos phi) / (R + r)
    const double t = 2 * M_PI * unit(rng), u = 2 * M_PI * unit(rng);
    if (unit(rng) * (truth.major_radius + truth.minor_radius) >
        truth.major_radius + truth.minor_radius * std::cos(u))
      continue;
    const Eigen::Vector3d e(std::cos(t), std::sin(t), 0.0);
    const Eigen::Vector3d n = std::cos(u) * e + std::sin(u) * truth.axis;
    pts.push_back(truth.center + truth.major_radius * e + (truth.minor_radius + noise(rng)) * n);
  }
  while (pts.size() < 12000) {  // the floor outside the torus's footprint
    const Eigen::Vector3d x(side(rng), side(rng), noise(rng));
    if (x.head<2>().norm() > truth.major_radius + truth.minor_radius + 2) pts.push_back(x);
  }
  while (pts.size() < 14000) pts.push_back({side(rng), side(rng), height(rng)});
  Eigen::Matrix3Xd cloud(3, static_cast<Eigen::Index>(pts.size()));
  for (std::size_t i = 0; i < pts.size(); ++i) cloud.col(static_cast<Eigen::Index>(i)) = pts[i];
  DetectionOptions options;
  options.kinds = {PrimitiveKind::kTorus, PrimitiveKind::kPlane};
  options.seed = 3;
  const DetectionResult result = DetectPrimitives(cloud, options);
  int tori = 0, planes = 0;
  for (const DetectedPrimitive& instance : result.instances) {
    std::printf("[ torus scene ] %s: %zu inliers, RMS %.3f mm, %d draws\n", ToString(instance.kind),
                instance.inliers.size(), instance.rms, instance.draws);
    if (const auto* t = std::get_if<Torus>(&instance.shape)) {
      ++tori;
      double u_major = 0, u_minor = 0;
      for (const ParameterUncertainty& u : instance.uncertainties) {
        if (u.name == "major_radius") u_major = u.standard_uncertainty;
        if (u.name == "minor_radius") u_minor = u.standard_uncertainty;
      }
      ASSERT_GT(u_major, 0);
      std::printf("[ torus scene ] R %.4f (u %.4f), r %.4f (u %.4f), axis tilt %.2e rad\n", t->major_radius,
                  u_major, t->minor_radius, u_minor, LineAngle(t->axis, truth.axis));
      EXPECT_NEAR(t->major_radius, truth.major_radius, 5 * u_major);
      EXPECT_NEAR(t->minor_radius, truth.minor_radius, 5 * u_minor);
      EXPECT_LT((t->center - truth.center).norm(), 0.05);
      EXPECT_GT(static_cast<double>(instance.inliers.size()), 0.95 * 6000);
    } else if (std::holds_alternative<Plane>(instance.shape)) {
      ++planes;
      EXPECT_GT(std::abs(std::get<Plane>(instance.shape).normal.z()), 1 - 1e-4);
    }
  }
  EXPECT_EQ(tori, 1);
  EXPECT_EQ(planes, 1);
  EXPECT_EQ(result.instances.size(), 2u);
}

// The same seed, the same result, on one thread and on two (OpenMP only scores candidates already drawn).
TEST(PrimitiveDetection, TheSameSeedGivesTheSameResultOnAnyNumberOfThreads) {
  const SpheresAndCylinderScene scene = MakeSpheresAndCylinderScene(4);
  DetectionOptions options;
  options.kinds = {PrimitiveKind::kPlane, PrimitiveKind::kSphere, PrimitiveKind::kCylinder};
  options.seed = 11;
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const DetectionResult a = DetectPrimitives(scene.cloud.points, options);
  omp_set_num_threads(2);
  const DetectionResult b = DetectPrimitives(scene.cloud.points, options);
  omp_set_num_threads(threads);
  ASSERT_EQ(a.instances.size(), b.instances.size());
  for (std::size_t i = 0; i < a.instances.size(); ++i) {
    EXPECT_EQ(a.instances[i].kind, b.instances[i].kind);
    EXPECT_EQ(a.instances[i].inliers, b.instances[i].inliers);
    EXPECT_EQ(a.instances[i].rms, b.instances[i].rms);  // bit for bit
  }
  EXPECT_EQ(a.rejected, b.rejected);
}

TEST(PrimitiveDetection, BadInputIsRejectedWithAReason) {
  DetectionOptions options;
  EXPECT_FALSE(options.IsValid());  // no kind
  options.kinds = {PrimitiveKind::kPlane};
  EXPECT_TRUE(options.IsValid());
  EXPECT_THROW(DetectPrimitives(Eigen::Matrix3Xd::Random(3, 5), options), std::invalid_argument);
  Eigen::Matrix3Xd bad = Eigen::Matrix3Xd::Random(3, 100);
  bad(1, 7) = std::nan("");
  EXPECT_THROW(DetectPrimitives(bad, options), std::invalid_argument);
}

}  // namespace
}  // namespace s2m
