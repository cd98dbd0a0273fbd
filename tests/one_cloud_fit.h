#pragma once
// The options of `scan2model fit` for one in-memory cloud in millimetres (one view, no file), as the tests
// that fit synthetic objects through the command's own path (pipeline::ComputeFit) build them.

#include <Eigen/Core>
#include <memory>
#include <string>

#include "pipeline/fit_options.h"
#include "registration/scan.h"

namespace s2m::test {

inline pipeline::FitOptions OneCloudFitOptions(const Eigen::Matrix3Xd& points, const std::string& name,
                                               const std::string& model) {
  auto set = std::make_shared<ScanSet>();
  Scan scan;
  scan.units = "mm";
  scan.points = points;
  set->scans.push_back(scan);
  pipeline::FitOptions o;
  o.file = name;
  o.views = set;
  o.model = model;
  o.interactive = false;
  return o;
}

}  // namespace s2m::test
