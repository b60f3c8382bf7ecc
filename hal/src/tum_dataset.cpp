#include "hwr/hal/tum_dataset.hpp"

#include <filesystem>
#include <string_view>
#include <system_error>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "hwr/core/log.hpp"
#include "hwr/core/time.hpp"
#include "hwr/core/timestamp_text.hpp"
#include "image_file.hpp"
#include "text_table.hpp"
#include "hwr/core/time_association.hpp"

namespace hwr::hal {
namespace {

using core::Expected;
using core::ParseError;
using core::Status;

std::string join(const std::string& dir, const std::string& file) {
  if (!file.empty() && file.front() == '/') return file;
  return dir + "/" + file;
}

bool is_file(const std::string& path) {
  std::error_code ec;
  return std::filesystem::is_regular_file(path, ec);
}

// rgb.txt / depth.txt: "timestamp filename" per line; every listed image must exist.
template <class Entry>
Status read_image_list(const std::string& dir, const std::string& name, std::vector<Entry>* out) {
  const std::string path = dir + "/" + name;
  std::string text;
  HWR_RETURN_IF_ERROR(text::read_file(path, &text));
  std::string_view f[2];
  return text::for_each_data_line(text, [&](int line_no, std::string_view line) -> Status {
    const std::string where = text::where(path, line_no);
    const size_t n = text::split_fields(line, ' ', f, 2);
    if (n != 2)
      return ParseError(where + "expected 'timestamp filename', got " + std::to_string(n) + " fields");
    Entry e;
    if (!core::parse_timestamp_s(f[0], &e.t_ns)) {
      return ParseError(where + "bad timestamp " + text::quote(f[0]) + " (expected decimal seconds)");
    }
    if (!out->empty() && e.t_ns <= out->back().t_ns) {
      return ParseError(where + "timestamps must increase (" + std::string(f[0]) + " after " +
                        core::format_timestamp_s(out->back().t_ns, 6) + ")");
    }
    e.file = join(dir, std::string(f[1]));
    if (!is_file(e.file)) return core::NotFound(where + "listed image " + text::quote(f[1]) + " not found");
    out->push_back(std::move(e));
    return Status::Ok();
  });
}

Status read_accelerometer(const std::string& path, std::vector<TumAccelSample>* out) {
  std::string text;
  HWR_RETURN_IF_ERROR(text::read_file(path, &text));
  std::string_view f[4];
  return text::for_each_data_line(text, [&](int line_no, std::string_view line) -> Status {
    const std::string where = text::where(path, line_no);
    const size_t n = text::split_fields(line, ' ', f, 4);
    if (n != 4)
      return ParseError(where + "expected 'timestamp ax ay az', got " + std::to_string(n) + " fields");
    TumAccelSample s;
    if (!core::parse_timestamp_s(f[0], &s.t_ns))
      return ParseError(where + "bad timestamp " + text::quote(f[0]));
    for (int k = 0; k < 3; ++k) {
      if (!text::parse_double(f[k + 1], &s.accel_mps2[k])) {
        return ParseError(where + "field " + std::to_string(k + 2) +
                          ": not a finite number: " + text::quote(f[k + 1]));
      }
    }
    if (!out->empty() && s.t_ns <= out->back().t_ns) {
      return ParseError(where + "timestamps must increase (" + std::string(f[0]) + " after " +
                        core::format_timestamp_s(out->back().t_ns, 6) + ")");
    }
    out->push_back(s);
    return Status::Ok();
  });
}

}  // namespace

Expected<TumDataset> TumDataset::open(const std::string& dir, const TumDatasetOptions& options) {
  if (!(options.depth_scale > 0)) return core::InvalidArgument("TumDataset: depth_scale must be > 0");
  if (!(options.max_association_dt_s > 0)) {
    return core::InvalidArgument("TumDataset: max_association_dt_s must be > 0");
  }
  std::error_code ec;
  if (!std::filesystem::exists(dir, ec)) return core::NotFound(dir + ": TUM dataset folder not found");
  if (!std::filesystem::is_directory(dir, ec)) return core::NotFound(dir + ": not a folder");

  TumDataset ds;
  ds.dir_ = dir;
  ds.options_ = options;
  HWR_RETURN_IF_ERROR(read_image_list(dir, "rgb.txt", &ds.rgb_));
  HWR_RETURN_IF_ERROR(read_image_list(dir, "depth.txt", &ds.depth_));

  const std::string gt_path = dir + "/groundtruth.txt";
  if (std::filesystem::exists(gt_path, ec)) {
    auto gt = core::read_tum_trajectory(gt_path);
    if (!gt.ok()) return gt.status();
    ds.groundtruth_ = std::move(gt).value();
  } else if (options.require_groundtruth) {
    return core::NotFound(gt_path + ": ground truth file not found");
  }
  const std::string accel_path = dir + "/accelerometer.txt";
  if (std::filesystem::exists(accel_path, ec))
    HWR_RETURN_IF_ERROR(read_accelerometer(accel_path, &ds.accelerometer_));

  std::vector<int64_t> t_rgb(ds.rgb_.size());
  std::vector<int64_t> t_depth(ds.depth_.size());
  for (size_t i = 0; i < ds.rgb_.size(); ++i) t_rgb[i] = ds.rgb_[i].t_ns;
  for (size_t i = 0; i < ds.depth_.size(); ++i) t_depth[i] = ds.depth_[i].t_ns;
  for (const core::IndexPair& p :
       core::associate_nearest(t_rgb, t_depth, core::s_to_ns(options.max_association_dt_s))) {
    ds.pairs_.push_back({p.a, p.b});
  }
  if (ds.pairs_.empty()) {
    return core::CorruptData(dir + ": no colour/depth pairs closer than " +
                             std::to_string(options.max_association_dt_s) + " s (" +
                             std::to_string(ds.rgb_.size()) + " colour, " + std::to_string(ds.depth_.size()) +
                             " depth frames listed)");
  }
  HWR_LOG_INFO("hal.tum", "%s: %zu colour, %zu depth frames, %zu pairs, %zu ground-truth poses", dir.c_str(),
               ds.rgb_.size(), ds.depth_.size(), ds.pairs_.size(), ds.groundtruth_.size());
  return ds;
}

Status TumDataset::load_frame(size_t i, RgbdFrame* out) const {
  if (i >= pairs_.size()) {
    return core::OutOfRange(dir_ + ": frame " + std::to_string(i) + " requested, dataset has " +
                            std::to_string(pairs_.size()));
  }
  const Entry& rgb = rgb_[pairs_[i].rgb];
  const Entry& depth = depth_[pairs_[i].depth];
  HWR_RETURN_IF_ERROR(decode_image_file(rgb.file, cv::IMREAD_COLOR, &file_bytes_, &out->bgr));
  HWR_RETURN_IF_ERROR(decode_image_file(depth.file, cv::IMREAD_UNCHANGED, &file_bytes_, &depth_raw_));
  if (depth_raw_.type() != CV_16UC1) {
    return ParseError(depth.file + ": depth image is " + describe_mat(depth_raw_) +
                      ", expected a 16-bit single-channel PNG");
  }
  if (depth_raw_.size() != out->bgr.size()) {
    return core::CorruptData(depth.file + ": depth image is " + describe_mat(depth_raw_) +
                             " but colour image " + rgb.file + " is " + describe_mat(out->bgr));
  }
  const PinholeIntrinsics& k = options_.intrinsics;
  if (k.width > 0 && k.height > 0 && (out->bgr.cols != k.width || out->bgr.rows != k.height)) {
    return core::CorruptData(rgb.file + ": image is " + describe_mat(out->bgr) + ", camera is " +
                             std::to_string(k.width) + "x" + std::to_string(k.height));
  }
  depth_raw_.convertTo(out->depth_m, CV_32F, 1.0 / options_.depth_scale);
  out->invalid_depth_px =
      static_cast<uint32_t>(depth_raw_.total() - static_cast<size_t>(cv::countNonZero(depth_raw_)));
  out->right_gray.release();
  out->intrinsics = k;
  out->intrinsics.width = out->bgr.cols;
  out->intrinsics.height = out->bgr.rows;
  out->t_ns = rgb.t_ns;
  out->seq = pairs_[i].rgb;
  return Status::Ok();
}

}  // namespace hwr::hal
