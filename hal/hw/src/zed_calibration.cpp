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

std::string upper(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
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
// lower-case section → lower-case key → value. A repeated key keeps its last value (as SimpleIni,
// which zed-open-capture reads the file with, does without multi-key mode).
using Ini = std::map<std::string, std::map<std::string, Entry>>;

core::Expected<Ini> parse_ini(std::string_view text, const std::string& source) {
  constexpr std::string_view kUtf8Bom = "\xEF\xBB\xBF";
  if (text.substr(0, kUtf8Bom.size()) == kUtf8Bom) text.remove_prefix(kUtf8Bom.size());
  Ini ini;
  std::string section;
  int line_no = 0;
  while (!text.empty()) {
    const size_t eol = text.find('\n');
    std::string_view line = trim(text.substr(0, eol));  // trim also drops a CR
    text.remove_prefix(eol == std::string_view::npos ? text.size() : eol + 1);
    ++line_no;
    const std::string where = source + ":" + std::to_string(line_no) + ": ";
    if (line.empty() || line.front() == ';' || line.front() == '#') continue;
    if (line.front() == '[') {
      if (line.back() != ']') return core::ParseError(where + "unterminated section header");
      section = lower(trim(line.substr(1, line.size() - 2)));
      ini[section];  // an empty section still exists
      continue;
    }
    const size_t eq = line.find('=');
    if (eq == std::string_view::npos) {
      return core::ParseError(where + "expected 'key = value', got '" + std::string(line.substr(0, 60)) +
                              "'");
    }
    // Keys before the first [section] land in section "" (ignored, as SimpleIni does).
    const std::string key = lower(trim(line.substr(0, eq)));
    if (key.empty()) return core::ParseError(where + "empty key");
    ini[section][key] = Entry{std::string(trim(line.substr(eq + 1))), line_no};
  }
  return ini;
}

struct Mode {
  const char* name;  // the section / key suffix
  int width, height;
};

// hardware.md: per-eye sizes of the ZED 2i's video modes.
constexpr Mode kModes[] = {{"2K", 2208, 1242}, {"FHD", 1920, 1080}, {"HD", 1280, 720}, {"VGA", 672, 376}};

const Mode* find_mode(int eye_width) {
  for (const Mode& m : kModes) {
    if (m.width == eye_width) return &m;
  }
  return nullptr;
}

// Reads numbers out of the INI, keeping the first error (named) and carrying on so the code reads
// straight; callers check error() once.
class Reader {
 public:
  Reader(const Ini& ini, std::string source) : ini_(ini), source_(std::move(source)) {}

  // The number under [section] key (lower-case names); nullopt if absent (an error when required)
  // or not a finite number (always an error).
  std::optional<double> number(const std::string& section, const std::string& key, bool required = true) {
    auto s = ini_.find(section);
    if (s == ini_.end()) {
      if (required) fail(core::NotFound(source_ + ": no section [" + upper(section) + "]"));
      return std::nullopt;
    }
    auto k = s->second.find(key);
    if (k == s->second.end()) {
      if (required) fail(core::NotFound(source_ + ": [" + upper(section) + "] has no key '" + key + "'"));
      return std::nullopt;
    }
    std::string_view v = k->second.value;
    if (!v.empty() && v.front() == '+') v.remove_prefix(1);  // from_chars takes no '+'
    double x = 0;
    const auto r = std::from_chars(v.data(), v.data() + v.size(), x);  // locale-independent
    if (v.empty() || r.ec != std::errc() || r.ptr != v.data() + v.size() || !std::isfinite(x)) {
      fail(core::ParseError(source_ + ":" + std::to_string(k->second.line) + ": [" + upper(section) + "] " +
                            key + " = '" + k->second.value.substr(0, 40) +
                            "' is not a finite number (a '.' decimal point is expected)"));
      return std::nullopt;
    }
    return x;
  }
  const core::Status& error() const { return error_; }

 private:
  void fail(core::Status st) {
    if (error_.ok()) error_ = std::move(st);
  }
  const Ini& ini_;
  std::string source_;
  core::Status error_;
};

PinholeIntrinsics read_camera(Reader& r, const std::string& section, const Mode& mode) {
  PinholeIntrinsics K;
  K.width = mode.width;
  K.height = mode.height;
  K.fx = r.number(section, "fx").value_or(0);
  K.fy = r.number(section, "fy").value_or(0);
  K.cx = r.number(section, "cx").value_or(0);
  K.cy = r.number(section, "cy").value_or(0);
  // OpenCV order k1 k2 p1 p2 k3; p1 p2 k3 optional (see the header).
  static const char* const kKeys[5] = {"k1", "k2", "p1", "p2", "k3"};
  for (size_t i = 0; i < 5; ++i) K.distortion[i] = r.number(section, kKeys[i], i < 2).value_or(0);
  return K;
}

core::Status check_camera(const PinholeIntrinsics& K, const std::string& source, const std::string& section) {
  if (!(K.fx > 0 && K.fy > 0)) {
    return core::OutOfRange(source + ": [" + section + "] focal lengths must be positive (fx = " +
                            std::to_string(K.fx) + ", fy = " + std::to_string(K.fy) + ")");
  }
  if (!(K.cx > 0 && K.cx < K.width && K.cy > 0 && K.cy < K.height)) {
    return core::OutOfRange(source + ": [" + section + "] principal point (" + std::to_string(K.cx) + ", " +
                            std::to_string(K.cy) + ") is outside the " + std::to_string(K.width) + "x" +
                            std::to_string(K.height) + " image: a section for another resolution?");
  }
  return core::Status::Ok();
}

}  // namespace

