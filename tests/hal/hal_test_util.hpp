#pragma once
// Shared helpers for the hal tests: dataset paths that fail loudly when missing, scratch folders,
// small file writers.

#include <cstddef>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>

#include "hwr/core/status.hpp"

namespace hwr::hal::testing {

inline const std::string kTeddyDir = HWR_DATA_DIR "/tum-fr3-teddy-200/rgbd_dataset_freiburg3_teddy";
inline const std::string kEurocStaticMav0 = HWR_DATA_DIR "/euroc-v1-01-static-start/mav0";
inline const std::string kEurocImu40sMav0 = HWR_DATA_DIR "/euroc-v1-02-imu-40s/mav0";

// A test that needs a dataset fails (never skips) when it is absent.
#define HWR_REQUIRE_DATASET(dir)                                                                  \
  ASSERT_TRUE(std::filesystem::is_directory(dir))                                                 \
      << "dataset folder missing: " << (dir) << "\n(the shared data sets live in ../shared/data " \
      << "beside the repository; see shared/data/README.md)"

// A fresh, empty folder under the system temp folder, unique per name and process; removed when
// the test program exits.
inline std::filesystem::path scratch_dir(const std::string& name) {
  struct Cleanup {
    std::vector<std::filesystem::path> dirs;
    ~Cleanup() {
      std::error_code ec;
      for (const auto& d : dirs) std::filesystem::remove_all(d, ec);
    }
  };
  static Cleanup cleanup;
  const auto dir = std::filesystem::temp_directory_path() /
                   ("hwr_hal_test_" + name + "_" + std::to_string(static_cast<long>(::getpid())));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  cleanup.dirs.push_back(dir);
  return dir;
}

inline void write_text(const std::filesystem::path& path, const std::string& text) {
  std::filesystem::create_directories(path.parent_path());
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f << text;
}

// Copies the first `bytes` bytes of `from` into `to` (a truncated file).
inline void write_truncated_copy(const std::filesystem::path& from, const std::filesystem::path& to,
                                 size_t bytes) {
  std::ifstream in(from, std::ios::binary);
  std::string data(bytes, '\0');
  in.read(data.data(), static_cast<std::streamsize>(bytes));
  data.resize(static_cast<size_t>(in.gcount()));
  write_text(to, data);
}

// Errors are one line a person can act on.
inline void expect_one_line_error(const core::Status& st, const std::string& must_contain) {
  EXPECT_FALSE(st.ok());
  EXPECT_EQ(st.message().find('\n'), std::string::npos) << st.message();
  EXPECT_NE(st.message().find(must_contain), std::string::npos)
      << "message: " << st.message() << "\nexpected to contain: " << must_contain;
}

}  // namespace hwr::hal::testing
