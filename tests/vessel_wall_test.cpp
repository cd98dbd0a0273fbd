// Exploration (temporary).
#include <gtest/gtest.h>

#include <cstdio>

#include "pipeline/fit_options.h"
#include "synthetic/synthetic_cases.h"
#include "registration/scan.h"

namespace s2m {
namespace {

TEST(VesselWall, SingleSheetOnTwoSurfaces) {
  const WallTruth truth = MakeTwoSurfaceVessel(0.05, 6000, 7);
  auto set = std::make_shared<ScanSet>();
  Scan scan;
  scan.units = "mm";
  scan.points = truth.cloud.points;
  set->scans.push_back(scan);
  pipeline::FitOptions o;
  o.file = "vessel";
  o.views = set;
  o.model = "revolution";
  o.interactive = false;
  o.wall = true;
  const pipeline::FitOutcome outcome = pipeline::ComputeFit(o);
  std::printf("%s\n", outcome.text.c_str());
}

TEST(VesselWall, TwoSurfaceSherdExplore) {
  for (double arc : {0.4}) {
  SherdSpec spec;
  spec.arc_fraction = arc;
  spec.rim = true;
  spec.inner_surface = true;
  spec.fracture_faces = true;
  spec.seed = 3;
  const SherdTruth truth = MakeSherd(spec);
  auto set = std::make_shared<ScanSet>();
  Scan scan;
  scan.units = "mm";
  scan.points = truth.cloud.points;
  set->scans.push_back(scan);
  pipeline::FitOptions o;
  o.file = "sherd";
  o.views = set;
  o.model = "revolution";
  o.interactive = false;
  o.wall = true;
  try {
  const pipeline::FitOutcome outcome = pipeline::ComputeFit(o);
  std::printf("%s\n%s\n", outcome.document["wall"]["outer"].dump().c_str(), outcome.document["wall"]["inner"].dump().c_str());
  std::printf("%s\ntruth rim diameter %g axis %g %g %g\n", outcome.text.c_str(), truth.rim_diameter, truth.cloud.axis_direction.x(), truth.cloud.axis_direction.y(), truth.cloud.axis_direction.z());
  } catch (const std::exception& e) { std::printf("error %s\n", e.what()); }
  }
}

}  // namespace
}  // namespace s2m
