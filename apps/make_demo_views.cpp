// Generates the demo's multi-view recording: a vase (surface of revolution) seen by a scanner from four
// directions, with measurement noise and scanner poses that are off by about a degree and half a millimetre,
// written as one PLY per view plus a scan2model.views/1 manifest. Usage: s2m_make_demo_views <manifest.json>.
// Deterministic (fixed seed).

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <random>

#include "acquisition/scan_set_io.h"
#include "fitting/initial_models.h"
#include "fitting/kinematic_surfaces.h"

int main(int argc, char** argv) {
  using namespace s2m;
  if (argc != 2) {
    std::cerr << "usage: s2m_make_demo_views <manifest.json>\n";
    return 2;
  }
  Eigen::Matrix2Xd profile(2, 8);             // radius, height in mm: foot, belly, neck, lip
  profile << 30, 42, 58, 66, 55, 38, 34, 41,  //
      0, 20, 45, 70, 95, 120, 135, 150;
  const KinematicSurface vase = KinematicSurface::Revolution(UnitSpacedClamped(4, 8), profile);
  // The vase stands on a turntable whose axis is tilted slightly and offset in the world.
  const RigidMotion world_T_vase = RigidMotion::FromHelicalVelocity({0.02, -0.01, 0.0}, {120.0, -35.0, 10.0});
  std::mt19937_64 rng(2026);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.02);  // mm
  ScanSet set;
  set.name = "demo vase, 4 views";
  LocalGeometry g;
  for (int k = 0; k < 4; ++k) {
    // Scanner k looks at the vase from angle 90k degrees; it sees about 150 degrees of the surface.
    const double centre = M_PI / 2 * k;
    const RigidMotion world_T_scan_true =
        world_T_vase *
        RigidMotion(Eigen::AngleAxisd(centre, Eigen::Vector3d::UnitZ()).toRotationMatrix(),
                    Eigen::Vector3d::Zero()) *
        RigidMotion::FromHelicalVelocity({0.0, 0.0, 0.0}, {250.0, 0.0, 60.0});
    Eigen::Matrix3Xd world_points(3, 1500);
    for (int j = 0; j < 1500; ++j) {
      const double u =
          vase.basis().lo() + (vase.basis().hi() - vase.basis().lo()) * (0.02 + 0.96 * uniform(rng));
      const double v = centre + (uniform(rng) - 0.5) * 2.6;
      vase.Evaluate({u, v}, 1, g);
      const Eigen::Vector3d n = Eigen::Vector3d(g.d1.col(0)).cross(Eigen::Vector3d(g.d1.col(1))).normalized();
      world_points.col(j) = world_T_vase * (Eigen::Vector3d(g.point) + noise(rng) * n);
    }
    Scan scan;
    scan.points = world_T_scan_true.inverse().apply(world_points);
    scan.units = "mm";
    // The recorded device pose: off by up to about a degree and half a millimetre.
    const RigidMotion error = RigidMotion::FromHelicalVelocity(
        {0.012 * std::cos(1.7 * k), 0.01 * std::sin(2.3 * k), 0.008 * (k - 1.5)},
        {0.5 * std::sin(k + 1.0), 0.4 * std::cos(2.0 * k), 0.3});
    scan.world_T_scan = error * world_T_scan_true;
    set.scans.push_back(scan);
  }
  std::filesystem::create_directories(std::filesystem::path(argv[1]).parent_path());
  WriteScanSet(argv[1], set);
  std::cout << "wrote " << set.scans.size() << " views to " << argv[1] << "\n";
  return 0;
}
