// `scan2model fit --model fe-surface`: a fair triangular finite-element surface (docs/fe-surfaces.md) fitted
// to a patch of points parametrized by its projection onto the points' best plane or its development onto
// their best cylinder.

#include "fitting/fe_surface_fit.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <optional>
#include <sstream>

#include "acquisition/format_error.h"
#include "acquisition/point_cloud_io.h"
#include "fitting/domain_mesh.h"
#include "fitting/fe_surface.h"
#include "fitting/fe_surface_model.h"
#include "fitting/foot_point.h"
#include "fitting/noise_estimate.h"
#include "fitting/primitive_fit.h"
#include "fitting/primitives.h"
#include "fitting/surface_interrogation.h"
#include "pipeline/domain_measures.h"
#include "pipeline/exit_code.h"
#include "pipeline/fit_options.h"
#include "pipeline/output.h"
#include "pipeline/patch_boundary.h"

namespace s2m::pipeline {
namespace {

// The points' best plane: origin at the centroid, in-plane axes along the two largest principal directions,
// the normal along the smallest (right-handed).
struct PlaneFrame {
  Eigen::Vector3d origin;
  Eigen::Matrix3d axes;    // columns: u, v, normal
  Eigen::Vector3d spread;  // standard deviations along the three axes
};

PlaneFrame FitPlaneFrame(const Eigen::Matrix3Xd& points) {
  PlaneFrame f;
  f.origin = points.rowwise().mean();
  const Eigen::Matrix3Xd centred = points.colwise() - f.origin;
  const Eigen::Matrix3d scatter = centred * centred.transpose() / static_cast<double>(points.cols());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter);  // ascending eigenvalues
  f.axes.col(0) = solver.eigenvectors().col(2);
  f.axes.col(1) = solver.eigenvectors().col(1);
  f.axes.col(2) = f.axes.col(0).cross(f.axes.col(1));
  f.spread = solver.eigenvalues().reverse().cwiseMax(0.0).cwiseSqrt();
  return f;
}

// The chart the patch is parametrized over (docs/fe-surfaces.md section 6): a right-handed frame of the data
// (origin, axes) and, for a cylinder, its radius about the frame's z axis.
struct Chart {
  bool cylinder = false;
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();  // columns: the frame's x, y, z in data coordinates
  double radius = 0.0;
  double angular_gap = 0.0;  // cylinder: the largest angle round the axis without points (radians)

