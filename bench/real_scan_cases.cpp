// The measured table of docs/method.md section 19 ("Measured through the command"): the synthetic cases of
// real scans without hand work, each fitted through the fit dispatch (`scan2model fit`, pipeline::ComputeFit)
// twice, without the new machinery (plain least squares, the normals' start, the old default of 8 control
// points) and with it (robust extraction, global starts, automatic complexity, the adequacy verdict). Prints
// a markdown table on standard output; nothing here is a pass/fail test
// (tests/kinematic_start_command_test.cpp, tests/primitive_detection_test.cpp and tests/adequacy_test.cpp
// assert the tolerances).

#include <Eigen/Core>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "acquisition/scan_set_io.h"
#include "pipeline/fit_option_table.h"
#include "pipeline/fit_options.h"
#include "synthetic/clutter_scenes.h"
#include "synthetic/synthetic_cases.h"

namespace {

using s2m::pipeline::FitOptions;
namespace fs = std::filesystem;

fs::path Temp(const std::string& name) {
  return fs::temp_directory_path() / ("s2m_real_scan_cases_" + name);
}

std::string WriteXyz(const std::string& name, const Eigen::Matrix3Xd& points) {
  const fs::path path = Temp(name + ".xyz");
  std::ofstream out(path);
  out.precision(17);
  for (Eigen::Index j = 0; j < points.cols(); ++j)
    out << points(0, j) << ' ' << points(1, j) << ' ' << points(2, j) << '\n';
  return path.string();
}

// Runs `fit` with command-line style options ("--start normals", ...) through the option table.
struct Run {
  nlohmann::json doc;
  double seconds = 0.0;
};
Run Fit(const std::string& file, const std::string& model, const std::vector<std::string>& args) {
  FitOptions o;
  o.file = file;
  o.model = model;
  o.json = true;
  o.interactive = false;
  for (std::size_t i = 0; i < args.size(); i += 2) {
    for (const s2m::pipeline::FitOptionSpec& spec : s2m::pipeline::FitOptionTable()) {
      if (spec.names.rfind(args[i], 0) == 0) s2m::pipeline::ApplyFitOption(spec, args[i + 1], o);
    }
  }
  const auto start = std::chrono::steady_clock::now();
  Run r;
  r.doc = s2m::pipeline::ComputeFit(o).document;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return r;
}

std::string Text(const char* format, double a, double b = 0, double c = 0, double d = 0) {
  char text[300];
  std::snprintf(text, sizeof text, format, a, b, c, d);
  return text;
}

void Row(const std::string& name, const std::string& without, const std::string& with) {
  std::printf("| %s | %s | %s |\n", name.c_str(), without.c_str(), with.c_str());
  std::fflush(stdout);
}

struct AxisError {
  double degrees = 0.0, distance = 0.0;
};
AxisError CompareAxis(const s2m::KinematicCloud& c, const nlohmann::json& doc) {
  const Eigen::Vector3d point(doc["axis"]["point"][0].get<double>(), doc["axis"]["point"][1].get<double>(),
                              doc["axis"]["point"][2].get<double>());
  const Eigen::Vector3d d =
      Eigen::Vector3d(doc["axis"]["direction"][0].get<double>(), doc["axis"]["direction"][1].get<double>(),
                      doc["axis"]["direction"][2].get<double>())
          .normalized();
  const Eigen::Vector3d t = c.axis_direction.normalized();
  const Eigen::Vector3d centroid = c.points.leftCols(c.surface_points).rowwise().mean();
  const Eigen::Vector3d offset = c.axis_point + t * t.dot(centroid - c.axis_point) - point;
  return {std::acos(std::min(1.0, std::abs(d.dot(t)))) * 180 / M_PI, (offset - d * d.dot(offset)).norm()};
}

std::string Verdict(const nlohmann::json& doc) {
  const nlohmann::json& a = doc["adequacy"];
  return std::string(a["adequate"] == true ? "adequate" : "NOT adequate");
}

void SphereOnStand() {
  const s2m::SphereOnStandScene scene = s2m::MakeSphereOnStandScene(7000, 0.2, 1);
  const std::string file = WriteXyz("sphere", scene.cloud.points);
  auto describe = [&](const Run& r) {
    const nlohmann::json& p = r.doc["parameters"];
    const Eigen::Vector3d c(p["center"][0].get<double>(), p["center"][1].get<double>(),
                            p["center"][2].get<double>());
    return Text("radius error %.3f mm, centre %.3f mm off; ", std::abs(p["radius"].get<double>() - 25.0),
                (c - scene.truth.center).norm()) +
           Verdict(r.doc);
  };
  Row("sphere 50 mm on a stand, floor and wall (7 m, noise 0.2 mm)", describe(Fit(file, "sphere", {})),
      describe(Fit(file, "sphere", {"--robust", "true"})));
}

void Thread() {
  const s2m::KinematicCloud c = s2m::ShallowThreadCloud(0.1, 0.02, 3000, 5);
  const std::string file = WriteXyz("thread", c.points);
  auto describe = [&](const Run& r) {
    const double v = r.doc["pitch"]["value"].get<double>(), u = r.doc["pitch"]["uncertainty"].get<double>();
    return Text("pitch %.4f (%.3g u off), RMS %.4f, %.0f s; ", v, (v - c.pitch) / u,
                r.doc["residuals"]["rms"].get<double>(), r.seconds) +
           Verdict(r.doc);
  };
  const Run without = Fit(file, "helical", {"--start", "normals"});
  Row(Text("helical, pitch 4 mm/rad, normals say %.3f (factor %.1f)",
           without.doc["start"]["normals_value"].get<double>(),
           c.pitch / without.doc["start"]["normals_value"].get<double>()),
      describe(without), describe(Fit(file, "helical", {})));
}

void Shell() {
  const s2m::KinematicCloud c = s2m::ConicalShellCloud(0.3, 0.02, 4000, 7);
  const std::string file = WriteXyz("shell", c.points);
  const std::string estimate = std::to_string(c.growth / 5);
  auto describe = [&](const Run& r) {
    const double v = r.doc["growth"]["value"].get<double>(), u = r.doc["growth"]["uncertainty"].get<double>();
    return Text("growth %.5f (%.3g u off), RMS %.4f, %.0f s; ", v, (v - c.growth) / u,
                r.doc["residuals"]["rms"].get<double>(), r.seconds) +
           Verdict(r.doc);
  };
  Row("conical shell, growth 0.05, given as 0.01 (--growth)",
      describe(Fit(file, "spiral", {"--start", "normals", "--growth", estimate})),
      describe(Fit(file, "spiral", {"--growth", estimate})));
}

void Sherds() {
  for (const double fraction : {0.15, 0.25, 0.40}) {
    for (const bool breaks : {false, true}) {
      const s2m::KinematicCloud c = s2m::SherdCloud(fraction, breaks, 0.05, 8000, 11);
      const std::string file = WriteXyz("sherd", c.points);
      auto describe = [&](const Run& r) {
        const AxisError e = CompareAxis(c, r.doc);
        return Text("axis %.3f deg, %.3f mm; RMS %.4f, %.0f s; ", e.degrees, e.distance,
                    r.doc["residuals"]["rms"].get<double>(), r.seconds) +
               Verdict(r.doc);
      };
      Row(Text("sherd %.0f %% of the circumference, ", 100 * fraction) +
              (breaks ? "with fracture faces" : "surface only"),
          describe(Fit(file, "revolution", {"--start", "normals", "--bending", "0.001"})),
          describe(Fit(file, "revolution", {})));
    }
  }
}

void Profiles() {
  for (const std::string name : {"vase", "helical"}) {
    const fs::path manifest = Temp(name) / "views.json";
    fs::create_directories(manifest.parent_path());
    s2m::WriteScanSet(manifest, s2m::RecordedViews(s2m::MakeSyntheticCase(name)));
    const std::string model = name == "vase" ? "revolution" : "helical";
    auto describe = [&](const Run& r) {
      return Text("%.0f control points, RMS %.5f (noise estimate %.5f), %.0f s; ",
                  std::stod(r.doc["complexity"]["chosen"].get<std::string>()),
                  r.doc["residuals"]["rms"].get<double>(),
                  r.doc["complexity"]["noise_estimate"].get<double>(), r.seconds) +
             Verdict(r.doc);
    };
    Row("synthetic " + std::string(name == "vase" ? "vase" : "screw") + ", 6 views (old default 8 / auto)",
        describe(Fit(manifest.string(), model, {"--control-points", "8"})),
        describe(Fit(manifest.string(), model, {})));
  }
}

void CylinderOnCone() {
  // A cone of half-angle 5 degrees (radius 20 at mid-height, 60 tall), noise 0.02: a cylinder cannot follow
  // it.
  std::mt19937 rng(4);
  std::normal_distribution<double> noise(0.0, 0.02);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Eigen::Matrix3Xd points(3, 4000);
  const double tan_half = std::tan(5 * M_PI / 180);
  for (Eigen::Index j = 0; j < points.cols(); ++j) {
    const double z = -30 + 60 * unit(rng), a = 2 * M_PI * unit(rng);
    const double r = 20 + z * tan_half + noise(rng);
    points.col(j) << r * std::cos(a), r * std::sin(a), z;
  }
  const std::string file = WriteXyz("cone", points);
  const Run r = Fit(file, "cylinder", {});
  Row("cylinder fitted to a cone's points (half-angle 5 deg, noise 0.02)",
      Text("RMS %.3f, uncertainties printed as trusted (no verdict)",
           r.doc["residuals"]["rms"].get<double>()),
      Text("RMS %.3f = %.0f x the noise estimate; ", r.doc["residuals"]["rms"].get<double>(),
           r.doc["adequacy"]["rms_to_noise"].get<double>()) +
          Verdict(r.doc) + ", uncertainty_trusted " + r.doc["adequacy"]["uncertainty_trusted"].dump());
}

}  // namespace

int main(int argc, char** argv) {
  const std::string only = argc > 1 ? argv[1] : "";
  std::printf(
      "| case | without (plain least squares, normals' start, 8 control points) | with |\n|---|---|---|\n");
  const std::vector<std::pair<std::string, std::function<void()>>> cases = {
      {"sphere", SphereOnStand}, {"thread", Thread},     {"shell", Shell},
      {"sherds", Sherds},        {"profiles", Profiles}, {"cone", CylinderOnCone}};
  for (const auto& [name, run] : cases) {
    if (!only.empty() && only != name) continue;
    try {
      run();
    } catch (const std::exception& e) {
      Row(name, std::string("failed: ") + e.what(), "");
    }
  }
  return 0;
}
