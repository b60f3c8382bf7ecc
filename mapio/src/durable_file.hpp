#pragma once
// Crash-safe file and folder primitives shared by the ground store, the operator console and the cloud
// writers (private to mapio).
// core/file_io.hpp writes whole in-memory files atomically and fsyncs directories; this adds a
// streaming atomic writer for files too large to build in memory first (a merged map of millions of points).
// Same protocol as core: PATH.tmp, fsync, rename over PATH, then fsync of the directory.

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "hwr/core/status.hpp"

namespace hwr::mapio::detail {

// The folder part of a path ("." when it has none).
std::string parent_directory(const std::string& path);

// mkdir of one level; fsync of its parent when it was created, so the new entry is durable. OK when
// it is already a folder; kIoError when it exists as something else or cannot be made.
core::Status make_dir(const std::string& parent, const std::string& dir);
// Entries of a folder, sorted by name; kIoError when it cannot be listed.
core::Status list_dir(const std::string& dir, std::vector<std::filesystem::directory_entry>* out);
// A folder / a regular file, not through a symbolic link.
bool is_dir(const std::filesystem::directory_entry& e);
bool is_file(const std::filesystem::directory_entry& e);

// Streams bytes into PATH.tmp; commit() makes them PATH. Destroyed without a successful commit()
// (an error, an early return), it removes the temp file, so PATH is never touched.
class AtomicFileWriter {
 public:
  AtomicFileWriter() = default;
  AtomicFileWriter(const AtomicFileWriter&) = delete;
  AtomicFileWriter& operator=(const AtomicFileWriter&) = delete;
  ~AtomicFileWriter();

  core::Status open(const std::string& path);
  core::Status write(const void* data, size_t size);
  // fsync, close, rename PATH.tmp -> PATH, fsync the folder.
  core::Status commit();

 private:
  void abandon();

  int fd_ = -1;
  std::string path_, tmp_;
};

}  // namespace hwr::mapio::detail
