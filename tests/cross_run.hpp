#pragma once
// Starting a program this build made (hwr-ground, or the test binary itself in a private network
// namespace). On the host it runs directly; in the cross build's tests (cmake --preset agx) the test
// runs under CMAKE_CROSSCOMPILING_EMULATOR (qemu-aarch64 -L <sysroot>) and so must every aarch64
// program it starts: there is no binfmt_misc to do it for us. HWR_TEST_EMULATOR is that emulator
// command, its words separated by '|' ("" on the host).

#include <string>
#include <vector>

namespace hwr::test {

inline std::vector<std::string> emulator_argv() {
  std::vector<std::string> out;
  const std::string list = HWR_TEST_EMULATOR;
  size_t start = 0;
  while (start < list.size()) {
    const size_t end = list.find('|', start);
    out.push_back(list.substr(start, end == std::string::npos ? std::string::npos : end - start));
    if (end == std::string::npos) break;
    start = end + 1;
  }
  return out;
}

// argv with the emulator in front (unchanged on the host). argv[0] is then the emulator: spawn it
// with a PATH search (posix_spawnp) or give its full path.
inline std::vector<std::string> emulated_argv(std::vector<std::string> argv) {
  std::vector<std::string> out = emulator_argv();
  out.insert(out.end(), argv.begin(), argv.end());
  return out;
}

// A shell command word sequence that runs program (already quoted as the caller needs).
inline std::string emulated_command(const std::string& program) {
  std::string out;
  for (const std::string& a : emulator_argv()) out += "'" + a + "' ";
  return out + program;
}

}  // namespace hwr::test
