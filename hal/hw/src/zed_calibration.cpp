#include "hwr/hal/hw/zed_calibration.hpp"

#include <cctype>
#include <charconv>
#include <cmath>
#include <map>
#include <optional>

#include <Eigen/Geometry>

#include "hwr/core/file_io.hpp"

namespace hwr::hal::hw {
namespace {

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

struct Entry {
  std::string value;
  int line = 0;
};
using Ini = std::map<std::string, std::map<std::string, Entry>>;  // lower-case section → key → value

core::Expected<Ini> parse_ini(std::string_view text, const std::string& source) {
  Ini ini;
  std::string section;
  int line_no = 0;
  while (!text.empty()) {
    const size_t eol = text.find('\n');
    std::string_view line = trim(text.substr(0, eol));  // trim also drops a CR
    text.remove_prefix(eol == std::string_view::npos ? text.size() : eol + 1);
    ++line_no;
    if (line.empty() || line.front() == ';' || line.front() == '#') continue;
    if (line.front() == '[') {
      if (line.back() != ']')
        return core::ParseError(source + ":" + std::to_string(line_no) + ": unterminated section header");
      section = lower(trim(line.substr(1, line.size() - 2)));
      continue;
    }
    const size_t eq = line.find('=');
    if (eq == std::string_view::npos) {
      return core::ParseError(source + ":" + std::to_string(line_no) + ": expected 'key = value', got '" +
                              std::string(line.substr(0, 60)) + "'");
    }
    ini[section][lower(trim(line.substr(0, eq)))] = Entry{std::string(trim(line.substr(eq + 1))), line_no};
  }
  return ini;
}

const char* resolution_name(int eye_width) {
  switch (eye_width) {
    case 2208:
      return "2K";
    case 1920:
      return "FHD";
    case 1280:
      return "HD";
    case 672:
      return "VGA";
    default:
      return nullptr;
  }
}

int eye_height(int eye_width) {
  switch (eye_width) {
    case 2208:
      return 1242;
    case 1920:
      return 1080;
    case 1280:
      return 720;
    default:
      return 376;
  }
}

class Reader {
 public:
  Reader(const Ini& ini, std::string source) : ini_(ini), source_(std::move(source)) {}

  // The number under [section] key (lower-case names), or an error naming both.
  std::optional<double> number(const std::string& section, const std::string& key, bool required = true) {
    auto s = ini_.find(section);
    if (s == ini_.end()) {
      if (required && error_.ok()) error_ = core::NotFound(source_ + ": no section [" + upper(section) + "]");
      return std::nullopt;
    }
    auto k = s->second.find(key);
    if (k == s->second.end()) {
      if (required && error_.ok()) {
        error_ = core::NotFound(source_ + ": [" + upper(section) + "] has no key '" + key + "'");
      }
      return std::nullopt;
    }
    const std::string& v = k->second.value;
    double x = 0;
    const auto r = std::from_chars(v.data(), v.data() + v.size(), x);  // locale-independent
    if (r.ec != std::errc() || r.ptr != v.data() + v.size() || !std::isfinite(x)) {
      if (error_.ok()) {
        error_ = core::ParseError(source_ + ":" + std::to_string(k->second.line) + ": [" + upper(section) +
                                  "] " + key + " = '" + v + "' is not a finite number");
      }
      return std::nullopt;
    }
    return x;
  }
  const core::Status& error() const { return error_; }

 private:
  static std::string upper(std::string s) {
    for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    return s;
  }
  const Ini& ini_;
  std::string source_;
  core::Status error_;
};

PinholeIntrinsics read_camera(Reader& r, const std::string& section, int width) {
  PinholeIntrinsics K;
  K.width = width;
  K.height = eye_height(width);
  K.fx = r.number(section, "fx").value_or(0);
  K.fy = r.number(section, "fy").value_or(0);
  K.cx = r.number(section, "cx").value_or(0);
  K.cy = r.number(section, "cy").value_or(0);
  const char* keys[5] = {"k1", "k2", "p1", "p2", "k3"};
  for (int i = 0; i < 5; ++i)
    K.distortion[static_cast<size_t>(i)] = r.number(section, keys[i], i != 4).value_or(0);
  return K;
}

}  // namespace

core::Expected<hal::StereoRig> parse_zed_calibration(std::string_view text, int eye_width,
                                                     const std::string& source_name) {
  const char* res = resolution_name(eye_width);
  if (res == nullptr) {
    return core::InvalidArgument(source_name + ": no ZED resolution has eye width " +
                                 std::to_string(eye_width) + " (2208, 1920, 1280, 672)");
  }
  auto ini = parse_ini(text, source_name);
  if (!ini.ok()) return ini.status();
  Reader r(ini.value(), source_name);
  const std::string suffix = lower(res);
  hal::StereoRig rig;
  rig.left = read_camera(r, "left_cam_" + suffix, eye_width);
  rig.right = read_camera(r, "right_cam_" + suffix, eye_width);
  const double baseline_mm = r.number("stereo", "baseline").value_or(0);
  auto ty = r.number("stereo", "ty_" + suffix, false);
  auto tz = r.number("stereo", "tz_" + suffix, false);
  if (!ty) ty = r.number("stereo", "ty");
  if (!tz) tz = r.number("stereo", "tz");
  const double rx = r.number("stereo", "rx_" + suffix).value_or(0);
  const double cv = r.number("stereo", "cv_" + suffix).value_or(0);
  const double rz = r.number("stereo", "rz_" + suffix).value_or(0);
  if (!r.error().ok()) return r.error();

  if (!(rig.left.fx > 0 && rig.left.fy > 0 && rig.right.fx > 0 && rig.right.fy > 0)) {
    return core::OutOfRange(source_name + ": focal lengths at " + res + " must be positive");
  }
  if (!(baseline_mm > 0)) return core::OutOfRange(source_name + ": Baseline must be positive (mm)");
  const auto& dl = rig.left.distortion;
  const auto& dr = rig.right.distortion;
  if (dl[0] == 0 && dl[1] == 0 && dr[0] == 0 && dr[1] == 0) {
    return core::CorruptData(
        source_name + ": k1 and k2 are zero for both cameras at " + res +
        ": a calibration file saved under a comma-decimal locale; download it again from "
        "Stereolabs (https://calib.stereolabs.com/?SN=<serial>)");
  }
  // Rodrigues vector → rotation (Eigen's angle-axis; identity for a zero vector).
  const Eigen::Vector3d rot(rx, cv, rz);
  const double angle = rot.norm();
  const Eigen::Matrix3d R_right_left =
      angle > 0 ? Eigen::AngleAxisd(angle, rot / angle).toRotationMatrix() : Eigen::Matrix3d::Identity();
  rig.T_left_right = Eigen::Isometry3d::Identity();
  rig.T_left_right.linear() = R_right_left.transpose();
  rig.T_left_right.translation() = Eigen::Vector3d(baseline_mm, *ty, *tz) * 1e-3;
  return rig;
}

core::Expected<hal::StereoRig> load_zed_calibration_file(const std::string& path, int eye_width) {
  std::string text;
  if (core::Status st = core::read_file(path, &text); !st.ok()) {
    return core::Status(st.code(), st.message() +
                                       " (the ZED's calibration: download SN<serial>.conf from "
                                       "https://calib.stereolabs.com/?SN=<serial>)");
  }
  return parse_zed_calibration(text, eye_width, path);
}

std::string zed_calibration_file_name(uint32_t serial) { return "SN" + std::to_string(serial) + ".conf"; }

}  // namespace hwr::hal::hw
