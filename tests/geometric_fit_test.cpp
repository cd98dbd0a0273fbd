// The fitting engine (docs/method.md sections 1-4, 9-10): models, foot points, the six error terms and step
// control.

#include "fitting/geometric_fit.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <functional>
#include <memory>
#include <random>

#include "acquisition/glyph_outline.h"
#include "acquisition/nist_reference.h"
#include "acquisition/point_cloud_io.h"
#include "fitting/bspline_models.h"
#include "fitting/initial_models.h"
#include "fitting/kinematic_surfaces.h"
#include "fitting/part_model.h"
#include "fitting/primitive_compare.h"
#include "fitting/primitive_models.h"
#include "test_models.h"
#include "test_paths.h"

namespace s2m {
namespace {

// ---- B-spline basis
// -------------------------------------------------------------------------------------------

TEST(BSplineBasis, PartitionOfUnityAndDerivatives) {
  for (const BSplineBasis& b :
       {BSplineBasis::Clamped(4, {0, 0, 0, 0, 0.3, 0.35, 1.2, 2, 2, 2, 2}),
        BSplineBasis::Periodic(3, {0, 0.5, 0.7, 1.5, 2.0, 3.0}), UnitSpacedPeriodic(5, 9)}) {
    BSplineBasis::Values v, vp, vm;
    for (double t = b.lo() + 0.005; t < b.hi(); t += 0.0173) {  // inside, so that t +- h stays in the domain
      b.Evaluate(t, 2, v);
      double sum = 0, dsum = 0;
      for (int i = 0; i < b.order(); ++i) sum += v.values[0][static_cast<std::size_t>(i)];
      for (int i = 0; i < b.order(); ++i) dsum += v.values[1][static_cast<std::size_t>(i)];
      EXPECT_NEAR(sum, 1.0, 1e-14);
      EXPECT_NEAR(dsum, 0.0, 1e-11);
      const double h = 1e-6;
      b.Evaluate(t + h, 1, vp);
      b.Evaluate(t - h, 1, vm);
      if (vp.first != v.first || vm.first != v.first) continue;  // a knot lies within h
      for (int i = 0; i < b.order(); ++i) {
        const auto k = static_cast<std::size_t>(i);
        EXPECT_NEAR(v.values[1][k], (vp.values[0][k] - vm.values[0][k]) / (2 * h), 1e-6);
        EXPECT_NEAR(v.values[2][k], (vp.values[1][k] - vm.values[1][k]) / (2 * h), 1e-4);
      }
    }
  }
}

TEST(BSplineBasis, KnotVectorsAreValidated) {
  EXPECT_THROW(BSplineBasis::Clamped(4, {0, 0, 0, 0, 1, 0.5, 1, 1, 1, 1}),
               std::invalid_argument);  // decreasing
  EXPECT_THROW(BSplineBasis::Clamped(4, {0, 0, 0, 1, 1, 1, 1}),
               std::invalid_argument);  // ends not repeated 4 times
  EXPECT_THROW(BSplineBasis::Clamped(3, {0, 0, 0, 0.5, 0.5, 0.5, 1, 1, 1}),
               std::invalid_argument);  // multiplicity 3
  EXPECT_THROW(BSplineBasis::ClampedUniform(4, 3),
               std::invalid_argument);  // fewer control points than the order
  EXPECT_THROW(BSplineBasis::Periodic(3, {0, 1, 1, 2}), std::invalid_argument);  // not strictly increasing
  EXPECT_THROW(BSplineBasis::ClampedUniform(1, 5), std::invalid_argument);
  try {
    BSplineBasis::Clamped(4, {0, 0, 0, 0, 1, 0.5, 1, 1, 1, 1});
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("non-decreasing"), std::string::npos);
  }
}

TEST(BSplineBasis, GramMatricesIntegrateExactly) {
  // integral of B_i'' B_j'' by a fine composite Simpson rule agrees with the per-span Gauss-Legendre result.
  const BSplineBasis b = BSplineBasis::Clamped(4, {0, 0, 0, 0, 0.4, 1.0, 1.1, 2, 2, 2, 2});
  const std::vector<double> gram = b.GramMatrix(2);
  const int n = b.num_control();
  Eigen::MatrixXd numeric = Eigen::MatrixXd::Zero(n, n);
  const std::vector<double> breaks = b.Breakpoints();
  BSplineBasis::Values v;
  for (std::size_t s = 0; s + 1 < breaks.size(); ++s) {
    const int m = 200;
    const double a = breaks[s], h = (breaks[s + 1] - a) / m;
    for (int k = 0; k <= m; ++k) {
      const double w = (k == 0 || k == m) ? 1.0 : (k % 2 ? 4.0 : 2.0);
      b.Evaluate(std::min(a + k * h, breaks[s + 1] - 1e-12), 2, v);
      for (int i = 0; i < b.order(); ++i)
        for (int j = 0; j < b.order(); ++j)
          numeric(v.first + i, v.first + j) +=
              w * h / 3 * v.values[2][static_cast<std::size_t>(i)] * v.values[2][static_cast<std::size_t>(j)];
    }
  }
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) EXPECT_NEAR(gram[static_cast<std::size_t>(i * n + j)], numeric(i, j), 1e-7);
}

