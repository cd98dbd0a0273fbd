#include "pipeline/surface_render.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "pipeline/output.h"
#include "pipeline/svg.h"

namespace s2m::pipeline {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kDegree = M_PI / 180.0;
constexpr int kMargin = 10;
constexpr int kBarStrip = 160;  // the curvature map's colour bar and its numbers, right of the surface
constexpr int kFontScale = 2;   // the 5 x 7 glyphs drawn as 2 x 2 pixel cells

// The surface point, first and second derivatives in the world.
struct WorldJet {
  Eigen::Vector3d point;
  Eigen::Matrix<double, 3, 2> d1;
  Eigen::Matrix3d d2;
};

WorldJet Evaluate(const ParametricModel& model, const RigidMotion& pose, double u, double v,
                  int derivatives) {
  LocalGeometry g;
  model.Evaluate({u, v, 0.0}, derivatives, g);
  WorldJet j;
  j.point = pose * To3(g.point);
  j.d1.setZero();
  j.d2.setZero();
  if (derivatives >= 1) j.d1 = pose.rotation() * g.d1.topLeftCorner(3, 2);
  if (derivatives >= 2) j.d2 = pose.rotation() * g.d2.topLeftCorner(3, 3);
  return j;
}

// A 5 x 7 bitmap font for numbers: each glyph is 7 rows of 5 bits (most significant bit on the left).
struct Glyph {
  char c;
  std::uint8_t rows[7];
};
constexpr Glyph kGlyphs[] = {
    {'0', {0x0e, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0e}}, {'1', {0x04, 0x0c, 0x04, 0x04, 0x04, 0x04, 0x0e}},
    {'2', {0x0e, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1f}}, {'3', {0x1f, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0e}},
    {'4', {0x02, 0x06, 0x0a, 0x12, 0x1f, 0x02, 0x02}}, {'5', {0x1f, 0x10, 0x1e, 0x01, 0x01, 0x11, 0x0e}},
    {'6', {0x06, 0x08, 0x10, 0x1e, 0x11, 0x11, 0x0e}}, {'7', {0x1f, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08}},
    {'8', {0x0e, 0x11, 0x11, 0x0e, 0x11, 0x11, 0x0e}}, {'9', {0x0e, 0x11, 0x11, 0x0f, 0x01, 0x02, 0x0c}},
    {'-', {0x00, 0x00, 0x00, 0x1f, 0x00, 0x00, 0x00}}, {'+', {0x00, 0x04, 0x04, 0x1f, 0x04, 0x04, 0x00}},
    {'.', {0x00, 0x00, 0x00, 0x00, 0x00, 0x0c, 0x0c}}, {'e', {0x00, 0x00, 0x0e, 0x11, 0x1f, 0x10, 0x0e}},
};

// Draws `text` (digits, sign, point, exponent; other characters as blanks) with its top left at (x, y).
void DrawText(RgbImage& image, int x, int y, const std::string& text) {
  for (const char c : text) {
    for (const Glyph& g : kGlyphs) {
      if (g.c != c) continue;
      for (int row = 0; row < 7; ++row)
        for (int col = 0; col < 5; ++col)
          if (g.rows[row] & (0x10 >> col))
            for (int a = 0; a < kFontScale; ++a)
              for (int b = 0; b < kFontScale; ++b)
                image.Set(x + col * kFontScale + a, y + row * kFontScale + b, 0, 0, 0);
    }
    x += 6 * kFontScale;
  }
}

std::string Short(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.3g", value);
  return buffer;
}

std::string Vector(const Eigen::Vector3d& v) {
  return "(" + Format(v.x(), 4) + ", " + Format(v.y(), 4) + ", " + Format(v.z(), 4) + ")";
}

// The smallest parameter distance of a and b (across the seam of a periodic parameter).
double ParameterDistance(double a, double b, bool periodic, double period) {
  const double d = std::abs(a - b);
  return periodic ? std::min(d, std::abs(period - std::fmod(d, period))) : d;
}

// Values at the q-quantile (0..1) of |values| (finite ones); 0 when there are none.
double AbsQuantile(const std::vector<double>& values, double q) {
  std::vector<double> a;
  for (const double x : values)
    if (std::isfinite(x)) a.push_back(std::abs(x));
  if (a.empty()) return 0.0;
  const std::size_t k = static_cast<std::size_t>(std::floor(q * static_cast<double>(a.size() - 1)));
  std::nth_element(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(k), a.end());
  return a[k];
}

}  // namespace

