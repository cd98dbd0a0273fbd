// The joint solver (docs/method.md section 6) on a synthetic pot scanned in three overlapping views.

#include "fitting/joint_fit.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <random>

#include "fitting/initial_models.h"
#include "fitting/kinematic_surfaces.h"
#include "fitting/primitive_models.h"

namespace s2m {
namespace {

KinematicSurface TruePot() {
  Eigen::Matrix2Xd profile(2, 7);
  profile << 3.0, 3.6, 4.2, 3.5, 2.8, 3.2, 3.6,  //
      0.0, 1.5, 3.0, 4.5, 6.0, 7.5, 9.0;
  return KinematicSurface::Revolution(UnitSpacedClamped(4, 7), profile);
}

struct PotScans {
  std::vector<Eigen::Matrix3Xd> scans;  // scan coordinates
  std::vector<RigidMotion> truth;       // model_T_scan
  std::vector<RigidMotion> initial;     // perturbed device poses
};

PotScans ScanPot(const KinematicSurface& pot, double sigma) {
  PotScans out;
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> u(0.2, 3.8), a(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, sigma);
  LocalGeometry g;
  for (int k = 0; k < 3; ++k) {
    const RigidMotion truth =
        RigidMotion::FromHelicalVelocity({0.03 * k, -0.04, 0.02}, {0.2 * k - 0.1, 0.15, 0.1 * k});
    Eigen::Matrix3Xd model_points(3, 600);
    for (int j = 0; j < 600; ++j) {
      const double v = 2 * M_PI * k / 3 + 3.6 * a(rng);  // each view sees about 206 degrees
      pot.Evaluate({u(rng), v}, 1, g);
      const Eigen::Vector3d n = Eigen::Vector3d(g.d1.col(0)).cross(Eigen::Vector3d(g.d1.col(1))).normalized();
      model_points.col(j) = Eigen::Vector3d(g.point) + (sigma > 0 ? noise(rng) : 0.0) * n;
    }
    out.scans.push_back(truth.inverse().apply(model_points));
    out.truth.push_back(truth);
    // Each device pose is off by up to about 1 degree and 0.05 units, differently per view.
    const double d = k - 1.0;
    out.initial.push_back(RigidMotion::FromHelicalVelocity({0.012 * d, -0.01 * (k == 1 ? 1 : -1), 0.015 * k},
                                                           {0.05 * d, -0.04 * (k == 2 ? 1 : -1), 0.03 * d}) *
                          truth);
  }
  return out;
}

KinematicSurface StartingProfile() {
  Eigen::Matrix2Xd profile(2, 7);
  for (int i = 0; i < 7; ++i) profile.col(i) << 3.4, 1.5 * i;
  return KinematicSurface::Revolution(UnitSpacedClamped(4, 7), profile);
}

// Distance of the point (r, z) from the true generatrix, by dense sampling.
double ProfileDistance(const KinematicSurface& truth, const Eigen::Vector2d& rz) {
  double best = INFINITY;
  for (int i = 0; i <= 4000; ++i) best = std::min(best, (truth.ProfilePoint(4.0 * i / 4000) - rz).norm());
  return best;
}

TEST(JointFit, RecoversProfileAndAxesOfAPotFromThreeViews) {
  const KinematicSurface truth = TruePot();
  const PotScans views = ScanPot(truth, 0.0);
  KinematicSurface pot = StartingProfile();
  JointFitOptions o;
  o.optimizer.max_iterations = 60;
  const JointFitResult r = FitJointly(pot, views.scans, views.initial, o);
  EXPECT_LT(r.residuals.rms, 1e-7) << ToString(r.stop_reason) << " after " << r.iterations << " iterations";
  EXPECT_GT(r.shared_iterations, 0);
  for (std::size_t k = 0; k < 3; ++k) {
    // Gauge-free checks: each scan's axis (the model's z axis seen from the scan) matches the truth.
    const RigidMotion fit_inv = r.model_T_scan[k].inverse(), true_inv = views.truth[k].inverse();
    const Eigen::Vector3d dir_fit = fit_inv.rotation().col(2), dir_true = true_inv.rotation().col(2);
    EXPECT_LT(std::atan2(dir_fit.cross(dir_true).norm(), dir_fit.dot(dir_true)), 1e-7) << "scan " << k;
    const Eigen::Vector3d offset = fit_inv.translation() - true_inv.translation();
    EXPECT_LT((offset - offset.dot(dir_true) * dir_true).norm(), 1e-6) << "scan " << k;
  }
  // The profile equals the truth up to the common axial shift the gauge leaves free.
  const double shift = (r.model_T_scan[0] * views.truth[0].inverse()).translation().z();
  for (int i = 0; i <= 40; ++i) {
    const Eigen::Vector2d rz = pot.ProfilePoint(0.3 + 3.4 * i / 40);
    EXPECT_LT(ProfileDistance(truth, rz - Eigen::Vector2d(0.0, shift)), 1e-5) << "profile sample " << i;
  }
}

TEST(JointFit, PerScanMotionsBeatFittingThePreRegisteredCloud) {
  // docs/method.md section 6: fitting the initially registered cloud (one shared motion only) leaves the
  // registration error in the result; freeing the per-scan motions removes it.
  const PotScans views = ScanPot(TruePot(), 0.002);
  KinematicSurface shared_only = StartingProfile(), joint = StartingProfile();
  JointFitOptions o;
  o.optimizer.max_iterations = 40;
  o.per_scan_motions = false;  // the baseline: one motion for the whole pre-registered cloud
  const double rms_shared = FitJointly(shared_only, views.scans, views.initial, o).residuals.rms;
  o.per_scan_motions = true;
  const double rms_joint = FitJointly(joint, views.scans, views.initial, o).residuals.rms;
  EXPECT_LT(rms_joint, 0.5 * rms_shared) << "joint " << rms_joint << " vs shared " << rms_shared;
  EXPECT_LT(rms_joint, 1.2 * 0.002);  // down to the noise
}

TEST(JointFit, JointNeedsFewerIterationsThanAlternatingToTheSameRms) {
  const PotScans views = ScanPot(TruePot(), 0.0);
  int iterations[2];
  for (int alternating = 0; alternating < 2; ++alternating) {
    KinematicSurface pot = StartingProfile();
    JointFitOptions o;
    o.alternating = alternating == 1;
    o.optimizer.target_rms = 1e-6;
    o.optimizer.max_iterations = 200;
    const JointFitResult r = FitJointly(pot, views.scans, views.initial, o);
    ASSERT_EQ(r.stop_reason, StopReason::kTargetReached) << (alternating ? "alternating" : "joint");
    iterations[alternating] = r.iterations;
  }
  EXPECT_GE(iterations[1], 2 * iterations[0])
      << "joint " << iterations[0] << ", alternating " << iterations[1];
}

TEST(JointFit, GaugeIsRemovedOrReportedByName) {
  const PotScans views = ScanPot(TruePot(), 0.0);
  KinematicSurface pot = StartingProfile();
  JointFitOptions o;
  o.optimizer.max_iterations = 40;
  EXPECT_TRUE(FitJointly(pot, views.scans, views.initial, o).unobservable.empty());
  // With the gauge left in, each scan's rotation about the axis (and one common axial shift) stay
  // undetermined.
  KinematicSurface free_pot = StartingProfile();
  o.remove_gauge = false;
  const JointFitResult r = FitJointly(free_pot, views.scans, views.initial, o);
  EXPECT_LT(r.residuals.rms, 1e-6);
  ASSERT_GE(r.unobservable.size(), 3u);
  int rotations = 0;
  for (const std::string& name : r.unobservable) rotations += name.find("rotation z") != std::string::npos;
  EXPECT_GE(rotations, 3) << ::testing::PrintToString(r.unobservable);
}

TEST(JointFit, ReportedUncertaintiesMatchTheMonteCarloScatter) {
  // 200 noisy re-scans of the same pot: the errors of the axis tilt (seen from scan 1), the scan's lateral
  // position and the radius at mid-height, divided by the uncertainty the fit reports, must scatter with
  // standard deviation near 1 (issue bounds 0.8 to 1.25).
  const KinematicSurface truth = TruePot();
  const int trials = 200;
  std::vector<double> z_tilt, z_shift, z_radius;
  for (int t = 0; t < trials; ++t) {
    std::mt19937_64 rng(1000 + t);
    std::uniform_real_distribution<double> u(0.2, 3.8), a(0.0, 1.0);
    std::normal_distribution<double> noise(0.0, 0.01);
    std::vector<Eigen::Matrix3Xd> scans;
    std::vector<RigidMotion> poses, initial;
    LocalGeometry g;
    for (int k = 0; k < 3; ++k) {
      const RigidMotion pose =
          RigidMotion::FromHelicalVelocity({0.03 * k, -0.04, 0.02}, {0.2 * k - 0.1, 0.15, 0.1 * k});
      Eigen::Matrix3Xd model_points(3, 300);
      for (int j = 0; j < 300; ++j) {
        truth.Evaluate({u(rng), 2 * M_PI * k / 3 + 3.6 * a(rng)}, 1, g);
        const Eigen::Vector3d n =
            Eigen::Vector3d(g.d1.col(0)).cross(Eigen::Vector3d(g.d1.col(1))).normalized();
        model_points.col(j) = Eigen::Vector3d(g.point) + noise(rng) * n;
      }
      scans.push_back(pose.inverse().apply(model_points));
      poses.push_back(pose);
      initial.push_back(
          RigidMotion::FromHelicalVelocity({0.003 * (k - 1), 0.002, 0.0}, {0.01, -0.01 * k, 0.0}) * pose);
    }
    KinematicSurface pot = truth;
    JointFitOptions o;
    o.shared_motion_iterations = 0;
    o.optimizer.max_iterations = 30;
    const JointFitResult r = FitJointly(pot, scans, initial, o);
    ASSERT_EQ(r.pose_uncertainty.size(), 3u);
    const RigidMotion error =
        r.model_T_scan[1] * poses[1].inverse();  // the correction still left, model frame
    const Eigen::AngleAxisd aa(error.rotation());
    const Eigen::Vector3d w = aa.angle() * aa.axis();
    z_tilt.push_back(w.x() / r.pose_uncertainty[1].rotation.x());
    z_shift.push_back(error.translation().y() / r.pose_uncertainty[1].translation.y());
    // The radius at mid-height: a geometric quantity (a control point alone is not: it can slide along the
    // profile).
    Eigen::VectorXd gradient;
    const double radius = pot.RadiusAtHeight(4.5, &gradient);
    z_radius.push_back((radius - truth.RadiusAtHeight(4.5)) /
                       std::sqrt(gradient.dot(r.shape_covariance * gradient)));
  }
  for (const auto& [name, z] : {std::pair<const char*, std::vector<double>&>{"tilt", z_tilt},
                                {"shift", z_shift},
                                {"radius", z_radius}}) {
    double mean = 0, sq = 0;
    for (double v : z) mean += v / trials;
    for (double v : z) sq += (v - mean) * (v - mean) / (trials - 1);
    std::printf("standardized %s errors: mean %.3f, standard deviation %.3f over %d trials\n", name, mean,
                std::sqrt(sq), trials);
    EXPECT_GT(std::sqrt(sq), 0.8) << name;
    EXPECT_LT(std::sqrt(sq), 1.25) << name;
    EXPECT_LT(std::abs(mean), 0.3) << name << ": biased";
  }
}

// Three views of a model's surface (noise-free) with mis-registered device poses.
template <class Model>
void ViewsOf(const Model& truth, double v_lo, double v_hi, std::vector<Eigen::Matrix3Xd>& scans,
             std::vector<RigidMotion>& initial) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> a(0.0, 1.0);
  LocalGeometry g;
  const ParameterDomain d = truth.domain();
  for (int k = 0; k < 3; ++k) {
    const RigidMotion pose =
        RigidMotion::FromHelicalVelocity({0.02 * k, -0.03, 0.01}, {0.1 * k, 0.05, -0.05 * k});
    Eigen::Matrix3Xd points(3, 800);
    for (int j = 0; j < 800; ++j) {
      const double u = d.lo[0] + (d.hi[0] - d.lo[0]) * (0.05 + 0.9 * a(rng));
      const double v =
          v_lo + (v_hi - v_lo) * (k + 1.6 * a(rng)) / 3.6;  // overlapping thirds of the angle range
      truth.Evaluate({u, v}, 0, g);
      points.col(j) = g.point;
    }
    scans.push_back(pose.inverse().apply(points));
    const double e = k - 1.0;
    initial.push_back(RigidMotion::FromHelicalVelocity({0.004 * e, -0.003, 0.0}, {0.01 * e, 0.008, 0.0}) *
                      pose);
  }
}

TEST(JointFit, RecoversThePitchOfAHelicalSurfaceAndTheGrowthOfASpiralShell) {
  Eigen::Matrix2Xd drill(2, 6);
  drill << 0.6, 0.9, 1.2, 1.1, 0.8, 0.5,  //
      -0.3, -0.2, -0.05, 0.05, 0.2, 0.3;
  const KinematicSurface helical = KinematicSurface::Helical(UnitSpacedClamped(4, 6), drill, 0.2, 2.0);
  std::vector<Eigen::Matrix3Xd> scans;
  std::vector<RigidMotion> initial;
  ViewsOf(helical, -2.0 * M_PI, 2.0 * M_PI, scans, initial);
  KinematicSurface start = KinematicSurface::Helical(UnitSpacedClamped(4, 6), drill * 1.01, 0.19, 2.0);
  JointFitOptions o;
  o.optimizer.max_iterations = 80;
  const JointFitResult r = FitJointly(start, scans, initial, o);
  EXPECT_LT(r.residuals.rms, 1e-8) << ToString(r.stop_reason);
  EXPECT_NEAR(start.pitch(), 0.2, 1e-8);

  Eigen::Matrix2Xd whorl(2, 5);
  whorl << 1.0, 1.3, 1.5, 1.3, 1.0,  //
      -0.4, -0.2, 0.0, 0.2, 0.4;
  const SpiralSurface shell(UnitSpacedClamped(4, 5), whorl, 0.12, -2.0, 6.0);
  scans.clear();
  initial.clear();
  ViewsOf(shell, -2.0, 6.0, scans, initial);
  SpiralSurface shell_start(UnitSpacedClamped(4, 5), whorl * 0.98, 0.115, -2.0, 6.0);
  const JointFitResult rs = FitJointly(shell_start, scans, initial, o);
  EXPECT_LT(rs.residuals.rms, 1e-8) << ToString(rs.stop_reason);
  EXPECT_NEAR(shell_start.growth(), 0.12, 1e-8);
  EXPECT_NEAR(shell_start.WhorlExpansionRate(), std::exp(2 * M_PI * 0.12), 1e-6);
}

// The same shell in millimetres and in centimetres (all coordinates x 10): lengths and their uncertainties
// scale by 10, the growth (per radian) and its uncertainty do not. The covariance is computed in the unit box
// and mapped back by the model's own similarity; a uniform scale^2 made the growth's uncertainty grow with
// the object's size.
TEST(JointFit, UncertaintiesKeepTheirUnitsWhenTheDataAreScaled) {
  Eigen::Matrix2Xd whorl(2, 5);
  whorl << 1.0, 1.3, 1.5, 1.3, 1.0,  //
      -0.4, -0.2, 0.0, 0.2, 0.4;
  const SpiralSurface shell(UnitSpacedClamped(4, 5), whorl, 0.12, -2.0, 6.0);
  std::vector<Eigen::Matrix3Xd> scans;
  std::vector<RigidMotion> initial;
  ViewsOf(shell, -2.0, 6.0, scans, initial);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 0.002);
  for (Eigen::Matrix3Xd& s : scans) s = s.unaryExpr([&](double x) { return x + noise(rng); });
  JointFitOptions o;
  o.optimizer.max_iterations = 80;
  SpiralSurface small(UnitSpacedClamped(4, 5), whorl * 0.98, 0.115, -2.0, 6.0);
  const JointFitResult a = FitJointly(small, scans, initial, o);
  constexpr double kTimes = 10.0;
  std::vector<Eigen::Matrix3Xd> scaled_scans;
  std::vector<RigidMotion> scaled_initial;
  for (std::size_t k = 0; k < scans.size(); ++k) {
    scaled_scans.push_back(kTimes * scans[k]);
    scaled_initial.emplace_back(initial[k].rotation(), kTimes * initial[k].translation());
  }
  SpiralSurface large(UnitSpacedClamped(4, 5), kTimes * 0.98 * whorl, 0.115, -2.0, 6.0);
  const JointFitResult b = FitJointly(large, scaled_scans, scaled_initial, o);
  ASSERT_EQ(a.shape_uncertainty.size(), b.shape_uncertainty.size());
  const Eigen::Index growth = small.num_parameters() - 1;
  std::printf("growth %.8f +- %.3g (x %g: %.8f +- %.3g)\n", small.growth(), a.shape_uncertainty[growth],
              kTimes, large.growth(), b.shape_uncertainty[growth]);
  EXPECT_NEAR(large.growth(), small.growth(), 1e-9);
  EXPECT_NEAR(b.shape_uncertainty[growth] / a.shape_uncertainty[growth], 1.0, 1e-4);
  // The control points slide with the frame's turn about the axis (the curve scales by e^(p dv)): no
  // uncertainty of their own (NaN) at either size; their covariance scales by 10^2.
  for (Eigen::Index i = 0; i < growth; ++i)
    EXPECT_EQ(std::isnan(b.shape_uncertainty[i]), std::isnan(a.shape_uncertainty[i]));
  const Eigen::MatrixXd ratio = b.shape_covariance.topLeftCorner(growth, growth)
                                    .cwiseQuotient(a.shape_covariance.topLeftCorner(growth, growth));
  EXPECT_NEAR(ratio.minCoeff(), kTimes * kTimes, 1e-2 * kTimes * kTimes);
  EXPECT_NEAR(ratio.maxCoeff(), kTimes * kTimes, 1e-2 * kTimes * kTimes);
  // And the growth's uncertainty is that of the data: its error here within 4 of it.
  EXPECT_LT(std::abs(small.growth() - 0.12), 4 * a.shape_uncertainty[growth]);
}

