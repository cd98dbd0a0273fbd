// Micro-benchmarks of issue 7 (Google Benchmark; docs/benchmarks.md): foot points per second per core for
// each model family, and normal-equation assembly throughput. One OpenMP thread throughout (per core: the
// engine's loops are parallel over points, so the rate on c cores is about c times this).
//
// Foot points are timed through the engine's own entry point ComputeFootPoints (fitting/foot_point.h), which
// is what every fit and registration calls per iteration:
//   - closed-form models (primitives, part faces): the closed-form foot point and the distance;
//   - Newton models cold: seed from the nearest model sample (k-d tree built per call), then Newton;
//   - Newton models warm: the previous iteration's foot points passed as `warm`, the points moved by a small
//     rigid motion (0.05 degree, 0.01 % of the size), as between two iterations of a converging fit;
//   - Newton models warm, trusted: the same with WarmStart::kTrusted (no sample search; rigid registration);
//   - Newton only ("refine"): RefineFootPoint from the previous parameter, i.e. the warm start without the
//     seed-tree search that ComputeFootPoints still does per point;
//   - squared distance field queries (no foot point at all: the O(1) approximant of d^2 of a precomputed
//   field).
// Usage: micro_benchmarks [Google Benchmark flags, e.g. --benchmark_format=csv --benchmark_filter=Spline]

#include <benchmark/benchmark.h>
#include <omp.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <cstdio>
#include <memory>
#include <random>
#include <string>

#include "fitting/bspline_models.h"
#include "fitting/foot_point.h"
#include "fitting/geometric_fit.h"
#include "fitting/initial_models.h"
#include "fitting/primitive_models.h"
#include "fitting/squared_distance_field.h"
#include "registration/rigid_step.h"
#include "synthetic/synthetic_cases.h"

using namespace s2m;

namespace {

constexpr Eigen::Index kPoints = 20000;

struct Family {
  std::unique_ptr<ParametricModel> model;
  Eigen::MatrixXd points;  // near the model
};

Eigen::MatrixXd WithNoise(const Eigen::Matrix3Xd& p, double sigma, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, sigma);
  Eigen::MatrixXd out = p;
  for (Eigen::Index i = 0; i < out.size(); ++i) out.data()[i] += gauss(rng);
  return out;
}

Eigen::Matrix3Xd Columns(const Eigen::Matrix3Xd& p, Eigen::Index count) {
  Eigen::Matrix3Xd out(3, count);
  for (Eigen::Index i = 0; i < count; ++i) out.col(i) = p.col(i % p.cols());
  return out;
}

// The reference models of synthetic/synthetic_cases.h (truth), with their views' points in the model frame.
Family FromCase(const std::string& name) {
  SyntheticCase c = MakeSyntheticCase(name);
  Eigen::Index total = 0;
  for (const auto& s : c.views.scans) total += s.cols();
  Eigen::Matrix3Xd all(3, total);
  Eigen::Index at = 0;
  for (std::size_t k = 0; k < c.views.scans.size(); ++k) {
    all.middleCols(at, c.views.scans[k].cols()) = c.views.model_T_scan_true[k].apply(c.views.scans[k]);
    at += c.views.scans[k].cols();
  }
  return {std::move(c.truth), Columns(all, kPoints)};
}