// ---- Property tests shared by every model of the family
// -------------------------------------------------------

using ModelFactory = std::function<std::unique_ptr<ParametricModel>()>;

// A one-face part of each face type in a tilted frame, its quantities linear expressions with several terms
// (face 0 is what the family tests evaluate; the foot-point test sees both faces).
std::unique_ptr<ParametricModel> PartWithFace(FaceType type) {
  PartDefinition d;
  d.parameters = {{"a", 2.0, false}, {"b", 0.5, false}, {"angle", 0.35, true}};
  PartFace f = test::TiltedTestFace(type, 0, 0.0);
  f.name = "face";
  PartFace other = f;
  other.patch.reset();
  other.name = "other";
  other.type = FaceType::kPlane;
  other.frame = Eigen::Matrix3d::Identity();
  other.offset = {-6.0, {{0, 1.0}}};
  d.faces = {f, other};
  return std::make_unique<PartModel>(d);
}

struct NamedFactory {
  std::string name;
  ModelFactory make;
};
void PrintTo(const NamedFactory& f, std::ostream* os) {
  *os << f.name;
}

std::vector<NamedFactory> Models() {
  return {
      {"open_curve_2d",
       [] {
         Eigen::MatrixXd p(2, 6);
         p << 0, 1, 2, 3, 4, 5, 0, 1.5, -0.5, 1, 0.2, 0.8;
         return std::make_unique<BSplineCurve>(UnitSpacedClamped(4, 6), p);
       }},
      {"closed_curve_2d",
       [] {
         Eigen::MatrixXd p(2, 7);
         for (int i = 0; i < 7; ++i) p.col(i) << (1 + 0.3 * (i % 2)) * std::cos(i * 0.9), std::sin(i * 0.9);
         return std::make_unique<BSplineCurve>(UnitSpacedPeriodic(4, 7), p);
       }},
      {"curve_3d",
       [] {
         Eigen::MatrixXd p(3, 5);
         p << 0, 1, 2, 3, 4, 0, 1, 0, -1, 0, 0, 0.5, 1, 0.5, 0;
         return std::make_unique<BSplineCurve>(UnitSpacedClamped(3, 5), p);
       }},
      {"surface",
       [] {
         Eigen::Matrix3Xd p(3, 25);
         for (int i = 0; i < 5; ++i)
           for (int j = 0; j < 5; ++j) p.col(i * 5 + j) << i, j, 0.3 * std::sin(i + 2.0 * j);
         return std::make_unique<BSplineSurface>(UnitSpacedClamped(4, 5), UnitSpacedClamped(3, 5), p);
       }},
      {"periodic_surface",
       [] {
         Eigen::Matrix3Xd p(3, 24);
         for (int i = 0; i < 6; ++i)
           for (int j = 0; j < 4; ++j)
             p.col(i * 4 + j) << (2 + 0.2 * j) * std::cos(i), (2 + 0.1 * i) * std::sin(i), j;
         return std::make_unique<BSplineSurface>(UnitSpacedPeriodic(4, 6), UnitSpacedClamped(4, 4), p);
       }},
      {"ellipse_3d",
       [] {
         return std::make_unique<Ellipse3D>(
             Eigen::Vector3d(1, 2, 3),
             Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix(), 2.0, 0.7);
       }},
      {"cylinder_model",
       [] {
         return std::make_unique<CylinderModel>(
             Cylinder{{1, 2, 3}, Eigen::Vector3d(1, -1, 2).normalized(), 1.5});
       }},
      {"sphere_model",
       [] {
         return std::make_unique<SphereModel>(
             Sphere{{1, -2, 0.5}, 2.0}, Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 0, 0)).toRotationMatrix());
       }},
      {"revolution",
       [] {
         Eigen::Matrix2Xd profile(2, 6);
         profile << 1.0, 1.4, 1.8, 1.5, 1.2, 1.6, 0.0, 0.5, 1.2, 2.0, 2.6, 3.2;
         return std::make_unique<KinematicSurface>(
             KinematicSurface::Revolution(UnitSpacedClamped(4, 6), profile));
       }},
      {"helical",
       [] {
         Eigen::Matrix2Xd profile(2, 5);
         profile << 0.5, 0.8, 1.0, 0.9, 0.6, -0.2, -0.1, 0.0, 0.1, 0.2;
         return std::make_unique<KinematicSurface>(
             KinematicSurface::Helical(UnitSpacedClamped(3, 5), profile, 0.15, 2.0));
       }},
      {"spiral",
       [] {
         Eigen::Matrix2Xd profile(2, 5);
         profile << 1.0, 1.3, 1.5, 1.3, 1.0, -0.4, -0.2, 0.0, 0.2, 0.4;
         return std::make_unique<SpiralSurface>(UnitSpacedClamped(4, 5), profile, 0.12, -2.0, 6.0);
       }},
      {"part_plane", [] { return PartWithFace(FaceType::kPlane); }},
      {"part_cylinder", [] { return PartWithFace(FaceType::kCylinder); }},
      {"part_cone", [] { return PartWithFace(FaceType::kCone); }},
      {"part_sphere", [] { return PartWithFace(FaceType::kSphere); }},
      {"part_torus", [] { return PartWithFace(FaceType::kTorus); }},
      {"part_spline_patch", [] { return PartWithFace(FaceType::kSplinePatch); }},
      {"circle_3d",
       [] {
         return std::make_unique<Ellipse3D>(Eigen::Vector3d(0, 0, 1), Eigen::Matrix3d::Identity(), 1.5, 1.5,
                                            true);
       }},
  };
}

