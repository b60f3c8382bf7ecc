#pragma once
// Whole-file reads and crash-safe whole-file writes, with errors that name the path.

#include <cstddef>
#include <string>
#include <vector>

#include "hwr/core/status.hpp"

namespace hwr::core {

// NotFound when the path does not exist, IoError for a folder or a failed read.
Status read_file(const std::string& path, std::string* out);

// Writes path + ".tmp", flushes it to disk (fsync), then renames it over path, so a process
// killed at any moment leaves either the old file or the complete new one, never a truncated
// file under the final name.
Status write_file_atomic(const std::string& path, const std::string& bytes);
Status write_file_atomic(const std::string& path, const std::vector<unsigned char>& bytes);

// Writes all `size` bytes to an open file descriptor, retrying short writes and EINTR. Returns 0,
// or the errno of the failed write.
int write_all_fd(int fd, const void* data, size_t size);

// fsync(2) of a directory: makes the entries created, renamed or removed in it durable (the last
// step of a crash-safe write: temp file, fsync, rename, fsync of the directory).
Status fsync_directory(const std::string& dir);

}  // namespace hwr::core
