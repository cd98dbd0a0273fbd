// Rigid registration: the linearized step (docs/method.md section 5) and registration of scans to a fixed
// model.

#include "fitting/model_registration.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "fitting/bspline_models.h"
#include "fitting/initial_models.h"
#include "registration/rigid_step.h"

namespace s2m {
namespace {

TEST(RigidStep, RecoversTheVelocityOfExactLinearCorrespondences) {
  // Targets s = x + cbar + c x x exactly: PDM's step is exact, and so is TDM's when the normals span space.
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Vector3d c(0.01, -0.02, 0.015), cbar(0.1, 0.05, -0.2);
  RigidNormalEquations pdm, tdm;
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector3d x(u(rng), u(rng), u(rng));
    const Eigen::Vector3d n = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    const Eigen::Vector3d s = x + cbar + c.cross(x);
    pdm.Add({x, s, Eigen::Matrix3d::Identity(), 1.0});
    tdm.Add({x, s, n * n.transpose(), 1.0});
  }
  for (const RigidNormalEquations* eq : {&pdm, &tdm}) {
    const Eigen::Matrix<double, 6, 1> v = SolveRigidVelocity(*eq);
    EXPECT_LT((v.head<3>() - c).norm(), 1e-13);
    EXPECT_LT((v.tail<3>() - cbar).norm(), 1e-13);
  }
}

// A wavy, non-symmetric sheet: every rigid motion changes the distances, so the pose is observable.
BSplineSurface WavySheet() {
  Eigen::Matrix3Xd p(3, 64);
  for (int i = 0; i < 8; ++i)
    for (int j = 0; j < 8; ++j)
      p.col(i * 8 + j) << i * 0.3, j * 0.3, 0.25 * std::sin(1.3 * i + 0.7 * j) + 0.02 * i * j;
  return BSplineSurface(UnitSpacedClamped(4, 8), UnitSpacedClamped(4, 8), p);
}

// Points on the sheet's interior, expressed in a scan frame: scan = truth^-1 (model points).
Eigen::Matrix3Xd ScanOf(const BSplineSurface& sheet, const RigidMotion& model_T_scan, int n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(1.0, 4.0);
  Eigen::Matrix3Xd model_points(3, n);
  LocalGeometry g;
  for (int j = 0; j < n; ++j) {
    sheet.Evaluate({u(rng), u(rng)}, 0, g);
    model_points.col(j) = g.point;
  }
  return model_T_scan.inverse().apply(model_points);
}

double PoseError(const RigidMotion& a, const RigidMotion& b) {
  const RigidMotion d = a.inverse() * b;
  return d.angle() + d.translation().norm();
}

TEST(ModelRegistration, TdmAndSdmRecoverThePoseInFewIterationsPdmNeedsMany) {
  const BSplineSurface sheet = WavySheet();
  const RigidMotion truth = RigidMotion::FromHelicalVelocity({0.05, -0.08, 0.1}, {0.08, -0.05, 0.04});
  const Eigen::Matrix3Xd scan = ScanOf(sheet, truth, 800, 1);
  int iterations[3] = {0, 0, 0};
  const ErrorTerm terms[] = {ErrorTerm::kPdm, ErrorTerm::kTdm, ErrorTerm::kSdm};
  for (int k = 0; k < 3; ++k) {
    ModelRegistrationOptions o;
    o.error_term = terms[k];
    o.optimizer.target_rms = 1e-12;
    o.optimizer.max_iterations = 300;
    const ModelRegistrationResult r = RegisterToModel(sheet, scan, RigidMotion::Identity(), o);
    iterations[k] = r.stop_reason == StopReason::kTargetReached ? r.iterations : 100000;
    if (terms[k] != ErrorTerm::kPdm) {
      ASSERT_EQ(r.stop_reason, StopReason::kTargetReached) << ToString(terms[k]);
      EXPECT_LT(PoseError(r.model_T_scan, truth), 1e-8) << ToString(terms[k]);
      EXPECT_LE(r.iterations, 20) << ToString(terms[k]);
    }
  }
  EXPECT_GE(iterations[0], 3 * iterations[2]) << "PDM " << iterations[0] << " vs SDM " << iterations[2];
}

TEST(ModelRegistration, RegistersEveryScanOfASetAndAccumulatesWorldPoses) {
  const BSplineSurface sheet = WavySheet();
  const RigidMotion world_T_model = RigidMotion::FromHelicalVelocity({0.3, 0.1, -0.2}, {5, -2, 1});
  ScanSet set;
  std::vector<RigidMotion> truths;
  for (int k = 0; k < 3; ++k) {
    const RigidMotion model_T_scan =
        RigidMotion::FromHelicalVelocity({0.02 * k, -0.03, 0.04}, {0.05, 0.02 * k, -0.03});
    Scan s;
    s.points = ScanOf(sheet, model_T_scan, 400, 10 + k);
    // A device pose that is nearly right: the registration corrects it.
    s.world_T_scan = world_T_model *
                     RigidMotion::FromHelicalVelocity({0.01, 0.0, -0.01}, {0.02, -0.01, 0.0}) * model_T_scan;
    set.scans.push_back(s);
    truths.push_back(world_T_model * model_T_scan);
  }
  const auto results = RegisterScansToModel(sheet, world_T_model, set);
  ASSERT_EQ(results.size(), 3u);
  for (int k = 0; k < 3; ++k) {
    EXPECT_LT(results[static_cast<std::size_t>(k)].residuals.rms, 1e-9);
    EXPECT_LT(
        PoseError(set.scans[static_cast<std::size_t>(k)].world_T_scan, truths[static_cast<std::size_t>(k)]),
        1e-8);
  }
}

TEST(ModelRegistration, RejectsBadInput) {
  const BSplineSurface sheet = WavySheet();
  EXPECT_THROW(RegisterToModel(sheet, Eigen::Matrix3Xd(3, 0), RigidMotion::Identity()),
               std::invalid_argument);
  Eigen::Matrix3Xd bad = Eigen::Matrix3Xd::Ones(3, 5);
  bad(2, 2) = std::nan("");
  EXPECT_THROW(RegisterToModel(sheet, bad, RigidMotion::Identity()), std::invalid_argument);
  // In a set, the failing scan is named.
  ScanSet set;
  set.scans.resize(2);
  set.scans[0].points = ScanOf(sheet, RigidMotion::Identity(), 100, 1);
  set.scans[1].points = bad;
  try {
    RegisterScansToModel(sheet, RigidMotion::Identity(), set);
    ADD_FAILURE() << "no error for a scan with NaN";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("scan 1: ", 0), 0u) << e.what();
  }
}

