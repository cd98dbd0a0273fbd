#pragma once
// Small SVG plots for reports and drawings (self-contained markup, no scripts, no external resources). Every
// function returns one well-formed <svg> element with its xmlns, usable inline in HTML or as a file.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace s2m::pipeline::svg {

// Text escaped for XML character data and attribute values.
std::string Escape(const std::string& text);
// A coordinate or value for markup: finite, at most 4 decimals, no exponent for ordinary magnitudes.
std::string Num(double value);
// "Nice" tick values (1, 2, 5 x 10^k steps) covering [lo, hi], about `target` of them.
std::vector<double> NiceTicks(double lo, double hi, int target = 6);
// A <text> element at (x, y), its text escaped; `extra` is more attributes, written as given (with a
// leading space).
std::string Text(double x, double y, const std::string& text, const std::string& anchor = "middle",
                 const std::string& extra = "");
// A <line> element; `extra` as for Text.
std::string Line(double x1, double y1, double x2, double y2, const std::string& stroke, double width = 1.0,
                 const std::string& extra = "");
// A diverging colour for t in [-1, 1]: blue (negative), white (0), red (positive), as #rrggbb.
std::string DivergingColour(double t);
// The same colour as 8-bit red, green, blue (the raster images of pipeline/surface_render.h).
std::array<std::uint8_t, 3> DivergingRgb(double t);

struct Series {
  std::vector<double> x, y;
  std::string colour = "#1f5fa8";
  std::string label;
};

struct Size {
  int width = 640;
  int height = 320;
};

// Lines with markers; with `log_y` the y axis is logarithmic (non-positive values are left out).
std::string LinePlot(const std::string& title, const std::string& x_label, const std::string& y_label,
                     const std::vector<Series>& series, bool log_y, Size size = {});
// Bars over consecutive bins: edges has one more entry than counts.
std::string Histogram(const std::string& title, const std::string& x_label, const std::vector<double>& edges,
                      const std::vector<double>& counts, Size size = {});
// One bar per label.
std::string BarChart(const std::string& title, const std::string& y_label,
                     const std::vector<std::string>& labels, const std::vector<double>& values,
                     Size size = {});
// Points (already projected to 2D, equal scale on both axes) coloured by value in [-range, range], with a
// colour bar labelled in `unit`. With `weights` (a robust fit's IRLS weights, one per point), points with
// weight below 0.5 are drawn as green crosses (down-weighted) and weight 0 as black crosses (rejected),
// with a legend.
std::string ColouredScatter(const std::string& title, const std::vector<Eigen::Vector2d>& points,
                            const std::vector<double>& values, double range, const std::string& unit,
                            Size size = {}, const std::vector<double>& weights = {});

// A plane curve's curvature comb (docs/fair-curves.md section 6): the curve (polyline through `points`), a
// tooth from each point to its `tips` entry (every `tooth_every`-th), the envelope through the tips, and the
// junctions as small circles. Equal scale on both axes.
std::string CurvatureComb(const std::string& title, const std::vector<Eigen::Vector2d>& points,
                          const std::vector<Eigen::Vector2d>& tips,
                          const std::vector<Eigen::Vector2d>& junctions, int tooth_every = 2,
                          Size size = {640, 480});

}  // namespace s2m::pipeline::svg
