// Generates the demo recordings, one PLY per view plus a scan2model.views/1 manifest (recordings/README.md):
//   s2m_make_demo_views [vase] <manifest.json>   a vase (surface of revolution) seen from four directions,
//   with
//                                                measurement noise and scanner poses off by about a degree
//                                                and half a millimetre (world: the lab's frame)
//   s2m_make_demo_views block <manifest.json>    the counterbored block of
//   docs/examples/counterbored_block.part.json
//                                                (the "part" case of synthetic/synthetic_cases.h): 8 views,
//                                                0.02 mm noise, recorded poses off by 2 degrees and 2 mm
//                                                (world: the part frame, as a fixture would give it)
//   s2m_make_demo_views wall <manifest.json>     a vessel scanned outside and inside (MakeTwoSurfaceVessel of
//                                                synthetic/synthetic_cases.h): two views, 3000 points each,
//                                                0.05 mm noise, 6 mm wall (docs/archaeology.md section 10)
// Deterministic (fixed seeds).

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <random>
#include <string>

#include "acquisition/scan_set_io.h"
#include "fitting/initial_models.h"
#include "fitting/kinematic_surfaces.h"
#include "synthetic/synthetic_cases.h"

namespace s2m {
namespace {

ScanSet MakeVaseViews() {
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
  return set;
}

// The two-surface vessel as two views in one world frame: the outside's points, then the inside's.
ScanSet MakeWallViews() {
  const WallTruth truth = MakeTwoSurfaceVessel(0.05, 3000, 11);
  ScanSet set;
  set.name = "demo vessel scanned outside and inside (6 mm wall), 2 views";
  const Eigen::Index outer = truth.cloud.surface_points;
  for (int k = 0; k < 2; ++k) {
    Scan scan;
    scan.units = "mm";
    scan.points = k == 0 ? Eigen::Matrix3Xd(truth.cloud.points.leftCols(outer))
                         : Eigen::Matrix3Xd(truth.cloud.points.rightCols(truth.inner_points));
    set.scans.push_back(scan);
  }
  return set;
}

}  // namespace
}  // namespace s2m

int main(int argc, char** argv) {
  using namespace s2m;
  const std::string which = argc == 3 ? argv[1] : "vase";
  if ((argc != 2 && argc != 3) ||
      (which != "vase" && which != "block" && which != "freeform" && which != "wall")) {
    std::cerr << "usage: s2m_make_demo_views [vase|block|freeform|wall] <manifest.json>\n";
    return 2;
  }
  const std::filesystem::path manifest = argv[argc - 1];
  ScanSet set = which == "vase"   ? MakeVaseViews()
                : which == "wall" ? MakeWallViews()
                                  : RecordedViews(MakeSyntheticCase(which == "block" ? "part" : which));
  if (which == "block") set.name = "demo block (docs/examples/counterbored_block.part.json), 8 views";
  if (which == "freeform")
    set.name = "plate with a free-form top (docs/examples/freeform_plate.part.json), 8 views";
  std::filesystem::create_directories(manifest.parent_path());
  WriteScanSet(manifest, set);
  std::cout << "wrote " << set.scans.size() << " views (" << set.TotalPoints() << " points) to "
            << manifest.string() << "\n";
  return 0;
}