// Gauge of primitives (issue 4): each scan's rotation about and shift along a cylinder's axis, and its
// rotations about a sphere's centre, are removed; what stays unobservable is only the model's own
// re-parametrization (a cylinder's axis point sliding along the axis and its frame turning about it), never a
// scan motion.
TEST(JointFit, PrimitivesRemoveTheirSymmetriesFromEveryScan) {
  for (int kind = 0; kind < 2; ++kind) {
    std::unique_ptr<ParametricModel> truth;
    if (kind == 0) {
      truth = std::make_unique<CylinderModel>(
          Cylinder{{1.0, -2.0, 0.5}, Eigen::Vector3d(0.2, 0.1, 1).normalized(), 3.0});
    } else {
      truth = std::make_unique<SphereModel>(Sphere{{1.0, -2.0, 0.5}, 3.0});
    }
    std::vector<Eigen::Matrix3Xd> scans;
    std::vector<RigidMotion> initial;
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> a(0.0, 1.0);
    LocalGeometry g;
    for (int k = 0; k < 4; ++k) {
      const RigidMotion pose =
          RigidMotion::FromHelicalVelocity({0.1 * k, -0.2, 0.05 * k}, {2.0 * k, 1.0, -1.0});
      Eigen::Matrix3Xd points(3, 400);
      for (int j = 0; j < 400; ++j) {
        // Overlapping patches of the surface (cylinder: angle and height; sphere: longitude and latitude).
        const double u = 2 * M_PI * (k + 1.8 * a(rng)) / 4, v = kind == 0 ? 4 * a(rng) - 2 : a(rng) - 0.5;
        truth->Evaluate({u, v, 0.0}, 0, g);
        points.col(j) = g.point;
      }
      scans.push_back(pose.inverse().apply(points));
      initial.push_back(RigidMotion::FromHelicalVelocity({0.01, -0.01 * k, 0.005}, {0.05, 0.02 * k, -0.03}) *
                        pose);
    }
    auto model = truth->Clone();
    model->ApplyStep(Eigen::VectorXd::Constant(model->num_parameters(), 0.02));
    JointFitOptions o;
    o.optimizer.max_iterations = 60;
    const JointFitResult r = FitJointly(*model, scans, initial, o);
    EXPECT_LT(r.residuals.rms, 1e-8) << kind << " " << ToString(r.stop_reason);
    for (const std::string& name : r.unobservable) EXPECT_EQ(name.find("scan"), std::string::npos) << name;
    const int radius = model->num_parameters() - 1;
    EXPECT_NEAR(model->parameters()[radius], 3.0, 1e-8) << model->parameter_name(radius);
    // Left in, the symmetries are reported as scan motions by name.
    auto free_model = truth->Clone();
    o.remove_gauge = false;
    int scan_directions = 0;
    for (const std::string& name : FitJointly(*free_model, scans, initial, o).unobservable)
      scan_directions += name.find("scan") != std::string::npos;
    EXPECT_GE(scan_directions, kind == 0 ? 6 : 9) << "kind " << kind;
  }
}