  Eigen::Matrix3Xd ToLocal(const Eigen::Matrix3Xd& points) const {
    return axes.transpose() * (points.colwise() - origin);
  }
  // (u, v) of points in the frame: the projection (x, y), or the development (R atan2(y, x), z) with the
  // angle's cut opposite the patch.
  Eigen::Matrix2Xd Parameters(const Eigen::Matrix3Xd& local) const {
    if (!cylinder) return local.topRows<2>();
    Eigen::Matrix2Xd uv(2, local.cols());
    for (Eigen::Index i = 0; i < local.cols(); ++i)
      uv.col(i) = Eigen::Vector2d(radius * std::atan2(local(1, i), local(0, i)), local(2, i));
    return uv;
  }
};

Chart PlaneChart(const PlaneFrame& plane) {
  Chart c;
  c.origin = plane.origin;
  c.axes = plane.axes;
  return c;
}

// The points' best cylinder (least squares, fitting/primitive_fit.h) as a chart: z along the axis, the
// origin on the axis at the points' mean height, x towards the middle of the points' angular range (the cut
// of the angle at the middle of the largest gap round the axis). A patch that goes round the axis (largest
// gap under 30 degrees) is refused: the development of a closed tube is not one polygon.
Chart CylinderChart(const Eigen::Matrix3Xd& points, const std::string& file) {
  Cylinder cylinder;
  try {
    cylinder = FitCylinder(points).shape;
  } catch (const FitError& e) {
    throw FitFailure(kFitError,
                     file + ": --projection cylinder: no cylinder fits the points (" + e.what() + ")");
  }
  if (!(cylinder.radius > 0.0) || !std::isfinite(cylinder.radius) || !cylinder.axis_direction.allFinite() ||
      !cylinder.axis_point.allFinite())
    throw FitFailure(kFitError, file + ": --projection cylinder: the cylinder fit did not converge");
  Chart c;
  c.cylinder = true;
  c.radius = cylinder.radius;
  const Eigen::Matrix3d frame = FrameWithAxis(cylinder.axis_direction.normalized());
  const Eigen::Vector3d centroid = points.rowwise().mean();
  c.origin = cylinder.axis_point + frame.col(2) * frame.col(2).dot(centroid - cylinder.axis_point);
  std::vector<double> angles(static_cast<std::size_t>(points.cols()));
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const Eigen::Vector3d q = frame.transpose() * (points.col(i) - c.origin);
    angles[static_cast<std::size_t>(i)] = std::atan2(q.y(), q.x());
  }
  std::sort(angles.begin(), angles.end());
  double gap = angles.front() + 2.0 * M_PI - angles.back(), gap_middle = angles.back() + 0.5 * gap;
  for (std::size_t i = 1; i < angles.size(); ++i)
    if (angles[i] - angles[i - 1] > gap) {
      gap = angles[i] - angles[i - 1];
      gap_middle = angles[i - 1] + 0.5 * gap;
    }
  c.angular_gap = gap;
  if (gap < M_PI / 6.0)
    throw FitFailure(kFitError,
                     file +
                         ": --projection cylinder: the points go round the cylinder's axis (largest "
                         "gap " +
                         Format(gap * 180.0 / M_PI, 3) +
                         " degrees); a closed tube is not one patch (its development needs a cut)");
  const double middle = gap_middle + M_PI;
  c.axes.col(0) = std::cos(middle) * frame.col(0) + std::sin(middle) * frame.col(1);
  c.axes.col(2) = frame.col(2);
  c.axes.col(1) = c.axes.col(2).cross(c.axes.col(0));
  return c;
}

// Andrew's monotone chain: the convex hull counter-clockwise, without collinear points.
Eigen::Matrix2Xd ConvexHull(const Eigen::Matrix2Xd& uv) {
  std::vector<Eigen::Vector2d> p(static_cast<std::size_t>(uv.cols()));
  for (Eigen::Index i = 0; i < uv.cols(); ++i) p[static_cast<std::size_t>(i)] = uv.col(i);
  std::sort(p.begin(), p.end(), [](const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y());
  });
  const auto cross = [](const Eigen::Vector2d& o, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
    return (a - o).x() * (b - o).y() - (a - o).y() * (b - o).x();
  };
  std::vector<Eigen::Vector2d> hull(2 * p.size());
  std::size_t k = 0;
  for (std::size_t i = 0; i < p.size(); ++i) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], p[i]) <= 0) --k;
    hull[k++] = p[i];
  }
  for (std::size_t i = p.size() - 1, t = k + 1; i > 0; --i) {
    while (k >= t && cross(hull[k - 2], hull[k - 1], p[i - 1]) <= 0) --k;
    hull[k++] = p[i - 1];
  }
  hull.resize(k > 0 ? k - 1 : 0);
  Eigen::Matrix2Xd out(2, static_cast<Eigen::Index>(hull.size()));
  for (std::size_t i = 0; i < hull.size(); ++i) out.col(static_cast<Eigen::Index>(i)) = hull[i];
  return out;
}

