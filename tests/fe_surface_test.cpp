// Fang's finite-element surface (fitting/fe_surface.h) and its fit to scattered points
// (fitting/fe_surface_fit.h), docs/fe-surfaces.md sections 3-4.
#include "fitting/fe_surface.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <stdexcept>

#include "fitting/fe_surface_fit.h"
#include "fitting/fe_surface_model.h"
#include "fitting/hermite_curve.h"
#include "fitting/model_checker.h"

namespace s2m {
namespace {

// A regular hexagon of circumradius `radius` split into six triangles at its centre, each subdivided into
// n^2 congruent triangles.
FeMesh SubdividedHexagon(double radius, int n) {
  FeMesh mesh;
  std::map<std::pair<long long, long long>, int> index;
  std::vector<Eigen::Vector2d> vertices;
  const auto vertex = [&](const Eigen::Vector2d& p) {
    const auto key = std::make_pair(std::llround(p.x() * 1e9), std::llround(p.y() * 1e9));
    const auto found = index.find(key);
    if (found != index.end()) return found->second;
    vertices.push_back(p);
    return index[key] = static_cast<int>(vertices.size()) - 1;
  };
  for (int k = 0; k < 6; ++k) {
    const double a = k * M_PI / 3.0, b = (k + 1) * M_PI / 3.0;
    const Eigen::Vector2d p(radius * std::cos(a), radius * std::sin(a)),
        q(radius * std::cos(b), radius * std::sin(b));
    const auto at = [&](int i, int j) {
      return vertex((static_cast<double>(i) / n) * p + (static_cast<double>(j) / n) * q);
    };
    for (int i = 0; i < n; ++i)
      for (int j = 0; i + j < n; ++j) {
        mesh.triangles.push_back({at(i, j), at(i + 1, j), at(i, j + 1)});
        if (i + j + 1 < n) mesh.triangles.push_back({at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)});
      }
  }
  mesh.uv.resize(2, static_cast<Eigen::Index>(vertices.size()));
  for (std::size_t i = 0; i < vertices.size(); ++i) mesh.uv.col(static_cast<Eigen::Index>(i)) = vertices[i];
  return mesh;
}

bool InsideHexagon(const Eigen::Vector2d& p, double radius) {
  for (int k = 0; k < 6; ++k) {
    const double a = (k + 0.5) * M_PI / 3.0;
    if (p.x() * std::cos(a) + p.y() * std::sin(a) > radius * std::cos(M_PI / 6.0)) return false;
  }
  return true;
}

// The Gaussian bump (unit height, sigma 1) as a graph (u, v, g(u, v)), with its first derivatives.
Eigen::Matrix3d GaussianBump(const Eigen::Vector2d& p) {
  const double g = std::exp(-0.5 * p.squaredNorm());
  Eigen::Matrix3d f;
  f.col(0) = Eigen::Vector3d(p.x(), p.y(), g);
  f.col(1) = Eigen::Vector3d(1, 0, -p.x() * g);
  f.col(2) = Eigen::Vector3d(0, 1, -p.y() * g);
  return f;
}

TEST(FeSurface, ReproducesQuadraticsAndIsC1AcrossEveryInteriorEdge) {
  FeSurface surface(SubdividedHexagon(3.0, 3));
  // A quadratic vector field: reproduced exactly, with the exact thin-plate energy and no C2 jumps.
  const auto quadratic = [](const Eigen::Vector2d& p) {
    Eigen::Matrix3d f;
    f.col(0) =
        Eigen::Vector3d(p.x() + 0.3 * p.y() * p.y(), p.y() - 0.2 * p.x() * p.y(), 0.5 * p.x() * p.x() + 1.0);
    f.col(1) = Eigen::Vector3d(1.0, -0.2 * p.y(), p.x());
    f.col(2) = Eigen::Vector3d(0.6 * p.y(), 1.0 - 0.2 * p.x(), 0.0);
    return f;
  };
  surface.Interpolate(quadratic);
  for (const FeSurfacePoint& at : surface.SamplePoints(4)) {
    const Eigen::Vector2d p = surface.ParameterOf(at);
    EXPECT_LT((surface.Evaluate(at).point - quadratic(p).col(0)).norm(), 1e-12);
  }
  // Thin plate |w_uu|^2 + 2|w_uv|^2 + |w_vv|^2 = 0.6^2 + 2 * 0.2^2 + 1 per unit area; hexagon area 3
  // sqrt(3)/2 R^2.
  const double area = 1.5 * std::sqrt(3.0) * 9.0;
  FairnessWeights weights;
  weights.bending = 1.0;
  weights.jump2 = 1.0;
  const FeSurfaceEnergy energy = surface.Energy(weights);
  EXPECT_NEAR(energy.bending, area * (0.36 + 0.08 + 1.0), 1e-9 * area);
  EXPECT_LT(energy.jump, 1e-10 * energy.bending);  // zero up to the rounding of the quadratic form

  // A Gaussian bump interpolated from its nodal data: value and normal slope agree along every interior edge
  // from both sides; its C2 jumps are not zero.
  surface.Interpolate(GaussianBump);
  double worst = 0.0;
  for (int e = 0; e < surface.edge_count(); ++e) {
    if (surface.boundary_edge(e)) continue;
    const Eigen::Vector2d a = surface.mesh().uv.col(surface.edge(e)[0]),
                          b = surface.mesh().uv.col(surface.edge(e)[1]);
    const Eigen::Vector2d n = GlobalEdgeFrame(a, b).normal;
    for (int k = 1; k < 10; ++k) {
      const Eigen::Vector2d p = a + 0.1 * k * (b - a);
      std::array<FeSurfaceGeometry, 2> side;
      for (int s = 0; s < 2; ++s) {
        const int t = surface.edge_triangles(e)[static_cast<std::size_t>(s)];
        side[static_cast<std::size_t>(s)] = surface.Evaluate({t, surface.element(t).Barycentric(p)});
      }
      worst =
          std::max({worst, (side[0].point - side[1].point).norm(), (side[0].d1 * n - side[1].d1 * n).norm()});
    }
  }
  EXPECT_LT(worst, 1e-12);
  EXPECT_GT(surface.Energy(weights).jump, 1e-4);
}

TEST(FeSurface, LocateWalksToTheHostTriangleAndClampsOutsidePoints) {
  FeSurface surface(SubdividedHexagon(3.0, 4));
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> coordinate(-3.5, 3.5);
  FeSurfacePoint at;
  for (int trial = 0; trial < 500; ++trial) {
    const Eigen::Vector2d p(coordinate(rng), coordinate(rng));
    const bool inside = surface.Locate(p, at);
    EXPECT_GE(at.barycentric.minCoeff(), 0.0);
    EXPECT_NEAR(at.barycentric.sum(), 1.0, 1e-12);
    if (InsideHexagon(p, 3.0 - 1e-9)) {
      EXPECT_TRUE(inside);
      EXPECT_LT((surface.ParameterOf(at) - p).norm(), 1e-12);
    } else if (!InsideHexagon(p, 3.0 + 1e-9)) {
      EXPECT_FALSE(inside);
      // The clamped point is on the boundary, no farther than the hexagon's nearest point ... and not nearer.
      const Eigen::Vector2d q = surface.ParameterOf(at);
      EXPECT_TRUE(InsideHexagon(q, 3.0 + 1e-9));
      EXPECT_FALSE(InsideHexagon(q, 3.0 - 1e-9));
    }
  }
}

TEST(FeSurface, RefusesBadMeshesWithAMessage) {
  const auto message = [](FeMesh mesh) {
    try {
      FeSurface surface(std::move(mesh));
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  FeMesh mesh;
  mesh.uv.resize(2, 4);
  mesh.uv << 0, 1, 0, 1, 0, 0, 1, 1;
  EXPECT_NE(message(mesh).find("no triangles"), std::string::npos);
  mesh.triangles = {{0, 1, 4}};
  EXPECT_NE(message(mesh).find("refers to vertex 4"), std::string::npos);
  mesh.triangles = {{0, 2, 1}};
  EXPECT_NE(message(mesh).find("clockwise"), std::string::npos);
  mesh.uv.conservativeResize(2, 5);
  mesh.uv.col(4) = Eigen::Vector2d(0.5, -1.0);
  mesh.triangles = {{0, 1, 2}, {0, 1, 3}, {1, 0, 4}};  // three triangles on the edge 0-1
  EXPECT_NE(message(mesh).find("more than two triangles"), std::string::npos);
  mesh.triangles = {{0, 1, 2}};
  mesh.uv(0, 3) = NAN;
  EXPECT_NE(message(mesh).find("not finite"), std::string::npos);
}

struct BumpErrors {
  double e_max = 0.0, e_mean = 0.0;
};

// Errors measured as the thesis does (Fang 1994, ch. 6): points sampled on the TRUE surface (not the noisy
// input), each one's distance to the reconstruction.
// e_max and e_mean of the distances from points of the true surface `truth(u, v)` (parameters uniform over
// the hexagon of circumradius 3) to the fitted surface, each point's foot searched from its parameter.
template <typename Truth>
BumpErrors ErrorsToTruth(const FeSurface& surface, int samples, std::mt19937& rng, const Truth& truth) {
  std::uniform_real_distribution<double> coordinate(-3.0, 3.0);
  BumpErrors errors;
  int count = 0;
  FeSurfacePoint at;
  while (count < samples) {
    const Eigen::Vector2d p(coordinate(rng), coordinate(rng));
    if (!InsideHexagon(p, 3.0)) continue;
    const Eigen::Vector3d x = truth(p);
    surface.Locate(p, at);
    FeFootPoint(surface, x, at);
    const double e = (surface.Evaluate(at).point - x).norm();
    errors.e_max = std::max(errors.e_max, e);
    errors.e_mean += e;
    ++count;
  }
  errors.e_mean /= count;
  return errors;
}

BumpErrors ErrorsToTheTrueBump(const FeSurface& surface, int samples, std::mt19937& rng) {
  return ErrorsToTruth(surface, samples, rng,
                       [](const Eigen::Vector2d& p) -> Eigen::Vector3d { return GaussianBump(p).col(0); });
}

struct NoisyBump {
  Eigen::Matrix3Xd points;
  Eigen::Matrix2Xd start_uv;
};

NoisyBump SampleNoisyBump(int count, double noise, std::mt19937& rng) {
  std::uniform_real_distribution<double> coordinate(-3.0, 3.0);
  std::normal_distribution<double> gauss(0.0, noise);
  NoisyBump data;
  data.points.resize(3, count);
  data.start_uv.resize(2, count);
  for (int i = 0; i < count;) {
    const Eigen::Vector2d p(coordinate(rng), coordinate(rng));
    if (!InsideHexagon(p, 3.0)) continue;
    data.points.col(i) = GaussianBump(p).col(0) + Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
    data.start_uv.col(i) = data.points.col(i).head<2>();
    ++i;
  }
  return data;
}

TEST(FeSurfaceFit, GaussianBumpFromScatteredNoisyPoints) {
  // The thesis' Gaussian example: unit height, sigma 1, over a hexagon of circumradius 3, from scattered
  // noisy points (here 3000 points, isotropic noise 0.005 = 0.5 % of the height), the patch parametrized by
  // its projection with the boundary pinned in the plane. Every method must bring the reconstruction within 1
  // % of the height of the true surface everywhere (e_max) and well under the noise on average; TDM and SDM
  // converge in a few iterations, PDM (the plain sliding springs) only linearly, so after the same 50
  // iterations it is still above SDM's objective.
  std::mt19937 rng(2024);
  const NoisyBump data = SampleNoisyBump(3000, 0.005, rng);
  std::map<ErrorTerm, FeSurfaceFitResult> fits;
  for (ErrorTerm method : {ErrorTerm::kPdm, ErrorTerm::kTdm, ErrorTerm::kSdm}) {
    FeSurface surface(SubdividedHexagon(3.0, 4));
    FeSurfaceFitOptions options;
    options.method = method;
    const std::vector<FeFixedDirection> boundary = SetPlanarChart(surface);
    const FeSurfaceFitResult fit = FitFeSurface(data.points, data.start_uv, options, surface, boundary);
    std::mt19937 check_rng(99);
    const BumpErrors errors = ErrorsToTheTrueBump(surface, 4000, check_rng);
    std::printf("method %d: %d iterations%s, objective %.8f, RMS %.5f, e_max %.5f, e_mean %.5f, %d dofs\n",
                static_cast<int>(method), fit.iterations, fit.converged ? " (converged)" : "",
                fit.objective.back(), fit.rms, errors.e_max, errors.e_mean, surface.dof_count());
    EXPECT_LT(errors.e_max, 0.01);
    EXPECT_LT(errors.e_mean, 0.002);
    EXPECT_NEAR(fit.rms, 0.005, 0.0005);  // isotropic noise 0.005 per coordinate: 0.005 along the normal
    fits[method] = fit;
  }
  EXPECT_TRUE(fits[ErrorTerm::kTdm].converged);
  EXPECT_TRUE(fits[ErrorTerm::kSdm].converged);
  EXPECT_LT(fits[ErrorTerm::kSdm].iterations, 20);
  EXPECT_GT(fits[ErrorTerm::kPdm].objective.back(), fits[ErrorTerm::kSdm].objective.back());
}

TEST(FeSurfaceFit, CurvatureJumpTermLowersTheJumpsAcrossEdges) {
  // Fang's C2-jump term (eq. P4): with it, the integral of the squared Hessian jump over the interior edges
  // is measurably smaller, at an unchanged accuracy.
  std::mt19937 rng(2025);
  const NoisyBump data = SampleNoisyBump(3000, 0.005, rng);
  FairnessWeights measure;
  measure.jump2 = 1.0;
  std::vector<double> jumps;
  for (double jump : {0.0, 1e-6}) {
    FeSurface surface(SubdividedHexagon(3.0, 4));
    FeSurfaceFitOptions options;
    options.jump = jump;
    const std::vector<FeFixedDirection> boundary = SetPlanarChart(surface);
    const FeSurfaceFitResult fit = FitFeSurface(data.points, data.start_uv, options, surface, boundary);
    std::mt19937 check_rng(98);
    const BumpErrors errors = ErrorsToTheTrueBump(surface, 3000, check_rng);
    jumps.push_back(surface.Energy(measure).jump);
    std::printf("jump weight %g: integral of |Hessian jump|^2 over the edges %.6f, e_max %.5f, e_mean %.5f\n",
                jump, jumps.back(), errors.e_max, errors.e_mean);
    EXPECT_LT(errors.e_max, 0.01);
    EXPECT_TRUE(fit.converged);
  }
  EXPECT_LT(jumps[1], 0.5 * jumps[0]);
}

TEST(FeSurfaceFit, PatchOfACylinderDevelopedOntoIt) {
  // A patch of a cylinder of radius 5 (about the z axis) with a Gaussian bump of unit height and sigma 1
  // pushing it outwards, parametrized by its development (u = R theta, v = z) over the hexagon of
  // circumradius 3 (0.6 rad either side): the chart of eq. P8c, the boundary free to move radially only. The
  // errors to the true surface are bounded as for the planar bump; the boundary vertices keep their angle
  // and height (the reduced transformation with directions that are not coordinate axes).
  const double radius = 5.0;
  const auto truth = [radius](const Eigen::Vector2d& p) -> Eigen::Vector3d {
    const double r = radius + std::exp(-0.5 * p.squaredNorm());
    return {r * std::cos(p.x() / radius), r * std::sin(p.x() / radius), p.y()};
  };
  std::mt19937 rng(2026);
  std::uniform_real_distribution<double> coordinate(-3.0, 3.0);
  std::normal_distribution<double> gauss(0.0, 0.005);
  const int count = 3000;
  Eigen::Matrix3Xd points(3, count);
  Eigen::Matrix2Xd start_uv(2, count);
  for (int i = 0; i < count;) {
    const Eigen::Vector2d p(coordinate(rng), coordinate(rng));
    if (!InsideHexagon(p, 3.0)) continue;
    points.col(i) = truth(p) + Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
    start_uv.col(i) = Eigen::Vector2d(radius * std::atan2(points(1, i), points(0, i)), points(2, i));
    ++i;
  }
  FeSurface surface(SubdividedHexagon(3.0, 4));
  const std::vector<FeFixedDirection> boundary = SetCylindricalChart(surface, radius);
  const Eigen::MatrixX3d start = surface.dofs();
  const FeSurfaceFitResult fit = FitFeSurface(points, start_uv, FeSurfaceFitOptions{}, surface, boundary);
  std::mt19937 check_rng(97);
  const BumpErrors errors = ErrorsToTruth(surface, 4000, check_rng, truth);
  std::printf("cylinder patch: %d iterations%s, RMS %.5f, e_max %.5f, e_mean %.5f\n", fit.iterations,
              fit.converged ? " (converged)" : "", fit.rms, errors.e_max, errors.e_mean);
  EXPECT_TRUE(fit.converged);
  EXPECT_LT(errors.e_max, 0.01);
  EXPECT_LT(errors.e_mean, 0.002);
  EXPECT_NEAR(fit.rms, 0.005, 0.0005);
  int boundary_vertices = 0;
  for (int e = 0; e < surface.edge_count(); ++e) {
    if (!surface.boundary_edge(e)) continue;
    for (int v : surface.edge(e)) {
      const Eigen::Vector3d before = start.row(surface.vertex_dof(v, 0)).transpose();
      const Eigen::Vector3d after = surface.dofs().row(surface.vertex_dof(v, 0)).transpose();
      EXPECT_NEAR(std::atan2(after.y(), after.x()), std::atan2(before.y(), before.x()), 1e-12);
      EXPECT_NEAR(after.z(), before.z(), 1e-12);
      ++boundary_vertices;
    }
  }
  EXPECT_GT(boundary_vertices, 0);

  // The chart refuses a domain that would wrap round the axis.
  FeSurface wide(SubdividedHexagon(3.0, 1));
  EXPECT_THROW(SetCylindricalChart(wide, 0.5), std::invalid_argument);
  EXPECT_THROW(SetCylindricalChart(wide, -1.0), std::invalid_argument);
}

TEST(FeSurfaceFit, ADofFixedInThreeDirectionsKeepsItsValue) {
  // Three independent fixed directions (not the axes) leave a dof no freedom; a zero direction or a dof out
  // of range is refused.
  std::mt19937 rng(11);
  const NoisyBump data = SampleNoisyBump(800, 0.005, rng);
  FeSurface surface(SubdividedHexagon(3.0, 2));
  std::vector<FeFixedDirection> fixed = SetPlanarChart(surface);
  const int centre_dof = surface.vertex_dof(0, 0);
  for (const Eigen::Vector3d& d :
       {Eigen::Vector3d(1, 1, 0), Eigen::Vector3d(1, -1, 0), Eigen::Vector3d(0, 1, 1)})
    fixed.push_back({centre_dof, d});
  const Eigen::MatrixX3d before = surface.dofs();
  FitFeSurface(data.points, data.start_uv, FeSurfaceFitOptions{}, surface, fixed);
  EXPECT_LT((surface.dofs().row(centre_dof) - before.row(centre_dof)).norm(), 1e-12);
  EXPECT_GT((surface.dofs() - before).cwiseAbs().maxCoeff(), 0.1);  // the bump was fitted around it
  FeSurface other(SubdividedHexagon(3.0, 2));
  SetPlanarChart(other);
  EXPECT_THROW(
      FitFeSurface(data.points, data.start_uv, FeSurfaceFitOptions{}, other, {{0, Eigen::Vector3d::Zero()}}),
      std::invalid_argument);
  EXPECT_THROW(FitFeSurface(data.points, data.start_uv, FeSurfaceFitOptions{}, other,
                            {{other.dof_count(), Eigen::Vector3d::UnitX()}}),
               std::invalid_argument);
}

TEST(FeSurfaceFit, AFixedPointAndATangentPlaneAtAVertexAreKeptExactly) {
  // The geometric constraints of the reduced transformation (eq. P9) beside the chart's: the centre vertex
  // is held at a point on the bump and its tangent plane at a given tilt (w_u . n0 = w_v . n0 = 0, two fixed
  // directions of its slope dofs); the fit moves everything else.
  std::mt19937 rng(12);
  const NoisyBump data = SampleNoisyBump(1500, 0.005, rng);
  FeSurface surface(SubdividedHexagon(3.0, 3));
  std::vector<FeFixedDirection> fixed = SetPlanarChart(surface);
  const Eigen::Vector3d n0 = Eigen::Vector3d(0.3, -0.2, 1.0).normalized();
  const Eigen::Vector3d point(0.0, 0.0, 1.05);
  Eigen::MatrixX3d q = surface.dofs();
  q.row(surface.vertex_dof(0, 0)) = point.transpose();
  q.row(surface.vertex_dof(0, 1)) = Eigen::Vector3d(1, 0, -n0.x() / n0.z()).transpose();
  q.row(surface.vertex_dof(0, 2)) = Eigen::Vector3d(0, 1, -n0.y() / n0.z()).transpose();
  surface.set_dofs(q);
  ASSERT_NEAR(surface.mesh().uv.col(0).norm(), 0.0, 1e-12);  // vertex 0 is the centre
  for (int axis = 0; axis < 3; ++axis)
    fixed.push_back({surface.vertex_dof(0, 0), Eigen::Vector3d::Unit(axis)});
  fixed.push_back({surface.vertex_dof(0, 1), n0});
  fixed.push_back({surface.vertex_dof(0, 2), n0});
  const Eigen::MatrixX3d before = surface.dofs();
  const FeSurfaceFitResult r =
      FitFeSurface(data.points, data.start_uv, FeSurfaceFitOptions{}, surface, fixed);
  const Eigen::Vector3d w_u = surface.dofs().row(surface.vertex_dof(0, 1)).transpose();
  const Eigen::Vector3d w_v = surface.dofs().row(surface.vertex_dof(0, 2)).transpose();
  EXPECT_LT((surface.dofs().row(surface.vertex_dof(0, 0)).transpose() - point).norm(), 1e-12);
  EXPECT_LT(std::abs(w_u.dot(n0)), 1e-12);
  EXPECT_LT(std::abs(w_v.dot(n0)), 1e-12);
  EXPECT_LT((w_u.cross(w_v).normalized() - n0).norm(), 1e-12);  // the surface's normal there is n0
  // The slopes themselves were free within the plane, and the rest of the bump was fitted.
  EXPECT_GT((surface.dofs().row(surface.vertex_dof(0, 1)) - before.row(surface.vertex_dof(0, 1))).norm(),
            1e-4);
  EXPECT_GT((surface.dofs() - before).cwiseAbs().maxCoeff(), 0.5);
  EXPECT_LT(r.rms, 0.05);
}

TEST(FeSurface, FootPointWalksAcrossTrianglesToTheOrthogonalFoot) {
  // A bump surface; points off it along its normal by +-0.1 at random parameters, each foot searched from
  // the triangle farthest from it: the walk must reach the true foot (the offset's parameter) and stop
  // with the residual orthogonal to both tangents. A point beyond the domain ends on the boundary (false).
  FeSurface surface(SubdividedHexagon(3.0, 4));
  surface.Interpolate(GaussianBump);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> coordinate(-2.4, 2.4), side(-1.0, 1.0);
  int checked = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const Eigen::Vector2d uv(coordinate(rng), coordinate(rng));
    if (!InsideHexagon(uv, 2.4)) continue;
    FeSurfacePoint truth;
    ASSERT_TRUE(surface.Locate(uv, truth));
    const FeSurfaceGeometry g = surface.Evaluate(truth);
    const Eigen::Vector3d normal = g.d1.col(0).cross(g.d1.col(1)).normalized();
    const Eigen::Vector3d x = g.point + (side(rng) > 0 ? 0.1 : -0.1) * normal;
    // Start in the triangle whose centroid is farthest from uv.
    FeSurfacePoint at;
    double farthest = -1.0;
    for (int t = 0; t < surface.triangle_count(); ++t) {
      const double d = (surface.ParameterOf({t, Eigen::Vector3d::Constant(1.0 / 3.0)}) - uv).norm();
      if (d > farthest) {
        farthest = d;
        at = {t, Eigen::Vector3d::Constant(1.0 / 3.0)};
      }
    }
    ASSERT_TRUE(FeFootPoint(surface, x, at)) << "trial " << trial;
    const FeSurfaceGeometry foot = surface.Evaluate(at);
    EXPECT_LT((surface.ParameterOf(at) - uv).norm(), 1e-8) << "trial " << trial;
    EXPECT_LT(std::abs((x - foot.point).dot(foot.d1.col(0))), 1e-10);
    EXPECT_LT(std::abs((x - foot.point).dot(foot.d1.col(1))), 1e-10);
    ++checked;
  }
  EXPECT_GT(checked, 100);
  FeSurfacePoint at;
  EXPECT_FALSE(FeFootPoint(surface, Eigen::Vector3d(5.0, 0.3, 0.0), at));
  const Eigen::Vector2d edge = surface.ParameterOf(at);
  double support = 0.0;  // the hexagon's support function: its apothem on the boundary
  for (int k = 0; k < 6; ++k)
    support = std::max(
        support, edge.x() * std::cos((k + 0.5) * M_PI / 3.0) + edge.y() * std::sin((k + 0.5) * M_PI / 3.0));
  EXPECT_NEAR(support, 3.0 * std::cos(M_PI / 6.0), 1e-9);
  EXPECT_GT(edge.x(), 2.0);
}

// A bump on a tilted, bent sheet (its boundary out of a plane): the graph (u, v, f) with its slopes.
Eigen::Matrix3d BumpOnASheet(const Eigen::Vector2d& p) {
  Eigen::Matrix3d f = GaussianBump(p);
  f(2, 0) += 0.15 * p.x() + 0.05 * p.y() * p.y();
  f(2, 1) += 0.15;
  f(2, 2) += 0.1 * p.y();
  return f;
}

// The six sides of the hexagon of circumradius 3 as open cubic Hermite curves of `elements` elements, their
// nodes on the true surface with its exact slopes (the sides' boundary curves, as fitted boundary curves
// would give them), and the trace of eq. P12 they define.
struct HexagonBoundary {
  std::vector<Eigen::Vector2d> corners;
  std::vector<HermiteCurve> sides;

  explicit HexagonBoundary(int elements) {
    for (int k = 0; k <= 6; ++k)
      corners.emplace_back(3.0 * std::cos(k * M_PI / 3.0), 3.0 * std::sin(k * M_PI / 3.0));
    for (int k = 0; k < 6; ++k) {
      const Eigen::Vector2d a = corners[static_cast<std::size_t>(k)],
                            b = corners[static_cast<std::size_t>(k + 1)];
      Eigen::MatrixXd dofs(3, 2 * (elements + 1));
      for (int n = 0; n <= elements; ++n) {
        const Eigen::Matrix3d f = BumpOnASheet(a + (b - a) * n / static_cast<double>(elements));
        dofs.col(2 * n) = f.col(0);
        dofs.col(2 * n + 1) =
            f.col(1) * (b - a).x() + f.col(2) * (b - a).y();  // d/du, u in [0, 1] along the side
      }
      sides.push_back(HermiteCurve::Uniform(3, elements, dofs, false));
    }
  }
  // The side through uv parallel to d, and the curve's point and slope per unit length along d.
  void Trace(const Eigen::Vector2d& uv, const Eigen::Vector2d& d, Eigen::Vector3d& point,
             Eigen::Vector3d& slope) const {
    for (int k = 0; k < 6; ++k) {
      const Eigen::Vector2d a = corners[static_cast<std::size_t>(k)],
                            b = corners[static_cast<std::size_t>(k + 1)];
      const Eigen::Vector2d t = (b - a) / (b - a).norm();
      const double along = (uv - a).dot(t), length = (b - a).norm();
      const double off = std::abs((uv - a).x() * t.y() - (uv - a).y() * t.x());
      if (off > 1e-9 || along < -1e-9 || along > length + 1e-9 ||
          std::abs(d.x() * t.y() - d.y() * t.x()) > 1e-9)
        continue;
      Eigen::MatrixXd jet;
      sides[static_cast<std::size_t>(k)].EvaluateJet(std::clamp(along / length, 0.0, 1.0), 1, jet);
      point = jet.col(0);
      slope = jet.col(1) / length * d.dot(t);
      return;
    }
    throw std::invalid_argument("not on the hexagon's boundary");
  }
};

TEST(FeSurfaceFit, BoundaryConformsExactlyToHermiteBoundaryCurves) {
  // Fang's n-sided patch (thesis 4.3.4.1, docs/fe-surfaces.md eq. P12): the boundary given as six cubic
  // Hermite curves with nodes at the mesh's boundary vertices; the conformity rows, kept by the reduced
  // transformation (eq. P9) through the fit, make the surface's boundary the curves themselves, while the
  // inside fits the points as well as with a planar chart.
  const HexagonBoundary boundary(4);
  const auto trace = [&boundary](const Eigen::Vector2d& uv, const Eigen::Vector2d& d, Eigen::Vector3d& point,
                                 Eigen::Vector3d& slope) { boundary.Trace(uv, d, point, slope); };
  std::mt19937 rng(2027);
  std::uniform_real_distribution<double> coordinate(-3.0, 3.0);
  std::normal_distribution<double> gauss(0.0, 0.005);
  Eigen::Matrix3Xd points(3, 3000);
  Eigen::Matrix2Xd start_uv(2, 3000);
  for (int i = 0; i < 3000;) {
    const Eigen::Vector2d p(coordinate(rng), coordinate(rng));
    if (!InsideHexagon(p, 3.0)) continue;
    points.col(i) = BumpOnASheet(p).col(0) + Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
    start_uv.col(i) = points.col(i).head<2>();
    ++i;
  }
  FeSurface surface(SubdividedHexagon(3.0, 4));
  SetPlanarChart(surface);  // the inside starts flat; its returned pins are not used
  const std::vector<FeLinearConstraint> conformity = SetBoundaryConformity(surface, trace);
  const FeSurfaceFitResult fit =
      FitFeSurface(points, start_uv, FeSurfaceFitOptions{}, surface, {}, conformity);
  // The boundary, sampled along every side, against the curves.
  double boundary_error = 0.0;
  FeSurfacePoint at;
  for (int k = 0; k < 6; ++k)
    for (int i = 0; i <= 40; ++i) {
      const Eigen::Vector2d a = boundary.corners[static_cast<std::size_t>(k)],
                            b = boundary.corners[static_cast<std::size_t>(k + 1)];
      const Eigen::Vector2d uv = a + (b - a) * (i / 40.0);
      surface.Locate(uv, at);
      Eigen::MatrixXd jet;
      boundary.sides[static_cast<std::size_t>(k)].EvaluateJet(i / 40.0, 0, jet);
      boundary_error =
          std::max(boundary_error, (surface.Evaluate(at).point - Eigen::Vector3d(jet.col(0))).norm());
    }
  std::mt19937 check_rng(98);
  const BumpErrors errors =
      ErrorsToTruth(surface, 4000, check_rng,
                    [](const Eigen::Vector2d& p) -> Eigen::Vector3d { return BumpOnASheet(p).col(0); });
  std::printf(
      "boundary curves: %d iterations%s, RMS %.5f, boundary off the curves %.2e, e_max %.5f, e_mean %.5f\n",
      fit.iterations, fit.converged ? " (converged)" : "", fit.rms, boundary_error, errors.e_max,
      errors.e_mean);
  EXPECT_TRUE(fit.converged);
  EXPECT_LT(boundary_error, 1e-10);
  EXPECT_LT(errors.e_max, 0.01);
  EXPECT_LT(errors.e_mean, 0.002);
  EXPECT_NEAR(fit.rms, 0.005, 0.0005);

  // Curves that do not meet at a corner, and a side whose curve runs at another speed than the side's length
  // (Fang's consistency condition): refused with the reason.
  FeSurface gap(SubdividedHexagon(3.0, 4));
  const auto apart = [&boundary](const Eigen::Vector2d& uv, const Eigen::Vector2d& d, Eigen::Vector3d& point,
                                 Eigen::Vector3d& slope) {
    boundary.Trace(uv, d, point, slope);
    if ((uv - boundary.corners[0]).norm() < 1e-9 && d.y() > 0.1)
      point.z() += 0.01;  // the side towards corner 1
  };
  try {
    SetBoundaryConformity(gap, apart);
    ADD_FAILURE() << "curves apart at a corner accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("do not meet"), std::string::npos) << e.what();
  }
  const auto uneven = [&boundary](const Eigen::Vector2d& uv, const Eigen::Vector2d& d, Eigen::Vector3d& point,
                                  Eigen::Vector3d& slope) {
    boundary.Trace(uv, d, point, slope);
    if (uv.y() > 2.0 && std::abs(d.y()) < 1e-9 && d.x() > 0) slope *= 1.2;  // the top side, towards +x
  };
  FeSurface fast(SubdividedHexagon(3.0, 4));
  try {
    SetBoundaryConformity(fast, uneven);
    ADD_FAILURE() << "inconsistent slopes accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("disagree"), std::string::npos) << e.what();
  }
}

TEST(FeSurfaceModel, PassesTheModelChecker) {
  // The FE surface as a model of the engine: derivatives against differences, the shape Jacobian against
  // parameter differences, similarity, clone and parameter round trip (fitting/model_checker.h). The samples
  // lie inside the triangles, away from their edges (the second derivatives jump across edges and have no
  // value at vertices).
  FeSurface surface(SubdividedHexagon(3.0, 2));
  surface.Interpolate(GaussianBump);
  const FeSurfaceModel model(surface);
  const ModelCheckReport report = CheckModel(model);
  std::printf("%s", report.ToString().c_str());
  EXPECT_TRUE(report.ok()) << report.ToString();
}

TEST(FeSurfaceModel, EvaluatesTheSurfaceAndKnowsItsPolygonalDomain) {
  FeSurface surface(SubdividedHexagon(3.0, 3));
  surface.Interpolate(GaussianBump);
  const FeSurfaceModel model(surface);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> coordinate(-3.0, 3.0);
  int inside = 0, outside = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const Eigen::Vector2d p(coordinate(rng), coordinate(rng));
    const bool in = model.InDomain({p.x(), p.y(), 0.0});
    EXPECT_EQ(in, InsideHexagon(p, 3.0)) << p.transpose();
    if (!in) {
      ++outside;
      continue;
    }
    ++inside;
    LocalGeometry g;
    model.Evaluate({p.x(), p.y(), 0.0}, 2, g);
    FeSurfacePoint at;
    surface.Locate(p, at);
    const FeSurfaceGeometry expected = surface.Evaluate(at);
    EXPECT_LT((g.point - expected.point).norm(), 1e-12);
    EXPECT_LT((g.d1 - expected.d1).norm(), 1e-10);
  }
  EXPECT_GT(inside, 100);
  EXPECT_GT(outside, 50);  // the bounding box's corners are not the surface
}

// The bump's boundary curves (the true surface's boundary): Fang's setting, where the boundary holds the
// plate.
void BumpBoundaryTrace(const Eigen::Vector2d& uv, const Eigen::Vector2d& d, Eigen::Vector3d& point,
                       Eigen::Vector3d& slope) {
  const double height = std::exp(-0.5 * uv.squaredNorm());
  point = Eigen::Vector3d(uv.x(), uv.y(), height);
  slope = Eigen::Vector3d(d.x(), d.y(), -height * uv.dot(d));
}

TEST(FangSpringForces, KeepEachForceAndApplyItBetweenTheFootAndTheCentroid) {
  // Eq. P15a: the linear load over the host triangle has the force's total and direction; its work on a
  // linear field is the force's work at barycentric (1, 1, 1) / 4 + Lbar / 4 (at the centroid: the foot).
  FeSurface surface(SubdividedHexagon(3.0, 2));
  surface.Interpolate([](const Eigen::Vector2d& p) {
    Eigen::Matrix3d f;
    f << p.x(), 1.0, 0.0, p.y(), 0.0, 1.0, std::sin(p.x()) * p.y(), std::cos(p.x()) * p.y(), std::sin(p.x());
    return f;
  });
  // Affine virtual displacements dw(u, v) = a + B (u, v), as dof vectors (the element reproduces them).
  const Eigen::Vector3d a(0.3, -1.2, 0.7);
  Eigen::Matrix<double, 3, 2> b;
  b << 0.5, -0.25, 1.5, 0.75, -1.0, 2.0;
  FeSurface field = surface;
  field.Interpolate([&](const Eigen::Vector2d& p) {
    Eigen::Matrix3d f;
    f.col(0) = a + b * p;
    f.rightCols<2>() = b;
    return f;
  });
  Eigen::VectorXd displacement(3 * field.dof_count());
  for (int d = 0; d < field.dof_count(); ++d)
    displacement.segment<3>(3 * d) = field.dofs().row(d).transpose();

  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(0.05, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    FeSurfacePoint foot;
    foot.triangle = trial % surface.triangle_count();
    foot.barycentric = Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
    if (trial == 0) foot.barycentric.setOnes();
    foot.barycentric /= foot.barycentric.sum();
    const Eigen::Vector3d force(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng));
    Eigen::Matrix3Xd point(3, 1);
    point.col(0) = surface.Evaluate(foot).point + force;
    const Eigen::VectorXd forces = FangSpringForces(surface, point, {foot});
    // The total on the value dofs (a translation's work) is the force.
    Eigen::Vector3d total = Eigen::Vector3d::Zero();
    for (int v = 0; v < surface.vertex_count(); ++v) total += forces.segment<3>(3 * surface.vertex_dof(v, 0));
    EXPECT_LT((total - force).norm(), 1e-12 * force.norm());
    FeSurfacePoint applied = foot;
    applied.barycentric = Eigen::Vector3d::Constant(0.25) + foot.barycentric / 4.0;
    const double expected = force.dot(a + b * surface.ParameterOf(applied));
    EXPECT_NEAR(forces.dot(displacement), expected, 1e-12 * (1.0 + std::abs(expected)));
    if (trial == 0) {  // at the centroid, the concentrated force's work
      EXPECT_NEAR(forces.dot(displacement), force.dot(a + b * surface.ParameterOf(foot)), 1e-12);
    }
  }
  EXPECT_THROW(FangSpringForces(surface, Eigen::Matrix3Xd::Zero(3, 2), {FeSurfacePoint{}}),
               std::invalid_argument);
}

