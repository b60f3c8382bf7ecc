// read_file / write_file_atomic: round trip, no temporary left behind, clear errors.

#include <unistd.h>

#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "hwr/core/file_io.hpp"

namespace hwr::core {
namespace {

namespace fs = std::filesystem;

fs::path fresh_dir() {
  const fs::path d = fs::temp_directory_path() / ("hwr_file_io_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

TEST(FileIo, GivenBytesWhenWrittenAtomicallyThenTheyReadBackAndNoTemporaryRemains) {
  const fs::path d = fresh_dir();
  const std::string path = (d / "a.bin").string();
  const std::string bytes("line 1\n\0binary\xff", 15);
  ASSERT_TRUE(write_file_atomic(path, bytes).ok());
  ASSERT_TRUE(write_file_atomic(path, std::string("replaced")).ok());  // over an existing file
  std::string back;
  ASSERT_TRUE(read_file(path, &back).ok());
  EXPECT_EQ(back, "replaced");
  EXPECT_FALSE(fs::exists(path + ".tmp"));
  ASSERT_TRUE(write_file_atomic(path, std::vector<unsigned char>{1, 2, 3}).ok());
  ASSERT_TRUE(read_file(path, &back).ok());
  EXPECT_EQ(back, std::string("\x01\x02\x03", 3));
  fs::remove_all(d);
}

TEST(FileIo, GivenBadPathsThenErrorsNameThePathAndTheProblem) {
  const fs::path d = fresh_dir();
  std::string out;
  const Status missing = read_file((d / "nope.txt").string(), &out);
  EXPECT_EQ(missing.code(), ErrorCode::kNotFound);
  EXPECT_NE(missing.message().find("nope.txt: file not found"), std::string::npos);
  const Status folder = read_file(d.string(), &out);
  EXPECT_EQ(folder.code(), ErrorCode::kIoError);
  EXPECT_NE(folder.message().find("is a directory"), std::string::npos);
  const Status unwritable = write_file_atomic((d / "no" / "such" / "dir.txt").string(), std::string("x"));
  EXPECT_EQ(unwritable.code(), ErrorCode::kIoError);
  EXPECT_NE(unwritable.message().find("dir.txt: cannot open for writing"), std::string::npos);
  fs::remove_all(d);
}

}  // namespace
}  // namespace hwr::core
