#pragma once
// The `scan2model` subcommands. Each registers its options on the app and returns the function that runs it.

#include <CLI/CLI.hpp>
#include <functional>

#include "pipeline/exit_code.h"
#include "pipeline/fit_options.h"

namespace s2m::app {

// The commands are thin: they wire CLI11 to the pipeline library (pipeline/), whose names they use
// unqualified.
using namespace s2m::pipeline;

using Runner = std::function<int()>;

Runner AddInfoCommand(CLI::App& app);
Runner AddFitCommand(CLI::App& app);
// `scan2model fit`: ComputeFit, then the text or JSON on standard output (notes and errors on standard
// error); returns the exit code.
int RunFit(const FitOptions& o);
Runner AddDetectCommand(CLI::App& app);  // apps/detect_command.cpp, docs/cli.md
Runner AddRecordCommand(CLI::App& app);  // apps/acquire_commands.cpp
Runner AddExportCommand(CLI::App& app);
Runner AddBatchCommand(CLI::App& app);        // apps/batch_command.cpp, docs/batch.md
Runner AddReportCommand(CLI::App& app);       // apps/report_command.cpp
Runner AddInspectCommand(CLI::App& app);      // apps/inspect_command.cpp, docs/metrology.md
Runner AddRegisterCommand(CLI::App& app);     // apps/register_command.cpp, docs/cli.md
Runner AddScanCommand(CLI::App& app);         // apps/scan_command.cpp, docs/horus-scan.md
Runner AddDevicesCommand(CLI::App& app);      // apps/devices_command.cpp, docs/devices.md
Runner AddCalibrateCommand(CLI::App& app);    // apps/calibrate_command.cpp, docs/laser-scanning.md
Runner AddInterrogateCommand(CLI::App& app);  // apps/interrogate_command.cpp, docs/interrogation.md

}  // namespace s2m::app
