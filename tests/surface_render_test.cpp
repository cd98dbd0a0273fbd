// The interrogation renderer (pipeline/surface_render.h), its PNG writer (pipeline/png.h) and the surfaces
// rebuilt from result documents (pipeline/surface_model_json.h): the PNG decodes with zlib, the rendered
// pixels are the exact surface's, a sphere's isophote pixels lie on the predicted circles, a torus' curvature
// map holds the closed-form values.

#include "pipeline/surface_render.h"

#include <gtest/gtest.h>
#include <zlib.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "fitting/kinematic_surfaces.h"
#include "fitting/primitive_models.h"
#include "pipeline/png.h"
#include "pipeline/surface_model_json.h"

namespace s2m::pipeline {
namespace {

std::uint32_t ReadUint32(const std::string& s, std::size_t at) {
  return (static_cast<std::uint32_t>(static_cast<unsigned char>(s[at])) << 24) |
         (static_cast<std::uint32_t>(static_cast<unsigned char>(s[at + 1])) << 16) |
         (static_cast<std::uint32_t>(static_cast<unsigned char>(s[at + 2])) << 8) |
         static_cast<std::uint32_t>(static_cast<unsigned char>(s[at + 3]));
}

// Decodes a PNG as EncodePng writes it (8-bit RGB, filter 0), checking the signature, every chunk's CRC and
// the inflated size; returns the image, or fails the test.
RgbImage Decode(const std::string& png) {
  RgbImage image;
  EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n"));
  std::size_t at = 8;
  std::string idat;
  std::vector<std::string> types;
  while (at + 12 <= png.size()) {
    const std::uint32_t length = ReadUint32(png, at);
    const std::string type = png.substr(at + 4, 4);
    const std::string data = png.substr(at + 8, length);
    const std::uint32_t crc = ReadUint32(png, at + 8 + length);
    uLong expected = crc32(0L, Z_NULL, 0);
    expected =
        crc32(expected, reinterpret_cast<const Bytef*>(png.data() + at + 4), static_cast<uInt>(4 + length));
    EXPECT_EQ(crc, static_cast<std::uint32_t>(expected)) << "chunk " << type;
    types.push_back(type);
    if (type == "IHDR") {
      image.width = static_cast<int>(ReadUint32(data, 0));
      image.height = static_cast<int>(ReadUint32(data, 4));
      EXPECT_EQ(data.substr(8), std::string("\x08\x02\x00\x00\x00", 5));
    }
    if (type == "IDAT") idat += data;
    at += 12 + length;
  }
  EXPECT_EQ(at, png.size());
  EXPECT_EQ(types, (std::vector<std::string>{"IHDR", "IDAT", "IEND"}));
  const std::size_t row = 3 * static_cast<std::size_t>(image.width);
  std::string raw((row + 1) * static_cast<std::size_t>(image.height) + 1, '\0');
  uLongf size = static_cast<uLongf>(raw.size());
  EXPECT_EQ(uncompress(reinterpret_cast<Bytef*>(raw.data()), &size,
                       reinterpret_cast<const Bytef*>(idat.data()), static_cast<uLong>(idat.size())),
            Z_OK);
  EXPECT_EQ(size, (row + 1) * static_cast<std::size_t>(image.height));  // exactly the scanlines
  image.pixels.resize(row * static_cast<std::size_t>(image.height));
  for (int y = 0; y < image.height; ++y) {
    EXPECT_EQ(raw[static_cast<std::size_t>(y) * (row + 1)], '\0');  // filter type none
    std::memcpy(&image.pixels[static_cast<std::size_t>(y) * row],
                &raw[static_cast<std::size_t>(y) * (row + 1) + 1], row);
  }
  return image;
}

TEST(Png, DecodesToTheImageWithValidChunks) {
  RgbImage image(37, 11);
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x)
      image.Set(x, y, static_cast<std::uint8_t>(7 * x), static_cast<std::uint8_t>(20 * y),
                static_cast<std::uint8_t>(x ^ y));
  const RgbImage back = Decode(EncodePng(image));
  EXPECT_EQ(back.width, 37);
  EXPECT_EQ(back.height, 11);
  EXPECT_EQ(back.pixels, image.pixels);
  RgbImage broken(4, 4);
  broken.pixels.pop_back();
  EXPECT_THROW(EncodePng(broken), std::invalid_argument);
  EXPECT_THROW(EncodePng(RgbImage()), std::invalid_argument);
}

TEST(Png, Base64OfTheRfc4648Vectors) {
  EXPECT_EQ(Base64(""), "");
  EXPECT_EQ(Base64("f"), "Zg==");
  EXPECT_EQ(Base64("fo"), "Zm8=");
  EXPECT_EQ(Base64("foo"), "Zm9v");
  EXPECT_EQ(Base64("foob"), "Zm9vYg==");
  EXPECT_EQ(Base64("fooba"), "Zm9vYmE=");
  EXPECT_EQ(Base64("foobar"), "Zm9vYmFy");
}

// The front intersection of the ray through pixel centre (x + 0.5, y + 0.5) with the sphere: orthographic
// along the view, or from the eye in perspective.
std::optional<Eigen::Vector3d> RayHit(const SurfaceRendering& r, int x, int y, const Eigen::Vector3d& centre,
                                      double radius) {
  const double a = (x + 0.5 - r.x0) / r.scale, b = (r.y0 - (y + 0.5)) / r.scale;
  const Eigen::Vector3d origin = r.eye ? *r.eye : Eigen::Vector3d(a * r.right + b * r.up);
  const Eigen::Vector3d direction =
      r.eye ? Eigen::Vector3d((r.forward + a * r.right + b * r.up).normalized()) : r.forward;
  const Eigen::Vector3d w = origin - centre;
  const double half_b = w.dot(direction), c = w.squaredNorm() - radius * radius;
  const double disc = half_b * half_b - c;
  if (disc < 0) return std::nullopt;
  return origin + (-half_b - std::sqrt(disc)) * direction;
}

// A sphere rendered with isophotes (orthographic, or in perspective from `eye`): every exact pixel is the
// ray's intersection with the sphere, and every isophote pixel lies on a predicted circle.
void CheckSphereIsophotes(const std::optional<Eigen::Vector3d>& eye) {
  const Eigen::Vector3d centre(0.5, -1.0, 2.0);
  const double radius = 3.0;
  const SphereModel sphere(Sphere{centre, radius});
  SurfaceRenderOptions o;
  o.width = 320;
  o.height = 320;
  o.view = Eigen::Vector3d(0.2, -0.1, -1.0).normalized();
  o.up = Eigen::Vector3d::UnitY();
  o.eye = eye;
  o.light = Eigen::Vector3d(0.4, 0.5, 1.0).normalized();
  o.colouring = SurfaceColouring::kIsophotes;
  o.isophote_angles_deg = {15, 30, 45, 60, 75};
  const SurfaceRendering r = RenderSurface(sphere, RigidMotion::Identity(), o);
  ASSERT_GT(r.seen_pixels, 20000);
  // Every pixel the Newton step placed is the exact surface point under the pixel centre, its normal the
  // sphere's outward normal (the visible side).
  EXPECT_GT(r.exact_pixels, r.seen_pixels * 99 / 100);
  int line_pixels = 0;
  std::vector<int> per_level(o.isophote_angles_deg.size(), 0);
  for (int y = 0; y < r.image.height; ++y) {
    for (int x = 0; x < r.image.width; ++x) {
      const SurfacePixel& p = r.at(x, y);
      if (!p.seen || !p.exact) continue;
      const std::optional<Eigen::Vector3d> hit = RayHit(r, x, y, centre, radius);
      ASSERT_TRUE(hit) << x << " " << y;
      EXPECT_LT((p.point - *hit).norm(), 1e-8 * radius) << x << " " << y;
      EXPECT_LT((p.normal - (*hit - centre) / radius).norm(), 1e-8) << x << " " << y;
      if (!p.line) continue;
      ++line_pixels;
      // The predicted circle of level c (the points at angle acos(c) from L) passes between this pixel and
      // one of its neighbours: N.L - c, from the analytic ray hits, changes sign.
      const double f = ((*hit - centre) / radius).dot(o.light.normalized());
      bool on_circle = false;
      for (std::size_t k = 0; k < o.isophote_angles_deg.size(); ++k) {
        const double c = std::cos(o.isophote_angles_deg[k] * M_PI / 180);
        for (const auto& [dx, dy] : {std::pair{1, 0}, std::pair{-1, 0}, std::pair{0, 1}, std::pair{0, -1}}) {
          const std::optional<Eigen::Vector3d> n = RayHit(r, x + dx, y + dy, centre, radius);
          if (!n) continue;
          const double g = ((*n - centre) / radius).dot(o.light.normalized());
          if ((f - c) * (g - c) <= 0) {
            on_circle = true;
            ++per_level[k];
            break;
          }
        }
        if (on_circle) break;
      }
      EXPECT_TRUE(on_circle) << "isophote pixel " << x << " " << y << " N.L " << f;
    }
  }
  // Every level that is visible has its line: the five circles are all on the visible half here.
  for (std::size_t k = 0; k < per_level.size(); ++k)
    EXPECT_GT(per_level[k], 50) << "angle " << o.isophote_angles_deg[k];
  EXPECT_GT(line_pixels, 5 * 50);
  // The image itself: line pixels black, the background white, in the PNG as written.
  const RgbImage decoded = Decode(EncodePng(r.image));
  for (int y = 0; y < r.image.height; ++y) {
    for (int x = 0; x < r.image.width; ++x) {
      const std::uint8_t* px = decoded.at(x, y);
      if (r.at(x, y).line) {
        EXPECT_EQ(px[0] + px[1] + px[2], 0);
      }
      if (!r.at(x, y).seen) {
        EXPECT_EQ(px[0] + px[1] + px[2], 3 * 255);
      }
    }
  }
}

TEST(SurfaceRender, SphereIsophotePixelsLieOnThePredictedCircles) {
  CheckSphereIsophotes(std::nullopt);
}

TEST(SurfaceRender, InPerspectiveTooFromAnEyePoint) {
  // The eye 12 radii from the centre, against the view direction (the same view as above).
  CheckSphereIsophotes(Eigen::Vector3d(0.5, -1.0, 2.0) - 12 * Eigen::Vector3d(0.2, -0.1, -1.0).normalized());
  // An eye inside the surface's extent along the view is refused.
  SurfaceRenderOptions o;
  o.eye = Eigen::Vector3d::Zero();
  EXPECT_THROW(RenderSurface(SphereModel(Sphere{}), RigidMotion::Identity(), o), std::invalid_argument);
}

TEST(SurfaceRender, TorusCurvatureMapHoldsTheClosedFormValues) {
  Torus t;
  t.center = Eigen::Vector3d(1, 2, 3);
  t.axis = Eigen::Vector3d(0.2, 0.3, 1.0).normalized();
  t.major_radius = 3.0;
  t.minor_radius = 1.0;
  const TorusModel torus(t);
  SurfaceRenderOptions o;
  o.width = 400;
  o.height = 300;
  o.colouring = SurfaceColouring::kCurvature;
  o.curvature = CurvatureKind::kGaussian;
  o.view = Eigen::Vector3d(0.1, -0.6, -1.0).normalized();
  const SurfaceRendering r = RenderSurface(torus, RigidMotion::Identity(), o);
  int checked = 0, positive = 0, negative = 0;
  for (const SurfacePixel& p : r.pixels) {
    if (!p.seen || !p.exact) continue;
    const double w = t.major_radius + t.minor_radius * std::cos(p.v);
    const double k = std::cos(p.v) / (t.minor_radius * w);
    EXPECT_NEAR(p.value, k, 1e-9 * std::max(std::abs(k), 1e-3));
    ++checked;
    (k > 0 ? positive : negative) += 1;
  }
  EXPECT_GT(checked, 10000);
  EXPECT_GT(positive, 0);
  EXPECT_GT(negative, 0);
  // The default range is symmetric and the colour bar's end values are printed.
  EXPECT_DOUBLE_EQ(r.range[0], -r.range[1]);
  EXPECT_GT(r.range[1], 0);
  EXPECT_NE(r.caption.find("gaussian curvature"), std::string::npos) << r.caption;
}

// Lines of every kind are drawn where the pixel's value and a neighbour's lie on different sides of a level.
TEST(SurfaceRender, LinesSeparateNeighboursOnDifferentSidesOfALevel) {
  Eigen::Matrix2Xd profile(2, 5);
  profile << 2.0, 2.6, 1.4, 2.2, 1.0, 0.0, 1.0, 2.0, 3.0, 4.0;
  const KinematicSurface vase =
      KinematicSurface::Revolution(BSplineBasis::Clamped(4, {0, 0, 0, 0, 0.5, 1, 1, 1, 1}), profile);
  const RigidMotion pose(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()).toRotationMatrix(),
                         Eigen::Vector3d(1, 2, 3));
  for (const SurfaceColouring c : {SurfaceColouring::kIsophotes, SurfaceColouring::kReflectionLines,
                                   SurfaceColouring::kContours, SurfaceColouring::kZebra}) {
    SurfaceRenderOptions o;
    o.width = 240;
    o.height = 240;
    o.colouring = c;
    ChooseView(vase, pose, Eigen::Vector3d(pose.rotation().col(2)), o);
    const SurfaceRendering r = RenderSurface(vase, pose, o);
    EXPECT_GT(r.seen_pixels, 5000) << ToString(c);
    int lines = 0;
    for (int y = 0; y < r.image.height; ++y) {
      for (int x = 0; x < r.image.width; ++x) {
        const SurfacePixel& p = r.at(x, y);
        if (!p.line) continue;
        ++lines;
        bool crossing = false;
        for (const auto& [dx, dy] : {std::pair{1, 0}, std::pair{-1, 0}, std::pair{0, 1}, std::pair{0, -1}}) {
          if (x + dx < 0 || y + dy < 0 || x + dx >= r.image.width || y + dy >= r.image.height) continue;
          const SurfacePixel& q = r.at(x + dx, y + dy);
          if (!q.seen) continue;
          for (const double level : r.levels) crossing |= (p.value - level) * (q.value - level) <= 0;
        }
        EXPECT_TRUE(crossing) << ToString(c) << " " << x << " " << y;
      }
    }
    if (c == SurfaceColouring::kZebra) {
      EXPECT_EQ(lines, 0);  // stripes, not lines
    } else {
      EXPECT_GT(lines, 100) << ToString(c);
    }
  }
}

