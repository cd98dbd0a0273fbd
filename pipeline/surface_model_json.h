#pragma once
// The fitted surface of a result document, rebuilt exactly from its JSON (the `surface` member of
// scan2model.multiview/1 documents of kinematic surfaces and of a scan2model.part_fit/1 document's
// spline-patch faces, the bases and control points of scan2model.bspline/1 surfaces, the mesh and dofs of
// scan2model.fe-surface/1 surfaces; docs/cli.md), for the
// report's interrogation images and `scan2model interrogate` (docs/interrogation.md).

#include <Eigen/Core>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "fitting/bspline_basis.h"
#include "fitting/fe_surface.h"
#include "fitting/parametric_model.h"
#include "registration/rigid_motion.h"

namespace s2m::pipeline {

// A B-spline basis as {order, periodic, knots, domain}, and back (std::invalid_argument or a JSON exception
// for unusable members).
nlohmann::json BasisJson(const BSplineBasis& basis);
BSplineBasis BasisFromJson(const nlohmann::json& j);
// Control points as rows [x, y(, z)] -> a dimension x count matrix.
Eigen::MatrixXd ControlPointsFromJson(const nlohmann::json& j);

// A kinematic surface (revolution, helical, spiral) in its own frame placed in the world by world_T_model:
// {"kind", "world_T_model" (4 x 4), "basis", "profile" ([r, z] per control point), "v_range", and "pitch"
// (helical) or "growth" with "allometry" [q, a, v_c] (spiral)}. std::invalid_argument for other models.
nlohmann::json SurfaceModelJson(const ParametricModel& model, const RigidMotion& world_T_model);

// The finite-element surface of a scan2model.fe-surface/1 document's `mesh` member (docs/cli.md): the
// triangles rebuild the edges in the order the document lists them (checked), with every node's dofs.
FeSurface FeSurfaceFromJson(const nlohmann::json& mesh);

struct FittedSurface {
  std::string label;  // what the surface is, for headings ("surface of revolution", ...)
  std::unique_ptr<ParametricModel> model;
  RigidMotion world_T_model;
  std::optional<Eigen::Vector3d> axis;  // unit, in the world, for surfaces with an axis
};

// The fitted surfaces a result document describes: a B-spline surface, an FE surface, a multi-view kinematic
// surface, the spline-patch faces of a part (none for curves, primitives and a part's analytic faces, which
// are unbounded). Throws std::invalid_argument naming the member when a surface's members are unusable
// (missing, wrong type, non-finite numbers, invalid knots).
std::vector<FittedSurface> FittedSurfaces(const nlohmann::json& document);

}  // namespace s2m::pipeline
