#include "map_store_files.hpp"

#include "hwr/core/file_io.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace hwr::recon::store_detail {
namespace {

std::string errno_text(int err) { return std::strerror(err); }

}  // namespace

core::Status write_file_synced(const std::string& path, const ByteSpan* spans, size_t n_spans) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) return core::IoError(path + ": cannot create: " + errno_text(errno));
  int err = 0;
  for (size_t s = 0; s < n_spans && err == 0; ++s) err = core::write_all_fd(fd, spans[s].data, spans[s].size);
  // The data must be on disk before the directory holding it is renamed into place.
  if (err == 0 && ::fsync(fd) != 0) err = errno;
  if (::close(fd) != 0 && err == 0) err = errno;
  if (err != 0) return core::IoError(path + ": write failed: " + errno_text(err));
  return core::Status::Ok();
}

core::Status ReadFile::open(const std::string& path, ReadFile* out) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    const int err = errno;
    if (err == ENOENT) return core::NotFound(path + ": file not found");
    return core::IoError(path + ": cannot open for reading: " + errno_text(err));
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const int err = errno;
    ::close(fd);
    return core::IoError(path + ": fstat failed: " + errno_text(err));
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    return core::IoError(path + ": not a regular file");
  }
  if (out->fd_ >= 0) ::close(out->fd_);
  out->fd_ = fd;
  out->size_bytes_ = static_cast<uint64_t>(st.st_size);
  out->path_ = path;
  return core::Status::Ok();
}

ReadFile::~ReadFile() {
  if (fd_ >= 0) ::close(fd_);
}

core::Status ReadFile::read_at(uint64_t offset, void* out, size_t n) const {
  char* p = static_cast<char*>(out);
  while (n > 0) {
    const ssize_t got = ::pread(fd_, p, n, static_cast<off_t>(offset));
    if (got < 0) {
      if (errno == EINTR) continue;
      return core::IoError(path_ + ": read failed: " + errno_text(errno));
    }
    if (got == 0) return core::CorruptData(path_ + ": file ends early (truncated while being read)");
    p += got;
    n -= static_cast<size_t>(got);
    offset += static_cast<uint64_t>(got);
  }
  return core::Status::Ok();
}

bool file_size_bytes(const std::string& path, uint64_t* out) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return false;
  *out = static_cast<uint64_t>(st.st_size);
  return true;
}

}  // namespace hwr::recon::store_detail
