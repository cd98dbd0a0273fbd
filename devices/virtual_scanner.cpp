#include "devices/virtual_scanner.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <stdexcept>

#include "devices/device_options.h"
#include "synthetic/synthetic_cases.h"

namespace s2m {

namespace {

constexpr double kDegree = M_PI / 180.0;

// SplitMix64 (Steele, Lea, Flood, OOPSLA 2014): decorrelated seeds for the per-frame generators, so that a
// frame's noise depends on (seed, stream, frame) alone, not on how many numbers earlier frames drew.
std::uint64_t Mix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}
std::mt19937_64 FrameGenerator(std::uint64_t seed, std::uint64_t purpose, std::uint64_t frame) {
  return std::mt19937_64(Mix(Mix(Mix(seed) ^ purpose) ^ frame));
}

// The sensor's frame in the lab: x right, y down, z along the line of sight (the camera convention of
// depth_frame.h), at `position` looking at `target`, the lab's z up.
RigidMotion LookAt(const Eigen::Vector3d& position, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - position).normalized();
  Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ());
  if (x.norm() < 1e-9) x = Eigen::Vector3d::UnitX();  // looking straight down or up
  x.normalize();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d r;
  r << x, y, z;
  return RigidMotion(r, position);
}

class VirtualScanner final : public FrameSource {
 public:
  VirtualScanner(SceneMesh scene, const VirtualScannerOptions& options) : caster_(scene), options_(options) {
    if (options_.turntable.steps < 1)
      throw std::invalid_argument("virtual scanner: steps must be at least 1");
    if (!(options_.metres_per_unit > 0))
      throw std::invalid_argument("virtual scanner: metres_per_unit must be positive");
    const Eigen::Vector3d lo = scene.vertices.rowwise().minCoeff(), hi = scene.vertices.rowwise().maxCoeff();
    scale_ = (hi - lo).norm();
    double radius = 0;
    for (Eigen::Index i = 0; i < scene.vertices.cols(); ++i)
      radius = std::max(radius, scene.vertices.col(i).head<2>().norm());
    const bool depth = options_.sensor == VirtualScannerOptions::Sensor::kDepthCamera;
    double distance = options_.distance;
    if (distance <= 0) distance = depth ? 0.7 / options_.metres_per_unit : 3.0 * radius;
    const double height =
        std::isnan(options_.target_height) ? 0.5 * (lo.z() + hi.z()) : options_.target_height;
    const Eigen::Vector3d target(0, 0, height);
    if (options_.elevations_rad.empty())
      throw std::invalid_argument("virtual scanner: at least one elevation");
    for (const double el : options_.elevations_rad) {
      Sweep sweep;
      sweep.lab_T_sensor = LookAt(target + distance * Eigen::Vector3d(std::cos(el), 0, std::sin(el)), target);
      // The laser scanner's camera: camera_angle around the table from the laser, same height.
      sweep.laser_camera_position =
          target + RotationAboutAxis(Eigen::Vector3d::UnitZ(), options_.laser.camera_angle_rad) *
                       (sweep.lab_T_sensor.translation() - target);
      sweeps_.push_back(sweep);
    }
    // The laser fan covers the scene: its half-angle reaches the scene's corners in the laser plane's y.
    for (Sweep& sweep : sweeps_) {
      if (depth) break;
      double reach = 0;
      const RigidMotion sensor_T_lab = sweep.lab_T_sensor.inverse();
      for (int corner = 0; corner < 8; ++corner) {
        const Eigen::Vector3d c((corner & 1) ? hi.x() : lo.x(), (corner & 2) ? hi.y() : lo.y(),
                                (corner & 4) ? hi.z() : lo.z());
        // Any turntable angle: the corner's radius about the axis matters, not its azimuth.
        const double r = c.head<2>().norm();
        for (double s : {-1.0, 1.0}) {
          const Eigen::Vector3d p = sensor_T_lab * Eigen::Vector3d(0, s * r, c.z());
          if (p.z() > 0) reach = std::max(reach, std::abs(p.y() / p.z()));
        }
      }
      sweep.fan_half_angle = std::atan(reach) * 1.05;
    }
    // The true axis: the nominal z tilted towards `axis_tilt_azimuth`, shifted in the table plane.
    const TurntableOptions& t = options_.turntable;
    true_axis_ = Eigen::Vector3d(std::sin(t.axis_tilt_rad) * std::cos(t.axis_tilt_azimuth_rad),
                                 std::sin(t.axis_tilt_rad) * std::sin(t.axis_tilt_azimuth_rad),
                                 std::cos(t.axis_tilt_rad));
    true_axis_point_ = Eigen::Vector3d(t.axis_offset_x, t.axis_offset_y, 0.0);

    description_.name = options_.name;
    nlohmann::json device = {{"name", "virtual:" + options_.name},
                             {"sensor", depth ? "kinect" : "laser-line"},
                             {"turntable_steps", t.steps},
                             {"seed", options_.seed}};
    description_.device_json = device.dump();
    nlohmann::json calibration = {
        {"turntable", {{"nominal_axis", {0, 0, 1}}, {"nominal_axis_point", {0, 0, 0}}}},
        {"lab_T_sensor", nlohmann::json::array()},
        // What the simulation used and a real device would not know: kept for tests and reports.
        {"simulation",
         {{"true_axis", {true_axis_.x(), true_axis_.y(), true_axis_.z()}},
          {"true_axis_point", {true_axis_point_.x(), true_axis_point_.y(), true_axis_point_.z()}},
          {"angle_noise_rad", t.angle_noise_rad},
          {"scene_units", scene.units},
          {"metres_per_unit", options_.metres_per_unit}}}};
    if (depth) {
      const DepthCameraOptions& c = options_.camera;
      calibration["camera"] = {{"width", c.width},
                               {"height", c.height},
                               {"baseline_m", c.baseline_m},
                               {"disparity_step_px", c.disparity_step_px},
                               {"disparity_noise_px", c.disparity_noise_px}};
    } else {
      calibration["laser"] = {{"points_per_profile", options_.laser.points_per_profile},
                              {"fan_half_angle_rad", sweeps_.front().fan_half_angle},
                              {"noise", options_.laser.noise},
                              {"camera_angle_rad", options_.laser.camera_angle_rad}};
    }
    for (const Sweep& sweep : sweeps_) {
      calibration["lab_T_sensor"].push_back(
          Matrix(sweep.lab_T_sensor.matrix(), depth ? options_.metres_per_unit * OutputPerMetre() : 1.0));
    }
    description_.calibration_json = calibration.dump();
    StreamInfo stream;
    if (depth) {
      const DepthCameraOptions& c = options_.camera;
      if (c.width < 1 || c.height < 1 || !(c.fx > 0) || !(c.fy > 0) || !(c.depth_unit_m > 0) ||
          !(c.baseline_m > 0))
        throw std::invalid_argument(
            "virtual scanner: camera size, focal lengths, depth unit and baseline must be positive");
      if (c.output_units != "m" && c.output_units != "mm")
        throw std::invalid_argument("virtual scanner: depth units must be m or mm, not " + c.output_units);
      stream = {"depth", FrameKind::kDepth, c.output_units,
                DepthIntrinsics{c.fx, c.fy, c.cx, c.cy, c.depth_unit_m * OutputPerMetre(), true}};
    } else {
      if (options_.laser.points_per_profile < 2)
        throw std::invalid_argument("virtual scanner: points must be at least 2");
      stream = {"profile", FrameKind::kProfile, scene.units, std::nullopt};
    }
    description_.streams.push_back(stream);
  }

