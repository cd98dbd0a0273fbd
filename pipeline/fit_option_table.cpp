#include "pipeline/fit_option_table.h"

#include <cmath>
#include <filesystem>
#include <set>
#include <stdexcept>

#include "fitting/measurement_uncertainty.h"

namespace s2m::pipeline {
namespace {

std::string Join(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : ", ") + item;
  return out;
}

double ParseNumber(const std::string& key, const std::string& text) {
  try {
    std::size_t used = 0;
    const double v = std::stod(text, &used);
    if (used != text.size() || !std::isfinite(v)) throw std::invalid_argument("");
    return v;
  } catch (const std::exception&) {
    throw std::invalid_argument("option " + key + ": '" + text + "' is not a number");
  }
}

int ToInt(const std::string& text) {
  return static_cast<int>(std::stod(text));
}

std::vector<FitOptionSpec> MakeTable() {
  using K = FitOptionKind;
  std::vector<FitOptionSpec> t;
  t.push_back(
      {"method",
       "--method",
       K::kChoice,
       "",
       "Error term per iteration: pdm, tdm, sdm, cdm, gtdm or gn (primitives: tdm or sdm; hermite-curve: "
       "spring, sdm, tdm or pdm; fe-surface: sdm, tdm, pdm, cdm or spring; spring being Fang's sliding "
       "springs). Default: tdm for primitives and multi-view fits, sdm for splines, Hermite curves and FE "
       "surfaces",
       {"pdm", "tdm", "sdm", "cdm", "gtdm", "gn", "spring"},
       false,
       -1e300,
       1e300,
       [](FitOptions& o, const std::string& v) { o.method = v; }});
  t.push_back(
      {"control_points",
       "--control-points",
       K::kText,
       "auto",
       "Splines and generatrices: control points, auto (chosen by knot insertion until the fit is "
       "adequate and the information criterion stops improving), auto:MAX, N for a curve or a "
       "generatrix, NUxNV for a surface; a part's free-form patches: auto, auto:MAX or file (the part "
       "file's nets)",
       {},
       false,
       -1e300,
       1e300,
       [](FitOptions& o, const std::string& v) { o.control_points = v; }});
  t.push_back({"efd",
               "--efd",
               K::kInteger,
               "0",
               "revolution: the vessel's outline (the profile and its mirror, closed across rim and base) as "
               "this many normalized elliptic Fourier harmonics (docs/archaeology.md section 8); 0: none",
               {},
               false,
               0,
               100,
               [](FitOptions& o, const std::string& v) { o.efd_harmonics = ToInt(v); }});
  t.push_back({"order",
               "--order",
               K::kInteger,
               "4",
               "Splines: order (degree + 1)",
               {},
               false,
               2,
               8,
               [](FitOptions& o, const std::string& v) { o.order = ToInt(v); }});
  t.push_back(
      {"closed",
       "--closed",
       K::kFlag,
       "",
       "bspline-curve, hermite-curve: closed (periodic) curve; bspline-surface: periodic in u over a fitted "
       "cylinder",
       {},
       false,
       -1e300,
       1e300,
       [](FitOptions& o, const std::string& v) { o.closed = v == "true"; }});
  t.push_back(
      {"stretch",
       "--stretch",
       K::kNumber,
       "0",
       "Splines: fairness weight of the stretch (membrane) energy, unit box; fe-surface: relative weight "
       "(docs/fe-surfaces.md eq. P6)",
       {},
       false,
       0,
       1e300,
       [](FitOptions& o, const std::string& v) { o.stretch = std::stod(v); }});
  t.push_back(
      {"bending",
       "--bending",
       K::kNumber,
       "0.001 (splines), 1e-07 (fe-surface)",
       "Splines: fairness weight of the bending (thin plate) energy, unit box; fe-surface: relative weight "
       "(docs/fe-surfaces.md eq. P6)",
       {},
       false,
       0,
       1e300,
       [](FitOptions& o, const std::string& v) {
         o.bending = std::stod(v);
         o.bending_given = true;
       }});
  t.push_back(
      {"boundary",
       "--boundary",
       K::kText,
       "auto",
       "fe-surface: boundary curves, 3 or more comma-separated cubic hermite-curve documents (.json) in "
       "their "
       "order round an n-sided patch (docs/fe-surfaces.md section 6a); or the domain's outline, a point file "
       "(PLY, PCD, XYZ) of its corners in order, projected onto the points' plane; auto: the convex hull of "
       "the "
       "points' projection",
       {},
       false,
       -1e300,
       1e300,
       [](FitOptions& o, const std::string& v) { o.boundary = v; }});
  t.push_back({"projection",
               "--projection",
               K::kChoice,
               "plane",
               "fe-surface: the chart the patch is parametrized over: plane (its projection onto the points' "
               "best plane) or cylinder (its development onto the points' best cylinder: u = radius x angle, "
               "v = height; docs/fe-surfaces.md eq. P8c)",
               {"plane", "cylinder"},
               false,
               -1e300,
               1e300,
               [](FitOptions& o, const std::string& v) { o.projection = v; }});
  t.push_back({"size",
               "--size",
               K::kNumber,
               "0",
               "fe-surface: the triangles' longest edge in data units (0: from --elements)",
               {},
               false,
               0,
               1e300,
               [](FitOptions& o, const std::string& v) { o.size = std::stod(v); }});
  // Hermite curves (docs/fair-curves.md).
  t.push_back({"degree",
               "--degree",
               K::kInteger,
               "5",
               "hermite-curve: 3 (cubic, C1) or 5 (quintic, C2)",
               {},
               false,
               3,
               5,
               [](FitOptions& o, const std::string& v) { o.degree = ToInt(v); }});
  t.push_back({"elements",
               "--elements",
               K::kText,
               "auto",
               "hermite-curve: number of elements, or auto (elements split where the local error is largest "
               "until the tolerance, or the data's noise estimate, is met); fe-surface: number of triangles, "
               "or auto (about 30 points per triangle, then refined where the surface bends)",
               {},
               false,
               -1e300,
               1e300,
               [](FitOptions& o, const std::string& v) { o.elements = v; },
               [](const std::string& v) {
                 if (v == "auto") return;
                 std::size_t used = 0;
                 int n = 0;
                 try {
                   n = std::stoi(v, &used);
                 } catch (const std::exception&) {
                   used = 0;
                 }
                 if (used != v.size() || n < 1)
                   throw std::invalid_argument("--elements: '" + v + "' is not a positive integer or auto");
               }});
  t.push_back({"interpolate",
               "--interpolate",
               K::kFlag,
               "",
               "hermite-curve: interpolate the ordered points (each a node, derivatives free, uniform knots) "
               "instead of approximating them",
               {},
               false,
               -1e300,
               1e300,
               [](FitOptions& o, const std::string& v) { o.interpolate = v == "true"; }});
  t.push_back(
      {"c2",
       "--c2",
       K::kFlag,
       "",
       "hermite-curve, cubic: C2 by the reduced transformation (the slopes follow from the positions)",
       {},
       false,
       -1e300,
       1e300,
       [](FitOptions& o, const std::string& v) { o.c2 = v == "true"; }});
  const auto weight = [&t](const char* key, const char* names, const char* default_text, const char* what,
                           double FitOptions::*member) {
    t.push_back({key,
                 names,
                 K::kNumber,
                 default_text,
                 std::string("hermite-curve: Fang's weight of ") + what +
                     " on the parameter domain [0, 1] (h = 1 / elements), closeness 1/2 sum d^2",
                 {},
                 false,
                 0,
                 1e300,
                 [member](FitOptions& o, const std::string& v) {
                   o.*member = std::stod(v);
                   if (member == &FitOptions::alpha3) o.alpha3_given = true;
                 }});
  };
  weight("alpha1", "--alpha1", "0", "the stretch energy integral |w'|^2 du", &FitOptions::alpha1);
  weight("alpha2", "--alpha2", "0", "the bending energy integral |w''|^2 du", &FitOptions::alpha2);
  weight(
      "alpha3", "--alpha3", "1e-08 (hermite-curve), 0 (splines)",
      "the curvature-variation energy integral |w'''|^2 du (splines and generatrices: the same on their own "
      "parameter, unit box)",
      &FitOptions::alpha3);
  weight("beta2", "--beta2", "0", "the second-derivative jumps at junctions (cubic; splines: at knots)",
         &FitOptions::beta2);
  weight("beta3", "--beta3", "0", "the third-derivative jumps at junctions (splines: at knots)",
         &FitOptions::beta3);
  t.push_back({"tolerance",
               "--tolerance",
               K::kNumber,
               "0",
               "hermite-curve: target RMS distance in data units; the weights are scaled by the one factor "
               "that meets it (the fairest curve within it). 0: the weights as given",
               {},
               false,
               0,
               1e300,
               [](FitOptions& o, const std::string& v) { o.tolerance = std::stod(v); }});
  t.push_back(
      {"fairness_fraction",
       "--fairness-fraction",
       K::kNumber,
       "0",
       "hermite-curve: scale-free fairness control phi in (0, 1): minimize (1 - phi) C / C0 + phi F / F0, "
       "the closeness relative to the data's noise and the fairness relative to a circle as long as the "
       "data (docs/fair-curves.md eq. F27); the alpha/beta weights give the mix. 0: the weights as given",
       {},
       false,
       0,
       1,
       [](FitOptions& o, const std::string& v) { o.fairness_fraction = std::stod(v); }});
  t.push_back(
      {"geometric_variation",
       "--geometric-variation",
       K::kNumber,
       "0",
       "hermite-curve, plane curves: the share g in [0, 1) of alpha3 that weighs the curvature variation "
       "along the arc, g alpha3 L0^5 integral (dkappa/ds)^2 ds, instead of the parametric integral |w'''|^2 "
       "du (docs/fair-curves.md eq. F30); fairer where the parametrization absorbs curvature variation, "
       "slower. 0: Fang's parametric energy alone",
       {},
       false,
       0,
       1,
       [](FitOptions& o, const std::string& v) { o.geometric_variation = std::stod(v); }});
  t.push_back(
      {"relative_variation",
       "--relative-variation",
       K::kFlag,
       "",
       "hermite-curve, with --geometric-variation: weigh the curvature variation relative to the "
       "curvature, integral (dkappa/ds)^2 / (1 + (kappa L0 / pi)^2) ds (docs/fair-curves.md eq. F34), "
       "so that a sharp end is kept instead of rounded off at the price of dents elsewhere",
       {},
       false,
       -1e300,
       1e300,
       [](FitOptions& o, const std::string& v) { o.relative_variation = v == "true"; }});
  t.push_back(
      {"start",
       "--start",
       K::kChoice,
       "auto",
       "Revolution, helical, spiral: where the joint fit starts. auto: from the normals (revolution: "
       "the best cylinder's axis), and only when that fit's RMS stays above the noise band a global "
       "search (pitch or growth periodicity, sherd axis search) whose best starts are fitted too, the "
       "lowest all-points objective winning; normals: the normals' start only; global: the search "
       "always (docs/method.md section 19)",
       {"auto", "normals", "global"},
       false,
       -1e300,
       1e300,
       [](FitOptions& o, const std::string& v) { o.start = v; }});
  t.push_back(
      {"pitch",
       "--pitch",
       K::kNumber,
       "",
       "Helical: a pitch (length per radian along the axis) to centre the pitch searches on instead of "
       "the normals' estimate",
       {},
       false,
       -1e300,
       1e300,
       [](FitOptions& o, const std::string& v) { o.pitch = std::stod(v); }});
  t.push_back({"growth",
               "--growth",
               K::kNumber,
               "",
               "Spiral: a growth (per radian) to centre the growth searches on instead of the normals' "
               "estimate",
               {},
               false,
               -1e300,
               1e300,
               [](FitOptions& o, const std::string& v) { o.growth = std::stod(v); }});
  t.push_back(
      {"wall",
       "--wall",
       K::kFlag,
       "",
       "Revolution: the data hold the vessel's inner and outer surfaces; fit both sharing one axis and "
       "report the wall's thickness along the height, the capacity (inside the inner surface), the "
       "outer and the material volume (docs/archaeology.md section 10)",
       {},
       false,
       -1e300,
       1e300,
       [](FitOptions& o, const std::string& v) { o.wall = v == "true"; }});
  t.push_back({"fill_height",
               "--fill-height",
               K::kNumber,
               "",
               "Revolution: the vessel's volume also up to this height above the base, in the data's units, "
               "with its uncertainty (docs/archaeology.md eq. A2); the volume to the rim is always reported",
               {},
               false,
               0,
               1e300,
               [](FitOptions& o, const std::string& v) { o.fill_height = std::stod(v); }});
  t.push_back(
      {"loss",
       "--loss",
       K::kText,
       "auto",
       "Robust loss of every fit: auto, none, huber[:scale], cauchy[:scale] or tukey[:scale] (scale: a "
       "distance in input units; omitted: 2.4-4.7 x the MAD noise estimate, re-estimated every iteration; "
       "docs/method.md section 15). auto: cauchy for recordings, device frames and organized depth clouds "
       "(flying pixels, mixed edges), none for NIST .ds and other point files (docs/cli.md)",
       {},
       false,
       -1e300,
       1e300,
       [](FitOptions& o, const std::string& v) {
         o.loss_given = v != "auto";
         o.loss = o.loss_given ? ParseRobustLoss(v) : RobustLoss{};
       },
       [](const std::string& v) {
         if (v != "auto") ParseRobustLoss(v);
       }});
  t.push_back({"criterion",
               "--criterion",
               K::kChoice,
               "lsq",
               "Primitives: the reference feature of the form error besides the least-squares fit: lsq (the "
               "least-squares zone only), minzone (the minimum zone of ISO 1101: flatness, roundness, "
               "cylindricity, ...), inscribed or circumscribed (circle, cylinder, sphere); docs/metrology.md",
               {"lsq", "minzone", "inscribed", "circumscribed"},
               false,
               -1e300,
               1e300,
               [](FitOptions& o, const std::string& v) { o.criterion = v; }});
  t.push_back(
      {"uncertainty",
       "--uncertainty",
       K::kText,
       "none",
       "Primitives and multi-view fits (refused for the others): uncertainties of the derived quantities "
       "(diameters, the cone's "
       "diameter "
       "at the data's mid-height, the torus' diameters, the form error of --criterion; a vessel's rim and "
       "base "
       "diameters and volume, the pitch, the growth and whorl expansion rate): none, linear (the GUM's law "
       "of "
       "propagation from the fit's covariance) or monte-carlo:N (GUM Supplement 1, N refits of perturbed "
       "data); expanded uncertainty U with its coverage factor (docs/metrology.md)",
       {},
       false,
       -1e300,
       1e300,
       [](FitOptions& o, const std::string& v) { o.uncertainty = v; },
       [](const std::string& v) { UncertaintyMethod::FromString(v); }});
  t.push_back(
      {"robust",
       "--robust",
       K::kFlag,
       "",
       "Primitives: detect the dominant instance among clutter first (efficient RANSAC, as `detect`), "
       "then fit it on its inliers (loss tukey unless --loss is given); the rejected points are counted",
       {},
       false,
       -1e300,
       1e300,
       [](FitOptions& o, const std::string& v) { o.robust = v == "true"; }});
  t.push_back(
      {"seed",
       "--seed",
       K::kInteger,
       "1",
       "--robust: seed of the sampling (the same seed, the same result)",
       {},
       false,
       0,
       2147483647,
       [](FitOptions& o, const std::string& v) { o.seed = static_cast<std::uint64_t>(std::stod(v)); }});
  t.push_back({"rejected_output",
               "--rejected-output",
               K::kPath,
               "",
               "--robust: write the rejected points (not in the instance) to this PLY",
               {},
               false,
               -1e300,
               1e300,
               [](FitOptions& o, const std::string& v) { o.rejected_output = v; }});
  t.push_back({"step_control",
               "--step-control",
               K::kChoice,
               "lm",
               "Splines: lm (Levenberg-Marquardt), armijo or none",
               {"lm", "armijo", "none"},
               false,
               -1e300,
               1e300,
               [](FitOptions& o, const std::string& v) { o.step_control = v; }});
  t.push_back(
      {"",
       "--output,-o",
       K::kText,
       "",
       "Write PREFIX.json (the --json document); splines also PREFIX.ply (samples) and PREFIX_history.csv",
       {},
       false,
       -1e300,
       1e300,
       [](FitOptions& o, const std::string& v) { o.output = v; }});
  t.push_back({"initial",
               "--initial",
               K::kPath,
               "",
               "Splines: start from this curve or surface (a scan2model.bspline/1 JSON, e.g. an earlier "
               "PREFIX.json)",
               {},
               false,
               -1e300,
               1e300,
               [](FitOptions& o, const std::string& v) { o.initial = v; }});
  t.push_back({"contour",
               "--contour",
               K::kInteger,
               "0",
               "Glyph (.glif) inputs: which contour to fit",
               {},
               false,
               0,
               1e9,
               [](FitOptions& o, const std::string& v) { o.contour = ToInt(v); }});
  t.push_back({"max_iterations",
               "--max-iterations",
               K::kInteger,
               "200",
               "Iteration cap",
               {},
               false,
               1,
               1e9,
               [](FitOptions& o, const std::string& v) { o.max_iterations = ToInt(v); }});
  t.push_back({"reference",
               "--reference",
               K::kPath,
               "",
               "A NIST .fit reference file to compare the result with",
               {},
               false,
               -1e300,
               1e300,
               [](FitOptions& o, const std::string& v) { o.reference = v; }});
  t.push_back({"",
               "--history",
               K::kText,
               "",
               "Write the per-iteration history to this CSV file",
               {},
               false,
               -1e300,
               1e300,
               [](FitOptions& o, const std::string& v) { o.history = v; }});
  t.push_back({"units",
               "--units",
               K::kText,
               "",
               "Declare the input's units (e.g. mm) when the file does not say",
               {},
               false,
               -1e300,
               1e300,
               [](FitOptions& o, const std::string& v) { o.units = v; }});
  // The multi-view solver: on the command line the flags --joint (the default, stated explicitly),
  // --alternating and --register-then-fit; in a manifest the key "solver". Each flag sets its own member, so
  // that the command line keeps combining --alternating with --register-then-fit as it always has.
  t.push_back(
      {"solver",
       "",
       K::kChoice,
       "joint",
       "Multi-view: joint (every view's pose and the model together, one linear solve per iteration; the "
       "default), alternating (the baseline: registration step, then fitting step) or register-then-fit "
       "(one shared motion for all views: fit the pre-registered cloud; a baseline)",
       {"joint", "alternating", "register-then-fit"},
       true,
       -1e300,
       1e300,
       [](FitOptions& o, const std::string& v) {
         if (v == "joint") o.joint = true;
         if (v == "alternating") o.alternating = true;
         if (v == "register-then-fit") o.register_then_fit = true;
       }});
  t.push_back({"",
               "--verbose,-v",
               K::kFlag,
               "",
               "Print the per-iteration history (RMS, max distance, damping, step, time)",
               {},
               false,
               -1e300,
               1e300,
               [](FitOptions& o, const std::string& v) { o.verbose = v == "true"; }});
  t.push_back({"",
               "--json",
               K::kFlag,
               "",
               "Machine-readable output (schema scan2model.fit/1, docs/cli.md)",
               {},
               false,
               -1e300,
               1e300,
               [](FitOptions& o, const std::string& v) { o.json = v == "true"; }});
  return t;
}

}  // namespace

