#include "pipeline/surface_model_json.h"

#include <cmath>
#include <stdexcept>

#include "fitting/bspline_models.h"
#include "fitting/fe_surface_model.h"
#include "fitting/kinematic_surfaces.h"

namespace s2m::pipeline {
namespace {

double Finite(const nlohmann::json& j, const std::string& what) {
  if (!j.is_number()) throw std::invalid_argument(what + " is not a number");
  const double x = j.get<double>();
  if (!std::isfinite(x)) throw std::invalid_argument(what + " is not finite");
  return x;
}

Eigen::Matrix4d MatrixFromJson(const nlohmann::json& j, const std::string& what) {
  if (!j.is_array() || j.size() != 4) throw std::invalid_argument(what + " must be a 4 x 4 matrix");
  Eigen::Matrix4d m;
  for (std::size_t r = 0; r < 4; ++r) {
    if (!j[r].is_array() || j[r].size() != 4) throw std::invalid_argument(what + " must be a 4 x 4 matrix");
    for (std::size_t c = 0; c < 4; ++c)
      m(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = Finite(j[r][c], what);
  }
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  if (!(r.transpose() * r).isIdentity(1e-9) || !(r.determinant() > 0))
    throw std::invalid_argument(what + " is not a rigid motion");
  return m;
}

nlohmann::json MatrixJson(const Eigen::Matrix4d& m) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
  return rows;
}

}  // namespace

nlohmann::json BasisJson(const BSplineBasis& b) {
  return {
      {"order", b.order()}, {"periodic", b.periodic()}, {"knots", b.knots()}, {"domain", {b.lo(), b.hi()}}};
}

BSplineBasis BasisFromJson(const nlohmann::json& j) {
  const int order = j.at("order").get<int>();
  std::vector<double> knots = j.at("knots").get<std::vector<double>>();
  for (const double k : knots)
    if (!std::isfinite(k)) throw std::invalid_argument("a knot is not finite");
  return j.at("periodic").get<bool>() ? BSplineBasis::Periodic(order, std::move(knots))
                                      : BSplineBasis::Clamped(order, std::move(knots));
}

Eigen::MatrixXd ControlPointsFromJson(const nlohmann::json& j) {
  const auto rows = j.get<std::vector<std::vector<double>>>();
  if (rows.empty()) throw std::invalid_argument("no control points");
  Eigen::MatrixXd m(static_cast<Eigen::Index>(rows.front().size()), static_cast<Eigen::Index>(rows.size()));
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (rows[i].size() != rows.front().size())
      throw std::invalid_argument("control points of different dimensions");
    for (std::size_t c = 0; c < rows[i].size(); ++c) {
      if (!std::isfinite(rows[i][c])) throw std::invalid_argument("a control point is not finite");
      m(static_cast<Eigen::Index>(c), static_cast<Eigen::Index>(i)) = rows[i][c];
    }
  }
  return m;
}

nlohmann::json SurfaceModelJson(const ParametricModel& model, const RigidMotion& world_T_model) {
  nlohmann::json j;
  const ParameterDomain d = model.domain();
  auto profile_json = [](const Eigen::Matrix2Xd& profile) {
    nlohmann::json rows = nlohmann::json::array();
    for (Eigen::Index i = 0; i < profile.cols(); ++i) rows.push_back({profile(0, i), profile(1, i)});
    return rows;
  };
  if (const auto* k = dynamic_cast<const KinematicSurface*>(&model)) {
    j["kind"] = k->helical() ? "helical" : "revolution";
    j["basis"] = BasisJson(k->basis());
    j["profile"] = profile_json(k->profile());
    if (k->helical()) j["pitch"] = k->pitch();
  } else if (const auto* s = dynamic_cast<const SpiralSurface*>(&model)) {
    j["kind"] = "spiral";
    j["basis"] = BasisJson(s->basis());
    j["profile"] = profile_json(s->profile());
    j["growth"] = s->growth();
    if (s->allometric()) j["allometry"] = {s->growth_change(), s->axial_excess(), s->allometry_reference()};
  } else {
    throw std::invalid_argument("not a kinematic surface: " + model.name());
  }
  j["v_range"] = {d.lo[1], d.hi[1]};
  j["world_T_model"] = MatrixJson(world_T_model.matrix());
  return j;
}