  const SourceDescription& description() const override { return description_; }

  std::optional<Frame> Next() override {
    if (next_ >= *FrameCount()) return std::nullopt;
    const int k = next_++;
    const TurntableOptions& t = options_.turntable;
    // Frame k: sweep k / steps (one per elevation), turntable step k % steps.
    const Sweep& sweep = sweeps_[static_cast<std::size_t>(k / t.steps)];
    const double nominal = t.start_angle_rad + 2 * M_PI * (k % t.steps) / t.steps;
    std::mt19937_64 table_rng = FrameGenerator(options_.seed, 1, static_cast<std::uint64_t>(k));
    const double truth =
        nominal +
        (t.angle_noise_rad > 0 ? std::normal_distribution<double>(0.0, t.angle_noise_rad)(table_rng) : 0.0);
    // The table turned the object by `truth` about the true axis: lab = A world, A = o + R (x - o).
    const Eigen::Matrix3d R = RotationAboutAxis(true_axis_, truth);
    const RigidMotion lab_T_world_true(R, true_axis_point_ - R * true_axis_point_);
    const RigidMotion world_T_sensor_true = lab_T_world_true.inverse() * sweep.lab_T_sensor;
    const RigidMotion world_T_sensor_nominal =
        RigidMotion(RotationAboutAxis(Eigen::Vector3d::UnitZ(), -nominal), Eigen::Vector3d::Zero()) *
        sweep.lab_T_sensor;
    std::mt19937_64 rng = FrameGenerator(options_.seed, 2, static_cast<std::uint64_t>(k));

    Frame f;
    f.stream = 0;
    f.timestamp_ns = options_.start_time_ns + std::llround(options_.interval_s * 1e9 * k);
    f.turntable_angle_rad = nominal;
    f.source = "virtual:" + options_.name + " frame " + std::to_string(k);
    if (options_.sensor == VirtualScannerOptions::Sensor::kDepthCamera) {
      f.kind = FrameKind::kDepth;
      f.view = k;
      f.depth = RenderDepth(world_T_sensor_true, rng);
      const double scale = options_.metres_per_unit * OutputPerMetre();  // scene units to the stream's
      f.world_T_scan =
          RigidMotion(world_T_sensor_nominal.rotation(), world_T_sensor_nominal.translation() * scale);
    } else {
      f.kind = FrameKind::kProfile;
      f.view = k / t.steps;  // every profile of a sweep belongs to its view
      f.points = LaserProfile(world_T_sensor_true, lab_T_world_true, sweep, rng);
      f.world_T_scan = world_T_sensor_nominal;
    }
    return f;
  }

