#include "pipeline/svg.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>

namespace s2m::pipeline::svg {
namespace {

constexpr int kLeft = 70, kRight = 20, kTop = 34, kBottom = 46;  // plot margins, pixels

std::string Open(Size size) {
  return "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + std::to_string(size.width) + "\" height=\"" +
         std::to_string(size.height) + "\" viewBox=\"0 0 " + std::to_string(size.width) + " " +
         std::to_string(size.height) + "\" font-family=\"sans-serif\" font-size=\"12\">\n";
}

// A tick label: short and exact enough.
std::string TickLabel(double v) {
  if (v == 0.0) return "0";
  char buffer[32];
  const double a = std::abs(v);
  if (a >= 1e5 || a < 1e-3) {
    std::snprintf(buffer, sizeof buffer, "%.1e", v);
  } else {
    std::snprintf(buffer, sizeof buffer, "%.6g", v);
  }
  return buffer;
}

// Maps data to pixels inside the plot area.
struct Frame {
  Size size;
  double x_lo = 0, x_hi = 1, y_lo = 0, y_hi = 1;
  double X(double x) const { return kLeft + (x - x_lo) / (x_hi - x_lo) * (size.width - kLeft - kRight); }
  double Y(double y) const {
    return size.height - kBottom - (y - y_lo) / (y_hi - y_lo) * (size.height - kTop - kBottom);
  }
};

void Widen(double& lo, double& hi) {
  if (!(hi > lo)) {
    const double pad = std::max(std::abs(lo) * 0.1, 1e-12);
    lo -= pad;
    hi += pad;
  }
}

// Title, axes box, x and y ticks (y ticks given as values in axis coordinates with their labels).
std::string Axes(const Frame& f, const std::string& title, const std::string& x_label,
                 const std::string& y_label, const std::vector<double>& x_ticks,
                 const std::vector<std::pair<double, std::string>>& y_ticks) {
  std::ostringstream s;
  s << Text(f.size.width / 2.0, 20, title, "middle", " font-size=\"14\" font-weight=\"bold\"");
  const double x0 = kLeft, x1 = f.size.width - kRight, y0 = f.size.height - kBottom, y1 = kTop;
  s << "<rect x=\"" << Num(x0) << "\" y=\"" << Num(y1) << "\" width=\"" << Num(x1 - x0) << "\" height=\""
    << Num(y0 - y1) << "\" fill=\"none\" stroke=\"#444\"/>\n";
  for (double t : x_ticks) {
    if (t < f.x_lo - 1e-12 * std::abs(f.x_hi - f.x_lo) || t > f.x_hi + 1e-12 * std::abs(f.x_hi - f.x_lo))
      continue;
    s << Line(f.X(t), y0, f.X(t), y0 + 5, "#444") << Text(f.X(t), y0 + 18, TickLabel(t));
  }
  for (const auto& [value, label] : y_ticks) {
    s << Line(x0 - 5, f.Y(value), x0, f.Y(value), "#444") << Line(x0, f.Y(value), x1, f.Y(value), "#ddd")
      << Text(x0 - 8, f.Y(value) + 4, label, "end");
  }
  s << Text((x0 + x1) / 2, f.size.height - 8, x_label);
  s << "<text transform=\"translate(14," << Num((y0 + y1) / 2) << ") rotate(-90)\" text-anchor=\"middle\">"
    << Escape(y_label) << "</text>\n";
  return s.str();
}

}  // namespace

std::string Escape(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        // Control characters are not allowed in XML 1.0 (except tab, newline, carriage return).
        if (static_cast<unsigned char>(c) < 0x20 && c != '\t' && c != '\n' && c != '\r') {
          out += ' ';
        } else {
          out += c;
        }
    }
  }
  return out;
}

std::string Num(double value) {
  if (!std::isfinite(value)) return "0";
  char buffer[48];
  std::snprintf(buffer, sizeof buffer, "%.4f", value);
  std::string s = buffer;
  while (!s.empty() && s.back() == '0') s.pop_back();
  if (!s.empty() && s.back() == '.') s.pop_back();
  return s == "-0" ? "0" : s;
}

