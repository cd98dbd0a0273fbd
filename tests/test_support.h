#pragma once
// Helpers several test files share: fresh temporary folders and running a command line.

#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <string>

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

}  // namespace s2m::test