class ModelFamily : public ::testing::TestWithParam<NamedFactory> {
 protected:
  std::vector<ParamT> TestParameters(const ParametricModel& m) {
    const ParameterDomain d = m.domain();
    std::vector<ParamT> ts;
    // Within a band of width at most 4 around the domain's middle (the cylinder's axial range is unbounded).
    auto at = [&](int k, double fraction) {
      const auto i = static_cast<std::size_t>(k);
      const double span = std::min(d.hi[i] - d.lo[i], 4.0);
      return 0.5 * (d.lo[i] + d.hi[i]) + (fraction - 0.5) * span;
    };
    for (double a : {0.13, 0.41, 0.77})
      for (double b : {0.21, 0.66}) ts.push_back({at(0, a), at(1, b)});
    return ts;
  }
};

TEST_P(ModelFamily, ShapeJacobianMatchesCentralDifferences) {
  auto model = GetParam().make();
  const Eigen::VectorXd p0 = model->parameters();
  std::vector<JacobianEntry> entries;
  LocalGeometry gp, gm;
  for (const ParamT& t : TestParameters(*model)) {
    model->ShapeJacobian(t, true, entries);
    Eigen::MatrixXd analytic = Eigen::MatrixXd::Zero(model->ambient_dimension(), model->num_parameters());
    Eigen::MatrixXd analytic_dt = analytic;
    for (const JacobianEntry& e : entries) {
      analytic.col(e.index) += e.column.head(model->ambient_dimension());
      analytic_dt.col(e.index) += e.dcolumn_dt[0].head(model->ambient_dimension());
    }
    const double h = 1e-6;
    for (int k = 0; k < model->num_parameters(); ++k) {
      Eigen::VectorXd step = Eigen::VectorXd::Zero(model->num_parameters());
      step[k] = h;
      auto plus = model->Clone(), minus = model->Clone();
      plus->ApplyStep(step);
      minus->ApplyStep(-step);
      plus->Evaluate(t, 1, gp);
      minus->Evaluate(t, 1, gm);
      EXPECT_LT((Eigen::VectorXd((gp.point - gm.point) / (2 * h)) - analytic.col(k)).norm(), 1e-7)
          << GetParam().name << " " << model->parameter_name(k);
      EXPECT_LT((Eigen::VectorXd((gp.d1.col(0) - gm.d1.col(0)) / (2 * h)) - analytic_dt.col(k)).norm(), 1e-6)
          << GetParam().name << " d/dt of " << model->parameter_name(k);
    }
  }
}