core::Expected<hal::StereoRig> parse_zed_calibration(std::string_view text, int eye_width,
                                                     const std::string& source_name) {
  const Mode* mode = find_mode(eye_width);
  if (mode == nullptr) {
    return core::InvalidArgument(source_name + ": no ZED resolution has eye width " +
                                 std::to_string(eye_width) + " (2208 2K, 1920 FHD, 1280 HD, 672 VGA)");
  }
  auto ini = parse_ini(text, source_name);
  if (!ini.ok()) return ini.status();
  Reader r(ini.value(), source_name);
  const std::string suffix = lower(mode->name);
  const std::string left_section = "left_cam_" + suffix;
  const std::string right_section = "right_cam_" + suffix;
  hal::StereoRig rig;
  rig.left = read_camera(r, left_section, *mode);
  rig.right = read_camera(r, right_section, *mode);
  const std::optional<double> baseline_mm = r.number("stereo", "baseline");
  std::optional<double> ty_mm = r.number("stereo", "ty_" + suffix, false);
  std::optional<double> tz_mm = r.number("stereo", "tz_" + suffix, false);
  if (!ty_mm && r.error().ok()) ty_mm = r.number("stereo", "ty", false);
  if (!tz_mm && r.error().ok()) tz_mm = r.number("stereo", "tz", false);
  if (!ty_mm) r.number("stereo", "ty_" + suffix);  // names the missing key
  if (!tz_mm) r.number("stereo", "tz_" + suffix);
  const double rx = r.number("stereo", "rx_" + suffix).value_or(0);
  const double cv = r.number("stereo", "cv_" + suffix).value_or(0);
  const double rz = r.number("stereo", "rz_" + suffix).value_or(0);
  if (!r.error().ok()) return r.error();

  HWR_RETURN_IF_ERROR(check_camera(rig.left, source_name, upper(left_section)));
  HWR_RETURN_IF_ERROR(check_camera(rig.right, source_name, upper(right_section)));
  if (!(*baseline_mm > 0 && *baseline_mm < 1000)) {
    return core::OutOfRange(source_name + ": [STEREO] Baseline = " + std::to_string(*baseline_mm) +
                            " is not a stereo baseline in mm (0 < Baseline < 1000; the ZED 2i's is ~120)");
  }
  if (!(std::fabs(*ty_mm) < *baseline_mm && std::fabs(*tz_mm) < *baseline_mm)) {
    return core::OutOfRange(source_name + ": [STEREO] TY, TZ_" + mode->name + " = " + std::to_string(*ty_mm) +
                            ", " + std::to_string(*tz_mm) + " mm are not small against Baseline = " +
                            std::to_string(*baseline_mm) + " mm (a ZED's eyes are side by side)");
  }
  const auto& dl = rig.left.distortion;
  const auto& dr = rig.right.distortion;
  if (dl[0] == 0 && dl[1] == 0 && dr[0] == 0 && dr[1] == 0) {
    return core::CorruptData(source_name + ": k1 and k2 are zero for both cameras at " + mode->name +
                             ": a calibration file saved under a comma-decimal locale; download it again "
                             "from Stereolabs (https://calib.stereolabs.com/?SN=<serial>)");
  }
  // The eyes are built parallel: the factory's angles are ~1e-3 rad. 0.2 rad (11°) is far beyond any
  // ZED and catches a corrupted digit or a value in degrees.
  const Eigen::Vector3d rvec(rx, cv, rz);
  if (!(rvec.norm() <= 0.2)) {
    return core::OutOfRange(source_name + ": [STEREO] rotation (RX, CV, RZ)_" + mode->name + " = (" +
                            std::to_string(rx) + ", " + std::to_string(cv) + ", " + std::to_string(rz) +
                            ") rad turns the right eye by more than 0.2 rad (degrees instead of radians?)");
  }
  // R_right_left = Rodrigues([RX, CV, RZ]) (angle |r| about r/|r|; identity for r = 0), as
  // zed-open-capture passes it to cv::stereoRectify. T_left_right = [Rᵀ | Rᵀ · t_file] (header).
  const double angle = rvec.norm();
  const Eigen::Matrix3d R_right_left =
      angle > 0 ? Eigen::AngleAxisd(angle, rvec / angle).toRotationMatrix() : Eigen::Matrix3d::Identity();
  const Eigen::Vector3d t_file_m = Eigen::Vector3d(*baseline_mm, *ty_mm, *tz_mm) * 1e-3;
  rig.T_left_right = Eigen::Isometry3d::Identity();
  rig.T_left_right.linear() = R_right_left.transpose();
  rig.T_left_right.translation() = R_right_left.transpose() * t_file_m;
  return rig;
}

core::Expected<hal::StereoRig> load_zed_calibration_file(const std::string& path, int eye_width) {
  std::string text;
  if (core::Status st = core::read_file(path, &text); !st.ok()) {
    return core::Status(st.code(), st.message() +
                                       " (the ZED's factory calibration: download SN<serial>.conf from "
                                       "https://calib.stereolabs.com/?SN=<serial>)");
  }
  return parse_zed_calibration(text, eye_width, path);
}

std::string zed_calibration_file_name(uint32_t serial) { return "SN" + std::to_string(serial) + ".conf"; }

}  // namespace hwr::hal::hw
