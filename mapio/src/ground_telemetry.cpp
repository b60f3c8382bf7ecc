#include "hwr/mapio/ground_telemetry.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <sstream>

#include "hwr/core/file_io.hpp"
#include "hwr/core/log.hpp"
#include "hwr/mapio/ground_store.hpp"

namespace hwr::mapio {
namespace fs = std::filesystem;

namespace {

constexpr char kTelemetryDir[] = "telemetry";
constexpr char kStatusFile[] = "status.lcm";

core::Status make_dirs(const std::string& path) {
  std::error_code ec;
  fs::create_directories(path, ec);
  if (ec) return core::IoError("cannot create " + path + ": " + ec.message());
  return core::Status::Ok();
}

std::string trajectory_name(int64_t run_id) { return "trajectory_" + std::to_string(run_id) + ".txt"; }

// "kf_<run>_<t_ns>_<W>x<H>.jpg"; false for any other name.
bool parse_keyframe_name(const std::string& name, KeyframeImageInfo* out) {
  long long run = 0, t = 0;
  int w = 0, h = 0, consumed = 0;
  if (std::sscanf(name.c_str(), "kf_%lld_%lld_%dx%d.jpg%n", &run, &t, &w, &h, &consumed) != 4) return false;
  if (static_cast<size_t>(consumed) != name.size() || run < 0 || t < 0 || w < 1 || h < 1) return false;
  out->run_id = run;
  out->keyframe_t_ns = t;
  out->width = w;
  out->height = h;
  return true;
}

bool parse_pose_line(const std::string& line, TrajectoryPose* out) {
  std::istringstream in(line);
  int tracking = 0, localized = 0;
  in >> out->t_ns >> tracking >> localized;
  for (double& v : out->T_world_cam) in >> v;
  if (in.fail() || (tracking != 0 && tracking != 1) || (localized != 0 && localized != 1)) return false;
  std::string rest;
  if (in >> rest) return false;
  for (const double v : out->T_world_cam)
    if (!std::isfinite(v)) return false;
  out->tracking = tracking == 1;
  out->localized = localized == 1;
  return true;
}

}  // namespace

struct GroundTelemetry::Robot {
  RobotTelemetry view;
  std::FILE* trajectory_file = nullptr;  // trajectory_<view.run_id>.txt, appending
  ~Robot() {
    if (trajectory_file != nullptr) std::fclose(trajectory_file);
  }
};

GroundTelemetry::GroundTelemetry(GroundTelemetryConfig config) : config_(std::move(config)) {}
GroundTelemetry::~GroundTelemetry() = default;

core::Expected<std::unique_ptr<GroundTelemetry>> GroundTelemetry::open(const GroundTelemetryConfig& config) {
  if (config.out_dir.empty()) return core::InvalidArgument("ground telemetry: no output folder");
  if (config.max_trajectory_poses < 2)
    return core::InvalidArgument("ground telemetry: max_trajectory_poses < 2");
  HWR_RETURN_IF_ERROR(make_dirs(config.out_dir));
  std::unique_ptr<GroundTelemetry> g(new GroundTelemetry(config));
  HWR_RETURN_IF_ERROR(g->load());
  return g;
}

std::string GroundTelemetry::dir_of(const std::string& robot_id) const {
  return config_.out_dir + "/" + robot_id + "/" + kTelemetryDir;
}

GroundTelemetry::Robot& GroundTelemetry::robot_of(const std::string& robot_id) {
  std::unique_ptr<Robot>& r = robots_[robot_id];
  if (!r) r = std::make_unique<Robot>();
  return *r;
}

core::Status GroundTelemetry::load() {
  std::error_code ec;
  for (const fs::directory_entry& robot_dir : fs::directory_iterator(config_.out_dir, ec)) {
    const std::string robot_id = robot_dir.path().filename().string();
    const std::string dir = robot_dir.path().string() + "/" + kTelemetryDir;
    if (!GroundStore::validate_robot_id(robot_id).ok() || !fs::is_directory(dir)) continue;
    // The latest run: the largest run id among the trajectories, the status and the images.
    int64_t latest = -1;
    std::vector<KeyframeImageInfo> images;
    std::error_code list_ec;
    for (const fs::directory_entry& f : fs::directory_iterator(dir, list_ec)) {
      const std::string name = f.path().filename().string();
      long long run = 0;
      int consumed = 0;
      KeyframeImageInfo kf;
      if (std::sscanf(name.c_str(), "trajectory_%lld.txt%n", &run, &consumed) == 1 &&
          static_cast<size_t>(consumed) == name.size() && run >= 0) {
        latest = std::max<int64_t>(latest, run);
      } else if (parse_keyframe_name(name, &kf)) {
        kf.path = f.path().string();
        images.push_back(kf);
        latest = std::max(latest, kf.run_id);
      }
    }
    if (list_ec) return core::IoError("cannot read " + dir + ": " + list_ec.message());
    Robot& r = robot_of(robot_id);
    std::string bytes;
    const std::string status_path = dir + "/" + kStatusFile;
    if (core::read_file(status_path, &bytes).ok()) {
      const core::Status st =
          decode_status(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), &status_, config_.wire);
      if (st.ok() && status_.robot_id == robot_id) {
        r.view.status = status_;
        latest = std::max(latest, status_.run_id);
      } else {
        notes_.push_back(status_path + ": " + (st.ok() ? "another robot's status" : st.message()) +
                         ", not loaded");
      }
    }
    r.view.run_id = latest;
    if (r.view.status && r.view.status->run_id != latest) r.view.status.reset();
    std::sort(images.begin(), images.end(), [](const KeyframeImageInfo& a, const KeyframeImageInfo& b) {
      return a.keyframe_t_ns < b.keyframe_t_ns;
    });
    for (const KeyframeImageInfo& kf : images)
      if (kf.run_id == latest) r.view.keyframes.push_back(kf);
    if (latest < 0) continue;
    // Lines end with '\n': a last line without one was cut by a crash (even if what is left parses).
    std::string text;
    (void)core::read_file(dir + "/" + trajectory_name(latest), &text);
    int64_t number = 0, damaged = 0;
    size_t at = 0;
    while (at < text.size()) {
      const size_t end = text.find('\n', at);
      ++number;
      TrajectoryPose p;
      if (end == std::string::npos || !parse_pose_line(text.substr(at, end - at), &p)) {
        ++damaged;
      } else {
        add_pose(r, p);
      }
      at = end == std::string::npos ? text.size() : end + 1;
    }
    if (damaged > 0) {
      notes_.push_back(dir + "/" + trajectory_name(latest) + ": " + std::to_string(damaged) + " of " +
                       std::to_string(number) + " lines damaged, skipped");
    }
  }
  if (ec) return core::IoError("cannot read " + config_.out_dir + ": " + ec.message());
  return core::Status::Ok();
}