namespace {

Eigen::Vector3d Vector3FromJson(const nlohmann::json& j, const std::string& what) {
  if (!j.is_array() || j.size() != 3) throw std::invalid_argument(what + " must be [x, y, z]");
  return {Finite(j[0], what), Finite(j[1], what), Finite(j[2], what)};
}

}  // namespace

FeSurface FeSurfaceFromJson(const nlohmann::json& mesh) {
  const nlohmann::json& vertices = mesh.at("vertices");
  const nlohmann::json& triangles = mesh.at("triangles");
  const nlohmann::json& edges = mesh.at("edges");
  FeMesh m;
  m.uv.resize(2, static_cast<Eigen::Index>(vertices.size()));
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    const nlohmann::json& uv = vertices[i].at("uv");
    if (!uv.is_array() || uv.size() != 2) throw std::invalid_argument("mesh.vertices[].uv must be [u, v]");
    m.uv.col(static_cast<Eigen::Index>(i)) = Eigen::Vector2d(Finite(uv[0], "uv"), Finite(uv[1], "uv"));
  }
  for (const nlohmann::json& t : triangles) {
    if (!t.is_array() || t.size() != 3) throw std::invalid_argument("mesh.triangles[] must be [i, j, k]");
    m.triangles.push_back({t[0].get<int>(), t[1].get<int>(), t[2].get<int>()});
  }
  FeSurface surface(std::move(m));  // validates the triangles
  if (static_cast<int>(edges.size()) != surface.edge_count())
    throw std::invalid_argument("mesh.edges has " + std::to_string(edges.size()) + " edges, the triangles " +
                                std::to_string(surface.edge_count()));
  Eigen::MatrixX3d q(surface.dof_count(), 3);
  for (int v = 0; v < surface.vertex_count(); ++v) {
    const nlohmann::json& vertex = vertices[static_cast<std::size_t>(v)];
    q.row(surface.vertex_dof(v, 0)) = Vector3FromJson(vertex.at("w"), "w").transpose();
    q.row(surface.vertex_dof(v, 1)) = Vector3FromJson(vertex.at("w_u"), "w_u").transpose();
    q.row(surface.vertex_dof(v, 2)) = Vector3FromJson(vertex.at("w_v"), "w_v").transpose();
  }
  for (int e = 0; e < surface.edge_count(); ++e) {
    const nlohmann::json& edge = edges[static_cast<std::size_t>(e)];
    const std::array<int, 2> ends = {edge.at("vertices").at(0).get<int>(),
                                     edge.at("vertices").at(1).get<int>()};
    if (std::minmax(ends[0], ends[1]) != std::minmax(surface.edge(e)[0], surface.edge(e)[1]))
      throw std::invalid_argument("mesh.edges[" + std::to_string(e) +
                                  "] does not join the vertices the triangles give it");
    q.row(surface.edge_dof(e)) = Vector3FromJson(edge.at("w_n"), "w_n").transpose();
  }
  surface.set_dofs(q);
  return surface;
}