TEST(SurfaceRender, RefusesCurvesAndInvalidOptions) {
  Eigen::Matrix2Xd profile(2, 4);
  profile << 1, 1, 1, 1, 0, 1, 2, 3;
  const BSplineCurve curve(BSplineBasis::Clamped(4, {0, 0, 0, 0, 1, 1, 1, 1}), profile);
  EXPECT_THROW(RenderSurface(curve, RigidMotion::Identity(), {}), std::invalid_argument);
  SurfaceRenderOptions chosen;
  EXPECT_THROW(ChooseView(curve, RigidMotion::Identity(), std::nullopt, chosen), std::invalid_argument);
  const SphereModel sphere(Sphere{});
  SurfaceRenderOptions o;
  o.light = Eigen::Vector3d(std::nan(""), 0, 1);
  EXPECT_THROW(RenderSurface(sphere, RigidMotion::Identity(), o), std::invalid_argument);
  o = {};
  o.up = o.view;
  EXPECT_THROW(RenderSurface(sphere, RigidMotion::Identity(), o), std::invalid_argument);
  o = {};
  o.range = std::array<double, 2>{1.0, -1.0};
  std::string why;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("range"), std::string::npos);
}

TEST(SurfaceModelJson, KinematicSurfacesRoundTripExactly) {
  Eigen::Matrix2Xd profile(2, 5);
  profile << 2.0, 2.6, 1.4, 2.2, 1.0, 0.0, 1.0, 2.0, 3.0, 4.0;
  const BSplineBasis basis = BSplineBasis::Clamped(4, {0, 0, 0, 0, 0.5, 1, 1, 1, 1});
  const RigidMotion pose(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix(),
                         Eigen::Vector3d(-1, 0.5, 4));
  const KinematicSurface revolution = KinematicSurface::Revolution(basis, profile);
  const KinematicSurface helical = KinematicSurface::Helical(basis, profile, 0.3, 1.5);
  const SpiralSurface spiral = SpiralSurface(basis, profile, 0.1, -2.0, 9.0).WithAllometry(0.01, -0.02);
  for (const ParametricModel* model : std::vector<const ParametricModel*>{&revolution, &helical, &spiral}) {
    nlohmann::json doc = {{"schema", "scan2model.multiview/1"}, {"surface", SurfaceModelJson(*model, pose)}};
    const std::vector<FittedSurface> back = FittedSurfaces(nlohmann::json::parse(doc.dump()));
    ASSERT_EQ(back.size(), 1u) << model->name();
    const ParameterDomain d = model->domain(), e = back[0].model->domain();
    EXPECT_EQ(d.lo, e.lo);
    EXPECT_EQ(d.hi, e.hi);
    for (const double u : {0.1, 0.45, 0.9}) {
      for (const double v : {-1.5, 0.2, 2.9}) {
        LocalGeometry a, b;
        model->Evaluate({u, v, 0.0}, 2, a);
        back[0].model->Evaluate({u, v, 0.0}, 2, b);
        EXPECT_LT((pose * To3(a.point) - back[0].world_T_model * To3(b.point)).norm(), 1e-12)
            << model->name();
        EXPECT_LT((a.d2 - b.d2).norm(), 1e-12) << model->name();
      }
    }
    // The rebuilt surface renders: nearly every pixel it covers traced to its exact point.
    SurfaceRenderOptions o;
    o.width = 260;
    o.height = 200;
    o.colouring = SurfaceColouring::kCurvature;
    o.curvature = CurvatureKind::kMean;
    ChooseView(*back[0].model, back[0].world_T_model, back[0].axis, o);
    const SurfaceRendering r = RenderSurface(*back[0].model, back[0].world_T_model, o);
    EXPECT_GT(r.seen_pixels, 2000) << model->name();
    EXPECT_GT(r.exact_pixels, r.seen_pixels * 95 / 100) << model->name();
    // Unusable members are named.
    doc["surface"]["profile"][0][0] = nullptr;
    EXPECT_THROW(FittedSurfaces(doc), std::invalid_argument);
  }
  EXPECT_TRUE(FittedSurfaces(nlohmann::json{{"schema", "scan2model.fit/1"}, {"model", "sphere"}}).empty());
}

}  // namespace
}  // namespace s2m::pipeline