// Merges the ends of a convex polygon's edges shorter than `spacing` (the mesher would otherwise need
// triangles as small as the shortest boundary edge) without cutting anything off: the short edge b c is
// replaced by the point X where its neighbours' lines a b and d c meet beyond it, so the polygon stays
// convex, counter-clockwise and CONTAINS the old one (every point of the hull stays inside the domain;
// dropping b or c instead would cut a corner off and leave points beyond the patch's edge, with their
// distance to it counted as misfit). X lies at height |bc| sin(tb) sin(tc) / sin(tb + tc) over b c (tb, tc
// the turns at b and c); an edge whose merge would bulge out further than `spacing` (turns adding up to
// nearly half a turn) is kept.
Eigen::Matrix2Xd ThinConvexPolygon(const Eigen::Matrix2Xd& polygon, double spacing) {
  std::vector<Eigen::Vector2d> p;
  for (Eigen::Index i = 0; i < polygon.cols(); ++i) p.push_back(polygon.col(i));
  const auto cross = [](const Eigen::Vector2d& u, const Eigen::Vector2d& v) {
    return u.x() * v.y() - u.y() * v.x();
  };
  std::vector<char> keep_edge(p.size(), 0);  // edges found not to merge (indexed by their first vertex)
  while (p.size() > 3) {
    const std::size_t n = p.size();
    std::size_t shortest = n;
    for (std::size_t i = 0; i < n; ++i) {
      const double length = (p[(i + 1) % n] - p[i]).norm();
      if (!keep_edge[i] && length < spacing &&
          (shortest == n || length < (p[(shortest + 1) % n] - p[shortest]).norm()))
        shortest = i;
    }
    if (shortest == n) break;
    const Eigen::Vector2d& a = p[(shortest + n - 1) % n];
    const Eigen::Vector2d& b = p[shortest];
    const Eigen::Vector2d& c = p[(shortest + 1) % n];
    const Eigen::Vector2d& d = p[(shortest + 2) % n];
    // X = b + s (b - a) = c + t (c - d): solve s (b - a) - t (c - d) = c - b.
    const Eigen::Vector2d ab = b - a, dc = c - d;
    const double det = cross(ab, -dc);
    bool merged = false;
    if (det != 0.0) {
      const double s = cross(c - b, -dc) / det, t = cross(ab, c - b) / det;
      const Eigen::Vector2d x = b + s * ab;
      const Eigen::Vector2d bc = c - b;
      const double height = std::abs(cross(bc, x - b)) / bc.norm();
      if (s >= 0.0 && t >= 0.0 && height <= spacing) {
        p[shortest] = x;
        p.erase(p.begin() + static_cast<std::ptrdiff_t>((shortest + 1) % n));
        keep_edge.assign(p.size(), 0);
        merged = true;
      }
    }
    if (!merged) keep_edge[shortest] = 1;
  }
  Eigen::Matrix2Xd out(2, static_cast<Eigen::Index>(p.size()));
  for (std::size_t i = 0; i < p.size(); ++i) out.col(static_cast<Eigen::Index>(i)) = p[i];
  return out;
}

double PolygonArea(const Eigen::Matrix2Xd& p) {
  double twice = 0.0;
  for (Eigen::Index i = 0; i < p.cols(); ++i) {
    const Eigen::Index j = (i + 1) % p.cols();
    twice += p(0, i) * p(1, j) - p(0, j) * p(1, i);
  }
  return 0.5 * twice;
}

FeMesh ToFeMesh(const DomainMesh& mesh) {
  FeMesh out;
  out.uv = mesh.vertices;
  for (int t = 0; t < mesh.triangle_count(); ++t)
    out.triangles.push_back({mesh.triangles(0, t), mesh.triangles(1, t), mesh.triangles(2, t)});
  return out;
}

// The longest-edge bound for about `count` triangles over `area`: equilateral triangles of edge h have area
// sqrt(3) h^2 / 4, and Delaunay refinement under a bound h leaves the median edge at about two thirds of it
// (measured on the Gaussian bump's hull: median 0.47 under the bound 0.73), hence the factor 1.5.
double EdgeForTriangleCount(double area, double count) {
  return 1.5 * std::sqrt(4.0 * area / (std::sqrt(3.0) * count));
}

