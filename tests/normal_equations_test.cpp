// The normal equations against finite differences of the objectives they linearize. The joint solver's
// assembly (fitting/joint_fit.cpp) is internal, so this checks its public building blocks: the rigid step's
// 6 x 6 system (registration/rigid_step.h; docs/method.md section 5) and the geometric fit's error matrices
// (fitting/geometric_fit.h; docs/method.md section 2) on models at exact foot points.

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <functional>
#include <random>

#include "fitting/bspline_models.h"
#include "fitting/foot_point.h"
#include "fitting/geometric_fit.h"
#include "fitting/joint_fit.h"
#include "fitting/primitive_models.h"
#include "registration/rigid_step.h"

namespace s2m {
namespace {

using Vector6 = Eigen::Matrix<double, 6, 1>;
using Matrix6 = Eigen::Matrix<double, 6, 6>;

// A random symmetric positive semi-definite error matrix like SDM's: a normal with weight 1, tangents with
// curvature weights in [0, 1).
Eigen::Matrix3d RandomErrorMatrix(std::mt19937& rng) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> normal(0.0, 1.0);
  const Eigen::Vector3d axis(normal(rng), normal(rng), normal(rng));
  const Eigen::Matrix3d frame = Eigen::AngleAxisd(axis.norm(), axis.normalized()).toRotationMatrix();
  return frame * Eigen::Vector3d(unit(rng), unit(rng), 1.0).asDiagonal() * frame.transpose();
}

std::vector<PointConstraint> RandomConstraints(std::mt19937& rng, int count) {
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> weight(0.5, 2.0);
  std::vector<PointConstraint> out;
  for (int i = 0; i < count; ++i) {
    PointConstraint p;
    p.x = Eigen::Vector3d(normal(rng), normal(rng), normal(rng)) * 2.0;
    p.target = p.x + 0.1 * Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
    p.M = RandomErrorMatrix(rng);
    p.weight = weight(rng);
    out.push_back(p);
  }
  return out;
}

// E(c, cbar) = sum w (x' - s)^T M (x' - s) with x' = x + cbar + c x x (docs/method.md section 5, eq. of the
// linearized motion).
double RigidObjective(const std::vector<PointConstraint>& constraints, const Vector6& velocity) {
  const Eigen::Vector3d c = velocity.head<3>(), cbar = velocity.tail<3>();
  double sum = 0.0;
  for (const PointConstraint& p : constraints) {
    const Eigen::Vector3d e = p.x + cbar + c.cross(p.x) - p.target;
    sum += p.weight * e.dot(p.M * e);
  }
  return sum;
}

Vector6 CentralGradient(const std::function<double(const Vector6&)>& f, const Vector6& at, double h) {
  Vector6 g;
  for (int i = 0; i < 6; ++i) {
    Vector6 plus = at, minus = at;
    plus[i] += h;
    minus[i] -= h;
    g[i] = (f(plus) - f(minus)) / (2 * h);
  }
  return g;
}

TEST(RigidNormalEquations, GradientAndMatrixAreHalfTheObjectivesDerivatives) {
  std::mt19937 rng(7);
  const std::vector<PointConstraint> constraints = RandomConstraints(rng, 40);
  RigidNormalEquations eq;
  for (const PointConstraint& p : constraints) eq.Add(p);
  const auto objective = [&](const Vector6& v) { return RigidObjective(constraints, v); };
  // E is quadratic: E(v) = E(0) + 2 g^T v + v^T H v, so grad E = 2 (g + H v) exactly and central differences
  // have no truncation error (only rounding).
  const double h = 1e-4;
  const Vector6 zero = Vector6::Zero();
  EXPECT_LT((CentralGradient(objective, zero, h) - 2.0 * eq.g).norm(), 1e-8 * (1.0 + eq.g.norm()));
  Matrix6 hessian;
  for (int j = 0; j < 6; ++j) {
    Vector6 plus = zero, minus = zero;
    plus[j] += h;
    minus[j] -= h;
    hessian.col(j) = (CentralGradient(objective, plus, h) - CentralGradient(objective, minus, h)) / (2 * h);
  }
  EXPECT_LT((hessian - 2.0 * eq.H).norm(), 1e-5 * eq.H.norm());
  EXPECT_LT((eq.H - eq.H.transpose()).norm(), 1e-14 * eq.H.norm());
}

TEST(RigidNormalEquations, RankOneDirectionsEqualTheFullErrorMatrix) {
  std::mt19937 rng(11);
  const std::vector<PointConstraint> constraints = RandomConstraints(rng, 25);
  RigidNormalEquations full, directions;
  for (const PointConstraint& p : constraints) {
    full.Add(p);
    // M = sum_k lambda_k v_k v_k^T: one AddDirection per eigenvector.
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(p.M);
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d v = eig.eigenvectors().col(k);
      directions.AddDirection(p.x, v, p.weight * eig.eigenvalues()[k], v.dot(p.x - p.target));
    }
  }
  EXPECT_LT((full.H - directions.H).norm(), 1e-12 * full.H.norm());
  EXPECT_LT((full.g - directions.g).norm(), 1e-12 * (1.0 + full.g.norm()));
  // Adding one set of equations to another sums them.
  RigidNormalEquations twice = full;
  twice.Add(full);
  EXPECT_LT((twice.H - 2.0 * full.H).norm(), 1e-14 * full.H.norm());
}

