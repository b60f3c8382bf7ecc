// Writes a seed corpus for fuzz_ack_message into the folder given as the only argument: sealed,
// LCM-encoded chunk_ack_t messages (chunk_wire.hpp) for the robot and run ids the fuzz target's
// sender accepts from any ack (it is built from the ack's own ids), with cumulative and selective
// values inside and around its window, resume reports, and a long selective list. Sealed, so the
// fuzzer starts past the CRC check and reaches ChunkSender::on_ack with acks it accepts.
// Generated at test time; seeds are never committed.

#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "corpus_dir.hpp"
#include "hwr/mapio/chunk_wire.hpp"

int main(int argc, char** argv) {
  std::string dir;
  if (const int rc = hwr::fuzz::corpus_dir_from_args(argc, argv, &dir); rc != 0) return rc;
  struct Seed {
    int64_t cumulative;
    std::vector<int64_t> selective;
    bool resume;
  };
  std::vector<int64_t> many;
  for (int64_t s = 10; s < 10 + 200; s += 2) many.push_back(s);
  // The target's sender has link_seqs 0..7 in flight.
  const std::vector<Seed> seeds = {
      {-1, {}, false},       {-1, {}, true}, {0, {}, false},  {3, {5, 7}, false}, {7, {}, false},
      {-1, {1, 2, 6}, true}, {2, {4}, true}, {8, {9}, false}, {6, {}, true},      {1, many, false},
  };
  int written = 0;
  int index = 0;
  for (const char* robot : {"hwr-0", "r"}) {
    for (const Seed& s : seeds) {
      hwr_lcm::chunk_ack_t ack;
      ack.t_ns = 1000 + index;
      ack.robot_id = robot;
      ack.run_id = index % 2 == 0 ? 1732477000000000000 : 0;
      ack.cumulative_seq = s.cumulative;
      ack.selective = s.selective;
      ack.resume_report = s.resume ? 1 : 0;
      hwr::mapio::seal_ack(&ack);
      if (!hwr::mapio::verify_ack(ack, hwr::mapio::ChunkWireLimits{}).ok()) {
        std::fprintf(stderr, "seed %d does not verify\n", index);
        return 1;
      }
      std::vector<uint8_t> bytes;
      const hwr::core::Status st = hwr::mapio::encode_ack_message(ack, &bytes);
      if (!st.ok()) {
        std::fprintf(stderr, "seed %d: %s\n", index, st.message().c_str());
        return 1;
      }
      const std::string path = dir + "/ack_" + std::to_string(index) + ".lcm";
      FILE* f = std::fopen(path.c_str(), "wb");
      if (f == nullptr || std::fwrite(bytes.data(), 1, bytes.size(), f) != bytes.size() ||
          std::fclose(f) != 0) {
        std::fprintf(stderr, "cannot write %s\n", path.c_str());
        return 1;
      }
      ++written;
      ++index;
    }
  }
  std::printf("%d ack seeds in %s\n", written, dir.c_str());
  return 0;
}
