// `scan2model fit --model revolution <views.json|.conf|cloud>`: joint registration and fitting of several
// views.

#include <Eigen/Geometry>
#include <chrono>
#include <iomanip>
#include <iostream>
#include <limits>

#include "acquisition/format_error.h"
#include "apps/commands.h"
#include "apps/fit_options.h"
#include "apps/output.h"
#include "apps/views.h"
#include "fitting/initial_models.h"
#include "fitting/joint_fit.h"
#include "fitting/kinematic_surfaces.h"
#include "fitting/primitive_fit.h"

namespace s2m::app {
namespace {

// The frame of the initial axis: z along the axis of the cylinder best fitting all views merged in the world.
RigidMotion InitialAxisFrame(const ScanSet& set) {
  const Cylinder c = FitCylinder(set.MergedWorldPoints()).shape;
  return RigidMotion(FrameWithAxis(c.axis_direction), c.axis_point);
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
    JointFitOptions options = JointOptions(o);  // TDM by default (apps/views.cpp)
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
    j["solver"] = SolverName(options);
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
    std::vector<RigidMotion> corrected;
    for (std::size_t k = 0; k < K; ++k) corrected.push_back(world_T_model_fit * r.model_T_scan[k]);
    j["views"] = ViewsJson(set, corrected, r);
    AddSolverJson(j, r, seconds);
    WriteRequestedFiles(o, j, r);
    if (o.json) {
      std::cout << j.dump(2) << "\n";
      return kOk;
    }
    std::cout << "scan2model fit: surface of revolution to " << K << " views (" << set.TotalPoints()
              << " points) of " << o.file << " (units " << units << ")\n\n"
              << "  solver            " << SolverSummary(options, r, seconds) << "\n"
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
    std::cout << ViewsTable(j["views"]) << UnobservableText(r);
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
