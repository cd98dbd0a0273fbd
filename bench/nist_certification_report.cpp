// Measures our primitive fits against all 60 NIST reference pairs, with TDM and SDM steps, and prints a
// markdown table: the largest deviation per geometry (relative to each data set's extent, or in radians) and
// the iterations. A second table: the form errors (minimum zone, started at the least-squares fit) of the
// same sets, their ratio to the least-squares zone, the iterations and the time beside the least-squares
// fit's (docs/metrology.md). Usage: nist_certification_report [path/to/nist_l2_reference_pairs]   (default:
// ../shared/data/... beside the repo)

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <string>

#include "acquisition/nist_reference.h"
#include "acquisition/point_cloud_io.h"
#include "fitting/minimum_zone.h"
#include "fitting/primitive_compare.h"
#include "fitting/primitive_fit.h"

namespace fs = std::filesystem;
using namespace s2m;

struct Summary {
  double position = 0, direction = 0, size = 0, angle = 0;
  int iterations = 0, max_iterations = 0, sets = 0;
  double seconds = 0;
  std::string worst_set;
};

template <class Shape, class Fit, class Read>
void Run(const fs::path& dir, const char* prefix, ErrorTerm method, Fit fit_fn, Read read_fn, Summary& s) {
  for (int i = 1; i <= 15; ++i) {
    const std::string name = prefix + std::to_string(i);
    const Scan scan = ReadPointCloud(dir / (name + ".ds"));
    PrimitiveFitOptions options;
    options.error_term = method;
    const auto start = std::chrono::steady_clock::now();
    const auto fit = fit_fn(scan.points, options);
    s.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const PrimitiveDeviation d = Compare(fit.shape, read_fn(dir / (name + ".fit")));
    const double extent = ComputeBounds(scan.points).diagonal();
    const double worst_before = std::max({s.position, s.direction, s.size, s.angle});
    s.position = std::max(s.position, d.position / extent);
    s.direction = std::max(s.direction, d.direction);
    s.size = std::max(s.size, d.size / extent);
    s.angle = std::max(s.angle, d.angle);
    if (std::max({s.position, s.direction, s.size, s.angle}) > worst_before) s.worst_set = name;
    s.iterations += fit.iterations;
    s.max_iterations = std::max(s.max_iterations, fit.iterations);
    ++s.sets;
  }
}

struct FormSummary {
  double min_ratio = 1e300, max_ratio = 0;  // minimum zone / least-squares zone
  int interpolated = 0;  // sets whose zones are at the rounding level (as many points as parameters)
  int iterations = 0, max_iterations = 0, sets = 0, converged = 0;
  std::size_t min_contacts = 1000, max_contacts = 0;
  double lsq_seconds = 0, zone_seconds = 0;
};

template <class Fit>
void RunForm(const fs::path& dir, const char* prefix, Fit fit_fn, FormSummary& s) {
  for (int i = 1; i <= 15; ++i) {
    const Scan scan = ReadPointCloud(dir / (std::string(prefix) + std::to_string(i) + ".ds"));
    const auto t0 = std::chrono::steady_clock::now();
    const auto fit = fit_fn(scan.points, PrimitiveFitOptions{});
    const auto t1 = std::chrono::steady_clock::now();
    const auto zone = MinimumZoneFit(scan.points, fit.shape);
    const auto t2 = std::chrono::steady_clock::now();
    s.lsq_seconds += std::chrono::duration<double>(t1 - t0).count();
    s.zone_seconds += std::chrono::duration<double>(t2 - t1).count();
    const double lsq = ZoneAbout(scan.points, fit.shape).zone_width;
    if (lsq > 1e-12 * ComputeBounds(scan.points).diagonal()) {
      const double ratio = zone.zone_width / lsq;
      s.min_ratio = std::min(s.min_ratio, ratio);
      s.max_ratio = std::max(s.max_ratio, ratio);
    } else {
      ++s.interpolated;  // both zones are rounding noise: no ratio
    }
    s.iterations += zone.iterations;
    s.max_iterations = std::max(s.max_iterations, zone.iterations);
    s.min_contacts = std::min(s.min_contacts, zone.contacts.size());
    s.max_contacts = std::max(s.max_contacts, zone.contacts.size());
    s.converged += zone.converged ? 1 : 0;
    ++s.sets;
  }
}