TEST(RigidNormalEquations, BlockAssemblyEqualsTheExplicitProduct) {
  // AddSymmetric's blocks against w A^T M A and w A^T M (x - s) with A = MotionJacobian(x) formed explicitly.
  std::mt19937 rng(17);
  for (const PointConstraint& p : RandomConstraints(rng, 20)) {
    RigidNormalEquations blocks;
    blocks.AddSymmetric(p.x, p.M, p.weight, p.x - p.target);
    const Eigen::Matrix<double, 3, 6> a = MotionJacobian(p.x);
    const Matrix6 h = p.weight * a.transpose() * p.M * a;
    const Vector6 g = p.weight * a.transpose() * p.M * (p.x - p.target);
    EXPECT_LT((blocks.H - h).norm(), 1e-14 * h.norm());
    EXPECT_LT((blocks.g - g).norm(), 1e-14 * (1.0 + g.norm()));
    EXPECT_EQ(blocks.H, blocks.H.transpose());
  }
}

TEST(RigidNormalEquations, SolvedVelocityIsTheObjectivesMinimum) {
  std::mt19937 rng(13);
  const std::vector<PointConstraint> constraints = RandomConstraints(rng, 30);
  RigidNormalEquations eq;
  for (const PointConstraint& p : constraints) eq.Add(p);
  const auto objective = [&](const Vector6& v) { return RigidObjective(constraints, v); };
  const Vector6 velocity = SolveRigidVelocity(eq);
  // The gradient of E vanishes at the solution (central differences in (c, cbar)), and every nearby
  // velocity is worse.
  EXPECT_LT(CentralGradient(objective, velocity, 1e-4).norm(), 1e-8 * (1.0 + 2.0 * eq.g.norm()));
  std::normal_distribution<double> normal(0.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    Vector6 delta;
    for (int i = 0; i < 6; ++i) delta[i] = 1e-3 * normal(rng);
    EXPECT_GT(objective(velocity + delta), objective(velocity));
  }
  // With Levenberg-Marquardt damping the step solves (H + lambda diag H) v = -g: the damped objective's
  // gradient 2 (g + H v + lambda diag(H) v) vanishes.
  const double lambda = 0.3;
  const Vector6 damped = SolveRigidVelocity(eq, lambda);
  const auto damped_objective = [&](const Vector6& v) {
    return objective(v) + lambda * v.dot(eq.H.diagonal().asDiagonal() * v);
  };
  EXPECT_LT(CentralGradient(damped_objective, damped, 1e-4).norm(), 1e-8 * (1.0 + 2.0 * eq.g.norm()));
  EXPECT_LT(damped.norm(), velocity.norm());
}

// ---- The geometric fit's normal equations at exact foot points
// ---------------------------------------------------------

// 1/2 sum_j d^2(x_j, C(P; .)) at the feet of the generic path (closed form where the model has it).
double HalfSquaredDistances(const ParametricModel& model, const Eigen::Matrix3Xd& points) {
  std::vector<FootPoint> feet;
  ComputeFootPoints(model, points, feet);
  double sum = 0.0;
  for (const FootPoint& f : feet) sum += 0.5 * f.distance * f.distance;
  return sum;
}

