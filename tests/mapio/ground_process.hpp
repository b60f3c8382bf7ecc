#pragma once
// The hwr-ground program as a child process of a mapio test (the link, operator and viewer tests):
// started with posix_spawn (qemu-aarch64 in front in the cross build's tests, cross_run.hpp), its
// stdout and stderr into one log file, stopped with SIGTERM (its orderly stop).

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "hwr/core/file_io.hpp"

#include "cross_run.hpp"

namespace hwr::test {

inline const std::string kGroundProgram = HWR_BINARY_DIR "/apps/hwr-ground/hwr-ground";

// hwr-ground with `args`, its output into `log` (/dev/null to drop it); -1 when it cannot start.
inline pid_t start_ground_process(const std::vector<std::string>& args, const std::string& log) {
  std::vector<std::string> full = {kGroundProgram};
  full.insert(full.end(), args.begin(), args.end());
  full = emulated_argv(full);
  std::vector<char*> argv;
  for (auto& a : full) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = -1;
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  const int rc = posix_spawn(&pid, full[0].c_str(), &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  return rc == 0 ? pid : -1;
}

// SIGTERM, then its exit status (-1 when it did not exit normally); *pid becomes -1.
inline int stop_ground_process(pid_t* pid) {
  kill(*pid, SIGTERM);
  int st = 0;
  waitpid(*pid, &st, 0);
  *pid = -1;
  return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

// The port `hwr-ground --http 127.0.0.1:0` printed into its log ("viewer at http://127.0.0.1:PORT/"),
// waiting up to timeout_s for it (qemu is slow to start); -1 when it never did.
inline int wait_for_viewer_port(const std::string& log, double timeout_s = 60) {
  const std::regex re("viewer at http://127\\.0\\.0\\.1:([0-9]+)/");
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < until) {
    std::string text;
    (void)core::read_file(log, &text);
    std::smatch m;
    if (std::regex_search(text, m, re)) return std::stoi(m[1]);
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return -1;
}

}  // namespace hwr::test