std::string ToString(SurfaceColouring colouring) {
  switch (colouring) {
    case SurfaceColouring::kShading:
      return "shading";
    case SurfaceColouring::kCurvature:
      return "curvature";
    case SurfaceColouring::kIsophotes:
      return "isophotes";
    case SurfaceColouring::kReflectionLines:
      return "reflection lines";
    case SurfaceColouring::kZebra:
      return "zebra stripes";
    case SurfaceColouring::kContours:
      return "contours";
  }
  return "";
}

bool SurfaceRenderOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& text) {
    if (why) *why = text;
    return false;
  };
  const int min_width = colouring == SurfaceColouring::kCurvature ? kBarStrip + 64 : 64;
  if (width < min_width || height < 64 || width > 8192 || height > 8192)
    return fail("the image must be between " + std::to_string(min_width) + "x64 and 8192x8192 pixels");
  if (!view.allFinite() || !up.allFinite() || !light.allFinite() || view.norm() == 0 || light.norm() == 0)
    return fail("the view, up and light directions must be finite and non-zero");
  if (!(view.normalized().cross(up).norm() > 1e-6 * up.norm()))
    return fail("the up direction must not be parallel to the view direction");
  if (grid < 2 || grid > 4096) return fail("the grid must have 2 to 4096 cells per parameter");
  for (const double a : isophote_angles_deg)
    if (!(a >= 0 && a <= 180)) return fail("isophote angles must lie in [0, 180] degrees");
  if (colouring == SurfaceColouring::kIsophotes && isophote_angles_deg.empty())
    return fail("isophotes need at least one angle");
  if (lines < 1 || lines > 1000) return fail("the number of lines or stripes must be 1 to 1000");
  if (range && !(std::isfinite((*range)[0]) && std::isfinite((*range)[1]) && (*range)[0] < (*range)[1]))
    return fail("the colour range must be finite with its low end below its high end");
  std::string plane_why;
  if (light_plane && !light_plane->IsValid(&plane_why)) return fail(plane_why);
  if (eye && !eye->allFinite()) return fail("the eye point must be finite");
  if (contour_direction && (!contour_direction->allFinite() || contour_direction->norm() == 0))
    return fail("the contour direction must be finite and non-zero");
  return true;
}

void ChooseView(const ParametricModel& model, const RigidMotion& world_T_model,
                const std::optional<Eigen::Vector3d>& axis, SurfaceRenderOptions& options) {
  const ParameterDomain d = model.domain();
  if (d.dimension != 2 || model.ambient_dimension() != 3)
    throw std::invalid_argument("only surfaces in 3D have a view (the model '" + model.name() +
                                "' is not one)");
  Eigen::Vector3d normal_sum = Eigen::Vector3d::Zero(), centre = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> points;
  const int n = 16;
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; j <= n; ++j) {
      const double u = d.lo[0] + (d.hi[0] - d.lo[0]) * i / n, v = d.lo[1] + (d.hi[1] - d.lo[1]) * j / n;
      const WorldJet w = Evaluate(model, world_T_model, u, v, 1);
      const Eigen::Vector3d c = w.d1.col(0).cross(w.d1.col(1));
      if (c.norm() > 0) normal_sum += c.normalized();
      points.push_back(w.point);
      centre += w.point;
    }
  }
  centre /= static_cast<double>(points.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& p : points) scatter += (p - centre) * (p - centre).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
  Eigen::Vector3d view, up;
  if (axis) {
    up = axis->normalized();
    Eigen::Vector3d side = world_T_model.rotation().col(0);
    side -= side.dot(up) * up;
    if (side.norm() < 1e-6) side = up.unitOrthogonal();
    side.normalize();
    view = -(std::cos(20 * kDegree) * side + std::sin(20 * kDegree) * up);
  } else {
    // Along the mean normal when the surface has a side that faces one way; a closed surface (normals
    // cancelling) is seen along its points' least principal direction.
    view = normal_sum.norm() > 1e-3 * static_cast<double>(points.size())
               ? Eigen::Vector3d(-normal_sum.normalized())
               : Eigen::Vector3d(eig.eigenvectors().col(0));
    up = eig.eigenvectors().col(2);
    up -= up.dot(view) * view;
    if (up.norm() < 1e-6) up = view.unitOrthogonal();
    up.normalize();
  }
  options.view = view.normalized();
  options.up = up;
  const Eigen::Vector3d right = options.view.cross(up).normalized();
  options.light = (-options.view + 0.6 * up - 0.5 * right).normalized();
}

