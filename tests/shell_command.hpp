// Test helper: runs a shell command and reads what it writes to its standard output.
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <string>

namespace subslip::testing {

struct CommandOutput {
  int code;         // the exit code; -1 when the command did not exit normally
  std::string out;  // its standard output ("popen failed" when it could not be started)
};

// Runs `command` with /bin/sh (popen) to its end.
inline CommandOutput run_command(const std::string& command) {
  FILE* pipe = ::popen(command.c_str(), "r");
  if (pipe == nullptr) return {-1, "popen failed"};
  std::string out;
  char buf[4096];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, pipe)) > 0) out.append(buf, n);
  const int status = ::pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

}  // namespace subslip::testing
