#include "apps/stop_signal.h"

#include <csignal>
#include <stdexcept>

namespace s2m::app {
namespace {

std::atomic<bool> g_stop{false};
std::atomic<int> g_signal{0};
std::atomic<bool> g_installed{false};
struct sigaction g_previous_int, g_previous_term;

// Async-signal-safe: lock-free atomics, sigaction and raise only.
extern "C" void OnStopSignal(int signal_number) {
  if (g_stop.exchange(true)) {
    // The second signal: the default action now (the process ends as it would have without us).
    struct sigaction default_action {};
    default_action.sa_handler = SIG_DFL;
    sigemptyset(&default_action.sa_mask);
    sigaction(signal_number, &default_action, nullptr);
    raise(signal_number);
    return;
  }
  g_signal = signal_number;
}

}  // namespace

StopOnSignals::StopOnSignals() {
  static_assert(std::atomic<bool>::is_always_lock_free && std::atomic<int>::is_always_lock_free);
  if (g_installed.exchange(true)) throw std::logic_error("StopOnSignals: only one at a time");
  g_stop = false;
  g_signal = 0;
  struct sigaction action {};
  action.sa_handler = OnStopSignal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = SA_RESTART;  // reads and writes in flight go on; the work polls the flag
  sigaction(SIGINT, &action, &g_previous_int);
  sigaction(SIGTERM, &action, &g_previous_term);
}

StopOnSignals::~StopOnSignals() {
  sigaction(SIGINT, &g_previous_int, nullptr);
  sigaction(SIGTERM, &g_previous_term, nullptr);
  g_installed = false;
}

bool StopOnSignals::Requested() {
  return g_stop.load();
}

const std::atomic<bool>& StopOnSignals::Flag() {
  return g_stop;
}

std::string StopOnSignals::SignalName() {
  switch (g_signal.load()) {
    case SIGINT:
      return "SIGINT";
    case SIGTERM:
      return "SIGTERM";
    default:
      return "";
  }
}

}  // namespace s2m::app
