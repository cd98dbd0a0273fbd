// `scan2model inspect`: scan views against a nominal mesh (pipeline/inspection.h, docs/metrology.md).
#include <iostream>

#include "acquisition/format_error.h"
#include "apps/commands.h"
#include "pipeline/inspection.h"
#include "pipeline/output.h"

#ifndef S2M_VERSION
#define S2M_VERSION "unknown"
#endif

namespace s2m::app {

Runner AddInspectCommand(CLI::App& app) {
  auto o = std::make_shared<InspectOptions>();
  CLI::App* cmd = app.add_subcommand(
      "inspect",
      "Compare scan views with a nominal mesh (STL, OBJ, PLY): registration, signed deviations per face "
      "group, "
      "GD&T checks with uncertainties and ISO 14253-1 decisions, a metrology report (docs/metrology.md)");
  cmd->add_option("views", o->input,
                  "The scan: a point cloud, a views.json manifest, a recording (.s2mrec) or an E57 file")
      ->required();
  cmd->add_option("--nominal", o->nominal, "The nominal mesh: .stl (binary or ASCII), .obj, .ply")
      ->required();
  cmd->add_option("--part", o->checks,
                  "A checks file (scan2model.checks/1): profile, flatness, position, diameter");
  cmd->add_option("--output,-o", o->output,
                  "PREFIX: writes PREFIX.json, PREFIX.html and PREFIX_deviations.csv");
  cmd->add_option("--units", o->units, "The nominal's units when its file states none (default: the views')");
  cmd->add_option("--method", o->method, "Registration error term: sdm (default), tdm, pdm");
  cmd->add_option("--datum", o->datums,
                  "A face group to align on (repeat for several; overrides the checks file's \"datums\")");
  cmd->add_flag("!--no-per-view", o->per_view, "Register all views as one rigid body only");
  cmd->add_option("--uncertainty", o->uncertainty, "none | linear (default) | monte-carlo:N");
  cmd->add_option("--seed", o->seed, "Monte Carlo seed (default 1)");
  cmd->add_option("--operator", o->operator_name, "The operator named in the report's traceability block");
  cmd->add_flag("--json", o->json, "Print the scan2model.inspection/1 document instead of the text");
  return [o]() {
    o->software_version = S2M_VERSION;
    try {
      const InspectOutcome outcome = ComputeInspection(*o);
      for (const std::string& note : outcome.notes) std::cerr << "note: " << note << "\n";
      if (o->json)
        std::cout << outcome.document.dump(2) << "\n";
      else
        std::cout << outcome.text;
      return int{kOk};
    } catch (const FitFailure& e) {
      return ReportError("inspect", e.what(), e.exit_code(), o->json);
    } catch (const FormatError& e) {
      return ReportError("inspect", e.what(), kInputError, o->json);
    }
  };
}

}  // namespace s2m::app
