// The virtual Horus rig: devices/virtual_horus.h.

#include "devices/virtual_horus.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <random>
#include <sstream>
#include <stdexcept>

#include "devices/device_options.h"
#include "devices/laser_line.h"

namespace s2m {
namespace {

constexpr double kDegree = M_PI / 180.0;

Eigen::Matrix3d Rz(double a) {
  return RotationAboutAxis(Eigen::Vector3d::UnitZ(), a);
}

// Camera at `eye` looking at `target`, x horizontal: platform_T_camera (OpenCV's camera axes: x right, y
// down, z forward).
RigidMotion LookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
  const Eigen::Vector3d z = (target - eye).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d r;
  r << x, y, z;
  return {r, eye};
}

struct LaserGeometry {
  Eigen::Vector3d emitter, normal, aim;  // platform frame; the plane through the emitter with this normal
};

std::vector<LaserGeometry> Lasers(const VirtualHorusOptions& o) {
  std::vector<LaserGeometry> lasers;
  for (const double sign : {-1.0, 1.0}) {
    LaserGeometry l;
    l.emitter =
        Rz(sign * o.laser_angle_deg * kDegree) * Eigen::Vector3d(0, -o.camera_distance, o.camera_height);
    l.aim = Eigen::Vector3d(0, 0, o.target_height);
    const Eigen::Vector3d along = (l.aim - l.emitter).normalized();
    Eigen::Vector3d n = Eigen::Vector3d::UnitZ().cross(along).normalized();
    n = RotationAboutAxis(along, o.laser_tilt_deg * kDegree) * n;
    l.emitter += o.laser_offset * n;
    l.aim += o.laser_offset * n;
    l.normal = n;
    lasers.push_back(l);
  }
  return lasers;
}

// Separable Gaussian blur, in place, edges clamped.
void Blur(std::vector<float>& image, int width, int height, double sigma) {
  const int reach = static_cast<int>(std::ceil(3 * sigma));
  std::vector<float> kernel;
  float total = 0;
  for (int i = -reach; i <= reach; ++i) {
    kernel.push_back(static_cast<float>(std::exp(-i * i / (2 * sigma * sigma))));
    total += kernel.back();
  }
  for (float& k : kernel) k /= total;
  std::vector<float> tmp(image.size());
  for (int r = 0; r < height; ++r)
    for (int c = 0; c < width; ++c) {
      float s = 0;
      for (int i = -reach; i <= reach; ++i)
        s += kernel[static_cast<std::size_t>(i + reach)] *
             image[static_cast<std::size_t>(r) * width + std::clamp(c + i, 0, width - 1)];
      tmp[static_cast<std::size_t>(r) * width + c] = s;
    }
  for (int r = 0; r < height; ++r)
    for (int c = 0; c < width; ++c) {
      float s = 0;
      for (int i = -reach; i <= reach; ++i)
        s += kernel[static_cast<std::size_t>(i + reach)] *
             tmp[static_cast<std::size_t>(std::clamp(r + i, 0, height - 1)) * width + c];
      image[static_cast<std::size_t>(r) * width + c] = s;
    }
}

class VirtualBoard : public TurntableBoard {
 public:
  explicit VirtualBoard(std::shared_ptr<VirtualHorusRig> rig) : rig_(std::move(rig)) {}
  std::string Banner() const override { return "Horus 0.1 ['$' for help]"; }
  void EnableMotor(bool on) override { motor_ = on; }
  void SetFeedRate(double) override {}
  void SetAcceleration(double) override {}
  void MoveTo(double degrees) override {
    if (!motor_)
      throw DeviceError(DeviceError::Kind::kProtocol, "virtual Horus: MoveTo with the motor disabled (M17)");
    rig_->set_angle_rad(degrees * kDegree);
  }
  void SetLaser(int laser, bool on) override {
    if (laser < 0 || laser > 1)
      throw DeviceError(DeviceError::Kind::kProtocol, "virtual Horus: no laser " + std::to_string(laser));
    rig_->set_laser(laser, on);
  }
  int ReadLightSensor(int) override { return 512; }
  void Reset() override {
    rig_->set_angle_rad(0.0);
    rig_->set_laser(0, false);
    rig_->set_laser(1, false);
    motor_ = false;
  }

 private:
  std::shared_ptr<VirtualHorusRig> rig_;
  bool motor_ = false;
};

class VirtualCamera : public ImageCamera {
 public:
  explicit VirtualCamera(std::shared_ptr<VirtualHorusRig> rig) : rig_(std::move(rig)) {}
  std::string Name() const override { return "horus-virtual camera"; }
  Image8 Capture() override { return rig_->Render(); }