void GroundTelemetry::reject(const core::Status& why) {
  ++stats_.rejected;
  stats_.last_error = why.message();
  HWR_LOG_WARN("ground", "telemetry message rejected: %s", why.message().c_str());
}

void GroundTelemetry::switch_run(Robot& r, int64_t run_id) {
  if (run_id == r.view.run_id) return;
  r.view.run_id = run_id;
  r.view.trajectory.clear();
  r.view.keyframes.clear();
  r.view.status.reset();
  if (r.trajectory_file != nullptr) std::fclose(r.trajectory_file);
  r.trajectory_file = nullptr;
}

void GroundTelemetry::add_pose(Robot& r, const TrajectoryPose& pose) {
  std::vector<TrajectoryPose>& t = r.view.trajectory;
  if (t.size() >= config_.max_trajectory_poses) {
    // Keep the first pose and every other one back from the newest: the whole path stays drawn, at
    // half the density.
    size_t kept = 1;
    for (size_t i = 2 - (t.size() - 1) % 2; i < t.size(); i += 2) t[kept++] = t[i];
    t.resize(kept);
  }
  t.push_back(pose);
}

void GroundTelemetry::on_pose_message(const uint8_t* data, size_t size) {
  const core::Status st = decode_pose(data, size, &pose_, config_.wire);
  if (!st.ok()) return reject(st);
  Robot& r = robot_of(pose_.robot_id);
  if (pose_.run_id < r.view.run_id) {
    ++stats_.out_of_order;  // a late message of an earlier run
    return;
  }
  switch_run(r, pose_.run_id);
  if (!r.view.trajectory.empty() && pose_.t_ns <= r.view.trajectory.back().t_ns) {
    ++stats_.out_of_order;
    return;
  }
  TrajectoryPose p;
  p.t_ns = pose_.t_ns;
  p.tracking = pose_.tracking == 1;
  p.localized = pose_.localized == 1;
  std::copy(pose_.T_world_cam, pose_.T_world_cam + 12, p.T_world_cam);
  add_pose(r, p);
  ++stats_.poses;
  if (r.trajectory_file == nullptr) {
    const std::string dir = dir_of(pose_.robot_id);
    core::Status made = make_dirs(dir);
    if (made.ok()) {
      const std::string path = dir + "/" + trajectory_name(pose_.run_id);
      r.trajectory_file = std::fopen(path.c_str(), "a+");
      if (r.trajectory_file == nullptr) {
        made = core::IoError("cannot open " + path + ": " + std::strerror(errno));
      } else if (std::fseek(r.trajectory_file, -1, SEEK_END) == 0 && std::fgetc(r.trajectory_file) != '\n') {
        std::fseek(r.trajectory_file, 0, SEEK_END);  // C: a read and a write need a seek between them
        // A line cut by a crash stays one damaged line (a trailing word no pose line has), even where
        // what is left of it would parse.
        std::fputs(" cut\n", r.trajectory_file);
      }
    }
    if (!made.ok()) {
      ++stats_.store_errors;
      stats_.last_error = made.message();
      return;
    }
  }
  char line[512];
  int n =
      std::snprintf(line, sizeof line, "%" PRId64 " %d %d", p.t_ns, p.tracking ? 1 : 0, p.localized ? 1 : 0);
  for (const double v : p.T_world_cam)
    n += std::snprintf(line + n, sizeof line - static_cast<size_t>(n), " %.17g", v);
  line[n++] = '\n';
  if (std::fwrite(line, 1, static_cast<size_t>(n), r.trajectory_file) != static_cast<size_t>(n) ||
      std::fflush(r.trajectory_file) != 0) {
    ++stats_.store_errors;
    stats_.last_error = "writing " + trajectory_name(pose_.run_id) + ": " + std::strerror(errno);
  }
}

