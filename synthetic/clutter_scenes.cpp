#include "synthetic/clutter_scenes.h"

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <random>
#include <utility>

namespace s2m {
namespace {

constexpr double kNoHit = std::numeric_limits<double>::infinity();

// The smallest ray parameter t > 0 at which o + t d (d unit) meets the object, or infinity.
double Hit(const Sphere& s, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  const Eigen::Vector3d w = o - s.center;
  const double b = d.dot(w), c = w.squaredNorm() - s.radius * s.radius;
  const double disc = b * b - c;
  if (disc < 0) return kNoHit;
  const double root = std::sqrt(disc);
  if (-b - root > 0) return -b - root;
  if (-b + root > 0) return -b + root;
  return kNoHit;
}

double Hit(const FiniteCylinder& f, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  const Eigen::Vector3d& a = f.cylinder.axis_direction;
  const Eigen::Vector3d w = o - f.cylinder.axis_point;
  const Eigen::Vector3d dp = d - d.dot(a) * a, wp = w - w.dot(a) * a;
  const double qa = dp.squaredNorm(), qb = 2 * dp.dot(wp),
               qc = wp.squaredNorm() - f.cylinder.radius * f.cylinder.radius;
  const double disc = qb * qb - 4 * qa * qc;
  if (qa <= 0 || disc < 0) return kNoHit;
  const double root = std::sqrt(disc);
  for (double t : {(-qb - root) / (2 * qa), (-qb + root) / (2 * qa)}) {
    if (t <= 0) continue;
    const double z = a.dot(w + t * d);
    if (z >= 0 && z <= f.length) return t;
  }
  return kNoHit;
}

double Hit(const Plane& p, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  const double nd = p.normal.dot(d);
  if (std::abs(nd) < 1e-12) return kNoHit;
  const double t = p.normal.dot(p.point - o) / nd;
  return t > 0 ? t : kNoHit;
}

// The first hit of the ray from `o` along `d` among the scene's objects: (t, object index), or (infinity,
// -1).
std::pair<double, int> FirstHit(const std::vector<SceneObject>& scene, const Eigen::Vector3d& o,
                                const Eigen::Vector3d& d) {
  double best = kNoHit;
  int label = -1;
  for (std::size_t k = 0; k < scene.size(); ++k) {
    const double t = std::visit([&](const auto& object) { return Hit(object, o, d); }, scene[k]);
    if (t < best) {
      best = t;
      label = static_cast<int>(k);
    }
  }
  return {best, label};
}

}  // namespace

LabelledCloud CastRays(const std::vector<SceneObject>& scene, const RayGrid& grid) {
  const Eigen::Vector3d forward = (grid.look_at - grid.origin).normalized();
  const Eigen::Vector3d right = forward.cross(grid.up).normalized();
  const Eigen::Vector3d up = right.cross(forward);
  const int columns = static_cast<int>(std::floor(2 * grid.half_width / grid.step)) + 1;
  const int rows = static_cast<int>(std::floor(2 * grid.half_height / grid.step)) + 1;
  std::mt19937_64 rng(grid.seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  // Constant angular steps in azimuth and elevation about the centre ray.
  auto direction = [&](double azimuth, double elevation) {
    return (std::cos(elevation) * (std::cos(azimuth) * forward + std::sin(azimuth) * right) +
            std::sin(elevation) * up)
        .normalized();
  };
  std::vector<Eigen::Vector3d> points;
  LabelledCloud cloud;
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < columns; ++c) {
      const double azimuth = -grid.half_width + c * grid.step, elevation = -grid.half_height + r * grid.step;
      const Eigen::Vector3d d = direction(azimuth, elevation);
      const auto [best, label] = FirstHit(scene, grid.origin, d);
      if (label < 0) continue;
      double t = best;
      int point_label = label;
      if (grid.flying_pixel_probability > 0) {
        // The footprint's other object, if any: the first of the four half-step rays that meets one.
        const double h = 0.5 * grid.step;
        for (const auto& [da, de] :
             {std::pair{-h, 0.0}, std::pair{h, 0.0}, std::pair{0.0, -h}, std::pair{0.0, h}}) {
          const auto [t_other, other] = FirstHit(scene, grid.origin, direction(azimuth + da, elevation + de));
          if (other < 0 || other == label) continue;
          if (uniform(rng) < grid.flying_pixel_probability) {
            const double w = uniform(rng);
            t = w * best + (1 - w) * t_other;
            point_label = kFlyingPixel;
          }
          break;
        }
      }
      t += grid.range_noise * noise(rng);
      points.push_back(grid.origin + t * d);
      cloud.labels.push_back(point_label);
    }
  }
  cloud.points.resize(3, static_cast<Eigen::Index>(points.size()));
  for (std::size_t i = 0; i < points.size(); ++i) cloud.points.col(static_cast<Eigen::Index>(i)) = points[i];
  return cloud;
}

SphereOnStandScene MakeSphereOnStandScene(double range, double noise, std::uint64_t seed,
                                          double flying_pixels) {
  SphereOnStandScene s;
  s.truth = Sphere{Eigen::Vector3d::Zero(), 25.0};
  s.objects.push_back(s.truth);
  s.objects.push_back(FiniteCylinder{Cylinder{{0, 0, -65}, Eigen::Vector3d::UnitZ(), 6.0}, 41.0});
  s.objects.push_back(Plane{{0, 0, -65}, Eigen::Vector3d::UnitZ()});
  s.objects.push_back(Plane{{0, 40, 0}, -Eigen::Vector3d::UnitY()});
  RayGrid grid;
  const double elevation = 0.21;
  grid.origin = Eigen::Vector3d(0, -range * std::cos(elevation), range * std::sin(elevation));
  // The window's centre ray passes 19 mm below the sphere's centre (28 mm above to 66 mm below it).
  grid.look_at = Eigen::Vector3d(0, 0, -19);
  grid.step = 1.2 / range;
  grid.half_width = 28.0 / range;
  grid.half_height = 47.0 / range;
  grid.range_noise = noise;
  grid.flying_pixel_probability = flying_pixels;
  grid.seed = seed;
  s.cloud = CastRays(s.objects, grid);
  return s;
}

SpheresAndCylinderScene MakeSpheresAndCylinderScene(std::uint64_t seed, double flying_pixels) {
  SpheresAndCylinderScene s;
  // Side by side across the view, so that no object hides a part of another (an occluded object would be
  // seen as two disconnected patches: two instances).
  s.objects.push_back(Sphere{{-220, 0, 30}, 30.0});
  s.objects.push_back(Sphere{{-90, 20, 40}, 40.0});
  s.objects.push_back(Sphere{{60, 0, 50}, 50.0});
  s.objects.push_back(FiniteCylinder{Cylinder{{200, 40, 0}, Eigen::Vector3d::UnitZ(), 40.0}, 1000.0});
  s.objects.push_back(Plane{{0, 0, 0}, Eigen::Vector3d::UnitZ()});
  RayGrid grid;
  grid.origin = Eigen::Vector3d(0, -1500, 800);
  grid.look_at = Eigen::Vector3d(0, 20, 40);
  grid.step = 1.5e-3;
  grid.half_width = 0.17;
  grid.half_height = 0.13;
  grid.range_noise = 0.3;
  grid.flying_pixel_probability = flying_pixels;
  grid.seed = seed;
  s.cloud = CastRays(s.objects, grid);
  return s;
}

}  // namespace s2m
