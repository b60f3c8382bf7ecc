#include "transfer_bench_stream.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <utility>

#include "bench_sequences.hpp"
#include "hwr/core/log.hpp"
#include "hwr/estimation/estimator_config.hpp"
#include "hwr/estimation/offline_run.hpp"
#include "hwr/recon/local_mapper.hpp"
#include "hwr/recon/local_mapper_config.hpp"

namespace hwr::bench {
namespace {

// The frames skipped once enough points were streamed fail with this message; the log filter below
// keeps run_offline's per-frame warning about them off stderr.
constexpr const char* kEnoughPoints = "transfer bench: enough points streamed";

void drop_enough_points_warnings(core::LogLevel level, const char* module, const char* message, void*) {
  if (std::strstr(message, kEnoughPoints) != nullptr) return;
  std::fprintf(stderr, "[%s] %s: %s\n", core::to_string(level), module, message);
}

class CaptureSink final : public recon::MapStreamSink {
 public:
  CaptureSink(PointStream* out, size_t max_points) : out_(out), max_points_(max_points) {}
  int64_t now_ns = 0;  // simulated time of the frame being mapped

  bool enough() const { return max_points_ > 0 && out_->size() >= max_points_; }

  void stream(uint32_t segment_id, const Eigen::Isometry3d& T_world_segment,
              const recon::CloudPoint* points_segment, const uint32_t* /*voxel_ids*/, int n,
              bool segment_complete) override {
    if (enough()) return;
    StreamBatch b;
    b.segment_id = static_cast<int32_t>(segment_id);
    b.T_world_segment = T_world_segment;
    b.t_ns = now_ns;
    b.segment_complete = segment_complete;
    b.first = out_->size();
    b.n = n;
    for (int i = 0; i < n; ++i) {
      const recon::CloudPoint& p = points_segment[i];
      out_->points_segment.push_back({p.x_m, p.y_m, p.z_m, p.r, p.g, p.b, p.flags});
    }
    out_->batches.push_back(b);
    out_->duration_ns = std::max(out_->duration_ns, now_ns);
  }

