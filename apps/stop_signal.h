#pragma once
// SIGINT and SIGTERM ask a long command (batch, record, scan) to stop at its next safe point: the work in
// flight is finished and written, nothing half-written is left, and the command says how to resume
// (docs/reliability.md). A second signal while stopping ends the process at once with the signal's default
// action, which is safe too: every result and frame is written atomically.

#include <atomic>
#include <string>

namespace s2m::app {

// While alive, SIGINT and SIGTERM set the stop flag instead of ending the process; the handlers in place
// before are restored by the destructor. One at a time.
class StopOnSignals {
 public:
  StopOnSignals();
  ~StopOnSignals();
  StopOnSignals(const StopOnSignals&) = delete;
  StopOnSignals& operator=(const StopOnSignals&) = delete;

  // True once a signal asked to stop (readable from any thread).
  static bool Requested();
  // The flag itself, for code that takes an atomic to poll (pipeline::BatchOptions::stop).
  static const std::atomic<bool>& Flag();
  // "SIGTERM" or "SIGINT" (the first one received), empty when none was.
  static std::string SignalName();
};

}  // namespace s2m::app
