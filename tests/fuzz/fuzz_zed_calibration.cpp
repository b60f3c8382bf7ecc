// libFuzzer target: the ZED 2i calibration file parser (hal/hw/zed_calibration.hpp). The first byte
// picks the eye width (its value modulo 5: 2208, 1920, 1280, 672, or 1000, which no mode has); the
// rest is the SN<serial>.conf text. Findings: a crash or sanitizer report; an error without the
// source name in its message; an accepted rig that breaks what the parser promises (the mode's image
// size, positive focal lengths, the principal point inside the image, k1/k2 not all zero, the right
// eye at +x with |t| < 1 m, an orthonormal rotation of at most 0.2 rad, all finite); and two metamorphic
// oracles: the same text with CRLF line ends, and the same text upper-cased (section and key names are
// case-insensitive, numbers read the same), must give the identical outcome and rig.
// Seeds: make_zed_calibration_seeds.cpp.

#include <cctype>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include <Eigen/Geometry>

#include "hwr/hal/hw/zed_calibration.hpp"

namespace {

void check(bool ok) {
  if (!ok) std::abort();
}

bool same_rig(const hwr::hal::StereoRig& a, const hwr::hal::StereoRig& b) {
  const auto same = [](const hwr::hal::PinholeIntrinsics& x, const hwr::hal::PinholeIntrinsics& y) {
    return x.width == y.width && x.height == y.height && x.fx == y.fx && x.fy == y.fy && x.cx == y.cx &&
           x.cy == y.cy && x.distortion == y.distortion;
  };
  return same(a.left, b.left) && same(a.right, b.right) && a.T_left_right.matrix() == b.T_left_right.matrix();
}

void check_rig(const hwr::hal::StereoRig& rig, int width) {
  const int height = width == 2208 ? 1242 : width == 1920 ? 1080 : width == 1280 ? 720 : 376;
  for (const hwr::hal::PinholeIntrinsics* k : {&rig.left, &rig.right}) {
    check(k->width == width && k->height == height);
    check(std::isfinite(k->fx) && std::isfinite(k->fy) && k->fx > 0 && k->fy > 0);
    check(k->cx > 0 && k->cx < width && k->cy > 0 && k->cy < height);
    for (double d : k->distortion) check(std::isfinite(d));
  }
  check(!(rig.left.distortion[0] == 0 && rig.left.distortion[1] == 0 && rig.right.distortion[0] == 0 &&
          rig.right.distortion[1] == 0));
  const Eigen::Matrix3d R = rig.T_left_right.linear();
  const Eigen::Vector3d t = rig.T_left_right.translation();
  check(R.allFinite() && t.allFinite());
  check((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() < 1e-9 && R.determinant() > 0);
  check(Eigen::AngleAxisd(R).angle() <= 0.2 + 1e-9);  // the parser's plausibility bound
  // T_left_right = [Rᵀ_rl | Rᵀ_rl·t_file], t_file = [Baseline, TY, TZ]/1000 with 0 < Baseline < 1000 mm:
  // with R = Rᵀ_rl, t_file = Rᵀ·t has x in (0, 1).
  const Eigen::Vector3d t_file = R.transpose() * t;
  check(t_file.x() > 0 && t_file.x() < 1.0);
  check(std::fabs(t_file.y()) < t_file.x() && std::fabs(t_file.z()) < t_file.x());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  static const int kWidths[5] = {2208, 1920, 1280, 672, 1000};
  const int width = kWidths[data[0] % 5];
  const std::string_view text(reinterpret_cast<const char*>(data + 1), size - 1);
  using hwr::hal::hw::parse_zed_calibration;
  auto rig = parse_zed_calibration(text, width, "fuzz.conf");
  if (rig.ok()) {
    check(width != 1000);
    check_rig(*rig, width);
  } else {
    check(rig.status().message().find("fuzz.conf") != std::string::npos);
  }

  // CRLF line ends: the same outcome and rig.
  std::string crlf;
  crlf.reserve(text.size() * 2);
  for (char c : text) {
    if (c == '\n') crlf += '\r';
    crlf += c;
  }
  auto rig_crlf = parse_zed_calibration(crlf, width, "fuzz.conf");
  check(rig_crlf.ok() == rig.ok());
  if (rig.ok()) check(same_rig(*rig, *rig_crlf));

  // Upper-cased: names are case-insensitive; from_chars reads "1E-05", "INF", "NAN" as it reads the
  // lower-case forms.
  std::string upper(text);
  for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  auto rig_upper = parse_zed_calibration(upper, width, "fuzz.conf");
  check(rig_upper.ok() == rig.ok());
  if (rig.ok()) check(same_rig(*rig, *rig_upper));
  return 0;
}