  std::vector<std::int64_t> Views() const override {
    const bool laser = options_.sensor == VirtualScannerOptions::Sensor::kLaserLine;
    const auto count = laser ? static_cast<std::int64_t>(sweeps_.size()) : *FrameCount();
    std::vector<std::int64_t> v;
    for (std::int64_t k = 0; k < count; ++k) v.push_back(k);
    return v;
  }
  void SeekView(std::int64_t view) override {
    const std::vector<std::int64_t> views = Views();
    if (std::find(views.begin(), views.end(), view) == views.end())
      throw std::out_of_range("virtual scanner: no view " + std::to_string(view));
    next_ = static_cast<int>(options_.sensor == VirtualScannerOptions::Sensor::kLaserLine
                                 ? view * options_.turntable.steps
                                 : view);
  }
  std::optional<std::int64_t> FrameCount() const override {
    return static_cast<std::int64_t>(options_.turntable.steps) * static_cast<std::int64_t>(sweeps_.size());
  }

 private:
  double OutputPerMetre() const { return options_.camera.output_units == "mm" ? 1000.0 : 1.0; }

  static nlohmann::json Matrix(const Eigen::Matrix4d& m, double translation_scale) {
    nlohmann::json rows = nlohmann::json::array();
    for (int r = 0; r < 4; ++r) {
      nlohmann::json row = nlohmann::json::array();
      for (int c = 0; c < 4; ++c) row.push_back(c == 3 && r < 3 ? m(r, c) * translation_scale : m(r, c));
      rows.push_back(row);
    }
    return rows;
  }