// The objective with parameter i moved by delta, on a fresh clone (rotation parameters are increments
// set_parameters applies to the frame).
double ObjectiveAt(const ParametricModel& model, const Eigen::Matrix3Xd& points, int i, double delta) {
  std::unique_ptr<ParametricModel> trial = model.Clone();
  Eigen::VectorXd p = model.parameters();
  p[i] += delta;
  trial->set_parameters(p);
  return HalfSquaredDistances(*trial, points);
}

struct NormalEquations {
  Eigen::MatrixXd H;
  Eigen::VectorXd g;
};

// sum_j J_j^T M_j J_j and sum_j J_j^T M_j (C(t_j) - x_j), J_j = dC/dP at the exact foot t_j, M_j the error
// term's matrix in the principal frame there (docs/method.md section 2): the geometric fit's system.
NormalEquations Assemble(const ParametricModel& model, const Eigen::Matrix3Xd& points, ErrorTerm term) {
  const int r = model.num_parameters();
  NormalEquations out{Eigen::MatrixXd::Zero(r, r), Eigen::VectorXd::Zero(r)};
  std::vector<FootPoint> feet;
  ComputeFootPoints(model, points, feet);
  std::vector<JacobianEntry> entries;
  LocalGeometry g;
  for (Eigen::Index j = 0; j < points.cols(); ++j) {
    const FootPoint& foot = feet[static_cast<std::size_t>(j)];
    model.Evaluate(foot.t, 2, g);
    const VecS x = points.col(j);
    const Eigen::Matrix3d M = ErrorMatrix(term, ComputePrincipalFrame(g, x), 3);
    model.ShapeJacobian(foot.t, false, entries);
    Eigen::Matrix3Xd J = Eigen::Matrix3Xd::Zero(3, r);
    for (const JacobianEntry& e : entries) J.col(e.index) += e.column;
    out.H += J.transpose() * M * J;
    out.g += J.transpose() * M * (To3(g.point) - points.col(j));
  }
  return out;
}

// Points near the model: model points at spread parameters moved along the normal by `noise` x N(0, 1).
Eigen::Matrix3Xd PointsNear(const ParametricModel& model, double noise, std::mt19937& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  const std::vector<ParamT> ts = model.SampleParameters();
  const ParameterDomain d = model.domain();
  Eigen::Matrix3Xd points(3, 60);
  LocalGeometry g;
  for (Eigen::Index j = 0; j < points.cols(); ++j) {
    ParamT t = ts[static_cast<std::size_t>(j) * ts.size() / static_cast<std::size_t>(points.cols())];
    t[0] += 0.013;  // off the sample grid (and a sphere's poles)
    // Inside open ends: a foot on a boundary is the end rule's, not an orthogonal projection (docs/method.md
    // section 4), and there the distance is not differentiable in the shape.
    for (std::size_t k = 0; k < 2; ++k) {
      const double width = d.hi[k] - d.lo[k];
      if (!d.periodic[k]) t[k] = std::clamp(t[k], d.lo[k] + 0.05 * width, d.hi[k] - 0.05 * width);
    }
    model.Evaluate(t, 1, g);
    const Eigen::Vector3d n = To3(g.d1.col(0)).cross(To3(g.d1.col(1))).normalized();
    points.col(j) = To3(g.point) + noise * normal(rng) * n;
  }
  return points;
}

struct FitCase {
  const char* name;
  std::function<std::unique_ptr<ParametricModel>()> make;
};

std::vector<FitCase> FitCases() {
  return {
      {"sphere",
       [] {
         return std::make_unique<SphereModel>(Sphere{{1, -2, 0.5}, 2.0});
       }},
      {"cylinder",
       [] {
         return std::make_unique<CylinderModel>(
             Cylinder{{1, 2, 3}, Eigen::Vector3d(1, -1, 2).normalized(), 1.5});
       }},
      {"spline surface",
       [] {
         Eigen::Matrix3Xd p(3, 25);
         for (int i = 0; i < 5; ++i)
           for (int j = 0; j < 5; ++j) p.col(i * 5 + j) << i, j, 0.3 * std::sin(i + 2.0 * j);
         return std::make_unique<BSplineSurface>(BSplineBasis::ClampedUniform(4, 5, 0.0, 2.0),
                                                 BSplineBasis::ClampedUniform(3, 5, 0.0, 3.0), p);
       }},
  };
}

