// Writes a seed corpus for fuzz_chunk_decoder into the folder given as the only argument: chunks of a
// few sizes in both Draco methods, with and without ids and normals, so the fuzzer starts from valid
// bitstreams of every shape the codec writes. Generated at test time; seeds are never committed.

#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "corpus_dir.hpp"
#include "hwr/mapio/chunk_codec.hpp"

int main(int argc, char** argv) {
  std::string dir;
  if (const int rc = hwr::fuzz::corpus_dir_from_args(argc, argv, &dir); rc != 0) return rc;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-2.f, 2.f);
  int written = 0;
  for (int n : {1, 5, 40, 300}) {
    std::vector<hwr::mapio::ChunkPoint> points(static_cast<size_t>(n));
    std::vector<uint32_t> ids(static_cast<size_t>(n));
    std::vector<float> normals(3 * static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) {
      auto& p = points[static_cast<size_t>(i)];
      p = {u(rng),
           u(rng),
           u(rng),
           static_cast<uint8_t>(i),
           static_cast<uint8_t>(3 * i),
           static_cast<uint8_t>(7 * i),
           static_cast<uint8_t>(i % 2)};
      ids[static_cast<size_t>(i)] = 1000u + static_cast<uint32_t>(i) * 977u;
      const float len = std::sqrt(p.x_m * p.x_m + p.y_m * p.y_m + p.z_m * p.z_m) + 1e-3f;
      normals[3 * static_cast<size_t>(i)] = p.x_m / len;
      normals[3 * static_cast<size_t>(i) + 1] = p.y_m / len;
      normals[3 * static_cast<size_t>(i) + 2] = p.z_m / len;
    }
    for (int variant = 0; variant < 16; ++variant) {
      hwr::mapio::ChunkCodecConfig cfg;
      cfg.preserve_order = (variant & 1) != 0;
      cfg.with_point_ids = (variant & 2) != 0;
      const bool with_normals = (variant & 4) != 0;
      cfg.color_bits = (variant & 8) != 0 ? 5 : 8;  // kd-tree + 5 bits: the split layout
      cfg.speed = variant % 3 == 0 ? 10 : 5;
      std::vector<uint8_t> bytes;
      auto info = hwr::mapio::encode_chunk(points.data(), n, cfg.with_point_ids ? ids.data() : nullptr,
                                           with_normals ? normals.data() : nullptr, cfg, &bytes);
      if (!info.ok()) {
        std::fprintf(stderr, "encode failed: %s\n", info.status().to_string().c_str());
        return 1;
      }
      const std::string path = dir + "/seed_n" + std::to_string(n) + "_v" + std::to_string(variant) + ".drc";
      std::FILE* f = std::fopen(path.c_str(), "wb");
      if (f == nullptr || std::fwrite(bytes.data(), 1, bytes.size(), f) != bytes.size() ||
          std::fclose(f) != 0) {
        std::fprintf(stderr, "cannot write %s\n", path.c_str());
        return 1;
      }
      ++written;
    }
  }
  std::printf("wrote %d seed chunks to %s\n", written, dir.c_str());
  return 0;
}
