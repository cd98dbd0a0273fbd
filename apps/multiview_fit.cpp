// `scan2model fit --model revolution <views.json|.conf|cloud>`: joint registration and fitting of several
// views.

#include <Eigen/Geometry>
#include <chrono>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <limits>

#include "acquisition/format_error.h"
#include "acquisition/point_cloud_io.h"
#include "acquisition/scan_set_io.h"
#include "apps/commands.h"
#include "apps/fit_options.h"
#include "apps/output.h"
#include "fitting/initial_models.h"
#include "fitting/joint_fit.h"
#include "fitting/kinematic_surfaces.h"
#include "fitting/primitive_fit.h"

namespace s2m::app {
namespace {

ScanSet ReadViews(const std::string& file) {
  const std::string ext = std::filesystem::path(file).extension().string();
  if (ext == ".json" || ext == ".conf") return ReadScanSet(file);
  ScanSet set;  // a single cloud: one view in world coordinates
  set.scans.push_back(ReadPointCloud(file));
  return set;
}

// The frame of the initial axis: z along the axis of the cylinder best fitting all views merged in the world.
RigidMotion InitialAxisFrame(const ScanSet& set) {
  const Cylinder c = FitCylinder(set.MergedWorldPoints()).shape;
  return RigidMotion(FrameWithAxis(c.axis_direction), c.axis_point);
}

nlohmann::json PoseJson(const RigidMotion& m) {
  return ToJson(m.matrix());
}

}  // namespace

int RunMultiViewFit(const FitOptions& o) {
  try {
    if (o.model != "revolution")
      throw std::invalid_argument("multi-view fitting supports --model revolution so far");
    const ScanSet set = ReadViews(o.file);
    const std::size_t K = set.scans.size();
    const int n = o.control_points.empty() ? 8 : std::stoi(o.control_points);
    // Model frame: the initial axis. Scans start at their given world poses, expressed in that frame.
    const RigidMotion world_T_model = InitialAxisFrame(set);
    const RigidMotion model_T_world = world_T_model.inverse();
    std::vector<Eigen::Matrix3Xd> scans;
    std::vector<RigidMotion> initial;
    for (const Scan& s : set.scans) {
      scans.push_back(s.points);
      initial.push_back(model_T_world * s.world_T_scan);
    }
    KinematicSurface pot = InitialRevolution(model_T_world.apply(set.MergedWorldPoints()), n, o.order);
    JointFitOptions options;
    // TDM by default here (measured on the demo vase, 4 noisy views: TDM 16 iterations, 0.3 s; SDM still
    // creeping after 200, 2 s, to the same result): SDM's tangential terms damp the profile's
    // re-parametrization, the slow direction once the data sit at the noise level (docs/registration.md).
    options.error_term = ErrorTermFromString(o.method.empty() ? "tdm" : o.method);
    options.max_iterations = o.max_iterations;
    options.alternating = o.alternating;
    options.per_scan_motions = !o.register_then_fit;
    options.fairness = {o.stretch, o.bending};
    const auto start = std::chrono::steady_clock::now();
    const JointFitResult r = FitJointly(pot, scans, initial, options);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

    // Report in the data's world. The fit fixes the views only relative to each other and to the model; place
    // the result so that the views' pose corrections average to zero (the least total correction: no single
    // device pose is trusted more than the others).
    RigidMotion world_T_model_fit = set.scans[0].world_T_scan * r.model_T_scan[0].inverse();
    Eigen::Vector3d mean_rotation = Eigen::Vector3d::Zero(), mean_translation = Eigen::Vector3d::Zero();
    for (std::size_t k = 0; k < K; ++k) {
      const RigidMotion correction =
          world_T_model_fit * r.model_T_scan[k] * set.scans[k].world_T_scan.inverse();
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
    world_T_model_fit = mean_correction.inverse() * world_T_model_fit;
    const Eigen::Vector3d axis_point = world_T_model_fit.translation();
    const Eigen::Vector3d axis_direction = world_T_model_fit.rotation().col(2);
    const std::string units = o.units.empty() ? set.scans[0].units : o.units;

    nlohmann::json j;
    j["schema"] = "scan2model.multiview/1";
    j["input"] = {{"file", o.file}, {"views", K}, {"points", set.TotalPoints()}, {"units", units}};
    j["model"] = o.model;
    j["method"] = ToString(options.error_term);
    j["solver"] = options.alternating        ? "alternating"
                  : options.per_scan_motions ? "joint"
                                             : "register-then-fit";
    j["axis"] = {{"point", ToJson(axis_point)}, {"direction", ToJson(axis_direction)}};
    std::vector<std::vector<double>> profile_cp, samples;
    for (Eigen::Index i = 0; i < pot.profile().cols(); ++i)
      profile_cp.push_back({pot.profile()(0, i), pot.profile()(1, i)});
    std::vector<double> radius_uncertainty;
    for (int i = 0; i <= 50; ++i) {
      const Eigen::Vector2d rz =
          pot.ProfilePoint(pot.basis().lo() + (pot.basis().hi() - pot.basis().lo()) * i / 50);
      samples.push_back({rz.y(), rz.x()});  // (height along the axis from the axis point, radius)
      // The radius at that height, with its standard uncertainty propagated from the shape covariance.
      double u = std::numeric_limits<double>::quiet_NaN();
      if (r.shape_covariance.size() > 0) {
        try {
          Eigen::VectorXd gradient;
          pot.RadiusAtHeight(rz.y(), &gradient);
          u = std::sqrt(gradient.dot(r.shape_covariance * gradient));
        } catch (const std::domain_error&) {  // the profile turns back in height there: no radius function
        }
      }
      radius_uncertainty.push_back(u);
    }
    j["profile"] = {{"order", pot.basis().order()},
                    {"knots", pot.basis().knots()},
                    {"control_points_radius_height", profile_cp},
                    {"samples_height_radius", samples}};
    j["profile"]["samples_radius_uncertainty"] = nlohmann::json::array();
    for (double u : radius_uncertainty) {
      j["profile"]["samples_radius_uncertainty"].push_back(std::isfinite(u) ? nlohmann::json(u)
                                                                            : nlohmann::json(nullptr));
    }
    j["views"] = nlohmann::json::array();
    for (std::size_t k = 0; k < K; ++k) {
      const RigidMotion corrected = world_T_model_fit * r.model_T_scan[k];
      const RigidMotion correction = corrected * set.scans[k].world_T_scan.inverse();
      j["views"].push_back({{"source", set.scans[k].metadata.source},
                            {"points", set.scans[k].size()},
                            {"rms", r.per_scan[k].rms},
                            {"max_abs", r.per_scan[k].max_abs},
                            {"world_T_scan", PoseJson(corrected)},
                            {"correction",
                             {{"rotation_deg", correction.angle() * 180.0 / M_PI},
                              {"translation", correction.translation().norm()}}}});
      if (k < r.pose_uncertainty.size()) {
        const ScanPoseUncertainty& pu = r.pose_uncertainty[k];
        j["views"][k]["pose_uncertainty"] = {
            {"rotation_deg", ToJson(Eigen::Vector3d(pu.rotation * 180.0 / M_PI))},
            {"translation", ToJson(pu.translation)}};
      }
    }
    j["residuals"] = {
        {"count", r.residuals.count}, {"rms", r.residuals.rms}, {"max_abs", r.residuals.max_abs}};
    j["iterations"] = r.iterations;
    j["shared_iterations"] = r.shared_iterations;
    j["stop_reason"] = ToString(r.stop_reason);
    j["unobservable"] = r.unobservable;
    j["seconds"] = seconds;
    j["history"] = HistoryJson(r.history);
    if (!o.output.empty()) WriteTextAtomically(o.output + ".json", j.dump(2) + "\n");
    if (!o.history.empty()) WriteTextAtomically(o.history, HistoryCsv(r.history));
    if (o.json) {
      std::cout << j.dump(2) << "\n";
      return kOk;
    }
    std::cout << "scan2model fit: surface of revolution to " << K << " views (" << set.TotalPoints()
              << " points) of " << o.file << " (units " << units << ")\n\n"
              << "  solver            " << j["solver"].get<std::string>() << " registration and fitting, "
              << ToString(options.error_term) << ", " << r.iterations << " iterations ("
              << r.shared_iterations << " with one shared motion), stopped: " << ToString(r.stop_reason)
              << ", " << Format(seconds * 1e3, 4) << " ms\n"
              << "  axis point        " << Format(axis_point) << "\n"
              << "  axis direction    " << Format(axis_direction) << "\n"
              << "  residuals         RMS " << Format(r.residuals.rms, 6) << ", max "
              << Format(r.residuals.max_abs, 6)
              << "\n\n  profile (height along the axis, radius, standard uncertainty of the radius)\n";
    for (int i = 0; i <= 50; i += 5) {
      const double u = radius_uncertainty[static_cast<std::size_t>(i)];
      std::cout << "  " << std::setw(14) << Format(samples[static_cast<std::size_t>(i)][0], 6)
                << std::setw(14) << Format(samples[static_cast<std::size_t>(i)][1], 6) << std::setw(12)
                << (std::isfinite(u) ? Format(u, 2) : std::string("-")) << "\n";
    }
    std::cout << "\n  view   points        RMS    pose correction (deg, translation)\n";
    for (std::size_t k = 0; k < K; ++k) {
      const auto& v = j["views"][k];
      std::cout << "  " << std::setw(4) << k << std::setw(9) << v["points"].get<int>() << std::setw(11)
                << Format(v["rms"].get<double>(), 4) << "    "
                << Format(v["correction"]["rotation_deg"].get<double>(), 3) << ", "
                << Format(v["correction"]["translation"].get<double>(), 3) << "\n";
    }
    if (!r.unobservable.empty()) {
      std::cout << "\n  unobservable:";
      for (const std::string& u : r.unobservable) std::cout << " " << u << ";";
      std::cout << "\n";
    }
    if (o.verbose) std::cout << HistoryTable(r.history);
    return kOk;
  } catch (const FormatError& e) {
    return ReportError("fit", e.what(), kInputError, o.json);
  } catch (const std::invalid_argument& e) {
    return ReportError("fit", o.file + ": " + e.what(), kUsage, o.json);
  } catch (const std::exception& e) {
    return ReportError("fit", o.file + ": " + e.what(), kFitError, o.json);
  }
}

}  // namespace s2m::app