// TDM at exact feet: C(t) - x lies along the normal n, so J^T n n^T (C - x) = J^T (C - x), the gradient of
// 1/2 sum d^2 with the feet held fixed, which is its gradient (the feet are stationary: the envelope
// theorem). Checked by central differences of the objective with the feet recomputed.
TEST(GeometricFitNormalEquations, TdmGradientIsTheObjectivesGradient) {
  for (const FitCase& c : FitCases()) {
    std::mt19937 rng(3);
    const std::unique_ptr<ParametricModel> model = c.make();
    const Eigen::Matrix3Xd points = PointsNear(*model, 0.02, rng);
    const NormalEquations tdm = Assemble(*model, points, ErrorTerm::kTdm);
    Eigen::VectorXd numeric(model->num_parameters());
    for (int i = 0; i < model->num_parameters(); ++i) {
      // Not smaller: the objective carries the Newton feet's rounding (about 1e-12 of it).
      const double h = 1e-4 * std::max(1.0, std::abs(model->parameters()[i]));
      numeric[i] = (ObjectiveAt(*model, points, i, h) - ObjectiveAt(*model, points, i, -h)) / (2 * h);
    }
    EXPECT_LT((tdm.g - numeric).norm(), 1e-6 * (tdm.g.norm() + 1e-3)) << c.name << "\n"
                                                                      << tdm.g.transpose() << "\n"
                                                                      << numeric.transpose();
    // SDM and GTDM share the normal part: on surfaces their gradients equal TDM's (the tangential terms
    // vanish at exact feet, where C - x is normal).
    EXPECT_LT((Assemble(*model, points, ErrorTerm::kSdm).g - tdm.g).norm(), 1e-10 * (tdm.g.norm() + 1e-3))
        << c.name;
  }
}

// Points on the model (zero residuals): the Hessian of 1/2 sum d^2 is sum grad d grad d^T = sum J^T n n^T J,
// TDM's normal matrix (Gauss-Newton is exact at zero residual). Checked by second differences.
TEST(GeometricFitNormalEquations, TdmNormalMatrixIsTheObjectivesHessianAtZeroResidual) {
  // The primitives (r^2 second differences of the objective each; the spline surface's 75 parameters would
  // need 22500).
  std::vector<FitCase> cases = FitCases();
  cases.pop_back();
  for (const FitCase& c : cases) {
    std::mt19937 rng(5);
    const std::unique_ptr<ParametricModel> model = c.make();
    const Eigen::Matrix3Xd points = PointsNear(*model, 0.0, rng);
    const NormalEquations tdm = Assemble(*model, points, ErrorTerm::kTdm);
    const int r = model->num_parameters();
    Eigen::MatrixXd numeric(r, r);
    const Eigen::VectorXd p0 = model->parameters();
    for (int i = 0; i < r; ++i) {
      for (int k = 0; k < r; ++k) {
        const double hi = 1e-4 * std::max(1.0, std::abs(p0[i])), hk = 1e-4 * std::max(1.0, std::abs(p0[k]));
        auto at = [&](double di, double dk) {
          std::unique_ptr<ParametricModel> trial = model->Clone();
          Eigen::VectorXd p = p0;
          p[i] += di;
          p[k] += dk;
          trial->set_parameters(p);
          return HalfSquaredDistances(*trial, points);
        };
        numeric(i, k) = (at(hi, hk) - at(hi, -hk) - at(-hi, hk) + at(-hi, -hk)) / (4 * hi * hk);
      }
    }
    EXPECT_LT((tdm.H - numeric).norm(), 1e-4 * tdm.H.norm()) << c.name << "\n" << tdm.H << "\n\n" << numeric;
  }
}

// ---- The joint fit's normal equations (LinearizeJointFit) against the joint objective
// -------------------------------------------------------------

// F(D, m_1, m_2) = 1/2 sum_k sum_j d^2(x' , C(P + D)), x' the points of scan k moved by the exact motion of
// its velocity m_k = (c_k, cbar_k): the objective the joint system linearizes (docs/method.md eq. 19).
double JointObjective(const ParametricModel& model, const std::vector<Eigen::Matrix3Xd>& scans,
                      const Eigen::VectorXd& x) {
  const int r = model.num_parameters();
  std::unique_ptr<ParametricModel> trial = model.Clone();
  trial->set_parameters(model.parameters() + x.head(r));
  double sum = 0.0;
  for (std::size_t k = 0; k < scans.size(); ++k) {
    const Eigen::Index o = r + 6 * static_cast<Eigen::Index>(k);
    const RigidMotion motion = RigidMotion::FromHelicalVelocity(x.segment<3>(o), x.segment<3>(o + 3));
    sum += HalfSquaredDistances(*trial, motion.apply(scans[k]));
  }
  return sum;
}