Family MakeFamily(const std::string& name) {
  if (name == "cylinder") {
    Cylinder cyl{Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(0.2, 0.3, 1).normalized(), 20.0};
    auto model = std::make_unique<CylinderModel>(cyl);
    const ParameterDomain d = model->domain();
    Eigen::Matrix3Xd p(3, kPoints);
    std::mt19937_64 rng(1);
    std::uniform_real_distribution<double> a(d.lo[0], d.hi[0]), h(-30, 30);
    LocalGeometry g;
    for (Eigen::Index i = 0; i < kPoints; ++i) {
      model->Evaluate({a(rng), h(rng), 0}, 0, g);
      p.col(i) = To3(g.point);
    }
    return {std::move(model), WithNoise(p, 0.05, 2)};
  }
  if (name == "sphere") {
    auto model = std::make_unique<SphereModel>(Sphere{Eigen::Vector3d(1, 2, 3), 25.0});
    Eigen::Matrix3Xd p(3, kPoints);
    std::mt19937_64 rng(3);
    std::normal_distribution<double> gauss(0, 1);
    for (Eigen::Index i = 0; i < kPoints; ++i)
      p.col(i) =
          Eigen::Vector3d(1, 2, 3) + 25.0 * Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
    return {std::move(model), WithNoise(p, 0.05, 4)};
  }
  if (name == "bspline-curve") {
    // A closed planar curve with 40 control points around a wobbly circle.
    Eigen::MatrixXd control(2, 40);
    for (int i = 0; i < 40; ++i) {
      const double a = 2 * M_PI * i / 40, r = 10 + 1.5 * std::sin(5 * a);
      control.col(i) << r * std::cos(a), r * std::sin(a);
    }
    auto model = std::make_unique<BSplineCurve>(UnitSpacedPeriodic(4, 40), control);
    const ParameterDomain d = model->domain();
    Eigen::MatrixXd p(2, kPoints);
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> t(d.lo[0], d.hi[0]);
    std::normal_distribution<double> gauss(0, 0.05);
    LocalGeometry g;
    for (Eigen::Index i = 0; i < kPoints; ++i) {
      model->Evaluate({t(rng), 0, 0}, 0, g);
      p.col(i) = g.point + Eigen::Vector2d(gauss(rng), gauss(rng));
    }
    return {std::move(model), p};
  }
  if (name == "bspline-surface") {
    const int n = 10;
    Eigen::Matrix3Xd control(3, n * n);
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        const double x = -50 + 100.0 * i / (n - 1), y = -50 + 100.0 * j / (n - 1);
        control.col(i * n + j) << x, y, 10 * std::sin(0.07 * x + 0.4) * std::cos(0.05 * y - 0.3);
      }
    auto model = std::make_unique<BSplineSurface>(UnitSpacedClamped(4, n), UnitSpacedClamped(4, n), control);
    const ParameterDomain d = model->domain();
    Eigen::Matrix3Xd p(3, kPoints);
    std::mt19937_64 rng(6);
    std::uniform_real_distribution<double> u(0.1, 0.9);
    LocalGeometry g;
    for (Eigen::Index i = 0; i < kPoints; ++i) {
      model->Evaluate({d.lo[0] + u(rng) * (d.hi[0] - d.lo[0]), d.lo[1] + u(rng) * (d.hi[1] - d.lo[1]), 0}, 0,
                      g);
      p.col(i) = To3(g.point);
    }
    return {std::move(model), WithNoise(p, 0.02, 7)};
  }
  if (name == "revolution") return FromCase("vase");
  if (name == "helical") return FromCase("helical");
  if (name == "spiral") return FromCase("spiral");
  if (name == "part") return FromCase("part");
  throw std::invalid_argument("unknown family " + name);
}

// The points moved by a small rigid motion about their centroid: the next iteration's points.
Eigen::MatrixXd Moved(const Eigen::MatrixXd& points) {
  const Eigen::Index s = points.rows();
  const Eigen::VectorXd centre = points.rowwise().mean();
  const double size = (points.rowwise().maxCoeff() - points.rowwise().minCoeff()).norm();
  Eigen::MatrixXd r = Eigen::MatrixXd::Identity(s, s);
  const double a = 0.05 * M_PI / 180;
  r.topLeftCorner(2, 2) << std::cos(a), -std::sin(a), std::sin(a), std::cos(a);
  Eigen::MatrixXd out = r * (points.colwise() - centre);
  out.colwise() += centre + Eigen::VectorXd::Constant(s, 1e-4 * size / std::sqrt(double(s)));
  return out;
}

void FootPointsCold(benchmark::State& state, const std::string& name) {
  const Family f = MakeFamily(name);
  std::vector<FootPoint> feet;
  for (auto _ : state) {
    ComputeFootPoints(*f.model, f.points, feet);
    benchmark::DoNotOptimize(feet.data());
  }
  state.SetItemsProcessed(state.iterations() * f.points.cols());
}

void FootPointsWarm(benchmark::State& state, const std::string& name) {
  const Family f = MakeFamily(name);
  std::vector<FootPoint> warm, feet;
  ComputeFootPoints(*f.model, f.points, warm);
  const Eigen::MatrixXd moved = Moved(f.points);
  for (auto _ : state) {
    ComputeFootPoints(*f.model, moved, feet, &warm);
    benchmark::DoNotOptimize(feet.data());
  }
  state.SetItemsProcessed(state.iterations() * f.points.cols());
}

