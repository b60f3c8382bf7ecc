#include "sim_text.hpp"

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace hwr::sim::text {

std::string num(double v) {
  if (std::isnan(v)) return ".nan";
  if (std::isinf(v)) return v > 0 ? ".inf" : "-.inf";
  if (v == 0.0) return "0";  // also -0
  char buf[64];
  // Plain decimals where they are short ("20", "0.00024"), else the shortest exponent form.
  const double a = std::abs(v);
  if (a >= 1e-6 && a < 1e15) {
    for (int d = 0; d <= 17; ++d) {
      std::snprintf(buf, sizeof(buf), "%.*f", d, v);
      if (std::strtod(buf, nullptr) == v) return buf;
    }
  }
  for (int p = 1; p <= 17; ++p) {
    std::snprintf(buf, sizeof(buf), "%.*g", p, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

std::string quoted(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

std::string list(const double* v, int n) {
  std::string s = "[";
  for (int i = 0; i < n; ++i) s += (i ? ", " : "") + num(v[i]);
  return s + "]";
}

std::string matrix16(const Eigen::Isometry3d& T) {
  double v[16];
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) v[4 * r + c] = T.matrix()(r, c);
  }
  return list(v, 16);
}

bool isometry_from16(const std::vector<double>& v, Eigen::Isometry3d* T) {
  if (v.size() != 16) return false;
  Eigen::Matrix4d M;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) M(r, c) = v[4 * r + c];
  }
  if (!M.allFinite() || M(3, 0) != 0.0 || M(3, 1) != 0.0 || M(3, 2) != 0.0 || M(3, 3) != 1.0) return false;
  const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-6 || R.determinant() <= 0.0) return false;
  *T = Eigen::Isometry3d::Identity();
  T->linear() = Eigen::Quaterniond(R).normalized().toRotationMatrix();
  T->translation() = M.topRightCorner<3, 1>();
  return true;
}

namespace {
core::Status write_bytes_atomic(const std::string& path, const void* data, size_t size) {
  const std::string tmp = path + ".tmp";
  std::FILE* f = std::fopen(tmp.c_str(), "wb");
  if (f == nullptr) return core::IoError(path + ": cannot open for writing: " + std::strerror(errno));
  const size_t written = size == 0 ? 0 : std::fwrite(data, 1, size, f);
  const bool ok = written == size && std::fflush(f) == 0;
  const int err = errno;
  if (std::fclose(f) != 0 || !ok) {
    std::remove(tmp.c_str());
    return core::IoError(path + ": write failed: " + std::strerror(err));
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const int e = errno;
    std::remove(tmp.c_str());
    return core::IoError(path + ": rename failed: " + std::strerror(e));
  }
  return core::Status::Ok();
}
}  // namespace

core::Status write_file_atomic(const std::string& path, const std::string& bytes) {
  return write_bytes_atomic(path, bytes.data(), bytes.size());
}

core::Status write_file_atomic(const std::string& path, const std::vector<unsigned char>& bytes) {
  return write_bytes_atomic(path, bytes.data(), bytes.size());
}

core::Status read_file(const std::string& path, std::string* out) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) return core::NotFound(path + ": cannot open: " + std::strerror(errno));
  out->clear();
  char buf[65536];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof(buf), f)) > 0) out->append(buf, n);
  const bool bad = std::ferror(f) != 0;
  std::fclose(f);
  if (bad) return core::IoError(path + ": read failed");
  return core::Status::Ok();
}

}  // namespace hwr::sim::text
