#include "pipeline/complexity.h"

#include <cmath>
#include <iomanip>
#include <sstream>
#include <stdexcept>

#include "pipeline/output.h"

namespace s2m::pipeline {
namespace {

int PositiveCount(const std::string& text, const std::string& whole) {
  std::size_t used = 0;
  int n = 0;
  try {
    n = std::stoi(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size() || n < 2)
    throw std::invalid_argument("--control-points '" + whole + "': '" + text +
                                "' is not a count of at least 2");
  return n;
}

}  // namespace

ControlPointRequest ParseControlPoints(const std::string& text, bool surface) {
  ControlPointRequest r;
  if (text.empty() || text == "auto") return r;
  if (text.rfind("auto:", 0) == 0) {
    r.max = PositiveCount(text.substr(5), text);
    return r;
  }
  r.automatic = false;
  const std::size_t x = text.find('x');
  if (surface != (x != std::string::npos)) {
    throw std::invalid_argument("--control-points '" + text + "': expected auto, auto:MAX or " +
                                (surface ? "NUxNV (e.g. 8x6)" : "a count (e.g. 12)"));
  }
  if (surface) {
    r.first = PositiveCount(text.substr(0, x), text);
    r.second = PositiveCount(text.substr(x + 1), text);
  } else {
    r.first = PositiveCount(text, text);
  }
  return r;
}

nlohmann::json ComplexityJson(const ComplexityChoice& c, const ComplexityOptions& o) {
  nlohmann::json steps = nlohmann::json::array();
  for (const ComplexityStep& s : c.steps) {
    steps.push_back({{"control_points", s.control_points},
                     {"parameters", s.parameters},
                     {"points", s.points},
                     {"rms", s.rms},
                     {"bic", s.bic},
                     {"band_rms", NumberOrNull(s.band_rms)},
                     {"adequate", s.adequate ? nlohmann::json(*s.adequate) : nlohmann::json(nullptr)},
                     {"iterations", s.iterations},
                     {"valid", s.valid}});
  }
  return {{"mode", c.mode},
          {"chosen", c.steps.at(c.chosen).control_points},
          {"stop_reason", c.stop_reason},
          {"criterion", "bic"},
          {"significance", o.significance},
          {"noise_estimate", NumberOrNull(o.noise)},
          {"noise_dof", NumberOrNull(o.noise_dof)},
          {"steps", steps}};
}

std::string ComplexityText(const ComplexityChoice& c) {
  std::ostringstream t;
  const ComplexityStep& chosen = c.steps.at(c.chosen);
  t << "  control points    " << chosen.control_points << " (" << c.mode << ": " << c.stop_reason << ")\n";
  if (c.steps.size() > 1) {
    t << "    " << std::setw(10) << "count" << std::setw(14) << "RMS" << std::setw(14) << "band RMS"
      << std::setw(16) << "BIC"
      << "  adequate\n";
    for (std::size_t i = 0; i < c.steps.size(); ++i) {
      const ComplexityStep& s = c.steps[i];
      t << "    " << std::setw(10) << s.control_points << std::setw(14) << Format(s.rms, 6) << std::setw(14)
        << (std::isfinite(s.band_rms) ? Format(s.band_rms, 6) : std::string("-")) << std::setw(16)
        << Format(s.bic, 8) << "  " << (s.adequate ? (*s.adequate ? "yes" : "no") : "-")
        << (s.valid ? "" : "  (folded: not used)") << (i == c.chosen ? "  <- chosen" : "") << "\n";
    }
  }
  return t.str();
}

}  // namespace s2m::pipeline