 private:
  std::shared_ptr<VirtualHorusRig> rig_;
};

}  // namespace

HorusCalibration VirtualHorusTruth(const VirtualHorusOptions& o) {
  HorusCalibration c;
  c.camera.width = o.width;
  c.camera.height = o.height;
  c.camera.fx = o.fx;
  c.camera.fy = o.fy;
  c.camera.cx = std::isnan(o.cx) ? (o.width - 1) / 2.0 : o.cx;
  c.camera.cy = std::isnan(o.cy) ? (o.height - 1) / 2.0 : o.cy;
  c.camera.distortion = o.distortion;
  c.platform_T_camera =
      LookAt(Eigen::Vector3d(0, -o.camera_distance, o.camera_height), Eigen::Vector3d(0, 0, o.target_height));
  const RigidMotion camera_T_platform = c.platform_T_camera.inverse();
  for (const LaserGeometry& l : Lasers(o)) {
    LaserPlane p;
    p.normal = camera_T_platform.rotation() * l.normal;
    p.distance = p.normal.dot(camera_T_platform * l.emitter);
    if (p.distance < 0) p.normal = -p.normal, p.distance = -p.distance;
    c.lasers.push_back(p);
  }
  return c;
}

VirtualHorusRig::VirtualHorusRig(SceneMesh scene, const VirtualHorusOptions& options)
    : options_(options), truth_(VirtualHorusTruth(options)), lasers_on_(2, false) {
  if (options_.width < 8 || options_.height < 8 || options_.fx <= 0 || options_.fy <= 0)
    throw std::invalid_argument("virtual Horus: the image must be at least 8 x 8 pixels and fx, fy positive");
  if (options_.fan_rays < 2 || options_.supersampling < 1 || options_.stripe_sigma_px <= 0)
    throw std::invalid_argument(
        "virtual Horus: fan_rays >= 2, supersampling >= 1 and stripe_sigma > 0 are needed");
  caster_ = std::make_unique<RayCaster>(scene);
  for (const LaserGeometry& l : Lasers(options_)) emitters_.push_back(l.emitter);
}

VirtualHorusRig::~VirtualHorusRig() = default;

void VirtualHorusRig::set_laser(int l, bool on) {
  lasers_on_.at(static_cast<std::size_t>(l)) = on;
}

void VirtualHorusRig::PlacePattern(const ChessboardPattern& pattern,
                                   std::optional<RigidMotion> platform_T_pattern) {
  if (!platform_T_pattern) {
    pattern_.reset();
    return;
  }
  pattern_ = pattern;
  platform_T_pattern_ = *platform_T_pattern;
}

RigidMotion VirtualHorusRig::StandingPatternPose(const ChessboardPattern& pattern, double offset) {
  Eigen::Matrix3d r;
  r << Eigen::Vector3d::UnitX(), -Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitY();
  const Eigen::Vector3d first(-(pattern.columns - 1) / 2.0 * pattern.square, -offset,
                              pattern.bottom_row_height + (pattern.rows - 1) * pattern.square);
  return {r, first};
}

std::vector<RigidMotion> VirtualHorusRig::HandHeldPatternPoses(const ChessboardPattern& pattern,
                                                               int count) const {
  std::vector<RigidMotion> poses;
  const Eigen::Vector3d centre((pattern.columns - 1) / 2.0 * pattern.square,
                               (pattern.rows - 1) / 2.0 * pattern.square, 0.0);
  for (int k = 0; k < count; ++k) {
    // Tilts about the camera's x and y axes on a spiral, distances 280..360 mm, the centre off the optical
    // axis.
    const double phase = 2 * M_PI * k / std::max(count, 1);
    const double tilt = (k % 2 == 0 ? 25.0 : 15.0) * kDegree;
    const Eigen::Matrix3d r = RotationAboutAxis(Eigen::Vector3d::UnitX(), tilt * std::cos(phase)) *
                              RotationAboutAxis(Eigen::Vector3d::UnitY(), tilt * std::sin(phase)) *
                              RotationAboutAxis(Eigen::Vector3d::UnitZ(), 0.1 * std::sin(2 * phase));
    const double z = 300.0 + 40.0 * std::cos(3 * phase);
    const Eigen::Vector3d at(25.0 * std::sin(phase), 15.0 * std::cos(phase), z);
    const RigidMotion camera_T_pattern(r, at - r * centre);
    poses.push_back(truth_.platform_T_camera * camera_T_pattern);
  }
  return poses;
}

