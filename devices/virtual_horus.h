#pragma once
// The virtual Horus rig (issue 6): a turntable board and a camera rendering what a Ciclop-style scanner's
// camera would see -- the laser lines on a model (ray cast on its exact surface with
// devices/virtual_scanner.h's RayCaster) or a chessboard standing on the platform (analytic, supersampled) --
// with the calibration that is true by construction, so the whole image -> points path and the calibration
// procedures have ground truth.
//
// Rendering. The scene turns with the table: at angle theta an object point p is at Rz(theta) p in the
// platform frame (HorusCalibration's convention). A laser is a fan of rays from its emitter in its plane;
// each ray's first hit on the scene is the lit point (so it is visible from the laser), kept when the camera
// sees it too (nothing in between, the surface facing the camera). The lit points, projected with the
// camera's intrinsics and distortion, form a polyline whose crossing with each pixel row is the stripe's true
// centre there; the stripe is drawn on the red channel with a Gaussian profile across the row (width
// stripe_sigma_px) on a dim background with Gaussian sensor noise. The stripe's brightness ignores the
// surface's albedo and slope.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "devices/horus_calibration.h"
#include "devices/horus_interfaces.h"
#include "devices/virtual_scanner.h"

namespace s2m {

struct VirtualHorusOptions {
  // Camera: a Ciclop's Logitech C270 halved (1280 x 960, fx about 1430 px, in Horus's default calibration).
  int width = 640, height = 480;
  double fx = 715.0, fy = 715.0;
  double cx = std::numeric_limits<double>::quiet_NaN(),
         cy = std::numeric_limits<double>::quiet_NaN();  // NaN: centre
  std::array<double, 5> distortion = {0, 0, 0, 0, 0};
  // Placement (platform frame, mm): camera at (0, -camera_distance, camera_height) looking at the axis at
  // target_height, its x axis horizontal (so platform x is the camera's x projected, as the calibration
  // defines).
  double camera_distance = 300.0, camera_height = 120.0, target_height = 75.0;
  // Lasers: emitters at the camera's distance and height, turned by -laser_angle_deg (laser 0, left) and
  // +laser_angle_deg (laser 1) about the axis, aimed at the axis at target_height; each plane contains the
  // vertical, then is shifted by laser_offset (mm, along its normal) and tilted by laser_tilt_deg about its
  // aim line, so that a calibration must find planes that miss the axis.
  double laser_angle_deg = 30.0;
  double laser_offset = 1.5, laser_tilt_deg = 1.0;
  int fan_rays = 4000;  // rays per laser fan over +-fan_half_angle_deg
  double fan_half_angle_deg = 40.0;
  // Images.
  double stripe_sigma_px = 1.5;  // the stripe's Gaussian profile across a row
  double stripe_peak = 180.0;    // grey levels added to the red channel at the stripe's centre
  double background = 25.0;      // the dim scene without a pattern
  double noise = 1.0;            // sensor noise, grey levels (standard deviation); 0: off
  int supersampling = 4;         // per axis, for the pattern's anti-aliasing
  double blur_sigma_px = 0.7;    // the lens's point spread (Gaussian) on the pattern image; 0: none
  std::uint64_t seed = 1;
};

// The true calibration of a rig with these options (two lasers).
HorusCalibration VirtualHorusTruth(const VirtualHorusOptions& options);

// The rig's shared state: the board and the camera of MakeVirtualHorus act on it.
class VirtualHorusRig {
 public:
  VirtualHorusRig(SceneMesh scene, const VirtualHorusOptions& options);
  ~VirtualHorusRig();
  const HorusCalibration& truth() const { return truth_; }
  const VirtualHorusOptions& options() const { return options_; }
  double angle_rad() const { return angle_rad_; }
  void set_angle_rad(double a) { angle_rad_ = a; }
  bool laser(int l) const { return lasers_on_.at(static_cast<std::size_t>(l)); }
  void set_laser(int l, bool on);
  // A chessboard in place of the model (as a user puts the pattern on the platform): its pose at turntable
  // angle 0; it turns with the table. nullopt: the model again.
  void PlacePattern(const ChessboardPattern& pattern, std::optional<RigidMotion> platform_T_pattern);
  // The calibration pattern standing upright on the platform facing the camera, its plane `offset` mm in
  // front of the axis (so a laser line moves across it as the table turns), its lowest corner row at the
  // pattern's bottom_row_height.
  static RigidMotion StandingPatternPose(const ChessboardPattern& pattern, double offset = 30.0);
  // Poses for intrinsics calibration: the pattern held in front of the camera, tilted up to about 25 degrees.
  std::vector<RigidMotion> HandHeldPatternPoses(const ChessboardPattern& pattern, int count) const;

  // The current image (3 channels, BGR).
  Image8 Render();
  // Where laser l's stripe truly is in the current state: its centre in each pixel row it crosses (x =
  // column, y = row) and the lit surface point there, in the object frame (the platform frame at angle 0).
  struct Stripe {
    std::vector<Eigen::Vector2d> pixels;
    std::vector<Eigen::Vector3d> object_points;
  };
  Stripe TrueStripe(int laser) const;
  const RayCaster& caster() const { return *caster_; }

 private:
  VirtualHorusOptions options_;
  HorusCalibration truth_;
  std::unique_ptr<RayCaster> caster_;
  std::vector<Eigen::Vector3d> emitters_;  // platform frame
  double angle_rad_ = 0.0;
  std::vector<bool> lasers_on_;
  std::optional<ChessboardPattern> pattern_;
  RigidMotion platform_T_pattern_;
  std::uint64_t frames_ = 0;
};

struct VirtualHorus {
  std::unique_ptr<TurntableBoard> board;
  std::unique_ptr<ImageCamera> camera;
  HorusCalibration truth;
  std::shared_ptr<VirtualHorusRig> rig;  // the scene behind both (place the pattern, read the truth)
};

// "horus-virtual:<scene>[,key=value...]" or "<scene>[,key=value...]": scene as SceneByName takes it; keys
// width, height, fx, fy, cx, cy, k1, k2, p1, p2, k3, distance (camera_distance), camera_height,
// target_height, laser_angle_deg, laser_offset, laser_tilt_deg, fan_rays, stripe_sigma, stripe_peak,
// background, noise, supersampling, blur, seed, units (of a mesh). Throws std::invalid_argument naming the
// bad key or value.
VirtualHorusOptions ParseVirtualHorus(const std::string& spec, std::string& scene, std::string& mesh_units);
VirtualHorus MakeVirtualHorus(const std::string& spec);

}  // namespace s2m
