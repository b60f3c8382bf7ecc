#pragma once
// Runs a test body inside a private network namespace (issue #5: UDP multicast only there, never
// towards any outside address). The test re-executes its own binary under `unshare -rn` with
// HWR_IN_PRIVATE_NETNS=1 and only that test selected; inside, the loopback is brought up with a
// multicast route on it, so udpm:// traffic never leaves the namespace.
//
//   TEST(Suite, Name) {
//     if (!hwr::test::in_private_netns()) { HWR_RUN_IN_PRIVATE_NETNS(); return; }
//     ... udpm:// code ...
//   }

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "cross_run.hpp"

namespace hwr::test {

// True inside the namespace child; it also leaves the marker file the parent checks, so a filter
// that selects no test (gtest then exits 0) cannot pass for a test that never ran.
inline bool in_private_netns() {
  if (std::getenv("HWR_IN_PRIVATE_NETNS") == nullptr) return false;
  // The variable alone is not trusted: a fresh network namespace has only `lo` (/proc/self/net/dev
  // lists the interfaces of this process's namespace), so a stray HWR_IN_PRIVATE_NETNS=1 never puts
  // nft rules or routes on the host.
  bool only_lo = false;
  if (FILE* f = std::fopen("/proc/self/net/dev", "r")) {
    char line[512];
    int interfaces = 0, lo = 0;
    while (std::fgets(line, sizeof(line), f)) {
      const char* colon = std::strchr(line, ':');
      if (colon == nullptr) continue;  // the two header lines
      const char* name = line;
      while (*name == ' ') ++name;
      ++interfaces;
      if (colon - name == 2 && std::strncmp(name, "lo", 2) == 0) ++lo;
    }
    std::fclose(f);
    only_lo = interfaces == 1 && lo == 1;
  }
  if (!only_lo) {
    std::fprintf(stderr, "HWR_IN_PRIVATE_NETNS is set but this network namespace has more than lo\n");
    std::abort();
  }
  if (const char* marker = std::getenv("HWR_NETNS_MARKER")) {
    if (FILE* f = std::fopen(marker, "w")) std::fclose(f);
  }
  return true;
}

// Brings up lo and routes multicast over it (run inside the namespace).
inline bool setup_private_loopback() {
  return std::system("ip link set lo up && ip route add 224.0.0.0/4 dev lo") == 0;
}

inline std::string self_exe() {
  char buf[4096];
  const ssize_t n = readlink("/proc/self/exe", buf, sizeof(buf) - 1);
  if (n <= 0) return {};
  buf[n] = '\0';
  return buf;
}

// Returns the namespace child's exit status (0: passed), or -1 when no namespace can be made here;
// *output gets what the child printed.
inline int rerun_in_private_netns(const std::string& test_full_name, std::string* output) {
  if (std::system("unshare -rn true >/dev/null 2>&1") != 0) return -1;
  const std::string marker = "/tmp/hwr_netns_marker_" + std::to_string(getpid());
  const std::string log = "/tmp/hwr_netns_log_" + std::to_string(getpid());
  std::remove(marker.c_str());
  const std::string cmd = "HWR_IN_PRIVATE_NETNS=1 HWR_NETNS_MARKER='" + marker + "' unshare -rn " +
                          emulated_command("'" + self_exe() + "'") + " --gtest_filter='" + test_full_name +
                          "' >'" + log + "' 2>&1";
  const int st = std::system(cmd.c_str());
  if (FILE* f = std::fopen(log.c_str(), "r")) {
    char buf[4096];
    size_t n = 0;
    while ((n = std::fread(buf, 1, sizeof(buf), f)) > 0) output->append(buf, n);
    std::fclose(f);
  }
  std::remove(log.c_str());
  const bool ran = std::remove(marker.c_str()) == 0;
  if (!ran) return 127;  // the test body never ran inside the namespace
  return WIFEXITED(st) ? WEXITSTATUS(st) : 128;
}

}  // namespace hwr::test

#define HWR_RUN_IN_PRIVATE_NETNS()                                                                      \
  do {                                                                                                  \
    const ::testing::TestInfo* info_ = ::testing::UnitTest::GetInstance()->current_test_info();         \
    const std::string name_ = std::string(info_->test_suite_name()) + "." + info_->name();              \
    std::string out_;                                                                                   \
    const int rc_ = ::hwr::test::rerun_in_private_netns(name_, &out_);                                  \
    if (rc_ < 0) GTEST_SKIP() << "cannot create a private network namespace here (unshare -rn failed)"; \
    EXPECT_EQ(rc_, 0) << "the test failed inside its private network namespace:\n" << out_;             \
  } while (0)