SurfaceRendering RenderSurface(const ParametricModel& model, const RigidMotion& world_T_model,
                               const SurfaceRenderOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument(why);
  const ParameterDomain domain = model.domain();
  if (domain.dimension != 2 || model.ambient_dimension() != 3)
    throw std::invalid_argument("only surfaces in 3D can be rendered (the model '" + model.name() +
                                "' is not one)");
  SurfaceRendering out;
  const int width = options.width, height = options.height;
  out.image = RgbImage(width, height, 255);
  out.pixels.assign(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), SurfacePixel{});
  const Eigen::Vector3d forward = options.view.normalized();
  out.forward = forward;
  out.right = forward.cross(options.up).normalized();
  out.up = out.right.cross(forward);
  out.eye = options.eye;
  const Eigen::Vector3d light = options.light.normalized();

  // 1. The grid's vertices, projected.
  const int n = options.grid;
  const double du = (domain.hi[0] - domain.lo[0]) / n, dv = (domain.hi[1] - domain.lo[1]) / n;
  std::vector<Eigen::Vector3d> vertices;
  vertices.reserve(static_cast<std::size_t>((n + 1) * (n + 1)));
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; j <= n; ++j) {
      const Eigen::Vector3d p =
          Evaluate(model, world_T_model, domain.lo[0] + du * i, domain.lo[1] + dv * j, 0).point;
      if (!p.allFinite()) throw std::invalid_argument("the surface has non-finite points");
      vertices.push_back(p);
      if (out.eye && !(forward.dot(p - *out.eye) > 0))
        throw std::invalid_argument(
            "the surface must lie in front of the eye point (along the view direction)");
      const Eigen::Vector2d a = out.ImagePlane(p);
      const Eigen::Vector3d q(a.x(), a.y(), forward.dot(p));
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
  }
  const bool bar = options.colouring == SurfaceColouring::kCurvature;
  const double available_w = width - (bar ? kBarStrip : 0) - 2 * kMargin, available_h = height - 2 * kMargin;
  const double extent_x = std::max(hi.x() - lo.x(), 1e-300), extent_y = std::max(hi.y() - lo.y(), 1e-300);
  out.scale = std::min(available_w / extent_x, available_h / extent_y);
  out.x0 = kMargin + 0.5 * (available_w - out.scale * extent_x) - out.scale * lo.x();
  out.y0 = kMargin + 0.5 * (available_h - out.scale * extent_y) + out.scale * hi.y();

  // Grid vertices outside a polygonal domain (fitting/fe_surface_model.h) are not on the surface: the
  // triangles touching them are left out.
  std::vector<char> in_domain(vertices.size(), 1);
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j)
      in_domain[static_cast<std::size_t>(i * (n + 1) + j)] =
          model.InDomain({domain.lo[0] + du * i, domain.lo[1] + dv * j, 0.0}) ? 1 : 0;

  // 2. Rasterize the triangles with a depth buffer; each covered pixel keeps the interpolated (u, v).
  std::vector<double> depth(out.pixels.size(), std::numeric_limits<double>::infinity());
  auto vertex = [&](int i, int j) -> const Eigen::Vector3d& {
    return vertices[static_cast<std::size_t>(i * (n + 1) + j)];
  };
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const int corners[2][3][2] = {{{i, j}, {i + 1, j}, {i + 1, j + 1}},
                                    {{i, j}, {i + 1, j + 1}, {i, j + 1}}};
      for (const auto& tri : corners) {
        if (!in_domain[static_cast<std::size_t>(tri[0][0] * (n + 1) + tri[0][1])] ||
            !in_domain[static_cast<std::size_t>(tri[1][0] * (n + 1) + tri[1][1])] ||
            !in_domain[static_cast<std::size_t>(tri[2][0] * (n + 1) + tri[2][1])])
          continue;
        Eigen::Vector2d s[3];
        double z[3], pu[3], pv[3];
        for (int k = 0; k < 3; ++k) {
          const Eigen::Vector3d& p = vertex(tri[k][0], tri[k][1]);
          s[k] = out.Project(p);
          z[k] = forward.dot(p);
          pu[k] = domain.lo[0] + du * tri[k][0];
          pv[k] = domain.lo[1] + dv * tri[k][1];
        }
        const double area = (s[1] - s[0]).x() * (s[2] - s[0]).y() - (s[1] - s[0]).y() * (s[2] - s[0]).x();
        if (area == 0 || !std::isfinite(area)) continue;
        const int x_lo =
            std::max(0, static_cast<int>(std::floor(std::min({s[0].x(), s[1].x(), s[2].x()}) - 0.5)));
        const int x_hi =
            std::min(width - 1, static_cast<int>(std::ceil(std::max({s[0].x(), s[1].x(), s[2].x()}))));
        const int y_lo =
            std::max(0, static_cast<int>(std::floor(std::min({s[0].y(), s[1].y(), s[2].y()}) - 0.5)));
        const int y_hi =
            std::min(height - 1, static_cast<int>(std::ceil(std::max({s[0].y(), s[1].y(), s[2].y()}))));
        for (int y = y_lo; y <= y_hi; ++y) {
          for (int x = x_lo; x <= x_hi; ++x) {
            const Eigen::Vector2d c(x + 0.5, y + 0.5);
            double b[3];
            for (int k = 0; k < 3; ++k) {
              const Eigen::Vector2d& a0 = s[(k + 1) % 3];
              const Eigen::Vector2d& a1 = s[(k + 2) % 3];
              b[k] = ((a1 - a0).x() * (c - a0).y() - (a1 - a0).y() * (c - a0).x()) / area;
            }
            // Pixels on a shared edge belong to both triangles (no cracks); the depth test keeps one.
            if (b[0] < 0 || b[1] < 0 || b[2] < 0) continue;
            const double zz = b[0] * z[0] + b[1] * z[1] + b[2] * z[2];
            const std::size_t index =
                static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x);
            if (!(zz < depth[index])) continue;
            depth[index] = zz;
            SurfacePixel& px = out.pixels[index];
            px.seen = true;
            px.u = b[0] * pu[0] + b[1] * pu[1] + b[2] * pu[2];
            px.v = b[0] * pv[0] + b[1] * pv[1] + b[2] * pv[2];
          }
        }
      }
    }
  }

  // 3. Each pixel's exact surface point: Newton on (right.w(u, v), up.w(u, v)) = the pixel centre, from the
  // grid's (u, v), kept within two grid cells of it (the same sheet) and inside the domain.
  const double period_u = domain.hi[0] - domain.lo[0], period_v = domain.hi[1] - domain.lo[1];
  std::vector<SurfacePointCurvature> curvature(out.pixels.size());
  int seen = 0, exact = 0, singular = 0;
  // Pixels are independent: rows in parallel (the model's Evaluate is const and thread-safe).
