// Writes a seed corpus for fuzz_telemetry_message into the folder given as the only argument: valid
// LCM-encoded pose_t, status_t and keyframe_image_t messages (a real JPEG from OpenCV among them),
// each behind the selector byte the target reads first (0 pose, 1 status, 2 keyframe image).
// Generated at test time; seeds are never committed.

#include <cstdio>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "corpus_dir.hpp"
#include "hwr/mapio/telemetry_wire.hpp"

namespace {

bool write_seed(const std::string& dir, int index, uint8_t selector, const std::vector<uint8_t>& message) {
  const std::string path = dir + "/telemetry_" + std::to_string(index) + ".bin";
  FILE* f = std::fopen(path.c_str(), "wb");
  const bool ok = f != nullptr && std::fputc(selector, f) != EOF &&
                  std::fwrite(message.data(), 1, message.size(), f) == message.size();
  if (f != nullptr && std::fclose(f) != 0) return false;
  if (!ok) std::fprintf(stderr, "cannot write %s\n", path.c_str());
  return ok;
}

}  // namespace

int main(int argc, char** argv) {
  std::string dir;
  if (const int rc = hwr::fuzz::corpus_dir_from_args(argc, argv, &dir); rc != 0) return rc;
  std::vector<uint8_t> bytes;
  auto fail = [](const char* what, const hwr::core::Status& st) {
    std::fprintf(stderr, "%s seed: %s\n", what, st.message().c_str());
    return 1;
  };
  int index = 0;
  hwr_lcm::pose_t p;  // LCM types leave their scalars uninitialized: set every field
  p.t_ns = 1'700'000'000'000'000'000;
  p.robot_id = "hwr-0";
  p.run_id = 1'732'477'000'000'000'000;
  const double T[12] = {0, -1, 0, 1.5, 1, 0, 0, -2.25, 0, 0, 1, 0.75};
  std::copy(T, T + 12, p.T_world_cam);
  p.tracking = 1;
  p.localized = 0;
  if (const auto st = hwr::mapio::encode_pose(p, &bytes); !st.ok()) return fail("pose", st);
  if (!write_seed(dir, index++, 0, bytes)) return 1;

  for (const int tasks : {0, 5}) {
    hwr_lcm::status_t s;
    s.t_ns = 5;
    s.robot_id = "hwr-0";
    s.run_id = 7;
    s.num_tasks = tasks;
    for (int i = 0; i < tasks; ++i) {
      s.task_name.push_back("task" + std::to_string(i));
      s.task_runs.push_back(100 * i);
      s.task_overruns.push_back(i);
      s.task_slips.push_back(0);
    }
    s.num_counters = 2;
    s.counter_name = {"link.resends", "camera.gaps"};
    s.counter_value = {3, -1};
    if (const auto st = hwr::mapio::encode_status(s, &bytes); !st.ok()) return fail("status", st);
    if (!write_seed(dir, index++, 1, bytes)) return 1;
  }

  hwr_lcm::keyframe_image_t m;
  m.t_ns = 9;
  m.robot_id = "hwr-0";
  m.run_id = 7;
  m.keyframe_t_ns = 1'700'000'000'100'000'000;
  m.width = 32;
  m.height = 24;
  m.jpeg_width = 32;
  m.jpeg_height = 24;
  const cv::Mat image(24, 32, CV_8UC3, cv::Scalar(10, 200, 90));
  std::vector<uint8_t> jpeg;
  if (!cv::imencode(".jpg", image, jpeg)) return 1;
  m.jpeg = jpeg;
  m.size = static_cast<int32_t>(jpeg.size());
  if (const auto st = hwr::mapio::encode_keyframe_image(m, &bytes); !st.ok())
    return fail("keyframe image", st);
  if (!write_seed(dir, index++, 2, bytes)) return 1;
  std::printf("%d seeds in %s\n", index, dir.c_str());
  return 0;
}