VirtualHorusRig::Stripe VirtualHorusRig::TrueStripe(int laser) const {
  const VirtualHorusOptions& o = options_;
  const LaserGeometry geometry = Lasers(o).at(static_cast<std::size_t>(laser));
  // The fan in the object frame (the scene turned by angle: platform = Rz(angle) object).
  const Eigen::Matrix3d object_R_platform = Rz(-angle_rad_);
  const Eigen::Vector3d along = (geometry.aim - geometry.emitter).normalized();
  const Eigen::Vector3d up = geometry.normal.cross(along).normalized();
  const auto n = static_cast<Eigen::Index>(o.fan_rays);
  Eigen::Matrix3Xd origins(3, n), directions(3, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const double phi =
        o.fan_half_angle_deg * kDegree * (2.0 * static_cast<double>(i) / static_cast<double>(n - 1) - 1);
    origins.col(i) = object_R_platform * geometry.emitter;
    directions.col(i) = object_R_platform * (std::cos(phi) * along + std::sin(phi) * up);
  }
  const RigidMotion camera_T_platform = truth_.platform_T_camera.inverse();
  const Eigen::Vector3d camera_object = object_R_platform * truth_.platform_T_camera.translation();
  std::vector<bool> valid(static_cast<std::size_t>(n), false);
  Eigen::Matrix3Xd points(3, n);
  if (pattern_) {
    // The board: the plane z = 0 of the pattern's frame, within its squares and a one-square white margin.
    // The pattern turns with the table: fixed in the object frame.
    const RigidMotion object_T_pattern = platform_T_pattern_;
    const RigidMotion pattern_T_object = object_T_pattern.inverse();
    const double s = pattern_->square;
    for (Eigen::Index i = 0; i < n; ++i) {
      const Eigen::Vector3d po = pattern_T_object * Eigen::Vector3d(origins.col(i));
      const Eigen::Vector3d pd = pattern_T_object.rotation() * directions.col(i);
      if (std::abs(pd.z()) < 1e-12) continue;
      const double t = -po.z() / pd.z();
      if (t <= 0) continue;
      const Eigen::Vector3d x = po + t * pd;
      if (x.x() < -2 * s || x.x() > (pattern_->columns + 1) * s || x.y() < -2 * s ||
          x.y() > (pattern_->rows + 1) * s)
        continue;
      const Eigen::Vector3d c = pattern_T_object * camera_object;
      if (c.z() * po.z() <= 0) continue;  // the camera sees the board's other side
      points.col(i) = object_T_pattern * x;
      valid[static_cast<std::size_t>(i)] = true;
    }
  } else {
    const std::vector<RayHit> hits = caster_->Cast(origins, directions);
    for (Eigen::Index i = 0; i < n; ++i) {
      const RayHit& h = hits[static_cast<std::size_t>(i)];
      if (!h.hit || h.normal.dot(camera_object - h.point) <= 0) continue;
      points.col(i) = h.point;
      valid[static_cast<std::size_t>(i)] = true;
    }
    const std::vector<bool> seen = caster_->Visible(points, camera_object, 1e-3);
    for (Eigen::Index i = 0; i < n; ++i)
      valid[static_cast<std::size_t>(i)] =
          valid[static_cast<std::size_t>(i)] && seen[static_cast<std::size_t>(i)];
  }
  // Project, and cut the polyline at each pixel row between neighbouring lit points (a gap: not neighbours).
  const double gap =
      4.0 * o.camera_distance * (2 * o.fan_half_angle_deg * kDegree) / static_cast<double>(n - 1) + 1.0;
  Stripe stripe;
  std::vector<Eigen::Vector2d> pixel(static_cast<std::size_t>(n));
  for (Eigen::Index i = 0; i < n; ++i)
    if (valid[static_cast<std::size_t>(i)]) {
      const Eigen::Vector3d c = camera_T_platform * (Rz(angle_rad_) * points.col(i));
      if (c.z() <= 1e-6) {
        valid[static_cast<std::size_t>(i)] = false;
        continue;
      }
      pixel[static_cast<std::size_t>(i)] = ProjectToPixel(truth_.camera, c);
    }
  for (Eigen::Index i = 0; i + 1 < n; ++i) {
    const auto a = static_cast<std::size_t>(i), b = a + 1;
    if (!valid[a] || !valid[b] || (points.col(i) - points.col(i + 1)).norm() > gap) continue;
    const Eigen::Vector2d p = pixel[a], q = pixel[b];
    if (p.y() == q.y()) continue;
    const double lo = std::min(p.y(), q.y()), hi = std::max(p.y(), q.y());
    for (int row = static_cast<int>(std::ceil(lo)); row < hi; ++row) {
      if (row < 0 || row >= o.height) continue;
      const double t = (row - p.y()) / (q.y() - p.y());
      stripe.pixels.emplace_back(p.x() + t * (q.x() - p.x()), row);
      stripe.object_points.push_back(points.col(i) + t * (points.col(i + 1) - points.col(i)));
    }
  }
  return stripe;
}

