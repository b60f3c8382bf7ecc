#include "hwr/estimation/bal_format.hpp"

#include <charconv>
#include <climits>
#include <cmath>
#include <cstdint>
#include <string_view>
#include <system_error>

#include "hwr/core/file_io.hpp"
#include "hwr/core/so3.hpp"

namespace hwr::estimation {
namespace {

// Whitespace-separated tokens with the line number of the current one, for error messages.
class Tokenizer {
 public:
  explicit Tokenizer(std::string_view text) : p_(text.data()), end_(text.data() + text.size()) {}

  bool next(std::string_view* token) {
    while (p_ < end_ && is_space(*p_)) {
      if (*p_ == '\n') ++line_;
      ++p_;
    }
    if (p_ == end_) return false;
    const char* start = p_;
    while (p_ < end_ && !is_space(*p_)) ++p_;
    *token = std::string_view(start, static_cast<size_t>(p_ - start));
    return true;
  }
  int line() const { return line_; }

 private:
  static bool is_space(char c) {
    return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
  }
  const char* p_;
  const char* end_;
  int line_ = 1;
};

class BalParser {
 public:
  BalParser(const std::string& path, std::string_view text) : path_(path), tok_(text) {}

  core::Status error(core::ErrorCode code, const std::string& what) const {
    return {code, path_ + ":" + std::to_string(tok_.line()) + ": " + what};
  }

  core::Status read_int64(const char* what, int64_t* out) {
    std::string_view t;
    if (!tok_.next(&t)) return error(core::ErrorCode::kCorruptData, std::string("file ends before ") + what);
    const auto [ptr, ec] = std::from_chars(t.data(), t.data() + t.size(), *out);
    if (ec != std::errc() || ptr != t.data() + t.size()) {
      return error(core::ErrorCode::kParseError, std::string("expected an integer ") + what + ", got '" +
                                                     std::string(t.substr(0, 40)) + "'");
    }
    return core::Status::Ok();
  }

  core::Status read_index(const char* what, int limit, int* out) {
    int64_t v = 0;
    HWR_RETURN_IF_ERROR(read_int64(what, &v));
    if (v < 0 || v >= limit) {
      return error(core::ErrorCode::kCorruptData, std::string(what) + " " + std::to_string(v) +
                                                      " out of range [0, " + std::to_string(limit) + ")");
    }
    *out = static_cast<int>(v);
    return core::Status::Ok();
  }

  core::Status read_double(const char* what, double* out) {
    std::string_view t;
    if (!tok_.next(&t)) return error(core::ErrorCode::kCorruptData, std::string("file ends before ") + what);
    const auto [ptr, ec] = std::from_chars(t.data(), t.data() + t.size(), *out);
    if (ec != std::errc() || ptr != t.data() + t.size() || !std::isfinite(*out)) {
      return error(core::ErrorCode::kParseError, std::string("expected a finite number for ") + what +
                                                     ", got '" + std::string(t.substr(0, 40)) + "'");
    }
    return core::Status::Ok();
  }

  bool at_end() {
    std::string_view t;
    return !tok_.next(&t);
  }

