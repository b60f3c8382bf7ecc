#pragma once
// Crash-safety tests: fork a writer, SIGKILL it after a delay, and hand back to the test, which then
// checks what the writer left on disk (tests/recon/test_map_store.cpp, tests/mapio/test_ground_store.cpp).

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <thread>

#include <gtest/gtest.h>

namespace hwr::test {

// Runs writer() (which must not return) in a child process and kills it with SIGKILL after
// delay_ms. Fails the test when the child could not be made or ended before the kill.
template <class Writer>
void kill_writer_after(int delay_ms, Writer&& writer) {
  const pid_t child = ::fork();
  ASSERT_GE(child, 0) << "fork failed";
  if (child == 0) writer();
  std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms));
  ASSERT_EQ(::kill(child, SIGKILL), 0);
  int wstatus = 0;
  ASSERT_EQ(::waitpid(child, &wstatus, 0), child);
  ASSERT_TRUE(WIFSIGNALED(wstatus) && WTERMSIG(wstatus) == SIGKILL)
      << "the writer ended before the kill, exit status " << (WIFEXITED(wstatus) ? WEXITSTATUS(wstatus) : -1);
}

}  // namespace hwr::test