#pragma omp parallel for schedule(dynamic, 4) reduction(+ : seen, exact, singular)
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const std::size_t index =
          static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x);
      SurfacePixel& px = out.pixels[index];
      if (!px.seen) continue;
      ++seen;
      const Eigen::Vector2d target((x + 0.5 - out.x0) / out.scale, (out.y0 - (y + 0.5)) / out.scale);
      double u = px.u, v = px.v;
      for (int it = 0; it < 8; ++it) {
        const WorldJet w = Evaluate(model, world_T_model, u, v, 1);
        const Eigen::Vector2d r = out.ImagePlane(w.point) - target;
        if (r.norm() * out.scale < 1e-9) {
          px.exact = true;
          break;
        }
        Eigen::Matrix2d j;
        j << out.right.dot(w.d1.col(0)), out.right.dot(w.d1.col(1)), out.up.dot(w.d1.col(0)),
            out.up.dot(w.d1.col(1));
        if (out.eye) {  // d/dt of (a.q) / (f.q): (a.q_t - (a.q / f.q) f.q_t) / f.q
          const double eye_depth = forward.dot(w.point - *out.eye);
          const Eigen::Vector2d a = out.ImagePlane(w.point);
          for (int k = 0; k < 2; ++k) {
            const double depth_t = forward.dot(w.d1.col(k));
            j(0, k) = (j(0, k) - a.x() * depth_t) / eye_depth;
            j(1, k) = (j(1, k) - a.y() * depth_t) / eye_depth;
          }
        }
        const double det = j.determinant();
        if (!(std::abs(det) > 0)) break;
        const Eigen::Vector2d step = -j.inverse() * r;
        u += step.x();
        v += step.y();
        if (!std::isfinite(u) || !std::isfinite(v) ||
            ParameterDistance(u, px.u, domain.periodic[0], period_u) > 2 * du ||
            ParameterDistance(v, px.v, domain.periodic[1], period_v) > 2 * dv ||
            (!domain.periodic[0] && (u < domain.lo[0] || u > domain.hi[0])) ||
            (!domain.periodic[1] && (v < domain.lo[1] || v > domain.hi[1])) || !model.InDomain({u, v, 0.0}))
          break;
      }
      if (px.exact) {
        ++exact;
        px.u = u;
        px.v = v;
      }
      const WorldJet w = Evaluate(model, world_T_model, px.u, px.v, 2);
      SurfacePointCurvature c = InterrogateSurfacePoint(w.point, w.d1, w.d2);
      px.point = w.point;
      if (c.regular) {
        // Turned towards the viewer; the signed curvatures follow the normal (Fang's sign for the visible
        // side: positive where the visible surface bulges towards the viewer).
        if (c.normal.dot(forward) > 0) {
          c.normal = -c.normal;
          c.mean = -c.mean;
          const double kmax = c.kmax;
          c.kmax = -c.kmin;
          c.kmin = -kmax;
          std::swap(c.direction_max, c.direction_min);
        }
        px.normal = c.normal;
      } else {
        px.normal.setConstant(kNaN);
        ++singular;
      }
      curvature[index] = c;
    }
  }
  out.seen_pixels = seen;
  out.exact_pixels = exact;
  out.singular_pixels = singular;

  // 4. The scalar each pixel shows, and the levels.
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& p : vertices) centre += p;
  centre /= static_cast<double>(vertices.size());
  double radius = 0;
  for (const Eigen::Vector3d& p : vertices) radius = std::max(radius, (p - centre).norm());
  // The lights span a window of the light plane 4 bounding radii wide about its origin (a finite set of
  // tubes, as in a real light tunnel): grazing reflections would otherwise spread the offsets without bound.
  const double window = 2 * std::max(radius, std::numeric_limits<double>::min());
  LightPlane plane;
  if (options.light_plane) {
    plane = *options.light_plane;
  } else {
    plane.origin = centre + 2 * radius * light;
    Eigen::Vector3d s = out.right - out.right.dot(light) * light;
    if (s.norm() < 1e-6) s = light.unitOrthogonal();
    plane.direction = s.normalized();
    plane.across = light.cross(plane.direction).normalized();
    plane.eye = options.eye ? *options.eye : Eigen::Vector3d(centre - 3 * radius * forward);
  }
  out.light_plane = plane;
  const Eigen::Vector3d contour_direction =
      options.contour_direction ? Eigen::Vector3d(options.contour_direction->normalized()) : out.up;
  std::vector<double> values;
  values.reserve(out.pixels.size());
  for (std::size_t index = 0; index < out.pixels.size(); ++index) {
    SurfacePixel& px = out.pixels[index];
    if (!px.seen) continue;
    const SurfacePointCurvature& c = curvature[index];
    switch (options.colouring) {
      case SurfaceColouring::kShading:
      case SurfaceColouring::kIsophotes:
        px.value = c.regular ? IsophoteValue(px.normal, light) : kNaN;
        break;
      case SurfaceColouring::kCurvature:
        px.value = c.regular ? CurvatureValue(c, options.curvature) : kNaN;
        break;
      case SurfaceColouring::kReflectionLines:
      case SurfaceColouring::kZebra:
        px.value = c.regular ? ReflectionLineParameter(plane, px.point, px.normal).offset : kNaN;
        break;
      case SurfaceColouring::kContours:
        px.value = ContourHeight(px.point, Eigen::Vector3d::Zero(), contour_direction);
        break;
    }
    values.push_back(px.value);
  }
  double value_lo = std::numeric_limits<double>::infinity(), value_hi = -value_lo;
  for (const double x : values) {
    if (!std::isfinite(x)) continue;
    value_lo = std::min(value_lo, x);
    value_hi = std::max(value_hi, x);
  }
  const bool have_values = value_lo <= value_hi;
  switch (options.colouring) {
    case SurfaceColouring::kIsophotes:
      for (const double a : options.isophote_angles_deg) out.levels.push_back(std::cos(a * kDegree));
      break;
    case SurfaceColouring::kReflectionLines:
      for (int k = 1; k <= options.lines; ++k)
        out.levels.push_back(-window + 2 * window * k / (options.lines + 1));
      break;
    case SurfaceColouring::kContours:
      if (have_values)
        for (int k = 1; k <= options.lines; ++k)
          out.levels.push_back(value_lo + (value_hi - value_lo) * k / (options.lines + 1));
      break;
    case SurfaceColouring::kCurvature: {
      if (options.range) {
        out.range = *options.range;
      } else {
        // +- the 99th percentile of |value|, but not below the rounding level of the surface's own curvature
        // scale (a cylinder's K is zero to rounding: white, not a full-scale map of rounding noise).
        std::vector<double> absolute;
        for (std::size_t index = 0; index < out.pixels.size(); ++index)
          if (out.pixels[index].seen) absolute.push_back(curvature[index].absolute);
        const double scale = AbsQuantile(absolute, 0.99);
        const double unit = options.curvature == CurvatureKind::kGaussian ? scale * scale : scale;
        double half =
            std::max(AbsQuantile(values, 0.99), std::sqrt(std::numeric_limits<double>::epsilon()) * unit);
        if (!(half > 0)) half = 1.0;
        out.range = options.curvature == CurvatureKind::kAbsolute ? std::array<double, 2>{0.0, half}
                                                                  : std::array<double, 2>{-half, half};
      }
      break;
    }
    default:
      break;
  }
  std::sort(out.levels.begin(), out.levels.end());
  const double zebra_spacing = 2 * window / options.lines;

  // 5. Colours: Lambert shading (ambient 0.3) under the map's colour; lines between neighbouring pixels
  // whose values lie on different sides of a level.
  const double middle = 0.5 * (out.range[0] + out.range[1]), half_range = 0.5 * (out.range[1] - out.range[0]);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const SurfacePixel& px = out.at(x, y);
      if (!px.seen) continue;
      const bool regular = px.normal.allFinite();
      const double shade = regular ? 0.3 + 0.7 * std::max(0.0, px.normal.dot(light)) : 0.5;
      std::array<double, 3> rgb{220, 220, 220};
      if (options.colouring == SurfaceColouring::kCurvature && std::isfinite(px.value)) {
        const std::array<std::uint8_t, 3> c = svg::DivergingRgb((px.value - middle) / half_range);
        rgb = {double(c[0]), double(c[1]), double(c[2])};
        const double s = 0.55 + 0.45 * shade;  // the colour stays readable in the shadow
        for (double& ch : rgb) ch *= s;
      } else if (options.colouring == SurfaceColouring::kZebra && std::abs(px.value) <= window) {
        const double g = ZebraStripe(px.value + window, zebra_spacing) ? 30 : 245;
        rgb = {g * shade, g * shade, g * shade};
      } else if ((options.colouring == SurfaceColouring::kReflectionLines && !std::isfinite(px.value)) ||
                 options.colouring == SurfaceColouring::kZebra) {
        // Mirrors no light of the plane (zebra: none of the window's stripes).
        rgb = {110 * shade, 110 * shade, 125 * shade};
      } else {
        for (double& ch : rgb) ch *= shade;
      }
      out.image.Set(x, y, static_cast<std::uint8_t>(std::lround(std::clamp(rgb[0], 0.0, 255.0))),
                    static_cast<std::uint8_t>(std::lround(std::clamp(rgb[1], 0.0, 255.0))),
                    static_cast<std::uint8_t>(std::lround(std::clamp(rgb[2], 0.0, 255.0))));
    }
  }
  if (!out.levels.empty()) {
    auto band = [&](double value) {
      return static_cast<long>(std::upper_bound(out.levels.begin(), out.levels.end(), value) -
                               out.levels.begin());
    };
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        const SurfacePixel& p = out.at(x, y);
        if (!p.seen || !std::isfinite(p.value)) continue;
        for (const auto& [nx, ny] : {std::pair{x + 1, y}, std::pair{x, y + 1}}) {
          if (nx >= width || ny >= height) continue;
          const SurfacePixel& q = out.at(nx, ny);
          if (!q.seen || !std::isfinite(q.value)) continue;
          // Not across an occlusion boundary: the two points must be within a few grid cells in (u, v).
          if (ParameterDistance(p.u, q.u, domain.periodic[0], period_u) > 4 * du ||
              ParameterDistance(p.v, q.v, domain.periodic[1], period_v) > 4 * dv)
            continue;
          const long bp = band(p.value), bq = band(q.value);
          if (bp == bq) continue;
          const double level = out.levels[static_cast<std::size_t>(std::min(bp, bq))];
          const bool mark_p = std::abs(p.value - level) <= std::abs(q.value - level);
          const int mx = mark_p ? x : nx, my = mark_p ? y : ny;
          out.pixels[static_cast<std::size_t>(my) * static_cast<std::size_t>(width) +
                     static_cast<std::size_t>(mx)]
              .line = true;
        }
      }
    }
    for (int y = 0; y < height; ++y)
      for (int x = 0; x < width; ++x)
        if (out.at(x, y).line) out.image.Set(x, y, 0, 0, 0);
  }

  // 6. The colour bar with its numbers, and the caption.
  std::ostringstream caption;
  caption << ToString(options.colouring) << ", "
          << (out.eye ? "perspective view from " + Vector(*out.eye) + " along "
                      : std::string("orthographic view along "))
          << Vector(forward) << ", up " << Vector(out.up) << ", light towards " << Vector(light);
  if (bar) {
    const int bar_x = width - kBarStrip + 16, bar_w = 18, top = kMargin + 8, bottom = height - kMargin - 8;
    for (int y = top; y <= bottom; ++y) {
      const double t = 1.0 - 2.0 * (y - top) / (bottom - top);  // +1 at the top
      const std::array<std::uint8_t, 3> c = svg::DivergingRgb(t);
      for (int x = bar_x; x < bar_x + bar_w; ++x) out.image.Set(x, y, c[0], c[1], c[2]);
    }
    for (int k = 0; k <= 4; ++k) {
      const int y = top + (bottom - top) * k / 4;
      const double value = out.range[1] - (out.range[1] - out.range[0]) * k / 4;
      for (int x = bar_x - 3; x < bar_x + bar_w + 3; ++x) out.image.Set(x, y, 0, 0, 0);
      DrawText(out.image, bar_x + bar_w + 6, y - 7, Short(value));
    }
    caption << "; " << ToString(options.curvature) << " curvature, colour range [" << Format(out.range[0], 4)
            << ", " << Format(out.range[1], 4)
            << "] (values beyond it take the end colours), sign: positive where the visible side is convex "
               "(the normal turned towards the viewer, the centre of curvature behind the surface)";
  }
  if (options.colouring == SurfaceColouring::kIsophotes) {
    caption << "; isophotes N.L = cos(a) for a =";
    for (const double a : options.isophote_angles_deg) caption << " " << Format(a, 4);
    caption << " degrees";
  }
  if (options.colouring == SurfaceColouring::kReflectionLines ||
      options.colouring == SurfaceColouring::kZebra) {
    caption << "; light plane through " << Vector(plane.origin) << ", lines along " << Vector(plane.direction)
            << ", offsets along " << Vector(plane.across) << ", eye at " << Vector(plane.eye) << "; ";
    if (options.colouring == SurfaceColouring::kZebra)
      caption << "stripes " << Format(zebra_spacing, 4) << " wide (" << options.lines
              << " across the offsets " << Format(-window, 4) << " to " << Format(window, 4) << ")";
    else
      caption << out.levels.size() << " lights at offsets " << Format(out.levels.front(), 4) << " to "
              << Format(out.levels.back(), 4);
  }
  if (options.colouring == SurfaceColouring::kContours) {
    caption << "; " << out.levels.size() << " contours of the height along " << Vector(contour_direction);
    if (!out.levels.empty())
      caption << ", " << Format(out.levels.front(), 4) << " to " << Format(out.levels.back(), 4);
  }
  if (out.singular_pixels > 0) caption << "; " << out.singular_pixels << " pixels at singular points (grey)";
  out.caption = caption.str();
  return out;
}

}  // namespace s2m::pipeline
