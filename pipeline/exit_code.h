#pragma once
// Exit codes of `scan2model`, stable across releases (docs/cli.md). They live in the pipeline library because
// a failed fit or batch object carries one (FitFailure, the batch records) long before a process exits.

namespace s2m::pipeline {

enum ExitCode : int {
  kOk = 0,
  kUsage = 2,       // bad command line
  kInputError = 3,  // unreadable, corrupt, empty or degenerate input
  kFitError = 4,    // the fit could not be computed
  kInternal = 70,   // a bug: please report it
  // A device failed: not found, no permission, disconnected, timed out (docs/horus-scan.md).
  kDeviceError = 5,
  // Stopped by SIGINT or SIGTERM at a safe point: everything finished is written, a rerun resumes
  // (`batch`, `record`, `scan`; docs/reliability.md).
  kInterrupted = 6,
};

}  // namespace s2m::pipeline
