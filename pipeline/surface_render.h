#pragma once
// A small software renderer for surface interrogation (docs/interrogation.md): a fitted surface sampled over
// its parameter domain into a triangle grid, projected orthographically along a view direction (or in
// perspective from an eye point) with a depth buffer, and every pixel it covers traced back to its exact
// parameters (u, v) (the grid's barycentric (u, v), refined by Newton until the exact surface point projects
// onto the pixel's centre); the pixel's colour then comes from the exact derivatives there
// (fitting/surface_interrogation.h): Lambert shading, a curvature map with a colour bar, isophotes, Klass
// reflection lines, zebra stripes or contours. No GPU, no image library: the image is written by
// pipeline/png.h.

#include <Eigen/Core>
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "fitting/parametric_model.h"
#include "fitting/surface_interrogation.h"
#include "pipeline/png.h"
#include "registration/rigid_motion.h"

namespace s2m::pipeline {

// What colours the surface.
enum class SurfaceColouring { kShading, kCurvature, kIsophotes, kReflectionLines, kZebra, kContours };
std::string ToString(SurfaceColouring colouring);

struct SurfaceRenderOptions {
  int width = 640, height = 480;  // pixels, the colour bar's strip included
  // The direction the camera looks along (from the eye towards the surface) and the direction that is up in
  // the image (projected onto the image plane), both in the surface's world frame.
  Eigen::Vector3d view = Eigen::Vector3d(0, 0, -1);
  Eigen::Vector3d up = Eigen::Vector3d::UnitY();
  // Set: a perspective view from this eye point (the whole surface must lie in front of it), which is also
  // the reflection lines' eye; unset: an orthographic view.
  std::optional<Eigen::Vector3d> eye;
  // Towards the light: Lambert shading and the isophotes' L.
  Eigen::Vector3d light = Eigen::Vector3d(0.3, 0.4, 1.0).normalized();
  // Grid cells per parameter direction (the triangles that find each pixel's surface point; the pixel's
  // values come from the exact surface, not from the grid).
  int grid = 192;
  SurfaceColouring colouring = SurfaceColouring::kShading;
  CurvatureKind curvature = CurvatureKind::kGaussian;
  // The curvature map's colour range [lo, hi] (white at the middle); unset: symmetric, +- the 99th
  // percentile of |value| over the pixels, so that the few pixels next to a singular point do not flatten
  // the scale (values beyond the range take the end colours).
  std::optional<std::array<double, 2>> range;
  // Isophotes: lines of N.L = cos(angle) for each angle (degrees between the normal and the light).
  std::vector<double> isophote_angles_deg = {20, 40, 60, 80, 100, 120, 140, 160};
  // Reflection lines and zebra stripes: `lines` lights (or stripes) evenly spread over a window of the light
  // plane 4 bounding radii of the surface wide, centred on the plane's origin (offsets -2 R to 2 R). Unset
  // light plane: perpendicular to `light` at 2 R from the surface's centre on the light's side, lines along
  // the image's horizontal, the eye at 3 R from the centre against the view direction.
  int lines = 12;
  std::optional<LightPlane> light_plane;
  // Contours: `lines` levels of the height along `contour_direction` (unset: the image's up) spread evenly
  // over the visible surface's heights.
  std::optional<Eigen::Vector3d> contour_direction;
  bool IsValid(std::string* why) const;
};

// Every pixel the surface covers, traced back to the surface.
struct SurfacePixel {
  bool seen = false;
  bool exact = false;  // Newton placed the exact surface point on the pixel's centre (else the grid's guess)
  bool line = false;   // drawn as an isophote, reflection line or contour
  double u = 0.0, v = 0.0;
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  // Unit normal turned towards the viewer (isophotes and shading use it; NaN at singular points).
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  // The scalar the colouring shows (curvature, N.L, reflection offset, height; NaN where undefined).
  double value = 0.0;
};

struct SurfaceRendering {
  RgbImage image;
  std::vector<SurfacePixel> pixels;  // row-major, image.width * image.height
  // The projection: pixel coordinates (x right, y down, centres at integer + 0.5) of a point, pixel = (x0 +
  // scale X, y0 - scale Y) with the image-plane coordinates (X, Y) = ImagePlane(p).
  Eigen::Vector3d right = Eigen::Vector3d::UnitX(), up = Eigen::Vector3d::UnitY(),
                  forward = -Eigen::Vector3d::UnitZ();
  std::optional<Eigen::Vector3d> eye;  // perspective: (X, Y) = (right.q, up.q) / forward.q, q = p - eye
  double scale = 1.0, x0 = 0.0, y0 = 0.0;
  Eigen::Vector2d ImagePlane(const Eigen::Vector3d& p) const {
    if (!eye) return {right.dot(p), up.dot(p)};
    const Eigen::Vector3d q = p - *eye;
    return Eigen::Vector2d(right.dot(q), up.dot(q)) / forward.dot(q);
  }
  Eigen::Vector2d Project(const Eigen::Vector3d& p) const {
    const Eigen::Vector2d a = ImagePlane(p);
    return {x0 + scale * a.x(), y0 - scale * a.y()};
  }
  // The levels the lines were drawn at (isophotes: N.L), or the curvature map's colour range.
  std::vector<double> levels;
  std::array<double, 2> range{0.0, 0.0};
  LightPlane light_plane;  // the reflection lines' and zebra stripes' light plane as used
  int seen_pixels = 0, singular_pixels = 0, exact_pixels = 0;
  // The parameters in words (view, light, angles, range, eye, sign convention), for a caption.
  std::string caption;
  const SurfacePixel& at(int x, int y) const {
    return pixels[static_cast<std::size_t>(y) * static_cast<std::size_t>(image.width) +
                  static_cast<std::size_t>(x)];
  }
};

// Renders `model` (a surface in 3D: domain dimension 2) placed in the world by `world_T_model`. Throws
// std::invalid_argument for curves and invalid options.
SurfaceRendering RenderSurface(const ParametricModel& model, const RigidMotion& world_T_model,
                               const SurfaceRenderOptions& options);

// A view that shows the surface whole: for a surface with an axis (kinematic surfaces; `axis` the unit axis
// in the world) from the side, 20 degrees above the plane across the axis, the axis up; otherwise along the
// mean of the unit normals over the domain, the points' principal direction across it up. The light comes
// from the viewer's side, from above and the left. std::invalid_argument for curves.
void ChooseView(const ParametricModel& model, const RigidMotion& world_T_model,
                const std::optional<Eigen::Vector3d>& axis, SurfaceRenderOptions& options);

}  // namespace s2m::pipeline
