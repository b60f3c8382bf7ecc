// Writes a seed corpus for fuzz_recording_log into the folder given as the only argument: small valid
// sensor recordings (SensorRecorder), mono and stereo, with IMU, magnetometer and GNSS samples and a
// few 8x6 frames, so mutation starts from files the reader accepts. Generated at test time; seeds are
// never committed.

#include <cstdio>
#include <limits>
#include <string>

#include <opencv2/core.hpp>

#include "corpus_dir.hpp"
#include "hwr/mapio/sensor_recorder.hpp"

namespace {

constexpr int kW = 8, kH = 6;

bool write_seed(const std::string& path, bool stereo, int frames, int samples) {
  hwr::hal::SourceInfo info;
  info.name = "seed";
  info.intrinsics.width = kW;
  info.intrinsics.height = kH;
  info.intrinsics.fx = info.intrinsics.fy = 10;
  info.intrinsics.cx = 3.5;
  info.intrinsics.cy = 2.5;
  info.has_imu = info.has_mag = info.has_gnss = true;
  info.stereo = stereo;
  info.first_t_ns = 1'000'000'000;
  hwr::mapio::SensorRecorderConfig config;
  config.wait_when_full = true;
  auto rec = hwr::mapio::SensorRecorder::open(path, info, config);
  if (!rec.ok()) {
    std::fprintf(stderr, "%s\n", rec.status().message().c_str());
    return false;
  }
  for (int i = 0; i < samples; ++i) {
    const int64_t t_ns = info.first_t_ns + int64_t{i} * 5'000'000;
    hwr::hal::ImuSample s;
    s.t_ns = t_ns;
    s.accel_mps2 = Eigen::Vector3d(0.1 * i, 0, 9.81);
    (*rec)->record_imu(s);
    if (i % 4 == 0) {
      hwr::hal::MagSample m;
      m.t_ns = t_ns;
      m.field_uT = Eigen::Vector3d(20, 0, 40);
      (*rec)->record_mag(m);
    }
    if (i % 10 == 0) {
      hwr::hal::GnssFix g;
      g.t_ns = t_ns;
      g.fix_type = 3;
      g.lat_deg = 63.4;
      (*rec)->record_gnss(g);
    }
  }
  for (int k = 0; k < frames; ++k) {
    hwr::hal::RgbdFrame f;
    f.t_ns = info.first_t_ns + int64_t{k} * 33'333'333;
    f.bgr = cv::Mat(kH, kW, CV_8UC3, cv::Scalar(10 * k, 20, 30));
    f.depth_m = cv::Mat(kH, kW, CV_32FC1, cv::Scalar(1.5f + 0.1f * static_cast<float>(k)));
    f.depth_m.at<float>(0, 0) = std::numeric_limits<float>::quiet_NaN();
    if (stereo) f.right_gray = cv::Mat(kH, kW, CV_8UC1, cv::Scalar(7 * k));
    (*rec)->record_frame(f);
  }
  const hwr::core::Status st = (*rec)->close();
  if (!st.ok()) std::fprintf(stderr, "%s\n", st.message().c_str());
  return st.ok();
}

}  // namespace

int main(int argc, char** argv) {
  std::string dir;
  if (const int rc = hwr::fuzz::corpus_dir_from_args(argc, argv, &dir); rc != 0) return rc;
  const bool ok = write_seed(dir + "/mono_2frames.lcmlog", false, 2, 12) &&
                  write_seed(dir + "/stereo_2frames.lcmlog", true, 2, 12) &&
                  write_seed(dir + "/imu_only.lcmlog", false, 0, 30) &&
                  write_seed(dir + "/stereo_1frame.lcmlog", true, 1, 0);
  return ok ? 0 : 1;
}