TEST_P(ModelFamily, ParameterDerivativesMatchCentralDifferences) {
  auto model = GetParam().make();
  const int m = model->domain().dimension;
  LocalGeometry g, gp, gm;
  for (const ParamT& t : TestParameters(*model)) {
    model->Evaluate(t, 2, g);
    const double h = 1e-5;
    for (int k = 0; k < m; ++k) {
      ParamT tp = t, tm = t;
      tp[static_cast<std::size_t>(k)] += h;
      tm[static_cast<std::size_t>(k)] -= h;
      model->Evaluate(tp, 1, gp);
      model->Evaluate(tm, 1, gm);
      EXPECT_LT((Eigen::VectorXd((gp.point - gm.point) / (2 * h)) - Eigen::VectorXd(g.d1.col(k))).norm(),
                1e-8);
      // Second derivatives: d/dt_k of C_t0 gives C_uu (k = 0) or C_uv (k = 1); d/dt_1 of C_t1 gives C_vv.
      const Eigen::VectorXd numeric = (gp.d1.col(0) - gm.d1.col(0)) / (2 * h);
      EXPECT_LT((numeric - Eigen::VectorXd(g.d2.col(k))).norm(), 1e-6) << GetParam().name;
      if (m == 2 && k == 1) {
        EXPECT_LT(
            (Eigen::VectorXd((gp.d1.col(1) - gm.d1.col(1)) / (2 * h)) - Eigen::VectorXd(g.d2.col(2))).norm(),
            1e-6);
      }
    }
  }
}

TEST_P(ModelFamily, PrincipalCurvaturesMatchNumericNormalCurvatures) {
  // kappa_k equals the normal curvature n . C'' / |C'|^2 along the principal direction, measured by finite
  // differences of the model itself; tangents are unit and orthogonal, the normal space completes them.
  auto model = GetParam().make();
  LocalGeometry g, gp, gm;
  for (const ParamT& t : TestParameters(*model)) {
    model->Evaluate(t, 2, g);
    VecS x = g.point;
    const PrincipalFrame f = ComputePrincipalFrame(g, x);
    const int m = model->domain().dimension;
    for (int k = 0; k < f.tangent_count; ++k) {
      const Eigen::Vector3d tk = f.tangents[static_cast<std::size_t>(k)];
      EXPECT_NEAR(tk.norm(), 1.0, 1e-12);
      EXPECT_NEAR(tk.dot(f.normals[0]), 0.0, 1e-12);
      // Parameter direction v with C_t v parallel to T_k.
      Eigen::Vector2d v = Eigen::Vector2d::Zero();
      if (m == 1) {
        v[0] = 1.0;
      } else {
        Eigen::Matrix<double, 3, 2> ct = Eigen::Matrix<double, 3, 2>::Zero();
        ct.topRows(g.d1.rows()) = g.d1;
        v = ct.colPivHouseholderQr().solve(tk);
      }
      const double h = 1e-4;
      model->Evaluate({t[0] + h * v[0], t[1] + h * v[1]}, 0, gp);
      model->Evaluate({t[0] - h * v[0], t[1] - h * v[1]}, 0, gm);
      Eigen::Vector3d second = Eigen::Vector3d::Zero(), first = Eigen::Vector3d::Zero();
      second.head(g.point.size()) = (gp.point - 2 * g.point + gm.point) / (h * h);
      first.head(g.point.size()) = (gp.point - gm.point) / (2 * h);
      const double numeric = f.normals[0].dot(second) / first.squaredNorm();
      EXPECT_NEAR(f.curvatures[static_cast<std::size_t>(k)], numeric, 1e-5 * (1 + std::abs(numeric)))
          << GetParam().name;
    }
    if (f.tangent_count == 2) {
      EXPECT_NEAR(f.tangents[0].dot(f.tangents[1]), 0.0, 1e-10);
    }
  }
}

