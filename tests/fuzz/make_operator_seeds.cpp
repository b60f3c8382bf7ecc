// Writes a seed corpus for fuzz_operator_message into the folder given as the only argument: valid
// LCM-encoded detection_t, operator_command_t (every kind) and command_ack_t messages, each behind
// the selector byte the target reads first (0 detection, 1 command, 2 ack). Valid, so mutation
// starts past the fingerprint and the validation. Generated at test time; seeds are never committed.

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "corpus_dir.hpp"
#include "hwr/mapio/operator_wire.hpp"

namespace {

bool write_seed(const std::string& dir, int index, uint8_t selector, const std::vector<uint8_t>& message) {
  const std::string path = dir + "/operator_" + std::to_string(index) + ".bin";
  FILE* f = std::fopen(path.c_str(), "wb");
  const bool ok = f != nullptr && std::fputc(selector, f) != EOF &&
                  std::fwrite(message.data(), 1, message.size(), f) == message.size();
  if (f != nullptr && std::fclose(f) != 0) return false;
  if (!ok) std::fprintf(stderr, "cannot write %s\n", path.c_str());
  return ok;
}

void set_box(double* center, double* size, double* q, double scale) {
  for (int i = 0; i < 3; ++i) {
    center[i] = scale * (i + 1);
    size[i] = scale * 0.1 * (i + 1);
  }
  q[0] = std::cos(scale);
  q[1] = 0;
  q[2] = std::sin(scale);
  q[3] = 0;
}

}  // namespace

int main(int argc, char** argv) {
  std::string dir;
  if (const int rc = hwr::fuzz::corpus_dir_from_args(argc, argv, &dir); rc != 0) return rc;
  int index = 0;
  std::vector<uint8_t> bytes;
  auto fail = [](const char* what, const hwr::core::Status& st) {
    std::fprintf(stderr, "%s seed: %s\n", what, st.message().c_str());
    return 1;
  };
  for (const int seam_points : {0, 2, 64}) {
    hwr_lcm::detection_t d;  // LCM types leave their scalars uninitialized: set every field
    d.t_ns = 1000 + seam_points;
    d.robot_id = seam_points == 0 ? "r" : "hwr-0";
    d.run_id = 1732477000000000000;
    d.detection_id = seam_points;
    d.segment_id = 3;
    d.keyframe_t_ns = 999;
    d.source = static_cast<int8_t>(seam_points % 3);
    d.state = static_cast<int8_t>((seam_points / 2) % 3);
    d.confidence = 0.5f;
    d.box_px[0] = 10;
    d.box_px[1] = 20;
    d.box_px[2] = 30;
    d.box_px[3] = 40;
    set_box(d.box_center_world_m, d.box_size_m, d.box_q_world_box, 0.3);
    d.num_seam_points = seam_points;
    for (int i = 0; i < seam_points; ++i) d.seam_world_m.push_back({0.01 * i, 1.0, 0.5});
    const hwr::core::Status st = hwr::mapio::encode_detection(d, &bytes);
    if (!st.ok()) return fail("detection", st);
    if (!write_seed(dir, index++, 0, bytes)) return 1;
  }
  for (int kind = 0; kind < 4; ++kind) {
    hwr_lcm::operator_command_t c;
    c.t_ns = 2000 + kind;
    c.robot_id = "hwr-0";
    c.command_id = 1732477001000000000 + kind;
    c.kind = static_cast<int8_t>(kind);
    c.detection_id = kind;
    c.keyframe_t_ns = kind == 3 ? 999 : 0;
    c.box_px[0] = c.box_px[1] = 0;
    c.box_px[2] = c.box_px[3] = kind == 3 ? 16 : 0;
    set_box(c.box_center_world_m, c.box_size_m, c.box_q_world_box, 0.2 * (kind + 1));
    const hwr::core::Status st = hwr::mapio::encode_operator_command(c, &bytes);
    if (!st.ok()) return fail("command", st);
    if (!write_seed(dir, index++, 1, bytes)) return 1;
  }
  for (const bool accepted : {true, false}) {
    hwr_lcm::command_ack_t a;
    a.t_ns = 3000;
    a.robot_id = "hwr-0";
    a.command_id = 1732477001000000002;
    a.accepted = accepted ? 1 : 0;
    a.reason = accepted ? "" : "no detection 2 on this robot";
    a.detection_id = accepted ? 2 : -1;
    const hwr::core::Status st = hwr::mapio::encode_command_ack(a, &bytes);
    if (!st.ok()) return fail("ack", st);
    if (!write_seed(dir, index++, 2, bytes)) return 1;
  }
  std::printf("%d operator seeds in %s\n", index, dir.c_str());
  return 0;
}