 private:
  PointStream* out_;
  size_t max_points_;
};

}  // namespace

core::Expected<PointStream> capture_point_stream(const std::string& name, size_t max_points) {
  auto seq = open_sequence(name, 0.0);
  if (!seq.ok()) return seq.status();
  if (seq->log.frame_t_ns.empty()) return core::InvalidArgument("sequence " + name + " has no frames");
  estimation::PoseEstimatorConfig est_cfg;
  recon::LocalMapperConfig map_cfg;
  auto mapper =
      recon::LocalMapper::create(map_cfg, seq->log.info.intrinsics, est_cfg.tracker.orb.max_features);
  if (!mapper.ok()) return mapper.status();

  PointStream out;
  out.name = name;
  if (max_points > 0) out.points_segment.reserve(max_points + (size_t{1} << 16));
  CaptureSink sink(&out, max_points);
  mapper->set_stream_sink(&sink);
  const int64_t t0_ns = seq->log.frame_t_ns.front();
  const int64_t t_last_ns = seq->log.frame_t_ns.back();

  // Once enough points are streamed the remaining frames are not rendered (their load fails fast).
  auto load = seq->log.load_frame;
  seq->log.load_frame = [&sink, load](size_t i, hal::RgbdFrame* f) -> core::Status {
    if (sink.enough()) return core::Unavailable(kEnoughPoints);
    return load(i, f);
  };
  core::set_log_sink(drop_enough_points_warnings);

  estimation::OfflineRunOptions opt;
  opt.estimator = est_cfg;
  int64_t last_mapped_ns = 0;
  opt.after_frame = [&](size_t i, const estimation::PoseEstimator& e) {
    sink.now_ns = seq->log.frame_t_ns[i] - t0_ns;
    last_mapped_ns = sink.now_ns;
    ++out.frames;
    mapper->update(e.tracker().keyframes(), nullptr);
  };
  opt.at_end = [&](const estimation::PoseEstimator& e) {
    sink.now_ns = last_mapped_ns;  // the end-of-run flush belongs to the last frame mapped
    mapper->finish(e.tracker().keyframes(), nullptr);
  };
  const auto wall0 = std::chrono::steady_clock::now();
  auto run = estimation::run_offline(seq->log, opt);
  out.pipeline_wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  core::set_log_sink(nullptr);
  if (!run.ok()) return run.status();
  out.cut_short = sink.enough() && last_mapped_ns < t_last_ns - t0_ns;
  if (out.size() > max_points && max_points > 0) {
    // Keep exactly max_points: the batch holding the last one is cut.
    while (!out.batches.empty() && out.batches.back().first >= max_points) out.batches.pop_back();
    if (!out.batches.empty()) {
      StreamBatch& b = out.batches.back();
      b.n = static_cast<int>(std::min<size_t>(static_cast<size_t>(b.n), max_points - b.first));
    }
    out.points_segment.resize(max_points);
  }
  if (out.size() == 0) return core::NotFound("sequence " + name + ": the local mapper streamed no points");
  return out;
}

PointStream first_points(const std::vector<PointStream>& streams, size_t n) {
  PointStream out;
  out.points_segment.reserve(n);
  size_t total = 0;
  for (const PointStream& s : streams) total += s.size();
  if (total == 0 || n == 0) return out;
  int32_t segment_offset = 0;
  int64_t time_offset_ns = 0;
  while (out.size() < n) {
    for (const PointStream& s : streams) {
      int32_t max_segment = -1;
      for (const StreamBatch& b : s.batches) {
        if (out.size() >= n) break;
        StreamBatch c = b;
        c.segment_id = b.segment_id + segment_offset;
        c.t_ns = b.t_ns + time_offset_ns;
        c.first = out.size();
        c.n = static_cast<int>(std::min<size_t>(static_cast<size_t>(b.n), n - out.size()));
        // A cut batch, or the end of a stream cut short, closes its segment.
        if (c.n < b.n || &b == &s.batches.back()) c.segment_complete = true;
        out.points_segment.insert(out.points_segment.end(),
                                  s.points_segment.begin() + static_cast<ptrdiff_t>(b.first),
                                  s.points_segment.begin() + static_cast<ptrdiff_t>(b.first) + c.n);
        out.batches.push_back(c);
        out.duration_ns = c.t_ns;
        max_segment = std::max(max_segment, b.segment_id);
      }
      if (out.size() >= n) break;
      segment_offset += max_segment + 1;
      // The next stream (or the next loop) starts one frame period after this one ended.
      time_offset_ns += s.duration_ns + 100'000'000;
    }
  }
  // The robot stops: the segment of the last point closes.
  out.batches.back().segment_complete = true;
  return out;
}

namespace {

constexpr char kCacheMagic[8] = {'H', 'W', 'R', 'T', 'S', 'C', '0', '1'};

template <class T>
void put(std::ofstream& f, const T& v) {
  f.write(reinterpret_cast<const char*>(&v), sizeof(T));
}
template <class T>
bool get(std::ifstream& f, T* v) {
  return static_cast<bool>(f.read(reinterpret_cast<char*>(v), sizeof(T)));
}

}  // namespace

core::Status save_point_streams(const std::string& path, const std::string& key,
                                const std::vector<PointStream>& s) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    if (!f) return core::IoError("stream cache: cannot write " + tmp);
    f.write(kCacheMagic, sizeof(kCacheMagic));
    put(f, static_cast<uint64_t>(key.size()));
    f.write(key.data(), static_cast<std::streamsize>(key.size()));
    put(f, static_cast<uint64_t>(s.size()));
    for (const PointStream& p : s) {
      put(f, static_cast<uint64_t>(p.name.size()));
      f.write(p.name.data(), static_cast<std::streamsize>(p.name.size()));
      put(f, p.duration_ns);
      put(f, static_cast<uint64_t>(p.frames));
      put(f, p.pipeline_wall_s);
      put(f, static_cast<uint8_t>(p.cut_short));
      put(f, static_cast<uint64_t>(p.batches.size()));
      for (const StreamBatch& b : p.batches) {
        put(f, b.segment_id);
        f.write(reinterpret_cast<const char*>(b.T_world_segment.matrix().data()), 16 * sizeof(double));
        put(f, b.t_ns);
        put(f, static_cast<uint8_t>(b.segment_complete));
        put(f, static_cast<uint64_t>(b.first));
        put(f, b.n);
      }
      put(f, static_cast<uint64_t>(p.points_segment.size()));
      f.write(reinterpret_cast<const char*>(p.points_segment.data()),
              static_cast<std::streamsize>(p.points_segment.size() * sizeof(mapio::ChunkPoint)));
    }
    if (!f.flush()) return core::IoError("stream cache: cannot write " + tmp);
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0)
    return core::IoError("stream cache: cannot rename to " + path);
  return core::Status();
}

