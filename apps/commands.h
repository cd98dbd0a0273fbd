#pragma once
// The `scan2model` subcommands. Each registers its options on the app and returns the function that runs it.

#include <CLI/CLI.hpp>
#include <functional>

namespace s2m::app {

// Exit codes, stable across releases (docs/cli.md).
enum ExitCode : int {
  kOk = 0,
  kUsage = 2,       // bad command line
  kInputError = 3,  // unreadable, corrupt, empty or degenerate input
  kFitError = 4,    // the fit could not be computed
  kInternal = 70,   // a bug: please report it
};

using Runner = std::function<int()>;

Runner AddInfoCommand(CLI::App& app);
Runner AddFitCommand(CLI::App& app);
Runner AddRecordCommand(CLI::App& app);  // apps/acquire_commands.cpp
Runner AddExportCommand(CLI::App& app);
Runner AddBatchCommand(CLI::App& app);   // apps/batch_command.cpp, docs/batch.md
Runner AddReportCommand(CLI::App& app);  // apps/report.cpp
Runner AddDevicesCommand(CLI::App& app);  // apps/devices_command.cpp, docs/devices.md
Runner AddCalibrateCommand(CLI::App& app);  // apps/calibrate_command.cpp, docs/laser-scanning.md

}  // namespace s2m::app