// Warm with WarmStart::kTrusted: Newton straight from the previous parameter, no sample search (what a rigid
// registration to a fixed model uses, fitting/model_registration.cpp).
void FootPointsWarmTrusted(benchmark::State& state, const std::string& name) {
  const Family f = MakeFamily(name);
  std::vector<FootPoint> warm, feet;
  ComputeFootPoints(*f.model, f.points, warm);
  const Eigen::MatrixXd moved = Moved(f.points);
  for (auto _ : state) {
    ComputeFootPoints(*f.model, moved, feet, &warm, WarmStart::kTrusted);
    benchmark::DoNotOptimize(feet.data());
  }
  state.SetItemsProcessed(state.iterations() * f.points.cols());
}

void FootPointsRefineOnly(benchmark::State& state, const std::string& name) {
  const Family f = MakeFamily(name);
  std::vector<FootPoint> warm;
  ComputeFootPoints(*f.model, f.points, warm);
  const Eigen::MatrixXd moved = Moved(f.points);
  const ParameterDomain d = f.model->domain();
  LocalGeometry g;
  for (auto _ : state) {
    double sum = 0;
    for (Eigen::Index j = 0; j < moved.cols(); ++j)
      sum +=
          RefineFootPoint(*f.model, d, VecS(moved.col(j)), warm[static_cast<std::size_t>(j)].t, g).distance;
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * f.points.cols());
}

// Assembly of the 6x6 rigid normal equations (registration/rigid_step.h) from per-point SDM constraints:
// the model-registration step's accumulation, excluding the model evaluation. The constraints are given as
// SDM's frame (a unit normal with weight 1, two tangents with curvature weights), as a field query returns
// them.
struct SdmFrameConstraint {
  Eigen::Vector3d x, residual, normal, tangent1, tangent2;
  double beta1 = 0.0, beta2 = 0.0;
};

std::vector<SdmFrameConstraint> RandomSdmConstraints() {
  std::mt19937_64 rng(9);
  std::normal_distribution<double> gauss(0, 1);
  std::uniform_real_distribution<double> unit(0, 1);
  std::vector<SdmFrameConstraint> constraints(4096);
  for (SdmFrameConstraint& c : constraints) {
    c.x = Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
    c.residual = 0.01 * Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
    c.normal = Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
    c.tangent1 = c.normal.unitOrthogonal();
    c.tangent2 = c.normal.cross(c.tangent1);
    c.beta1 = unit(rng);
    c.beta2 = unit(rng);
  }
  return constraints;
}

