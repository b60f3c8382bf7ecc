#include "hwr/hal/euroc_dataset.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string_view>
#include <system_error>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "hwr/core/config.hpp"
#include "hwr/core/log.hpp"
#include "hwr/core/time.hpp"
#include "image_file.hpp"
#include "text_table.hpp"
#include "hwr/core/time_association.hpp"

namespace hwr::hal {
namespace {

namespace fs = std::filesystem;
using core::Expected;
using core::ParseError;
using core::Status;

bool exists(const std::string& path) {
  std::error_code ec;
  return fs::exists(path, ec);
}

bool is_dir(const std::string& path) {
  std::error_code ec;
  return fs::is_directory(path, ec);
}

// EuRoC's sensor.yaml is written by OpenCV's FileStorage and starts with "%YAML:1.0", a directive
// yaml-cpp rejects; it carries nothing we need. The line is blanked so line numbers still match.
Expected<core::ConfigDocument> load_sensor_yaml(const std::string& path) {
  std::string text;
  HWR_RETURN_IF_ERROR(text::read_file(path, &text));
  const size_t b = text.find_first_not_of(" \t\r\n");
  if (b != std::string::npos && text.compare(b, 5, "%YAML") == 0) {
    const size_t e = text.find('\n', b);
    text.replace(b, (e == std::string::npos ? text.size() : e) - b, "");
  }
  return core::ConfigDocument::parse(text, path);
}

// Type errors and missing required keys; unknown keys are fine in third-party files.
Status config_errors(const core::ConfigDocument& doc) {
  for (const std::string& e : doc.all_errors()) {
    if (e.find(": unknown key '") == std::string::npos) return ParseError(e);
  }
  return Status::Ok();
}

Status read_T_BS(const core::ConfigDocument& doc, core::ConfigMap root, const std::string& path,
                 Eigen::Isometry3d* out) {
  if (!root.has("T_BS")) return ParseError(path + ": key 'T_BS' required but missing");
  core::ConfigMap t = root.child("T_BS");
  int rows = 4;
  int cols = 4;
  std::vector<double> data;
  t.get("rows", &rows).get("cols", &cols).require("data", &data);
  HWR_RETURN_IF_ERROR(config_errors(doc));
  if (rows != 4 || cols != 4 || data.size() != 16) {
    return ParseError(path + ":" + std::to_string(t.line()) +
                      ": key 'T_BS': expected a 4x4 matrix (16 numbers), got " + std::to_string(rows) + "x" +
                      std::to_string(cols) + " with " + std::to_string(data.size()) + " numbers");
  }
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = data[static_cast<size_t>(4 * r + c)];
  }
  const Eigen::Matrix3d R = m.topLeftCorner<3, 3>();
  const double orth_err = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (orth_err > 1e-5 || R.determinant() < 0 ||
      (m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 0) {
    return ParseError(path + ":" + std::to_string(t.line()) +
                      ": key 'T_BS' is not a rigid transform (|R^T R - I| = " + std::to_string(orth_err) +
                      ")");
  }
  out->setIdentity();
  out->linear() = Eigen::Quaterniond(R).normalized().toRotationMatrix();
  out->translation() = m.topRightCorner<3, 1>();
  return Status::Ok();
}

// "#timestamp [ns],filename"; rows whose image is absent are counted, not kept.
Status read_camera_list(const std::string& cam_dir, std::vector<std::pair<int64_t, std::string>>* frames,
                        size_t* listed, size_t* missing, std::string* first_missing);

}  // namespace

Expected<EurocCameraCalib> read_euroc_camera_yaml(const std::string& path) {
  auto doc = load_sensor_yaml(path);
  if (!doc.ok()) return doc.status();
  core::ConfigMap root = doc->root();
  std::string camera_model = "pinhole";
  std::string distortion_model = "radial-tangential";
  Eigen::Vector4d k = Eigen::Vector4d::Zero();
  Eigen::Vector2d resolution = Eigen::Vector2d::Zero();
  std::vector<double> dist;
  EurocCameraCalib calib;
  root.get("camera_model", &camera_model)
      .get("distortion_model", &distortion_model)
      .require("intrinsics", &k)
      .require("resolution", &resolution)
      .require("distortion_coefficients", &dist)
      .get("rate_hz", &calib.rate_hz);
  HWR_RETURN_IF_ERROR(config_errors(*doc));
  HWR_RETURN_IF_ERROR(read_T_BS(*doc, root, path, &calib.T_body_cam));
  if (camera_model != "pinhole") {
    return ParseError(path + ": camera_model '" + camera_model + "' is not supported (expected pinhole)");
  }
  if (distortion_model != "radial-tangential" && distortion_model != "radtan") {
    return ParseError(path + ": distortion_model '" + distortion_model +
                      "' is not supported (expected radial-tangential)");
  }
  if (dist.size() != 4 && dist.size() != 5) {
    return ParseError(path + ": distortion_coefficients: expected 4 or 5 numbers (k1 k2 p1 p2 [k3]), got " +
                      std::to_string(dist.size()));
  }
  if (resolution.x() < 1 || resolution.y() < 1 || resolution.x() != std::floor(resolution.x()) ||
      resolution.y() != std::floor(resolution.y()) || !(k.x() > 0) || !(k.y() > 0)) {
    return ParseError(path + ": resolution must be two positive integers and fu, fv positive");
  }
  PinholeIntrinsics& in = calib.intrinsics;
  in.width = static_cast<int>(resolution.x());
  in.height = static_cast<int>(resolution.y());
  in.fx = k[0];
  in.fy = k[1];
  in.cx = k[2];
  in.cy = k[3];
  for (size_t i = 0; i < dist.size(); ++i) in.distortion[i] = dist[i];
  return calib;
}

Expected<EurocImuCalib> read_euroc_imu_yaml(const std::string& path) {
  auto doc = load_sensor_yaml(path);
  if (!doc.ok()) return doc.status();
  core::ConfigMap root = doc->root();
  EurocImuCalib calib;
  calib.present = true;
  root.get("rate_hz", &calib.rate_hz)
      .get("gyroscope_noise_density", &calib.gyro_noise_density)
      .get("gyroscope_random_walk", &calib.gyro_random_walk)
      .get("accelerometer_noise_density", &calib.accel_noise_density)
      .get("accelerometer_random_walk", &calib.accel_random_walk);
  HWR_RETURN_IF_ERROR(config_errors(*doc));
  if (root.has("T_BS")) HWR_RETURN_IF_ERROR(read_T_BS(*doc, root, path, &calib.T_body_imu));
  return calib;
}

namespace {

Status read_camera_list(const std::string& cam_dir, std::vector<std::pair<int64_t, std::string>>* frames,
                        size_t* listed, size_t* missing, std::string* first_missing) {
  const std::string path = cam_dir + "/data.csv";
  std::string text;
  HWR_RETURN_IF_ERROR(text::read_file(path, &text));
  std::string_view f[2];
  int64_t last_t_ns = 0;
  return text::for_each_data_line(text, [&](int line_no, std::string_view line) -> Status {
    const std::string where = text::where(path, line_no);
    const size_t n = text::split_fields(line, ',', f, 2);
    if (n != 2) {
      return ParseError(where + "expected 2 comma-separated fields (timestamp [ns],filename), got " +
                        std::to_string(n));
    }
    int64_t t_ns = 0;
    if (!text::parse_int64(f[0], &t_ns)) {
      return ParseError(where + "field 1 (timestamp [ns]): not an integer: " + text::quote(f[0]));
    }
    if (*listed > 0 && t_ns <= last_t_ns) {
      return ParseError(where + "timestamps must increase (" + std::to_string(t_ns) + " after " +
                        std::to_string(last_t_ns) + ")");
    }
    if (f[1].empty()) return ParseError(where + "empty filename");
    last_t_ns = t_ns;
    ++*listed;
    std::string file = cam_dir + "/data/" + std::string(f[1]);
    std::error_code ec;
    if (!fs::is_regular_file(file, ec)) {
      if (*missing == 0) *first_missing = where + "'" + std::string(f[1]) + "'";
      ++*missing;
      return Status::Ok();
    }
    frames->emplace_back(t_ns, std::move(file));
    return Status::Ok();
  });
}

}  // namespace

Expected<EurocDataset> EurocDataset::open(const std::string& mav0_dir, const EurocDatasetOptions& options) {
  if (!(options.max_stereo_dt_s > 0))
    return core::InvalidArgument("EurocDataset: max_stereo_dt_s must be > 0");
  if (!exists(mav0_dir)) return core::NotFound(mav0_dir + ": EuRoC mav0 folder not found");
  if (!is_dir(mav0_dir)) return core::NotFound(mav0_dir + ": not a folder");
  EurocDataset ds;
  ds.dir_ = mav0_dir;

  // Cameras: both or neither.
  const bool has_cam[2] = {is_dir(mav0_dir + "/cam0"), is_dir(mav0_dir + "/cam1")};
  if (has_cam[0] != has_cam[1]) {
    return core::NotFound(mav0_dir + "/cam" + (has_cam[0] ? "1" : "0") + ": camera folder not found (cam" +
                          (has_cam[0] ? "0" : "1") + " exists; stereo needs both)");
  }
  ds.has_stereo_ = has_cam[0];
  if (ds.has_stereo_) {
    for (int c = 0; c < 2; ++c) {
      const std::string cam_dir = mav0_dir + "/cam" + std::to_string(c);
      auto calib = read_euroc_camera_yaml(cam_dir + "/sensor.yaml");
      if (!calib.ok()) return calib.status();
      Camera& cam = ds.cam_[c];
      cam.calib = *calib;
      std::string first_missing;
      std::vector<std::pair<int64_t, std::string>> frames;
      HWR_RETURN_IF_ERROR(read_camera_list(cam_dir, &frames, &cam.listed, &cam.missing, &first_missing));
      for (auto& f : frames) cam.frames.push_back({f.first, std::move(f.second)});
      if (cam.missing > 0) {
        HWR_LOG_WARN("hal.euroc",
                     "%s/data.csv: %zu of %zu listed frames have no image file; skipped (first: %s)",
                     cam_dir.c_str(), cam.missing, cam.listed, first_missing.c_str());
      }
    }
    std::vector<int64_t> t[2];
    for (int c = 0; c < 2; ++c) {
      for (const Frame& f : ds.cam_[c].frames) t[c].push_back(f.t_ns);
    }
    for (const core::IndexPair& p :
         core::associate_nearest(t[0], t[1], core::s_to_ns(options.max_stereo_dt_s))) {
      ds.pairs_.push_back({p.a, p.b});
    }
    if (ds.pairs_.empty()) {
      return core::CorruptData(mav0_dir + ": no cam0/cam1 frames closer than " +
                               std::to_string(options.max_stereo_dt_s) + " s (" +
                               std::to_string(ds.cam_[0].frames.size()) + " and " +
                               std::to_string(ds.cam_[1].frames.size()) + " frames with images)");
    }
  }

  auto imu = read_imu_csv(mav0_dir + "/imu0/data.csv");
  if (!imu.ok()) return imu.status();
  ds.imu_ = std::move(imu).value();
  if (ds.imu_.empty()) return core::CorruptData(mav0_dir + "/imu0/data.csv: no IMU samples");
  if (exists(mav0_dir + "/imu0/sensor.yaml")) {
    auto calib = read_euroc_imu_yaml(mav0_dir + "/imu0/sensor.yaml");
    if (!calib.ok()) return calib.status();
    ds.imu_calib_ = *calib;
  }

  for (const char* gt_file : {"/state_groundtruth_estimate0/data.csv", "/gt0/data.csv"}) {
    if (!exists(mav0_dir + gt_file)) continue;
    auto gt = read_euroc_state_csv(mav0_dir + gt_file);
    if (!gt.ok()) return gt.status();
    ds.state_gt_ = std::move(gt).value();
    break;
  }

  const fs::path parent = fs::path(mav0_dir).lexically_normal().parent_path();
  if (!options.tum_groundtruth_file.empty()) {
    const fs::path p(options.tum_groundtruth_file);
    ds.tum_gt_path_ = (p.is_absolute() ? p : parent / p).string();
  } else {
    const std::string ov_dir = (parent / "groundtruth_ov_data").string();
    std::vector<std::string> found;
    std::error_code ec;
    if (is_dir(ov_dir)) {
      for (const auto& entry : fs::directory_iterator(ov_dir, ec)) {
        const std::string name = entry.path().filename().string();
        const std::string suffix = "_original.txt";
        if (name.size() > suffix.size() &&
            name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0) {
          found.push_back(entry.path().string());
        }
      }
    }
    if (found.size() == 1) ds.tum_gt_path_ = found.front();
  }
  if (!ds.tum_gt_path_.empty()) {
    auto gt = core::read_tum_trajectory(ds.tum_gt_path_);
    if (!gt.ok()) return gt.status();
    ds.tum_gt_ = std::move(gt).value();
  }

  HWR_LOG_INFO("hal.euroc", "%s: %zu stereo pairs, %zu IMU samples, %zu state and %zu TUM ground-truth poses",
               mav0_dir.c_str(), ds.pairs_.size(), ds.imu_.size(), ds.state_gt_.size(), ds.tum_gt_.size());
  return ds;
}

Status EurocDataset::load_stereo(size_t i, cv::Mat* left_gray, cv::Mat* right_gray) const {
  if (i >= pairs_.size()) {
    return core::OutOfRange(dir_ + ": stereo pair " + std::to_string(i) + " requested, dataset has " +
                            std::to_string(pairs_.size()));
  }
  cv::Mat* out[2] = {left_gray, right_gray};
  const std::string* files[2] = {&left_path(i), &right_path(i)};
  for (int c = 0; c < 2; ++c) {
    HWR_RETURN_IF_ERROR(decode_image_file(*files[c], cv::IMREAD_GRAYSCALE, &file_bytes_, out[c]));
    const PinholeIntrinsics& k = cam_[c].calib.intrinsics;
    if (out[c]->cols != k.width || out[c]->rows != k.height) {
      return core::CorruptData(*files[c] + ": image is " + describe_mat(*out[c]) + ", sensor.yaml says " +
                               std::to_string(k.width) + "x" + std::to_string(k.height));
    }
  }
  return Status::Ok();
}

}  // namespace hwr::hal
