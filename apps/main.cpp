// scan2model: from scanner views to measured models. See README.md and docs/cli.md.

#include <exception>
#include <iostream>

#include "apps/commands.h"

#ifndef S2M_VERSION
#define S2M_VERSION "unknown"
#endif

int main(int argc, char** argv) {
  CLI::App app{"scan2model: fit models to multi-view scans (SDM/TDM/PDM registration and fitting)",
               "scan2model"};
  app.set_version_flag("--version", std::string("scan2model ") + S2M_VERSION);
  app.require_subcommand(1);
  app.footer(
      "Run 'scan2model <command> --help' for a command's options. Exit codes: 0 ok, 2 usage, "
      "3 bad input, 4 fit failed, 5 device error.");
  const s2m::app::Runner info = s2m::app::AddInfoCommand(app);
  const s2m::app::Runner fit = s2m::app::AddFitCommand(app);
  const s2m::app::Runner detect = s2m::app::AddDetectCommand(app);
  const s2m::app::Runner record = s2m::app::AddRecordCommand(app);
  const s2m::app::Runner export_views = s2m::app::AddExportCommand(app);
  const s2m::app::Runner batch = s2m::app::AddBatchCommand(app);
  const s2m::app::Runner report = s2m::app::AddReportCommand(app);
  const s2m::app::Runner inspect = s2m::app::AddInspectCommand(app);
  const s2m::app::Runner register_views = s2m::app::AddRegisterCommand(app);
  const s2m::app::Runner scan = s2m::app::AddScanCommand(app);
  const s2m::app::Runner devices = s2m::app::AddDevicesCommand(app);
  const s2m::app::Runner interrogate = s2m::app::AddInterrogateCommand(app);
#ifdef S2M_HAVE_HORUS
  const s2m::app::Runner calibrate = s2m::app::AddCalibrateCommand(app);
#endif
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return s2m::app::kUsage;
  }
  try {
    if (app.got_subcommand("info")) return info();
    if (app.got_subcommand("fit")) return fit();
    if (app.got_subcommand("detect")) return detect();
    if (app.got_subcommand("record")) return record();
    if (app.got_subcommand("export")) return export_views();
    if (app.got_subcommand("batch")) return batch();
    if (app.got_subcommand("report")) return report();
    if (app.got_subcommand("inspect")) return inspect();
    if (app.got_subcommand("register")) return register_views();
    if (app.got_subcommand("scan")) return scan();
    if (app.got_subcommand("devices")) return devices();
    if (app.got_subcommand("interrogate")) return interrogate();
#ifdef S2M_HAVE_HORUS
    if (app.got_subcommand("calibrate")) return calibrate();
#endif
  } catch (const std::exception& e) {
    std::cerr << "scan2model: internal error: " << e.what() << "\n";
    return s2m::app::kInternal;
  }
  return s2m::app::kUsage;
}
