#include "acquisition/synthetic_batch.h"

#include <cmath>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include "acquisition/format_error.h"
#include "acquisition/scan_set_io.h"
#include "fitting/initial_models.h"
#include "fitting/kinematic_surfaces.h"
#include "synthetic/synthetic_cases.h"

namespace s2m {
namespace {

constexpr double kDegree = M_PI / 180.0;

std::string Id(const std::string& kind, int k) {
  std::ostringstream s;
  s << kind << "_" << (k < 10 ? "0" : "") << k;
  return s.str();
}

void Write(const std::filesystem::path& manifest, const ScanSet& set) {
  std::filesystem::create_directories(manifest.parent_path());
  WriteScanSet(manifest, set);
}

ScanSet ToScanSet(const SyntheticViews& views, const std::string& name) {
  ScanSet set;
  set.name = name;
  for (std::size_t k = 0; k < views.scans.size(); ++k) {
    Scan scan;
    scan.points = views.scans[k];
    scan.units = "mm";
    scan.world_T_scan = views.model_T_scan_recorded[k];
    set.scans.push_back(scan);
  }
  return set;
}

// A pot's profile (radius, height in mm): foot, belly, shoulder, neck, rim, varied per object.
KinematicSurface PotSurface(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> vary(0.85, 1.15);
  const double scale = vary(rng), belly = vary(rng), neck = vary(rng);
  Eigen::Matrix2Xd profile(2, 7);
  profile << 28 * scale, 40 * scale * belly, 52 * scale * belly, 46 * scale, 32 * scale * neck,
      30 * scale * neck,
      36 * scale,  //
      0, 18, 40, 62, 82, 96, 108;
  profile.row(1) *= scale;
  return KinematicSurface::Revolution(UnitSpacedClamped(4, 7), profile);
}

ViewOptions Errors(const SyntheticBatchOptions& o, std::uint64_t seed) {
  ViewOptions v;
  v.noise = o.noise;
  v.rotation_error = o.rotation_error;
  v.translation_error = o.translation_error;
  v.seed = seed;
  return v;
}

}  // namespace

std::filesystem::path WriteSyntheticBatch(const std::filesystem::path& dir, const SyntheticBatchOptions& o) {
  std::filesystem::create_directories(dir);
  std::mt19937_64 rng(o.seed);
  std::ostringstream csv;
  csv << "id,input,model,max_iterations\n";
  std::uint64_t seed = o.seed * 1000;
  for (int k = 0; k < o.pots; ++k) {
    const KinematicSurface pot = PotSurface(rng);
    const SurfaceSample s =
        SampleAroundAxis(pot, pot.basis().lo(), pot.basis().hi(), -M_PI, M_PI, o.samples_per_object, ++seed);
    const SyntheticViews views =
        ScanFromDirections(s, RingOfDirections(4, 20 * kDegree, 0.3 * k), Errors(o, ++seed));
    const std::string id = Id("pot", k);
    Write(dir / id / "views.json", ToScanSet(views, "synthetic pot " + id));
    csv << id << "," << id << "/views.json,revolution,\n";
  }
  for (int k = 0; k < o.sherds; ++k) {
    // Between a quarter and half of the circumference is missing; three views face what is left.
    const KinematicSurface pot = PotSurface(rng);
    const double missing = (90 + 90.0 * k / std::max(1, o.sherds - 1)) * kDegree;
    const double half = M_PI - missing / 2;
    const SurfaceSample s =
        SampleAroundAxis(pot, pot.basis().lo(), pot.basis().hi(), -half, half, o.samples_per_object, ++seed);
    const SyntheticViews views = ScanFromDirections(
        s,
        {Eigen::Vector3d(std::cos(-half / 2), std::sin(-half / 2), 0.35), Eigen::Vector3d(1, 0, 0.35),
         Eigen::Vector3d(std::cos(half / 2), std::sin(half / 2), 0.35)},
        Errors(o, ++seed));
    const std::string id = Id("sherd", k);
    Write(dir / id / "views.json", ToScanSet(views, "synthetic sherd " + id));
    csv << id << "," << id << "/views.json,revolution,\n";
  }
  for (int k = 0; k < o.shells; ++k) {
    // The shell of synthetic_cases.h ("spiral"), growth varied per object.
    Eigen::Matrix2Xd whorl(2, 6);
    whorl << 20, 25, 30, 31, 26, 19,  //
        -8, -6, -2, 2, 6, 8;
    const double growth = 0.10 + 0.02 * k;
    const SpiralSurface shell(UnitSpacedClamped(4, 6), whorl, growth, -2.0, 6.0);
    const SurfaceSample s = SampleAroundAxis(shell, shell.basis().lo(), shell.basis().hi(), -1.8, 5.8,
                                             o.samples_per_object, ++seed);
    std::vector<Eigen::Vector3d> directions = RingOfDirections(3, 30 * kDegree);
    for (const Eigen::Vector3d& below : RingOfDirections(3, -30 * kDegree, 60 * kDegree))
      directions.push_back(below);
    ViewOptions errors = Errors(o, ++seed);
    errors.rotation_error *= o.shell_pose_error_scale;
    errors.translation_error *= o.shell_pose_error_scale;
    const SyntheticViews views = ScanFromDirections(s, directions, errors);
    const std::string id = Id("shell", k);
    Write(dir / id / "views.json", ToScanSet(views, "synthetic shell " + id));
    csv << id << "," << id << "/views.json,spiral," << o.shell_max_iterations << "\n";
  }
  if (o.corrupt) {
    const KinematicSurface pot = PotSurface(rng);
    const SurfaceSample s =
        SampleAroundAxis(pot, pot.basis().lo(), pot.basis().hi(), -M_PI, M_PI, o.samples_per_object, ++seed);
    const SyntheticViews views = ScanFromDirections(s, RingOfDirections(4, 20 * kDegree), Errors(o, ++seed));
    Write(dir / "corrupt_pot" / "views.json", ToScanSet(views, "a pot whose first view is truncated"));
    // Cut the first view's PLY in the middle of its binary vertex data, as an interrupted copy would.
    const std::filesystem::path ply = dir / "corrupt_pot" / "view_000.ply";
    std::filesystem::resize_file(ply, std::filesystem::file_size(ply) / 2);
    csv << "corrupt_pot,corrupt_pot/views.json,revolution,\n";
  }
  const std::filesystem::path manifest = dir / "batch.csv";
  std::ofstream out(manifest);
  out << csv.str();
  if (!out) throw FormatError(manifest.string(), "", "cannot write");
  return manifest;
}

}  // namespace s2m