TEST(FeSurfaceFit, FangSpringsOnThePlateOnSpringsApproachTheLeastSquaresFitAsTheElementsShrink) {
  // Fang's sliding springs (eqs. P15-P16) with the springs' stiffness at the first feet in the quadratic
  // model: the scan patch's setting (the boundary free along the plane's normal). The iteration stops at the
  // distributed loads' equilibrium, which is not the least-squares minimum: each load acts between its foot
  // and its triangle's centroid (eq. P15a), so the data are blurred over an element. Halving the elements
  // must bring the equilibrium closer to the minimum (SDM's, converged).
  std::mt19937 rng(2024);
  const NoisyBump data = SampleNoisyBump(3000, 0.005, rng);
  std::vector<double> gaps;
  for (int subdivisions : {4, 8}) {
    FeSurface surface(SubdividedHexagon(3.0, subdivisions));
    FeSurface reference = surface;
    FeSurfaceFitOptions options;
    options.solver = FeSolver::kFangSprings;
    options.max_iterations = 400;
    const FeSurfaceFitResult fit =
        FitFeSurface(data.points, data.start_uv, options, surface, SetPlanarChart(surface));
    const FeSurfaceFitResult exact =
        FitFeSurface(data.points, data.start_uv, FeSurfaceFitOptions{}, reference, SetPlanarChart(reference));
    std::mt19937 check_rng(99);
    const BumpErrors errors = ErrorsToTheTrueBump(surface, 4000, check_rng);
    std::mt19937 check_rng2(99);
    const BumpErrors exact_errors = ErrorsToTheTrueBump(reference, 4000, check_rng2);
    gaps.push_back(fit.objective.back() / exact.objective.back() - 1.0);
    std::printf(
        "springs (plate on springs), %d triangles: %d iterations%s, objective %.8f (%.3f %% above SDM's), "
        "RMS "
        "%.5f, e_max %.5f, e_mean %.5f; SDM e_max %.5f, e_mean %.5f\n",
        surface.triangle_count(), fit.iterations, fit.converged ? " (converged)" : "", fit.objective.back(),
        100.0 * gaps.back(), fit.rms, errors.e_max, errors.e_mean, exact_errors.e_max, exact_errors.e_mean);
    EXPECT_TRUE(fit.converged);
    EXPECT_GE(gaps.back(), 0.0);
    for (std::size_t k = 1; k < fit.objective.size(); ++k) EXPECT_LT(fit.objective[k], fit.objective[k - 1]);
  }
  EXPECT_LT(gaps[1], gaps[0]);
}

