#include "pipeline/interrogate.h"

#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <vector>

#include "acquisition/format_error.h"
#include "pipeline/output.h"
#include "pipeline/png.h"
#include "pipeline/surface_model_json.h"

namespace s2m::pipeline {

InterrogateOutcome ComputeInterrogation(const InterrogateOptions& o) {
  std::ifstream in(o.input);
  if (!in) throw FormatError(o.input, "", "cannot open");
  nlohmann::json document;
  try {
    document = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw FormatError(o.input, "", std::string("not valid JSON: ") + e.what());
  }
  if (!document.is_object()) throw FormatError(o.input, "", "not a result of scan2model fit");
  // A batch object record holds its fit under "result".
  const nlohmann::json& d =
      document.value("schema", "") == "scan2model.batch_object/1" && document.contains("result")
          ? document["result"]
          : document;
  std::vector<FittedSurface> surfaces;
  try {
    surfaces = FittedSurfaces(d);
  } catch (const std::invalid_argument& e) {
    throw FormatError(o.input, "", e.what());
  }
  if (surfaces.empty()) {
    const std::string model =
        d.contains("model") && d["model"].is_string() ? d["model"].get<std::string>() : "";
    throw FormatError(
        o.input, "",
        "the document describes no surface to interrogate (model '" + model + "', schema '" +
            d.value("schema", "") +
            "'; B-spline surfaces, the multi-view kinematic surfaces and parts' spline patches are "
            "interrogated)");
  }
  const FittedSurface& f = surfaces.front();
  SurfaceRenderOptions render = o.render;
  ChooseView(*f.model, f.world_T_model, f.axis, render);
  const bool view_given = o.view.has_value();
  Eigen::Vector3d view = view_given ? *o.view : render.view;
  if (o.eye) {
    const Eigen::Vector3d eye = *o.eye;
    render.eye = eye;
    // A 17 x 17 sample of the surface's domain: its centre is where the eye looks without --view, and all of
    // it must lie in front of the eye.
    const ParameterDomain domain = f.model->domain();
    std::vector<Eigen::Vector3d> samples;
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    LocalGeometry g;
    for (int i = 0; i <= 16; ++i) {
      for (int j = 0; j <= 16; ++j) {
        f.model->Evaluate({domain.lo[0] + (domain.hi[0] - domain.lo[0]) * i / 16,
                           domain.lo[1] + (domain.hi[1] - domain.lo[1]) * j / 16, 0.0},
                          0, g);
        samples.push_back(f.world_T_model * To3(g.point));
        centre += samples.back();
      }
    }
    if (!view_given) {
      view = centre / static_cast<double>(samples.size()) - eye;
      if (view.norm() == 0) throw std::invalid_argument("--eye is the surface's centre: give --view too");
    }
    for (const Eigen::Vector3d& p : samples)
      if (!(view.dot(p - eye) > 0))
        throw std::invalid_argument(
            "--eye: the whole surface must lie in front of the eye point along the view");
  }
  if (view_given || o.eye) {
    render.view = view.normalized();
    if (render.view.cross(render.up).norm() < 1e-3) {
      // The chosen up is along the given view: take the world axis least aligned with it instead.
      Eigen::Index k;
      render.view.cwiseAbs().minCoeff(&k);
      render.up = Eigen::Vector3d::Unit(k);
    }
  }
  if (o.light) render.light = o.light->normalized();
  std::string why;
  if (!render.IsValid(&why)) throw std::invalid_argument(why);
  SurfaceRendering r;
  try {
    r = RenderSurface(*f.model, f.world_T_model, render);
  } catch (const std::invalid_argument& e) {  // the options are valid: the surface is not (non-finite points)
    throw FormatError(o.input, "", e.what());
  }
  WriteTextAtomically(o.output, EncodePng(r.image));
  return {f.label, r.caption, r.seen_pixels, r.singular_pixels};
}

}  // namespace s2m::pipeline