  DepthImage RenderDepth(const RigidMotion& world_T_camera, std::mt19937_64& rng) const {
    const DepthCameraOptions& c = options_.camera;
    const double m = options_.metres_per_unit;
    const Eigen::Index n = static_cast<Eigen::Index>(c.width) * c.height;
    Eigen::Matrix3Xd origins(3, n), directions(3, n);
    for (int v = 0; v < c.height; ++v) {
      for (int u = 0; u < c.width; ++u) {
        const Eigen::Index i = static_cast<Eigen::Index>(v) * c.width + u;
        // Through the pixel's centre: integer coordinates (depth_frame.h's back-projection).
        const Eigen::Vector3d ray((u - c.cx) / c.fx, (v - c.cy) / c.fy, 1.0);
        origins.col(i) = world_T_camera.translation();
        directions.col(i) = world_T_camera.rotation() * ray;
      }
    }
    const std::vector<RayHit> hits = caster_.Cast(origins, directions);
    // True depth along the optical axis, metres; 0 for no return.
    std::vector<double> z(static_cast<std::size_t>(n), 0.0);
    const RigidMotion camera_T_world = world_T_camera.inverse();
    for (Eigen::Index i = 0; i < n; ++i) {
      const RayHit& h = hits[static_cast<std::size_t>(i)];
      if (!h.hit) continue;
      const double zi = (camera_T_world * h.point).z() * m;
      const double cosine = std::abs(h.normal.dot(directions.col(i).normalized()));
      if (zi < c.min_range_m || zi > c.max_range_m || cosine < c.min_incidence_cosine) continue;
      z[static_cast<std::size_t>(i)] = zi;
    }
    DepthImage image;
    image.width = c.width;
    image.height = c.height;
    image.values.assign(static_cast<std::size_t>(n), 0);
    std::normal_distribution<double> gauss(0.0, 1.0);
    const double fb = c.fx * c.baseline_m;
    for (int v = 0; v < c.height; ++v) {
      for (int u = 0; u < c.width; ++u) {
        const std::size_t i =
            static_cast<std::size_t>(v) * static_cast<std::size_t>(c.width) + static_cast<std::size_t>(u);
        // Drawn for every pixel, used or not: a pixel's noise does not depend on which others returned.
        const double e = gauss(rng);
        if (z[i] == 0) continue;
        if (c.edge_jump_m > 0) {
          bool edge = false;
          const int du[4] = {-1, 1, 0, 0}, dv[4] = {0, 0, -1, 1};
          for (int q = 0; q < 4 && !edge; ++q) {
            const int uu = u + du[q], vv = v + dv[q];
            if (uu < 0 || vv < 0 || uu >= c.width || vv >= c.height) continue;
            const double zn = z[static_cast<std::size_t>(vv) * static_cast<std::size_t>(c.width) +
                                static_cast<std::size_t>(uu)];
            edge = zn == 0 || std::abs(zn - z[i]) > c.edge_jump_m;
          }
          if (edge) continue;
        }
        // Khoshelham and Elberink 2012, eq. 4-5 and 10: disparity d = f b / z, noisy and quantized.
        double d = fb / z[i] + c.disparity_noise_px * e;
        if (c.disparity_step_px > 0) d = std::round(d / c.disparity_step_px) * c.disparity_step_px;
        if (!(d > 0)) continue;
        const double raw = std::round(fb / d / c.depth_unit_m);
        if (raw >= 1 && raw <= 65535) image.values[i] = static_cast<std::uint16_t>(raw);
      }
    }
    return image;
  }

  struct Sweep {
    RigidMotion lab_T_sensor;
    Eigen::Vector3d laser_camera_position = Eigen::Vector3d::Zero();
    double fan_half_angle = 0.0;
  };

