#include "pipeline/views.h"

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <sstream>

#include "acquisition/e57_io.h"
#include "acquisition/format_error.h"
#include "acquisition/frame_source.h"
#include "acquisition/point_cloud_io.h"
#include "acquisition/recording.h"
#include "acquisition/scan_set_io.h"
#include "pipeline/output.h"
#include "registration/scan_to_scan.h"

namespace s2m::pipeline {

ScanSet ReadViews(const std::string& file) {
  const std::string ext = std::filesystem::path(file).extension().string();
  if (ext == ".json" || ext == ".conf") return ReadScanSet(file);
  if (IsE57File(file)) return ReadE57ScanSet(file);  // every data3D scan a view, its pose the view's pose
  // A recording is replayed through the same frame path as a live device: points as they are, depth images
  // back-projected with the stream's intrinsics, the profiles of a sweep gathered into one view.
  if (ext == kRecordingExtension) {
    const std::unique_ptr<FrameSource> source = OpenRecordingSource(file);
    return FramesToScanSet(*source);
  }
  ScanSet set;  // a single cloud: one view in world coordinates
  set.scans.push_back(ReadPointCloud(file));
  return set;
}

const ScanSet& InputViews(const FitOptions& options, ScanSet& storage) {
  if (options.views) return *options.views;
  storage = ReadViews(options.file);
  return storage;
}

std::optional<Scan> InputCloud(const std::string& file, const ScanSet* views) {
  ScanSet storage;
  const ScanSet* set = views;
  if (!set) {
    const std::string extension = std::filesystem::path(file).extension().string();
    if (extension != kRecordingExtension && extension != ".json" && extension != ".conf") return std::nullopt;
    storage = ReadViews(file);
    set = &storage;
  }
  if (set->scans.empty()) throw FormatError(file, "", "no views");
  const Scan& first = set->scans.front();
  // One cloud given in memory in world coordinates: as it is, normals and all.
  if (views && set->scans.size() == 1 && first.world_T_scan.matrix() == Eigen::Matrix4d::Identity())
    return first;
  Scan scan;
  scan.points = set->MergedWorldPoints();
  scan.units = first.units;
  scan.metadata = first.metadata;
  scan.metadata.source = file;
  return scan;
}

JointFitOptions JointOptions(const FitOptions& o) {
  JointFitOptions options;
  // TDM by default (measured on the demo vase, 4 noisy views: TDM 16 iterations, 0.3 s; SDM still creeping
  // after 200, 2 s, to the same result): SDM's tangential terms damp the profile's re-parametrization, the
  // slow direction once the data sit at the noise level (docs/registration.md).
  options.error_term = ErrorTermFromString(o.method.empty() ? "tdm" : o.method);
  options.optimizer.max_iterations = o.max_iterations;
  options.optimizer.loss = o.loss;
  options.alternating = o.alternating;
  options.per_scan_motions = !o.register_then_fit;
  return options;
}

std::string SolverName(const JointFitOptions& options) {
  return options.alternating ? "alternating" : options.per_scan_motions ? "joint" : "register-then-fit";
}

nlohmann::json ViewsJson(const ScanSet& set, const std::vector<RigidMotion>& world_T_scan,
                         const JointFitResult& result) {
  nlohmann::json views = nlohmann::json::array();
  for (std::size_t k = 0; k < set.scans.size(); ++k) {
    const RigidMotion correction = world_T_scan[k] * set.scans[k].world_T_scan.inverse();
    nlohmann::json v = {{"source", set.scans[k].metadata.source},
                        {"points", set.scans[k].size()},
                        {"rms", result.per_scan[k].rms},
                        {"max_abs", result.per_scan[k].max_abs},
                        {"world_T_scan", ToJson(world_T_scan[k].matrix())},
                        {"correction",
                         {{"rotation_deg", correction.angle() * 180.0 / M_PI},
                          {"translation", correction.translation().norm()}}}};
    if (k < result.pose_uncertainty.size()) {
      const ScanPoseUncertainty& pu = result.pose_uncertainty[k];
      v["pose_uncertainty"] = {{"rotation_deg", ToJson(Eigen::Vector3d(pu.rotation * 180.0 / M_PI))},
                               {"translation", ToJson(pu.translation)}};
    }
    views.push_back(std::move(v));
  }
  return views;
}

std::string ViewsTable(const nlohmann::json& views) {
  std::ostringstream t;
  t << "\n  view   points        RMS    pose correction (deg, translation)\n";
  for (std::size_t k = 0; k < views.size(); ++k) {
    const nlohmann::json& v = views[k];
    t << "  " << std::setw(4) << k << std::setw(9) << v["points"].get<long long>() << std::setw(11)
      << Format(v["rms"].get<double>(), 4) << "    "
      << Format(v["correction"]["rotation_deg"].get<double>(), 3) << ", "
      << Format(v["correction"]["translation"].get<double>(), 3) << "\n";
  }
  return t.str();
}

void AddSolverJson(nlohmann::json& j, const JointFitResult& result, double seconds) {
  j["residuals"] = {{"count", result.residuals.count},
                    {"rms", result.residuals.rms},
                    {"max_abs", result.residuals.max_abs}};
  j["iterations"] = result.iterations;
  j["shared_iterations"] = result.shared_iterations;
  j["stop_reason"] = ToString(result.stop_reason);
  j["unobservable"] = result.unobservable;
  j["seconds"] = seconds;
  j["history"] = HistoryJson(result.history);
}

std::string SolverSummary(const JointFitOptions& options, const JointFitResult& result, double seconds) {
  return SolverName(options) + " registration and fitting, " + ToString(options.error_term) + ", " +
         std::to_string(result.iterations) + " iterations (" + std::to_string(result.shared_iterations) +
         " with one shared motion), stopped: " + ToString(result.stop_reason) + ", " +
         Format(seconds * 1e3, 4) + " ms";
}

std::string UnobservableText(const JointFitResult& result) {
  if (result.unobservable.empty()) return "";
  std::string text = "\n  unobservable:";
  for (const std::string& u : result.unobservable) text += " " + u + ";";
  return text + "\n";
}

void WriteRequestedFiles(const FitOptions& o, const nlohmann::json& document, const JointFitResult& result) {
  if (!o.output.empty()) WriteTextAtomically(o.output + ".json", document.dump(2) + "\n");
  if (!o.history.empty()) WriteTextAtomically(o.history, HistoryCsv(result.history));
}

RigidMotion PlaceModelInWorld(const ScanSet& set, const std::vector<RigidMotion>& model_T_scan) {
  const std::size_t K = set.scans.size();
  const RigidMotion world_T_model = set.scans[0].world_T_scan * model_T_scan[0].inverse();
  Eigen::Vector3d mean_rotation = Eigen::Vector3d::Zero(), mean_translation = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < K; ++k) {
    const RigidMotion correction = world_T_model * model_T_scan[k] * set.scans[k].world_T_scan.inverse();
    const Eigen::AngleAxisd aa(correction.rotation());
    mean_rotation += aa.angle() * aa.axis() / static_cast<double>(K);
    mean_translation += correction.translation() / static_cast<double>(K);
  }
  const RigidMotion mean_correction(
      Eigen::AngleAxisd(mean_rotation.norm(), mean_rotation.norm() > 0
                                                  ? Eigen::Vector3d(mean_rotation.normalized())
                                                  : Eigen::Vector3d::UnitZ())
          .toRotationMatrix(),
      mean_translation);
  return mean_correction.inverse() * world_T_model;
}