const std::vector<FitOptionSpec>& FitOptionTable() {
  static const std::vector<FitOptionSpec> kTable = MakeTable();
  return kTable;
}

const FitOptionSpec* FindManifestOption(const std::string& key) {
  if (key.empty()) return nullptr;
  for (const FitOptionSpec& o : FitOptionTable()) {
    if (o.key == key) return &o;
  }
  return nullptr;
}

std::string ManifestOptionKeys() {
  std::set<std::string> keys;  // sorted, as the manifest's error message has always listed them
  for (const FitOptionSpec& o : FitOptionTable()) {
    if (!o.key.empty()) keys.insert(o.key);
  }
  return Join(std::vector<std::string>(keys.begin(), keys.end()));
}

std::string ParseFitOption(const FitOptionSpec& o, const std::string& text) {
  const std::string& name = o.key.empty() ? o.names : o.key;
  switch (o.kind) {
    case FitOptionKind::kText:
      if (o.check) o.check(text);
      return text;
    case FitOptionKind::kPath:
      return text;
    case FitOptionKind::kFlag:
      if (text == "true" || text == "1") return "true";
      if (text == "false" || text == "0") return "false";
      throw std::invalid_argument(name + ": '" + text + "' is not true or false");
    case FitOptionKind::kChoice:
      for (const std::string& c : o.choices) {
        if (c == text) return text;
      }
      throw std::invalid_argument(name + " '" + text + "' (" + Join(o.choices) + ")");
    case FitOptionKind::kInteger: {
      const double v = ParseNumber(name, text);
      if (v != std::floor(v) || v < o.min || v > o.max) {
        throw std::invalid_argument("option " + name + ": '" + text + "' is not an integer in [" +
                                    std::to_string(static_cast<long long>(o.min)) + ", " +
                                    std::to_string(static_cast<long long>(std::min(o.max, 1e9))) + "]");
      }
      return std::to_string(static_cast<long long>(v));
    }
    case FitOptionKind::kNumber: {
      const double v = ParseNumber(name, text);
      if (v < o.min || v > o.max) {
        throw std::invalid_argument("option " + name + ": " + text + " is " +
                                    (v < o.min ? "below " : "above ") +
                                    std::to_string(v < o.min ? o.min : o.max));
      }
      return text;
    }
  }
  return text;
}