  Eigen::Matrix3Xd LaserProfile(const RigidMotion& world_T_laser, const RigidMotion& lab_T_world_true,
                                const Sweep& sweep, std::mt19937_64& rng) const {
    const double fan_half_angle_ = sweep.fan_half_angle;
    const LaserLineOptions& l = options_.laser;
    const int n = l.points_per_profile;
    Eigen::Matrix3Xd origins(3, n), directions(3, n), local(3, n);
    for (int i = 0; i < n; ++i) {
      const double phi = -fan_half_angle_ + 2 * fan_half_angle_ * i / (n - 1);
      local.col(i) = Eigen::Vector3d(0.0, std::sin(phi), std::cos(phi));  // the laser plane is x = 0
      origins.col(i) = world_T_laser.translation();
      directions.col(i) = world_T_laser.rotation() * local.col(i);
    }
    const std::vector<RayHit> hits = caster_.Cast(origins, directions);
    Eigen::Matrix3Xd lit(3, n);
    std::vector<int> ray_of;
    for (int i = 0; i < n; ++i) {
      const RayHit& h = hits[static_cast<std::size_t>(i)];
      if (!h.hit || std::abs(h.normal.dot(directions.col(i).normalized())) < l.min_incidence_cosine) continue;
      lit.col(static_cast<Eigen::Index>(ray_of.size())) = h.point;
      ray_of.push_back(i);
    }
    lit.conservativeResize(3, static_cast<Eigen::Index>(ray_of.size()));
    // Triangulation: the camera must see the lit point too (it sits camera_angle around the table).
    const Eigen::Vector3d camera = lab_T_world_true.inverse() * sweep.laser_camera_position;
    const std::vector<bool> seen = caster_.Visible(lit, camera, 1e-3 * scale_);
    std::normal_distribution<double> gauss(0.0, 1.0);
    Eigen::Matrix3Xd out(3, lit.cols());
    Eigen::Index count = 0;
    for (Eigen::Index j = 0; j < lit.cols(); ++j) {
      const double e = gauss(rng);
      if (!seen[static_cast<std::size_t>(j)]) continue;
      const int i = ray_of[static_cast<std::size_t>(j)];
      const double range = hits[static_cast<std::size_t>(i)].distance + l.noise * e;
      out.col(count++) = range * local.col(i);  // the laser's frame: along its ray, exactly in its plane
    }
    out.conservativeResize(3, count);
    return out;
  }

  RayCaster caster_;
  VirtualScannerOptions options_;
  SourceDescription description_;
  std::vector<Sweep> sweeps_;
  Eigen::Vector3d true_axis_, true_axis_point_;
  double scale_ = 1.0;
  int next_ = 0;
};

}  // namespace

// ---------------------------------------------------------------------------------------------- scenes

SceneMesh TessellateSurface(std::shared_ptr<const ParametricModel> model, double u0, double u1, double v0,
                            double v1, int nu, int nv) {
  if (!model || model->ambient_dimension() != 3 || model->domain().dimension != 2)
    throw std::invalid_argument("tessellation needs a surface in 3D");
  if (nu < 2 || nv < 2) throw std::invalid_argument("tessellation needs at least a 2 x 2 grid");
  SceneMesh mesh;
  mesh.vertices.resize(3, static_cast<Eigen::Index>(nu + 1) * (nv + 1));
  mesh.vertex_parameters.resize(2, mesh.vertices.cols());
  LocalGeometry g;
  for (int i = 0; i <= nu; ++i) {
    for (int j = 0; j <= nv; ++j) {
      const double u = u0 + (u1 - u0) * i / nu, v = v0 + (v1 - v0) * j / nv;
      model->Evaluate({u, v, 0.0}, 0, g);
      const Eigen::Index k = static_cast<Eigen::Index>(i) * (nv + 1) + j;
      mesh.vertices.col(k) = To3(g.point);
      mesh.vertex_parameters.col(k) = Eigen::Vector2d(u, v);
    }
  }
  mesh.triangles.resize(3, 2 * static_cast<Eigen::Index>(nu) * nv);
  Eigen::Index t = 0;
  for (int i = 0; i < nu; ++i) {
    for (int j = 0; j < nv; ++j) {
      const int a = i * (nv + 1) + j, b = a + nv + 1;
      mesh.triangles.col(t++) = Eigen::Vector3i(a, b, b + 1);
      mesh.triangles.col(t++) = Eigen::Vector3i(a, b + 1, a + 1);
    }
  }
  SceneMesh::Patch patch;
  patch.model = std::move(model);
  mesh.patches.push_back(patch);
  mesh.triangle_patch.assign(static_cast<std::size_t>(mesh.triangles.cols()), 0);
  return mesh;
}