// Two scans of the primitives' points (the first and the second half), at identity poses.
std::vector<Eigen::Matrix3Xd> TwoScans(const Eigen::Matrix3Xd& points) {
  const Eigen::Index half = points.cols() / 2;
  return {points.leftCols(half), points.rightCols(points.cols() - half)};
}

// TDM's joint gradient (shape block and both motion blocks) is the gradient of the joint objective, by
// central differences with the feet recomputed; SDM's equals TDM's at exact feet.
TEST(JointFitNormalEquations, TdmGradientIsTheJointObjectivesGradient) {
  std::vector<FitCase> cases = FitCases();
  cases.pop_back();  // the primitives (the spline surface's feet near its open boundary need the end rule)
  for (const FitCase& c : cases) {
    std::mt19937 rng(11);
    const std::unique_ptr<ParametricModel> model = c.make();
    const std::vector<Eigen::Matrix3Xd> scans = TwoScans(PointsNear(*model, 0.02, rng));
    const std::vector<RigidMotion> poses(2, RigidMotion());
    const JointNormalEquations tdm = LinearizeJointFit(*model, scans, poses, ErrorTerm::kTdm);
    const Eigen::Index n = tdm.g.size();
    ASSERT_EQ(n, model->num_parameters() + 12) << c.name;
    EXPECT_NEAR(tdm.objective, JointObjective(*model, scans, Eigen::VectorXd::Zero(n)), 1e-12) << c.name;
    Eigen::VectorXd numeric(n);
    for (Eigen::Index i = 0; i < n; ++i) {
      const double h = 1e-5;
      Eigen::VectorXd plus = Eigen::VectorXd::Zero(n), minus = Eigen::VectorXd::Zero(n);
      plus[i] = h;
      minus[i] = -h;
      numeric[i] = (JointObjective(*model, scans, plus) - JointObjective(*model, scans, minus)) / (2 * h);
    }
    EXPECT_LT((tdm.g - numeric).norm(), 1e-6 * (tdm.g.norm() + 1e-3)) << c.name << "\n"
                                                                      << tdm.g.transpose() << "\n"
                                                                      << numeric.transpose();
    const JointNormalEquations sdm = LinearizeJointFit(*model, scans, poses, ErrorTerm::kSdm);
    EXPECT_LT((sdm.g - tdm.g).norm(), 1e-10 * (tdm.g.norm() + 1e-3)) << c.name;
  }
}

// Points on the model: the joint objective's Hessian in shape and motions is TDM's joint matrix, the
// Gauss-Newton matrix of the orthogonal distances (exact at zero residual), coupling blocks included.
TEST(JointFitNormalEquations, TdmJointMatrixIsTheGaussNewtonHessianAtZeroResidual) {
  std::vector<FitCase> cases = FitCases();
  cases.pop_back();
  for (const FitCase& c : cases) {
    std::mt19937 rng(13);
    const std::unique_ptr<ParametricModel> model = c.make();
    const std::vector<Eigen::Matrix3Xd> scans = TwoScans(PointsNear(*model, 0.0, rng));
    const JointNormalEquations tdm =
        LinearizeJointFit(*model, scans, {RigidMotion(), RigidMotion()}, ErrorTerm::kTdm);
    const Eigen::Index n = tdm.g.size();
    Eigen::MatrixXd numeric(n, n);
    const double h = 1e-4;
    for (Eigen::Index i = 0; i < n; ++i) {
      for (Eigen::Index k = 0; k < n; ++k) {
        auto at = [&](double di, double dk) {
          Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
          x[i] += di;
          x[k] += dk;
          return JointObjective(*model, scans, x);
        };
        numeric(i, k) = (at(h, h) - at(h, -h) - at(-h, h) + at(-h, -h)) / (4 * h * h);
      }
    }
    EXPECT_LT((tdm.H - numeric).norm(), 1e-4 * tdm.H.norm()) << c.name << "\n" << tdm.H << "\n\n" << numeric;
  }
}

}  // namespace
}  // namespace s2m