std::vector<FittedSurface> FittedSurfaces(const nlohmann::json& document) {
  std::vector<FittedSurface> out;
  const std::string schema = document.value("schema", "");
  try {
    if (schema == "scan2model.bspline/1" && document.contains("basis_u")) {
      const Eigen::MatrixXd cp = ControlPointsFromJson(document.at("control_points"));
      if (cp.rows() != 3) throw std::invalid_argument("surface control points must be 3D");
      FittedSurface f;
      f.label = "B-spline surface";
      f.model = std::make_unique<BSplineSurface>(BasisFromJson(document.at("basis_u")),
                                                 BasisFromJson(document.at("basis_v")), cp);
      out.push_back(std::move(f));
    } else if (schema == "scan2model.fe-surface/1" && document.contains("mesh")) {
      FittedSurface f;
      f.label = "finite-element surface";
      f.model = std::make_unique<FeSurfaceModel>(FeSurfaceFromJson(document.at("mesh")));
      out.push_back(std::move(f));
    } else if (schema == "scan2model.part_fit/1" && document.contains("faces")) {
      // A part's spline-patch faces (the part frame is the world); its analytic faces are unbounded and not
      // drawn.
      for (const nlohmann::json& face : document.at("faces")) {
        if (!face.contains("surface")) continue;
        const nlohmann::json& s = face.at("surface");
        const Eigen::MatrixXd cp = ControlPointsFromJson(s.at("control_points"));
        if (cp.rows() != 3) throw std::invalid_argument("surface control points must be 3D");
        FittedSurface f;
        f.label = "spline patch '" + face.value("name", "") + "' of the part";
        f.model = std::make_unique<BSplineSurface>(BasisFromJson(s.at("basis_u")),
                                                   BasisFromJson(s.at("basis_v")), cp);
        out.push_back(std::move(f));
      }
    } else if (schema == "scan2model.multiview/1" && document.contains("surface")) {
      const nlohmann::json& s = document.at("surface");
      const std::string kind = s.at("kind").get<std::string>();
      BSplineBasis basis = BasisFromJson(s.at("basis"));
      const Eigen::MatrixXd profile = ControlPointsFromJson(s.at("profile"));
      if (profile.rows() != 2 || profile.cols() != basis.num_control())
        throw std::invalid_argument("the profile must have one (r, z) pair per basis function");
      const double v_lo = Finite(s.at("v_range").at(0), "v_range"),
                   v_hi = Finite(s.at("v_range").at(1), "v_range");
      if (!(v_lo < v_hi)) throw std::invalid_argument("v_range must be increasing");
      FittedSurface f;
      f.world_T_model = RigidMotion::FromMatrix(MatrixFromJson(s.at("world_T_model"), "world_T_model"));
      f.axis = f.world_T_model.rotation().col(2);
      if (kind == "revolution") {
        f.label = "surface of revolution";
        f.model = std::make_unique<KinematicSurface>(KinematicSurface::Revolution(std::move(basis), profile));
      } else if (kind == "helical") {
        f.label = "helical surface";
        f.model = std::make_unique<KinematicSurface>(KinematicSurface::Helical(
            std::move(basis), profile, Finite(s.at("pitch"), "pitch"), v_hi / M_PI));
      } else if (kind == "spiral") {
        f.label = "spiral surface";
        const double growth = Finite(s.at("growth"), "growth");
        if (s.contains("allometry")) {
          const nlohmann::json& a = s.at("allometry");
          const double centre = Finite(a.at(2), "allometry");
          // WithAllometry takes the middle of the angle range as v_c: build over a range centred there first.
          const SpiralSurface centred(basis, profile, growth, centre - 1, centre + 1);
          f.model = std::make_unique<SpiralSurface>(
              centred.WithAllometry(Finite(a.at(0), "allometry"), Finite(a.at(1), "allometry"))
                  .WithAngleRange(v_lo, v_hi));
        } else {
          f.model = std::make_unique<SpiralSurface>(std::move(basis), profile, growth, v_lo, v_hi);
        }
      } else {
        throw std::invalid_argument("unknown kind '" + kind + "'");
      }
      out.push_back(std::move(f));
    }
  } catch (const nlohmann::json::exception& e) {
    throw std::invalid_argument(std::string("the fitted surface's members are unusable: ") + e.what());
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("the fitted surface's members are unusable: ") + e.what());
  }
  return out;
}

}  // namespace s2m::pipeline