struct PatchFit {
  DomainMesh domain;
  std::unique_ptr<FeSurface> surface;
  FeSurfaceFitResult result;
};

PatchFit FitPatch(const Chart& chart, const DomainPolygon& polygon, const DomainMeshOptions& mesh_options,
                  const Eigen::Matrix3Xd& local, const Eigen::Matrix2Xd& uv,
                  const FeSurfaceFitOptions& fit_options, const CurvedBoundary* curves) {
  PatchFit p;
  p.domain = MeshDomain(polygon, mesh_options);
  p.surface = std::make_unique<FeSurface>(ToFeMesh(p.domain));
  if (curves) {
    // An n-sided patch (docs/fe-surfaces.md section 6a): the boundary conforms to the curves (eq. P12), the
    // inside starts as the fairest surface spanning them (eq. P14), and each point starts from its foot there
    // (global search).
    const std::vector<FeLinearConstraint> rows = SetBoundaryConformity(*p.surface, curves->Trace());
    FairFill(*p.surface, rows);
    const FeSurfaceModel start(*p.surface);
    std::vector<FootPoint> feet;
    ComputeFootPoints(start, local, feet);
    Eigen::Matrix2Xd start_uv(2, local.cols());
    for (Eigen::Index i = 0; i < local.cols(); ++i)
      start_uv.col(i) =
          Eigen::Vector2d(feet[static_cast<std::size_t>(i)].t[0], feet[static_cast<std::size_t>(i)].t[1]);
    p.result = FitFeSurface(local, start_uv, fit_options, *p.surface, {}, rows);
    return p;
  }
  const std::vector<FeFixedDirection> pinned =
      chart.cylinder ? SetCylindricalChart(*p.surface, chart.radius) : SetPlanarChart(*p.surface);
  p.result = FitFeSurface(local, uv, fit_options, *p.surface, pinned);
  return p;
}

nlohmann::json Vector(const Eigen::Vector3d& v) {
  return {v.x(), v.y(), v.z()};
}

}  // namespace

