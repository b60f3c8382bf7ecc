#include "hwr/core/file_io.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace hwr::core {

int write_all_fd(int fd, const void* data, size_t size) {
  const char* p = static_cast<const char*>(data);
  size_t left = size;
  while (left > 0) {
    const ssize_t n = ::write(fd, p, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      return errno;
    }
    p += n;
    left -= static_cast<size_t>(n);
  }
  return 0;
}

namespace {

Status write_bytes_atomic(const std::string& path, const void* data, size_t size) {
  const std::string tmp = path + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return IoError(path + ": cannot open for writing: " + std::strerror(errno));
  int err = write_all_fd(fd, data, size);
  if (err == 0 && ::fsync(fd) != 0) err = errno;
  if (::close(fd) != 0 && err == 0) err = errno;
  if (err != 0) {
    std::remove(tmp.c_str());
    return IoError(path + ": write failed: " + std::strerror(err));
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const int e = errno;
    std::remove(tmp.c_str());
    return IoError(path + ": rename failed: " + std::strerror(e));
  }
  return Status::Ok();
}

}  // namespace

Status read_file(const std::string& path, std::string* out) {
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(st)) return NotFound(path + ": file not found");
  if (std::filesystem::is_directory(st)) return IoError(path + ": is a directory, expected a file");
  std::ifstream f(path, std::ios::binary);
  if (!f) return IoError(path + ": cannot open for reading");
  std::ostringstream ss;
  ss << f.rdbuf();
  if (f.bad()) return IoError(path + ": read failed");
  *out = std::move(ss).str();
  return Status::Ok();
}

Status write_file_atomic(const std::string& path, const std::string& bytes) {
  return write_bytes_atomic(path, bytes.data(), bytes.size());
}

Status write_file_atomic(const std::string& path, const std::vector<unsigned char>& bytes) {
  return write_bytes_atomic(path, bytes.data(), bytes.size());
}

Status fsync_directory(const std::string& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return IoError(dir + ": cannot open directory for fsync: " + std::strerror(errno));
  int err = 0;
  if (::fsync(fd) != 0) err = errno;
  ::close(fd);
  if (err != 0) return IoError(dir + ": directory fsync failed: " + std::strerror(err));
  return Status::Ok();
}

}  // namespace hwr::core