void ApplyFitOption(const FitOptionSpec& option, const std::string& text, FitOptions& options) {
  option.set(options, ParseFitOption(option, text));
}

const char* ToString(InputKind kind) {
  switch (kind) {
    case InputKind::kCertified:
      return "certified reference data";
    case InputKind::kRecording:
      return "recordings";
    case InputKind::kDeviceFrame:
      return "device frames";
    case InputKind::kOrganizedCloud:
      return "organized depth clouds";
    case InputKind::kPointFile:
      return "point files";
  }
  return "point files";
}

InputKind ClassifyInput(const std::string& file, const std::string& device) {
  const std::string ext = std::filesystem::path(file).extension().string();
  if (ext == ".ds") return InputKind::kCertified;
  if (ext == ".s2mrec") return InputKind::kRecording;
  if (device == "file:organized") return InputKind::kOrganizedCloud;
  if (device == "file:depth-frame") return InputKind::kDeviceFrame;
  // Scans straight from a device (a live source or a device-named scan set) rather than a file.
  if (!device.empty() && device.rfind("file", 0) != 0) return InputKind::kDeviceFrame;
  return InputKind::kPointFile;
}

void ResolveDefaultLoss(FitOptions& o, InputKind kind) {
  if (o.loss_given) {
    o.loss_reason = "given";
    return;
  }
  switch (kind) {
    case InputKind::kRecording:
    case InputKind::kDeviceFrame:
    case InputKind::kOrganizedCloud:
      // Depth cameras' flying pixels (between a foreground and a background edge) and mixed edges are
      // gross outliers on one side of the surface: Cauchy's influence decays as 1/d (docs/method.md
      // section 17, measured on the real Kinect frames there).
      o.loss = ParseRobustLoss("cauchy");
      o.loss_reason = std::string("default for ") + ToString(kind) + " (flying pixels and mixed edges)";
      return;
    case InputKind::kCertified:
      o.loss = RobustLoss{};
      o.loss_reason = "default for certified reference data (plain least squares, as certified)";
      return;
    case InputKind::kPointFile:
      o.loss = RobustLoss{};
      o.loss_reason = "default for point files (plain least squares)";
      return;
  }
}

std::string ModelError(const std::string& model) {
  static const std::set<std::string> kModels = {
      "plane",         "sphere",          "cylinder",      "cone",       "line",       "circle",  "torus",
      "bspline-curve", "bspline-surface", "hermite-curve", "fe-surface", "revolution", "helical", "spiral"};
  if (kModels.count(model) > 0) return "";
  if (model.rfind("part:", 0) == 0)
    return model.size() > 5 ? "" : "part: needs a part file, e.g. part:block.part.json";
  return model +
         " is not a model (plane, sphere, cylinder, cone, line, circle, torus, bspline-curve, "
         "bspline-surface, hermite-curve, fe-surface, revolution, helical, spiral, part:FILE)";
}

}  // namespace s2m::pipeline