void GroundTelemetry::on_status_message(const uint8_t* data, size_t size, int64_t now_ns) {
  const core::Status st = decode_status(data, size, &status_, config_.wire);
  if (!st.ok()) return reject(st);
  Robot& r = robot_of(status_.robot_id);
  if (status_.run_id < r.view.run_id) {
    ++stats_.out_of_order;
    return;
  }
  switch_run(r, status_.run_id);
  r.view.status = status_;
  r.view.status_received_ns = now_ns;
  ++stats_.statuses;
  const std::string dir = dir_of(status_.robot_id);
  core::Status stored = make_dirs(dir);
  if (stored.ok()) stored = encode_status(status_, &encoded_, config_.wire);
  if (stored.ok()) stored = core::write_file_atomic(dir + "/" + kStatusFile, encoded_);
  if (!stored.ok()) {
    ++stats_.store_errors;
    stats_.last_error = stored.message();
  }
}

void GroundTelemetry::on_keyframe_image_message(const uint8_t* data, size_t size) {
  const core::Status st = decode_keyframe_image(data, size, &image_, config_.wire);
  if (!st.ok()) return reject(st);
  Robot& r = robot_of(image_.robot_id);
  if (image_.run_id < r.view.run_id) {
    ++stats_.out_of_order;
    return;
  }
  switch_run(r, image_.run_id);
  ++stats_.keyframe_images;
  KeyframeImageInfo kf;
  kf.run_id = image_.run_id;
  kf.keyframe_t_ns = image_.keyframe_t_ns;
  kf.width = image_.width;
  kf.height = image_.height;
  const std::string dir = dir_of(image_.robot_id);
  kf.path = dir + "/kf_" + std::to_string(kf.run_id) + "_" + std::to_string(kf.keyframe_t_ns) + "_" +
            std::to_string(kf.width) + "x" + std::to_string(kf.height) + ".jpg";
  core::Status stored = make_dirs(dir);
  if (stored.ok()) stored = core::write_file_atomic(kf.path, image_.jpeg);
  if (!stored.ok()) {
    ++stats_.store_errors;
    stats_.last_error = stored.message();
    return;  // the viewer serves images from their files
  }
  std::vector<KeyframeImageInfo>& list = r.view.keyframes;
  auto at = std::find_if(list.begin(), list.end(),
                         [&](const KeyframeImageInfo& k) { return k.keyframe_t_ns >= kf.keyframe_t_ns; });
  if (at != list.end() && at->keyframe_t_ns == kf.keyframe_t_ns) {
    *at = kf;  // sent again (the robot repeats images): replaced
  } else {
    list.insert(at, kf);
  }
}

std::vector<std::string> GroundTelemetry::robots() const {
  std::vector<std::string> out;
  for (const auto& [id, r] : robots_) out.push_back(id);
  return out;
}

const RobotTelemetry* GroundTelemetry::robot(const std::string& robot_id) const {
  auto it = robots_.find(robot_id);
  return it == robots_.end() ? nullptr : &it->second->view;
}

}  // namespace hwr::mapio