 private:
  std::string path_;
  Tokenizer tok_;
};

void append_double(std::string* out, double v) {
  char buf[32];
  const auto res = std::to_chars(buf, buf + sizeof(buf), v);  // shortest form that round-trips
  out->append(buf, res.ptr);
}

}  // namespace

core::Expected<BaProblem> read_bal(const std::string& path) {
  std::string text;
  HWR_RETURN_IF_ERROR(core::read_file(path, &text));
  BalParser in(path, text);
  int64_t counts[3] = {0, 0, 0};
  const char* names[3] = {"number of cameras", "number of points", "number of observations"};
  for (int i = 0; i < 3; ++i) {
    HWR_RETURN_IF_ERROR(in.read_int64(names[i], &counts[i]));
    if (counts[i] < 0 || counts[i] > INT_MAX) {
      return in.error(core::ErrorCode::kCorruptData,
                      std::string(names[i]) + " " + std::to_string(counts[i]) + " outside [0, INT_MAX]");
    }
  }
  // Every observation needs >= 8 bytes ("0 0 0 0\n"), every parameter >= 2: refuse counts the file
  // cannot hold before allocating anything for them.
  const uint64_t min_bytes =
      8 * static_cast<uint64_t>(counts[2]) +
      2 * (9 * static_cast<uint64_t>(counts[0]) + 3 * static_cast<uint64_t>(counts[1]));
  if (min_bytes > text.size()) {
    return core::CorruptData(path + ": header claims " + std::to_string(counts[0]) + " cameras, " +
                             std::to_string(counts[1]) + " points and " + std::to_string(counts[2]) +
                             " observations, more than a file of " + std::to_string(text.size()) +
                             " bytes can hold (truncated or corrupt)");
  }
  const int n_cameras = static_cast<int>(counts[0]), n_points = static_cast<int>(counts[1]);
  const int n_obs = static_cast<int>(counts[2]);
  BaProblem problem;
  problem.model = BaCameraModel::kBalRadial;
  problem.cameras.resize(static_cast<size_t>(n_cameras));
  problem.points.resize(static_cast<size_t>(n_points));
  problem.observations.resize(static_cast<size_t>(n_obs));
  for (BaObservation& o : problem.observations) {
    HWR_RETURN_IF_ERROR(in.read_index("camera index", n_cameras, &o.camera));
    HWR_RETURN_IF_ERROR(in.read_index("point index", n_points, &o.point));
    HWR_RETURN_IF_ERROR(in.read_double("observation x", &o.uv_px.x()));
    HWR_RETURN_IF_ERROR(in.read_double("observation y", &o.uv_px.y()));
  }
  for (BaCamera& cam : problem.cameras) {
    double v[9];
    for (double& x : v) HWR_RETURN_IF_ERROR(in.read_double("camera parameter", &x));
    cam.T_cam_world.setIdentity();
    cam.T_cam_world.linear() = core::so3_exp(Eigen::Vector3d(v[0], v[1], v[2]));
    cam.T_cam_world.translation() = Eigen::Vector3d(v[3], v[4], v[5]);
    cam.K.f = v[6];
    cam.K.k1 = v[7];
    cam.K.k2 = v[8];
    cam.K.fx = cam.K.fy = v[6];
    cam.K.cx = cam.K.cy = 0;
  }
  for (BaPoint& p : problem.points) {
    for (int i = 0; i < 3; ++i) HWR_RETURN_IF_ERROR(in.read_double("point coordinate", &p.p_world[i]));
  }
  if (!in.at_end()) {
    return in.error(core::ErrorCode::kCorruptData,
                    "trailing data after the last point (counts in the header too small?)");
  }
  return problem;
}

core::Status write_bal(const BaProblem& problem, const std::string& path) {
  const size_t nc = problem.cameras.size(), np = problem.points.size();
  for (size_t i = 0; i < problem.observations.size(); ++i) {
    const BaObservation& o = problem.observations[i];
    if (o.camera < 0 || static_cast<size_t>(o.camera) >= nc || o.point < 0 ||
        static_cast<size_t>(o.point) >= np) {
      return core::InvalidArgument("write_bal: observation " + std::to_string(i) + " refers to camera " +
                                   std::to_string(o.camera) + " / point " + std::to_string(o.point) +
                                   ", out of range");
    }
  }
  const bool pinhole = problem.model == BaCameraModel::kPinhole;
  // OpenCV camera axes (z forward, y down) to BAL's (looking down -z, y up).
  const Eigen::Matrix3d F = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
  std::string out;
  out.reserve(64 * (problem.observations.size() + 9 * nc + 3 * np) / 2 + 64);
  out += std::to_string(nc) + " " + std::to_string(np) + " " + std::to_string(problem.observations.size()) +
         "\n";
  for (const BaObservation& o : problem.observations) {
    Eigen::Vector2d uv = o.uv_px;
    if (pinhole) {
      const BaIntrinsics& K = problem.cameras[static_cast<size_t>(o.camera)].K;
      uv = Eigen::Vector2d(o.uv_px.x() - K.cx, -(o.uv_px.y() - K.cy) * K.fx / K.fy);
    }
    out += std::to_string(o.camera) + " " + std::to_string(o.point) + " ";
    append_double(&out, uv.x());
    out += ' ';
    append_double(&out, uv.y());
    out += '\n';
  }
  for (const BaCamera& cam : problem.cameras) {
    Eigen::Matrix3d R = cam.T_cam_world.linear();
    Eigen::Vector3d t = cam.T_cam_world.translation();
    double f = cam.K.f, k1 = cam.K.k1, k2 = cam.K.k2;
    if (pinhole) {
      R = F * R;
      t = F * t;
      f = cam.K.fx;
      k1 = k2 = 0;
    }
    const Eigen::Vector3d w = core::so3_log(R);
    const double v[9] = {w.x(), w.y(), w.z(), t.x(), t.y(), t.z(), f, k1, k2};
    for (const double x : v) {
      append_double(&out, x);
      out += '\n';
    }
  }
  for (const BaPoint& p : problem.points) {
    for (int i = 0; i < 3; ++i) {
      append_double(&out, p.p_world[i]);
      out += '\n';
    }
  }
  return core::write_file_atomic(path, out);
}

}  // namespace hwr::estimation
