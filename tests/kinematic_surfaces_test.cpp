// KinematicSurface's per-span power-form table of its generatrix (fitting/kinematic_surfaces.h, SpanPowerForm
// in fitting/bspline_models.h) against plain sums over the reference basis (BSplineBasis::EvaluateReference):
// ProfilePoint and Evaluate (which expose the private ProfileAt: at v = 0, d1.col(0) = (r', 0, z') and
// d2.col(0) = (r'', 0, z'')), for surfaces of revolution and helical surfaces, orders 3-5, uniform and
// non-uniform clamped knots, at random parameters, at the knots and at the ends; and that the table follows
// set_parameters, ApplySimilarity, Clone and CopyFrom.

#include "fitting/kinematic_surfaces.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "fitting/initial_models.h"

namespace s2m {
namespace {

constexpr double kRelative = 1e-13;

// Clamped knots on [0, 2] with spans of very different lengths (ratio about 10) and, for order >= 3, a double
// interior knot.
BSplineBasis NonUniform(int order, int num_control, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> gap(0.2, 2.0);
  std::vector<double> steps;
  const int interior = num_control - order;
  for (int i = 0; i <= interior; ++i) steps.push_back(gap(rng));
  double total = 0.0;
  for (double s : steps) total += s;
  std::vector<double> knots(static_cast<std::size_t>(order), 0.0);
  double at = 0.0;
  for (int i = 0; i < interior; ++i) {
    at += 2.0 * steps[static_cast<std::size_t>(i)] / total;
    knots.push_back(at);
  }
  if (order >= 3 && interior >= 2)
    knots[static_cast<std::size_t>(order) + 1] = knots[static_cast<std::size_t>(order)];
  knots.insert(knots.end(), static_cast<std::size_t>(order), 2.0);
  return BSplineBasis::Clamped(order, std::move(knots));
}

Eigen::Matrix2Xd RandomProfile(int n, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> r(0.5, 3.0), dz(0.1, 1.0);
  Eigen::Matrix2Xd p(2, n);
  double z = -1.0;
  for (int k = 0; k < n; ++k) {
    p(0, k) = r(rng);
    p(1, k) = z;
    z += dz(rng);
  }
  return p;
}

// The generatrix and its first two u-derivatives (columns) by the reference basis.
Eigen::Matrix<double, 2, 3> ReferenceProfile(const BSplineBasis& basis, const Eigen::Matrix2Xd& profile,
                                             double u) {
  BSplineBasis::Values v;
  basis.EvaluateReference(u, 2, v);
  Eigen::Matrix<double, 2, 3> rz = Eigen::Matrix<double, 2, 3>::Zero();
  for (int i = 0; i < basis.order(); ++i)
    for (int d = 0; d <= 2; ++d)
      rz.col(d) += v.values[static_cast<std::size_t>(d)][static_cast<std::size_t>(i)] *
                   profile.col(basis.ControlIndex(v.first, i));
  return rz;
}

// The rounding scale of derivative d: max |P| times the largest sum_i |B_i^(d)(u)| over the domain.
std::array<double, 3> DerivativeScales(const BSplineBasis& basis, const Eigen::Matrix2Xd& profile) {
  std::array<double, 3> scale{0.0, 0.0, 0.0};
  BSplineBasis::Values v;
  for (int s = 0; s <= 4000; ++s) {
    basis.EvaluateReference(basis.lo() + (basis.hi() - basis.lo()) * s / 4000, 2, v);
    for (std::size_t d = 0; d < 3; ++d) {
      double sum = 0.0;
      for (int i = 0; i < basis.order(); ++i) sum += std::abs(v.values[d][static_cast<std::size_t>(i)]);
      scale[d] = std::max(scale[d], sum);
    }
  }
  for (double& s : scale) s *= profile.cwiseAbs().maxCoeff();
  return scale;
}

// Parameters to check: random ones, every knot, each knot's neighbours one ulp away, and the ends.
std::vector<double> TestParameters(const BSplineBasis& basis, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(basis.lo(), basis.hi());
  std::vector<double> out;
  for (int i = 0; i < 300; ++i) out.push_back(u(rng));
  for (double k : basis.knots()) {
    out.push_back(k);
    out.push_back(std::nextafter(k, -1e300));
    out.push_back(std::nextafter(k, 1e300));
  }
  out.push_back(basis.lo());
  out.push_back(basis.hi());
  return out;
}

// Checks ProfilePoint and Evaluate (derivatives 0, 1, 2; v = 0 and a random v) of `surface` against the
// reference sums over surface.profile(); returns how many parameters were checked.
int ExpectMatchesReference(const KinematicSurface& surface, std::mt19937_64& rng, const std::string& label) {
  const BSplineBasis& basis = surface.basis();
  const std::array<double, 3> scale = DerivativeScales(basis, surface.profile());
  const ParameterDomain domain = surface.domain();
  std::uniform_real_distribution<double> angle(domain.lo[1], domain.hi[1]);
  int checked = 0;
  for (double u : TestParameters(basis, rng)) {
    SCOPED_TRACE(label + " u = " + std::to_string(u));
    const Eigen::Matrix<double, 2, 3> ref = ReferenceProfile(basis, surface.profile(), u);
    const Eigen::Vector2d point = surface.ProfilePoint(u);
    EXPECT_NEAR(point.x(), ref(0, 0), kRelative * scale[0]);
    EXPECT_NEAR(point.y(), ref(1, 0), kRelative * scale[0]);

    // At v = 0 the u-columns are (r', 0, z') and (r'', 0, z''): the table's derivatives directly.
    LocalGeometry g;
    surface.Evaluate({u, 0.0}, 2, g);
    EXPECT_EQ(g.point.size(), 3);
    EXPECT_EQ(g.d1.rows(), 3);
    EXPECT_EQ(g.d1.cols(), 2);
    EXPECT_EQ(g.d2.rows(), 3);
    EXPECT_EQ(g.d2.cols(), 3);
    EXPECT_NEAR(g.point[0], ref(0, 0), kRelative * scale[0]);
    EXPECT_NEAR(g.point[2], ref(1, 0), kRelative * scale[0]);
    EXPECT_NEAR(g.d1(0, 0), ref(0, 1), kRelative * scale[1]);
    EXPECT_NEAR(g.d1(2, 0), ref(1, 1), kRelative * scale[1]);
    EXPECT_NEAR(g.d2(0, 0), ref(0, 2), kRelative * scale[2]);
    EXPECT_NEAR(g.d2(2, 0), ref(1, 2), kRelative * scale[2]);

    // A general angle: the full local geometry x(u, v) = (r cos v, r sin v, z + p v) and its derivatives.
    const double v = angle(rng), c = std::cos(v), s = std::sin(v), p = surface.pitch();
    const double r = ref(0, 0), z = ref(1, 0), r1 = ref(0, 1), z1 = ref(1, 1), r2 = ref(0, 2), z2 = ref(1, 2);
    const Eigen::Vector3d point_ref(r * c, r * s, z + p * v);
    Eigen::Matrix<double, 3, 2> d1_ref;
    d1_ref << r1 * c, -r * s, r1 * s, r * c, z1, p;
    Eigen::Matrix3d d2_ref;
    d2_ref << r2 * c, -r1 * s, -r * c, r2 * s, r1 * c, -r * s, z2, 0.0, 0.0;
    for (int derivatives = 0; derivatives <= 2; ++derivatives) {
      surface.Evaluate({u, v}, derivatives, g);
      const double tol0 = kRelative * (scale[0] + std::abs(p * v));
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(g.point[k], point_ref[k], tol0);
      for (int k = 0; k < 3; ++k) {
        EXPECT_NEAR(g.d1(k, 0), derivatives >= 1 ? d1_ref(k, 0) : 0.0, kRelative * scale[1]);
        EXPECT_NEAR(g.d1(k, 1), derivatives >= 1 ? d1_ref(k, 1) : 0.0, kRelative * (scale[0] + std::abs(p)));
        EXPECT_NEAR(g.d2(k, 0), derivatives >= 2 ? d2_ref(k, 0) : 0.0, kRelative * scale[2]);
        EXPECT_NEAR(g.d2(k, 1), derivatives >= 2 ? d2_ref(k, 1) : 0.0, kRelative * scale[1]);
        EXPECT_NEAR(g.d2(k, 2), derivatives >= 2 ? d2_ref(k, 2) : 0.0, kRelative * scale[0]);
      }
    }
    ++checked;
  }
  return checked;
}

KinematicSurface MakeSurface(bool helical, BSplineBasis basis, Eigen::Matrix2Xd profile) {
  return helical ? KinematicSurface::Helical(std::move(basis), std::move(profile), 0.3, 2.0)
                 : KinematicSurface::Revolution(std::move(basis), std::move(profile));
}

TEST(KinematicProfileTable, MatchesReferenceSumsForOrdersKnotsAndKinds) {
  std::mt19937_64 rng(20261201);
  int cases = 0;
  for (bool helical : {false, true})
    for (int order = 3; order <= 5; ++order)
      for (bool uniform : {true, false}) {
        const int n = order + 6;
        BSplineBasis basis =
            uniform ? BSplineBasis::ClampedUniform(order, n, -0.5, 1.5) : NonUniform(order, n, rng);
        const KinematicSurface surface = MakeSurface(helical, basis, RandomProfile(n, rng));
        const std::string label = std::string(helical ? "helical" : "revolution") + " order " +
                                  std::to_string(order) + (uniform ? " uniform" : " non-uniform");
        // 300 random parameters plus 3 per knot plus both ends.
        EXPECT_EQ(ExpectMatchesReference(surface, rng, label), 300 + 3 * (n + order) + 2);
        ++cases;
      }
  EXPECT_EQ(cases, 12);
}

TEST(KinematicProfileTable, FollowsSetParametersApplySimilarityCloneAndCopy) {
  std::mt19937_64 rng(7);
  for (bool helical : {false, true}) {
    const int order = 4, n = 9;
    KinematicSurface surface = MakeSurface(helical, NonUniform(order, n, rng), RandomProfile(n, rng));

    // set_parameters: a new profile (and pitch), the table must be the new one.
    const Eigen::Matrix2Xd fresh = RandomProfile(n, rng);
    Eigen::VectorXd p = surface.parameters();
    p.head(fresh.size()) = Eigen::Map<const Eigen::VectorXd>(fresh.data(), fresh.size());
    if (helical) p[fresh.size()] = -0.7;
    surface.set_parameters(p);
    ASSERT_TRUE(surface.profile().isApprox(fresh, 0.0));
    const double u = 0.37;
    EXPECT_NEAR(surface.ProfilePoint(u).x(), ReferenceProfile(surface.basis(), fresh, u)(0, 0), 1e-13 * 3.0);
    ExpectMatchesReference(surface, rng, "after set_parameters");

    // Clone keeps the table of the state it was cloned from.
    const std::unique_ptr<ParametricModel> clone = surface.Clone();
    const Eigen::Vector2d before = surface.ProfilePoint(u);

    // ApplySimilarity: scaled radii and heights, heights shifted along the axis.
    surface.ApplySimilarity(1.7, VecS(Eigen::Vector3d(0.0, 0.0, 0.4)));
    const Eigen::Vector2d after = surface.ProfilePoint(u);
    EXPECT_NEAR(after.x(), 1.7 * before.x(), 1e-12);
    EXPECT_NEAR(after.y(), 1.7 * before.y() + 0.4, 1e-12);
    ExpectMatchesReference(surface, rng, "after ApplySimilarity");

    const auto& cloned = dynamic_cast<const KinematicSurface&>(*clone);
    EXPECT_EQ(cloned.ProfilePoint(u), before);
    ExpectMatchesReference(cloned, rng, "clone");

    // CopyFrom into a surface with another basis and profile takes the source's table too.
    KinematicSurface target = MakeSurface(helical, BSplineBasis::ClampedUniform(3, 5), RandomProfile(5, rng));
    target.CopyFrom(surface);
    EXPECT_EQ(target.ProfilePoint(u), surface.ProfilePoint(u));
    ExpectMatchesReference(target, rng, "CopyFrom");
  }
}

// The generatrix's end heights, evaluated by the basis' own sums as the fit's reports do (equal to the
// surface's evaluation only to the last bits), are reached: the radius there and its gradient, not a
// domain_error (the vessel's rim and base radii lost their uncertainty to it). 200 random vase profiles,
// heights increasing.
TEST(KinematicSurface, RadiusAtHeightReachesTheGeneratrixEnds) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> radius(20.0, 70.0), rise(3.0, 30.0), start(-80.0, 0.0);
  for (int trial = 0; trial < 200; ++trial) {
    Eigen::Matrix2Xd vase(2, 8);
    double z = start(rng);
    for (int k = 0; k < 8; ++k, z += rise(rng)) vase.col(k) << radius(rng), z;
    const KinematicSurface surface = KinematicSurface::Revolution(UnitSpacedClamped(4, 8), vase);
    const BSplineBasis& basis = surface.basis();
    for (const double u : {basis.lo(), basis.hi()}) {
      BSplineBasis::Values values;
      basis.Evaluate(u, 0, values);
      Eigen::Vector2d rz = Eigen::Vector2d::Zero();
      for (int k = 0; k < basis.order(); ++k)
        rz += values.values[0][static_cast<std::size_t>(k)] * vase.col(basis.ControlIndex(values.first, k));
      Eigen::VectorXd gradient;
      double r = 0.0;
      ASSERT_NO_THROW(r = surface.RadiusAtHeight(rz.y(), &gradient)) << "trial " << trial << ", u " << u;
      EXPECT_NEAR(r, rz.x(), 1e-9);
      EXPECT_TRUE(gradient.allFinite());
    }
  }
}

TEST(SpiralSurface, RaupParametersOfAStraightGeneratingCurve) {
  // A linear generatrix from (r, z) = (10, 2) to (20, 6) (order 2, the control points the curve's ends):
  // inner edge 10, outer 20, so D = 0.5; centre (15, 4), so T = 4 / 15; W = exp(2 pi p).
  Eigen::Matrix2Xd profile(2, 3);
  profile << 10, 15, 20,  //
      2, 4, 6;
  const SpiralSurface s(UnitSpacedClamped(2, 3), profile, 0.1, 0.0, 6.0);
  const SpiralSurface::Raup raup = s.RaupParameters();
  EXPECT_NEAR(raup.w, std::exp(2 * M_PI * 0.1), 1e-12);
  EXPECT_NEAR(raup.d, 0.5, 1e-12);
  EXPECT_NEAR(raup.t, 4.0 / 15.0, 1e-12);
  // Scaling the generating curve about the apex (the same shell a turn later) changes neither.
  Eigen::Matrix2Xd later = profile * std::exp(2 * M_PI * 0.1);
  const SpiralSurface::Raup same =
      SpiralSurface(UnitSpacedClamped(2, 3), later, 0.1, 0.0, 6.0).RaupParameters();
  EXPECT_NEAR(same.d, raup.d, 1e-12);
  EXPECT_NEAR(same.t, raup.t, 1e-12);
  // A curve crossing the axis has no D.
  profile(0, 0) = -5;
  EXPECT_TRUE(std::isnan(SpiralSurface(UnitSpacedClamped(2, 3), profile, 0.1, 0.0, 6.0).RaupParameters().d));
}

// The whorl measures of docs/shells.md eqs. S4-S6 on the straight generating curve above (r 10 to 20, z 2 to
// 6), logarithmic and allometric: the closed forms of the scales e^{p v + q v^2 / 2} and e^{(p + a) v + ...}.
TEST(SpiralSurface, WhorlMeasuresAgainstTheirClosedForms) {
  Eigen::Matrix2Xd profile(2, 3);
  profile << 10, 15, 20,  //
      2, 4, 6;
  const double p = 0.1, q = 0.004, a = -0.02, v = 5.0;
  for (const SpiralSurface& s :
       {SpiralSurface(UnitSpacedClamped(2, 3), profile, p, -4.0, 8.0),
        SpiralSurface(UnitSpacedClamped(2, 3), profile, p, -4.0, 8.0).WithAllometry(q, a)}) {
    // Eq. S1 about v_c, the middle of the angle range (2) for the allometric surface.
    const double qq = s.growth_change(), aa = s.axial_excess(), vc = s.allometric() ? 2.0 : 0.0;
    EXPECT_EQ(s.allometry_reference(), vc);
    auto radial = [&](double angle) { return std::exp(p * angle + 0.5 * qq * (angle - vc) * (angle - vc)); };
    const SpiralSurface::Whorl w = s.WhorlAt(v);
    EXPECT_NEAR(w.width, 10 * radial(v), 1e-9);
    EXPECT_NEAR(w.height, 4 * radial(v) * std::exp(aa * (v - vc)), 1e-9);
    EXPECT_NEAR(w.umbilical_width, 10 * (radial(v) + radial(v - M_PI)), 1e-9);
    EXPECT_NEAR(w.diameter, 20 * (radial(v) + radial(v - M_PI)), 1e-9);
    // The surface point itself carries the same scales.
    LocalGeometry g;
    s.Evaluate({1.0, v, 0.0}, 0, g);
    EXPECT_NEAR(g.point.head<2>().norm(), 15 * radial(v), 1e-9);
    EXPECT_NEAR(g.point.z(), 4 * radial(v) * std::exp(aa * (v - vc)), 1e-9);
  }
  // A generating curve reaching the axis leaves no umbilicus.
  profile(0, 0) = -5;
  EXPECT_EQ(SpiralSurface(UnitSpacedClamped(2, 3), profile, p, -4.0, 8.0).WhorlAt(v).umbilical_width, 0.0);
}

// ExtentsBetween (docs/shells.md eq. S5a): with the curve's own end points it is the plain extents over the
// range; with fixed end points, a change of the curve that slides its end along itself (the last control
// point moved along the end tangent, the direction of the last leg of the control polygon) moves the plain
// extents that sit at that end but not these, while an interior extreme follows the curve either way.
TEST(SpiralSurface, ExtentsBetweenHoldTheEndsWhereTheDataEnd) {
  Eigen::Matrix2Xd profile(2, 6);
  profile << 20, 25, 30, 31, 26, 19,  //
      -8, -6, -2, 2, 6, 8;
  const SpiralSurface shell(UnitSpacedClamped(4, 6), profile, 0.12, -M_PI, 3 * M_PI);
  const double lo = shell.basis().lo(), hi = shell.basis().hi();
  const Eigen::Vector2d end_lo = shell.CurvePoint(lo), end_hi = shell.CurvePoint(hi);
  const Eigen::Vector4d plain = shell.ExtentsBetween(lo, hi, end_lo, end_hi);
  EXPECT_EQ(shell.WhorlAt(2.0, plain).height, shell.WhorlAt(2.0).height);
  EXPECT_EQ(plain[2], -8.0);  // z_min and z_max at the clamped ends, r_min at the upper one
  EXPECT_EQ(plain[3], 8.0);
  EXPECT_EQ(plain[0], 19.0);
  // The end's tangent is the last leg of the control polygon: the curve slid along it by 1e-3 of the leg.
  Eigen::Matrix2Xd slid = profile;
  slid.col(5) += 1e-3 * (profile.col(5) - profile.col(4));
  const SpiralSurface moved = shell.WithGeneratrix(shell.basis(), slid);
  const Eigen::Vector4d moved_plain =
      moved.ExtentsBetween(lo, hi, moved.CurvePoint(lo), moved.CurvePoint(hi));
  const Eigen::Vector4d held = moved.ExtentsBetween(lo, hi, end_lo, end_hi);
  EXPECT_NEAR(moved_plain[3] - plain[3], 2e-3, 1e-12);  // the plain z_max moved with the slide
  EXPECT_NEAR(moved_plain[0] - plain[0], -7e-3, 1e-12);
  EXPECT_NEAR(held[3], plain[3], 1e-12);  // held where the data end
  EXPECT_NEAR(held[0], plain[0], 1e-12);
  EXPECT_NEAR(held[2], plain[2], 1e-12);        // the other end untouched
  EXPECT_NEAR(held[1], moved_plain[1], 1e-12);  // r_max inside the curve, as the curve has it
  // A range inside the curve: the samples between and the two given ends.
  const Eigen::Vector4d inner = shell.ExtentsBetween(0.5, 2.5, shell.CurvePoint(0.5), shell.CurvePoint(2.5));
  EXPECT_NEAR(inner[2], shell.CurvePoint(0.5).y(), 1e-12);
  EXPECT_NEAR(inner[3], shell.CurvePoint(2.5).y(), 1e-12);
  EXPECT_NEAR(shell.CurvePoint(1.0, 1).x(),
              (shell.CurvePoint(1.0 + 1e-6).x() - shell.CurvePoint(1.0 - 1e-6).x()) / 2e-6, 1e-6);
  EXPECT_THROW(shell.ExtentsBetween(2.0, 1.0, end_lo, end_hi), std::invalid_argument);
}

// The nested model at q = a = 0 is the logarithmic surface: same points and derivatives, two more
// parameters named after the growth.
TEST(SpiralSurface, AllometricAtZeroIsTheLogarithmicSpiral) {
  Eigen::Matrix2Xd profile(2, 5);
  profile << 1.0, 1.3, 1.5, 1.3, 1.0, -0.4, -0.2, 0.0, 0.2, 0.4;
  const SpiralSurface log_spiral(UnitSpacedClamped(4, 5), profile, 0.12, -2.0, 6.0);
  const SpiralSurface nested = log_spiral.WithAllometry();
  ASSERT_EQ(nested.num_parameters(), log_spiral.num_parameters() + 2);
  EXPECT_EQ(nested.parameter_name(log_spiral.num_parameters()), "growth_change");
  EXPECT_EQ(nested.parameter_name(log_spiral.num_parameters() + 1), "axial_excess");
  LocalGeometry a, b;
  for (const ParamT& t : {ParamT{0.3, -1.5, 0.0}, ParamT{1.7, 2.0, 0.0}, ParamT{1.1, 5.5, 0.0}}) {
    log_spiral.Evaluate(t, 2, a);
    nested.Evaluate(t, 2, b);
    EXPECT_LT((a.point - b.point).norm(), 1e-12);
    EXPECT_LT((a.d1 - b.d1).norm(), 1e-12);
    EXPECT_LT((a.d2 - b.d2).norm(), 1e-12);
  }
  Eigen::VectorXd params = nested.parameters();
  params.tail(2) << 0.01, 0.02;
  SpiralSurface moved = nested;
  moved.set_parameters(params);
  EXPECT_EQ(moved.growth_change(), 0.01);
  EXPECT_EQ(moved.axial_excess(), 0.02);
}

TEST(SpiralSurface, GrowingTubeFromRaupAgainstTheTrajectory) {
  // The closed forms (docs/archaeology.md eqs. A18-A20) against the curvature and torsion of the generating
  // circle's centre computed from its definition in our terms: the tube radius r = W^(theta / 2 pi), the
  // centre r_c = r (1 + D) / (1 - D) from the axis (inner edge over outer edge D) at the height T r_c,
  // turned by theta; derivatives by 5-point differences (step 2e-3: the first two to about 1e-9).
  for (const auto& [w, d, t] : {std::tuple{2.5, 0.3, 1.2}, std::tuple{10.0, -0.2, 0.4},
                                std::tuple{1.3, 0.6, -0.8}, std::tuple{3.0, 0.1, 0.0}}) {
    const SpiralSurface::GrowingTube g = SpiralSurface::GrowingTubeFromRaup({w, d, t});
    auto centre = [w = w, d = d, t = t](double theta) {  // bindings captured by copy (clang 14: not by [&])
      const double r_c = std::pow(w, theta / (2 * M_PI)) * (1 + d) / (1 - d);
      return Eigen::Vector3d(r_c * std::cos(theta), r_c * std::sin(theta), t * r_c);
    };
    const double theta = 0.7, h = 2e-3;
    const Eigen::Vector3d p2 = centre(theta + 2 * h), p1 = centre(theta + h), p0 = centre(theta),
                          m1 = centre(theta - h), m2 = centre(theta - 2 * h);
    const Eigen::Vector3d c1 = (-p2 + 8 * p1 - 8 * m1 + m2) / (12 * h);
    const Eigen::Vector3d c2 = (-p2 + 16 * p1 - 30 * p0 + 16 * m1 - m2) / (12 * h * h);
    const Eigen::Vector3d c3 = (p2 - 2 * p1 + 2 * m1 - m2) / (2 * h * h * h);
    const Eigen::Vector3d b = c1.cross(c2);
    const double r = std::pow(w, theta / (2 * M_PI));
    const double kappa = b.norm() / std::pow(c1.norm(), 3), tau = b.dot(c3) / b.squaredNorm();
    const double dr_ds = std::log(w) / (2 * M_PI) * r / c1.norm();
    EXPECT_NEAR(g.expansion, dr_ds, 1e-6 * std::abs(dr_ds)) << w << " " << d << " " << t;
    EXPECT_NEAR(g.curvature, kappa * r, 1e-6 * kappa * r) << w << " " << d << " " << t;
    // The third derivative's stencil errs by about h^2 f^(5) / 4: 1e-6 relative here.
    EXPECT_NEAR(g.torsion, tau * r, 1e-5 * std::abs(tau * r) + 1e-12) << w << " " << d << " " << t;
  }
  // Outside the model's range: no parameters.
  EXPECT_TRUE(std::isnan(SpiralSurface::GrowingTubeFromRaup({1.0, 0.3, 1.0}).expansion));
  EXPECT_TRUE(std::isnan(SpiralSurface::GrowingTubeFromRaup({2.0, 1.0, 1.0}).curvature));
}

}  // namespace
}  // namespace s2m