std::string Text(double x, double y, const std::string& text, const std::string& anchor,
                 const std::string& extra) {
  return "<text x=\"" + Num(x) + "\" y=\"" + Num(y) + "\" text-anchor=\"" + anchor + "\"" + extra + ">" +
         Escape(text) + "</text>\n";
}

std::string Line(double x1, double y1, double x2, double y2, const std::string& stroke, double width,
                 const std::string& extra) {
  return "<line x1=\"" + Num(x1) + "\" y1=\"" + Num(y1) + "\" x2=\"" + Num(x2) + "\" y2=\"" + Num(y2) +
         "\" stroke=\"" + stroke + "\" stroke-width=\"" + Num(width) + "\"" + extra + "/>\n";
}

std::vector<double> NiceTicks(double lo, double hi, int target) {
  if (!(hi > lo) || !std::isfinite(lo) || !std::isfinite(hi)) return {lo};
  const double raw = (hi - lo) / std::max(target, 1);
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  double step = magnitude;
  for (const double m : {1.0, 2.0, 5.0, 10.0}) {
    step = m * magnitude;
    if (step >= raw) break;
  }
  std::vector<double> ticks;
  for (double t = std::ceil(lo / step) * step; t <= hi + 1e-9 * step; t += step)
    ticks.push_back(std::abs(t) < 1e-12 * step ? 0.0 : t);
  return ticks;
}

std::array<std::uint8_t, 3> DivergingRgb(double t) {
  t = std::clamp(std::isfinite(t) ? t : 0.0, -1.0, 1.0);
  // White at 0 to #2166ac (negative) or #b2182b (positive).
  const double a = std::abs(t);
  const int r0 = t < 0 ? 0x21 : 0xb2, g0 = t < 0 ? 0x66 : 0x18, b0 = t < 0 ? 0xac : 0x2b;
  auto mix = [a](int c) { return static_cast<std::uint8_t>(std::lround(255.0 + (c - 255.0) * a)); };
  return {mix(r0), mix(g0), mix(b0)};
}

std::string DivergingColour(double t) {
  const std::array<std::uint8_t, 3> c = DivergingRgb(t);
  char buffer[8];
  std::snprintf(buffer, sizeof buffer, "#%02x%02x%02x", c[0], c[1], c[2]);
  return buffer;
}

std::string LinePlot(const std::string& title, const std::string& x_label, const std::string& y_label,
                     const std::vector<Series>& series, bool log_y, Size size) {
  Frame f{size};
  f.x_lo = f.y_lo = std::numeric_limits<double>::infinity();
  f.x_hi = f.y_hi = -std::numeric_limits<double>::infinity();
  auto y_of = [log_y](double y) { return log_y ? std::log10(y) : y; };
  for (const Series& s : series) {
    for (std::size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i]) || (log_y && s.y[i] <= 0)) continue;
      f.x_lo = std::min(f.x_lo, s.x[i]);
      f.x_hi = std::max(f.x_hi, s.x[i]);
      f.y_lo = std::min(f.y_lo, y_of(s.y[i]));
      f.y_hi = std::max(f.y_hi, y_of(s.y[i]));
    }
  }
  if (!std::isfinite(f.x_lo)) f.x_lo = 0, f.x_hi = 1, f.y_lo = 0, f.y_hi = 1;
  Widen(f.x_lo, f.x_hi);
  Widen(f.y_lo, f.y_hi);
  std::vector<std::pair<double, std::string>> y_ticks;
  if (log_y) {
    // Whole decades; within less than two decades also 2x and 5x.
    f.y_lo = std::floor(f.y_lo * 10) / 10 - 0.05;
    f.y_hi = std::ceil(f.y_hi * 10) / 10 + 0.05;
    const bool fine = f.y_hi - f.y_lo < 2.0;
    for (int e = static_cast<int>(std::floor(f.y_lo)); e <= static_cast<int>(std::ceil(f.y_hi)); ++e) {
      for (const double m : {1.0, 2.0, 5.0}) {
        if (m != 1.0 && !fine) continue;
        const double v = std::log10(m) + e;
        if (v >= f.y_lo && v <= f.y_hi) y_ticks.emplace_back(v, TickLabel(m * std::pow(10.0, e)));
      }
    }
  } else {
    for (double t : NiceTicks(f.y_lo, f.y_hi)) y_ticks.emplace_back(t, TickLabel(t));
  }
  std::ostringstream s;
  s << Open(size) << Axes(f, title, x_label, y_label, NiceTicks(f.x_lo, f.x_hi), y_ticks);
  double legend_y = kTop + 14;
  for (const Series& line : series) {
    std::ostringstream points;
    std::ostringstream markers;
    for (std::size_t i = 0; i < line.x.size() && i < line.y.size(); ++i) {
      if (!std::isfinite(line.x[i]) || !std::isfinite(line.y[i]) || (log_y && line.y[i] <= 0)) continue;
      const double px = f.X(line.x[i]), py = f.Y(y_of(line.y[i]));
      points << Num(px) << "," << Num(py) << " ";
      markers << "<circle cx=\"" << Num(px) << "\" cy=\"" << Num(py) << "\" r=\"2.5\" fill=\"" << line.colour
              << "\"/>\n";
    }
    s << "<polyline points=\"" << points.str() << "\" fill=\"none\" stroke=\"" << line.colour
      << "\" stroke-width=\"1.5\"/>\n"
      << markers.str();
    if (!line.label.empty()) {
      s << Line(size.width - kRight - 150, legend_y - 4, size.width - kRight - 130, legend_y - 4, line.colour,
                2)
        << Text(size.width - kRight - 125, legend_y, line.label, "start");
      legend_y += 16;
    }
  }
  s << "</svg>\n";
  return s.str();
}