SceneMesh CounterboredBlockMesh(const Eigen::VectorXd& values, int segments) {
  if (values.size() != 6) throw std::invalid_argument("the counterbored block has six parameters");
  const double W = values[0], D = values[1], H = values[2], rb = values[3] / 2, rc = values[4] / 2,
               depth = values[5];
  if (!(rb > 0 && rc > rb && 2 * rc < std::min(W, D) && depth > 0 && depth < H) || segments < 8)
    throw std::invalid_argument("inconsistent counterbored block dimensions");
  std::vector<Eigen::Vector3d> v;
  std::vector<Eigen::Vector3i> tri;
  std::vector<int> patch;
  auto add = [&](const Eigen::Vector3d& p) {
    v.push_back(p);
    return static_cast<int>(v.size()) - 1;
  };
  auto quad = [&](int a, int b, int c, int d, int p) {  // a b c d counter-clockwise from outside
    tri.emplace_back(a, b, c);
    tri.emplace_back(a, c, d);
    patch.push_back(p);
    patch.push_back(p);
  };
  // Four sides.
  const double x0 = -W / 2, x1 = W / 2, y0 = -D / 2, y1 = D / 2;
  const int b00 = add({x0, y0, 0}), b10 = add({x1, y0, 0}), b11 = add({x1, y1, 0}), b01 = add({x0, y1, 0});
  const int t00 = add({x0, y0, H}), t10 = add({x1, y0, H}), t11 = add({x1, y1, H}), t01 = add({x0, y1, H});
  quad(b00, b10, t10, t00, -1);
  quad(b10, b11, t11, t10, -1);
  quad(b11, b01, t01, t11, -1);
  quad(b01, b00, t00, t01, -1);
  // Rings: the top and bottom faces are fans from the block's outline to circles (counterbore on top, bore
  // at the bottom); the counterbore floor is an annulus; the walls are prisms refined to exact cylinders.
  const int n = segments;
  auto circle = [&](double r, double z) {
    std::vector<int> ids;
    for (int k = 0; k < n; ++k) {
      const double a = 2 * M_PI * k / n;
      ids.push_back(add({r * std::cos(a), r * std::sin(a), z}));
    }
    return ids;
  };
  const std::vector<int> top_c = circle(rc, H), floor_c = circle(rc, H - depth),
                         floor_b = circle(rb, H - depth), bottom_b = circle(rb, 0.0);
  // Outline points of the rectangle in the direction of each circle vertex (rays from the centre).
  auto outline = [&](double z) {
    std::vector<int> ids;
    for (int k = 0; k < n; ++k) {
      const double a = 2 * M_PI * k / n;
      const Eigen::Vector2d dir(std::cos(a), std::sin(a));
      const double s = std::min(std::abs(dir.x()) > 1e-15 ? (W / 2) / std::abs(dir.x()) : 1e300,
                                std::abs(dir.y()) > 1e-15 ? (D / 2) / std::abs(dir.y()) : 1e300);
      ids.push_back(add({s * dir.x(), s * dir.y(), z}));
    }
    return ids;
  };
  const std::vector<int> top_o = outline(H), bottom_o = outline(0.0);
  // The rectangle's corners belong to the planar faces too: fan triangles between consecutive outline points
  // would cut the corners off, so each sector also gets a triangle to the corner it spans.
  const std::array<int, 4> top_corners = {t10, t11, t01, t00}, bottom_corners = {b10, b11, b01, b00};
  auto corner_between = [&](int k) -> int {  // corner index in the sector from k to k+1, or -1
    const double a0 = 2 * M_PI * k / n, a1 = 2 * M_PI * (k + 1) / n;
    const double corners[4] = {std::atan2(y0, x1), std::atan2(y1, x1), std::atan2(y1, x0),
                               std::atan2(y0, x0)};
    for (int c = 0; c < 4; ++c) {
      double a = corners[c];
      if (a < 0) a += 2 * M_PI;
      if (a > a0 + 1e-12 && a < a1 - 1e-12) return c;
    }
    return -1;
  };
  SceneMesh mesh;
  mesh.units = "mm";
  SceneMesh::Patch counterbore, bore;
  counterbore.type = bore.type = SceneMesh::Patch::Type::kCylinder;
  counterbore.radius = rc;
  bore.radius = rb;
  mesh.patches = {counterbore, bore};
  for (int k = 0; k < n; ++k) {
    const int k1 = (k + 1) % n;
    const int corner = corner_between(k);
    // Top (normal +z): outline k, outline k1, circle k1, circle k seen from above is counter-clockwise as
    // circle k, outline k, outline k1, circle k1 ... written as quads around the annulus-like ring.
    if (corner < 0) {
      quad(top_c[static_cast<std::size_t>(k)], top_o[static_cast<std::size_t>(k)],
           top_o[static_cast<std::size_t>(k1)], top_c[static_cast<std::size_t>(k1)], -1);
      quad(bottom_b[static_cast<std::size_t>(k1)], bottom_o[static_cast<std::size_t>(k1)],
           bottom_o[static_cast<std::size_t>(k)], bottom_b[static_cast<std::size_t>(k)], -1);
    } else {
      const int tc = top_corners[static_cast<std::size_t>(corner)],
                bc = bottom_corners[static_cast<std::size_t>(corner)];
      quad(top_c[static_cast<std::size_t>(k)], top_o[static_cast<std::size_t>(k)], tc,
           top_c[static_cast<std::size_t>(k1)], -1);
      tri.emplace_back(top_c[static_cast<std::size_t>(k1)], tc, top_o[static_cast<std::size_t>(k1)]);
      patch.push_back(-1);
      quad(bottom_b[static_cast<std::size_t>(k1)], bc, bottom_o[static_cast<std::size_t>(k)],
           bottom_b[static_cast<std::size_t>(k)], -1);
      tri.emplace_back(bottom_b[static_cast<std::size_t>(k1)], bottom_o[static_cast<std::size_t>(k1)], bc);
      patch.push_back(-1);
    }
    // Counterbore floor (normal +z), annulus between rc and rb.
    quad(floor_b[static_cast<std::size_t>(k)], floor_c[static_cast<std::size_t>(k)],
         floor_c[static_cast<std::size_t>(k1)], floor_b[static_cast<std::size_t>(k1)], -1);
    // Walls face the axis.
    quad(top_c[static_cast<std::size_t>(k)], top_c[static_cast<std::size_t>(k1)],
         floor_c[static_cast<std::size_t>(k1)], floor_c[static_cast<std::size_t>(k)], 0);
    quad(floor_b[static_cast<std::size_t>(k)], floor_b[static_cast<std::size_t>(k1)],
         bottom_b[static_cast<std::size_t>(k1)], bottom_b[static_cast<std::size_t>(k)], 1);
  }
  mesh.vertices.resize(3, static_cast<Eigen::Index>(v.size()));
  for (std::size_t i = 0; i < v.size(); ++i) mesh.vertices.col(static_cast<Eigen::Index>(i)) = v[i];
  mesh.triangles.resize(3, static_cast<Eigen::Index>(tri.size()));
  for (std::size_t i = 0; i < tri.size(); ++i) mesh.triangles.col(static_cast<Eigen::Index>(i)) = tri[i];
  mesh.triangle_patch = patch;
  return mesh;
}