FitOutcome ComputeFeSurfaceFit(const FitOptions& o) {
  try {
    std::string format, units, device = "file";
    FitOutcome outcome;
    const Eigen::MatrixXd read = ReadFitPoints(o, format, units, outcome.notes, device);
    const std::string units_out = o.units.empty() ? units : o.units;
    if (read.rows() != 3) throw FitFailure(kUsage, o.file + ": fe-surface needs 3-D points");
    const Eigen::Matrix3Xd points = read;
    if (points.cols() < 10)
      throw FitFailure(kFitError, o.file + ": " + std::to_string(points.cols()) +
                                      " points; a surface patch needs at least 10");
    const PlaneFrame frame = FitPlaneFrame(points);
    if (!(frame.spread(1) > 1e-6 * frame.spread(0)))
      throw FitFailure(kFitError, o.file + ": the points lie on a line (spread " +
                                      Format(frame.spread(0), 4) + " along it, " +
                                      Format(frame.spread(1), 4) + " across): no surface patch spans them");
    if (o.projection != "plane" && o.projection != "cylinder")
      throw FitFailure(kUsage, "--projection " + o.projection + ": fe-surface takes plane or cylinder");
    // An n-sided patch bounded by fitted curves lives in the data's coordinates (an identity chart); the
    // curves, not a projection, make its domain.
    const bool curve_boundary = !o.boundary.empty() && o.boundary != "auto" && IsCurveBoundary(o.boundary);
    if (curve_boundary && o.projection != "plane")
      throw FitFailure(kUsage,
                       "--projection does not apply to a boundary of curves (the curves make the domain)");
    std::optional<CurvedBoundary> curves;
    if (curve_boundary) {
      if (o.progress) o.progress("reading the boundary curves and closing their domain polygon");
      curves.emplace(ReadCurvedBoundary(o.boundary));
    }
    const CurvedBoundary* curves_ptr = curves ? &*curves : nullptr;
    if (o.progress && o.projection == "cylinder") o.progress("fitting the points' cylinder");
    const Chart chart = curve_boundary               ? Chart{}
                        : o.projection == "cylinder" ? CylinderChart(points, o.file)
                                                     : PlaneChart(frame);
    const Eigen::Matrix3Xd local = chart.ToLocal(points);
    const Eigen::Matrix2Xd uv = chart.Parameters(local);

    // The domain: the boundary curves' polygon, the given outline projected onto the chart, or the points'
    // convex hull there.
    DomainPolygon polygon;
    std::string boundary_source = "auto (convex hull of the points' projection)";
    if (curves) {
      polygon = curves->polygon;
      boundary_source = std::to_string(curves->sides.size()) + " boundary curves (" + o.boundary + ")";
    } else if (!o.boundary.empty() && o.boundary != "auto") {
      const Scan outline = ReadPointCloud(o.boundary, DetectFormat(o.boundary));
      polygon.outer = chart.Parameters(chart.ToLocal(outline.points));
      if (polygon.outer.cols() >= 3 && PolygonArea(polygon.outer) < 0)
        polygon.outer = polygon.outer.rowwise().reverse().eval();
      boundary_source = o.boundary;
    } else {
      polygon.outer = ConvexHull(uv);
    }
    const double hull_area = std::abs(PolygonArea(polygon.outer));
    if (!(hull_area > 0.0)) throw FitFailure(kFitError, o.file + ": the points' projection has no area");

    // Element size: --size, or --elements N triangles, or auto (about 30 points per triangle, then refined
    // where the fitted surface bends).
    const bool adaptive = o.size <= 0 && (o.elements.empty() || o.elements == "auto");
    double edge = o.size;
    if (edge <= 0) {
      double count = std::clamp(static_cast<double>(points.cols()) / 30.0, 24.0, 2000.0);
      if (!adaptive) count = std::stod(o.elements);
      edge = EdgeForTriangleCount(hull_area, count);
    }
    if (o.boundary.empty() || o.boundary == "auto")
      polygon.outer = ThinConvexPolygon(polygon.outer, 0.1 * edge);
    try {
      polygon.Validate();
    } catch (const std::invalid_argument& e) {
      throw FitFailure(
          o.boundary.empty() || o.boundary == "auto" ? kFitError : kInputError,
          (o.boundary.empty() || o.boundary == "auto" ? o.file : o.boundary) + ": boundary: " + e.what());
    }
    DomainMeshOptions mesh_options;
    mesh_options.max_edge = edge;

    FeSurfaceFitOptions fit_options;
    const std::string method = o.method.empty() ? "sdm" : o.method;
    if (method == "spring") {
      // Fang's sliding springs (docs/fe-surfaces.md section 4b) with the springs' stiffness in the model: a
      // patch's boundary is free along its normal, where the plate alone would float. It stops by itself at
      // the loads' equilibrium, linearly as the feet slide, so it gets more iterations.
      fit_options.solver = FeSolver::kFangSprings;
      fit_options.spring_hessian = FeSpringHessian::kPlateOnSprings;
      fit_options.max_iterations = 400;
    } else if (method == "pdm" || method == "tdm" || method == "sdm" || method == "cdm") {
      fit_options.method = ErrorTermFromString(method);
    } else {
      throw FitFailure(kUsage, "--method " + method + ": fe-surface takes sdm, tdm, pdm, cdm or spring");
    }
    fit_options.stretch = o.stretch;
    fit_options.bending = o.bending_given ? o.bending : 1e-7;
    fit_options.jump = o.beta2;
    if (o.max_iterations > 0) fit_options.max_iterations = o.max_iterations;
    std::string why;
    if (!fit_options.IsValid(&why)) throw FitFailure(kUsage, "fe-surface: " + why);

    // The scanner noise without a model (fitting/noise_estimate.h), for the weight's choice and the adequacy.
    ScanSet single;
    single.scans.emplace_back();
    single.scans.back().points = points;
    const double noise = EstimateNoise(single);

    if (o.progress) o.progress("meshing the domain and fitting");
    PatchFit fit = FitPatch(chart, polygon, mesh_options, local, uv, fit_options, curves_ptr);
    // Without --bending, the weight by Morozov's discrepancy principle (docs/fe-surfaces.md eq. P11): the
    // largest of 1e-7, 1e-8, 1e-9, 1e-10 whose fit on the first mesh comes within the adequacy band of the
    // noise (RMS <= 1.5 sigma); a weaker weight is not tried once it no longer lowers the RMS by 10 % (the
    // mesh, not the fairness, then limits the fit).
    nlohmann::json bending_choice = nullptr;
    if (!o.bending_given) {
      nlohmann::json tried = nlohmann::json::array();
      tried.push_back({{"bending", fit_options.bending}, {"rms", fit.result.rms}});
      const double band = kAdequacyThreshold * noise;
      while (std::isfinite(noise) && fit.result.rms > band && fit_options.bending > 1.5e-10) {
        FeSurfaceFitOptions weaker = fit_options;
        weaker.bending = fit_options.bending / 10.0;
        if (o.progress)
          o.progress("RMS " + Format(fit.result.rms, 4) + " above 1.5 x the noise " + Format(noise, 4) +
                     ": fitting again with the bending weight " + Format(weaker.bending, 3));
        PatchFit next = FitPatch(chart, polygon, mesh_options, local, uv, weaker, curves_ptr);
        tried.push_back({{"bending", weaker.bending}, {"rms", next.result.rms}});
        if (!(next.result.rms < 0.9 * fit.result.rms)) break;
        fit_options = weaker;
        fit = std::move(next);
      }
      bending_choice = {
          {"rule", "discrepancy"},
          {"noise_estimate", std::isfinite(noise) ? nlohmann::json(noise) : nlohmann::json(nullptr)},
          {"band", std::isfinite(noise) ? nlohmann::json(band) : nlohmann::json(nullptr)},
          {"tried", tried},
          {"chosen", fit_options.bending}};
    }
    nlohmann::json refinement = nullptr;
    if (adaptive) {
      // Fang's refinement (thesis sec. 6.2): elements sized by the fitted surface's curvature, h(u, v) =
      // angle / |kappa|max, between a third of the first size and the first size (eq. P10); then fitted
      // again on the new mesh.
      const double angle = 0.25;
      const FeSurface& first = *fit.surface;
      FeSurfacePoint walker;
      mesh_options.size = [&first, &walker, angle, edge](double u, double v) {
        first.Locate(Eigen::Vector2d(u, v), walker);
        const FeSurfaceGeometry g = first.Evaluate(walker);
        const SurfacePointCurvature c = InterrogateSurfacePoint(g.point, g.d1, g.d2);
        const double k = c.regular ? std::max(std::abs(c.kmax), std::abs(c.kmin)) : 0.0;
        return std::clamp(k > 0 ? angle / k : edge, edge / 3.0, edge);
      };
      if (o.progress) o.progress("refining the mesh where the surface bends, and fitting again");
      const int first_triangles = fit.domain.triangle_count();
      const double first_rms = fit.result.rms;
      PatchFit refined = FitPatch(chart, polygon, mesh_options, local, uv, fit_options, curves_ptr);
      refinement = {
          {"angle_per_element", angle},
          {"first", {{"triangles", first_triangles}, {"rms", first_rms}}},
          {"refined", {{"triangles", refined.domain.triangle_count()}, {"rms", refined.result.rms}}}};
      fit = std::move(refined);
    }
    const FeSurface& surface = *fit.surface;
    const FeSurfaceFitResult& r = fit.result;

    // The document: mesh and dofs in data coordinates (positions c + R w, slopes R w_u), docs/cli.md.
    nlohmann::json& j = outcome.document;
    j["schema"] = "scan2model.fe-surface/1";
    j["input"] = {{"file", o.file}, {"format", format}, {"points", points.cols()}, {"units", units_out}};
    j["model"] = "fe-surface";
    j["method"] = method;
    j["projection"] = curves ? "boundary curves" : chart.cylinder ? "cylinder" : "plane";
    if (curves)
      j["boundary_curves"] = curves->ToJson();
    else if (chart.cylinder)
      j["cylinder"] = {{"origin", Vector(chart.origin)},
                       {"x_axis", Vector(chart.axes.col(0))},
                       {"y_axis", Vector(chart.axes.col(1))},
                       {"axis", Vector(chart.axes.col(2))},
                       {"radius", chart.radius},
                       {"angular_gap_degrees", chart.angular_gap * 180.0 / M_PI}};
    else
      j["plane"] = {{"origin", Vector(frame.origin)},
                    {"u_axis", Vector(frame.axes.col(0))},
                    {"v_axis", Vector(frame.axes.col(1))},
                    {"normal", Vector(frame.axes.col(2))}};
    nlohmann::json outline = nlohmann::json::array();
    for (Eigen::Index i = 0; i < polygon.outer.cols(); ++i)
      outline.push_back({polygon.outer(0, i), polygon.outer(1, i)});
    j["domain"] = {{"boundary", boundary_source}, {"polygon_uv", outline}, {"area", hull_area}};
    nlohmann::json vertices = nlohmann::json::array(), triangles = nlohmann::json::array(),
                   edges = nlohmann::json::array();
    const Eigen::MatrixX3d& q = surface.dofs();
    for (int v = 0; v < surface.vertex_count(); ++v) {
      const Eigen::Vector3d w = chart.origin + chart.axes * q.row(surface.vertex_dof(v, 0)).transpose();
      const Eigen::Vector3d wu = chart.axes * q.row(surface.vertex_dof(v, 1)).transpose();
      const Eigen::Vector3d wv = chart.axes * q.row(surface.vertex_dof(v, 2)).transpose();
      vertices.push_back({{"uv", {surface.mesh().uv(0, v), surface.mesh().uv(1, v)}},
                          {"w", Vector(w)},
                          {"w_u", Vector(wu)},
                          {"w_v", Vector(wv)}});
    }
    for (const auto& t : surface.mesh().triangles) triangles.push_back({t[0], t[1], t[2]});
    for (int e = 0; e < surface.edge_count(); ++e) {
      const Eigen::Vector2d a = surface.mesh().uv.col(surface.edge(e)[0]),
                            b = surface.mesh().uv.col(surface.edge(e)[1]);
      const EdgeFrame ef = GlobalEdgeFrame(a, b);
      edges.push_back({{"vertices", {surface.edge(e)[0], surface.edge(e)[1]}},
                       {"normal_uv", {ef.normal.x(), ef.normal.y()}},
                       {"w_n", Vector(chart.axes * q.row(surface.edge_dof(e)).transpose())}});
    }
    j["mesh"] = {{"vertices", vertices},
                 {"triangles", triangles},
                 {"edges", edges},
                 {"dofs", surface.dof_count()},
                 {"element", "Fang's 12-dof C1 triangle, docs/fe-surfaces.md eqs. T1-T9"}};
    if (!refinement.is_null()) j["mesh"]["refinement"] = refinement;
    j["weights"] = {
        {"relative",
         {{"stretch", fit_options.stretch}, {"bending", fit_options.bending}, {"jump", fit_options.jump}}},
        {"absolute",
         {{"stretch", r.weights.stretch}, {"bending", r.weights.bending}, {"jump", r.weights.jump2}}},
        {"bending_choice", bending_choice}};
    j["energy"] = {{"closeness", r.rms * r.rms * static_cast<double>(points.cols())},
                   {"stretch", r.energy.stretch},
                   {"bending", r.energy.bending},
                   {"jump", r.energy.jump}};
    j["residuals"] = {{"rms", r.rms}, {"max", r.max_distance}, {"boundary_feet", r.boundary_feet}};
    const Adequacy adequacy = AssessAdequacy(r.rms, noise);
    j["adequacy"] = adequacy.ToJson();
    j["iterations"] = r.iterations;
    j["converged"] = r.converged;
    j["objective_history"] =
        r.objective.size() > 1
            ? nlohmann::json(std::vector<double>(r.objective.begin() + 1, r.objective.end()))
            : nlohmann::json::array();

    if (!o.output.empty()) {
      WriteTextAtomically(o.output + ".json", j.dump(2) + "\n");
      Scan samples;
      const std::vector<FeSurfacePoint> at = surface.SamplePoints(6);
      samples.points.resize(3, static_cast<Eigen::Index>(at.size()));
      for (std::size_t i = 0; i < at.size(); ++i)
        samples.points.col(static_cast<Eigen::Index>(i)) =
            chart.origin + chart.axes * surface.Evaluate(at[i]).point;
      samples.units = units_out;
      WritePly(o.output + ".ply", samples);
    }

    std::ostringstream text;
    text << "scan2model fit: fe-surface, " << surface.triangle_count() << " triangles ("
         << surface.dof_count() << " vector dofs) to " << points.cols() << " points of " << o.file << " ("
         << format << ", units " << units_out << ")\n\n"
         << "  method            " << method << ", relative weights stretch "
         << Format(fit_options.stretch, 4) << " / bending " << Format(fit_options.bending, 4) << " / jump "
         << Format(fit_options.jump, 4)
         << (bending_choice.is_null() ? std::string(" (bending as given)")
             : std::isfinite(noise)   ? std::string(" (bending chosen from the noise estimate, eq. P11)")
                                      : std::string(" (bending: the default; the noise is unknown)"))
         << "\n"
         << "  chart             "
         << (curves
                 ? "the boundary curves' polygon (" + std::to_string(curves->sides.size()) +
                       " sides, closed in " + std::to_string(curves->closure.outer_iterations) +
                       " multiplier updates; the curves' ends joined, at most " +
                       Format(*std::max_element(curves->corner_gaps.begin(), curves->corner_gaps.end()), 3) +
                       " " + units_out + " apart)"
             : chart.cylinder ? "cylinder of radius " + Format(chart.radius, 6) + " " + units_out +
                                    " (the patch developed onto it: u = radius x angle, v = height)"
                              : std::string("the points' best plane (the patch projected onto it)"))
         << "\n"
         << "  domain            " << boundary_source << ", area " << Format(hull_area, 6) << " " << units_out
         << "^2\n";
    if (!refinement.is_null())
      text << "  refinement        " << refinement["first"]["triangles"].get<int>() << " -> "
           << refinement["refined"]["triangles"].get<int>() << " triangles where the surface bends (RMS "
           << Format(refinement["first"]["rms"].get<double>(), 4) << " -> " << Format(r.rms, 4) << ")\n";
    text << "  residuals         RMS " << Format(r.rms, 6) << ", max " << Format(r.max_distance, 6) << " "
         << units_out
         << (r.boundary_feet > 0
                 ? ", " + std::to_string(r.boundary_feet) + " points with feet on the boundary"
                 : "")
         << "\n"
         << "  energy            stretch " << Format(r.energy.stretch, 4) << ", bending "
         << Format(r.energy.bending, 4) << ", jump " << Format(r.energy.jump, 4) << "\n"
         << "  iterations        " << r.iterations
         << (r.converged ? " (converged)" : " (stopped at the iteration limit: not converged)") << "\n"
         << adequacy.Text();
    outcome.text = text.str();
    return outcome;
  } catch (const FormatError& e) {
    throw FitFailure(kInputError, e.what());
  } catch (const std::invalid_argument& e) {
    throw FitFailure(kFitError, o.file + ": fe-surface: " + e.what());
  }
}

}  // namespace s2m::pipeline
