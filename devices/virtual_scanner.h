#pragma once
// The virtual scanner (issue 5): a scene (a triangle mesh, or a fitting model tessellated into one) on a
// turntable, seen by a simulated sensor, producing the frames a real device would -- depth images with
// intrinsics from a Kinect-class camera, or laser profiles with turntable angles from a laser-line scanner --
// through the FrameSource interface, so its output can be recorded and replayed like a device's.
//
// Ray casting uses Open3D's t::geometry::RaycastingScene (Embree, single precision) to find which triangle a
// ray meets -- its CastRays, or, where that finds nothing (Debian's Open3D 0.16 build: docs/acquisition.md),
// sphere tracing on its closest-point queries; the hit is then recomputed in double precision: on the
// triangle's plane for a plain mesh, and by Newton's method on the exact surface for a tessellated model (ray
// S(u, v) = o + s d, started from the triangle's barycentric interpolation of its vertices' parameters).
// Zero-noise hits therefore lie on the model itself, not on its tessellation (tests/virtual_scanner_test.cpp:
// to 1e-9 relative). Open3D appears only in devices/open3d_ray_caster.cpp.
//
// Turntable convention: the world is the turntable's frame at angle 0 (z up the nominal axis, origin on the
// axis at the table's surface), in which the scene is placed. At turntable angle theta the table has turned
// the object by theta about its TRUE axis (the nominal one tilted and shifted by the configured axis error);
// the sensor is fixed. A frame's nominal pose is world_T_scan = Rz(-theta_nominal) * lab_T_sensor; the
// simulation uses the true axis and the true angle (nominal plus optional angle noise), so recorded poses are
// off exactly as a miscalibrated turntable's would be.

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "acquisition/frame_source.h"
#include "fitting/parametric_model.h"
#include "registration/rigid_motion.h"

namespace s2m {

// ------------------------------------------------------------------------------------------------ scenes

// A triangle mesh with, optionally, the exact surfaces its triangles approximate.
struct SceneMesh {
  Eigen::Matrix3Xd vertices;                        // scene units
  Eigen::Matrix<int, 3, Eigen::Dynamic> triangles;  // vertex indices, counter-clockwise seen from outside
  std::string units = "unknown";                    // of the vertices
  // Exact surfaces. triangle_patch[i] = -1: triangle i is itself the surface (plain mesh, a planar face);
  // otherwise an index into `patches`.
  struct Patch {
    enum class Type { kParametric, kCylinder } type = Type::kParametric;
    std::shared_ptr<const ParametricModel> model;          // kParametric: face 0 of this model
    Eigen::Vector3d axis_point = Eigen::Vector3d::Zero();  // kCylinder
    Eigen::Vector3d axis_direction = Eigen::Vector3d::UnitZ();
    double radius = 0.0;
  };
  std::vector<Patch> patches;
  std::vector<int> triangle_patch;     // empty (all -1) or one per triangle
  Eigen::Matrix2Xd vertex_parameters;  // (u, v) per vertex for kParametric triangles
};

// Face 0 of `model` over [u0, u1] x [v0, v1] as an nu x nv grid of quads, two triangles each, with the exact
// surface attached (every triangle refers to patch 0). Throws std::invalid_argument for a model that is not a
// surface in 3D or a grid smaller than 2 x 2.
SceneMesh TessellateSurface(std::shared_ptr<const ParametricModel> model, double u0, double u1, double v0,
                            double v1, int nu, int nv);

// The counterbored block of docs/examples/counterbored_block.part.json as a closed solid (part frame: bottom
// centre, z up the bore): values = width, depth, height, bore diameter, counterbore diameter, counterbore
// depth; the bore walls as `segments`-gon prisms refined to exact cylinders, the planar faces exact.
SceneMesh CounterboredBlockMesh(const Eigen::VectorXd& values, int segments = 128);

// A triangle mesh from a PLY file (Open3D's reader). Throws FormatError naming the file when it cannot be
// read or has no triangles.
SceneMesh ReadMeshPly(const std::filesystem::path& path, const std::string& units = "unknown");

// "vase", "helical", "spiral" (the true surfaces of synthetic/synthetic_cases.h, in mm, tessellated over
// their domains), "part" (CounterboredBlockMesh at 60 x 40 x 20, bore 10, counterbore 18 x 6 mm), or a .ply
// mesh path. Throws std::invalid_argument for an unknown name, FormatError for an unreadable file.
SceneMesh SceneByName(const std::string& name_or_mesh, const std::string& mesh_units = "mm");

// ---------------------------------------------------------------------------------------------- ray casting

struct RayHit {
  bool hit = false;
  double distance = 0.0;                            // along the unit direction, scene units
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  // on the exact surface (double precision)
  Eigen::Vector3d normal =
      Eigen::Vector3d::Zero();  // unit surface normal at the hit, facing the ray's origin
};

class RayCaster {
 public:
  explicit RayCaster(const SceneMesh& mesh);  // builds Open3D's acceleration structure once
  ~RayCaster();
  RayCaster(const RayCaster&) = delete;
  RayCaster& operator=(const RayCaster&) = delete;
  // One hit per ray; directions need not be unit (they are normalized). Rays whose refinement on an exact
  // surface does not converge (a ray grazing the surface's boundary) count as misses.
  std::vector<RayHit> Cast(const Eigen::Matrix3Xd& origins, const Eigen::Matrix3Xd& directions) const;
  // Whether each point is seen from `viewpoint` (nothing of the scene between them, up to `tolerance`).
  std::vector<bool> Visible(const Eigen::Matrix3Xd& points, const Eigen::Vector3d& viewpoint,
                            double tolerance) const;
  const SceneMesh& mesh() const { return mesh_; }

