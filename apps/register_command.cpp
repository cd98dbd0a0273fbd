// `scan2model register`: the command line of ComputeRegistration (pipeline/view_registration.h, docs/cli.md).
#include <iostream>

#include "acquisition/format_error.h"
#include "apps/commands.h"
#include "pipeline/output.h"
#include "pipeline/view_registration.h"

namespace s2m::app {

Runner AddRegisterCommand(CLI::App& app) {
  auto o = std::make_shared<RegisterOptions>();
  auto quiet = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand(
      "register",
      "Register the views of a part to each other (all views globally, no model), to a nominal mesh or to a "
      "fitted part, and write the corrected poses as a views manifest");
  cmd->add_option("views", o->input,
                  "The views: a views.json manifest, a Stanford .conf, a recording (.s2mrec) or an E57 file")
      ->required();
  cmd->add_option("--to", o->to,
                  "Register the views to a nominal mesh (.stl binary or ASCII, .obj, .ply), to the part a "
                  "'fit --model part:' result measured or to the surface 'fit --model fe-surface' fitted "
                  "(their -o PREFIX.json); default: to each other");
  cmd->add_option("--method", o->method,
                  "Error term: tdm (point-to-plane, default), sdm (squared distance), pdm (point-to-point)");
  cmd->add_option(
      "-o,--output", o->output,
      "Write the registered views manifest (scan2model.views/1 .json, one PLY per view beside it)");
  cmd->add_option("--samples", o->samples_per_view,
                  "Scan-to-scan: samples of each view paired per sweep (default 1500)")
      ->check(CLI::Range(1, 100000000));
  cmd->add_option("--max-sweeps", o->max_sweeps, "Scan-to-scan: at most this many sweeps (default 50)")
      ->check(CLI::Range(1, 100000));
  cmd->add_option("--fixed-view", o->fixed_view,
                  "Scan-to-scan: the view that keeps its pose (default 0); the others move relative to it");
  cmd->add_option("--units", o->units, "The nominal's units when its file states none (default: the views')");
  cmd->add_flag("!--no-per-view", o->per_view,
                "To a nominal: register all views as one rigid body only (their relative poses kept)");
  cmd->add_flag("--json", o->json, "Print the scan2model.registration/1 document instead of the text");
  cmd->add_flag("-q,--quiet", *quiet, "No progress on standard error");
  return [o, quiet]() {
    try {
      RegisterProgress progress;
      if (!*quiet)
        progress = [](const std::string& line) { std::cerr << "scan2model register: " << line << "\n"; };
      const RegisterOutcome outcome = ComputeRegistration(*o, progress);
      for (const std::string& note : outcome.notes)
        std::cerr << "scan2model register: note: " << note << "\n";
      if (o->json)
        std::cout << outcome.document.dump(2) << "\n";
      else
        std::cout << outcome.text;
      return outcome.unregistered_views.empty() ? int{kOk} : int{kFitError};
    } catch (const FitFailure& e) {
      return ReportError("register", e.what(), e.exit_code(), o->json);
    } catch (const FormatError& e) {
      return ReportError("register", e.what(), kInputError, o->json);
    }
  };
}

}  // namespace s2m::app
