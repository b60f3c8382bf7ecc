#include "durable_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>

#include "hwr/core/file_io.hpp"

namespace hwr::mapio::detail {

std::string parent_directory(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  if (slash == std::string::npos) return ".";
  if (slash == 0) return "/";
  return path.substr(0, slash);
}

core::Status make_dir(const std::string& parent, const std::string& dir) {
  if (::mkdir(dir.c_str(), 0755) == 0) return core::fsync_directory(parent);
  if (errno == EEXIST) {
    struct stat st {};
    if (::stat(dir.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) return core::Status::Ok();
    return core::IoError(dir + ": exists and is not a folder");
  }
  return core::IoError(dir + ": cannot create folder: " + std::strerror(errno));
}

core::Status list_dir(const std::string& dir, std::vector<std::filesystem::directory_entry>* out) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::directory_iterator it(dir, ec), end;
  if (ec) return core::IoError(dir + ": cannot list folder: " + ec.message());
  for (; it != end; it.increment(ec)) {
    if (ec) return core::IoError(dir + ": cannot list folder: " + ec.message());
    out->push_back(*it);
  }
  std::sort(out->begin(), out->end(),
            [](const fs::directory_entry& a, const fs::directory_entry& b) { return a.path() < b.path(); });
  return core::Status::Ok();
}

bool is_dir(const std::filesystem::directory_entry& e) {
  std::error_code ec;
  return e.is_directory(ec) && !e.is_symlink(ec);
}

bool is_file(const std::filesystem::directory_entry& e) {
  std::error_code ec;
  return e.is_regular_file(ec) && !e.is_symlink(ec);
}

AtomicFileWriter::~AtomicFileWriter() { abandon(); }

void AtomicFileWriter::abandon() {
  if (fd_ >= 0) {
    ::close(fd_);
    fd_ = -1;
    std::remove(tmp_.c_str());
  }
}

core::Status AtomicFileWriter::open(const std::string& path) {
  abandon();
  path_ = path;
  tmp_ = path + ".tmp";
  fd_ = ::open(tmp_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0) return core::IoError(path + ": cannot open " + tmp_ + " for writing: " + std::strerror(errno));
  return core::Status::Ok();
}

core::Status AtomicFileWriter::write(const void* data, size_t size) {
  if (fd_ < 0) return core::Internal(path_ + ": write() without a successful open()");
  const int err = core::write_all_fd(fd_, data, size);
  if (err != 0) {
    abandon();
    return core::IoError(path_ + ": write failed: " + std::strerror(err));
  }
  return core::Status::Ok();
}

core::Status AtomicFileWriter::commit() {
  if (fd_ < 0) return core::Internal(path_ + ": commit() without a successful open()");
  int err = 0;
  if (::fsync(fd_) != 0) err = errno;
  if (::close(fd_) != 0 && err == 0) err = errno;
  fd_ = -1;
  if (err == 0 && std::rename(tmp_.c_str(), path_.c_str()) != 0) err = errno;
  if (err != 0) {
    std::remove(tmp_.c_str());
    return core::IoError(path_ + ": write failed: " + std::strerror(err));
  }
  return core::fsync_directory(parent_directory(path_));
}

}  // namespace hwr::mapio::detail