core::Expected<std::vector<PointStream>> load_point_streams(const std::string& path, const std::string& key) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return core::NotFound("stream cache: no file " + path);
  char magic[sizeof(kCacheMagic)];
  uint64_t key_size = 0;
  if (!f.read(magic, sizeof(magic)) || std::memcmp(magic, kCacheMagic, sizeof(magic)) != 0 ||
      !get(f, &key_size) || key_size > 4096)
    return core::CorruptData("stream cache: " + path + " is not a stream cache");
  std::string k(key_size, '\0');
  if (!f.read(k.data(), static_cast<std::streamsize>(key_size)))
    return core::CorruptData("stream cache: " + path + " is truncated");
  if (k != key) return core::NotFound("stream cache: " + path + " was made for " + k);
  const auto corrupt = [&] {
    return core::CorruptData("stream cache: " + path + " is truncated or damaged");
  };
  uint64_t count = 0;
  if (!get(f, &count) || count > 64) return corrupt();
  std::vector<PointStream> out(count);
  for (PointStream& p : out) {
    uint64_t frames = 0, nb = 0, np = 0;
    uint8_t cut = 0;
    uint64_t name_size = 0;
    if (!get(f, &name_size) || name_size > 4096) return corrupt();
    p.name.resize(name_size);
    if (!f.read(p.name.data(), static_cast<std::streamsize>(name_size))) return corrupt();
    if (!get(f, &p.duration_ns) || !get(f, &frames) || !get(f, &p.pipeline_wall_s) || !get(f, &cut) ||
        !get(f, &nb) || nb > (uint64_t{1} << 24))
      return corrupt();
    p.frames = frames;
    p.cut_short = cut != 0;
    p.batches.resize(nb);
    for (StreamBatch& b : p.batches) {
      uint8_t complete = 0;
      uint64_t first = 0;
      if (!get(f, &b.segment_id) ||
          !f.read(reinterpret_cast<char*>(b.T_world_segment.matrix().data()), 16 * sizeof(double)) ||
          !get(f, &b.t_ns) || !get(f, &complete) || !get(f, &first) || !get(f, &b.n) || b.n < 0)
        return corrupt();
      b.segment_complete = complete != 0;
      b.first = first;
    }
    if (!get(f, &np) || np > (uint64_t{1} << 32)) return corrupt();
    for (const StreamBatch& b : p.batches)
      if (b.first + static_cast<uint64_t>(b.n) > np) return corrupt();
    p.points_segment.resize(np);
    if (!f.read(reinterpret_cast<char*>(p.points_segment.data()),
                static_cast<std::streamsize>(np * sizeof(mapio::ChunkPoint))))
      return corrupt();
  }
  return out;
}

}  // namespace hwr::bench
