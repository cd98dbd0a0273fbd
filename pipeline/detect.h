#pragma once
// `scan2model detect` and `fit --robust`: robust extraction of primitives from a raw scan
// (fitting/primitive_detection.h), its text and JSON (schema scan2model.detect/1, docs/cli.md) and the PLY
// files of the inliers (coloured per instance) and of the rejected points.

#include <cstdint>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "fitting/primitive_detection.h"
#include "pipeline/fit_options.h"
#include "registration/scan.h"

namespace s2m::pipeline {

struct DetectOptions {
  std::string file;
  // The input in memory instead of `file` (the Python bindings); `file` then only names it.
  std::shared_ptr<const ScanSet> views;
  std::vector<std::string> models;  // plane, sphere, cylinder, cone, torus
  int max_instances = 10;
  int min_support = 0;  // 0: automatic (max(30, N / 1000))
  std::uint64_t seed = 1;
  double epsilon = 0.0;  // 0: 3 sigma from the noise estimate
  double alpha = 0.0;    // radians; 0: from the noise
  std::string units;
  bool json = false;
  std::string output;  // PREFIX: PREFIX_inliers.ply, PREFIX_rejected.ply
};

struct DetectOutcome {
  nlohmann::json document;
  std::string text;
  std::vector<std::string> notes;
};

// Reads the scan, detects, writes the files asked for; throws FitFailure (kUsage, kInputError, kFitError).
DetectOutcome ComputeDetect(const DetectOptions& options);

// The detection options of a list of model names and the command's numbers; throws FitFailure(kUsage).
DetectionOptions MakeDetectionOptions(const std::vector<std::string>& models, int max_instances,
                                      int min_support, std::uint64_t seed, double epsilon, double alpha);
// The JSON of one instance: kind, parameters, uncertainties, support, RMS, the miss bound and draws.
nlohmann::json InstanceJson(const DetectedPrimitive& instance, const std::string& units);
// The detection's thresholds and stop: what --json reports under "detection".
nlohmann::json DetectionJson(const DetectionResult& result);
// The points of `indices` as a PLY (ASCII, x y z and an RGB colour); throws FormatError.
void WritePointsPly(const std::string& path, const Eigen::Matrix3Xd& points,
                    const std::vector<Eigen::Index>& indices, const std::vector<std::array<int, 3>>& colours);
// The distinct colour of instance k (the same in every file and report).
std::array<int, 3> InstanceColour(std::size_t k);

}  // namespace s2m::pipeline
