#include "acquisition/glyph_outline.h"

#include <cmath>
#include <regex>
#include <string>

#include "acquisition/format_error.h"
#include "acquisition/formats/readers.h"
#include "acquisition/formats/text_util.h"

namespace s2m {
namespace {

struct GlifPoint {
  Eigen::Vector2d p;
  std::string type;  // "", "line", "curve", "qcurve", "move"
  bool on_curve() const { return !type.empty(); }
};

std::size_t LineOf(const std::string& text, std::size_t offset) {
  return static_cast<std::size_t>(
             std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(offset), '\n')) +
         1;
}

Eigen::Vector2d Bezier(const std::vector<Eigen::Vector2d>& c, double t) {
  std::vector<Eigen::Vector2d> q = c;  // de Casteljau
  for (std::size_t level = 1; level < q.size(); ++level)
    for (std::size_t i = 0; i + level < q.size(); ++i) q[i] = (1 - t) * q[i] + t * q[i + 1];
  return q[0];
}

}  // namespace

std::vector<Eigen::Matrix2Xd> ReadGlifContours(const std::filesystem::path& path, int samples_per_segment) {
  const std::string file = path.string();
  const std::string text = formats::ReadFileBytes(file);
  if (text.find("<glyph") == std::string::npos)
    throw FormatError(file, "", "not a .glif file (no <glyph> element)");
  const std::regex contour_re(R"(<contour\b[^>]*>([\s\S]*?)</contour>)");
  const std::regex point_re(R"(<point\b([^>]*)/?>)");
  const std::regex attr_re(R"re((\w+)\s*=\s*"([^"]*)")re");
  std::vector<Eigen::Matrix2Xd> contours;
  for (auto c = std::sregex_iterator(text.begin(), text.end(), contour_re); c != std::sregex_iterator();
       ++c) {
    const std::string body = (*c)[1].str();
    const std::size_t body_offset = static_cast<std::size_t>(c->position(1));
    std::vector<GlifPoint> pts;
    for (auto p = std::sregex_iterator(body.begin(), body.end(), point_re); p != std::sregex_iterator();
         ++p) {
      const std::string attrs = (*p)[1].str();
      const std::string where = AtLine(LineOf(text, body_offset + static_cast<std::size_t>(p->position(0))));
      GlifPoint gp;
      bool has_x = false, has_y = false;
      for (auto a = std::sregex_iterator(attrs.begin(), attrs.end(), attr_re); a != std::sregex_iterator();
           ++a) {
        const std::string key = (*a)[1].str(), value = (*a)[2].str();
        if (key == "x" || key == "y") {
          double v;
          if (!formats::ParseDouble(value, v) || !std::isfinite(v))
            throw FormatError(file, where, "bad coordinate " + formats::Quoted(value));
          (key == "x" ? gp.p.x() : gp.p.y()) = v;
          (key == "x" ? has_x : has_y) = true;
        } else if (key == "type") {
          gp.type = value == "offcurve" ? "" : value;
        }
      }
      if (!has_x || !has_y) throw FormatError(file, where, "<point> without x or y");
      pts.push_back(gp);
    }
    if (pts.empty()) continue;
    if (pts.front().type == "move") continue;  // open contour (anchors, guides): not an outline
    // Rotate so that the list starts with an on-curve point; the contour is cyclic.
    const auto first_on =
        std::find_if(pts.begin(), pts.end(), [](const GlifPoint& g) { return g.on_curve(); });
    if (first_on == pts.end()) throw FormatError(file, "", "a contour has no on-curve point");
    std::rotate(pts.begin(), first_on, pts.end());
    std::vector<Eigen::Vector2d> samples;
    const std::size_t n = pts.size();
    std::size_t i = 0;
    do {
      std::vector<Eigen::Vector2d> control{pts[i].p};
      std::size_t k = (i + 1) % n;
      while (!pts[k].on_curve()) {
        control.push_back(pts[k].p);
        k = (k + 1) % n;
      }
      control.push_back(pts[k].p);
      if (pts[k].type == "qcurve" && control.size() > 3) {
        throw FormatError(file, "", "TrueType implied on-curve points are not supported");
      }
      for (int s = 0; s < samples_per_segment; ++s)
        samples.push_back(Bezier(control, static_cast<double>(s) / samples_per_segment));
      i = k;
    } while (i != 0);
    Eigen::Matrix2Xd m(2, static_cast<Eigen::Index>(samples.size()));
    for (std::size_t s = 0; s < samples.size(); ++s) m.col(static_cast<Eigen::Index>(s)) = samples[s];
    contours.push_back(std::move(m));
  }
  if (contours.empty()) throw FormatError(file, "", "no closed contour in the glyph");
  return contours;
}

}  // namespace s2m
