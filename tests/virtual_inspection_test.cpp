// Nominal inspection (docs/metrology.md section 5) of a part scanned by the virtual scanner
// (devices/virtual_scanner.h): the box [-30, 30] x [-20, 20] x [0, 20] mm with a 0.2 mm bump on its +x face
// is ray cast by the laser-line scanner on its turntable, one full turn at each of three elevations (three
// views, each seeing the four sides and the top or the bottom), every view's pose then put off by its own
// known rigid error; the views are inspected against the unbumped box. The registration must recover the
// views' true poses, the deviation map must show the bump with its amplitude, and every other face must stay
// within the scanner's noise. (tests/nominal_inspection_test.cpp does the same with synthetic/'s direct
// sampling.)

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "acquisition/frame_source.h"
#include "devices/virtual_scanner.h"
#include "fitting/nominal_inspection.h"
#include "fitting/triangle_mesh.h"
#include "test_meshes.h"

namespace s2m {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kA = 30, kB = 20, kC = 20;                          // half width, half depth, height (mm)
constexpr double kBumpHeight = 0.2, kBumpRadius = 8.0, kBumpZ = 10;  // on the +x face, centred at y = 0

// The bump: height cos^2(pi rho / (2 R)) within rho < R of (y, z) = (0, kBumpZ) on the +x face.
double Bump(double y, double z) {
  const double rho = std::hypot(y, z - kBumpZ);
  return rho < kBumpRadius ? kBumpHeight * std::pow(std::cos(kPi * rho / (2 * kBumpRadius)), 2) : 0.0;
}

// The nominal: the box, one group per face (test_meshes.h), in millimetres.
TriangleMesh Box() {
  TriangleMesh m = test::BoxMesh(kA, kB, kC);
  m.units = "mm";
  return m;
}

// The scanned part: the box with its +x face replaced by a 0.25 mm grid displaced by the bump (the grid's
// facets depart from the bump by at most kappa h^2 / 8 = 2.4e-4 mm, h = 0.35 mm the cells' diagonal and
// kappa = 2 (pi / 2R)^2 x 0.2 the bump's largest curvature), the other faces as in the nominal.
SceneMesh BumpedBox() {
  const TriangleMesh box = Box();
  const int ny = 160, nz = 80;
  SceneMesh s;
  s.units = "mm";
  s.vertices.resize(3, 8 + (ny + 1) * (nz + 1));
  s.vertices.leftCols(8) = box.vertices;
  auto grid = [&](int i, int j) { return 8 + j * (ny + 1) + i; };
  for (int j = 0; j <= nz; ++j)
    for (int i = 0; i <= ny; ++i) {
      const double y = -kB + 2 * kB * i / ny, z = kC * j / nz;
      s.vertices.col(grid(i, j)) << kA + Bump(y, z), y, z;
    }
  s.triangles.resize(3, 10 + 2 * ny * nz);
  Eigen::Index t = 0;
  for (Eigen::Index f = 2; f < 12; ++f) s.triangles.col(t++) = box.triangles.col(f);  // all but +x
  for (int j = 0; j < nz; ++j)
    for (int i = 0; i < ny; ++i) {  // counter-clockwise seen from +x: y, then z increasing
      s.triangles.col(t++) << grid(i, j), grid(i + 1, j), grid(i + 1, j + 1);
      s.triangles.col(t++) << grid(i, j), grid(i + 1, j + 1), grid(i, j + 1);
    }
  return s;
}

TEST(VirtualScannerInspection, FindsABumpOfTwoTenthsThroughTheLaserScanner) {
  const double noise = 0.01;  // mm, along each ray
  VirtualScannerOptions o;
  o.sensor = VirtualScannerOptions::Sensor::kLaserLine;
  o.laser.noise = noise;
  o.laser.points_per_profile = 160;
  o.turntable.steps = 120;                                               // 3 degrees between profiles
  o.elevations_rad = {30 * kPi / 180, -30 * kPi / 180, 10 * kPi / 180};  // one view per sweep
  o.seed = 3;
  o.name = "bumped box";
  const auto scanner = MakeVirtualScanner(BumpedBox(), o);
  const ScanSet views = FramesToScanSet(*scanner);
  ASSERT_EQ(views.scans.size(), 3u);

  // The scanner's poses are the true ones (no turntable error configured); each view's recorded pose is put
  // off by its own rotation of 2 degrees about a different axis and a translation of 2 mm.
  std::vector<Eigen::Matrix3Xd> scans;
  std::vector<RigidMotion> truth, recorded;
  const Eigen::Vector3d axes[3] = {{1, 2, 3}, {-2, 1, 1}, {1, -1, 2}};
  const Eigen::Vector3d shifts[3] = {{1.2, -1.0, 1.2}, {-0.8, 1.6, 0.8}, {0.0, -1.4, -1.4}};
  for (std::size_t k = 0; k < views.scans.size(); ++k) {
    scans.push_back(views.scans[k].points);
    truth.push_back(views.scans[k].world_T_scan);
    const RigidMotion error(RotationAboutAxis(axes[k].normalized(), 2 * kPi / 180), shifts[k]);
    recorded.push_back(error * truth.back());
    std::printf("view %zu: %ld points\n", k, static_cast<long>(scans.back().cols()));
  }

  // Registered by least squares (all views, then each on its own), then again from there with Tukey's loss
  // (scale from the data), which rejects the bump's points instead of letting them pull the views that see
  // the +x face (tests/nominal_inspection_test.cpp, FindsABumpOfTwoTenthsWithEveryViewOffOnItsOwn). Tukey's
  // loss straight from the recorded poses does not do here: with the scale taken from residuals dominated by
  // the top and bottom faces' points, the sides' points of a view off by 2 mm are all rejected and its
  // translation stays off by about that much (measured: 1.3 to 2.4 mm).
  const TriangleMeshModel nominal(Box());
  const NominalInspection coarse = InspectAgainstNominal(nominal, scans, recorded);
  NominalInspectionOptions robust;
  robust.registration.optimizer.loss = RobustLoss{LossKind::kTukey, 0.0};
  const NominalInspection r = InspectAgainstNominal(nominal, scans, coarse.nominal_T_scan, robust);
  for (std::size_t k = 0; k < truth.size(); ++k) {
    const RigidMotion error = r.nominal_T_scan[k] * truth[k].inverse();
    std::printf("view %zu: pose error after registration %.2e rad, %.2e mm\n", k, error.angle(),
                error.translation().norm());
    EXPECT_LT(error.angle(), 1e-4) << "view " << k;
    EXPECT_LT(error.translation().norm(), 5e-3) << "view " << k;
  }

  // The bump: the points within 2 mm of its centre lie outside the nominal by the bump's height there (mean
  // over them at least 0.2 cos^2(pi / 8) = 0.17 mm), to the noise's standard error; the +x face's highest
  // point is the bump's top to a few noise sigmas.
  double sum = 0, expected = 0;
  int n = 0;
  for (Eigen::Index i = 0; i < r.points.cols(); ++i) {
    const Eigen::Vector3d x = r.points.col(i);
    if (r.group[static_cast<std::size_t>(i)] == 0 && std::hypot(x.y(), x.z() - kBumpZ) < 2.0) {
      sum += r.deviations[i];
      expected += Bump(x.y(), x.z());
      ++n;
    }
  }
  std::printf("bump: %d points, mean deviation %.4f mm (expected %.4f); +x max %.4f mm\n", n, sum / n,
              expected / n, r.regions[0].max);
  for (const RegionDeviation& g : r.regions)
    std::printf("  %-7s %6ld points, mean %+.5f, sd %.5f, min %+.4f, max %+.4f mm\n", g.name.c_str(),
                static_cast<long>(g.count), g.mean, g.standard_deviation, g.min, g.max);
  ASSERT_GT(n, 50);
  EXPECT_GT(expected / n, 0.17);
  EXPECT_NEAR(sum / n, expected / n, 4 * noise / std::sqrt(n));
  EXPECT_NEAR(r.regions[0].max, kBumpHeight, 5 * noise);
  // Every other face: seen by every view (the bottom by the view from below), mean zero to 4 standard
  // errors, spread at most the noise along the rays (its component along the normal is smaller), no point
  // beyond 6 sigma.
  for (int g = 1; g < 6; ++g) {
    const RegionDeviation& region = r.regions[static_cast<std::size_t>(g)];
    ASSERT_GT(region.count, 1000) << region.name;
    EXPECT_LT(std::abs(region.mean), 4 * noise / std::sqrt(static_cast<double>(region.count)) + 1e-3)
        << region.name;
    EXPECT_LT(region.standard_deviation, 1.1 * noise) << region.name;
    EXPECT_LT(std::max(-region.min, region.max), 6 * noise) << region.name;
  }
}

}  // namespace
}  // namespace s2m