std::string Histogram(const std::string& title, const std::string& x_label, const std::vector<double>& edges,
                      const std::vector<double>& counts, Size size) {
  Frame f{size};
  if (edges.size() != counts.size() + 1 || counts.empty()) {
    return Open(size) + Text(size.width / 2.0, size.height / 2.0, title + ": no data") + "</svg>\n";
  }
  f.x_lo = edges.front();
  f.x_hi = edges.back();
  f.y_lo = 0;
  f.y_hi = std::max(1.0, *std::max_element(counts.begin(), counts.end())) * 1.05;
  Widen(f.x_lo, f.x_hi);
  std::vector<std::pair<double, std::string>> y_ticks;
  for (double t : NiceTicks(f.y_lo, f.y_hi, 5)) y_ticks.emplace_back(t, TickLabel(t));
  std::ostringstream s;
  s << Open(size) << Axes(f, title, x_label, "points", NiceTicks(f.x_lo, f.x_hi, 8), y_ticks);
  for (std::size_t i = 0; i < counts.size(); ++i) {
    const double x0 = f.X(edges[i]), x1 = f.X(edges[i + 1]), y = f.Y(counts[i]);
    const double centre = 0.5 * (edges[i] + edges[i + 1]);
    const double range = std::max(std::abs(edges.front()), std::abs(edges.back()));
    s << "<rect x=\"" << Num(x0) << "\" y=\"" << Num(y) << "\" width=\"" << Num(std::max(x1 - x0 - 1, 0.5))
      << "\" height=\"" << Num(f.Y(0) - y) << "\" fill=\"" << DivergingColour(range > 0 ? centre / range : 0)
      << "\" stroke=\"#555\" stroke-width=\"0.5\"/>\n";
  }
  if (f.x_lo < 0 && f.x_hi > 0)
    s << Line(f.X(0), kTop, f.X(0), f.Y(0), "#000", 1, " stroke-dasharray=\"4 3\"");
  s << "</svg>\n";
  return s.str();
}