TEST_P(ModelFamily, FootPointsAreOrthogonalOrOnABoundary) {
  auto model = GetParam().make();
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 0.1);
  const int s = model->ambient_dimension();
  Eigen::MatrixXd points(s, 60);
  LocalGeometry g;
  const std::vector<ParamT> ts = model->SampleParameters();
  for (int j = 0; j < 60; ++j) {
    model->Evaluate(ts[static_cast<std::size_t>(j * 7) % ts.size()], 0, g);
    points.col(j) = g.point;
    for (int c = 0; c < s; ++c) points(c, j) += noise(rng);
  }
  std::vector<FootPoint> feet;
  ComputeFootPoints(*model, points, feet);
  for (int j = 0; j < 60; ++j) {
    const FootPoint& f = feet[static_cast<std::size_t>(j)];
    model->Evaluate(f.t, 1, g);
    const VecS r = g.point - VecS(points.col(j));
    EXPECT_NEAR(r.norm(), f.distance, 1e-12);
    if (!f.on_boundary) {
      for (int k = 0; k < g.d1.cols(); ++k)
        EXPECT_LT(std::abs(g.d1.col(k).dot(r)), 1e-10 * (1 + g.d1.col(k).norm() * r.norm()));
    }
    // No sample of the model is closer than the foot point (a global, not just a local, minimum).
    for (const ParamT& t : ts) {
      model->Evaluate(t, 0, g);
      EXPECT_GE((g.point - VecS(points.col(j))).norm(), f.distance - 1e-9);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Models, ModelFamily, ::testing::ValuesIn(Models()),
                         [](const auto& param_info) { return param_info.param.name; });

// ---- Convergence of the error terms
// -----------------------------------------------------------------------------

// A zero-residual problem: points on a known closed curve, start from perturbed control points.
struct ZeroResidualCase {
  Eigen::MatrixXd points;
  Eigen::MatrixXd start;
};
ZeroResidualCase MakeZeroResidualCase() {
  Eigen::MatrixXd p(2, 8);
  for (int i = 0; i < 8; ++i)
    p.col(i) << std::cos(i * M_PI / 4) * (1 + 0.2 * std::sin(3 * i * M_PI / 4)), std::sin(i * M_PI / 4);
  const BSplineCurve truth(UnitSpacedPeriodic(4, 8), p);
  ZeroResidualCase c;
  c.points.resize(2, 100);
  LocalGeometry g;
  for (int i = 0; i < 100; ++i) {
    truth.Evaluate({8.0 * (i + 0.3) / 100, 0.0}, 0, g);
    c.points.col(i) = g.point;
  }
  std::mt19937_64 rng(1);
  std::normal_distribution<double> noise(0.0, 0.05);
  c.start = p;
  for (Eigen::Index i = 0; i < c.start.size(); ++i) c.start.data()[i] += noise(rng);
  return c;
}

std::vector<double> RmsHistory(ErrorTerm term, const ZeroResidualCase& c, int iterations) {
  BSplineCurve curve(UnitSpacedPeriodic(4, 8), c.start);
  GeometricFitOptions o;
  o.error_term = term;
  o.optimizer.max_iterations = iterations;
  std::vector<double> rms;
  for (const IterationRecord& r : FitModel(curve, c.points, o).history) rms.push_back(r.rms);
  return rms;
}

// The largest convergence-order estimate log(e_{k+1}/e_k) / log(e_k/e_{k-1}) over iterates in [1e-13, 1e-2].
double BestOrder(const std::vector<double>& e) {
  double best = 0.0;
  for (std::size_t k = 1; k + 1 < e.size(); ++k) {
    if (e[k + 1] < 1e-13 || e[k - 1] > 1e-2 || !(e[k] < e[k - 1]) || !(e[k + 1] < e[k])) continue;
    best = std::max(best, std::log(e[k + 1] / e[k]) / std::log(e[k] / e[k - 1]));
  }
  return best;
}

TEST(ErrorTerms, TdmSdmCdmAndGnConvergeQuadraticallyOnAZeroResidualProblem) {
  const ZeroResidualCase c = MakeZeroResidualCase();
  for (ErrorTerm term : {ErrorTerm::kTdm, ErrorTerm::kSdm, ErrorTerm::kCdm, ErrorTerm::kGn}) {
    const std::vector<double> e = RmsHistory(term, c, 30);
    ASSERT_FALSE(e.empty());
    EXPECT_LT(e.back(), 1e-12) << ToString(term);
    EXPECT_GE(BestOrder(e), 1.8) << ToString(term) << ": not quadratic";
  }
}

TEST(ErrorTerms, PdmConvergesLinearlyOnAZeroResidualProblem) {
  const std::vector<double> e = RmsHistory(ErrorTerm::kPdm, MakeZeroResidualCase(), 40);
  ASSERT_GE(e.size(), 40u);
  // A linear rate: the error shrinks by a roughly constant factor, far from the squaring of a quadratic
  // method.
  for (std::size_t k = 20; k + 1 < e.size(); ++k) {
    const double ratio = e[k + 1] / e[k];
    EXPECT_GT(ratio, 0.5) << "iteration " << k;
    EXPECT_LT(ratio, 1.0) << "iteration " << k;
  }
  EXPECT_GT(e.back(), 1e-6);
}

// Sparse, non-uniform points on the unit circle; closed cubic B-spline with 8 control points started
// off-centre.
Eigen::MatrixXd SparseCirclePoints() {
  Eigen::MatrixXd x(2, 40);
  for (int i = 0; i < 40; ++i) {
    const double a = 2 * M_PI * std::pow((i + 0.5) / 40, 1.5);
    x.col(i) << std::cos(a), std::sin(a);
  }
  return x;
}
Eigen::MatrixXd CircleStart() {
  Eigen::MatrixXd p(2, 8);
  for (int i = 0; i < 8; ++i) p.col(i) << 0.2 + 0.6 * std::cos(i * M_PI / 4), 0.6 * std::sin(i * M_PI / 4);
  return p;
}

int IterationsToRms(ErrorTerm term, double target) {
  BSplineCurve curve(UnitSpacedPeriodic(4, 8), CircleStart());
  GeometricFitOptions o;
  o.error_term = term;
  o.optimizer.target_rms = target;
  o.optimizer.max_iterations = 1000;
  const GeometricFitResult r = FitModel(curve, SparseCirclePoints(), o);
  return r.stop_reason == StopReason::kTargetReached ? r.iterations : 1000000;
}

TEST(ErrorTerms, PdmNeedsAtLeastFiveTimesTheIterationsOfSdmOnASparseCircle) {
  // Common target: 1.3x the RMS the best fit reaches (about 3.9e-4 for this spline).
  const double target = 5e-4;
  const int sdm = IterationsToRms(ErrorTerm::kSdm, target);
  const int pdm = IterationsToRms(ErrorTerm::kPdm, target);
  ASSERT_LT(sdm, 1000) << "SDM never reached the target";
  EXPECT_GE(pdm, 5 * sdm) << "PDM " << pdm << " vs SDM " << sdm;
}

// Points on the boundary of the square [-1, 1]^2 and a small circle inside, off-centre: every point on one
// side.
Eigen::MatrixXd SquarePoints() {
  Eigen::MatrixXd x(2, 100);
  int k = 0;
  for (int i = 0; i < 25; ++i) {
    const double s = -1 + 2.0 * i / 25;
    x.col(k++) << s, -1;
    x.col(k++) << 1, s;
    x.col(k++) << -s, 1;
    x.col(k++) << -1, -s;
  }
  return x;
}

double SquareFit(ErrorTerm term, StepStrategy control) {
  Eigen::MatrixXd p(2, 12);
  for (int i = 0; i < 12; ++i)
    p.col(i) << 0.4 + 0.3 * std::cos(i * M_PI / 6), 0.3 + 0.3 * std::sin(i * M_PI / 6);
  BSplineCurve curve(UnitSpacedPeriodic(4, 12), p);
  GeometricFitOptions o;
  o.error_term = term;
  o.optimizer.step_strategy = control;
  o.fairness.bending = 0.001;  // the paper's default in the unit box
  o.optimizer.max_iterations = 200;
  try {
    return FitModel(curve, SquarePoints(), o).residuals.rms;
  } catch (const std::exception&) {  // divergence to non-finite values or a singular system: no fit
    return std::numeric_limits<double>::infinity();
  }
}

TEST(ErrorTerms, OnASquareSdmFitsWhileTdmNeedsStepStrategy) {
  const double sdm = SquareFit(ErrorTerm::kSdm, StepStrategy::kFullStep);
  const double tdm = SquareFit(ErrorTerm::kTdm, StepStrategy::kFullStep);
  const double tdm_armijo = SquareFit(ErrorTerm::kTdm, StepStrategy::kArmijo);
  EXPECT_LT(sdm, 0.005) << "SDM without step control";
  EXPECT_LT(SquareFit(ErrorTerm::kSdm, StepStrategy::kTrustRegion), 0.005);
  EXPECT_GT(tdm, 10 * sdm) << "plain TDM was expected to fail from this start";
  EXPECT_LT(tdm_armijo, 0.005) << "TDM with Armijo backtracking";
}

Eigen::MatrixXd EllipsePoints() {
  Eigen::MatrixXd x(3, 200);
  for (int i = 0; i < 200; ++i)
    x.col(i) << std::cos(2 * M_PI * i / 200), 2 * std::sin(2 * M_PI * i / 200), 0.0;
  return x;
}

TEST(ErrorTerms, GtdmFitsA3DEllipseFromAFarStart) {
  for (const Eigen::Matrix3d& tilt :
       {Eigen::Matrix3d(Eigen::Matrix3d::Identity()),
        Eigen::Matrix3d(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 1, 0).normalized()))}) {
    Ellipse3D e({0.5, -0.4, 0.3}, tilt, 2.5, 0.6);
    GeometricFitOptions o;
    o.error_term = ErrorTerm::kGtdm;
    const GeometricFitResult r = FitModel(e, EllipsePoints(), o);
    EXPECT_LT(r.residuals.rms, 1e-10);
    EXPECT_NEAR(std::max(e.a(), e.b()), 2.0, 1e-9);
    EXPECT_NEAR(std::min(e.a(), e.b()), 1.0, 1e-9);
    EXPECT_NEAR(std::abs(e.normal().z()), 1.0, 1e-9);
  }
}