Image8 VirtualHorusRig::Render() {
  const VirtualHorusOptions& o = options_;
  Image8 image;
  image.width = o.width;
  image.height = o.height;
  image.channels = 3;
  std::vector<float> grey(static_cast<std::size_t>(o.width) * o.height, static_cast<float>(o.background));
  if (pattern_) {
    const RigidMotion camera_T_pattern = truth_.platform_T_camera.inverse() *
                                         RigidMotion(Rz(angle_rad_), Eigen::Vector3d::Zero()) *
                                         platform_T_pattern_;
    // The board's plane z = 0 seen through the pinhole is a homography: a normalized ray (x, y, 1) is
    // parallel to [r1 r2 t] (X, Y, 1), so (X, Y, 1) ~ G (x, y, 1) with G = [r1 r2 t]^-1, in front of the
    // camera where the third component is positive (Hartley and Zisserman, section 8.1.1).
    Eigen::Matrix3d plane;
    plane << camera_T_pattern.rotation().col(0), camera_T_pattern.rotation().col(1),
        camera_T_pattern.translation();
    const Eigen::Matrix3d G = plane.inverse();
    const bool distorted =
        std::any_of(o.distortion.begin(), o.distortion.end(), [](double d) { return d != 0; });
    const double s = pattern_->square;
    const int ss = o.supersampling;
    const double columns = pattern_->columns, rows = pattern_->rows;
    const CameraIntrinsics& k = truth_.camera;
    auto albedo = [&](double x, double y) {
      const Eigen::Vector3d r = distorted ? PixelRay(k, Eigen::Vector2d(x, y))
                                          : Eigen::Vector3d((x - k.cx) / k.fx, (y - k.cy) / k.fy, 1.0);
      const Eigen::Vector3d h = G * r;
      if (h.z() <= 1e-12) return o.background;
      const double i = std::floor(h.x() / h.z() / s), j = std::floor(h.y() / h.z() / s);
      if (i >= -1 && i < columns && j >= -1 && j < rows)
        return (static_cast<long>(i + j) % 2 == 0) ? 30.0 : 200.0;
      if (i >= -2 && i < columns + 1 && j >= -2 && j < rows + 1) return 200.0;  // the white margin
      return o.background;
    };
    // The albedo at the pixels' corners; a pixel is supersampled only where the corners of its 3 x 3
    // neighbourhood differ (an edge or a square's tip may cross it; squares are many pixels wide).
    const int W = o.width + 1, H = o.height + 1;
    std::vector<double> corner(static_cast<std::size_t>(W) * H);
    for (int row = 0; row < H; ++row)
      for (int col = 0; col < W; ++col)
        corner[static_cast<std::size_t>(row) * W + col] = albedo(col - 0.5, row - 0.5);
    for (int row = 0; row < o.height; ++row)
      for (int col = 0; col < o.width; ++col) {
        const double first = corner[static_cast<std::size_t>(row) * W + col];
        bool uniform = true;
        for (int r = std::max(0, row - 1); r <= std::min(H - 1, row + 2) && uniform; ++r)
          for (int c = std::max(0, col - 1); c <= std::min(W - 1, col + 2); ++c)
            if (corner[static_cast<std::size_t>(r) * W + c] != first) {
              uniform = false;
              break;
            }
        double value = first;
        if (!uniform) {
          double sum = 0;
          for (int a = 0; a < ss; ++a)
            for (int b = 0; b < ss; ++b)
              sum += albedo(col - 0.5 + (b + 0.5) / ss, row - 0.5 + (a + 0.5) / ss);
          value = sum / (ss * ss);
        }
        grey[static_cast<std::size_t>(row) * o.width + col] = static_cast<float>(value);
      }
    // The lens's blur (a Gaussian point spread function): smooths the supersampling's coverage steps, which
    // otherwise bias cv::cornerSubPix by about 0.1 px (measured).
    if (o.blur_sigma_px > 0) Blur(grey, o.width, o.height, o.blur_sigma_px);
  }
  std::vector<float> red = grey;
  for (int l = 0; l < 2; ++l) {
    if (!lasers_on_[static_cast<std::size_t>(l)]) continue;
    const Stripe stripe = TrueStripe(l);
    const double sigma = o.stripe_sigma_px;
    const int reach = static_cast<int>(std::ceil(4 * sigma));
    for (const Eigen::Vector2d& p : stripe.pixels) {
      const int row = static_cast<int>(p.y());
      const int c0 = static_cast<int>(std::lround(p.x()));
      for (int c = std::max(0, c0 - reach); c <= std::min(o.width - 1, c0 + reach); ++c) {
        const double d = c - p.x();
        red[static_cast<std::size_t>(row) * o.width + c] +=
            static_cast<float>(o.stripe_peak * std::exp(-d * d / (2 * sigma * sigma)));
      }
    }
  }
  std::mt19937_64 rng(o.seed * 1000003ULL + frames_++);
  std::normal_distribution<float> noise(0.0f, static_cast<float>(o.noise));
  image.pixels.resize(static_cast<std::size_t>(o.width) * o.height * 3);
  auto quantize = [](float v) { return static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L)); };
  for (std::size_t i = 0; i < grey.size(); ++i) {
    const float n = o.noise > 0 ? noise(rng) : 0.0f;
    const float g = grey[i] + n;
    // The red laser spills a little into green and blue, as a webcam's Bayer filter lets it.
    const float spill = 0.15f * (red[i] - grey[i]);
    image.pixels[3 * i + 0] = quantize(g + spill);
    image.pixels[3 * i + 1] = quantize(g + spill);
    image.pixels[3 * i + 2] = quantize(red[i] + n);
  }
  return image;
}

