// Fair surfaces from scattered noisy points (docs/fe-surfaces.md section 7): our finite-element surface
// (Fang's 12-dof triangles, SDM) against our tensor-product B-spline SDM fit and SciPy's
// CloughTocher2DInterpolator (a C1 interpolant of the points as a height field; run by
// bench/clough_tocher_baseline.py when python3 with SciPy is found), on the same points. Every surface is
// measured by the same code on the same grid of (x, y): its height there (parametric surfaces: the point
// whose projection is (x, y), by Newton steps), the error to the true surface (vertical, an upper bound of
// the distance), and the fairness as the integral of |grad H|^2 over the grid (H the mean curvature of the
// height field, both by central differences). Prints a markdown table; `build/bench/fe_surfaces [WORD]`
// runs only the cases whose name contains WORD.

#include <Eigen/LU>
#include <Eigen/SparseCholesky>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "fitting/bspline_models.h"
#include "fitting/domain_mesh.h"
#include "fitting/fe_surface.h"
#include "fitting/fe_surface_fit.h"
#include "fitting/foot_point.h"
#include "fitting/geometric_fit.h"
#include "fitting/initial_models.h"

namespace s2m {
namespace {

using Clock = std::chrono::steady_clock;

std::string Short(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", v);
  return text;
}
double Seconds(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

constexpr double kRadius = 3.0;  // the hexagon's circumradius
constexpr double kStep = 0.05;   // the measuring grid's spacing
constexpr double kInset = 2.8;   // the grid stays inside the hexagon of this circumradius

bool InsideHexagon(double x, double y, double radius) {
  for (int k = 0; k < 6; ++k) {
    const double a = (k + 0.5) * M_PI / 3.0;
    if (x * std::cos(a) + y * std::sin(a) > radius * std::cos(M_PI / 6.0)) return false;
  }
  return true;
}

struct Case {
  std::string name;
  std::function<double(double, double)> height;
  int points = 3000;
  double noise = 0.005;
};

// The measuring grid: nodes (i, j) at (i, j) * kStep, kept inside the inset hexagon.
struct Grid {
  int half = static_cast<int>(std::floor(kInset / kStep));
  int side() const { return 2 * half + 1; }
  double coordinate(int i) const { return (i - half) * kStep; }
  bool inside(int i, int j) const { return InsideHexagon(coordinate(i), coordinate(j), kInset); }
};

// A height on every grid node (NaN where a method has none).
using Heights = std::vector<double>;

struct Row {
  std::string method;
  double e_max = 0.0, e_mean = 0.0, fairness = 0.0, seconds = 0.0;
  long long dofs = 0;
  std::string note;
};

// Mean curvature of a height field by central differences, then the integral of |grad H|^2 over the nodes
// where every difference is defined.
double Fairness(const Grid& g, const Heights& z) {
  const int n = g.side();
  const auto at = [&](int i, int j) { return z[static_cast<std::size_t>(i * n + j)]; };
  std::vector<double> h(z.size(), std::nan(""));
  for (int i = 1; i + 1 < n; ++i)
    for (int j = 1; j + 1 < n; ++j) {
      const double zx = (at(i + 1, j) - at(i - 1, j)) / (2 * kStep),
                   zy = (at(i, j + 1) - at(i, j - 1)) / (2 * kStep);
      const double zxx = (at(i + 1, j) - 2 * at(i, j) + at(i - 1, j)) / (kStep * kStep);
      const double zyy = (at(i, j + 1) - 2 * at(i, j) + at(i, j - 1)) / (kStep * kStep);
      const double zxy =
          (at(i + 1, j + 1) - at(i + 1, j - 1) - at(i - 1, j + 1) + at(i - 1, j - 1)) / (4 * kStep * kStep);
      const double w = 1 + zx * zx + zy * zy;
      h[static_cast<std::size_t>(i * n + j)] =
          ((1 + zy * zy) * zxx - 2 * zx * zy * zxy + (1 + zx * zx) * zyy) / (2 * std::pow(w, 1.5));
    }
  double sum = 0.0;
  for (int i = 2; i + 2 < n; ++i)
    for (int j = 2; j + 2 < n; ++j) {
      const double hx =
          (h[static_cast<std::size_t>((i + 1) * n + j)] - h[static_cast<std::size_t>((i - 1) * n + j)]) /
          (2 * kStep);
      const double hy =
          (h[static_cast<std::size_t>(i * n + j + 1)] - h[static_cast<std::size_t>(i * n + j - 1)]) /
          (2 * kStep);
      if (std::isfinite(hx) && std::isfinite(hy)) sum += (hx * hx + hy * hy) * kStep * kStep;
    }
  return sum;
}

void Measure(const Grid& g, const Case& c, const Heights& z, Row& row) {
  double sum = 0.0;
  int count = 0, missing = 0;
  for (int i = 0; i < g.side(); ++i)
    for (int j = 0; j < g.side(); ++j) {
      if (!g.inside(i, j)) continue;
      const double v = z[static_cast<std::size_t>(i * g.side() + j)];
      if (!std::isfinite(v)) {
        ++missing;
        continue;
      }
      const double e = std::abs(v - c.height(g.coordinate(i), g.coordinate(j)));
      row.e_max = std::max(row.e_max, e);
      sum += e;
      ++count;
    }
  row.e_mean = count > 0 ? sum / count : std::nan("");
  row.fairness = Fairness(g, z);
  if (missing > 0) row.note += std::to_string(missing) + " grid nodes without a height; ";
}

// The height of a parametric surface above (x, y): Newton steps on the parameter for w_xy(t) = (x, y).
template <typename Evaluate>  // (t, point&, d1&) -> bool
double HeightAbove(double x, double y, Eigen::Vector2d t, const Evaluate& evaluate) {
  Eigen::Vector3d p;
  Eigen::Matrix<double, 3, 2> d1;
  for (int k = 0; k < 30; ++k) {
    if (!evaluate(t, p, d1)) return std::nan("");
    const Eigen::Vector2d r(x - p.x(), y - p.y());
    if (r.norm() < 1e-12) break;
    t += d1.topRows<2>().lu().solve(r);
  }
  return evaluate(t, p, d1) && std::hypot(x - p.x(), y - p.y()) < 1e-8 ? p.z() : std::nan("");
}

struct Data {
  Eigen::Matrix3Xd points;
};

Data Sample(const Case& c, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> coordinate(-kRadius, kRadius);
  std::normal_distribution<double> gauss(0.0, c.noise);
  Data d;
  d.points.resize(3, c.points);
  for (int i = 0; i < c.points;) {
    const double x = coordinate(rng), y = coordinate(rng);
    if (!InsideHexagon(x, y, kRadius)) continue;
    d.points.col(i) =
        Eigen::Vector3d(x, y, c.height(x, y)) + Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
    ++i;
  }
  return d;
}

Row FeSurfaceRow(const Case& c, const Data& d, const Grid& g, double edge, double jump,
                 bool springs = false) {
  Row row;
  row.method = std::string(springs ? "FE surface, Fang's springs" : "FE surface, SDM") + ", edge " +
               Short(edge) + (jump > 0 ? ", C2 jump " + Short(jump) : "");
  const auto start = Clock::now();
  DomainPolygon polygon;
  polygon.outer.resize(2, 6);
  for (int k = 0; k < 6; ++k)
    polygon.outer.col(k) = kRadius * Eigen::Vector2d(std::cos(k * M_PI / 3), std::sin(k * M_PI / 3));
  DomainMeshOptions mesh_options;
  mesh_options.max_edge = edge;
  const DomainMesh domain = MeshDomain(polygon, mesh_options);
  FeMesh mesh;
  mesh.uv = domain.vertices;
  for (int t = 0; t < domain.triangle_count(); ++t)
    mesh.triangles.push_back({domain.triangles(0, t), domain.triangles(1, t), domain.triangles(2, t)});
  FeSurface surface(mesh);
  const std::vector<FeFixedDirection> pinned = SetPlanarChart(surface);
  FeSurfaceFitOptions options;
  options.jump = jump;
  if (springs) {  // as `fit --model fe-surface --method spring`
    options.solver = FeSolver::kFangSprings;
    options.max_iterations = 400;
  }
  const FeSurfaceFitResult fit = FitFeSurface(d.points, d.points.topRows<2>(), options, surface, pinned);
  row.seconds = Seconds(start);
  row.dofs = 3LL * surface.dof_count();
  row.note = std::to_string(surface.triangle_count()) + " triangles, " + std::to_string(fit.iterations) +
             " iterations; ";
  Heights z(static_cast<std::size_t>(g.side() * g.side()), std::nan(""));
  FeSurfacePoint walker;
  for (int i = 0; i < g.side(); ++i)
    for (int j = 0; j < g.side(); ++j) {
      const double x = g.coordinate(i), y = g.coordinate(j);
      if (!InsideHexagon(x, y, kRadius - 1e-9)) continue;
      z[static_cast<std::size_t>(i * g.side() + j)] =
          HeightAbove(x, y, Eigen::Vector2d(x, y),
                      [&](const Eigen::Vector2d& t, Eigen::Vector3d& p, Eigen::Matrix<double, 3, 2>& d1) {
                        if (!surface.Locate(t, walker)) return false;
                        const FeSurfaceGeometry geometry = surface.Evaluate(walker);
                        p = geometry.point;
                        d1 = geometry.d1;
                        return true;
                      });
    }
  Measure(g, c, z, row);
  return row;
}

Row BSplineRow(const Case& c, const Data& d, const Grid& g, int control) {
  Row row;
  row.method =
      "B-spline surface, SDM, " + std::to_string(control) + "x" + std::to_string(control) + " control points";
  const auto start = Clock::now();
  BSplineSurface surface =
      InitialSurfaceByProjection(d.points, control, control, 4, SurfaceProjection::kPlane);
  GeometricFitOptions options;
  options.fairness.bending = 1e-3;  // `scan2model fit --model bspline-surface`'s default
  const GeometricFitResult fit = FitModel(surface, d.points, options);
  row.seconds = Seconds(start);
  row.dofs = surface.num_parameters();
  row.note = std::to_string(fit.iterations) + " iterations; ";
  Heights z(static_cast<std::size_t>(g.side() * g.side()), std::nan(""));
  const ParameterDomain domain = surface.domain();
  for (int i = 0; i < g.side(); ++i)
    for (int j = 0; j < g.side(); ++j) {
      const double x = g.coordinate(i), y = g.coordinate(j);
      if (!g.inside(i, j)) continue;
      Eigen::Matrix3Xd truth(3, 1);
      truth.col(0) = Eigen::Vector3d(x, y, c.height(x, y));
      std::vector<FootPoint> feet;
      ComputeFootPoints(surface, truth, feet);
      LocalGeometry geometry;
      z[static_cast<std::size_t>(i * g.side() + j)] = HeightAbove(
          x, y, Eigen::Vector2d(feet[0].t[0], feet[0].t[1]),
          [&](const Eigen::Vector2d& t, Eigen::Vector3d& p, Eigen::Matrix<double, 3, 2>& d1) {
            if (t.x() < domain.lo[0] || t.x() > domain.hi[0] || t.y() < domain.lo[1] || t.y() > domain.hi[1])
              return false;
            surface.Evaluate({t.x(), t.y(), 0.0}, 1, geometry);
            p = geometry.point.head<3>();
            d1 = geometry.d1.topLeftCorner<3, 2>();
            return true;
          });
    }
  Measure(g, c, z, row);
  return row;
}

std::optional<Row> CloughTocherRow(const Case& c, const Data& d, const Grid& g, const std::string& script) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "s2m_fe_surfaces_bench";
  std::filesystem::create_directories(dir);
  {
    std::ofstream points(dir / "points.txt"), grid(dir / "grid.txt");
    points.precision(17);
    grid.precision(17);
    for (Eigen::Index i = 0; i < d.points.cols(); ++i)
      points << d.points(0, i) << " " << d.points(1, i) << " " << d.points(2, i) << "\n";
    for (int i = 0; i < g.side(); ++i)
      for (int j = 0; j < g.side(); ++j) grid << g.coordinate(i) << " " << g.coordinate(j) << "\n";
  }
  const std::string command = std::string(S2M_PYTHON) + " '" + script + "' '" +
                              (dir / "points.txt").string() + "' '" + (dir / "grid.txt").string() + "' '" +
                              (dir / "z.txt").string() + "' > '" + (dir / "seconds.txt").string() +
                              "' 2>/dev/null";
  if (std::system(command.c_str()) != 0) return std::nullopt;
  Row row;
  row.method = "SciPy CloughTocher2DInterpolator (height field)";
  std::ifstream(dir / "seconds.txt") >> row.seconds;
  row.dofs = 3LL * d.points.cols();  // value and gradient at every data point
  Heights z;
  std::ifstream in(dir / "z.txt");
  std::string line;
  while (std::getline(in, line)) z.push_back(line == "nan" ? std::nan("") : std::stod(line));
  if (z.size() != static_cast<std::size_t>(g.side() * g.side())) return std::nullopt;
  for (int i = 0; i < g.side(); ++i)
    for (int j = 0; j < g.side(); ++j)
      if (!g.inside(i, j)) z[static_cast<std::size_t>(i * g.side() + j)] = std::nan("");
  Measure(g, c, z, row);
  row.note += "interpolates the noisy points; ";
  return row;
}

// Fang's question (thesis sec. 5.4): number the nodes for a small bandwidth (Gibbs-Poole-Stockmeyer root,
// Cuthill-McKee levels: fitting/domain_mesh.h) and solve a banded system, or leave the ordering to a sparse
// Cholesky (Eigen's SimplicialLDLT with its approximate minimum degree ordering). The matrix is one
// coordinate's normal matrix of the first step of a fit, K + sum_i N_i^T N_i (docs/fe-surfaces.md eq. P7 with
// PDM), on the hexagon meshed at three sizes; the factorization's fill (non-zeros of L) and its time (median
// of 7) for: AMD on our dof order, no reordering on the GPS/Cuthill-McKee numbering (the band Fang solves),
// and no reordering on the natural order (small meshes only: its band is nearly the whole matrix).
void SolverOrderings() {
  std::printf("\n### Sparse Cholesky orderings of the normal matrix (docs/fe-surfaces.md section 7)\n\n");
  std::printf(
      "| triangles | dofs | ordering | dof bandwidth | non-zeros of L | factorization ms "
      "|\n|---:|---:|---|---:|---:|---:|\n");
  const Case c{"gaussian", [](double x, double y) { return std::exp(-0.5 * (x * x + y * y)); }};
  const Data data = Sample(c, 17);
  for (double edge : {0.75, 0.4, 0.25}) {
    DomainPolygon polygon;
    polygon.outer.resize(2, 6);
    for (int k = 0; k < 6; ++k)
      polygon.outer.col(k) = kRadius * Eigen::Vector2d(std::cos(k * M_PI / 3), std::sin(k * M_PI / 3));
    DomainMeshOptions mesh_options;
    mesh_options.max_edge = edge;
    const DomainMesh domain = MeshDomain(polygon, mesh_options);
    FeMesh mesh;
    mesh.uv = domain.vertices;
    for (int t = 0; t < domain.triangle_count(); ++t)
      mesh.triangles.push_back({domain.triangles(0, t), domain.triangles(1, t), domain.triangles(2, t)});
    const FeSurface surface(mesh);
    FairnessWeights weights;
    weights.bending = 1e-7 * static_cast<double>(data.points.cols()) * std::pow(2 * kRadius, 4) /
                      (1.5 * std::sqrt(3.0) * kRadius * kRadius);
    Eigen::SparseMatrix<double> a = surface.EnergyMatrix(weights);
    std::vector<Eigen::Triplet<double>> triplets;
    FeSurfacePoint walker;
    for (Eigen::Index i = 0; i < data.points.cols(); ++i) {
      surface.Locate(data.points.col(i).head<2>(), walker);
      const TriangleShape shape = surface.element(walker.triangle).Evaluate(walker.barycentric);
      const auto& dofs = surface.element_dofs(walker.triangle);
      for (int p = 0; p < 12; ++p)
        for (int q = 0; q < 12; ++q)
          triplets.emplace_back(dofs[static_cast<std::size_t>(p)], dofs[static_cast<std::size_t>(q)],
                                shape.value(p) * shape.value(q));
    }
    Eigen::SparseMatrix<double> data_term(a.rows(), a.cols());
    data_term.setFromTriplets(triplets.begin(), triplets.end());
    a += data_term;
    // The dof permutation of the node numbering: node by node, 3 dofs per vertex, 1 per mid-edge node.
    // (The mesh and the surface number their edges independently: matched by their end vertices.)
    std::map<std::pair<int, int>, int> fe_edge;
    for (int e = 0; e < surface.edge_count(); ++e)
      fe_edge[std::minmax(surface.edge(e)[0], surface.edge(e)[1])] = e;
    Eigen::VectorXi dof_of(a.rows());
    int next = 0;
    for (Eigen::Index k = 0; k < domain.numbering.order.size(); ++k) {
      const int node = domain.numbering.order(k);
      if (node < domain.vertex_count())
        for (int which = 0; which < 3; ++which) dof_of(surface.vertex_dof(node, which)) = next++;
      else
        dof_of(surface.edge_dof(fe_edge.at(std::minmax(domain.edges(0, node - domain.vertex_count()),
                                                       domain.edges(1, node - domain.vertex_count()))))) =
            next++;
    }
    Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> permutation(dof_of);
    const Eigen::SparseMatrix<double> banded = permutation * a * permutation.transpose();
    const auto bandwidth = [](const Eigen::SparseMatrix<double>& m) {
      long long b = 0;
      for (int col = 0; col < m.outerSize(); ++col)
        for (Eigen::SparseMatrix<double>::InnerIterator it(m, col); it; ++it)
          b = std::max<long long>(b, std::abs(it.row() - col));
      return b;
    };
    const auto time = [](auto& solver, const Eigen::SparseMatrix<double>& m, long long& fill) {
      std::vector<double> ms;
      for (int r = 0; r < 7; ++r) {
        const auto start = Clock::now();
        solver.compute(m);
        ms.push_back(1e3 * Seconds(start));
      }
      std::sort(ms.begin(), ms.end());
      fill = solver.matrixL().nestedExpression().nonZeros();
      return ms[3];
    };
    long long fill = 0;
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> amd;
    const double t_amd = time(amd, a, fill);
    std::printf("| %d | %lld | AMD (sparse Cholesky) | %lld | %lld | %.2f |\n", surface.triangle_count(),
                static_cast<long long>(a.rows()), bandwidth(a), fill, t_amd);
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::NaturalOrdering<int>> natural;
    const double t_band = time(natural, banded, fill);
    std::printf("| %d | %lld | GPS + Cuthill-McKee, no reordering (banded) | %lld | %lld | %.2f |\n",
                surface.triangle_count(), static_cast<long long>(a.rows()), bandwidth(banded), fill, t_band);
    if (a.rows() > 3000) continue;  // the natural order's band is nearly the whole matrix: too slow to time
    const double t_natural = time(natural, a, fill);
    std::printf("| %d | %lld | natural, no reordering | %lld | %lld | %.2f |\n", surface.triangle_count(),
                static_cast<long long>(a.rows()), bandwidth(a), fill, t_natural);
  }
}

}  // namespace
}  // namespace s2m