std::string BarChart(const std::string& title, const std::string& y_label,
                     const std::vector<std::string>& labels, const std::vector<double>& values, Size size) {
  Frame f{size};
  f.x_lo = 0;
  f.x_hi = std::max<double>(1, static_cast<double>(values.size()));
  f.y_lo = 0;
  f.y_hi = 0;
  for (double v : values) {
    if (std::isfinite(v)) {
      f.y_lo = std::min(f.y_lo, v);
      f.y_hi = std::max(f.y_hi, v);
    }
  }
  if (f.y_hi == f.y_lo) f.y_hi = 1;
  f.y_hi += 0.05 * (f.y_hi - f.y_lo);
  std::vector<std::pair<double, std::string>> y_ticks;
  for (double t : NiceTicks(f.y_lo, f.y_hi, 5)) y_ticks.emplace_back(t, TickLabel(t));
  std::ostringstream s;
  s << Open(size) << Axes(f, title, "", y_label, {}, y_ticks);
  for (std::size_t i = 0; i < values.size(); ++i) {
    const double v = std::isfinite(values[i]) ? values[i] : 0.0;
    const double x0 = f.X(static_cast<double>(i) + 0.15), x1 = f.X(static_cast<double>(i) + 0.85);
    const double top = f.Y(std::max(v, 0.0)), bottom = f.Y(std::min(v, 0.0));
    s << "<rect x=\"" << Num(x0) << "\" y=\"" << Num(top) << "\" width=\"" << Num(x1 - x0) << "\" height=\""
      << Num(std::max(bottom - top, 0.5)) << "\" fill=\"#4a7ab5\"/>\n";
    if (i < labels.size()) s << Text((x0 + x1) / 2, size.height - kBottom + 16, labels[i]);
  }
  s << "</svg>\n";
  return s.str();
}

std::string ColouredScatter(const std::string& title, const std::vector<Eigen::Vector2d>& points,
                            const std::vector<double>& values, double range, const std::string& unit,
                            Size size, const std::vector<double>& weights) {
  constexpr int kBar = 90;  // room for the colour bar on the right
  std::ostringstream s;
  s << Open(size) << Text(size.width / 2.0, 20, title, "middle", " font-size=\"14\" font-weight=\"bold\"");
  if (points.empty()) return s.str() + Text(size.width / 2.0, size.height / 2.0, "no points") + "</svg>\n";
  Eigen::Vector2d lo = points.front(), hi = points.front();
  for (const Eigen::Vector2d& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double w = size.width - 20.0 - kBar, h = size.height - 50.0;
  const double extent = std::max({hi.x() - lo.x(), hi.y() - lo.y(), 1e-12});
  const double scale =
      std::min(w / std::max(hi.x() - lo.x(), extent * 1e-3), h / std::max(hi.y() - lo.y(), extent * 1e-3));
  const double ox = 10 + (w - scale * (hi.x() - lo.x())) / 2, oy = 34 + (h - scale * (hi.y() - lo.y())) / 2;
  if (!(range > 0)) range = 1;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double px = ox + scale * (points[i].x() - lo.x());
    const double py = oy + scale * (hi.y() - points[i].y());  // y up
    const double v = i < values.size() ? values[i] : 0.0;
    const double weight = i < weights.size() ? weights[i] : 1.0;
    if (weight < 0.5) {  // down-weighted (green) or rejected (black) by the robust loss: a cross
      const char* colour = weight == 0.0 ? "#000000" : "#1a9641";
      s << "<path d=\"M" << Num(px - 2.2) << " " << Num(py - 2.2) << "l4.4 4.4M" << Num(px - 2.2) << " "
        << Num(py + 2.2) << "l4.4 -4.4\" stroke=\"" << colour << "\" stroke-width=\"0.9\"/>\n";
      continue;
    }
    s << "<circle cx=\"" << Num(px) << "\" cy=\"" << Num(py) << "\" r=\"1.8\" fill=\""
      << DivergingColour(v / range) << "\"/>\n";
  }
  if (!weights.empty()) {
    s << "<path d=\"M14 " << Num(size.height - 14.0) << "l5 5M14 " << Num(size.height - 9.0)
      << "l5 -5\" stroke=\"#1a9641\"/>\n"
      << Text(24, size.height - 8.0, "down-weighted (robust weight < 0.5)", "start") << "<path d=\"M260 "
      << Num(size.height - 14.0) << "l5 5M260 " << Num(size.height - 9.0) << "l5 -5\" stroke=\"#000000\"/>\n"
      << Text(270, size.height - 8.0, "rejected (weight 0)", "start");
  }
  // Colour bar: +range at the top, -range at the bottom.
  const double bx = size.width - kBar + 20.0, by = 40.0, bh = size.height - 80.0;
  constexpr int kSteps = 20;
  for (int k = 0; k < kSteps; ++k) {
    const double t = 1.0 - 2.0 * (k + 0.5) / kSteps;
    s << "<rect x=\"" << Num(bx) << "\" y=\"" << Num(by + bh * k / kSteps) << "\" width=\"14\" height=\""
      << Num(bh / kSteps + 0.5) << "\" fill=\"" << DivergingColour(t) << "\"/>\n";
  }
  s << "<rect x=\"" << Num(bx) << "\" y=\"" << Num(by) << "\" width=\"14\" height=\"" << Num(bh)
    << "\" fill=\"none\" stroke=\"#444\"/>\n"
    << Text(bx + 18, by + 4, "+" + TickLabel(range), "start") << Text(bx + 18, by + bh / 2 + 4, "0", "start")
    << Text(bx + 18, by + bh + 4, "-" + TickLabel(range), "start") << Text(bx + 7, by + bh + 22, unit);
  s << "</svg>\n";
  return s.str();
}