VirtualHorusOptions ParseVirtualHorus(const std::string& spec, std::string& scene, std::string& mesh_units) {
  std::string body = spec;
  const std::string prefix = "horus-virtual:";
  if (body.rfind(prefix, 0) == 0) body = body.substr(prefix.size());
  const DeviceOptionList device = SplitDeviceOptions(
      body, "device '" + spec + "': no scene given (horus-virtual:<scene>[,key=value...])");
  scene = device.scene;
  mesh_units = "mm";
  VirtualHorusOptions o;
  for (const auto& option : device.options) {
    // Named references, not structured bindings: lambdas may capture bindings only from C++20 (clang 14,
    // Debian 12's, refuses them).
    const std::string& key = option.first;
    const std::string& value = option.second;
    auto number = [&]() { return DeviceOptionNumber(key, value); };
    auto integer = [&]() { return DeviceOptionInteger(key, value, 1, 1000000); };
    const std::map<std::string, double*> numbers = {{"fx", &o.fx},
                                                    {"fy", &o.fy},
                                                    {"cx", &o.cx},
                                                    {"cy", &o.cy},
                                                    {"k1", &o.distortion[0]},
                                                    {"k2", &o.distortion[1]},
                                                    {"p1", &o.distortion[2]},
                                                    {"p2", &o.distortion[3]},
                                                    {"k3", &o.distortion[4]},
                                                    {"distance", &o.camera_distance},
                                                    {"camera_height", &o.camera_height},
                                                    {"target_height", &o.target_height},
                                                    {"laser_angle_deg", &o.laser_angle_deg},
                                                    {"laser_offset", &o.laser_offset},
                                                    {"laser_tilt_deg", &o.laser_tilt_deg},
                                                    {"stripe_sigma", &o.stripe_sigma_px},
                                                    {"stripe_peak", &o.stripe_peak},
                                                    {"background", &o.background},
                                                    {"noise", &o.noise},
                                                    {"blur", &o.blur_sigma_px}};
    if (auto it = numbers.find(key); it != numbers.end()) {
      *it->second = number();
    } else if (key == "width") {
      o.width = integer();
    } else if (key == "height") {
      o.height = integer();
    } else if (key == "fan_rays") {
      o.fan_rays = integer();
    } else if (key == "supersampling") {
      o.supersampling = integer();
    } else if (key == "seed") {
      o.seed = static_cast<std::uint64_t>(integer());
    } else if (key == "units") {
      mesh_units = value;
    } else {
      throw std::invalid_argument("unknown device option '" + key +
                                  "' for horus-virtual (docs/laser-scanning.md)");
    }
  }
  return o;
}

VirtualHorus MakeVirtualHorus(const std::string& spec) {
  std::string scene, units;
  const VirtualHorusOptions options = ParseVirtualHorus(spec, scene, units);
  VirtualHorus v;
  v.rig = std::make_shared<VirtualHorusRig>(SceneByName(scene, units), options);
  v.truth = v.rig->truth();
  v.board = std::make_unique<VirtualBoard>(v.rig);
  v.camera = std::make_unique<VirtualCamera>(v.rig);
  return v;
}

}  // namespace s2m
