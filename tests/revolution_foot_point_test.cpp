// Meridian-plane foot points of surfaces of revolution (fitting/kinematic_surfaces.h, FootPointReduction in
// fitting/parametric_model.h): the foot of x lies in x's meridian half-plane where the profile radius is
// positive, so the engine runs a 1-D Newton on the generatrix and lifts the result. The reduced feet must be
// the 2-D Newton's (distance, boundary flag, foot position, geometry at the foot), cold and with both warm
// starts, on the vase, beyond the open ends of a profile, on the axis; and the engine must fall back to the
// 2-D Newton where the reduction does not hold (a profile that may cross the axis, feet on the axis).

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <random>

#include "fitting/foot_point.h"
#include "fitting/initial_models.h"
#include "fitting/kinematic_surfaces.h"
#include "synthetic/synthetic_cases.h"

namespace s2m {
namespace {

// A surface forwarded call by call, with or without its foot-point reduction, counting its evaluations: the
// generic 2-D path (reduction off) to compare with, and a probe of which path ran. Its shape Jacobian is the
// column list only (no FactoredShapeJacobian).
class Forwarding final : public ParametricModel {
 public:
  Forwarding(const KinematicSurface& surface, bool reduce) : surface_(surface), reduce_(reduce) {}
  Forwarding(const Forwarding& other)
      : ParametricModel(other), surface_(other.surface_), reduce_(other.reduce_) {}
  std::unique_ptr<ParametricModel> Clone() const override { return std::make_unique<Forwarding>(*this); }
  void CopyFrom(const ParametricModel& other) override {
    surface_ = dynamic_cast<const Forwarding&>(other).surface_;
  }
  std::string name() const override { return surface_.name(); }
  int ambient_dimension() const override { return 3; }
  ParameterDomain domain() const override { return surface_.domain(); }
  int num_parameters() const override { return surface_.num_parameters(); }
  std::string parameter_name(int index) const override { return surface_.parameter_name(index); }
  Eigen::VectorXd parameters() const override { return surface_.parameters(); }
  void set_parameters(const Eigen::VectorXd& p) override { surface_.set_parameters(p); }
  void ApplySimilarity(double scale, const VecS& offset) override { surface_.ApplySimilarity(scale, offset); }
  void Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const override {
    ++evaluations_;
    surface_.Evaluate(t, derivatives, out);
  }
  void ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const override {
    surface_.ShapeJacobian(t, with_dt, out);
  }
  std::vector<ParamT> SampleParameters() const override { return surface_.SampleParameters(); }
  bool SupportsTranslation() const override { return surface_.SupportsTranslation(); }
  Eigen::MatrixXd FairnessMatrix(const FairnessWeights& weights) const override {
    return surface_.FairnessMatrix(weights);
  }
  std::vector<Motion6> InvariantMotions() const override { return surface_.InvariantMotions(); }
  std::vector<Motion6> CommonMotionsAbsorbedByShape() const override {
    return surface_.CommonMotionsAbsorbedByShape();
  }
  const KinematicSurface& surface() const { return surface_; }
  // FactoredShapeJacobian is not forwarded: the assembly uses ShapeJacobian's columns.
  std::unique_ptr<FootPointReduction> MakeFootPointReduction() const override {
    return reduce_ ? surface_.MakeFootPointReduction() : nullptr;
  }
  long evaluations() const { return evaluations_; }

