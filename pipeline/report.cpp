#include "pipeline/report.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <iostream>
#include <numeric>
#include <sstream>

#include "acquisition/format_error.h"
#include "pipeline/batch.h"
#include "pipeline/domain_measures.h"
#include "pipeline/output.h"
#include "pipeline/png.h"
#include "pipeline/surface_model_json.h"
#include "pipeline/surface_render.h"
#include "pipeline/svg.h"

#ifndef S2M_VERSION
#define S2M_VERSION "unknown"
#endif

namespace s2m::pipeline {
namespace {

using svg::Escape;

std::string Number(const nlohmann::json& v, int digits = 8) {
  if (v.is_number()) return Format(v.get<double>(), digits);
  if (v.is_boolean()) return v.get<bool>() ? "yes" : "no";
  if (v.is_string()) return Escape(v.get<std::string>());
  return "&#8211;";  // en dash: no value
}

const char* kStyle = R"(
body { font-family: sans-serif; margin: 2em auto; max-width: 980px; color: #222; }
h1 { font-size: 1.5em; border-bottom: 2px solid #1f5fa8; padding-bottom: 0.2em; }
h2 { font-size: 1.15em; margin-top: 1.6em; color: #1f5fa8; }
table { border-collapse: collapse; margin: 0.5em 0; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }
th { background: #eef2f8; }
td.name, th.name { text-align: left; }
.pass { color: #1a7f37; font-weight: bold; }
.fail { color: #b2182b; font-weight: bold; }
.error { background: #fde8e8; border: 1px solid #b2182b; padding: 0.6em; }
.note { color: #555; font-size: 0.9em; }
figure { margin: 0.8em 0; }
)";

std::string Row(const std::vector<std::string>& cells, bool header = false) {
  std::string s = "<tr>";
  for (std::size_t i = 0; i < cells.size(); ++i) {
    const std::string tag = header ? "th" : "td";
    s += "<" + tag + (i == 0 ? " class=\"name\"" : "") + ">" + cells[i] + "</" + tag + ">";
  }
  return s + "</tr>\n";
}

std::string ParameterTable(const nlohmann::json& d) {
  const nlohmann::json params = FlatParameters(d);
  if (params.empty())
    return "<p class=\"note\">This model has no named parameters (see the result document).</p>\n";
  bool nominal = false, tolerance = false;
  for (const nlohmann::json& p : params) {
    nominal |= p.contains("nominal");
    tolerance |= p.contains("tolerance");
  }
  const bool untrusted = d.value("uncertainty_trusted", nlohmann::json(nullptr)) == false;
  std::ostringstream s;
  if (untrusted)
    s << "<p class=\"fail\">Uncertainties are NOT trustworthy: the model is inadequate (shown in "
         "brackets; see Model adequacy).</p>\n";
  s << "<table>\n";
  std::vector<std::string> header = {"parameter", "value", "standard uncertainty", "unit"};
  if (nominal) header.push_back("nominal");
  if (tolerance) header.insert(header.end(), {"tolerance", "verdict"});
  s << Row(header, true);
  for (const nlohmann::json& p : params) {
    const std::string u = Number(p["uncertainty"], 3);
    std::vector<std::string> cells = {Escape(p["name"].get<std::string>()), Number(p["value"], 10),
                                      untrusted && p["uncertainty"].is_number() ? "[" + u + "]" : u,
                                      Escape(p.value("unit", ""))};
    if (nominal) cells.push_back(Number(p.value("nominal", nlohmann::json(nullptr)), 10));
    if (tolerance) {
      cells.push_back(p.contains("tolerance") ? "&#177;" + Number(p["tolerance"], 6) : "&#8211;");
      const std::string verdict = p.value("verdict", "");
      cells.push_back(verdict.empty() ? "&#8211;"
                                      : "<span class=\"" + verdict + "\">" + Escape(verdict) + "</span>");
    }
    s << Row(cells);
  }
  s << "</table>\n";
  return s.str();
}

std::string Summary(const nlohmann::json& d) {
  std::ostringstream s;
  const nlohmann::json& in = d["input"];
  s << "<table>\n"
    << Row({"model", Escape(d.value("model", ""))}) << Row({"result schema", Escape(d.value("schema", ""))})
    << Row({"input", Escape(in.value("file", ""))});
  if (in.contains("views")) s << Row({"views", Number(in["views"])});
  s << Row({"points", Number(in["points"])}) << Row({"units", Escape(in.value("units", "unknown"))});
  if (d.contains("method")) s << Row({"error term", Escape(d["method"].get<std::string>())});
  if (d.contains("solver")) s << Row({"solver", Escape(d["solver"].get<std::string>())});
  s << Row({"residual RMS", Number(d["residuals"]["rms"], 6)})
    << Row({"largest |residual|", Number(d["residuals"]["max_abs"], 6)})
    << Row({"iterations", Number(d["iterations"])}) << Row({"stopped", Number(d["stop_reason"])})
    << Row({"time (s)", Number(d["seconds"], 4)});
  if (d.contains("unobservable") && !d["unobservable"].empty()) {
    std::string u;
    for (const nlohmann::json& n : d["unobservable"]) u += (u.empty() ? "" : "; ") + n.get<std::string>();
    s << Row({"unobservable", Escape(u)});
  }
  s << "</table>\n";
  return s.str();
}

std::string AdequacySection(const nlohmann::json& a) {
  std::ostringstream s;
  s << "<h2>Model adequacy</h2>\n<p>";
  if (a["adequate"].is_boolean()) {
    s << (a["adequate"].get<bool>() ? "<span class=\"pass\">The model is adequate</span>"
                                    : "<span class=\"fail\">The model is NOT adequate</span>")
      << ": ";
  } else {
    s << "Adequacy unknown: ";
  }
  s << "RMS of the fit " << Number(a.value("fit_scale", a["fit_rms"]), 4) << " ("
    << Escape(a.value("fit_scale_kind", "rms")) << "), noise estimated without the model "
    << Number(a["noise_estimate"], 4) << ": ratio <b>" << Number(a["rms_to_noise"], 3)
    << "</b> (band &#8804; " << Number(a["threshold"]) << ")";
  if (a.value("exact", false)) s << "; exact data (residuals at rounding level)";
  if (a.value("noise_at_rounding_level", false))
    s << "; the noise estimate is at rounding level (quantized depth or resampled points): unknown";
  s << ".</p>\n";
  const nlohmann::json& st = a.value("structure", nlohmann::json(nullptr));
  if (st.is_object()) {
    s << "<table>\n" << Row({"structure test", "statistic", "z", "effect", "significant"}, true);
    if (st["runs"].is_object()) {
      const nlohmann::json& r = st["runs"];
      s << Row({"runs of signs along " + Escape(r.value("order", "")),
                Number(r["runs"]) + " runs (expected " + Number(r["expected_runs"], 6) + ")",
                Number(r["z"], 3), "sign correlation " + Number(r["sign_correlation"], 3),
                Number(r["significant"])});
    }
    if (st["moran"].is_object()) {
      const nlohmann::json& m = st["moran"];
      s << Row({"Moran's I over " + Number(m["neighbours"]) + " nearest neighbours (" + Number(m["points"]) +
                    " points)",
                "I = " + Number(m["statistic"], 3), Number(m["z"], 3), "I", Number(m["significant"])});
    }
    s << "</table>\n<p class=\"note\">Significant: z beyond " << Number(st["z_threshold"])
      << " towards clustering and effect above " << Number(st["effect_threshold"])
      << " (docs/method.md section 17).</p>\n";
  }
  if (a.value("uncertainty_trusted", nlohmann::json(nullptr)) == false)
    s << "<p class=\"fail\">The uncertainties are NOT trustworthy: the model is inadequate (shown in "
         "brackets).</p>\n";
  const nlohmann::json& suggestions = a.value("suggestions", nlohmann::json::array());
  if (!suggestions.empty()) {
    s << "<p>What to try:</p>\n<ul>\n";
    for (const nlohmann::json& t : suggestions) s << "<li>" << Escape(t.get<std::string>()) << "</li>\n";
    s << "</ul>\n";
  }
  s << "<p class=\"note\">" << Escape(a.value("noise_method", "")) << "</p>\n";
  return s.str();
}

std::string Vessel(const nlohmann::json& v) {
  const std::string units = v.value("units", "");
  std::ostringstream s;
  s << "<h2>Vessel profile</h2>\n<table>\n"
    << Row({"height", Number(v["height"], 6) + " " + Escape(units)})
    << Row({"rim diameter", Number(v["rim_diameter"], 6) + " &#177; " +
                                Number(v["rim_diameter_uncertainty"], 2) + " " + Escape(units)})
    << Row({"base diameter", Number(v["base_diameter"], 6) + " &#177; " +
                                 Number(v["base_diameter_uncertainty"], 2) + " " + Escape(units)})
    << Row({"largest diameter", Number(v["max_diameter"], 6) + " " + Escape(units) + " at " +
                                    Number(v["max_diameter_height"], 4) + " above the base"});
  if (v.contains("volume") && v["volume"].is_number())
    s << Row({"volume (base to rim, inside the fitted surface)", Number(v["volume"], 6) + " &#177; " +
                                                                     Number(v["volume_uncertainty"], 2) +
                                                                     " " + Escape(units) + "&#179;"});
  if (v.contains("fill_volume") && v["fill_volume"].is_number())
    s << Row({"volume up to " + Number(v["fill_height"], 6) + " " + Escape(units) + " above the base",
              Number(v["fill_volume"], 6) + " &#177; " + Number(v["fill_volume_uncertainty"], 2) + " " +
                  Escape(units) + "&#179;"});
  s << "</table>\n";
  if (v.contains("roundness") && v["roundness"].is_object() && !v["roundness"]["bands"].empty()) {
    // Out-of-roundness per band (docs/archaeology.md section 4).
    s << "<h3>Out of round, base to rim</h3>\n<table>\n"
      << Row({"height above the base", "points", "centre off the axis", "ovality (max - min diameter)",
              "out of round (harmonics 2-4)", "residual RMS"},
             true);
    for (const nlohmann::json& b : v["roundness"]["bands"]) {
      if (b[4].is_null()) {
        s << Row({Number(b[0], 4) + " - " + Number(b[1], 4), Number(b[2], 8),
                  "not resolved (largest gap " + Number(b[3], 3) + "&#176;)", "", "", ""});
        continue;
      }
      s << Row({Number(b[0], 4) + " - " + Number(b[1], 4), Number(b[2], 8),
                Number(b[4], 3) + " &#177; " + Number(b[5], 2),
                Number(b[6], 3) + " &#177; " + Number(b[7], 2), Number(b[8], 3), Number(b[9], 3)});
    }
    s << "</table>\n";
  }
  s << "<figure>" << ProfileSvg(VesselMeasures::FromJson(v))
    << "<figcaption class=\"note\">Section left of the axis, outline right; "
    << Escape(v.value("convention", "")) << ".</figcaption></figure>\n";
  return s.str();
}

// A fair curve's interrogation (scan2model.hermite/1, docs/fair-curves.md section 6): the energy breakdown,
// curvature and its arc-length derivative against normalized arc length, the curvature comb with its envelope
// (plane curves; space curves seen along z), and the junctions' breaks.
std::string FairCurve(const nlohmann::json& d, const nlohmann::json& q, const std::string& heading) {
  std::ostringstream s;
  s << "<h2>" << Escape(heading) << "</h2>\n";
  if (d.contains("energy")) {
    const nlohmann::json& e = d["energy"];
    s << "<table>\n"
      << Row({"term", "weight", "energy"}, true)
      << Row({"closeness 1/2 &#8721; d&#178;", "1", Number(e["closeness"], 6)});
    const char* names[5][2] = {{"alpha1", "stretch &#8747;|w'|&#178;"},
                               {"alpha2", "bending &#8747;|w''|&#178;"},
                               {"alpha3", "variation &#8747;|w'''|&#178;"},
                               {"beta2", "jumps of w''"},
                               {"beta3", "jumps of w'''"}};
    for (const auto& n : names) s << Row({n[1], Number(d["weights"][n[0]], 6), Number(e[n[0]], 6)});
    s << "</table>\n";
  }
  s << "<table>\n"
    << Row({"length", Number(q["length"], 8)}) << Row({"max |&#954;|", Number(q["max_abs_kappa"], 6)})
    << Row({"&#8747;(d&#954;/ds)&#178; ds", Number(q["dkappa_ds_squared"], 6)})
    << Row({"Sapidis &#950; (sum of d&#954;/ds jumps)", Number(q["zeta"], 6)})
    << Row({"inflections", Number(static_cast<double>(q["inflections"].size()))})
    << Row({"largest G1 break (rad)", Number(q["max_g1"], 3)})
    << Row({"largest G2 break", Number(q["max_g2"], 3)}) << "</table>\n";
  const nlohmann::json& samples = q["samples"];
  svg::Series kappa{samples["s"].get<std::vector<double>>(), samples["kappa"].get<std::vector<double>>(),
                    "#1f5fa8", "curvature"};
  svg::Series dk{samples["s"].get<std::vector<double>>(), samples["dkappa_ds"].get<std::vector<double>>(),
                 "#b2182b", "dkappa/ds"};
  s << "<figure>" << svg::LinePlot("Curvature", "normalized arc length", "curvature", {kappa}, false)
    << "</figure>\n<figure>"
    << svg::LinePlot("Derivative of curvature", "normalized arc length", "dkappa/ds", {dk}, false)
    << "</figure>\n";
  std::vector<Eigen::Vector2d> points, tips, junctions;
  for (std::size_t i = 0; i < samples["point"].size(); ++i) {
    const auto p = samples["point"][i].get<std::vector<double>>();
    const auto t = samples["comb_tip"][i].get<std::vector<double>>();
    points.emplace_back(p[0], p[1]);
    tips.emplace_back(t[0], t[1]);
  }
  // Junction positions: the samples nearest in arc length.
  const std::vector<double> ss = samples["s"].get<std::vector<double>>();
  for (const nlohmann::json& j : q["junctions"]) {
    const double sj = j["s"].get<double>();
    std::size_t best = 0;
    for (std::size_t i = 0; i < ss.size(); ++i)
      if (std::abs(ss[i] - sj) < std::abs(ss[best] - sj)) best = i;
    if (!points.empty()) junctions.push_back(points[best]);
  }
  s << "<figure>"
    << svg::CurvatureComb(d.value("dimension", 2) == 3 ? "Curvature comb (seen along z)" : "Curvature comb",
                          points, tips, junctions)
    << "<figcaption class=\"note\">Teeth along the normal, length " << Number(q["comb_scale"], 4)
    << " x curvature (0.5 x length / max |&#954;|), on the outside of each bend; the envelope through their "
       "tips; circles: junctions of elements.</figcaption></figure>\n";
  return s.str();
}

// Every fitted surface's interrogation (docs/interrogation.md): the Gaussian, mean and principal curvature
// maps, isophotes, Klass reflection lines, zebra stripes and contours, rendered from the exact surface the
// document describes, as embedded PNG images with their parameters beside them.
std::string SurfaceInterrogation(const nlohmann::json& d) {
  std::vector<FittedSurface> surfaces;
  try {
    surfaces = FittedSurfaces(d);
  } catch (const std::invalid_argument& e) {
    return "<h2>Surface interrogation</h2>\n<p class=\"fail\">Not available: " + Escape(e.what()) + "</p>\n";
  }
  std::ostringstream s;
  for (const FittedSurface& f : surfaces) {
    s << "<h2>Surface interrogation: " << Escape(f.label) << "</h2>\n<p class=\"note\">Every pixel is traced "
      << "back to its exact surface parameters and coloured from the surface's exact first and second "
         "derivatives there (docs/interrogation.md). Curvature in 1/"
      << Escape(d["input"].value("units", "length unit")) << " (Gaussian: squared).</p>\n";
    SurfaceRenderOptions o;
    o.width = 600;
    o.height = 450;
    ChooseView(*f.model, f.world_T_model, f.axis, o);
    struct Image {
      SurfaceColouring colouring;
      CurvatureKind kind;
      const char* title;
    };
    for (const Image& image :
         {Image{SurfaceColouring::kCurvature, CurvatureKind::kGaussian, "Gaussian curvature"},
          Image{SurfaceColouring::kCurvature, CurvatureKind::kMean, "Mean curvature"},
          Image{SurfaceColouring::kCurvature, CurvatureKind::kMax, "Maximum principal curvature"},
          Image{SurfaceColouring::kCurvature, CurvatureKind::kMin, "Minimum principal curvature"},
          Image{SurfaceColouring::kIsophotes, CurvatureKind::kGaussian, "Isophotes"},
          Image{SurfaceColouring::kReflectionLines, CurvatureKind::kGaussian, "Reflection lines"},
          Image{SurfaceColouring::kZebra, CurvatureKind::kGaussian, "Zebra stripes"},
          Image{SurfaceColouring::kContours, CurvatureKind::kGaussian, "Contours"}}) {
      o.colouring = image.colouring;
      o.curvature = image.kind;
      try {
        const SurfaceRendering r = RenderSurface(*f.model, f.world_T_model, o);
        s << "<figure><img alt=\"" << image.title << "\" width=\"" << o.width << "\" height=\"" << o.height
          << "\" src=\"data:image/png;base64," << Base64(EncodePng(r.image))
          << "\"><figcaption class=\"note\"><b>" << image.title << "</b>: " << Escape(r.caption)
          << ".</figcaption></figure>\n";
      } catch (const std::exception& e) {
        s << "<p class=\"fail\">" << image.title << " not rendered: " << Escape(e.what()) << "</p>\n";
      }
    }
  }
  return s.str();
}

std::string Convergence(const nlohmann::json& d) {
  svg::Series rms{{}, {}, "#1f5fa8", "RMS"}, max{{}, {}, "#b2182b", "max distance"};
  for (const nlohmann::json& h : d.value("history", nlohmann::json::array())) {
    const double it = h["iteration"].get<double>();
    rms.x.push_back(it);
    rms.y.push_back(h["rms"].get<double>());
    max.x.push_back(it);
    max.y.push_back(h["max_distance"].get<double>());
  }
  if (rms.x.empty())
    return "<h2>Convergence</h2>\n<p class=\"note\">No iterations (a closed-form fit).</p>\n";
  return "<h2>Convergence</h2>\n<figure>" +
         svg::LinePlot("Residuals per iteration", "iteration", "distance (log scale)", {rms, max}, true) +
         "</figure>\n";
}

std::string Deviations(const nlohmann::json& d) {
  if (!d.contains("deviations") || !d["deviations"].contains("histogram"))
    return "<h2>Residuals</h2>\n<p class=\"note\">This fit stores no per-point deviations.</p>\n";
  const nlohmann::json& dev = d["deviations"];
  const std::string units = d["input"].value("units", "");
  std::ostringstream s;
  const nlohmann::json& h = dev["histogram"];
  s << "<h2>Residuals</h2>\n<p>Signed orthogonal distances of all " << Number(dev["count"])
    << " points from the fitted model (positive outside): mean " << Number(dev["mean"], 3) << ", RMS "
    << Number(dev["rms"], 4) << ", range " << Number(dev["min"], 4) << " to " << Number(dev["max"], 4) << " "
    << Escape(units) << "; " << Number(h["below"]) << " below and " << Number(h["above"])
    << " above the histogram's range.</p>\n<figure>"
    << svg::Histogram("Residual histogram", "signed distance (" + units + ")",
                      h["edges"].get<std::vector<double>>(), h["counts"].get<std::vector<double>>())
    << "</figure>\n";
  // The sample, projected: for models with an axis, a side view with the axis up; otherwise onto the two
  // principal directions of the points. Far points first, so that near ones are drawn over them.
  const nlohmann::json& sample = dev["sample"]["points"];
  const Eigen::Index n = static_cast<Eigen::Index>(sample.size());
  if (n == 0) return s.str();
  Eigen::Matrix3Xd p(3, n);
  std::vector<double> values, weights;
  for (Eigen::Index i = 0; i < n; ++i) {
    const nlohmann::json& row = sample[static_cast<std::size_t>(i)];
    p.col(i) << row[0].get<double>(), row[1].get<double>(), row[2].get<double>();
    values.push_back(row[3].get<double>());
    if (row.size() > 4) weights.push_back(row[4].get<double>());  // a robust fit's IRLS weight
  }
  const Eigen::Vector3d centre = p.rowwise().mean();
  const Eigen::Matrix3d scatter = (p.colwise() - centre) * (p.colwise() - centre).transpose();
  Eigen::Vector3d up, across;
  if (d.contains("axis")) {
    for (int i = 0; i < 3; ++i) up[i] = d["axis"]["direction"][static_cast<std::size_t>(i)].get<double>();
    if (d.contains("vessel")) {
      for (int i = 0; i < 3; ++i) up[i] = d["vessel"]["up"][static_cast<std::size_t>(i)].get<double>();
    }
    const Eigen::Matrix3d projector = Eigen::Matrix3d::Identity() - up * up.transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(projector * scatter * projector);
    across = eig.eigenvectors().col(2);
    // A shell's whorls show from above: look down the axis.
    if (d.contains("growth")) up = up.cross(across).normalized();
  } else {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
    across = eig.eigenvectors().col(2);
    up = eig.eigenvectors().col(1);
  }
  const Eigen::Vector3d towards_viewer = across.cross(up);
  std::vector<Eigen::Index> order(static_cast<std::size_t>(n));
  std::iota(order.begin(), order.end(), Eigen::Index{0});
  std::sort(order.begin(), order.end(), [&](Eigen::Index a, Eigen::Index b) {
    return towards_viewer.dot(p.col(a)) < towards_viewer.dot(p.col(b));
  });
  std::vector<Eigen::Vector2d> projected;
  std::vector<double> ordered_values, ordered_weights;
  for (const Eigen::Index i : order) {
    const Eigen::Vector3d q = p.col(i) - centre;
    projected.emplace_back(across.dot(q), up.dot(q));
    ordered_values.push_back(values[static_cast<std::size_t>(i)]);
    if (!weights.empty()) ordered_weights.push_back(weights[static_cast<std::size_t>(i)]);
  }
  const double range = 3 * dev["rms"].get<double>();
  s << "<h2>Deviation from the model</h2>\n<figure>"
    << svg::ColouredScatter("Points coloured by signed deviation (every " +
                                std::to_string(dev["sample"]["stride"].get<long long>()) + ". point)",
                            projected, ordered_values, range, units, {640, 480}, ordered_weights)
    << "<figcaption class=\"note\">Colour scale &#177;3 RMS; red outside the model, blue inside. "
    << (ordered_weights.empty()
            ? ""
            : "Crosses: points the robust loss down-weighted (" + Number(dev.value("down_weighted", 0)) +
                  " of all points) or rejected (" + Number(dev.value("rejected", 0)) + "). ")
    << (d.contains("growth") ? "View down the spiral's axis."
        : d.contains("axis") ? "Side view, axis up."
                             : "View along the points' least principal direction.")
    << "</figcaption></figure>\n";
  return s.str();
}

std::string Views(const nlohmann::json& d) {
  if (!d.contains("views")) return "";
  const nlohmann::json& views = d["views"];
  std::ostringstream s;
  s << "<h2>Views and pose corrections</h2>\n<table>\n"
    << Row({"view", "source", "points", "RMS", "rotation (deg)", "translation", "&#963; rotation (deg)",
            "&#963; translation"},
           true);
  std::vector<std::string> labels;
  std::vector<double> rotation, translation;
  for (std::size_t k = 0; k < views.size(); ++k) {
    const nlohmann::json& v = views[k];
    auto norm3 = [](const nlohmann::json& a) {  // null when a component is unknown (unobservable)
      double sum = 0;
      for (const nlohmann::json& x : a) {
        if (!x.is_number()) return nlohmann::json(nullptr);
        sum += x.get<double>() * x.get<double>();
      }
      return nlohmann::json(std::sqrt(sum));
    };
    const bool u = v.contains("pose_uncertainty");
    s << Row({std::to_string(k), Escape(v.value("source", "")), Number(v["points"]), Number(v["rms"], 4),
              Number(v["correction"]["rotation_deg"], 4), Number(v["correction"]["translation"], 4),
              u ? Number(norm3(v["pose_uncertainty"]["rotation_deg"]), 2) : "&#8211;",
              u ? Number(norm3(v["pose_uncertainty"]["translation"]), 2) : "&#8211;"});
    labels.push_back(std::to_string(k));
    rotation.push_back(v["correction"]["rotation_deg"].get<double>());
    translation.push_back(v["correction"]["translation"].get<double>());
  }
  s << "</table>\n<p class=\"note\">Correction = corrected pose relative to the recorded one; &#963; = "
       "length of "
       "the standard uncertainty vector of the pose.</p>\n<figure>"
    << svg::BarChart("Pose correction: rotation", "degrees", labels, rotation, {470, 260})
    << svg::BarChart("Pose correction: translation", d["input"].value("units", ""), labels, translation,
                     {470, 260})
    << "</figure>\n";
  return s.str();
}

}  // namespace

std::string ReportHtml(const nlohmann::json& in) {
  const bool record = in.value("schema", "") == "scan2model.batch_object/1";
  std::string title = record ? "object " + in.value("id", "") : "fit";
  std::ostringstream body;
  if (record && in.value("status", "") != "ok") {
    body << "<h2>Failed</h2>\n<div class=\"error\">" << Escape(in.value("error", "unknown error"))
         << " (exit code " << Number(in["exit_code"]) << ")</div>\n";
  } else {
    const nlohmann::json& d = record ? in.at("result") : in;
    const std::string schema = d.value("schema", "");
    if (schema != "scan2model.fit/1" && schema != "scan2model.multiview/1" &&
        schema != "scan2model.part_fit/1" && schema != "scan2model.bspline/1" &&
        schema != "scan2model.hermite/1" && schema != "scan2model.fe-surface/1") {
      throw std::invalid_argument("not a result of scan2model fit (schema '" + schema + "')");
    }
    if (!record) title += " of " + d["input"].value("file", "");
    body << Summary(d) << "<h2>Parameters</h2>\n" << ParameterTable(d);
    if (d.contains("verdict")) {
      const std::string v = d["verdict"].get<std::string>();
      body << "<p>Tolerance verdict: <span class=\"" << v << "\">" << Escape(v) << "</span></p>\n";
    }
    if (d.contains("adequacy")) body << AdequacySection(d["adequacy"]);
    if (d.contains("vessel")) body << Vessel(d["vessel"]);
    if (d.contains("interrogation")) body << FairCurve(d, d["interrogation"], "Fairness");
    if (d.contains("profile") && d["profile"].contains("interrogation"))
      body << FairCurve(d["profile"], d["profile"]["interrogation"], "Fairness of the generatrix (r, z)");
    body << SurfaceInterrogation(d);
    body << Convergence(d) << Deviations(d) << Views(d);
  }
  std::ostringstream html;
  html << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>scan2model report: "
       << Escape(title) << "</title>\n<style>" << kStyle
       << "</style>\n</head>\n<body>\n<h1>scan2model report: " << Escape(title) << "</h1>\n"
       << body.str() << "<p class=\"note\">Generated by scan2model " << S2M_VERSION
       << ". Uncertainties are standard (type A, GUM) from the Gauss-Newton covariance of the orthogonal "
          "distances.</p>\n</body>\n</html>\n";
  return html.str();
}

}  // namespace s2m::pipeline