// M = n n^T + beta1 T1 T1^T + beta2 T2 T2^T formed, then added by its symmetric blocks (the field pass's
// SDM).
void RigidAssembly(benchmark::State& state) {
  const std::vector<SdmFrameConstraint> constraints = RandomSdmConstraints();
  for (auto _ : state) {
    RigidNormalEquations eq;
    for (const SdmFrameConstraint& c : constraints) {
      const Eigen::Matrix3d m = c.normal * c.normal.transpose() +
                                c.beta1 * c.tangent1 * c.tangent1.transpose() +
                                c.beta2 * c.tangent2 * c.tangent2.transpose();
      eq.AddSymmetric(c.x, m, 1e-4, c.residual);
    }
    benchmark::DoNotOptimize(eq.H.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<long long>(constraints.size()));
}

// The same constraints as three rank-one terms (the field pass's SDM before AddSymmetric).
void RigidAssemblyByDirections(benchmark::State& state) {
  const std::vector<SdmFrameConstraint> constraints = RandomSdmConstraints();
  for (auto _ : state) {
    RigidNormalEquations eq;
    for (const SdmFrameConstraint& c : constraints) {
      eq.AddDirection(c.x, c.normal, 1e-4, c.normal.dot(c.residual));
      eq.AddDirection(c.x, c.tangent1, 1e-4 * c.beta1, c.tangent1.dot(c.residual));
      eq.AddDirection(c.x, c.tangent2, 1e-4 * c.beta2, c.tangent2.dot(c.residual));
    }
    benchmark::DoNotOptimize(eq.H.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<long long>(constraints.size()));
}

// TDM's one rank-one term per point, for the SDM/TDM ratio of the assembly.
void RigidAssemblyTdm(benchmark::State& state) {
  const std::vector<SdmFrameConstraint> constraints = RandomSdmConstraints();
  for (auto _ : state) {
    RigidNormalEquations eq;
    for (const SdmFrameConstraint& c : constraints)
      eq.AddDirection(c.x, c.normal, 1e-4, c.normal.dot(c.residual));
    benchmark::DoNotOptimize(eq.H.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<long long>(constraints.size()));
}

// The step of scan-to-scan registration (registration/scan_to_scan.cpp): the dense 6K x 6K system of K
// views' poses factored and solved once per sweep (argument: K). Its cost against a sweep's pairs is the
// reason there is no sparse pose graph (docs/registration.md).
void ScanToScanDenseStep(benchmark::State& state) {
  const auto n = static_cast<Eigen::Index>(6 * state.range(0));
  std::mt19937_64 rng(7);
  std::normal_distribution<double> gauss(0.0, 1.0);
  Eigen::MatrixXd a(n, n);
  for (Eigen::Index i = 0; i < a.size(); ++i) a.data()[i] = gauss(rng);
  const Eigen::MatrixXd H = a * a.transpose() + static_cast<double>(n) * Eigen::MatrixXd::Identity(n, n);
  Eigen::VectorXd g(n);
  for (Eigen::Index i = 0; i < n; ++i) g[i] = gauss(rng);
  for (auto _ : state) {
    const Eigen::VectorXd v = H.ldlt().solve(-g);
    benchmark::DoNotOptimize(v.data());
  }
  // The rate is in views' poses solved per second, like every other benchmark's items (the CSV's rate
  // column).
  state.SetItemsProcessed(state.iterations() * state.range(0));
}

// Per point of a model registration step: model evaluation with second derivatives, principal frame, SDM
// matrix and accumulation (fitting/model_registration.cpp's loop), on the B-spline surface at its foot
// points.
void RegistrationAssemblyOnSurface(benchmark::State& state) {
  const Family f = MakeFamily("bspline-surface");
  std::vector<FootPoint> feet;
  ComputeFootPoints(*f.model, f.points, feet);
  LocalGeometry g;
  for (auto _ : state) {
    RigidNormalEquations eq;
    for (Eigen::Index j = 0; j < f.points.cols(); ++j) {
      f.model->Evaluate(feet[static_cast<std::size_t>(j)].t, 2, g);
      const Eigen::Vector3d x = f.points.col(j);
      const PrincipalFrame frame = ComputePrincipalFrame(g, x);
      eq.Add({x, To3(g.point), ErrorMatrix(ErrorTerm::kSdm, frame, 3), 1.0});
    }
    benchmark::DoNotOptimize(eq.H.data());
  }
  state.SetItemsProcessed(state.iterations() * f.points.cols());
}

// Fixed work for instruction counting (`micro_benchmarks --probe FAMILY cold|warm|trusted REPETITIONS` under
// valgrind
// --tool=callgrind --toggle-collect='*ProbeFootPoints*'): Google Benchmark picks its own repetition counts,
// so its loops cannot be compared by instruction totals.
__attribute__((noinline)) double ProbeFootPoints(const Family& f, const Eigen::MatrixXd& points,
                                                 const std::vector<FootPoint>* warm, WarmStart mode,
                                                 int repetitions) {
  std::vector<FootPoint> feet;
  double sum = 0.0;
  for (int r = 0; r < repetitions; ++r) {
    ComputeFootPoints(*f.model, points, feet, warm, mode);
    sum += feet.back().distance;
  }
  return sum;
}

int Probe(const std::string& name, const std::string& mode, int repetitions) {
  const Family f = MakeFamily(name);
  std::vector<FootPoint> previous;
  ComputeFootPoints(*f.model, f.points, previous);
  const Eigen::MatrixXd moved = Moved(f.points);
  const bool warm = mode == "warm" || mode == "trusted";
  const double sum =
      ProbeFootPoints(f, warm ? moved : f.points, warm ? &previous : nullptr,
                      mode == "trusted" ? WarmStart::kTrusted : WarmStart::kVerified, repetitions);
  std::printf("%s %s: %d x %ld points, checksum %.17g\n", name.c_str(), mode.c_str(), repetitions,
              static_cast<long>(f.points.cols()), sum);
  return 0;
}

}  // namespace

// Queries of the squared distance field (fitting/squared_distance_field.h, cells of 1 mm, band 6 mm, over the
// points' bounding box grown by the band): the approximate foot, its principal frame and d^2, per point. The
// field is built once outside the timing (its build time is in the label).
void SquaredDistanceFieldQueries(benchmark::State& state, const std::string& name) {
  const Family f = MakeFamily(name);
  SquaredDistanceField::Options o;
  o.cell_size = 1.0;
  o.band = 6.0;
  const Eigen::Matrix3Xd points = f.points;
  o.box_min = points.rowwise().minCoeff().array() - o.band;
  o.box_max = points.rowwise().maxCoeff().array() + o.band;
  const SquaredDistanceField field(*f.model, o);
  SquaredDistanceField::Answer answer;
  double answered = 0.0;
  for (auto _ : state) {
    answered = 0.0;
    for (Eigen::Index j = 0; j < points.cols(); ++j)
      answered += field.Query(points.col(j), answer) ? 1.0 : 0.0;
    benchmark::DoNotOptimize(answer.squared_distance);
  }
  state.SetItemsProcessed(state.iterations() * points.cols());
  // A label, not user counters: Google Benchmark's CSV reporter aborts when a counter appears in some rows
  // only (the other benchmarks have none).
  char label[96];
  std::snprintf(label, sizeof label, "answered %.4f, %lld cells built in %.3f s",
                answered / static_cast<double>(points.cols()), static_cast<long long>(field.cell_count()),
                field.build_seconds());
  state.SetLabel(label);
}

BENCHMARK_CAPTURE(FootPointsCold, cylinder, std::string("cylinder"));
BENCHMARK_CAPTURE(FootPointsCold, sphere, std::string("sphere"));
BENCHMARK_CAPTURE(FootPointsCold, part_faces, std::string("part"));
BENCHMARK_CAPTURE(FootPointsCold, bspline_curve, std::string("bspline-curve"));
BENCHMARK_CAPTURE(FootPointsWarm, bspline_curve, std::string("bspline-curve"));
BENCHMARK_CAPTURE(FootPointsWarmTrusted, bspline_curve, std::string("bspline-curve"));
BENCHMARK_CAPTURE(FootPointsRefineOnly, bspline_curve, std::string("bspline-curve"));
BENCHMARK_CAPTURE(FootPointsCold, bspline_surface, std::string("bspline-surface"));
BENCHMARK_CAPTURE(FootPointsWarm, bspline_surface, std::string("bspline-surface"));
BENCHMARK_CAPTURE(FootPointsWarmTrusted, bspline_surface, std::string("bspline-surface"));
BENCHMARK_CAPTURE(FootPointsRefineOnly, bspline_surface, std::string("bspline-surface"));
BENCHMARK_CAPTURE(FootPointsCold, revolution, std::string("revolution"));
BENCHMARK_CAPTURE(FootPointsWarm, revolution, std::string("revolution"));
BENCHMARK_CAPTURE(FootPointsWarmTrusted, revolution, std::string("revolution"));
BENCHMARK_CAPTURE(FootPointsRefineOnly, revolution, std::string("revolution"));
BENCHMARK_CAPTURE(FootPointsCold, helical, std::string("helical"));
BENCHMARK_CAPTURE(FootPointsWarm, helical, std::string("helical"));
BENCHMARK_CAPTURE(FootPointsCold, spiral, std::string("spiral"));
BENCHMARK_CAPTURE(FootPointsWarm, spiral, std::string("spiral"));
BENCHMARK(RigidAssembly);
BENCHMARK(RigidAssemblyByDirections);
BENCHMARK(RigidAssemblyTdm);
BENCHMARK(RegistrationAssemblyOnSurface);
BENCHMARK(ScanToScanDenseStep)->Arg(10)->Arg(32)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(SquaredDistanceFieldQueries, bspline_surface, std::string("bspline-surface"));
BENCHMARK_CAPTURE(SquaredDistanceFieldQueries, cylinder, std::string("cylinder"));

int main(int argc, char** argv) {
  omp_set_num_threads(1);  // per core
  if (argc == 5 && std::string(argv[1]) == "--probe") return Probe(argv[2], argv[3], std::atoi(argv[4]));
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