SceneMesh SceneByName(const std::string& name, const std::string& mesh_units) {
  if (name == "part") {
    return CounterboredBlockMesh((Eigen::VectorXd(6) << 60, 40, 20, 10, 18, 6).finished());
  }
  // The single-surface cases (face 0 over its parameter domain); the parts have their own meshes.
  const std::vector<std::string> surfaces = {"vase", "helical", "spiral"};
  if (std::find(surfaces.begin(), surfaces.end(), name) != surfaces.end()) {
    SyntheticCase c = MakeSyntheticCase(name);
    std::shared_ptr<const ParametricModel> model(std::move(c.truth));
    const ParameterDomain d = model->domain();
    // Fine enough that the tessellation's hit is within Newton's basin on the exact surface.
    SceneMesh mesh = TessellateSurface(model, d.lo[0], d.hi[0], d.lo[1], d.hi[1], 96, 256);
    mesh.units = "mm";
    return mesh;
  }
  const std::filesystem::path path(name);
  if (path.extension() == ".ply") return ReadMeshPly(path, mesh_units);
  throw std::invalid_argument("unknown virtual scene '" + name +
                              "' (vase, helical, spiral, part, or a .ply mesh)");
}

VirtualScannerOptions ParseVirtualDevice(const std::string& spec, std::string& scene,
                                         std::string& mesh_units) {
  const std::string prefix = "virtual:";
  if (spec.rfind(prefix, 0) != 0)
    throw std::invalid_argument("device '" + spec + "': only virtual:<scene>[,key=value...] is supported");
  const DeviceOptionList device =
      SplitDeviceOptions(spec.substr(prefix.size()), "device '" + spec + "': no scene given");
  scene = device.scene;
  mesh_units = "mm";
  VirtualScannerOptions o;
  o.name = std::filesystem::path(scene).stem().string();
  for (const auto& option : device.options) {
    // Named references, not structured bindings: lambdas may capture bindings only from C++20 (clang 14,
    // Debian 12's, refuses them).
    const std::string& key = option.first;
    const std::string& value = option.second;
    auto number = [&]() { return DeviceOptionNumber(key, value); };
    auto integer = [&]() { return DeviceOptionInteger(key, value, 0, 1000000000); };
    if (key == "sensor") {
      if (value == "kinect") {
        o.sensor = VirtualScannerOptions::Sensor::kDepthCamera;
      } else if (value == "laser") {
        o.sensor = VirtualScannerOptions::Sensor::kLaserLine;
      } else {
        throw std::invalid_argument("device option 'sensor': '" + value + "' (kinect or laser)");
      }
    } else if (key == "steps") {
      o.turntable.steps = integer();
    } else if (key == "seed") {
      o.seed = static_cast<std::uint64_t>(integer());
    } else if (key == "distance") {
      o.distance = number();
    } else if (key == "elevation_deg") {
      // Several elevations separated by ':' (one sweep each), e.g. 30:-30.
      o.elevations_rad.clear();
      std::stringstream list(value);
      for (std::string e; std::getline(list, e, ':');) {
        std::size_t used = 0;
        double x = 0;
        try {
          x = std::stod(e, &used);
        } catch (const std::exception&) {
          used = 0;
        }
        if (e.empty() || used != e.size() || !std::isfinite(x) || std::abs(x) >= 90)
          throw std::invalid_argument("device option 'elevation_deg': '" + e +
                                      "' is not an angle in (-90, 90)");
        o.elevations_rad.push_back(x * kDegree);
      }
    } else if (key == "target_height") {
      o.target_height = number();
    } else if (key == "width") {
      o.camera.width = integer();
    } else if (key == "height") {
      o.camera.height = integer();
    } else if (key == "fx") {
      o.camera.fx = number();
    } else if (key == "fy") {
      o.camera.fy = number();
    } else if (key == "cx") {
      o.camera.cx = number();
    } else if (key == "cy") {
      o.camera.cy = number();
    } else if (key == "depth_unit") {
      o.camera.depth_unit_m = number();
    } else if (key == "depth_units") {
      o.camera.output_units = value;
    } else if (key == "disparity_noise") {
      o.camera.disparity_noise_px = number();
    } else if (key == "disparity_step") {
      o.camera.disparity_step_px = number();
    } else if (key == "edge_jump") {
      o.camera.edge_jump_m = number();
    } else if (key == "min_cosine") {
      o.camera.min_incidence_cosine = o.laser.min_incidence_cosine = number();
    } else if (key == "noise") {
      o.laser.noise = number();
    } else if (key == "points") {
      o.laser.points_per_profile = integer();
    } else if (key == "camera_angle_deg") {
      o.laser.camera_angle_rad = number() * kDegree;
    } else if (key == "axis_tilt_deg") {
      o.turntable.axis_tilt_rad = number() * kDegree;
    } else if (key == "axis_azimuth_deg") {
      o.turntable.axis_tilt_azimuth_rad = number() * kDegree;
    } else if (key == "axis_offset_x") {
      o.turntable.axis_offset_x = number();
    } else if (key == "axis_offset_y") {
      o.turntable.axis_offset_y = number();
    } else if (key == "angle_noise_deg") {
      o.turntable.angle_noise_rad = number() * kDegree;
    } else if (key == "interval") {
      o.interval_s = number();
    } else if (key == "units") {
      mesh_units = value;
    } else {
      throw std::invalid_argument("unknown device option '" + key + "'");
    }
  }
  if (o.turntable.steps < 1) throw std::invalid_argument("device option 'steps' must be at least 1");
  return o;
}

std::unique_ptr<FrameSource> MakeVirtualScanner(SceneMesh scene, const VirtualScannerOptions& options) {
  return std::make_unique<VirtualScanner>(std::move(scene), options);
}

}  // namespace s2m
