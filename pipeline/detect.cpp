// `scan2model detect`: robust extraction of primitives (fitting/primitive_detection.h) from one scan.
#include "pipeline/detect.h"

#include <array>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <sstream>

#include "acquisition/format_error.h"
#include "acquisition/point_cloud_io.h"
#include "fitting/primitive_fit.h"
#include "pipeline/exit_code.h"
#include "pipeline/output.h"
#include "pipeline/views.h"

namespace s2m::pipeline {
namespace {

nlohmann::json ParametersJson(const DetectedShape& shape) {
  nlohmann::json j;
  if (const auto* p = std::get_if<Plane>(&shape)) {
    j["point"] = ToJson(p->point);
    j["normal"] = ToJson(p->normal);
  } else if (const auto* s = std::get_if<Sphere>(&shape)) {
    j["center"] = ToJson(s->center);
    j["radius"] = s->radius;
    j["diameter"] = 2 * s->radius;
  } else if (const auto* c = std::get_if<Cylinder>(&shape)) {
    j["axis_point"] = ToJson(c->axis_point);
    j["axis_direction"] = ToJson(c->axis_direction);
    j["radius"] = c->radius;
    j["diameter"] = 2 * c->radius;
  } else if (const auto* t = std::get_if<Torus>(&shape)) {
    j["center"] = ToJson(t->center);
    j["axis_direction"] = ToJson(t->axis);
    j["major_radius"] = t->major_radius;
    j["minor_radius"] = t->minor_radius;
  } else {
    const Cone& k = std::get<Cone>(shape);
    j["axis_point"] = ToJson(k.axis_point);
    j["axis_direction"] = ToJson(k.axis_direction);
    j["radius"] = k.radius;
    j["half_angle"] = k.half_angle;
    j["apex"] = ToJson(k.Apex());
  }
  return j;
}

// One line per parameter: the value and, where the refit gives one, its standard uncertainty.
std::string ParametersText(const DetectedPrimitive& instance) {
  std::ostringstream t;
  auto uncertainty = [&](const std::string& name) -> std::string {
    for (const ParameterUncertainty& u : instance.uncertainties)
      if (u.name == name) return " +- " + Format(u.standard_uncertainty, 3) + (u.is_angle ? " rad" : "");
    return "";
  };
  if (const auto* p = std::get_if<Plane>(&instance.shape)) {
    t << "    point       " << Format(p->point, 9) << uncertainty("offset") << "\n"
      << "    normal      " << Format(p->normal, 9) << uncertainty("normal_direction") << "\n";
  } else if (const auto* s = std::get_if<Sphere>(&instance.shape)) {
    t << "    center      " << Format(s->center, 9) << uncertainty("center") << "\n"
      << "    radius      " << Format(s->radius, 9) << uncertainty("radius") << "\n";
  } else if (const auto* c = std::get_if<Cylinder>(&instance.shape)) {
    t << "    axis point  " << Format(c->axis_point, 9) << uncertainty("axis_position") << "\n"
      << "    axis        " << Format(c->axis_direction, 9) << uncertainty("axis_direction") << "\n"
      << "    radius      " << Format(c->radius, 9) << uncertainty("radius") << "\n";
  } else if (const auto* r = std::get_if<Torus>(&instance.shape)) {
    t << "    center      " << Format(r->center, 9) << "\n"
      << "    axis        " << Format(r->axis, 9) << uncertainty("axis_direction") << "\n"
      << "    R (major)   " << Format(r->major_radius, 9) << uncertainty("major_radius") << "\n"
      << "    r (minor)   " << Format(r->minor_radius, 9) << uncertainty("minor_radius") << "\n";
  } else {
    const Cone& k = std::get<Cone>(instance.shape);
    t << "    axis point  " << Format(k.axis_point, 9) << uncertainty("axis_position") << "\n"
      << "    axis        " << Format(k.axis_direction, 9) << uncertainty("axis_direction") << "\n"
      << "    radius      " << Format(k.radius, 9) << "\n"
      << "    half angle  " << Format(k.half_angle, 9) << " rad" << uncertainty("half_angle") << "\n";
  }
  t << "    uncertainties (type A, from the refit on the inliers):";
  for (const ParameterUncertainty& u : instance.uncertainties)
    t << " " << u.name << " " << Format(u.standard_uncertainty, 3) << (u.is_angle ? " rad" : "");
  t << "\n";
  return t.str();
}

}  // namespace

std::array<int, 3> InstanceColour(std::size_t k) {
  static const std::array<std::array<int, 3>, 10> kPalette = {{{230, 25, 75},
                                                               {60, 180, 75},
                                                               {0, 130, 200},
                                                               {245, 130, 48},
                                                               {145, 30, 180},
                                                               {70, 240, 240},
                                                               {240, 50, 230},
                                                               {210, 245, 60},
                                                               {250, 190, 212},
                                                               {0, 128, 128}}};
  return kPalette[k % kPalette.size()];
}

void WritePointsPly(const std::string& path, const Eigen::Matrix3Xd& points,
                    const std::vector<Eigen::Index>& indices,
                    const std::vector<std::array<int, 3>>& colours) {
  std::ostringstream out;
  out << "ply\nformat ascii 1.0\ncomment written by scan2model detect\nelement vertex " << indices.size()
      << "\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\nproperty uchar "
         "green\nproperty uchar blue\nend_header\n";
  out.precision(10);
  for (std::size_t i = 0; i < indices.size(); ++i) {
    const Eigen::Vector3d p = points.col(indices[i]);
    out << p.x() << ' ' << p.y() << ' ' << p.z() << ' ' << colours[i][0] << ' ' << colours[i][1] << ' '
        << colours[i][2] << '\n';
  }
  WriteTextAtomically(path, out.str());
}

DetectionOptions MakeDetectionOptions(const std::vector<std::string>& models, int max_instances,
                                      int min_support, std::uint64_t seed, double epsilon, double alpha) {
  DetectionOptions o;
  try {
    for (const std::string& m : models) {
      const PrimitiveKind kind = PrimitiveKindFromString(m);
      if (std::find(o.kinds.begin(), o.kinds.end(), kind) == o.kinds.end()) o.kinds.push_back(kind);
    }
  } catch (const std::invalid_argument& e) {
    throw FitFailure(kUsage, e.what());
  }
  o.max_instances = max_instances;
  o.min_support = min_support;
  o.seed = seed;
  o.epsilon = epsilon;
  o.alpha = alpha;
  std::string why;
  if (!o.IsValid(&why)) throw FitFailure(kUsage, "detect: " + why);
  return o;
}

nlohmann::json InstanceJson(const DetectedPrimitive& instance, const std::string& units) {
  nlohmann::json j;
  j["model"] = ToString(instance.kind);
  j["parameters"] = ParametersJson(instance.shape);
  for (const ParameterUncertainty& u : instance.uncertainties) {
    j["uncertainties"][u.name] = {{"standard_uncertainty", u.standard_uncertainty},
                                  {"unit", u.is_angle ? "rad" : units}};
  }
  j["support"] = instance.support();
  j["rms"] = instance.rms;
  j["epsilon"] = instance.epsilon;
  j["miss_probability"] = instance.miss_probability;
  j["draws"] = instance.draws;
  // More than 1 when parts cut apart by an occluder were merged (docs/method.md eq. 81).
  j["components"] = instance.components;
  j["merge_f"] = std::isfinite(instance.merge_f) ? nlohmann::json(instance.merge_f) : nlohmann::json(nullptr);
  return j;
}

nlohmann::json DetectionJson(const DetectionResult& r) {
  return {{"noise_sigma", r.noise_sigma},
          {"point_spacing", r.point_spacing},
          {"epsilon", r.epsilon},
          {"alpha_rad", r.alpha},
          {"connectivity", r.cluster_cell > 0 ? "grid" : "knn-graph"},
          {"min_support", r.min_support},
          {"octree_levels", r.octree_levels},
          {"stop_reason", r.stop_reason},
          {"final_miss_probability", r.final_miss_probability},
          {"rejected", r.rejected.size()}};
}

DetectOutcome ComputeDetect(const DetectOptions& o) {
  if (o.models.empty()) throw FitFailure(kUsage, "detect: give at least one --model");
  const DetectionOptions options =
      MakeDetectionOptions(o.models, o.max_instances, o.min_support, o.seed, o.epsilon, o.alpha);
  Scan scan;
  std::string format;
  try {
    if (o.views) {
      scan = *InputCloud(o.file, o.views.get());
      format = "memory";
    } else {
      const PointCloudFormat f = DetectFormat(o.file);
      format = ToString(f);
      scan = ReadPointCloud(o.file, f);
    }
  } catch (const FormatError& e) {
    throw FitFailure(kInputError, e.what());
  }
  if (!o.units.empty()) scan.units = o.units;
  const auto start = std::chrono::steady_clock::now();
  DetectionResult result;
  try {
    result = DetectPrimitives(scan.points, options, scan.has_normals() ? scan.normals : Eigen::Matrix3Xd());
  } catch (const std::invalid_argument& e) {
    throw FitFailure(kFitError, o.file + ": " + e.what());
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  DetectOutcome outcome;
  outcome.notes = scan.metadata.notes;
  nlohmann::json& j = outcome.document;
  j["schema"] = "scan2model.detect/1";
  j["input"] = DescribeScan(scan, o.file, format);
  j["models"] = o.models;
  j["seed"] = o.seed;
  j["detection"] = DetectionJson(result);
  j["instances"] = nlohmann::json::array();
  for (const DetectedPrimitive& instance : result.instances)
    j["instances"].push_back(InstanceJson(instance, scan.units));
  j["seconds"] = seconds;

  std::ostringstream t;
  t << "scan2model detect: " << scan.size() << " points of " << o.file << " (" << format << ", units "
    << scan.units << ")\n"
    << "  noise " << Format(result.noise_sigma, 3) << ", spacing " << Format(result.point_spacing, 3)
    << ", epsilon " << Format(result.epsilon, 3) << ", alpha " << Format(result.alpha, 3)
    << " rad, min support " << result.min_support << "\n\n";
  for (std::size_t k = 0; k < result.instances.size(); ++k) {
    const DetectedPrimitive& instance = result.instances[k];
    t << "  #" << k + 1 << " " << ToString(instance.kind) << ": " << instance.support() << " inliers, RMS "
      << Format(instance.rms, 4) << ", epsilon " << Format(instance.epsilon, 3)
      << (instance.components > 1
              ? ", " + std::to_string(instance.components) + " parts cut apart by an occluder, merged (F " +
                    Format(instance.merge_f, 3) + ")"
              : std::string())
      << "\n"
      << ParametersText(instance);
  }
  if (result.instances.empty()) t << "  no instance found\n";
  t << "\n  " << result.rejected.size() << " points in no instance; stopped: " << result.stop_reason
    << " (probability of a missed shape of " << result.min_support << " points "
    << Format(result.final_miss_probability, 2) << "), " << Format(seconds * 1e3, 4) << " ms\n";

  if (!o.output.empty()) {
    std::vector<Eigen::Index> indices;
    std::vector<std::array<int, 3>> colours;
    for (std::size_t k = 0; k < result.instances.size(); ++k) {
      for (Eigen::Index i : result.instances[k].inliers) {
        indices.push_back(i);
        colours.push_back(InstanceColour(k));
      }
    }
    try {
      if (!indices.empty()) WritePointsPly(o.output + "_inliers.ply", scan.points, indices, colours);
      if (!result.rejected.empty()) {
        WritePointsPly(o.output + "_rejected.ply", scan.points, result.rejected,
                       std::vector<std::array<int, 3>>(result.rejected.size(), {128, 128, 128}));
      }
    } catch (const FormatError& e) {
      throw FitFailure(kInputError, e.what());
    }
    j["files"] = {{"inliers", indices.empty() ? "" : o.output + "_inliers.ply"},
                  {"rejected", result.rejected.empty() ? "" : o.output + "_rejected.ply"}};
    t << "  wrote " << o.output << "_inliers.ply (coloured per instance) and " << o.output
      << "_rejected.ply\n";
  }
  outcome.text = t.str();
  return outcome;
}

}  // namespace s2m::pipeline