 private:
  KinematicSurface surface_;
  bool reduce_;
  mutable std::atomic<long> evaluations_{0};
};

// The points moved by a small rigid motion: the next iteration's points (a warm start's situation).
Eigen::Matrix3Xd Moved(const Eigen::Matrix3Xd& p) {
  const RigidMotion m(RotationAboutAxis(Eigen::Vector3d(1, -2, 0.5).normalized(), 0.2 * M_PI / 180),
                      Eigen::Vector3d(0.03, -0.02, 0.01));
  return m.apply(p);
}

struct Feet {
  std::vector<FootPoint> feet;
  std::vector<LocalGeometry> geometry;  // what FootPointOf leaves in g
};

Feet FeetOf(const ParametricModel& model, const Eigen::Matrix3Xd& points,
            const std::vector<FootPoint>* previous, WarmStart mode) {
  const FootPointContext context(model);
  Feet out;
  for (Eigen::Index j = 0; j < points.cols(); ++j) {
    const auto i = static_cast<std::size_t>(j);
    LocalGeometry g;
    out.feet.push_back(
        FootPointOf(context, points.col(j), previous != nullptr ? &(*previous)[i].t : nullptr, mode, g));
    out.geometry.push_back(g);
  }
  return out;
}

struct Differences {
  double distance = 0.0, position = 0.0, geometry = 0.0, lifted = 0.0;
};

// Reduced feet against the generic ones: distances, boundary flags, foot positions, and the geometry left in
// g, which must also be the model's own at the reduced foot's t. Returns the largest differences.
Differences ExpectSameFeet(const KinematicSurface& surface, const Eigen::Matrix3Xd& points,
                           const std::vector<FootPoint>* previous, WarmStart mode) {
  const Forwarding reduced(surface, true), generic(surface, false);
  const Feet a = FeetOf(reduced, points, previous, mode), b = FeetOf(generic, points, previous, mode);
  const double size = (points.rowwise().maxCoeff() - points.rowwise().minCoeff()).norm();
  Differences d;
  LocalGeometry own;
  for (std::size_t j = 0; j < a.feet.size(); ++j) {
    EXPECT_EQ(a.feet[j].on_boundary, b.feet[j].on_boundary) << "point " << j;
    d.distance = std::max(d.distance, std::abs(a.feet[j].distance - b.feet[j].distance));
    d.position = std::max(d.position, (a.geometry[j].point - b.geometry[j].point).norm());
    const double g_difference = std::max((a.geometry[j].d1 - b.geometry[j].d1).cwiseAbs().maxCoeff(),
                                         (a.geometry[j].d2 - b.geometry[j].d2).cwiseAbs().maxCoeff());
    d.geometry = std::max(d.geometry, g_difference);
    // The lifted geometry is the model's own at the returned t, and its distance that of C(t).
    surface.Evaluate(a.feet[j].t, 2, own);
    d.lifted = std::max(
        {d.lifted, (own.point - a.geometry[j].point).norm(),
         (own.d1 - a.geometry[j].d1).cwiseAbs().maxCoeff(), (own.d2 - a.geometry[j].d2).cwiseAbs().maxCoeff(),
         std::abs((own.point - VecS(points.col(static_cast<Eigen::Index>(j)))).norm() - a.feet[j].distance)});
    EXPECT_GE(a.feet[j].t[1], 0.0);
    EXPECT_LT(a.feet[j].t[1], 2 * M_PI);
  }
  // Both Newtons stop when a step no longer decreases |C - X| beyond its rounding, so the foot's position is
  // settled to about the square root of that rounding (foot_point_test): measured differences on
  // the vase are <= 4e-14 in distance and <= 2e-8 mm (1e-10 of the size) in position and derivatives, 4e-13
  // beyond a profile's ends; the lifted geometry is the model's own at the reduced t to 5e-14.
  EXPECT_LE(d.distance, 1e-12 * size);
  EXPECT_LE(d.position, 1e-9 * size);
  EXPECT_LE(d.geometry, 1e-9 * size);
  EXPECT_LE(d.lifted, 1e-14 * size);
  return d;
}

// Cold, then both warm starts after a small motion of the points.
void ExpectSameFeetAllModes(const KinematicSurface& surface, const Eigen::Matrix3Xd& points) {
  ExpectSameFeet(surface, points, nullptr, WarmStart::kVerified);
  const Forwarding generic(surface, false);
  const std::vector<FootPoint> previous = FeetOf(generic, points, nullptr, WarmStart::kVerified).feet;
  const Eigen::Matrix3Xd moved = Moved(points);
  for (const WarmStart mode : {WarmStart::kTrusted, WarmStart::kVerified})
    ExpectSameFeet(surface, moved, &previous, mode);
}

Eigen::Matrix3Xd VasePoints(const SyntheticCase& c, Eigen::Index count) {
  Eigen::Matrix3Xd points = c.views.model_T_scan_true[0].apply(c.views.scans[0]);
  points.conservativeResize(3, std::min<Eigen::Index>(points.cols(), count));
  return points;
}

TEST(RevolutionFootPoint, ReducedFeetEqualTheTwoDimensionalNewtonOnTheVase) {
  const SyntheticCase c = MakeSyntheticCase("vase");
  const auto* vase = dynamic_cast<const KinematicSurface*>(c.truth.get());
  ASSERT_NE(vase, nullptr);
  ASSERT_NE(vase->MakeFootPointReduction(), nullptr);
  ExpectSameFeetAllModes(*vase, VasePoints(c, 2000));
  // A start model 1 % off (the first feet of a fit) and points 5 mm off the surface.
  const auto* start = dynamic_cast<const KinematicSurface*>(c.start.get());
  ASSERT_NE(start, nullptr);
  Eigen::Matrix3Xd off = VasePoints(c, 1000);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> gauss(0.0, 5.0);
  for (Eigen::Index j = 0; j < off.cols(); ++j)
    off.col(j) += Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
  ExpectSameFeetAllModes(*start, off);
}

TEST(RevolutionFootPoint, TheReducedPathEvaluatesOnlyTheGeneratrix) {
  const SyntheticCase c = MakeSyntheticCase("vase");
  const auto& vase = dynamic_cast<const KinematicSurface&>(*c.truth);
  const Eigen::Matrix3Xd points = VasePoints(c, 500);
  const Forwarding reduced(vase, true), generic(vase, false);
  FeetOf(reduced, points, nullptr, WarmStart::kVerified);
  FeetOf(generic, points, nullptr, WarmStart::kVerified);
  // No evaluation of the surface itself (its samples for the 2-D seeds are never built either).
  EXPECT_EQ(reduced.evaluations(), 0);
  EXPECT_GT(generic.evaluations(), 3 * points.cols());
}

// The distance from x to a surface of revolution whose radii are >= 0, by brute force: the planar distance
// from (rho, h) to the generatrix (the meridian-plane argument) at 40000 samples: an upper bound of the true
// distance, within ~1e-5 of it on these models.
double BruteForceDistance(const KinematicSurface& surface, const Eigen::Vector3d& x) {
  const Eigen::Vector2d q(std::hypot(x.x(), x.y()), x.z());
  const double lo = surface.basis().lo(), hi = surface.basis().hi();
  double best = INFINITY;
  const int n = 40000;
  for (int i = 0; i <= n; ++i)
    best = std::min(best, (surface.ProfilePoint(lo + (hi - lo) * i / n) - q).norm());
  return best;
}

// A bowl-like profile (radius 20..40 over height 0..30) and points beyond its open ends (above the rim and
// below the bottom edge, outwards), where the feet lie on the boundary circles.
KinematicSurface Bowl() {
  return KinematicSurface::Revolution(
      UnitSpacedClamped(4, 6),
      (Eigen::Matrix2Xd(2, 6) << 20, 24, 30, 35, 38, 40, 0, 5, 11, 18, 24, 30).finished());
}

TEST(RevolutionFootPoint, ReducedFeetBeyondTheOpenEndsLieOnTheBoundary) {
  const KinematicSurface bowl = Bowl();
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> angle(-M_PI, M_PI), radius(15, 60), above(32, 45), below(-15, -2);
  Eigen::Matrix3Xd points(3, 600);
  for (Eigen::Index j = 0; j < points.cols(); ++j) {
    const double a = angle(rng), rho = radius(rng), h = j % 2 == 0 ? above(rng) : below(rng);
    points.col(j) << rho * std::cos(a), rho * std::sin(a), h;
  }
  ExpectSameFeetAllModes(bowl, points);
  const Forwarding reduced(bowl, true);
  const Feet feet = FeetOf(reduced, points, nullptr, WarmStart::kVerified);
  int on_boundary = 0;
  for (const FootPoint& f : feet.feet) on_boundary += f.on_boundary ? 1 : 0;
  EXPECT_GT(on_boundary, points.cols() / 2);  // most of them: beyond the rim and the bottom edge
}

TEST(RevolutionFootPoint, PointsOnTheAxisGetTheDistanceOfEveryMeridian) {
  const KinematicSurface bowl = Bowl();
  Eigen::Matrix3Xd points(3, 7);
  for (Eigen::Index j = 0; j < points.cols(); ++j)
    points.col(j) << 0.0, 0.0, -10.0 + 8.0 * static_cast<double>(j);
  const Forwarding reduced(bowl, true), generic(bowl, false);
  const Feet a = FeetOf(reduced, points, nullptr, WarmStart::kVerified);
  const Feet b = FeetOf(generic, points, nullptr, WarmStart::kVerified);
  EXPECT_EQ(reduced.evaluations(), 0);
  LocalGeometry own;
  for (std::size_t j = 0; j < a.feet.size(); ++j) {
    // Every v is a foot on the axis: the reduced one takes v = 0, the 2-D Newton keeps its seed's. The 2-D
    // Hessian is singular there (f is flat in v), so the 2-D Newton settles u only to ~1e-6 (measured); the
    // distance, stationary, agrees to rounding, and the reduced foot is the brute-force one.
    EXPECT_EQ(a.feet[j].t[1], 0.0);
    EXPECT_NEAR(a.feet[j].distance, b.feet[j].distance, 1e-12) << "point " << j;
    EXPECT_NEAR(a.feet[j].t[0], b.feet[j].t[0], 1e-5) << "point " << j;
    EXPECT_LE(a.feet[j].distance, BruteForceDistance(bowl, points.col(static_cast<Eigen::Index>(j))) + 1e-12)
        << "point " << j;
    EXPECT_EQ(a.feet[j].on_boundary, b.feet[j].on_boundary) << "point " << j;
    bowl.Evaluate(a.feet[j].t, 2, own);
    EXPECT_LE((own.point - a.geometry[j].point).norm(), 1e-13);
    EXPECT_LE((own.d1 - a.geometry[j].d1).cwiseAbs().maxCoeff(), 1e-13);
    EXPECT_LE((own.d2 - a.geometry[j].d2).cwiseAbs().maxCoeff(), 1e-13);
  }
}

Eigen::Matrix3Xd PointsAround(double rho_max, double z_lo, double z_hi, int count, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> angle(-M_PI, M_PI), radius(0, rho_max), height(z_lo, z_hi);
  Eigen::Matrix3Xd points(3, count);
  for (Eigen::Index j = 0; j < points.cols(); ++j) {
    const double a = angle(rng), rho = radius(rng);
    points.col(j) << rho * std::cos(a), rho * std::sin(a), height(rng);
  }
  return points;
}

TEST(RevolutionFootPoint, AProfileThatMayCrossTheAxisUsesTheTwoDimensionalNewton) {
  // Radii from 10 down to -6: the generatrix crosses the axis, where the meridian-plane argument fails.
  const KinematicSurface crossing = KinematicSurface::Revolution(
      UnitSpacedClamped(4, 5), (Eigen::Matrix2Xd(2, 5) << 10, 6, 2, -3, -6, 0, 5, 10, 15, 20).finished());
  EXPECT_EQ(crossing.MakeFootPointReduction(), nullptr);
  const Eigen::Matrix3Xd points = PointsAround(15, -5, 25, 300, 9);
  const Forwarding reduced(crossing, true), generic(crossing, false);
  const Feet a = FeetOf(reduced, points, nullptr, WarmStart::kVerified);
  const Feet b = FeetOf(generic, points, nullptr, WarmStart::kVerified);
  for (std::size_t j = 0; j < a.feet.size(); ++j) {
    EXPECT_EQ(a.feet[j].t, b.feet[j].t);
    EXPECT_EQ(a.feet[j].distance, b.feet[j].distance);
  }
  // Helical surfaces have no meridian plane either.
  EXPECT_EQ(KinematicSurface::Helical(UnitSpacedClamped(4, 5),
                                      (Eigen::Matrix2Xd(2, 5) << 10, 9, 8, 7, 6, 0, 1, 2, 3, 4).finished(),
                                      2.0, 2.0)
                .MakeFootPointReduction(),
            nullptr);
}

TEST(RevolutionFootPoint, FeetWhereTheGeneratrixTouchesTheAxisFallBackToTheTwoDimensionalNewton) {
  // A closed bottom: the profile starts on the axis (r = 0 at u = lo), then r >= 0 everywhere, so the
  // reduction holds, except at feet on the axis itself (the bottom's centre), where v is undetermined and the
  // surface singular: those go to the 2-D Newton, with the same result as without the reduction.
  const KinematicSurface cup = KinematicSurface::Revolution(
      UnitSpacedClamped(4, 6),
      (Eigen::Matrix2Xd(2, 6) << 0, 8, 15, 18, 19, 20, 0, 0, 1, 8, 16, 25).finished());
  ASSERT_NE(cup.MakeFootPointReduction(), nullptr);
  // Below the bottom's centre (its foot is the pole, u = lo) and elsewhere.
  Eigen::Matrix3Xd points = PointsAround(25, -5, 30, 400, 11);
  points.col(0) << 0.0, 0.0, -3.0;
  points.col(1) << 1e-3, -2e-3, -4.0;
  const Forwarding reduced(cup, true), generic(cup, false);
  const Feet a = FeetOf(reduced, points, nullptr, WarmStart::kVerified);
  const Feet b = FeetOf(generic, points, nullptr, WarmStart::kVerified);
  // The pole's feet are the 2-D Newton's exactly (it ran for them).
  EXPECT_EQ(a.feet[0].t, b.feet[0].t);
  EXPECT_EQ(a.feet[0].distance, b.feet[0].distance);
  EXPECT_NEAR(a.feet[0].distance, 3.0, 1e-12);
  EXPECT_GT(reduced.evaluations(), 0);  // the fallback did evaluate the surface
  // Elsewhere the reduced feet are the true ones (brute force). The 2-D Newton agrees with them to rounding,
  // except where it stalls at the singular pole (u = lo, every v): there it stops on the bottom's boundary,
  // farther away, and the reduced foot is the better one.
  const double size = 60.0;
  int stalled = 0;
  for (std::size_t j = 1; j < a.feet.size(); ++j) {
    const double brute = BruteForceDistance(cup, points.col(static_cast<Eigen::Index>(j)));
    EXPECT_LE(a.feet[j].distance, brute + 1e-12 * size) << "point " << j;
    EXPECT_GE(a.feet[j].distance, brute - 1e-4) << "point " << j;
    if (b.feet[j].distance <= brute + 1e-12 * size) {
      EXPECT_NEAR(a.feet[j].distance, b.feet[j].distance, 1e-12 * size) << "point " << j;
      EXPECT_EQ(a.feet[j].on_boundary, b.feet[j].on_boundary) << "point " << j;
    } else {
      EXPECT_TRUE(b.feet[j].on_boundary) << "point " << j;
      EXPECT_EQ(b.feet[j].t[0], cup.basis().lo()) << "point " << j;
      ++stalled;
    }
  }
  EXPECT_LT(stalled, 10);  // measured: 4 of 399 (points near the bottom's centre)
}

TEST(RevolutionFootPoint, FactoredShapeJacobianHasTheShapeJacobiansColumns) {
  const SyntheticCase c = MakeSyntheticCase("vase");
  const auto& vase = dynamic_cast<const KinematicSurface&>(*c.truth);
  const ParameterDomain d = vase.domain();
  std::vector<JacobianEntry> entries;
  FactoredJacobian factored;
  for (int i = 0; i <= 40; ++i) {
    const ParamT t{d.lo[0] + (d.hi[0] - d.lo[0]) * i / 40.0, 0.37 + 0.15 * i, 0.0};
    vase.ShapeJacobian(t, false, entries);
    ASSERT_TRUE(vase.FactoredShapeJacobian(t, factored));
    Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(3, vase.num_parameters());
    Eigen::MatrixXd from_factors = dense;
    for (const JacobianEntry& e : entries) dense.col(e.index) += e.column;
    for (int k = 0; k < factored.weight_count; ++k)
      for (int q = 0; q < factored.direction_count; ++q)
        from_factors.col(factored.first_index[static_cast<std::size_t>(k)] + q) +=
            factored.weights[static_cast<std::size_t>(k)] * factored.directions.col(q);
    EXPECT_LE((dense - from_factors).cwiseAbs().maxCoeff(), 1e-15) << "t " << t[0] << ", " << t[1];
  }
  const KinematicSurface helical = KinematicSurface::Helical(
      UnitSpacedClamped(4, 5), (Eigen::Matrix2Xd(2, 5) << 10, 9, 8, 7, 6, 0, 1, 2, 3, 4).finished(), 2.0,
      2.0);
  EXPECT_FALSE(helical.FactoredShapeJacobian({0.5, 0.5, 0.0}, factored));
}

// The joint fit of the vase with the meridian-plane feet and the factored assembly against the generic path
// (2-D Newton, the Jacobian's columns): the same iterations, and the same profile, poses and RMS to far
// below the noise.
TEST(RevolutionFootPoint, JointFitWithReducedFeetAndFactoredAssemblyMatchesTheGenericPath) {
  const SyntheticCase c = MakeSyntheticCase("vase");
  std::vector<Eigen::Matrix3Xd> scans;
  for (const Eigen::Matrix3Xd& scan : c.views.scans) {
    Eigen::Matrix3Xd every_fourth(3, (scan.cols() + 3) / 4);
    for (Eigen::Index j = 0; j < every_fourth.cols(); ++j) every_fourth.col(j) = scan.col(4 * j);
    scans.push_back(every_fourth);
  }
  JointFitOptions o = c.options;
  o.optimizer.max_iterations = 12;
  const auto& start = dynamic_cast<const KinematicSurface&>(*c.start);
  KinematicSurface fast = start;
  Forwarding generic(start, false);
  const JointFitResult a = FitJointly(fast, scans, c.views.model_T_scan_recorded, o);
  const JointFitResult b = FitJointly(generic, scans, c.views.model_T_scan_recorded, o);
  ASSERT_EQ(a.iterations, b.iterations);
  const double p_difference = (fast.parameters() - generic.parameters()).cwiseAbs().maxCoeff();
  // Measured: 5e-10 mm and 3e-16 mm (the feet agree to ~1e-8 mm, foot_point_test).
  EXPECT_LE(p_difference, 1e-8);  // mm, on a 150 mm vase
  EXPECT_LE(std::abs(a.residuals.rms - b.residuals.rms), 1e-12);
  for (std::size_t k = 0; k < scans.size(); ++k) {
    EXPECT_LE((a.model_T_scan[k].rotation() - b.model_T_scan[k].rotation()).norm(), 1e-9);
    EXPECT_LE((a.model_T_scan[k].translation() - b.model_T_scan[k].translation()).norm(), 1e-8);
  }
}

}  // namespace
}  // namespace s2m
