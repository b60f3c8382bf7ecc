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

}  // namespace hwr::sim::text
