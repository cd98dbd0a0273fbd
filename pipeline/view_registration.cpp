#include "pipeline/view_registration.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <functional>
#include <iomanip>
#include <sstream>
#include <stdexcept>

#include "acquisition/format_error.h"
#include "acquisition/formats/readers.h"
#include "acquisition/mesh_io.h"
#include "acquisition/part_file.h"
#include "acquisition/scan_set_io.h"
#include "fitting/fe_surface_model.h"
#include "fitting/foot_point.h"
#include "fitting/model_registration.h"
#include "fitting/nominal_inspection.h"
#include "fitting/part_model.h"
#include "pipeline/fit_options.h"
#include "pipeline/output.h"
#include "pipeline/surface_model_json.h"
#include "pipeline/views.h"
#include "registration/scan_to_scan.h"

namespace s2m::pipeline {

namespace {

constexpr double kDegree = M_PI / 180.0;

// One view's entry of the document: where it came from, its corrected pose, the correction relative to the
// pose it was read with, and its residuals (`residuals`: rms, max and how they were measured).
nlohmann::json ViewEntry(const Scan& scan, const RigidMotion& world_T_scan, nlohmann::json residuals) {
  const RigidMotion correction = world_T_scan * scan.world_T_scan.inverse();
  nlohmann::json v = {
      {"source", scan.metadata.source},
      {"points", scan.size()},
      {"world_T_scan", ToJson(world_T_scan.matrix())},
      {"correction",
       {{"rotation_deg", correction.angle() / kDegree}, {"translation", correction.translation().norm()}}}};
  v.update(residuals);
  return v;
}

// A view's residuals after registering it to a fixed model (a nominal mesh, a fitted part).
nlohmann::json ModelRegistrationJson(const ModelRegistrationResult& res) {
  return {{"rms", res.residuals.rms},
          {"max", res.residuals.max_abs},
          {"pairs", res.residuals.count},
          {"iterations", res.iterations},
          {"stop_reason", ToString(res.stop_reason)},
          {"registered", true}};
}

std::string ViewTable(const nlohmann::json& views, const std::string& units) {
  std::ostringstream t;
  t << "\n  view   points        RMS        max    pairs   correction (deg, " << units << ")\n";
  for (std::size_t k = 0; k < views.size(); ++k) {
    const nlohmann::json& v = views[k];
    const auto number = [&v](const char* key) {
      return v[key].is_number() ? Format(v[key].get<double>(), 4) : std::string("-");
    };
    t << "  " << std::setw(4) << k << std::setw(9) << v["points"].get<long long>() << std::setw(11)
      << number("rms") << std::setw(11) << number("max") << std::setw(9) << v["pairs"].get<long long>()
      << "   " << Format(v["correction"]["rotation_deg"].get<double>(), 3) << ", "
      << Format(v["correction"]["translation"].get<double>(), 3)
      << (v.value("registered", true) ? "" : "   NOT REGISTERED") << "\n";
  }
  return t.str();
}

ScanErrorTerm ScanTerm(const std::string& method) {
  if (method == "pdm") return ScanErrorTerm::kPdm;
  if (method == "tdm") return ScanErrorTerm::kTdm;
  if (method == "sdm") return ScanErrorTerm::kSdm;
  throw FitFailure(kUsage, "--method: registration takes pdm, tdm or sdm, not '" + method + "'");
}

// A rigid motion's size as the notes give it: "0.0123 deg, 0.0456 mm" (rotation in rad on input).
std::string MotionSize(double angle, double shift, const std::string& units) {
  return Format(angle * 180.0 / M_PI, 3) + " deg, " + Format(shift, 3) + " " + units;
}

void ScanToScan(const RegisterOptions& o, const ScanSet& views, const RegisterProgress& progress,
                RegisterOutcome& outcome, std::vector<RigidMotion>& world_T_scan) {
  const std::size_t K = views.scans.size();
  if (K < 2)
    throw FitFailure(kInputError, o.input + " holds " + std::to_string(K) +
                                      " view: registering views to each other needs two or more (give --to "
                                      "NOMINAL to register one view to a mesh)");
  if (o.fixed_view >= K)
    throw FitFailure(kUsage, "--fixed-view " + std::to_string(o.fixed_view) + ": " + o.input +
                                 " has views 0-" + std::to_string(K - 1));
  ScanToScanOptions options;
  options.error_term = ScanTerm(o.method);
  options.samples_per_view = o.samples_per_view;
  options.max_sweeps = o.max_sweeps;
  options.fixed_view = o.fixed_view;
  const std::string units = views.scans[0].units;
  if (progress) {
    options.progress = [&](int sweep, double rms) {
      std::ostringstream line;
      line << "sweep " << sweep << ": RMS " << Format(rms, 4) << " " << units;
      progress(line.str());
    };
  }
  std::vector<Eigen::Matrix3Xd> scans;
  std::vector<RigidMotion> start;
  for (std::size_t k = 0; k < K; ++k) {
    const Scan& s = views.scans[k];
    if (s.empty()) throw FitFailure(kInputError, o.input + ": view " + std::to_string(k) + " has no points");
    scans.push_back(s.points);
    start.push_back(s.world_T_scan);
  }
  const auto t0 = std::chrono::steady_clock::now();
  ScanToScanResult r;
  try {
    r = RegisterScansToEachOther(scans, start, options);
  } catch (const std::invalid_argument& e) {
    throw FitFailure(kInputError, o.input + ": " + e.what());
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  world_T_scan = r.world_T_scan;
  outcome.unregistered_views = r.unconstrained_views;

  nlohmann::json entries = nlohmann::json::array();
  for (std::size_t k = 0; k < K; ++k) {
    const ScanToScanViewResidual& res = r.view_residuals[k];
    nlohmann::json overlaps = nlohmann::json::array();
    for (std::size_t l = 0; l < K; ++l) {
      const int n = r.overlap(static_cast<Eigen::Index>(k), static_cast<Eigen::Index>(l));
      if (n > 0) overlaps.push_back({{"view", l}, {"pairs", n}});
    }
    const bool registered = std::find(r.unconstrained_views.begin(), r.unconstrained_views.end(), k) ==
                            r.unconstrained_views.end();
    entries.push_back(ViewEntry(views.scans[k], r.world_T_scan[k],
                                {{"rms", res.rms},
                                 {"max", res.max},
                                 {"pairs", res.pairs},
                                 {"samples", res.samples},
                                 {"correspondence_distance", res.correspondence_distance},
                                 {"overlaps", overlaps},
                                 {"fixed", k == o.fixed_view},
                                 {"registered", registered}}));
  }
  nlohmann::json& j = outcome.document;
  j["mode"] = "scan-to-scan";
  j["sweeps"] = r.sweeps;
  j["converged"] = r.converged;
  if (options.error_term == ScanErrorTerm::kPdm) j["stalled"] = r.stalled;
  j["last_step"] = {{"angle_deg", r.last_step_angle * 180.0 / M_PI}, {"displacement", r.last_step_shift}};
  j["rms_per_sweep"] = r.rms_per_sweep;
  if (options.error_term == ScanErrorTerm::kPdm)
    j["pending_point_to_plane_step"] = {{"angle_deg", r.pending_plane_angle * 180.0 / M_PI},
                                        {"displacement", r.pending_plane_shift}};
  j["fixed_view"] = o.fixed_view;
  j["samples_per_view"] = o.samples_per_view;
  j["seconds"] = seconds;
  j["views"] = entries;

  std::ostringstream text;
  text << "scan2model register: " << K << " views of " << o.input << " to each other (" << o.method
       << ", view " << o.fixed_view << " fixed), " << r.sweeps << " sweeps, "
       << (r.converged ? "converged"
           : r.stalled ? "stalled (not converged)"
                       : "stopped at the sweep cap")
       << ", " << Format(seconds, 3) << " s\n";
  text << ViewTable(entries, units);
  text << "\n  RMS and max: distances of each view's accepted pairs to the other views' local "
       << (options.error_term == ScanErrorTerm::kSdm ? "quadrics" : "planes") << " (" << units
       << "), measured in the last sweep\n";
  outcome.text = text.str();
  if (r.stalled) {
    // PDM's own steps settled while the views are still off each other's surfaces (its pairs with the nearest
    // sample hold them): how far, by the point-to-plane step the same pairs still ask for.
    outcome.notes.push_back(
        "point-to-point pairs stalled after " + std::to_string(r.sweeps) +
        " sweeps short of the surfaces: the point-to-plane step of the same pairs is still " +
        MotionSize(r.pending_plane_angle, r.pending_plane_shift, units) +
        ": the poses have not reached the surfaces' fit (use --method tdm)");
  } else if (!r.converged) {
    std::string note = "the poses still moved by more than the tolerances after " + std::to_string(r.sweeps) +
                       " sweeps (--max-sweeps; the last sweep moved a view by up to " +
                       MotionSize(r.last_step_angle, r.last_step_shift, units) +
                       "): check the views' overlap";
    if (options.error_term == ScanErrorTerm::kPdm)
      note += "; the point-to-plane step of the last sweep's pairs was " +
              MotionSize(r.pending_plane_angle, r.pending_plane_shift, units);
    outcome.notes.push_back(note);
  }
}

// One progress line per iteration of a registration to a model: "view 3: iteration 2: RMS 0.0123 mm" (view
// -1: all views as one rigid body).
void TellIteration(const RegisterProgress& progress, int view, int iteration, double rms,
                   const std::string& units) {
  std::ostringstream line;
  line << (view < 0 ? std::string("all views") : "view " + std::to_string(view)) << ": iteration "
       << iteration << ": RMS " << Format(rms, 4) << " " << units;
  progress(line.str());
}

void ToNominal(const RegisterOptions& o, const ScanSet& views, const RegisterProgress& progress,
               RegisterOutcome& outcome, std::vector<RigidMotion>& world_T_scan) {
  NominalInspectionOptions options;
  options.registration.error_term = ErrorTermFromString(o.method);
  options.per_view = o.per_view;
  TriangleMesh mesh;
  MeshFormat format{};
  const std::string units = !o.units.empty() ? o.units : views.scans[0].units;
  try {
    mesh = ReadMesh(o.to, units, &format);
  } catch (const FormatError& e) {
    throw FitFailure(kInputError, e.what());
  }
  if (mesh.units != "unknown" && views.scans[0].units != "unknown" && mesh.units != views.scans[0].units)
    throw FitFailure(kInputError, "the nominal " + o.to + " is in " + mesh.units + " but the views " +
                                      o.input + " are in " + views.scans[0].units +
                                      " (give --units to override the nominal's)");
  std::vector<Eigen::Matrix3Xd> scans;
  std::vector<RigidMotion> start;
  for (std::size_t k = 0; k < views.scans.size(); ++k) {
    if (views.scans[k].empty())
      throw FitFailure(kInputError, o.input + ": view " + std::to_string(k) + " has no points");
    scans.push_back(views.scans[k].points);
    start.push_back(views.scans[k].world_T_scan);
  }
  if (progress) {
    progress("registering " + std::to_string(scans.size()) + " views to " + o.to + " (" +
             std::to_string(mesh.triangle_count()) + " triangles)");
    options.progress = [&progress, &views](int view, int iteration, double rms) {
      TellIteration(progress, view, iteration, rms, views.scans[0].units);
    };
  }
  const auto t0 = std::chrono::steady_clock::now();
  NominalInspection r;
  try {
    r = InspectAgainstNominal(TriangleMeshModel(mesh), scans, start, options);
  } catch (const std::invalid_argument& e) {
    throw FitFailure(kFitError, std::string("registration to the nominal failed: ") + e.what());
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  world_T_scan = r.nominal_T_scan;
  nlohmann::json entries = nlohmann::json::array();
  for (std::size_t k = 0; k < scans.size(); ++k) {
    const ModelRegistrationResult& res = r.registration[o.per_view ? k : 0];
    entries.push_back(ViewEntry(views.scans[k], r.nominal_T_scan[k], ModelRegistrationJson(res)));
  }
  nlohmann::json& j = outcome.document;
  j["mode"] = "to-nominal";
  j["nominal"] = {{"file", o.to}, {"format", ToString(format)}, {"triangles", mesh.triangle_count()}};
  j["per_view"] = o.per_view;
  j["views_on_common_pose"] = r.views_on_common_pose;
  j["seconds"] = seconds;
  j["views"] = entries;
  std::ostringstream text;
  text << "scan2model register: " << scans.size() << " views of " << o.input << " to the nominal " << o.to
       << " (" << o.method << (o.per_view ? ", common then per view" : ", as one rigid body") << "), "
       << Format(seconds, 3) << " s\n"
       << ViewTable(entries, views.scans[0].units)
       << "\n  RMS and max: distances of each view's points to the nominal's triangles ("
       << views.scans[0].units << ")"
       << (o.per_view ? "" : "; with --no-per-view every view shows the common fit's residuals") << "\n";
  outcome.text = text.str();
  if (r.views_on_common_pose > 0)
    outcome.notes.push_back(std::to_string(r.views_on_common_pose) +
                            " view(s) kept the common pose: their own points leave a motion free");
}

// The part a `fit --model part:` document measured: its part file (found as the document names it, else
// beside the document) with the fitted values of the free parameters (angles in the document in degrees).
PartModel FittedPart(const nlohmann::json& fit, const std::string& fit_file, std::string& part_path) {
  part_path = fit.at("part").at("file").get<std::string>();
  if (!std::filesystem::exists(part_path)) {
    const std::filesystem::path beside = std::filesystem::path(fit_file).parent_path() / part_path;
    if (std::filesystem::exists(beside)) part_path = beside.string();
  }
  PartFile file;
  try {
    file = ReadPartFile(part_path);
  } catch (const FormatError& e) {
    throw FitFailure(kInputError, fit_file + ": its part file: " + e.what());
  }
  PartDefinition definition = file.definition;
  for (PartParameter& p : definition.parameters) {
    bool found = false;
    for (const nlohmann::json& fitted : fit.at("parameters")) {
      if (fitted.at("name").get<std::string>() != p.name) continue;
      p.value = fitted.at("value").get<double>() * (p.angle ? M_PI / 180.0 : 1.0);
      found = true;
    }
    if (!found)
      throw FitFailure(kInputError, fit_file + ": no fitted value of the part's parameter '" + p.name +
                                        "' (" + part_path + " is not the part this fit measured)");
  }
  try {
    return PartModel(std::move(definition));
  } catch (const std::invalid_argument& e) {
    throw FitFailure(kInputError, fit_file + ": the fitted part is not valid: " + e.what());
  }
}

void ToFittedPart(const RegisterOptions& o, const nlohmann::json& fit, const ScanSet& views,
                  const RegisterProgress& progress, RegisterOutcome& outcome,
                  std::vector<RigidMotion>& world_T_scan) {
  std::string part_path;
  PartModel part = [&] {
    try {
      return FittedPart(fit, o.to, part_path);
    } catch (const nlohmann::json::exception& e) {
      throw FitFailure(kInputError, o.to + ": malformed part fit document: " + e.what());
    }
  }();
  const std::string fit_units = fit.value("/part/units"_json_pointer, std::string("unknown"));
  const std::string units = views.scans[0].units;
  if (fit_units != "unknown" && !fit_units.empty() && units != "unknown" && fit_units != units)
    throw FitFailure(kInputError, "the fitted part " + o.to + " is in " + fit_units + " but the views " +
                                      o.input + " are in " + units);
  ModelRegistrationOptions options;
  options.error_term = ErrorTermFromString(o.method);
  ScanSet registered = views;
  for (std::size_t k = 0; k < registered.scans.size(); ++k) {
    if (registered.scans[k].empty())
      throw FitFailure(kInputError, o.input + ": view " + std::to_string(k) + " has no points");
  }
  if (progress)
    progress("registering " + std::to_string(views.scans.size()) + " views to the part measured in " + o.to);
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<ModelRegistrationResult> results;
  try {
    std::function<void(std::size_t, int, double)> tell;
    if (progress) {
      tell = [&progress, &units](std::size_t k, int iteration, double rms) {
        TellIteration(progress, static_cast<int>(k), iteration, rms, units);
      };
    }
    results = RegisterScansToModel(part, RigidMotion(), registered, options, tell);
  } catch (const std::invalid_argument& e) {
    throw FitFailure(kFitError, std::string("registration to the fitted part failed: ") + e.what());
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  nlohmann::json entries = nlohmann::json::array();
  for (std::size_t k = 0; k < registered.scans.size(); ++k) {
    world_T_scan.push_back(registered.scans[k].world_T_scan);
    const ModelRegistrationResult& res = results[k];
    entries.push_back(ViewEntry(views.scans[k], world_T_scan.back(), ModelRegistrationJson(res)));
  }
  nlohmann::json& j = outcome.document;
  j["mode"] = "to-part-fit";
  j["part_fit"] = {{"file", o.to}, {"part", part_path}, {"parameters", part.num_parameters()}};
  j["seconds"] = seconds;
  j["views"] = entries;
  std::ostringstream text;
  text << "scan2model register: " << views.scans.size() << " views of " << o.input
       << " to the part measured in " << o.to << " (" << part_path << ", " << o.method
       << ", each view on its own), " << Format(seconds, 3) << " s\n"
       << ViewTable(entries, units) << "\n  RMS and max: distances of each view's points to the fitted part ("
       << units << ")\n";
  outcome.text = text.str();
}

// The points of a view at `world_T_scan` that have an orthogonal foot inside the FE surface's domain (the
// others lie beyond the patch's edge: their nearest surface point is on its boundary and their residual is
// not along the normal), with those feet's unit normals.
struct PatchOverlap {
  std::vector<Eigen::Index> inside;
  Eigen::Matrix3Xd points, normals;  // of `inside`, in the world
};

PatchOverlap OverlapWithPatch(const FeSurfaceModel& surface, const Eigen::Matrix3Xd& scan,
                              const RigidMotion& world_T_scan) {
  const Eigen::Matrix3Xd world = world_T_scan.apply(scan);
  std::vector<FootPoint> feet;
  ComputeFootPoints(surface, world, feet);
  PatchOverlap o;
  std::vector<Eigen::Vector3d> normals;
  LocalGeometry g;
  for (Eigen::Index i = 0; i < world.cols(); ++i) {
    const FootPoint& f = feet[static_cast<std::size_t>(i)];
    if (f.on_boundary || f.excluded || !surface.InDomain(f.t)) continue;
    surface.Evaluate(f.t, 1, g);
    const Eigen::Vector3d n = Eigen::Vector3d(g.d1.col(0)).cross(Eigen::Vector3d(g.d1.col(1))).normalized();
    const Eigen::Vector3d r = world.col(i) - Eigen::Vector3d(g.point);
    // An orthogonal foot: the residual's tangential part is rounding error of Newton's stop (relative 1e-3
    // allows for it); a foot held on the domain's edge leaves a tangential part of the order of the residual.
    if ((r - r.dot(n) * n).norm() > 1e-3 * r.norm() + 1e-12) continue;
    o.inside.push_back(i);
    normals.push_back(n);
  }
  o.points.resize(3, static_cast<Eigen::Index>(o.inside.size()));
  o.normals.resize(3, o.points.cols());
  for (std::size_t k = 0; k < o.inside.size(); ++k) {
    o.points.col(static_cast<Eigen::Index>(k)) = world.col(o.inside[k]);
    o.normals.col(static_cast<Eigen::Index>(k)) = normals[k];
  }
  return o;
}

// Views registered to a fitted FE surface (scan2model.fe-surface/1, its mesh in data coordinates): each view
// on its own from its manifest pose, with only its points whose foot is inside the patch (chosen again from
// the new pose, up to 5 rounds, until the choice no longer changes). A view the patch does not hold (its
// points' normals leave a motion free, PoseConditioning under 1e-3: a view of a flat or cylindrical part of
// the patch, or fewer than 6 points on it) is reported as not registered and keeps its pose.
void ToFittedFeSurface(const RegisterOptions& o, const nlohmann::json& fit, const ScanSet& views,
                       const RegisterProgress& progress, RegisterOutcome& outcome,
                       std::vector<RigidMotion>& world_T_scan) {
  std::unique_ptr<FeSurfaceModel> surface;
  try {
    surface = std::make_unique<FeSurfaceModel>(FeSurfaceFromJson(fit.at("mesh")));
  } catch (const nlohmann::json::exception& e) {
    throw FitFailure(kInputError, o.to + ": malformed fe-surface document: " + e.what());
  } catch (const std::invalid_argument& e) {
    throw FitFailure(kInputError, o.to + ": malformed fe-surface document: " + e.what());
  }
  const std::string fit_units = fit.value("/input/units"_json_pointer, std::string("unknown"));
  const std::string units = views.scans[0].units;
  if (fit_units != "unknown" && !fit_units.empty() && units != "unknown" && fit_units != units)
    throw FitFailure(kInputError, "the fitted surface " + o.to + " is in " + fit_units + " but the views " +
                                      o.input + " are in " + units);
  ModelRegistrationOptions options;
  options.error_term = ErrorTermFromString(o.method);
  if (progress)
    progress("registering " + std::to_string(views.scans.size()) +
             " views to the finite-element surface of " + o.to + " (" +
             std::to_string(surface->surface().triangle_count()) + " triangles)");
  constexpr double kMinConditioning = 1e-3;
  const auto t0 = std::chrono::steady_clock::now();
  nlohmann::json entries = nlohmann::json::array();
  for (std::size_t k = 0; k < views.scans.size(); ++k) {
    const Scan& scan = views.scans[k];
    if (scan.empty())
      throw FitFailure(kInputError, o.input + ": view " + std::to_string(k) + " has no points");
    RigidMotion pose = scan.world_T_scan;
    ModelRegistrationResult result;
    const ModelRegistrationOptions view_options =
        progress ? WithProgress(options,
                                [&progress, &units, k](int iteration, double rms) {
                                  TellIteration(progress, static_cast<int>(k), iteration, rms, units);
                                })
                 : options;
    PatchOverlap overlap = OverlapWithPatch(*surface, scan.points, pose);
    double conditioning = PoseConditioning(overlap.points, overlap.normals);
    bool moved = false;  // registered at least once
    for (int round = 0; round < 5 && conditioning >= kMinConditioning; ++round) {
      Eigen::Matrix3Xd chosen(3, static_cast<Eigen::Index>(overlap.inside.size()));
      for (std::size_t i = 0; i < overlap.inside.size(); ++i)
        chosen.col(static_cast<Eigen::Index>(i)) = scan.points.col(overlap.inside[i]);
      try {
        result = RegisterToModel(*surface, chosen, pose, view_options);
      } catch (const std::invalid_argument& e) {
        throw FitFailure(kFitError,
                         "view " + std::to_string(k) + ": registration to the surface failed: " + e.what());
      }
      pose = result.model_T_scan;
      moved = true;
      PatchOverlap next = OverlapWithPatch(*surface, scan.points, pose);
      const bool same = next.inside == overlap.inside;
      overlap = std::move(next);
      conditioning = PoseConditioning(overlap.points, overlap.normals);
      if (same) break;
    }
    const bool registered = moved && conditioning >= kMinConditioning;
    if (!registered) {
      outcome.unregistered_views.push_back(k);
      pose = scan.world_T_scan;
    }
    world_T_scan.push_back(pose);
    nlohmann::json residuals = ModelRegistrationJson(result);
    residuals["registered"] = registered;
    residuals["points_on_patch"] = overlap.inside.size();
    residuals["conditioning"] = conditioning;
    if (!registered) {
      residuals["rms"] = nullptr;
      residuals["max"] = nullptr;
    }
    if (!moved) residuals["stop_reason"] = "not started: the surface does not hold the view at its start";
    entries.push_back(ViewEntry(scan, pose, residuals));
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  nlohmann::json& j = outcome.document;
  j["mode"] = "to-fe-surface";
  j["fe_surface"] = {{"file", o.to},
                     {"triangles", surface->surface().triangle_count()},
                     {"dofs", surface->surface().dof_count()}};
  j["min_conditioning"] = kMinConditioning;
  j["seconds"] = seconds;
  j["views"] = entries;
  std::ostringstream text;
  text << "scan2model register: " << views.scans.size() << " views of " << o.input
       << " to the finite-element surface of " << o.to << " (" << o.method
       << ", each view on its own, its points beyond the patch's edge left out), " << Format(seconds, 3)
       << " s\n"
       << ViewTable(entries, units)
       << "\n  RMS and max: distances of each view's points on the patch to the surface (" << units << ")\n";
  outcome.text = text.str();
  if (!outcome.unregistered_views.empty())
    outcome.unregistered_reason =
        "the surface does not hold them: their points on the patch leave a motion free (conditioning under " +
        Format(kMinConditioning, 3) + ", or fewer than 6 points on the patch); they keep their poses";
}

}  // namespace

RegisterOutcome ComputeRegistration(const RegisterOptions& o, const RegisterProgress& progress) {
  if (o.method != "pdm" && o.method != "tdm" && o.method != "sdm")
    throw FitFailure(kUsage, "--method: registration takes pdm, tdm or sdm, not '" + o.method + "'");
  if (o.samples_per_view < 1) throw FitFailure(kUsage, "--samples must be positive");
  if (o.max_sweeps < 1) throw FitFailure(kUsage, "--max-sweeps must be positive");
  ScanSet views;
  try {
    views = ReadViews(o.input);
  } catch (const FormatError& e) {
    throw FitFailure(kInputError, e.what());
  }
  if (views.scans.empty()) throw FitFailure(kInputError, o.input + ": no views");

  RegisterOutcome outcome;
  outcome.document["schema"] = "scan2model.registration/1";
  outcome.document["input"] = {
      {"file", o.input}, {"views", views.scans.size()}, {"units", views.scans[0].units}};
  outcome.document["method"] = o.method;
  std::vector<RigidMotion> world_T_scan;
  if (o.to.empty()) {
    ScanToScan(o, views, progress, outcome, world_T_scan);
  } else if (std::filesystem::path(o.to).extension() == ".json") {
    // A result document: the part a constrained-part fit measured or a fitted FE surface. Other fits are
    // refused: a primitive's or
    // a surface of revolution's symmetry leaves rotations of every view free (about a sphere's centre, about
    // an axis), so they cannot place views.
    nlohmann::json fit;
    try {
      fit = nlohmann::json::parse(formats::ReadFileBytes(o.to));
    } catch (const nlohmann::json::parse_error& e) {
      throw FitFailure(kInputError, o.to + ": invalid JSON (" + e.what() + ")");
    } catch (const nlohmann::json::out_of_range& e) {  // a number beyond double's range
      throw FitFailure(kInputError, o.to + ": invalid JSON (" + e.what() + ")");
    } catch (const FormatError& e) {
      throw FitFailure(kInputError, e.what());
    }
    const std::string schema = fit.is_object() ? fit.value("schema", "") : "";
    if (schema == "scan2model.fe-surface/1")
      ToFittedFeSurface(o, fit, views, progress, outcome, world_T_scan);
    else if (schema == "scan2model.part_fit/1")
      ToFittedPart(o, fit, views, progress, outcome, world_T_scan);
    else
      throw FitFailure(kInputError,
                       o.to +
                           ": --to takes a constrained part's fit (scan2model.part_fit/1), a finite-element "
                           "surface's (scan2model.fe-surface/1) or a nominal mesh, not " +
                           (schema.empty() ? std::string("this document") : schema) +
                           " (a primitive's or a surface of revolution's symmetry leaves the views' "
                           "rotations about it free)");
  } else {
    ToNominal(o, views, progress, outcome, world_T_scan);
  }

  if (!outcome.unregistered_views.empty()) {
    std::string list;
    for (std::size_t k : outcome.unregistered_views) list += (list.empty() ? "" : ", ") + std::to_string(k);
    outcome.notes.push_back("view(s) " + list + " are not registered: " +
                            (outcome.unregistered_reason.empty()
                                 ? std::string("they do not overlap the fixed view's group of views")
                                 : outcome.unregistered_reason) +
                            (o.output.empty() ? "" : "; no manifest was written"));
    outcome.document["unregistered_views"] = outcome.unregistered_views;
    return outcome;
  }
  if (!o.output.empty()) {
    ScanSet registered = views;
    std::vector<nlohmann::json> view_extra;
    for (std::size_t k = 0; k < registered.scans.size(); ++k) {
      registered.scans[k].world_T_scan = world_T_scan[k];
      const nlohmann::json& v = outcome.document["views"][k];
      view_extra.push_back({{"registration", {{"rms", v["rms"]}, {"max", v["max"]}, {"pairs", v["pairs"]}}}});
    }
    const nlohmann::json extra = {{"registration",
                                   {{"source", o.input},
                                    {"mode", outcome.document["mode"]},
                                    {"method", o.method},
                                    {"to", o.to.empty() ? nlohmann::json(nullptr) : nlohmann::json(o.to)}}}};
    try {
      WriteScanSet(o.output, registered, extra, view_extra);
    } catch (const std::exception& e) {
      throw FitFailure(kInputError, std::string("cannot write the manifest: ") + e.what());
    }
    outcome.document["output"] = o.output;
    outcome.text += "\n  wrote " + o.output + " (one PLY per view beside it)\n";
  }
  return outcome;
}

}  // namespace s2m::pipeline
