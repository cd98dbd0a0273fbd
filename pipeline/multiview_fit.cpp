// `scan2model fit --model revolution|helical|spiral <views.json|.conf|cloud>`: joint registration and fitting
// of several views to a kinematic surface.

#include <Eigen/Geometry>
#include <chrono>
#include <iomanip>
#include <iostream>
#include <limits>
#include <optional>
#include <sstream>

#include "acquisition/format_error.h"
#include "fitting/initial_models.h"
#include "fitting/joint_fit.h"
#include "fitting/kinematic_surfaces.h"
#include "fitting/model_complexity.h"
#include "fitting/primitive_fit.h"
#include "fitting/residual_structure.h"
#include "pipeline/complexity.h"
#include "pipeline/domain_measures.h"
#include "pipeline/exit_code.h"
#include "pipeline/fit_option_table.h"
#include "pipeline/fit_options.h"
#include "pipeline/interrogation_json.h"
#include "pipeline/output.h"
#include "pipeline/views.h"
#include "registration/scan_to_scan.h"

namespace s2m::pipeline {
namespace {

// The frame of the initial axis: z along the axis of the cylinder best fitting all views merged in the world.
RigidMotion InitialAxisFrame(const ScanSet& set) {
  const Cylinder c = FitCylinder(set.MergedWorldPoints()).shape;
  return RigidMotion(FrameWithAxis(c.axis_direction), c.axis_point);
}

// Helical and spiral surfaces: the axis (and pitch or growth, and the spiral's centre) from normals by line
// geometry (docs/method.md section 8), normals from local plane fits over 12 neighbours of the merged views.
KinematicAxis InitialKinematicAxis(const ScanSet& set, KinematicKind kind) {
  const Eigen::Matrix3Xd merged = set.MergedWorldPoints();
  return KinematicAxisFromNormals(merged, EstimateNormals(merged, 12), kind);
}

double UncertaintyOf(const ParametricModel& m, const JointFitResult& r, const std::string& name) {
  for (int i = 0; i < m.num_parameters(); ++i) {
    if (m.parameter_name(i) == name && i < r.shape_uncertainty.size()) return r.shape_uncertainty[i];
  }
  return std::numeric_limits<double>::quiet_NaN();
}

nlohmann::json NumberOrNull(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

}  // namespace

FitOutcome ComputeMultiViewFit(const FitOptions& given) {
  FitOptions o = given;
  try {
    if (o.model != "revolution" && o.model != "helical" && o.model != "spiral")
      throw std::invalid_argument(
          "multi-view fitting supports --model revolution, helical, spiral and part:FILE");
    // Automatic complexity (the default) starts coarse: one span more than a single cubic piece
    // (docs/method.md section 18).
    const ControlPointRequest request = ParseControlPoints(o.control_points, false);
    const ScanSet set = ReadViews(o.file);
    ResolveDefaultLoss(o, ClassifyInput(o.file, set.scans.empty() ? "" : set.scans.front().metadata.device));
    const std::size_t K = set.scans.size();
    // A given count is reached from a coarse fit by knot insertion too (FitFixedComplexity).
    // Not for spirals: measured on the synthetic shell at 8, reached from 6 the fit stalls at RMS 0.0269 for
    // noise 0.02 (fitted at 8 directly: 0.0200).
    const bool coarse_first = o.model != "spiral";
    const int n = request.automatic ? o.order + 1
                                    : (coarse_first ? std::min(request.first, o.order + 2) : request.first);
    const int max_control_points = request.max > 0 ? request.max : std::max(40, request.first);
    // Model frame: the initial axis (revolution: of the best cylinder; helical: from normals; spiral: from
    // normals, origin at the centre). Scans start at their given world poses, expressed in that frame.
    std::unique_ptr<ParametricModel> model;
    RigidMotion world_T_model;
    if (o.model == "revolution") {
      world_T_model = InitialAxisFrame(set);
      model = std::make_unique<KinematicSurface>(
          InitialRevolution(world_T_model.inverse().apply(set.MergedWorldPoints()), n, o.order));
    } else {
      KinematicAxis axis =
          InitialKinematicAxis(set, o.model == "helical" ? KinematicKind::kHelical : KinematicKind::kSpiral);
      if (axis.growth < 0) {  // the same motion reversed: report growing whorls about the opposite direction
        axis.growth = -axis.growth;
        axis.direction = -axis.direction;
      }
      world_T_model = RigidMotion(FrameWithAxis(axis.direction), axis.point);
      const Eigen::Matrix3Xd local = world_T_model.inverse().apply(set.MergedWorldPoints());
      if (o.model == "helical") {
        model =
            std::make_unique<KinematicSurface>(InitialHelicalWithPitchSearch(local, axis.pitch, n, o.order));
      } else {
        model =
            std::make_unique<SpiralSurface>(InitialSpiralWithGrowthSearch(local, axis.growth, n, o.order));
      }
    }
    const RigidMotion model_T_world = world_T_model.inverse();
    std::vector<Eigen::Matrix3Xd> scans;
    std::vector<RigidMotion> initial;
    for (const Scan& s : set.scans) {
      scans.push_back(s.points);
      initial.push_back(model_T_world * s.world_T_scan);
    }
    JointFitOptions options = JointOptions(o);  // TDM by default (apps/views.cpp)
    options.fairness = {o.stretch, o.bending, o.alpha3_given ? o.alpha3 : 0.0, o.beta2, o.beta3};
    // Helical and spiral profiles are distorted by a shared-motion stage on mis-registered views (measured on
    // the synthetic screw: stalls at RMS 1.7 x the noise; without it the noise is reached in 15 iterations,
    // docs/multiview-cases.md): per-view motions from the start.
    if (o.model != "revolution") options.shared_motion_iterations = 0;
    const auto start = std::chrono::steady_clock::now();
    const NoiseEstimate noise = EstimateNoiseWithDof(set);
    ComplexityOptions complexity_options;
    complexity_options.noise = noise.sigma;
    complexity_options.noise_dof = noise.dof;
    RefinableGeneratrixFit refinable(*model, scans, initial, options, max_control_points);
    const ComplexityChoice complexity =
        request.automatic
            ? ChooseComplexity(refinable, complexity_options)
            : FitFixedComplexity(refinable, complexity_options, coarse_first ? request.first : 0);
    const JointFitResult& r = refinable.result();
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

    FitOutcome outcome;
    nlohmann::json& j = outcome.document;
    j["schema"] = "scan2model.multiview/1";
    j["input"] = {{"file", o.file}, {"views", K}, {"points", set.TotalPoints()}, {"units", units}};
    j["model"] = o.model;
    j["method"] = ToString(options.error_term);
    j["solver"] = SolverName(options);
    j["loss"] = LossJson(o.loss, r.loss_scale, Eigen::VectorXd());
    j["loss"]["reason"] = o.loss_reason;
    j["axis"] = {{"point", ToJson(axis_point)}, {"direction", ToJson(axis_direction)}};
    const auto* kinematic = dynamic_cast<const KinematicSurface*>(model.get());
    const auto* spiral = dynamic_cast<const SpiralSurface*>(model.get());
    const BSplineBasis& basis = kinematic ? kinematic->basis() : spiral->basis();
    const Eigen::Matrix2Xd& profile = kinematic ? kinematic->profile() : spiral->profile();
    std::vector<std::vector<double>> profile_cp, samples;
    for (Eigen::Index i = 0; i < profile.cols(); ++i) profile_cp.push_back({profile(0, i), profile(1, i)});
    std::vector<double> radius_uncertainty;
    BSplineBasis::Values values;
    for (int i = 0; i <= 50; ++i) {
      const double u = basis.lo() + (basis.hi() - basis.lo()) * i / 50;
      basis.Evaluate(u, 0, values);
      Eigen::Vector2d rz = Eigen::Vector2d::Zero();
      for (int k = 0; k < basis.order(); ++k)
        rz +=
            values.values[0][static_cast<std::size_t>(k)] * profile.col(basis.ControlIndex(values.first, k));
      samples.push_back({rz.y(), rz.x()});  // (height along the axis from the axis point, radius)
      // The radius at that height, with its standard uncertainty propagated from the shape covariance (for
      // the generatrix of a spiral, at v = 0: its scale is tied to the growth and the gauge, not reported).
      double uncertainty = std::numeric_limits<double>::quiet_NaN();
      if (kinematic && r.shape_covariance.size() > 0) {
        try {
          Eigen::VectorXd gradient;
          kinematic->RadiusAtHeight(rz.y(), &gradient);
          uncertainty = std::sqrt(gradient.dot(r.shape_covariance * gradient));
        } catch (const std::domain_error&) {  // the profile turns back in height there: no radius function
        }
      }
      radius_uncertainty.push_back(uncertainty);
    }
    j["profile"] = {{"order", basis.order()},
                    {"knots", basis.knots()},
                    {"control_points_radius_height", profile_cp},
                    {"samples_height_radius", samples}};
    j["profile"]["samples_radius_uncertainty"] = nlohmann::json::array();
    for (double u : radius_uncertainty) j["profile"]["samples_radius_uncertainty"].push_back(NumberOrNull(u));
    {
      // The generatrix (r(u), z(u)) as a plane curve: its fairness (docs/fair-curves.md section 6).
      const BSplineCurve generatrix(basis, profile);
      j["profile"]["interrogation"] =
          InterrogationJson(InterrogateCurve(ToInterrogated(generatrix), {256, 0.0}), 2);
    }
    if (kinematic && kinematic->helical()) {
      j["pitch"] = MeasureHelix(kinematic->pitch(), UncertaintyOf(*model, r, "pitch"), units).ToJson();
    }
    if (spiral) {
      j["growth"] =
          MeasureShell(spiral->growth(), UncertaintyOf(*model, r, "growth"), spiral->WhorlExpansionRate())
              .ToJson();
    }
    std::vector<RigidMotion> corrected;
    for (std::size_t k = 0; k < K; ++k) corrected.push_back(world_T_model_fit * r.model_T_scan[k]);
    j["views"] = ViewsJson(set, corrected, r);
    AddSolverJson(j, r, seconds);
    // Domain outputs (docs/batch.md): the vessel's measures for a surface of revolution, the model's adequacy
    // against the views' own noise, and the signed deviations of the registered points.
    std::vector<Eigen::Matrix3Xd> model_points;
    for (std::size_t k = 0; k < K; ++k) model_points.push_back(r.model_T_scan[k].apply(scans[k]));
    const Eigen::Matrix3Xd registered = Concatenate(model_points);
    Eigen::Matrix3Xd feet;
    const Eigen::VectorXd deviations = SignedDistancesAroundAxis(*model, registered, &feet);
    // Adequacy (docs/method.md section 17): the RMS against the views' own noise, and the signed residuals'
    // structure, for a surface of revolution along the height (the generatrix's parameter up to its
    // direction), for helical and spiral surfaces along a Hilbert curve through the registered points.
    AdequacyEvidence evidence;
    evidence.family = ModelFamily::kMultiView;
    evidence.model = o.model;
    evidence.control_points = std::to_string(profile.cols());
    evidence.fit_rms = r.residuals.rms;
    evidence.noise_estimate = noise.sigma;
    evidence.residuals = deviations;
    evidence.points = feet;
    if (o.model == "revolution") {
      evidence.order = OrderByParameter(feet.row(2).transpose());
      evidence.order_description = "the height along the axis";
    }
    evidence.weights = RobustWeightsAt(o.loss, r.loss_scale, deviations);
    evidence.extent = ComputeBounds(registered).diagonal();
    const Adequacy adequacy = AssessAdequacy(evidence);
    const std::optional<bool> trusted = adequacy.uncertainty_trusted();
    j["deviations"] = DeviationsJson(world_T_model_fit.apply(registered), deviations, {}, evidence.weights);
    j["complexity"] = ComplexityJson(complexity, complexity_options);
    j["adequacy"] = adequacy.ToJson();
    std::optional<VesselMeasures> vessel;
    if (o.model == "revolution") {
      std::vector<Eigen::Vector2d> height_radius;
      for (const std::vector<double>& sample : samples) height_radius.emplace_back(sample[0], sample[1]);
      vessel = MeasureVessel(axis_point, axis_direction, height_radius, radius_uncertainty, units);
      j["vessel"] = vessel->ToJson();
    }
    MarkUncertainties(j, trusted);
    WriteRequestedFiles(o, j, r);
    if (vessel && !o.output.empty()) WriteProfileFiles(o.output, *vessel);
    std::ostringstream text;
    text << "scan2model fit: " << model->name() << " to " << K << " views (" << set.TotalPoints()
         << " points) of " << o.file << " (units " << units << ")\n\n"
         << UntrustedUncertaintiesLine(trusted) << "  solver            "
         << SolverSummary(options, r, seconds) << "\n"
         << "  loss              " << ToString(o.loss) << "; " << o.loss_reason << "\n"
         << "  axis point        " << Format(axis_point) << "\n"
         << "  axis direction    " << Format(axis_direction) << "\n";
    if (j.contains("pitch")) {
      text << "  pitch             " << Format(j["pitch"]["value"].get<double>(), 8) << " +- "
           << UncertaintyText(UncertaintyOf(*model, r, "pitch"), trusted, 2) << " per radian (lead "
           << Format(j["pitch"]["lead_per_turn"].get<double>(), 6) << " per turn)\n";
    }
    if (j.contains("growth")) {
      text << "  growth            " << Format(j["growth"]["value"].get<double>(), 8) << " +- "
           << UncertaintyText(UncertaintyOf(*model, r, "growth"), trusted, 2)
           << " per radian (whorl expansion rate "
           << Format(j["growth"]["whorl_expansion_rate"].get<double>(), 6) << ")\n";
    }
    text << ComplexityText(complexity);
    text << "  residuals         RMS " << Format(r.residuals.rms, 6) << ", max "
         << Format(r.residuals.max_abs, 6)
         << "\n\n  profile (height along the axis, radius, standard uncertainty of the radius)\n";
    for (int i = 0; i <= 50; i += 5) {
      const double u = radius_uncertainty[static_cast<std::size_t>(i)];
      text << "  " << std::setw(14) << Format(samples[static_cast<std::size_t>(i)][0], 6) << std::setw(14)
           << Format(samples[static_cast<std::size_t>(i)][1], 6) << std::setw(12)
           << UncertaintyText(u, trusted, 2) << "\n";
    }
    text << ViewsTable(j["views"]) << UnobservableText(r);
    if (o.verbose) text << HistoryTable(r.history);
    if (vessel) text << vessel->Text(trusted);
    text << adequacy.Text();
    outcome.text = text.str();
    return outcome;
  } catch (const FormatError& e) {
    throw FitFailure(kInputError, e.what());
  } catch (const std::invalid_argument& e) {
    throw FitFailure(kUsage, o.file + ": " + e.what());
  } catch (const FitFailure&) {
    throw;
  } catch (const std::exception& e) {
    throw FitFailure(kFitError, o.file + ": " + e.what());
  }
}

}  // namespace s2m::pipeline