TEST(ErrorTerms, PlainTdmOnA3DCurveIsReportedSingular) {
  for (StepStrategy control : {StepStrategy::kFullStep, StepStrategy::kTrustRegion}) {
    Ellipse3D e({0.5, -0.4, 0.0}, Eigen::Matrix3d::Identity(), 2.5, 0.6);
    GeometricFitOptions o;
    o.error_term = ErrorTerm::kTdm;
    o.optimizer.step_strategy = control;
    try {
      FitModel(e, EllipsePoints(), o);
      ADD_FAILURE() << "no error for plain TDM with " << ToString(control);
    } catch (const SingularSystemError& err) {
      const std::string what = err.what();
      EXPECT_NE(what.find("singular"), std::string::npos) << what;
      EXPECT_NE(what.find("centre z"), std::string::npos) << what;
      EXPECT_NE(what.find("use gtdm or sdm"), std::string::npos) << what;
    }
  }
}

// ---- Open curves, fairness, surfaces, real contours
// ------------------------------------------------------------------

TEST(GeometricFit, OpenCurveEndsFollowTheDataWithTheEndRule) {
  // Points on a half circle; the initial open curve covers only the middle of a smaller arc. The end rule
  // (docs/method.md section 4) pulls the ends out to the data's ends; without it the ends lag behind.
  Eigen::MatrixXd x(2, 60);
  for (int i = 0; i < 60; ++i) x.col(i) << std::cos(M_PI * i / 59), std::sin(M_PI * i / 59);
  Eigen::MatrixXd p(2, 6);
  for (int i = 0; i < 6; ++i)
    p.col(i) << 0.5 * std::cos(M_PI * (0.3 + 0.08 * i)), 0.5 * std::sin(M_PI * (0.3 + 0.08 * i));
  double rms[2];
  for (int rule = 0; rule < 2; ++rule) {
    BSplineCurve curve(UnitSpacedClamped(4, 6), p);
    GeometricFitOptions o;
    o.open_end_rule = rule == 1;
    rms[rule] = FitModel(curve, x, o).residuals.rms;
    if (rule == 1) {
      LocalGeometry g;
      for (double t : {curve.basis().lo(), curve.basis().hi()}) {
        curve.Evaluate({t, 0}, 0, g);
        EXPECT_LT(
            std::min((g.point - Eigen::Vector2d(1, 0)).norm(), (g.point - Eigen::Vector2d(-1, 0)).norm()),
            0.03);
      }
    }
  }
  EXPECT_LT(rms[1], 3e-3);
  EXPECT_GT(rms[0], 5 * rms[1]);
}

