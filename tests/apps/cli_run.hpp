// Runs a built program through the shell and captures what it prints, for the CLI tests. A command
// that starts with a program this build made (under HWR_BINARY_DIR) runs through the cross build's
// emulator in the agx build's tests (cross_run.hpp); others (node, unshare) run as they are.

#pragma once

#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <map>
#include <sstream>
#include <string>

#include "cross_run.hpp"

namespace hwr::testing {

// `command` with the emulator in front when it starts with a program of this build (a command that
// starts with `VAR=...`, `timeout` or a quoted path is not recognised: put the program first).
inline std::string with_emulator(const std::string& command) {
  const std::string built = HWR_BINARY_DIR "/";
  return command.rfind(built, 0) == 0 ? hwr::test::emulated_command(command) : command;
}

struct CliRun {
  int exit_code = -1;  // -1 when the program could not be started or did not exit normally
  std::string out;     // stdout and stderr together
};

// Runs `program args` with stderr folded into stdout.
inline CliRun run_cli(const std::string& program, const std::string& args) {
  CliRun r;
  FILE* p = ::popen((with_emulator(program) + " " + args + " 2>&1").c_str(), "r");
  if (p == nullptr) return r;
  char buf[4096];
  size_t n = 0;
  while ((n = std::fread(buf, 1, sizeof(buf), p)) > 0) r.out.append(buf, n);
  const int status = ::pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

// Starts `command` in the background through the shell, its stdout and stderr into `log`; its pid.
inline pid_t start_cli(const std::string& command, const std::string& log) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    const std::string cmd = "exec " + with_emulator(command) + " > '" + log + "' 2>&1";
    ::execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  return pid;
}

// Waits for a started program; its exit code, -1 if it did not exit normally.
inline int wait_cli(pid_t pid) {
  int status = 0;
  if (::waitpid(pid, &status, 0) != pid) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// Whether a started program has exited (*code: its exit code, -1 if not a normal exit); never blocks.
inline bool cli_exited(pid_t pid, int* code) {
  int status = 0;
  if (::waitpid(pid, &status, WNOHANG) != pid) return false;
  *code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return true;
}

// The `key=value` lines (no spaces) of a program's output.
inline std::map<std::string, std::string> key_values(const std::string& out) {
  std::map<std::string, std::string> kv;
  std::istringstream in(out);
  std::string line;
  while (std::getline(in, line)) {
    const size_t eq = line.find('=');
    if (eq != std::string::npos && line.find(' ') == std::string::npos)
      kv[line.substr(0, eq)] = line.substr(eq + 1);
  }
  return kv;
}

}  // namespace hwr::testing
