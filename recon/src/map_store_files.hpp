#pragma once
// POSIX file primitives of the map store's atomic protocol (map_store.hpp): whole-file writes that
// are fsync'ed before they return, directory fsync is core::fsync_directory, and
// bounded reads at an offset. Every error names the path and carries strerror(errno).

#include <cstddef>
#include <cstdint>
#include <string>

#include "hwr/core/status.hpp"

namespace hwr::recon::store_detail {

// One contiguous piece of a file's bytes, written in order.
struct ByteSpan {
  const void* data = nullptr;
  size_t size = 0;
};

// Creates `path` (it must not exist: O_EXCL), writes the spans in order, fsyncs and closes it.
// kIoError on any failure (the partial file is left for the caller's temp-directory cleanup).
core::Status write_file_synced(const std::string& path, const ByteSpan* spans, size_t n_spans);

// A read-only file descriptor that closes itself.
class ReadFile {
 public:
  // kNotFound when absent, kIoError otherwise.
  static core::Status open(const std::string& path, ReadFile* out);
  ReadFile() = default;
  ReadFile(const ReadFile&) = delete;
  ReadFile& operator=(const ReadFile&) = delete;
  ~ReadFile();

  uint64_t size_bytes() const { return size_bytes_; }
  // Reads exactly n bytes at offset; kCorruptData when the file ends first (it was truncated
  // after its size was taken), kIoError on a read error.
  core::Status read_at(uint64_t offset, void* out, size_t n) const;

 private:
  int fd_ = -1;
  uint64_t size_bytes_ = 0;
  std::string path_;
};

// stat(2) size of a file; false when it cannot be stat'ed.
bool file_size_bytes(const std::string& path, uint64_t* out);

}  // namespace hwr::recon::store_detail