TEST(GeometricFit, ResultsAreReportedInInputUnitsWhateverTheScale) {
  // The same problem in metres and in micrometres gives the same shape: normalization makes weights
  // unit-free.
  const Eigen::MatrixXd x = SparseCirclePoints();
  double rms[2];
  for (int k = 0; k < 2; ++k) {
    const double scale = k == 0 ? 1.0 : 1e6;
    BSplineCurve curve(UnitSpacedPeriodic(4, 8),
                       (CircleStart() * scale).colwise() + Eigen::Vector2d(3e6, -2e6));
    GeometricFitOptions o;
    o.fairness.bending = 1e-3;
    o.optimizer.max_iterations = 30;
    rms[k] = FitModel(curve, (x * scale).colwise() + Eigen::Vector2d(3e6, -2e6), o).residuals.rms / scale;
  }
  EXPECT_NEAR(rms[0], rms[1], 1e-6 * rms[0]);
}

TEST(GeometricFit, SurfaceFromAPlaneProjectionFitsAWavySheet) {
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::Matrix3Xd x(3, 1500);
  for (int j = 0; j < 1500; ++j) {
    const double a = u(rng), b = u(rng);
    x.col(j) << a, b, 0.25 * std::sin(2 * a) * std::cos(1.5 * b);
  }
  BSplineSurface surface = InitialSurfaceByProjection(x, 7, 7, 4, SurfaceProjection::kPlane);
  GeometricFitOptions o;
  o.optimizer.max_iterations = 15;
  const GeometricFitResult r = FitModel(surface, x, o);
  EXPECT_LT(r.residuals.rms, 1e-3);
  EXPECT_LT(r.residuals.rms, r.history.front().rms);
}

TEST(GeometricFit, SurfaceFromACylinderProjectionFitsABulgedTube) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Eigen::Matrix3Xd x(3, 2000);
  for (int j = 0; j < 2000; ++j) {
    const double a = 2 * M_PI * u(rng), z = 4 * u(rng);
    const double r = 1.0 + 0.1 * std::sin(z);
    x.col(j) << r * std::cos(a), r * std::sin(a), z;
  }
  BSplineSurface surface = InitialSurfaceByProjection(x, 8, 6, 4, SurfaceProjection::kCylinder);
  EXPECT_TRUE(surface.basis_u().periodic());
  GeometricFitOptions o;
  o.optimizer.max_iterations = 15;
  EXPECT_LT(FitModel(surface, x, o).residuals.rms, 2e-3);
}

