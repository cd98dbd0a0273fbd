#pragma once
// Helpers several test files share: fresh temporary folders, running a command line, signalling a child.

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

namespace s2m::test {

// An empty folder under the system's temporary directory, unique to this process and `name`.
inline std::filesystem::path FreshTempDir(const std::string& name) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("s2m_" + name + "_" + std::to_string(getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

struct ShellResult {
  int exit_code = -1;  // -1: killed by a signal
  int signal = 0;
  std::string out;  // stdout, with stderr unless `merge_stderr` was false (then stderr is discarded)
};

// Runs a shell command line.
inline ShellResult Shell(const std::string& command, bool merge_stderr = true) {
  ShellResult r;
  FILE* pipe = popen((command + (merge_stderr ? " 2>&1" : " 2>/dev/null")).c_str(), "r");
  if (pipe == nullptr) return r;
  char buffer[4096];
  std::size_t n;
  while ((n = fread(buffer, 1, sizeof buffer, pipe)) > 0) r.out.append(buffer, n);
  const int status = pclose(pipe);
  if (WIFEXITED(status)) {
    r.exit_code = WEXITSTATUS(status);
    if (r.exit_code > 128)
      r.signal = r.exit_code - 128;  // the shell reports a child killed by signal s as 128+s
  } else if (WIFSIGNALED(status)) {
    r.signal = WTERMSIG(status);
  }
  return r;
}

// The arguments as one shell command line, each single-quoted.
inline std::string Quote(const std::vector<std::string>& argv) {
  std::string line;
  for (const std::string& a : argv) {
    std::string quoted = "'";
    for (const char c : a) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
    line += (line.empty() ? "" : " ") + quoted + "'";
  }
  return line;
}

// A command run as a child (no shell) that gets `signal_number` after `delay_ms` milliseconds unless it has
// ended by then; its standard output and error go to `log`.
struct SignalledRun {
  int exit_code = -1;      // -1: ended by a signal
  int signal = 0;          // the signal that ended it, 0 when it exited
  bool signalled = false;  // the signal was sent (the child was still running at the delay)
  std::string log;
};
// As RunAndSignal below, but the signal goes when `ready()` first returns true (polled every 0.2 ms), or
// after `timeout_ms` if it never does.
inline SignalledRun RunAndSignalWhen(const std::vector<std::string>& argv, const std::function<bool()>& ready,
                                     int timeout_ms, int signal_number, const std::filesystem::path& log) {
  SignalledRun r;
  const pid_t pid = fork();
  if (pid == 0) {
    const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(fd, 1);
    dup2(fd, 2);
    std::vector<char*> args;
    for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    execv(args[0], args.data());
    _exit(127);
  }
  if (pid < 0) return r;
  int status = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  while (waitpid(pid, &status, WNOHANG) == 0) {
    if (ready() || std::chrono::steady_clock::now() >= deadline) {
      kill(pid, signal_number);
      r.signalled = true;
      waitpid(pid, &status, 0);
      break;
    }
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  if (WIFEXITED(status)) r.exit_code = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) r.signal = WTERMSIG(status);
  std::ifstream in(log);
  r.log.assign(std::istreambuf_iterator<char>(in), {});
  return r;
}
inline SignalledRun RunAndSignal(const std::vector<std::string>& argv, int delay_ms, int signal_number,
                                 const std::filesystem::path& log) {
  return RunAndSignalWhen(
      argv, [] { return false; }, delay_ms, signal_number, log);
}

}  // namespace s2m::test