 private:
  struct Impl;
  SceneMesh mesh_;
  std::unique_ptr<Impl> impl_;
};

// ------------------------------------------------------------------------------------------ sensor models

// A Kinect-class structured-light camera. Depth is measured through the disparity d = f b / z (Khoshelham and
// Elberink, Sensors 12(2):1437, 2012, eq. 4-5): its noise sigma_d gives the range-dependent depth noise
// sigma_z = z^2 sigma_d / (f b) (their eq. 10), and the disparity's 1/8-pixel sub-pixel steps quantize the
// depth (steps growing with z^2). Raw values are stored like OpenNI's, in units of depth_unit_m.
struct DepthCameraOptions {
  int width = 640, height = 480;                          // pixels
  double fx = 525.0, fy = 525.0, cx = 319.5, cy = 239.5;  // pinhole, pixels (OpenNI's defaults)
  double depth_unit_m = 0.001;                            // metres per raw value (OpenNI: millimetres)
  double baseline_m = 0.075;                              // projector-camera baseline (Kinect v1: 7.5 cm)
  double disparity_step_px = 1.0 / 8.0;                   // disparity quantization; 0: off
  // Disparity noise, pixels: 0.06 gives sigma_z = 1.5 mm at 1 m and 3.8 cm at 5 m (K&E 2012 report about 4 cm
  // at 5 m). 0: noise off.
  double disparity_noise_px = 0.06;
  double min_range_m = 0.4, max_range_m = 4.5;  // no return outside
  // Dropout at grazing angles: no return where the ray meets the surface at a cosine below this (75 degrees).
  double min_incidence_cosine = 0.26;
  // Dropout at depth edges: no return where a 4-neighbour's true depth differs by more than this, or the
  // neighbour has no return (the projected pattern breaks up across a depth discontinuity). 0: off.
  double edge_jump_m = 0.02;
  // Units of the depth stream's points and of the poses: "m" (OpenNI's convention) or "mm" (the raw values'
  // scale is then depth_unit_m * 1000 mm per raw value; the measurement itself is the same).
  std::string output_units = "m";
};

// A laser-line scanner on a turntable (Horus/Ciclop-like): a vertical laser fan, a camera beside the laser
// that must also see the lit point (triangulation occlusion), one profile per turntable step.
struct LaserLineOptions {
  int points_per_profile = 480;       // rays in the fan (the camera's rows)
  double noise = 0.02;                // standard deviation along the ray, scene units; 0: off
  double camera_angle_rad = 0.5236;   // the camera's line of sight 30 degrees from the laser's (about z)
  double min_incidence_cosine = 0.1;  // no return at more grazing incidence
};

struct TurntableOptions {
  int steps = 8;  // depth camera: stops (one frame and one view each); laser: profiles per turn
  double start_angle_rad = 0.0;
  double axis_tilt_rad = 0.0;                       // true axis tilted from the nominal z by this
  double axis_tilt_azimuth_rad = 0.0;               // ... towards this direction in the table plane
  double axis_offset_x = 0.0, axis_offset_y = 0.0;  // true axis shifted, scene units
  double angle_noise_rad = 0.0;  // standard deviation of each step's true angle about its nominal one
};

struct VirtualScannerOptions {
  enum class Sensor { kDepthCamera, kLaserLine };
  Sensor sensor = Sensor::kDepthCamera;
  DepthCameraOptions camera;
  LaserLineOptions laser;
  TurntableOptions turntable;
  // Sensor placement in the lab: looking at `target_height` on the nominal axis from `distance` away (scene
  // units), each of `elevations_rad` above the horizontal. distance 0: 0.7 m for the depth camera, 3 x the
  // scene's radius for the laser; target_height NaN: the scene's mid-height.
  double distance = 0.0;
  // One sweep per elevation (a full turn each; the depth camera's frames are views of their own, a laser
  // sweep is one view). No table is simulated: a negative elevation looks from below, as if the part had been
  // turned over and put back at the same place.
  std::vector<double> elevations_rad = {0.3491};  // 20 degrees
  double target_height = std::numeric_limits<double>::quiet_NaN();
  double metres_per_unit = 0.001;  // scene units to metres (the depth camera works in metres)
  std::int64_t start_time_ns = 1700000000000000000;  // timestamps: start + k * interval
  double interval_s = 0.5;
  std::uint64_t seed = 1;
  std::string name = "virtual";  // the device's name in the description ("virtual:<scene>")
};

// "virtual:<scene>[,key=value...]" as given to `scan2model record --device`: keys sensor=kinect|laser, steps,
// seed, distance, elevation_deg (several: 30:-30), target_height, width, height, fx, fy, cx, cy, depth_unit,
// depth_units (m or mm), disparity_noise, disparity_step, edge_jump, min_cosine, noise (laser), points
// (laser), camera_angle_deg, axis_tilt_deg, axis_azimuth_deg, axis_offset_x, axis_offset_y, angle_noise_deg,
// interval, units (of a mesh). Fills `scene` with the part before the first comma (after "virtual:"). Throws
// std::invalid_argument naming the bad key or value.
VirtualScannerOptions ParseVirtualDevice(const std::string& spec, std::string& scene,
                                         std::string& mesh_units);

// The virtual scanner as a frame source. Deterministic: the same scene, options and seed give the same
// frames, bit for bit (each frame's random numbers come from its own generator seeded by (seed, frame)).
std::unique_ptr<FrameSource> MakeVirtualScanner(SceneMesh scene, const VirtualScannerOptions& options);

}  // namespace s2m
