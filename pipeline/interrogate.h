#pragma once
// `scan2model interrogate`: one interrogation image of the surface a fit document describes
// (docs/interrogation.md): read the document, rebuild the surface exactly (pipeline/surface_model_json.h),
// render it (pipeline/surface_render.h) and write the PNG.

#include <Eigen/Core>
#include <optional>
#include <string>

#include "pipeline/surface_render.h"

namespace s2m::pipeline {

struct InterrogateOptions {
  std::string input;   // a fit's JSON document
  std::string output;  // the PNG to write
  // The colouring and its parameters; view, up and light are replaced by ChooseView's unless given below.
  SurfaceRenderOptions render;
  std::optional<Eigen::Vector3d> view, light;
  // A perspective view from this point (and the reflection lines' eye); without `view` it looks at the
  // surface's centre.
  std::optional<Eigen::Vector3d> eye;
};

struct InterrogateOutcome {
  std::string surface;  // what was rendered ("surface of revolution", ...)
  std::string caption;  // the parameters in words
  int seen_pixels = 0, singular_pixels = 0;
};

// Throws FormatError for an unreadable or unusable document (not JSON, not a fit, no surface, bad members)
// and std::invalid_argument for invalid options.
InterrogateOutcome ComputeInterrogation(const InterrogateOptions& options);

}  // namespace s2m::pipeline
