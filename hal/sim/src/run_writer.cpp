#include "hwr/sim/run_writer.hpp"

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <thread>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "hwr/core/time.hpp"
#include "hwr/core/timestamp_text.hpp"
#include "hwr/core/tum_trajectory.hpp"
#include "hwr/sim/random.hpp"
#include "hwr/sim/sample_times.hpp"
#include "hwr/sim/sim_calibration.hpp"
#include "hwr/sim/world_frame.hpp"
#include "sim_text.hpp"

namespace hwr::sim {
namespace {

namespace fs = std::filesystem;

Eigen::Quaterniond positive_w(const Eigen::Matrix3d& R) {
  Eigen::Quaterniond q(R);
  q.normalize();
  if (q.w() < 0) q.coeffs() *= -1.0;
  return q;
}

std::string imu_csv(const std::vector<ImuRecord>& imu) {
  std::string s =
      "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],a_RS_S_x [m s^-2],"
      "a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n";
  s.reserve(s.size() + imu.size() * 128);
  char buf[256];
  for (const ImuRecord& r : imu) {
    const hal::ImuSample& m = r.sample;
    std::snprintf(buf, sizeof(buf), "%lld,%.12g,%.12g,%.12g,%.12g,%.12g,%.12g\n",
                  static_cast<long long>(m.t_ns), m.gyro_radps.x(), m.gyro_radps.y(), m.gyro_radps.z(),
                  m.accel_mps2.x(), m.accel_mps2.y(), m.accel_mps2.z());
    s += buf;
  }
  return s;
}

struct GroundTruthRow {
  int64_t t_ns = 0;
  Eigen::Isometry3d T_world_imu;
  Eigen::Vector3d v_world_mps;
};

std::string state_csv(const std::vector<GroundTruthRow>& gt, const std::vector<ImuRecord>& imu) {
  std::string s =
      "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z [], "
      "v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], b_w_RS_S_y [rad "
      "s^-1], "
      "b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], b_a_RS_S_z [m s^-2]\n";
  s.reserve(s.size() + gt.size() * 256);
  char buf[512];
  for (size_t k = 0; k < gt.size(); ++k) {
    const Eigen::Vector3d p = gt[k].T_world_imu.translation();
    const Eigen::Quaterniond q = positive_w(gt[k].T_world_imu.linear());
    const Eigen::Vector3d& v = gt[k].v_world_mps;
    const Eigen::Vector3d& bg = imu[k].gyro_bias_radps;
    const Eigen::Vector3d& ba = imu[k].accel_bias_mps2;
    std::snprintf(
        buf, sizeof(buf),
        "%lld,%.9f,%.9f,%.9f,%.12f,%.12f,%.12f,%.12f,%.9f,%.9f,%.9f,%.12g,%.12g,%.12g,%.12g,%.12g,%.12g\n",
        static_cast<long long>(gt[k].t_ns), p.x(), p.y(), p.z(), q.w(), q.x(), q.y(), q.z(), v.x(), v.y(),
        v.z(), bg.x(), bg.y(), bg.z(), ba.x(), ba.y(), ba.z());
    s += buf;
  }
  return s;
}

std::string mag_csv(const std::vector<hal::MagSample>& mag) {
  std::string s = "#timestamp [ns],m_x [uT],m_y [uT],m_z [uT]\n";
  char buf[160];
  for (const hal::MagSample& m : mag) {
    std::snprintf(buf, sizeof(buf), "%lld,%.9g,%.9g,%.9g\n", static_cast<long long>(m.t_ns), m.field_uT.x(),
                  m.field_uT.y(), m.field_uT.z());
    s += buf;
  }
  return s;
}

std::string gnss_csv(const std::vector<GnssRecord>& gnss) {
  std::string s = "#timestamp [ns],lat [deg],lon [deg],height [m],h_acc [m],v_acc [m],fix_type,num_sv\n";
  char buf[200];
  for (const GnssRecord& r : gnss) {
    const hal::GnssFix& f = r.fix;
    if (f.fix_type == 0) {
      std::snprintf(buf, sizeof(buf), "%lld,nan,nan,nan,nan,nan,0,%d\n", static_cast<long long>(f.t_ns),
                    f.num_sv);
    } else {
      std::snprintf(buf, sizeof(buf), "%lld,%.10f,%.10f,%.4f,%.3f,%.3f,%d,%d\n",
                    static_cast<long long>(f.t_ns), f.lat_deg, f.lon_deg, f.height_m, f.h_acc_m, f.v_acc_m,
                    f.fix_type, f.num_sv);
    }
    s += buf;
  }
  return s;
}

std::string image_list(const char* what, const std::string& scenario, const std::string& folder,
                       const std::vector<std::string>& stamps) {
  std::string s = std::string("# ") + what + "\n# file: 'hwr-sim " + scenario + "'\n# timestamp filename\n";
  for (const std::string& t : stamps) s += t + " " + folder + "/" + t + ".png\n";
  return s;
}

std::string weld_yaml(const ScenarioSpec& spec, const Eigen::Isometry3d& T_world_scene) {
  const SceneGroundTruth truth = scene_ground_truth(spec.scene);
  std::string y;
  y += "# Weld work pieces of scenario '" + spec.name + "' in the world frame of this run (metres).\n";
  y += "# corners_world: 8 corners x, y, z; corner i sits at plate-local (sx L/2, sy W/2, sz T/2) with\n";
  y += "# sx = bit 2 of i, sy = bit 1, sz = bit 0 (bit set: +). size_m = length, width, thickness.\n";
  y += "frame: world\n";
  y += "scenario: " + text::quoted(spec.name) + "\n";
  y += "plates:";
  y += truth.plates.empty() ? " []\n" : "\n";
  for (const PlateTruth& p : truth.plates) {
    y += "  - name: " + text::quoted(p.name) + "\n";
    y += "    size_m: " + text::list(p.size_m) + "\n";
    y += "    T_world_plate: " + text::matrix16(T_world_scene * p.T_scene_plate) + "\n";
    double c[24];
    for (int i = 0; i < 8; ++i) {
      const Eigen::Vector3d w = T_world_scene * p.corners_scene[i];
      for (int j = 0; j < 3; ++j) c[3 * i + j] = w[j];
    }
    y += "    corners_world: " + text::list(c, 24) + "\n";
  }
  y += "seams:";
  y += truth.seams.empty() ? " []\n" : "\n";
  for (const SeamTruth& s : truth.seams) {
    y += "  - name: " + text::quoted(s.name) + "\n";
    y += std::string("    type: ") + (s.type == WeldJointSpec::Type::kFillet ? "fillet" : "butt") + "\n";
    y += "    start_world: " + text::list(Eigen::Vector3d(T_world_scene * s.start_scene)) + "\n";
    y += "    end_world: " + text::list(Eigen::Vector3d(T_world_scene * s.end_scene)) + "\n";
    y += "    plates: [" + text::quoted(s.plate_a) + ", " + text::quoted(s.plate_b) + "]\n";
  }
  return y;
}

core::Status write_png(const std::string& path, const cv::Mat& img, std::vector<unsigned char>* buf) {
  // Level 1 with Huffman-only coding: the sensor noise leaves little for LZ77 to find, so this is
  // ~40 % faster than the default strategy at the same size. PNG is lossless at every setting.
  static const std::vector<int> kParams = {cv::IMWRITE_PNG_COMPRESSION, 1, cv::IMWRITE_PNG_STRATEGY,
                                           cv::IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY};
  try {
    if (!cv::imencode(".png", img, *buf, kParams)) return core::IoError(path + ": PNG encoding failed");
  } catch (const cv::Exception& e) {
    return core::IoError(path + ": PNG encoding failed: " + e.what());
  }
  return text::write_file_atomic(path, *buf);
}

core::Status make_dir(const std::string& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return core::IoError("cannot create output folder '" + dir + "': " + ec.message());
  if (!fs::is_directory(dir, ec)) return core::IoError("output path '" + dir + "' is not a folder");
  return core::Status::Ok();
}

}  // namespace

void depth_to_u16(const cv::Mat& depth_m, double depth_scale, cv::Mat* depth_u16) {
  depth_u16->create(depth_m.rows, depth_m.cols, CV_16UC1);
  for (int r = 0; r < depth_m.rows; ++r) {
    const float* in = depth_m.ptr<float>(r);
    uint16_t* out = depth_u16->ptr<uint16_t>(r);
    for (int c = 0; c < depth_m.cols; ++c) {
      const double raw = std::round(static_cast<double>(in[c]) * depth_scale);
      out[c] = (raw > 0.0 && raw <= 65535.0) ? static_cast<uint16_t>(raw) : 0;
    }
  }
}

core::Expected<RunSummary> write_run(const ScenarioSpec& spec_in, const RunOptions& options,
                                     const RunProgress& progress) {
  ScenarioSpec spec = spec_in;
  if (options.duration_s > 0.0) spec.duration_s = options.duration_s;
  const std::string who = "scenario '" + spec.name + "': ";
  HWR_RETURN_IF_ERROR(validate_scenario(spec));
  auto traj_or = Trajectory::build(spec.trajectory);
  if (!traj_or.ok()) return core::InvalidArgument(who + traj_or.status().message());
  const Trajectory& traj = traj_or.value();
  const double duration = scenario_run_duration_s(spec, traj);
  if (options.out_dir.empty()) return core::InvalidArgument("no output folder given");
  const std::string& out = options.out_dir;

  // Fail early and clearly when the folder cannot be written.
  HWR_RETURN_IF_ERROR(make_dir(out));
  {
    const std::string probe = out + "/.hwr-sim-write-test";
    const core::Status st = text::write_file_atomic(probe, std::string("ok\n"));
    if (!st.ok()) return core::IoError("cannot write to output folder '" + out + "': " + st.message());
    std::remove(probe.c_str());
  }
  std::unique_ptr<Renderer> renderer;
  if (options.write_images) {
    auto r = Renderer::create(spec.scene);
    if (!r.ok()) return core::InvalidArgument(who + r.status().message());
    renderer = std::move(r.value());
    HWR_RETURN_IF_ERROR(make_dir(out + "/rgb"));
    HWR_RETURN_IF_ERROR(make_dir(out + "/depth"));
    if (spec.camera.stereo) HWR_RETURN_IF_ERROR(make_dir(out + "/right"));
  }

  const int64_t t0 = spec.start_time_ns;
  const Eigen::Isometry3d T_scene_world = world_frame_from_first_imu_pose(traj.evaluate(0.0).T_scene_imu);
  const Eigen::Isometry3d T_world_scene = T_scene_world.inverse();
  const Eigen::Isometry3d T_imu_cam = camera_T_imu_cam(spec.camera);

  RunSummary sum;
  sum.scenario = spec.name;
  sum.out_dir = out;
  sum.simulated_s = duration;
  sum.path_length_m = traj.evaluate(duration).distance_m;
  sum.joints = spec.scene.joints.size();

  // Sensor streams and ground truth.
  const std::vector<ImuRecord> imu = synthesize_imu(traj, spec.imu, spec.seed, duration, t0);
  std::vector<GroundTruthRow> gt(imu.size());
  std::vector<core::StampedPose> gt_cam(imu.size());
  for (size_t k = 0; k < imu.size(); ++k) {
    const TrajectoryState st = traj.evaluate(core::ns_to_s(imu[k].sample.t_ns - t0));
    gt[k].t_ns = imu[k].sample.t_ns;
    gt[k].T_world_imu = T_world_scene * st.T_scene_imu;
    gt[k].v_world_mps = T_world_scene.linear() * st.v_scene_mps;
    gt_cam[k].t_ns = gt[k].t_ns;
    gt_cam[k].T_world_body = gt[k].T_world_imu * T_imu_cam;
  }
  sum.imu_samples = imu.size();
  HWR_RETURN_IF_ERROR(text::write_file_atomic(out + "/imu.csv", imu_csv(imu)));
  HWR_RETURN_IF_ERROR(text::write_file_atomic(out + "/imu_state_groundtruth.csv", state_csv(gt, imu)));
  HWR_RETURN_IF_ERROR(core::write_tum_trajectory(out + "/groundtruth.txt", gt_cam,
                                                 "hwr-sim " + spec.name + ": T_world_cam at the IMU rate"));
  sum.files = {"imu.csv", "imu_state_groundtruth.csv", "groundtruth.txt"};
  if (spec.mag.enabled) {
    const std::vector<MagDipole> dipoles = mag_dipoles_for_scene(spec.scene, spec.mag, spec.seed);
    const std::vector<hal::MagSample> mag = synthesize_mag(traj, spec.mag, dipoles, spec.seed, duration, t0);
    sum.mag_samples = mag.size();
    HWR_RETURN_IF_ERROR(text::write_file_atomic(out + "/mag.csv", mag_csv(mag)));
    sum.files.push_back("mag.csv");
  }
  if (spec.gnss.enabled) {
    const std::vector<GnssRecord> gnss = synthesize_gnss(traj, spec.gnss, spec.seed, duration, t0);
    sum.gnss_samples = gnss.size();
    HWR_RETURN_IF_ERROR(text::write_file_atomic(out + "/gnss.csv", gnss_csv(gnss)));
    sum.files.push_back("gnss.csv");
  }
  HWR_RETURN_IF_ERROR(
      save_sim_calibration(out + "/calibration.yaml", make_sim_calibration(spec, T_scene_world)));
  HWR_RETURN_IF_ERROR(
      text::write_file_atomic(out + "/weld_groundtruth.yaml", weld_yaml(spec, T_world_scene)));
  HWR_RETURN_IF_ERROR(text::write_file_atomic(out + "/scenario_resolved.yaml", scenario_to_yaml(spec)));
  sum.files.insert(sum.files.end(), {"calibration.yaml", "weld_groundtruth.yaml", "scenario_resolved.yaml"});

  if (!options.write_images) {
    if (progress) progress(0, 0);
    return sum;
  }

  // Frames: workers take frame indices in turn; each frame's noise depends only on (seed, k).
  const std::vector<int64_t> offsets = sample_offsets_ns(spec.camera.rate_hz, duration);
  const size_t n_frames = offsets.size();
  std::vector<std::string> stamps(n_frames);
  for (size_t k = 0; k < n_frames; ++k) stamps[k] = core::format_timestamp_s(t0 + offsets[k], 6);
  const Eigen::Isometry3d T_cam_right = camera_T_cam_right(spec.camera);
  std::atomic<size_t> next{0}, done{0};
  std::atomic<bool> failed{false};
  core::Status first_error;
  std::mutex error_mutex;

  auto worker = [&]() {
    cv::Mat bgr, depth, depth16, right_bgr, right_depth, gray;
    std::vector<unsigned char> png;
    for (;;) {
      const size_t k = next.fetch_add(1);
      if (k >= n_frames || failed.load()) return;
      const double t_s = core::ns_to_s(offsets[k]);
      const Eigen::Isometry3d T_scene_cam = traj.evaluate(t_s).T_scene_imu * T_imu_cam;
      renderer->render(T_scene_cam, spec.camera.intrinsics, spec.render, &bgr, &depth);
      apply_depth_noise(spec.depth_noise, derive_seed(spec.seed, RandomStream::kDepthNoise, k), &depth);
      ExposureSpec exposure = spec.exposure;
      exposure.gain = exposure_gain_at(spec, t_s);
      apply_exposure(exposure, derive_seed(spec.seed, RandomStream::kExposure, k), &bgr);
      depth_to_u16(depth, spec.camera.depth_scale, &depth16);
      core::Status st = write_png(out + "/rgb/" + stamps[k] + ".png", bgr, &png);
      if (st.ok()) st = write_png(out + "/depth/" + stamps[k] + ".png", depth16, &png);
      if (st.ok() && spec.camera.stereo) {
        renderer->render(T_scene_cam * T_cam_right, spec.camera.intrinsics, spec.render, &right_bgr,
                         &right_depth);
        apply_exposure(exposure, derive_seed(spec.seed, RandomStream::kExposureRight, k), &right_bgr);
        cv::cvtColor(right_bgr, gray, cv::COLOR_BGR2GRAY);
        st = write_png(out + "/right/" + stamps[k] + ".png", gray, &png);
      }
      if (!st.ok()) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (first_error.ok()) first_error = st;
        failed.store(true);
        return;
      }
      done.fetch_add(1);
    }
  };
  const int n_threads = std::max(1, options.threads);
  std::vector<std::thread> pool;
  pool.reserve(n_threads);
  for (int i = 0; i < n_threads; ++i) pool.emplace_back(worker);
  while (done.load() < n_frames && !failed.load()) {
    if (progress) progress(done.load(), n_frames);
    // Poll at 4 Hz: the callback runs on this (the caller's) thread, never on a worker.
    for (int i = 0; i < 25 && done.load() < n_frames && !failed.load(); ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  for (std::thread& t : pool) t.join();
  if (!first_error.ok()) return first_error;
  if (progress) progress(done.load(), n_frames);

  HWR_RETURN_IF_ERROR(
      text::write_file_atomic(out + "/rgb.txt", image_list("color images", spec.name, "rgb", stamps)));
  HWR_RETURN_IF_ERROR(
      text::write_file_atomic(out + "/depth.txt", image_list("depth maps", spec.name, "depth", stamps)));
  sum.files.insert(sum.files.end(), {"rgb/", "depth/", "rgb.txt", "depth.txt"});
  if (spec.camera.stereo) {
    HWR_RETURN_IF_ERROR(
        text::write_file_atomic(out + "/right.txt", image_list("right images", spec.name, "right", stamps)));
    sum.files.insert(sum.files.end(), {"right/", "right.txt"});
  }
  sum.frames = n_frames;
  return sum;
}

}  // namespace hwr::sim
