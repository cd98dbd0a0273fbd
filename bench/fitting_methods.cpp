// Iterations and time each error term needs to reach a common RMS on the paper's test cases (docs/method.md
// section 11): sparse non-uniform points on a circle, points on a square from a one-sided start, and the
// glyph outlines. The common target is 5 % above the lowest RMS any method reaches within 300 iterations.
// Prints a markdown table. Usage: fitting_methods [path/to/font_glyphs]   (default:
// ../shared/data/font_glyphs beside the repository). The same cases run in the compare driver
// (docs/benchmarks.md), which adds a surface case.

#include <cstdio>
#include <filesystem>
#include <string>

#include "bench/fitting_method_cases.h"

using namespace s2m;

int main(int argc, char** argv) {
  const std::filesystem::path glyphs =
      argc > 1 ? std::filesystem::path(argv[1])
               : std::filesystem::path(S2M_SOURCE_DIR) / ".." / "shared" / "data" / "font_glyphs";
  std::printf(
      "| case | method | iterations to target | time to target (ms) | ms / iteration | lowest RMS in 300 | "
      "iterations vs SDM |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  for (const bench::FittingCase& c : bench::FittingCases(glyphs, false)) {
    const std::vector<bench::MethodRow> rows = bench::RunFittingMethods(c, 300);
    const bench::MethodRow& sdm = rows[2];
    for (const bench::MethodRow& r : rows) {
      char it[32] = "not reached", ms[32] = "-", ratio[32] = "-";
      if (r.iterations_to_target > 0) {
        std::snprintf(it, sizeof it, "%d", r.iterations_to_target);
        std::snprintf(ms, sizeof ms, "%.2f", r.seconds_to_target * 1e3);
        if (sdm.iterations_to_target > 0)
          std::snprintf(ratio, sizeof ratio, "%.1fx",
                        static_cast<double>(r.iterations_to_target) / sdm.iterations_to_target);
      }
      std::printf("| %s (target RMS %.3g) | %s | %s | %s | %.3f | %.4g | %s |\n", c.name.c_str(),
                  r.target_rms, ToString(r.method), it, ms, r.seconds_per_iteration * 1e3, r.lowest_rms,
                  ratio);
    }
  }
  return 0;
}