int main(int argc, char** argv) {
  const fs::path root = argc > 1
                            ? fs::path(argv[1])
                            : fs::path(S2M_SOURCE_DIR) / ".." / "shared" / "data" / "nist_l2_reference_pairs";
  if (!fs::is_directory(root)) {
    std::cerr << "nist_certification_report: no NIST reference pairs at " << root << "\n";
    return 2;
  }
  std::cout
      << "| geometry | method | max position dev. (rel.) | max direction dev. (rad) | max size dev. (rel.) | "
         "max apex-angle dev. (rad) | worst set | mean / max iterations | total time (ms) |\n"
      << "|---|---|---|---|---|---|---|---|---|\n";
  for (ErrorTerm method : {ErrorTerm::kTdm, ErrorTerm::kSdm}) {
    Summary plane, sphere, cylinder, cone;
    Run<Plane>(
        root / "Plane", "pla", method, [](auto& p, auto& o) { return FitPlane(p, o); }, ReadNistPlaneFit,
        plane);
    Run<Sphere>(
        root / "Sphere", "sph", method, [](auto& p, auto& o) { return FitSphere(p, o); }, ReadNistSphereFit,
        sphere);
    Run<Cylinder>(
        root / "Cylinder", "cyl", method, [](auto& p, auto& o) { return FitCylinder(p, o); },
        ReadNistCylinderFit, cylinder);
    Run<Cone>(
        root / "Cone", "con", method, [](auto& p, auto& o) { return FitCone(p, o); }, ReadNistConeFit, cone);
    for (const auto& [name, s] : {std::pair<const char*, Summary&>{"plane", plane},
                                  {"sphere", sphere},
                                  {"cylinder", cylinder},
                                  {"cone", cone}}) {
      std::printf("| %s | %s | %.2e | %.2e | %.2e | %.2e | %s | %.1f / %d | %.1f |\n", name, ToString(method),
                  s.position, s.direction, s.size, s.angle, s.worst_set.c_str(),
                  static_cast<double>(s.iterations) / s.sets, s.max_iterations, s.seconds * 1e3);
    }
  }
  std::cout
      << "\n| form error | minimum zone / least-squares zone, min - max (sets at the rounding level) | "
         "converged | mean / max iterations | contacts | least-squares fits (ms) | minimum-zone fits (ms) |\n"
      << "|---|---|---|---|---|---|---|\n";
  FormSummary flatness, sphericity, cylindricity, conicity;
  RunForm(
      root / "Plane", "pla", [](auto& p, auto o) { return FitPlane(p, o); }, flatness);
  RunForm(
      root / "Sphere", "sph", [](auto& p, auto o) { return FitSphere(p, o); }, sphericity);
  RunForm(
      root / "Cylinder", "cyl", [](auto& p, auto o) { return FitCylinder(p, o); }, cylindricity);
  RunForm(
      root / "Cone", "con", [](auto& p, auto o) { return FitCone(p, o); }, conicity);
  for (const auto& [name, s] : {std::pair<const char*, FormSummary&>{"flatness", flatness},
                                {"sphericity", sphericity},
                                {"cylindricity", cylindricity},
                                {"conicity", conicity}}) {
    std::printf("| %s | %.3f - %.3f (%d) | %d / %d | %.1f / %d | %zu - %zu | %.1f | %.1f |\n", name,
                s.min_ratio, s.max_ratio, s.interpolated, s.converged, s.sets,
                static_cast<double>(s.iterations) / s.sets, s.max_iterations, s.min_contacts, s.max_contacts,
                s.lsq_seconds * 1e3, s.zone_seconds * 1e3);
  }
  return 0;
}
