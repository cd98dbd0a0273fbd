#include "fitting/nominal_inspection.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>

namespace s2m {

bool NominalInspectionOptions::IsValid(std::string* why) const {
  auto fail = [why](const char* text) {
    if (why != nullptr) *why = text;
    return false;
  };
  if (datum_rounds < 1) return fail("datum_rounds must be at least 1");
  for (int g : datum_groups)
    if (g < 0) return fail("a datum group index is negative");
  return true;
}

namespace {

// The sub-mesh of the given groups (their triangles, all vertices kept).
TriangleMesh SubMesh(const TriangleMesh& mesh, const std::vector<int>& groups) {
  TriangleMesh out;
  out.vertices = mesh.vertices;
  out.units = mesh.units;
  std::vector<Eigen::Index> kept;
  for (Eigen::Index f = 0; f < mesh.triangle_count(); ++f)
    if (std::find(groups.begin(), groups.end(), mesh.GroupOf(f)) != groups.end()) kept.push_back(f);
  out.triangles.resize(3, static_cast<Eigen::Index>(kept.size()));
  for (std::size_t i = 0; i < kept.size(); ++i)
    out.triangles.col(static_cast<Eigen::Index>(i)) = mesh.triangles.col(kept[i]);
  return out;
}

Eigen::Matrix3Xd Columns(const Eigen::Matrix3Xd& points, const std::vector<Eigen::Index>& which) {
  Eigen::Matrix3Xd out(3, static_cast<Eigen::Index>(which.size()));
  for (std::size_t i = 0; i < which.size(); ++i) out.col(static_cast<Eigen::Index>(i)) = points.col(which[i]);
  return out;
}

// Whether the nominal's faces under the selected points fix all six motions of a rigid body well
// (PoseConditioning of fitting/model_registration.h at least 1e-3: no motion determined more than 32 times
// worse than the best determined one). Two planes leave the translation along their common line free; a view
// that sees little more than that is better placed by the common pose of all views.
bool FixesAllMotions(const TriangleMeshModel& nominal, const Eigen::Matrix3Xd& world,
                     const std::vector<Eigen::Index>& keep) {
  Eigen::Matrix3Xd points(3, static_cast<Eigen::Index>(keep.size())), normals(3, points.cols());
  for (std::size_t i = 0; i < keep.size(); ++i) {
    points.col(static_cast<Eigen::Index>(i)) = world.col(keep[i]);
    normals.col(static_cast<Eigen::Index>(i)) = nominal.FaceNormal(nominal.Foot(world.col(keep[i])).triangle);
  }
  return PoseConditioning(points, normals) > 1e-3;
}

}  // namespace

std::vector<RegionDeviation> RegionStatistics(const TriangleMesh& mesh, const Eigen::VectorXd& deviations,
                                              const std::vector<int>& group) {
  const std::vector<double> areas = mesh.GroupAreas();
  std::vector<RegionDeviation> regions(static_cast<std::size_t>(mesh.group_count()));
  std::vector<double> sum(regions.size(), 0.0), sum2(regions.size(), 0.0);
  for (std::size_t g = 0; g < regions.size(); ++g) {
    regions[g].group = static_cast<int>(g);
    regions[g].name = mesh.GroupName(static_cast<int>(g));
    regions[g].nominal_area = areas[g];
    regions[g].min = std::numeric_limits<double>::quiet_NaN();
    regions[g].max = std::numeric_limits<double>::quiet_NaN();
  }
  for (Eigen::Index i = 0; i < deviations.size(); ++i) {
    const auto g = static_cast<std::size_t>(group[static_cast<std::size_t>(i)]);
    RegionDeviation& r = regions[g];
    const double d = deviations[i];
    if (r.count == 0) r.min = r.max = d;
    r.min = std::min(r.min, d);
    r.max = std::max(r.max, d);
    ++r.count;
    sum[g] += d;
    sum2[g] += d * d;
  }
  for (std::size_t g = 0; g < regions.size(); ++g) {
    RegionDeviation& r = regions[g];
    if (r.count == 0) {
      r.mean = r.standard_deviation = r.rms = std::numeric_limits<double>::quiet_NaN();
      continue;
    }
    const auto n = static_cast<double>(r.count);
    r.mean = sum[g] / n;
    r.rms = std::sqrt(sum2[g] / n);
    r.standard_deviation =
        r.count > 1 ? std::sqrt(std::max(0.0, (sum2[g] - n * r.mean * r.mean) / (n - 1))) : 0.0;
  }
  return regions;
}

NominalInspection InspectAgainstNominal(const TriangleMeshModel& nominal,
                                        const std::vector<Eigen::Matrix3Xd>& scans,
                                        const std::vector<RigidMotion>& nominal_T_scan_initial,
                                        const NominalInspectionOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument("nominal inspection options: " + why);
  if (scans.empty()) throw std::invalid_argument("no views to inspect");
  if (scans.size() != nominal_T_scan_initial.size())
    throw std::invalid_argument("one initial pose per view is needed");
  const TriangleMesh& mesh = nominal.mesh();
  for (int g : options.datum_groups)
    if (g >= mesh.group_count()) throw std::invalid_argument("a datum group index is out of range");
  const bool datums = !options.datum_groups.empty();
  std::optional<TriangleMeshModel> datum_model;
  if (datums) datum_model.emplace(SubMesh(mesh, options.datum_groups));
  const TriangleMeshModel& target = datums ? *datum_model : nominal;

  NominalInspection out;
  out.nominal_T_scan = nominal_T_scan_initial;
  Eigen::Index total = 0;
  for (const Eigen::Matrix3Xd& s : scans) total += s.cols();
  if (total == 0) throw std::invalid_argument("the views hold no points");

  // The points that take part in the registration: all, or those whose foot on the full nominal lies inside
  // a datum face (not on its edges or corners, where the assignment is a guess).
  auto selected = [&](const Eigen::Matrix3Xd& world) {
    std::vector<Eigen::Index> keep;
    for (Eigen::Index i = 0; i < world.cols(); ++i) {
      if (!datums) {
        keep.push_back(i);
        continue;
      }
      const MeshFoot f = nominal.Foot(world.col(i));
      if (f.region != TriangleRegion::kFace) continue;
      const int g = mesh.GroupOf(f.triangle);
      if (std::find(options.datum_groups.begin(), options.datum_groups.end(), g) !=
          options.datum_groups.end())
        keep.push_back(i);
    }
    return keep;
  };

  // The registrations' options, their progress told with the view they register.
  const auto registration_options = [&](int view) {
    if (!options.progress) return options.registration;
    return WithProgress(options.registration, [&options, view](int iteration, double rms) {
      options.progress(view, iteration, rms);
    });
  };

  // (1) All views as one rigid body.
  const int rounds = datums ? options.datum_rounds : 1;
  RigidMotion correction = RigidMotion::Identity();
  ModelRegistrationResult common;
  for (int round = 0; round < rounds; ++round) {
    Eigen::Matrix3Xd merged(3, total);
    Eigen::Index at = 0;
    for (std::size_t k = 0; k < scans.size(); ++k) {
      merged.middleCols(at, scans[k].cols()) = (correction * nominal_T_scan_initial[k]).apply(scans[k]);
      at += scans[k].cols();
    }
    const std::vector<Eigen::Index> keep = selected(merged);
    if (keep.size() < 6) throw std::invalid_argument("fewer than 6 points lie on the datum faces");
    common =
        RegisterToModel(target, Columns(merged, keep), RigidMotion::Identity(), registration_options(-1));
    correction = common.model_T_scan * correction;
  }
  out.common_correction = correction;
  for (std::size_t k = 0; k < scans.size(); ++k)
    out.nominal_T_scan[k] = correction * nominal_T_scan_initial[k];

  // (2) Each view on its own.
  std::vector<std::vector<char>> used(scans.size());
  for (std::size_t k = 0; k < scans.size(); ++k) {
    used[k].assign(static_cast<std::size_t>(scans[k].cols()), 1);
    if (!options.per_view) {
      out.registration.push_back(common);
      continue;
    }
    ModelRegistrationResult result = common;
    for (int round = 0; round < rounds; ++round) {
      const Eigen::Matrix3Xd world = out.nominal_T_scan[k].apply(scans[k]);
      const std::vector<Eigen::Index> keep = selected(world);
      // A view that sees too little of the datums (e.g. two of their planes) keeps the common pose.
      if (!FixesAllMotions(nominal, world, keep)) {
        ++out.views_on_common_pose;
        break;
      }
      used[k].assign(used[k].size(), 0);
      for (Eigen::Index i : keep) used[k][static_cast<std::size_t>(i)] = 1;
      result = RegisterToModel(target, Columns(scans[k], keep), out.nominal_T_scan[k],
                               registration_options(static_cast<int>(k)));
      out.nominal_T_scan[k] = result.model_T_scan;
    }
    out.registration.push_back(result);
  }

  // Deviations at the final poses.
  out.points.resize(3, total);
  out.deviations.resize(total);
  out.normals.resize(3, total);
  out.triangle.resize(static_cast<std::size_t>(total));
  out.group.resize(static_cast<std::size_t>(total));
  out.view_of_point.resize(static_cast<std::size_t>(total));
  Eigen::Index at = 0;
  for (std::size_t k = 0; k < scans.size(); ++k) {
    out.points.middleCols(at, scans[k].cols()) = out.nominal_T_scan[k].apply(scans[k]);
    for (Eigen::Index i = 0; i < scans[k].cols(); ++i) {
      const auto j = static_cast<std::size_t>(at + i);
      out.view_of_point[j] = static_cast<Eigen::Index>(k);
      if (used[k][static_cast<std::size_t>(i)]) ++out.registration_points;
    }
    at += scans[k].cols();
  }
#pragma omp parallel for schedule(static)
  for (Eigen::Index i = 0; i < total; ++i) {
    const MeshFoot f = nominal.Foot(out.points.col(i));
    out.deviations[i] = f.signed_distance;
    out.triangle[static_cast<std::size_t>(i)] = f.triangle;
    out.group[static_cast<std::size_t>(i)] = mesh.GroupOf(f.triangle);
    out.normals.col(i) = nominal.FaceNormal(f.triangle);
  }
  out.regions = RegionStatistics(mesh, out.deviations, out.group);
  return out;
}

Eigen::VectorXd PoseDeviationUncertainty(const NominalInspection& inspection) {
  const Eigen::Index n = inspection.points.cols();
  Eigen::VectorXd u = Eigen::VectorXd::Constant(n, std::numeric_limits<double>::quiet_NaN());
  const Eigen::Index views = static_cast<Eigen::Index>(inspection.nominal_T_scan.size());
  for (Eigen::Index k = 0; k < views; ++k) {
    Eigen::Matrix<double, 6, 6> h = Eigen::Matrix<double, 6, 6>::Zero();
    double ss = 0.0;
    Eigen::Index count = 0;
    auto row = [&](Eigen::Index i) {
      Eigen::Matrix<double, 6, 1> a;
      const Eigen::Vector3d x = inspection.points.col(i), nrm = inspection.normals.col(i);
      a << x.cross(nrm), nrm;
      return a;
    };
    for (Eigen::Index i = 0; i < n; ++i) {
      if (inspection.view_of_point[static_cast<std::size_t>(i)] != k) continue;
      const Eigen::Matrix<double, 6, 1> a = row(i);
      h += a * a.transpose();
      ss += inspection.deviations[i] * inspection.deviations[i];
      ++count;
    }
    if (count <= 6) continue;
    const double s2 = ss / static_cast<double>(count - 6);
    // Pseudo-inverse over the eigenvalues above 1e-10 of the largest: a view that leaves a motion
    // undetermined (a single plane) gets no variance along it.
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eig(h);
    const double largest = eig.eigenvalues().maxCoeff();
    Eigen::Matrix<double, 6, 6> v = Eigen::Matrix<double, 6, 6>::Zero();
    for (int e = 0; e < 6; ++e)
      if (eig.eigenvalues()[e] > 1e-10 * largest)
        v += eig.eigenvectors().col(e) * eig.eigenvectors().col(e).transpose() / eig.eigenvalues()[e];
    v *= s2;
    for (Eigen::Index i = 0; i < n; ++i) {
      if (inspection.view_of_point[static_cast<std::size_t>(i)] != k) continue;
      const Eigen::Matrix<double, 6, 1> a = row(i);
      u[i] = std::sqrt(std::max(0.0, a.dot(v * a)));
    }
  }
  return u;
}

}  // namespace s2m