std::vector<Eigen::Matrix3Xd> ViewNormals(const ScanSet& set) {
  std::vector<Eigen::Matrix3Xd> normals;
  for (const Scan& s : set.scans) {
    try {
      normals.push_back(EstimateNormals(s.points, 12));
    } catch (const std::invalid_argument&) {
      normals.emplace_back();
    }
  }
  return normals;
}

nlohmann::json MultiViewDocumentHead(const FitOptions& o, const ScanSet& set, const JointFitOptions& options,
                                     double loss_scale, const Eigen::Vector3d& axis_point,
                                     const Eigen::Vector3d& axis_direction, const std::string& units) {
  nlohmann::json j;
  j["schema"] = "scan2model.multiview/1";
  j["input"] = {
      {"file", o.file}, {"views", set.scans.size()}, {"points", set.TotalPoints()}, {"units", units}};
  j["model"] = o.model;
  j["method"] = ToString(options.error_term);
  j["solver"] = SolverName(options);
  j["loss"] = LossJson(o.loss, loss_scale, Eigen::VectorXd());
  j["loss"]["reason"] = o.loss_reason;
  j["axis"] = {{"point", ToJson(axis_point)}, {"direction", ToJson(axis_direction)}};
  return j;
}

}  // namespace s2m::pipeline
