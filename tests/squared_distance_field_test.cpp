// The squared distance field (fitting/squared_distance_field.h): its approximate distances against exact foot
// points on a freeform B-spline patch and a cylinder, the cells it refuses, and registration with it.

#include "fitting/squared_distance_field.h"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <random>

#include "fitting/bspline_models.h"
#include "fitting/foot_point.h"
#include "fitting/initial_models.h"
#include "fitting/model_registration.h"
#include "fitting/primitive_models.h"
#include "registration/local_quadric.h"
#include "registration/rigid_step.h"
#include "synthetic/synthetic_cases.h"
#include "test_models.h"

namespace s2m {
namespace {

// Points over the inner part of the model's domain, each moved off the model by a uniform offset in
// [-offset, offset] along every axis.
Eigen::Matrix3Xd PointsAround(const ParametricModel& model, int count, double offset, double inner_lo,
                              double inner_hi, std::uint64_t seed) {
  return test::PointsOverInnerDomain(model, count, inner_lo, inner_hi,
                                     std::uniform_real_distribution<double>(-offset, offset), seed);
}

struct Agreement {
  double max_distance_error = 0.0;  // max | |y - q| - d(y) |
  double max_square_error = 0.0;    // max | |y - q|^2 - d^2(y) |
  int answered = 0;
};

Agreement Compare(const ParametricModel& model, const SquaredDistanceField& field,
                  const Eigen::Matrix3Xd& y) {
  std::vector<FootPoint> exact;
  ComputeFootPoints(model, y, exact);
  Agreement a;
  SquaredDistanceField::Answer answer;
  for (Eigen::Index j = 0; j < y.cols(); ++j) {
    if (!field.Query(y.col(j), answer)) continue;
    ++a.answered;
    const double d = exact[static_cast<std::size_t>(j)].distance;
    a.max_distance_error = std::max(a.max_distance_error, std::abs(std::sqrt(answer.squared_distance) - d));
    a.max_square_error = std::max(a.max_square_error, std::abs(answer.squared_distance - d * d));
    // The frame is oriented towards the point and delta is the distance along its normal.
    EXPECT_GE(answer.frame.delta, 0.0);
    EXPECT_NEAR(answer.frame.delta, std::sqrt(answer.squared_distance), 1e-6 + 1e-3 * d);
  }
  return a;
}

// Measured (20,000 points within 5 mm, cells of 1 mm): max distance error 2.1e-4 mm, max d^2 error 1.1e-3
// mm^2; with cells of 2 mm 1.6e-3 mm, 7.6x (third order in the cell size). Asserted with a margin of about
// 2x.
TEST(SquaredDistanceField, MatchesExactDistancesOnTheBumpyPatch) {
  const BSplineSurface patch = BumpyPatch(0.03);
  SquaredDistanceField::Options o;
  o.cell_size = 1.0;
  o.band = 6.0;
  const SquaredDistanceField field(patch, o);
  EXPECT_GT(field.cell_count(), 50000u);
  const Eigen::Matrix3Xd y = PointsAround(patch, 20000, 5.0 / std::sqrt(3.0), 0.1, 0.9, 3);
  const Agreement a = Compare(patch, field, y);
  EXPECT_EQ(a.answered, y.cols());  // inner points within the band: all answered by the field
  std::printf("patch, 1 mm cells: max |d error| %.3g mm, max |d^2 error| %.3g mm^2\n", a.max_distance_error,
              a.max_square_error);
  EXPECT_LT(a.max_distance_error, 4e-4);
  EXPECT_LT(a.max_square_error, 2.5e-3);

  o.cell_size = 2.0;
  const SquaredDistanceField coarse(patch, o);
  const Agreement b = Compare(patch, coarse, y);
  EXPECT_EQ(b.answered, y.cols());
  std::printf("patch, 2 mm cells: max |d error| %.3g mm, max |d^2 error| %.3g mm^2\n", b.max_distance_error,
              b.max_square_error);
  EXPECT_LT(b.max_distance_error, 3.5e-3);
  EXPECT_GT(b.max_distance_error, a.max_distance_error);  // coarser cells, larger error
}

// A cylinder of radius 20 has no third-order terms: the error is fourth order in the cell size. Measured
// (5,000 points within 3.5 mm, cells of 1 mm): max distance error 5.8e-6 mm, max d^2 error 3.5e-5 mm^2;
// asserted with a margin of about 3x.
TEST(SquaredDistanceField, MatchesExactDistancesOnACylinder) {
  Cylinder c;
  c.axis_point = Eigen::Vector3d(1, 2, 3);
  c.axis_direction = Eigen::Vector3d(0.2, -0.1, 1).normalized();
  c.radius = 20.0;
  const CylinderModel cylinder(c);
  SquaredDistanceField::Options o;
  o.cell_size = 1.0;
  o.band = 4.0;
  o.box_min = c.axis_point - Eigen::Vector3d::Constant(30.0);
  o.box_max = c.axis_point + Eigen::Vector3d::Constant(30.0);
  const SquaredDistanceField field(cylinder, o);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> angle(0, 2 * M_PI), height(-15, 15), radial(-3.5, 3.5);
  const Eigen::Vector3d e1 = c.axis_direction.unitOrthogonal(), e2 = c.axis_direction.cross(e1);
  Eigen::Matrix3Xd y(3, 5000);
  for (Eigen::Index j = 0; j < y.cols(); ++j) {
    const double a = angle(rng);
    y.col(j) = c.axis_point + height(rng) * c.axis_direction +
               (c.radius + radial(rng)) * (std::cos(a) * e1 + std::sin(a) * e2);
  }
  const Agreement a = Compare(cylinder, field, y);
  EXPECT_EQ(a.answered, y.cols());
  std::printf("cylinder R 20, 1 mm cells: max |d error| %.3g mm, max |d^2 error| %.3g mm^2\n",
              a.max_distance_error, a.max_square_error);
  EXPECT_LT(a.max_distance_error, 1.5e-5);
  EXPECT_LT(a.max_square_error, 1e-4);
  // Outside the band (beyond it, and near the axis, a focal line) and outside the box: no answer, exact feet.
  SquaredDistanceField::Answer answer;
  EXPECT_FALSE(field.Query(c.axis_point + (c.radius + 6.0) * e1, answer));
  EXPECT_FALSE(field.Query(c.axis_point + Eigen::Vector3d(100, 0, 0), answer));
  EXPECT_FALSE(field.Query(c.axis_point + 0.3 * e2, answer));
}

TEST(SquaredDistanceField, RefusesBoundaryCellsAndBadOptions) {
  const BSplineSurface patch = BumpyPatch(0.03);
  SquaredDistanceField::Options o;
  o.cell_size = 2.0;
  o.band = 4.0;
  const SquaredDistanceField field(patch, o);
  EXPECT_GT(field.untrusted_cell_count(), 0u);
  SquaredDistanceField::Answer answer;
  LocalGeometry g;
  const ParameterDomain d = patch.domain();
  patch.Evaluate({d.lo[0], 0.5 * (d.lo[1] + d.hi[1]), 0.0}, 0, g);  // on the open boundary u = lo
  EXPECT_FALSE(field.Query(To3(g.point), answer));
  o.cell_size = 0.0;
  EXPECT_THROW(SquaredDistanceField(patch, o), std::invalid_argument);
  o.cell_size = 1e-3;
  EXPECT_THROW(SquaredDistanceField(patch, o), std::invalid_argument);  // grid beyond max_grid_cells
}

// Registration with the field recovers the pose of a noise-free scan to the same tolerance as without it
// (tests/foot_point_test.cpp): the final exact iteration removes the field's approximation.
TEST(SquaredDistanceField, RegistrationWithTheFieldRecoversThePose) {
  const BSplineSurface patch = BumpyPatch(0.03);
  SquaredDistanceField::Options fo;
  fo.cell_size = 1.0;
  SquaredDistanceField field(patch, fo);
  const Eigen::Matrix3Xd on_model = PointsAround(patch, 3000, 0.0, 0.1, 0.9, 9);
  const auto [truth, start] = test::ThreeDegreeRegistrationPoses();
  const Eigen::Matrix3Xd scan = truth.inverse().apply(on_model);
  for (const ErrorTerm term : {ErrorTerm::kSdm, ErrorTerm::kTdm}) {
    ModelRegistrationOptions o;
    o.error_term = term;
    o.rotation_tolerance = 1e-10;
    o.translation_tolerance = 1e-10;
    o.squared_distance_field = &field;
    const ModelRegistrationResult r = RegisterToModel(patch, scan, start, o);
    const Eigen::Matrix3Xd placed = r.model_T_scan.apply(scan);
    EXPECT_LT((placed - on_model).colwise().norm().maxCoeff(), 1e-7) << ToString(term);
    EXPECT_LT(r.residuals.rms, 1e-7) << ToString(term);
    EXPECT_GE(r.field_iterations, 2) << ToString(term);
    EXPECT_EQ(r.iterations - r.field_iterations, 1) << ToString(term);
    // Before the exact iteration the field alone is already within its accuracy of the truth.
    const RigidMotion field_pose = r.pose_history[static_cast<std::size_t>(r.field_iterations - 1)];
    EXPECT_LT((field_pose.apply(scan) - on_model).colwise().norm().maxCoeff(), 1e-3) << ToString(term);
  }
}

// A lazy field holds only the cells of blocks it was prepared for, and each of them answers as the field
// built whole does: the same cells (the same trust tests), and the same approximant up to the exact feet's
// Newton tolerance (the cells' warm starts come from different neighbours).
TEST(SquaredDistanceField, LazyCellsAnswerAsTheWholeFieldDoes) {
  const BSplineSurface patch = BumpyPatch(0.03);
  SquaredDistanceField::Options o;
  const SquaredDistanceField whole(patch, o);
  o.lazy = true;
  SquaredDistanceField lazy(patch, o);
  EXPECT_EQ(lazy.cell_count(), 0u);
  const Eigen::Matrix3Xd y = PointsAround(patch, 5000, 1.0, 0.3, 0.7, 5);
  SquaredDistanceField::Answer a, b;
  for (Eigen::Index j = 0; j < y.cols(); ++j) ASSERT_FALSE(lazy.Query(y.col(j), a));  // nothing built yet
  lazy.Prepare(y);
  EXPECT_GT(lazy.cell_count(), 0u);
  EXPECT_LT(lazy.cell_count(), whole.cell_count() / 4);  // the middle of the patch, 1 mm either side
  for (Eigen::Index j = 0; j < y.cols(); ++j) {
    const bool answered = whole.Query(y.col(j), a);
    ASSERT_EQ(lazy.Query(y.col(j), b), answered) << j;
    if (!answered) continue;
    EXPECT_LT((a.foot - b.foot).norm(), 1e-9) << j;
    EXPECT_NEAR(a.squared_distance, b.squared_distance, 1e-9) << j;
    EXPECT_LT((a.frame.normals[0] - b.frame.normals[0]).norm(), 1e-9) << j;
    EXPECT_NEAR(a.frame.curvatures[0], b.frame.curvatures[0], 1e-9) << j;
  }
  // Preparing the same points again computes nothing more.
  const std::size_t cells = lazy.cell_count();
  lazy.Prepare(y);
  EXPECT_EQ(lazy.cell_count(), cells);
  // A field built whole ignores Prepare.
  SquaredDistanceField whole_copy(patch, SquaredDistanceField::Options());
  whole_copy.Prepare(y);
  EXPECT_EQ(whole_copy.cell_count(), whole.cell_count());
}

// The scan of the registration tests below: the patch's inner part with Gaussian noise of 0.02 mm along the
// normal (like the benchmark's), seen from `truth`; the start 3 degrees and about 1.9 mm off.
struct NoisyScan {
  Eigen::Matrix3Xd on_model, scan;
  RigidMotion truth, start;
};

NoisyScan MakeNoisyScan(const ParametricModel& model, int count) {
  NoisyScan s;
  const ParameterDomain d = model.domain();
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(0.1, 0.9);
  std::normal_distribution<double> gauss(0.0, 0.02);
  s.on_model.resize(3, count);
  LocalGeometry g;
  for (int j = 0; j < count; ++j) {
    model.Evaluate({d.lo[0] + u(rng) * (d.hi[0] - d.lo[0]), d.lo[1] + u(rng) * (d.hi[1] - d.lo[1]), 0.0}, 1,
                   g);
    const Eigen::Vector3d n = Eigen::Vector3d(g.d1.col(0)).cross(Eigen::Vector3d(g.d1.col(1))).normalized();
    s.on_model.col(j) = To3(g.point) + gauss(rng) * n;
  }
  const test::RegistrationPoses poses = test::ThreeDegreeRegistrationPoses();
  s.truth = poses.truth;
  s.start = poses.start;
  s.scan = s.truth.inverse().apply(s.on_model);
  return s;
}

// Registration of the noisy scan: the given term, run until its steps fall below 1e-9.
ModelRegistrationOptions NoisyScanRegistration(ErrorTerm term) {
  ModelRegistrationOptions o;
  o.error_term = term;
  o.rotation_tolerance = 1e-9;
  o.translation_tolerance = 1e-9;
  return o;
}

// The largest displacement of the scan's points between two poses.
double MaxDisplacement(const Eigen::Matrix3Xd& scan, const RigidMotion& a, const RigidMotion& b) {
  return (a.apply(scan) - b.apply(scan)).colwise().norm().maxCoeff();
}

// The field's parameter of the approximate foot (Answer::t, the warm start of the exact feet when the
// registration leaves the field) is near the exact foot's: with the parametrization's second-order term the
// model points differ by at most 1.0e-3 mm over points within 3 mm (measured; 1.0e-2 mm with the first-order
// term alone).
TEST(SquaredDistanceField, ParameterOfTheApproximateFootIsNearTheExactOne) {
  const BSplineSurface patch = BumpyPatch(0.03);
  SquaredDistanceField::Options o;
  const SquaredDistanceField field(patch, o);
  const Eigen::Matrix3Xd y = PointsAround(patch, 5000, 3.0 / std::sqrt(3.0), 0.1, 0.9, 5);
  std::vector<FootPoint> exact;
  ComputeFootPoints(patch, y, exact);
  SquaredDistanceField::Answer answer;
  LocalGeometry ga, ge;
  double worst = 0.0;
  for (Eigen::Index j = 0; j < y.cols(); ++j) {
    ASSERT_TRUE(field.Query(y.col(j), answer));
    patch.Evaluate(answer.t, 0, ga);
    patch.Evaluate(exact[static_cast<std::size_t>(j)].t, 0, ge);
    worst = std::max(worst, (ga.point - ge.point).norm());
  }
  std::printf("max |C(field t) - C(exact t)| %.3g mm\n", worst);
  EXPECT_LT(worst, 2e-3);
}

// The final exact iteration after the field's iterations starts its Newton feet from the field's parameters
// (then reuses Newton's geometry): its pose equals that of one cold exact iteration (feet from the model's
// sample tree) from the field's final pose, on a noisy scan, to rounding.
TEST(SquaredDistanceField, WarmStartedExactIterationEqualsTheColdOne) {
  const BSplineSurface patch = BumpyPatch(0.03);
  SquaredDistanceField field(patch, SquaredDistanceField::Options());
  const NoisyScan s = MakeNoisyScan(patch, 4000);
  for (const ErrorTerm term : {ErrorTerm::kSdm, ErrorTerm::kTdm}) {
    ModelRegistrationOptions o = NoisyScanRegistration(term);
    o.squared_distance_field = &field;
    const ModelRegistrationResult warm = RegisterToModel(patch, s.scan, s.start, o);
    ASSERT_EQ(warm.iterations - warm.field_iterations, 1) << ToString(term);
    const RigidMotion field_pose = warm.pose_history[static_cast<std::size_t>(warm.field_iterations - 1)];
    o.squared_distance_field = nullptr;
    o.optimizer.max_iterations = 1;
    const ModelRegistrationResult cold = RegisterToModel(patch, s.scan, field_pose, o);
    ASSERT_EQ(cold.iterations, 1) << ToString(term);
    EXPECT_LT(MaxDisplacement(s.scan, warm.model_T_scan, cold.model_T_scan), 1e-9) << ToString(term);
    EXPECT_NEAR(warm.residuals.rms, cold.residuals.rms, 1e-12) << ToString(term);
    // The residuals are the exact feet's at the final pose (its pass computes feet only, no equations).
    std::vector<FootPoint> feet;
    ComputeFootPoints(patch, warm.model_T_scan.apply(s.scan), feet);
    double sum = 0.0;
    for (const FootPoint& f : feet) sum += f.distance * f.distance;
    EXPECT_NEAR(warm.residuals.rms, std::sqrt(sum / static_cast<double>(feet.size())), 1e-12)
        << ToString(term);
    // Noise of 0.02 mm: the pose is recovered to a small fraction of it.
    EXPECT_LT(MaxDisplacement(s.scan, warm.model_T_scan, s.truth), 1e-2) << ToString(term);
    EXPECT_NEAR(warm.residuals.rms, 0.02, 2e-3) << ToString(term);
  }
}

// Registration with a lazy field ends at the pose the field built whole gives (both end with an exact
// iteration), computing only the cells the scan visited; a second scan of the model reuses them.
TEST(SquaredDistanceField, LazyFieldRegistersAsTheWholeOneWithFewerCells) {
  const BSplineSurface patch = BumpyPatch(0.03);
  SquaredDistanceField whole(patch, SquaredDistanceField::Options());
  SquaredDistanceField::Options lazy_options;
  lazy_options.lazy = true;
  const NoisyScan s = MakeNoisyScan(patch, 4000);
  for (const ErrorTerm term : {ErrorTerm::kSdm, ErrorTerm::kTdm}) {
    SquaredDistanceField lazy(patch, lazy_options);
    ModelRegistrationOptions o = NoisyScanRegistration(term);
    o.squared_distance_field = &whole;
    const ModelRegistrationResult a = RegisterToModel(patch, s.scan, s.start, o);
    o.squared_distance_field = &lazy;
    const ModelRegistrationResult b = RegisterToModel(patch, s.scan, s.start, o);
    EXPECT_EQ(a.field_iterations, b.field_iterations) << ToString(term);
    EXPECT_LT(MaxDisplacement(s.scan, a.model_T_scan, b.model_T_scan), 1e-7) << ToString(term);
    EXPECT_LT(MaxDisplacement(s.scan, b.model_T_scan, s.truth), 1e-2) << ToString(term);
    std::cout << ToString(term) << ": lazy field " << lazy.cell_count() << " cells in "
              << lazy.build_seconds() << " s, whole field " << whole.cell_count() << " cells in "
              << whole.build_seconds() << " s\n";
    EXPECT_LT(lazy.cell_count(), whole.cell_count() / 2) << ToString(term);
    // The same scan from a start nearby visits (almost) no new cells.
    const std::size_t cells = lazy.cell_count();
    const RigidMotion nearby =
        RigidMotion(RotationAboutAxis(Eigen::Vector3d::UnitZ(), 0.002), Eigen::Vector3d(0.1, 0.0, 0.0)) *
        s.start;
    const ModelRegistrationResult c = RegisterToModel(patch, s.scan, nearby, o);
    EXPECT_LT(MaxDisplacement(s.scan, c.model_T_scan, b.model_T_scan), 1e-7) << ToString(term);
    EXPECT_LT(lazy.cell_count(), cells + cells / 10) << ToString(term);
  }
}

// The exact passes add TDM's and SDM's error matrices from the model's fundamental forms in closed form; the
// first exact step equals the one from the general principal frame (ComputePrincipalFrame, ErrorMatrix) and
// full 3 x 3 constraints.
TEST(SquaredDistanceField, ExactStepEqualsTheGeneralErrorMatrixStep) {
  const BSplineSurface patch = BumpyPatch(0.03);
  const NoisyScan s = MakeNoisyScan(patch, 3000);
  const Eigen::Matrix3Xd placed = s.start.apply(s.scan);
  std::vector<FootPoint> feet;
  ComputeFootPoints(patch, placed, feet);
  for (const ErrorTerm term : {ErrorTerm::kSdm, ErrorTerm::kTdm}) {
    RigidNormalEquations eq;
    LocalGeometry g;
    int tangential = 0;
    for (Eigen::Index j = 0; j < placed.cols(); ++j) {
      patch.Evaluate(feet[static_cast<std::size_t>(j)].t, 2, g);
      const PrincipalFrame f = ComputePrincipalFrame(g, placed.col(j));
      if (SdmWeight(f.delta, f.curvatures[0]) > 0 || SdmWeight(f.delta, f.curvatures[1]) > 0) ++tangential;
      eq.Add(
          {placed.col(j), To3(g.point), ErrorMatrix(term, f, 3), 1.0 / static_cast<double>(placed.cols())});
    }
    EXPECT_GT(tangential, placed.cols() / 4);  // SDM's tangential terms are exercised
    const Eigen::Matrix<double, 6, 1> v = SolveRigidVelocity(eq, 1e-6);  // the first trial's damping
    const RigidMotion expected = RigidMotion::FromHelicalVelocity(v.head<3>(), v.tail<3>()) * s.start;
    ModelRegistrationOptions o;
    o.error_term = term;
    o.optimizer.max_iterations = 1;
    const ModelRegistrationResult r = RegisterToModel(patch, s.scan, s.start, o);
    ASSERT_EQ(r.iterations, 1) << ToString(term);
    EXPECT_LT(MaxDisplacement(s.scan, r.model_T_scan, expected), 1e-9) << ToString(term);
    EXPECT_GT(MaxDisplacement(s.scan, r.model_T_scan, s.start), 0.5) << ToString(term);  // a real step
  }
}

}  // namespace
}  // namespace s2m
