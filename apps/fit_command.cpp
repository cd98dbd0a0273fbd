// `scan2model fit`: the command line of ComputeFit (pipeline/fit_options.h).
#include <iostream>
#include <set>

#include "apps/commands.h"
#include "pipeline/fit_option_table.h"
#include "pipeline/fit_options.h"
#include "pipeline/output.h"

namespace s2m::app {
namespace {

// The help line: the table's text, its default and, for a manifest key, that key.
std::string Help(const FitOptionSpec& spec) {
  std::string help = spec.help;
  if (!spec.default_text.empty()) help += " (default " + spec.default_text + ")";
  if (!spec.key.empty()) help += " [batch manifest: " + spec.key + "]";
  return help;
}

// One row of the fit option table as CLI11 options: the value checked and applied by the table itself, so
// that the command line and the manifest accept exactly the same values.
void AddTableOption(CLI::App& cmd, const FitOptionSpec& spec, const std::shared_ptr<FitOptions>& o) {
  if (spec.choices_as_flags) {
    // Each choice a flag of its own; the first (the default, stated explicitly) excludes the others.
    CLI::Option* first = nullptr;
    for (const std::string& choice : spec.choices) {
      CLI::Option* flag = cmd.add_flag_function(
          "--" + choice, [&spec, o, choice](std::int64_t) { ApplyFitOption(spec, choice, *o); },
          "Multi-view solver: " + choice + (first == nullptr ? " (the default)" : "") + "; " + spec.help);
      if (first == nullptr) {
        first = flag;
      } else {
        flag->excludes(first);
      }
    }
    return;
  }
  if (spec.kind == FitOptionKind::kFlag) {
    cmd.add_flag_function(
        spec.names, [&spec, o](std::int64_t) { ApplyFitOption(spec, "true", *o); }, Help(spec));
    return;
  }
  cmd.add_option_function<std::string>(
         spec.names, [&spec, o](const std::string& text) { ApplyFitOption(spec, text, *o); }, Help(spec))
      ->check(CLI::Validator(
          [&spec](std::string& text) {
            try {
              ParseFitOption(spec, text);
              return std::string();
            } catch (const std::invalid_argument& e) {
              return std::string(e.what());
            }
          },
          spec.kind == FitOptionKind::kChoice ? "CHOICE"
          : spec.kind == FitOptionKind::kPath ? "FILE"
                                              : "VALUE"));
}

}  // namespace

Runner AddFitCommand(CLI::App& app) {
  auto o = std::make_shared<FitOptions>();
  CLI::App* cmd =
      app.add_subcommand("fit", "Fit a model to a point cloud by orthogonal-distance least squares");
  cmd->add_option("file", o->file,
                  "Input: a point cloud (.ply, .ply.gz, .pcd, .xyz/.txt/.csv/.pts, .ds), a glyph (.glif) for "
                  "curves, or "
                  "several views (.json manifest, Stanford .conf) for --model revolution, helical, spiral "
                  "and part:FILE")
      ->required();
  cmd->add_option(
         "--model,-m", o->model,
         "Model to fit: plane, sphere, cylinder, cone, line, circle, torus, bspline-curve, bspline-surface, "
         "hermite-curve, fe-surface, revolution, helical, spiral, or part:FILE (a constrained part, "
         "docs/parts.md)")
      ->required()
      ->check(CLI::Validator([](std::string& model) { return ModelError(model); }, "MODEL"));
  // The other options come from the table the batch manifest's keys come from too.
  for (const FitOptionSpec& spec : FitOptionTable()) AddTableOption(*cmd, spec, o);
  return [o]() { return RunFit(*o); };
}

int RunFit(const FitOptions& given) {
  FitOptions o = given;
  // Progress of long work on standard error, one line rewritten in place.
  bool progressed = false;
  std::size_t previous = 0;  // a shorter line is padded over the longer one before it
  o.progress = [&progressed, &previous](const std::string& line) {
    std::cerr << "\rscan2model fit: " << line
              << std::string(previous > line.size() ? previous - line.size() : 0, ' ') << std::flush;
    previous = line.size();
    progressed = true;
  };
  try {
    const FitOutcome outcome = ComputeFit(o);
    if (progressed) std::cerr << "\n";
    for (const std::string& note : outcome.notes) std::cerr << "scan2model fit: note: " << note << "\n";
    if (o.json) {
      std::cout << outcome.document.dump(2) << "\n";
    } else {
      std::cout << outcome.text;
    }
    return kOk;
  } catch (const FitFailure& e) {
    if (progressed) std::cerr << "\n";
    return ReportError("fit", e.what(), e.exit_code(), o.json);
  }
}

}  // namespace s2m::app