std::string CurvatureComb(const std::string& title, const std::vector<Eigen::Vector2d>& points,
                          const std::vector<Eigen::Vector2d>& tips,
                          const std::vector<Eigen::Vector2d>& junctions, int tooth_every, Size size) {
  std::ostringstream s;
  s << Open(size) << Text(size.width / 2.0, 20, title, "middle", " font-size=\"14\" font-weight=\"bold\"");
  if (points.empty() || tips.size() != points.size())
    return s.str() + Text(size.width / 2.0, size.height / 2.0, "no curve") + "</svg>\n";
  Eigen::Vector2d lo = points.front(), hi = points.front();
  for (const auto* set : {&points, &tips})
    for (const Eigen::Vector2d& p : *set) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
  const double w = size.width - 20.0, h = size.height - 50.0;
  const double extent = std::max({hi.x() - lo.x(), hi.y() - lo.y(), 1e-12});
  const double scale =
      std::min(w / std::max(hi.x() - lo.x(), extent * 1e-3), h / std::max(hi.y() - lo.y(), extent * 1e-3));
  const double ox = 10 + (w - scale * (hi.x() - lo.x())) / 2, oy = 34 + (h - scale * (hi.y() - lo.y())) / 2;
  auto x = [&](const Eigen::Vector2d& p) { return Num(ox + scale * (p.x() - lo.x())); };
  auto y = [&](const Eigen::Vector2d& p) { return Num(oy + scale * (hi.y() - p.y())); };  // y up
  const int every = std::max(1, tooth_every);
  s << "<path d=\"";
  for (std::size_t i = 0; i < points.size(); i += static_cast<std::size_t>(every))
    s << "M" << x(points[i]) << " " << y(points[i]) << "L" << x(tips[i]) << " " << y(tips[i]);
  s << "\" stroke=\"#9ab6d8\" stroke-width=\"0.7\" fill=\"none\"/>\n";
  auto polyline = [&](const std::vector<Eigen::Vector2d>& v, const char* colour, double width) {
    s << "<polyline fill=\"none\" stroke=\"" << colour << "\" stroke-width=\"" << width << "\" points=\"";
    for (const Eigen::Vector2d& p : v) s << x(p) << "," << y(p) << " ";
    s << "\"/>\n";
  };
  polyline(tips, "#1f5fa8", 1.0);    // the envelope
  polyline(points, "#222222", 1.6);  // the curve
  for (const Eigen::Vector2d& j : junctions)
    s << "<circle cx=\"" << x(j) << "\" cy=\"" << y(j) << "\" r=\"2.5\" fill=\"none\" stroke=\"#b2182b\"/>\n";
  return s.str() + "</svg>\n";
}

}  // namespace s2m::pipeline::svg