// A plane leaves three motions free and a sphere its three rotations (conditioning 0 up to rounding); three
// faces of a box fix all six; a cylinder the rotation about and the translation along its axis.
TEST(PoseConditioning, IsZeroExactlyWhenTheSurfaceLeavesAMotionFree) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  const int n = 300;
  Eigen::Matrix3Xd plane(3, n), plane_normals(3, n), sphere(3, n), sphere_normals(3, n), box(3, n),
      box_normals(3, n), cylinder(3, n), cylinder_normals(3, n);
  for (int i = 0; i < n; ++i) {
    plane.col(i) = Eigen::Vector3d(u(rng), u(rng), 0);
    plane_normals.col(i) = Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d d = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    sphere.col(i) = Eigen::Vector3d(1, 2, 3) + 2 * d;
    sphere_normals.col(i) = d;
    const int face = i % 3;
    Eigen::Vector3d p(u(rng), u(rng), u(rng));
    p(face) = 1;
    box.col(i) = p;
    box_normals.col(i) = Eigen::Vector3d::Unit(face);
    const double a = 3 * u(rng);
    cylinder.col(i) = Eigen::Vector3d(std::cos(a), std::sin(a), 2 * u(rng));
    cylinder_normals.col(i) = Eigen::Vector3d(std::cos(a), std::sin(a), 0);
  }
  EXPECT_LT(PoseConditioning(plane, plane_normals), 1e-14);
  EXPECT_LT(PoseConditioning(sphere, sphere_normals), 1e-14);
  EXPECT_LT(PoseConditioning(cylinder, cylinder_normals), 1e-14);
  EXPECT_GT(PoseConditioning(box, box_normals), 1e-2);
  EXPECT_EQ(PoseConditioning(box.leftCols(5), box_normals.leftCols(5)), 0.0);
  EXPECT_THROW(PoseConditioning(box, box_normals.leftCols(5)), std::invalid_argument);
}

}  // namespace
}  // namespace s2m
