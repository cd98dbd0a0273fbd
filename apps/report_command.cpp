// `scan2model report`: the command line of ReportHtml (pipeline/report.h).
#include <fstream>

#include "acquisition/format_error.h"
#include "apps/commands.h"
#include "pipeline/output.h"
#include "pipeline/report.h"

namespace s2m::app {

Runner AddReportCommand(CLI::App& app) {
  struct Options {
    std::string input, output;
  };
  auto o = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand(
      "report", "Write a self-contained HTML report (inline SVG plots, no network) of a fit's JSON result");
  cmd->add_option("result", o->input,
                  "A result document: `fit --json` output, `fit -o PREFIX`'s PREFIX.json, or a batch object "
                  "(OUTPUT/objects/ID.json)")
      ->required();
  cmd->add_option("--output,-o", o->output, "The HTML file to write")->required();
  return [o]() {
    try {
      std::ifstream in(o->input);
      if (!in) throw FormatError(o->input, "", "cannot open");
      nlohmann::json j;
      try {
        j = nlohmann::json::parse(in);
      } catch (const nlohmann::json::exception& e) {
        throw FormatError(o->input, "", std::string("not valid JSON: ") + e.what());
      }
      std::string html;
      try {
        html = ReportHtml(j);
      } catch (const std::exception& e) {  // missing members, wrong types: not a result we know
        throw FormatError(o->input, "", e.what());
      }
      WriteTextAtomically(o->output, html);
      return int{kOk};
    } catch (const FormatError& e) {
      return ReportError("report", e.what(), kInputError, false);
    }
  };
}

}  // namespace s2m::app
