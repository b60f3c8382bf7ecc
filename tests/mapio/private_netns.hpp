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
#include <string>

namespace hwr::test {

// True inside the namespace child; it also leaves the marker file the parent checks, so a filter
// that selects no test (gtest then exits 0) cannot pass for a test that never ran.
inline bool in_private_netns() {
  if (std::getenv("HWR_IN_PRIVATE_NETNS") == nullptr) return false;
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

// Returns the namespace child's exit status (0: passed), or -1 when no namespace can be made here.
inline int rerun_in_private_netns(const std::string& test_full_name) {
  if (std::system("unshare -rn true >/dev/null 2>&1") != 0) return -1;
  const std::string marker = "/tmp/hwr_netns_marker_" + std::to_string(getpid());
  std::remove(marker.c_str());
  const std::string cmd = "HWR_IN_PRIVATE_NETNS=1 HWR_NETNS_MARKER='" + marker + "' unshare -rn '" +
                          self_exe() + "' --gtest_filter='" + test_full_name + "' >/dev/null 2>&1";
  const int st = std::system(cmd.c_str());
  const bool ran = std::remove(marker.c_str()) == 0;
  if (!ran) return 127;  // the test body never ran inside the namespace
  return WIFEXITED(st) ? WEXITSTATUS(st) : 128;
}

}  // namespace hwr::test

#define HWR_RUN_IN_PRIVATE_NETNS()                                                                      \
  do {                                                                                                  \
    const ::testing::TestInfo* info_ = ::testing::UnitTest::GetInstance()->current_test_info();         \
    const std::string name_ = std::string(info_->test_suite_name()) + "." + info_->name();              \
    const int rc_ = ::hwr::test::rerun_in_private_netns(name_);                                         \
    if (rc_ < 0) GTEST_SKIP() << "cannot create a private network namespace here (unshare -rn failed)"; \
    EXPECT_EQ(rc_, 0) << "the test failed inside its private network namespace; rerun with "            \
                         "HWR_IN_PRIVATE_NETNS=1 unshare -rn <test binary> --gtest_filter="             \
                      << name_ << " to see why";                                                        \
  } while (0)