TEST(JointFit, AssemblyFromTheFootPointPassMatchesTheSeparatePass) {
  // The fast path (normal equations summed in the foot point pass that evaluates a trial, from Newton's
  // geometry at the feet) against the reference path (a separate assembly pass evaluating the model at every
  // foot again): the same iterations, parameters and poses to rounding, on a Newton model (the pot, both
  // stages, with noise) and on a closed-form one (a cylinder).
  const PotScans views = ScanPot(TruePot(), 0.002);
  std::vector<Eigen::VectorXd> parameters;
  std::vector<JointFitResult> results;
  for (const bool reuse : {true, false}) {
    KinematicSurface pot = StartingProfile();
    JointFitOptions o;
    o.optimizer.max_iterations = 25;
    o.reuse_foot_geometry = reuse;
    results.push_back(FitJointly(pot, views.scans, views.initial, o));
    parameters.push_back(pot.parameters());
  }
  ASSERT_EQ(results[0].iterations, results[1].iterations);
  EXPECT_EQ(results[0].shared_iterations, results[1].shared_iterations);
  EXPECT_LT((parameters[0] - parameters[1]).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_NEAR(results[0].residuals.rms, results[1].residuals.rms, 1e-12);
  for (std::size_t k = 0; k < views.scans.size(); ++k) {
    EXPECT_LT((results[0].model_T_scan[k].rotation() - results[1].model_T_scan[k].rotation()).norm(), 1e-9);
    EXPECT_LT((results[0].model_T_scan[k].translation() - results[1].model_T_scan[k].translation()).norm(),
              1e-9);
  }
  ASSERT_EQ(results[0].shape_uncertainty.size(), results[1].shape_uncertainty.size());
  for (Eigen::Index i = 0; i < results[0].shape_uncertainty.size(); ++i)
    EXPECT_NEAR(results[0].shape_uncertainty[i], results[1].shape_uncertainty[i], 1e-9);

  const CylinderModel truth(Cylinder{{1.0, -2.0, 0.5}, Eigen::Vector3d(0.2, 0.1, 1).normalized(), 3.0});
  std::vector<Eigen::Matrix3Xd> scans;
  std::vector<RigidMotion> initial;
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> a(0.0, 1.0);
  LocalGeometry g;
  for (int k = 0; k < 3; ++k) {
    const RigidMotion pose =
        RigidMotion::FromHelicalVelocity({0.1 * k, -0.2, 0.05 * k}, {2.0 * k, 1.0, -1.0});
    Eigen::Matrix3Xd points(3, 300);
    for (int j = 0; j < 300; ++j) {
      truth.Evaluate({2 * M_PI * (k + 1.8 * a(rng)) / 3, 4 * a(rng) - 2, 0.0}, 0, g);
      points.col(j) = g.point;
    }
    scans.push_back(pose.inverse().apply(points));
    initial.push_back(RigidMotion::FromHelicalVelocity({0.01, -0.01 * k, 0.005}, {0.05, 0.02 * k, -0.03}) *
                      pose);
  }
  std::vector<Eigen::VectorXd> cylinder;
  std::vector<int> iterations;
  for (const bool reuse : {true, false}) {
    auto model = truth.Clone();
    model->ApplyStep(Eigen::VectorXd::Constant(model->num_parameters(), 0.02));
    JointFitOptions o;
    o.optimizer.max_iterations = 30;
    o.reuse_foot_geometry = reuse;
    iterations.push_back(FitJointly(*model, scans, initial, o).iterations);
    cylinder.push_back(model->parameters());
  }
  EXPECT_EQ(iterations[0], iterations[1]);
  EXPECT_LT((cylinder[0] - cylinder[1]).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_NEAR(cylinder[0][cylinder[0].size() - 1], 3.0, 1e-8);
}

TEST(JointFit, TrustedWarmStartsAfterSmallStepsGiveTheVerifiedResult) {
  // Trusting the previous feet after small steps (the default) against verifying every warm start: the same
  // fit to rounding, on the pot (an open profile: feet at its ends fall back to the nearest sample) from a
  // start whose first steps are large (verified) and whose later ones are small (trusted).
  const PotScans views = ScanPot(TruePot(), 0.002);
  std::vector<Eigen::VectorXd> parameters;
  std::vector<JointFitResult> results;
  for (const double trust : {1e-2, 0.0}) {
    KinematicSurface pot = StartingProfile();
    JointFitOptions o;
    o.optimizer.max_iterations = 30;
    o.trusted_warm_start_step = trust;
    results.push_back(FitJointly(pot, views.scans, views.initial, o));
    parameters.push_back(pot.parameters());
  }
  // Large and small shape steps both occurred (the history records the shape step's norm).
  int small_steps = 0;
  for (const IterationRecord& rec : results[0].history) small_steps += rec.step_norm < 1e-2;
  EXPECT_GT(small_steps, 0);
  EXPECT_GT(results[0].history.front().step_norm, 1e-2);
  ASSERT_EQ(results[0].iterations, results[1].iterations);
  EXPECT_EQ(results[0].stop_reason, results[1].stop_reason);
  EXPECT_LT((parameters[0] - parameters[1]).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_NEAR(results[0].residuals.rms, results[1].residuals.rms, 1e-12);
  EXPECT_NEAR(results[0].residuals.max_abs, results[1].residuals.max_abs, 1e-9);
  for (std::size_t k = 0; k < views.scans.size(); ++k) {
    EXPECT_LT((results[0].model_T_scan[k].rotation() - results[1].model_T_scan[k].rotation()).norm(), 1e-9);
    EXPECT_LT((results[0].model_T_scan[k].translation() - results[1].model_T_scan[k].translation()).norm(),
              1e-9);
  }
}

TEST(JointFit, RejectsBadInput) {
  KinematicSurface pot = StartingProfile();
  EXPECT_THROW(FitJointly(pot, {}, {}), std::invalid_argument);
  EXPECT_THROW(FitJointly(pot, {Eigen::Matrix3Xd::Ones(3, 4)}, {}), std::invalid_argument);
  EXPECT_THROW(FitJointly(pot, {Eigen::Matrix3Xd(3, 0)}, {RigidMotion()}), std::invalid_argument);
}

}  // namespace
}  // namespace s2m