TEST(GeometricFit, GlyphOutlinesFitByClosedCubicSplines) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  // Stated accuracy: RMS below 2.5e-4 of each contour's bounding-box diagonal, with one control point per 8
  // samples (20 samples per Bezier segment, so 2.5 control points per segment).
  for (const char* glyph : {"S_", "g"}) {
    for (const Eigen::Matrix2Xd& contour :
         ReadGlifContours(test::SharedData(std::string("font_glyphs/") + glyph + ".glif"))) {
      BSplineCurve curve =
          InitialCurveFromQuadtree(contour, std::max(8, static_cast<int>(contour.cols() / 8)), 4, true);
      GeometricFitOptions o;
      o.fairness.bending = 1e-4;
      o.optimizer.max_iterations = 100;
      const GeometricFitResult r = FitModel(curve, contour, o);
      const double diagonal = (contour.rowwise().maxCoeff() - contour.rowwise().minCoeff()).norm();
      EXPECT_LT(r.residuals.rms, 2.5e-4 * diagonal)
          << glyph << " contour with " << contour.cols() << " samples";
    }
  }
}

TEST(GeometricFit, PrimitivesPlugIntoTheEngineAndReachTheNistReference) {
  // The engine with closed-form foot points reproduces the certified fits from a perturbed start, for every
  // error term that sees the normal direction.
  const Scan cyl = ReadPointCloud(test::TestData("nist/cyl1.ds"));
  const Cylinder cyl_ref = ReadNistCylinderFit(test::TestData("nist/cyl1.fit"));
  const Scan sph = ReadPointCloud(test::TestData("nist/sph1.ds"));
  const Sphere sph_ref = ReadNistSphereFit(test::TestData("nist/sph1.fit"));
  const double cyl_extent = ComputeBounds(cyl.points).diagonal(),
               sph_extent = ComputeBounds(sph.points).diagonal();
  for (ErrorTerm term : {ErrorTerm::kTdm, ErrorTerm::kSdm, ErrorTerm::kGn}) {
    GeometricFitOptions o;
    o.error_term = term;
    o.optimizer.max_iterations = 200;
    o.optimizer.objective_tolerance = 0.0;  // certified accuracy: stop on the step or gradient only
    Cylinder start = cyl_ref;
    start.axis_point += Eigen::Vector3d(0.5, -0.3, 0.2);
    start.axis_direction = (start.axis_direction + Eigen::Vector3d(0.02, 0.03, -0.01)).normalized();
    start.radius *= 1.02;
    CylinderModel cylinder(start);
    FitModel(cylinder, cyl.points, o);
    const PrimitiveDeviation dc = Compare(cylinder.shape(), cyl_ref);
    EXPECT_LT(dc.position / cyl_extent, 1e-8) << ToString(term);
    EXPECT_LT(dc.direction, 1e-8) << ToString(term);
    EXPECT_LT(dc.size / cyl_extent, 1e-8) << ToString(term);
    // Poles of the sphere's parametrization away from the data (NIST sph1 is a cap around -z of its centre).
    SphereModel sphere({sph_ref.center + Eigen::Vector3d(0.3, 0.2, -0.4), sph_ref.radius * 0.97},
                       Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()).toRotationMatrix());
    FitModel(sphere, sph.points, o);
    const PrimitiveDeviation ds = Compare(sphere.shape(), sph_ref);
    EXPECT_LT(ds.position / sph_extent, 1e-8) << ToString(term);
    EXPECT_LT(ds.size / sph_extent, 1e-8) << ToString(term);
  }
}

TEST(GeometricFit, BadInputIsRejectedClearly) {
  BSplineCurve curve(UnitSpacedPeriodic(4, 8), CircleStart());
  EXPECT_THROW(FitModel(curve, Eigen::MatrixXd(3, 10)), std::invalid_argument);  // wrong dimension
  EXPECT_THROW(FitModel(curve, Eigen::MatrixXd(2, 0)), std::invalid_argument);
  Eigen::MatrixXd x = SparseCirclePoints();
  x(0, 3) = std::nan("");
  EXPECT_THROW(FitModel(curve, x), std::invalid_argument);
  EXPECT_THROW(InitialCurveFromQuadtree(Eigen::Matrix2Xd::Zero(2, 2), 8, 4, true), std::invalid_argument);
  EXPECT_THROW(ErrorTermFromString("xdm"), std::invalid_argument);
}

}  // namespace
}  // namespace s2m
