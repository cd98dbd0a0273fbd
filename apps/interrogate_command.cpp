// `scan2model interrogate`: an interrogation image of a fitted surface (pipeline/interrogate.h,
// docs/interrogation.md).
#include <cmath>
#include <iostream>
#include <sstream>

#include "acquisition/format_error.h"
#include "apps/commands.h"
#include "pipeline/interrogate.h"
#include "pipeline/output.h"

namespace s2m::app {
namespace {

// "x,y,z" (or "a,b" with count 2) as finite numbers; false otherwise.
bool ParseNumbers(const std::string& text, std::size_t count, std::vector<double>& out) {
  out.clear();
  std::stringstream s(text);
  std::string item;
  while (std::getline(s, item, ',')) {
    try {
      std::size_t used = 0;
      const double x = std::stod(item, &used);
      if (used != item.size() || !std::isfinite(x)) return false;
      out.push_back(x);
    } catch (const std::exception&) {
      return false;
    }
  }
  return out.size() == count;
}

}  // namespace

Runner AddInterrogateCommand(CLI::App& app) {
  struct Options {
    std::string input, output, map, light, view, eye, size = "640x480", range;
    int isophotes = 0, reflection_lines = 0, zebra = 0, contours = 0;
  };
  auto o = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand(
      "interrogate",
      "Render a fitted surface's curvature map, isophotes, reflection lines, zebra stripes or contours from "
      "its exact representation into a PNG (docs/interrogation.md)");
  cmd->add_option("result", o->input,
                  "A fit's JSON document with a surface: a B-spline surface (scan2model.bspline/1) or a "
                  "kinematic surface of a multi-view fit (scan2model.multiview/1)")
      ->required();
  cmd->add_option("--output,-o", o->output, "The PNG file to write")->required();
  cmd->add_option("--map", o->map, "A curvature map: gaussian | mean | kmax | kmin | absolute");
  cmd->add_option("--isophotes", o->isophotes,
                  "N isophotes: N.L = cos(a) for a = k 180/(N+1) degrees, k = 1..N");
  cmd->add_option("--reflection-lines", o->reflection_lines, "N Klass reflection lines of a plane of lights");
  cmd->add_option("--zebra", o->zebra, "N zebra stripes (the reflection lines' offsets, alternately dark)");
  cmd->add_option("--contours", o->contours, "N contours of the height along the image's up direction");
  cmd->add_option("--light", o->light, "x,y,z: towards the light (shading, isophotes, the light plane)");
  cmd->add_option("--view", o->view, "x,y,z: the direction the camera looks along");
  cmd->add_option(
      "--eye", o->eye,
      "x,y,z: a perspective view from this point (default: orthographic), also the reflection lines' "
      "eye; without --view it looks at the surface's centre");
  cmd->add_option("--size", o->size, "WxH pixels (default 640x480)");
  cmd->add_option("--range", o->range,
                  "a,b: the curvature map's colour range (default: symmetric, +-99th "
                  "percentile of |value|)");
  return [o]() {
    auto usage = [](const std::string& message) {
      return ReportError("interrogate", message, kUsage, false);
    };
    InterrogateOptions options;
    options.input = o->input;
    options.output = o->output;
    SurfaceRenderOptions& r = options.render;
    int chosen = 0;
    if (!o->map.empty()) {
      ++chosen;
      r.colouring = SurfaceColouring::kCurvature;
      if (!ParseCurvatureKind(o->map, r.curvature))
        return usage("--map must be gaussian, mean, kmax, kmin or absolute (got '" + o->map + "')");
    }
    for (const auto& [n, colouring, name] :
         {std::tuple{o->isophotes, SurfaceColouring::kIsophotes, "--isophotes"},
          std::tuple{o->reflection_lines, SurfaceColouring::kReflectionLines, "--reflection-lines"},
          std::tuple{o->zebra, SurfaceColouring::kZebra, "--zebra"},
          std::tuple{o->contours, SurfaceColouring::kContours, "--contours"}}) {
      if (n == 0) continue;
      if (n < 0 || n > 1000) return usage(std::string(name) + " must be 1 to 1000");
      ++chosen;
      r.colouring = colouring;
      r.lines = n;
      if (colouring == SurfaceColouring::kIsophotes) {
        r.isophote_angles_deg.clear();
        for (int k = 1; k <= n; ++k) r.isophote_angles_deg.push_back(180.0 * k / (n + 1));
      }
    }
    if (chosen > 1) return usage("choose one of --map, --isophotes, --reflection-lines, --zebra, --contours");
    if (chosen == 0) r.colouring = SurfaceColouring::kCurvature;  // the Gaussian curvature map
    std::vector<double> numbers;
    if (!o->light.empty()) {
      if (!ParseNumbers(o->light, 3, numbers) || Eigen::Vector3d(numbers.data()).norm() == 0)
        return usage("--light must be three finite numbers x,y,z, not all zero (got '" + o->light + "')");
      options.light = Eigen::Vector3d(numbers.data());
    }
    if (!o->view.empty()) {
      if (!ParseNumbers(o->view, 3, numbers) || Eigen::Vector3d(numbers.data()).norm() == 0)
        return usage("--view must be three finite numbers x,y,z, not all zero (got '" + o->view + "')");
      options.view = Eigen::Vector3d(numbers.data());
    }
    if (!o->eye.empty()) {
      if (!ParseNumbers(o->eye, 3, numbers))
        return usage("--eye must be three finite numbers x,y,z (got '" + o->eye + "')");
      options.eye = Eigen::Vector3d(numbers.data());
    }
    if (!o->range.empty()) {
      if (!ParseNumbers(o->range, 2, numbers) || !(numbers[0] < numbers[1]))
        return usage("--range must be two finite numbers a,b with a < b (got '" + o->range + "')");
      r.range = std::array<double, 2>{numbers[0], numbers[1]};
    }
    {
      const std::size_t x = o->size.find('x');
      int w = 0, h = 0;
      try {
        std::size_t used_w = 0, used_h = 0;
        w = std::stoi(o->size.substr(0, x), &used_w);
        h = x == std::string::npos ? 0 : std::stoi(o->size.substr(x + 1), &used_h);
        if (used_w != x || used_h != o->size.size() - x - 1) w = h = 0;
      } catch (const std::exception&) {
        w = h = 0;
      }
      if (w <= 0 || h <= 0) return usage("--size must be WxH in pixels (got '" + o->size + "')");
      r.width = w;
      r.height = h;
    }
    try {
      const InterrogateOutcome outcome = ComputeInterrogation(options);
      std::cout << o->output << ": " << outcome.surface << ", " << outcome.caption << "\n";
      return int{kOk};
    } catch (const FormatError& e) {
      return ReportError("interrogate", e.what(), kInputError, false);
    } catch (const std::invalid_argument& e) {
      return usage(e.what());
    }
  };
}

}  // namespace s2m::app