TEST(FeSurfaceFit, FangsPlateAloneNeedsItsBoundaryHeldAndShortStepsWhenTheSpringsAreStiffer) {
  // The thesis' quadratic model (eq. P16 with K alone). Without boundary curves the plate can float along
  // the plane's normal and tilt at no energy: refused. With the boundary on curves: when the plate is stiff
  // (bending 1e-3) Fang's full steps converge; when the springs are stiffer (1e-5) the full step overshoots
  // and the line search shortens it; both end at the springs' equilibrium, whose objective is that of the
  // engine's PDM minimum to a fraction of a percent (the distributed loads are not the exact gradient).
  std::mt19937 rng(2024);
  const NoisyBump data = SampleNoisyBump(3000, 0.005, rng);
  {
    FeSurface surface(SubdividedHexagon(3.0, 4));
    FeSurfaceFitOptions options;
    options.solver = FeSolver::kFangSprings;
    options.spring_hessian = FeSpringHessian::kPlate;
    const std::vector<FeFixedDirection> boundary = SetPlanarChart(surface);
    try {
      FitFeSurface(data.points, data.start_uv, options, surface, boundary);
      ADD_FAILURE() << "the floating plate was not refused";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("does not hold the surface"), std::string::npos) << e.what();
    }
  }
  for (double bending : {1e-3, 1e-5}) {
    FeSurface surface(SubdividedHexagon(3.0, 4));
    SetPlanarChart(surface);
    const std::vector<FeLinearConstraint> rows = SetBoundaryConformity(surface, BumpBoundaryTrace);
    FeSurface reference = surface;
    FeSurfaceFitOptions options;
    options.solver = FeSolver::kFangSprings;
    options.spring_hessian = FeSpringHessian::kPlate;
    options.bending = bending;
    options.max_iterations = 100;
    const FeSurfaceFitResult fit = FitFeSurface(data.points, data.start_uv, options, surface, {}, rows);
    FeSurfaceFitOptions pdm;
    pdm.method = ErrorTerm::kPdm;
    pdm.bending = bending;
    pdm.max_iterations = 200;
    const FeSurfaceFitResult exact = FitFeSurface(data.points, data.start_uv, pdm, reference, {}, rows);
    const double shortest = *std::min_element(fit.step_lengths.begin(), fit.step_lengths.end());
    std::printf(
        "springs (plate alone), bending %g: %d iterations%s, shortest step %.4f, objective %.6f; PDM %d "
        "iterations%s, objective %.6f\n",
        bending, fit.iterations, fit.converged ? " (converged)" : "", shortest, fit.objective.back(),
        exact.iterations, exact.converged ? " (converged)" : "", exact.objective.back());
    EXPECT_TRUE(fit.converged);
    EXPECT_TRUE(exact.converged);
    if (bending == 1e-3) {
      EXPECT_EQ(shortest, 1.0);
    } else {
      EXPECT_LT(shortest, 1.0);
    }
    EXPECT_NEAR(fit.objective.back() / exact.objective.back(), 1.0, 0.01);
  }
}

}  // namespace
}  // namespace s2m