int main(int argc, char** argv) {
  using namespace s2m;
  std::setvbuf(stdout, nullptr, _IOLBF, 0);  // rows appear as they are measured
  const std::string only = argc > 1 ? argv[1] : "";
  const std::string script = std::string(S2M_BENCH_DIR) + "/clough_tocher_baseline.py";
  const std::vector<Case> cases = {
      {"gaussian", [](double x, double y) { return std::exp(-0.5 * (x * x + y * y)); }},
      {"ripple", [](double x, double y) { return 0.25 * std::sin(1.3 * x) * std::cos(1.1 * y); }},
  };
  const Grid grid;
  if (only.empty() || only == "orderings") SolverOrderings();
  for (const Case& c : cases) {
    if (!only.empty() && c.name.find(only) == std::string::npos) continue;
    const Data data = Sample(c, 17);
    std::vector<Row> rows;
    Row truth;
    truth.method = "true surface";
    Heights z(static_cast<std::size_t>(grid.side() * grid.side()), std::nan(""));
    for (int i = 0; i < grid.side(); ++i)
      for (int j = 0; j < grid.side(); ++j)
        if (grid.inside(i, j))
          z[static_cast<std::size_t>(i * grid.side() + j)] = c.height(grid.coordinate(i), grid.coordinate(j));
    Measure(grid, c, z, truth);
    rows.push_back(truth);
    rows.push_back(FeSurfaceRow(c, data, grid, 0.75, 0.0));
    rows.push_back(FeSurfaceRow(c, data, grid, 0.75, 1e-8));
    rows.push_back(FeSurfaceRow(c, data, grid, 0.75, 1e-6));
    rows.push_back(FeSurfaceRow(c, data, grid, 0.5, 0.0));
    rows.push_back(FeSurfaceRow(c, data, grid, 0.75, 0.0, true));
    rows.push_back(FeSurfaceRow(c, data, grid, 0.5, 0.0, true));
    rows.push_back(BSplineRow(c, data, grid, 12));
    rows.push_back(BSplineRow(c, data, grid, 18));
    if (std::optional<Row> ct = CloughTocherRow(c, data, grid, script))
      rows.push_back(*ct);
    else
      std::printf("(SciPy not found: no Clough-Tocher row)\n");
    std::printf("\n### %s: %d points, noise %.3f, hexagon of circumradius %.0f\n\n", c.name.c_str(), c.points,
                c.noise, kRadius);
    std::printf(
        "| method | e_max | e_mean | integral of abs(grad H)^2 | scalar dofs | seconds | note "
        "|\n|---|---:|---:|---:|---:|---:|---|\n");
    for (const Row& r : rows)
      std::printf("| %s | %.5f | %.5f | %.4f | %lld | %.3f | %s |\n", r.method.c_str(), r.e_max, r.e_mean,
                  r.fairness, r.dofs, r.seconds, r.note.c_str());
  }
  return 0;
}
