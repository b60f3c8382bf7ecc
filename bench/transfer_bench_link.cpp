#include "transfer_bench_link.hpp"

#include "hwr/mapio/spatial_order.hpp"

#include <stdlib.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <thread>
#include <unordered_map>
#include <utility>
#include <vector>

#include "hwr/mapio/ground_station.hpp"
#include "hwr/mapio/ground_store.hpp"
#include "hwr/mapio/lcm_link.hpp"

namespace hwr::bench {
namespace {

constexpr const char* kRobotId = "bench";

int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// A segment's decoded points against its submitted ones. The kd-tree coder reorders points within a
// chunk and the streamer reorders a batch before cutting it, so points are paired by position:
// decoded point k may pair with submitted point i of the same flags and the same colour as the codec
// keeps it (reduce_color_channel at color_bits) when every axis is within bound_m (the codec's
// guarantee). A maximum bipartite matching over those pairs (Kuhn's augmenting paths; almost every
// point has a single candidate) pairs each decoded point with a distinct submitted one whenever the
// bound held; a greedy nearest-point pairing could take another point's partner where two points
// of one colour lie within 2 mm and report a false excess. A decoded point left unpaired is then
// paired with its nearest unused candidate at any distance (its error, over the bound, is reported),
// or counted unmatched.
class SegmentMatcher {
 public:
  // Points are searched within twice the bound (at least 2 mm), on a grid of cells of twice that.
  SegmentMatcher(int color_bits, double bound_m)
      : color_bits_(color_bits),
        bound_m_(bound_m),
        radius_m_(std::max(0.002, 2.0 * bound_m)),
        cell_m_(2.0 * radius_m_) {}

  void match(const std::vector<mapio::ChunkPoint>& ref, const std::vector<mapio::ChunkPoint>& dec,
             TransferResult* r) {
    head_.clear();
    head_.reserve(ref.size());
    next_.assign(ref.size(), -1);
    for (size_t i = 0; i < ref.size(); ++i) {
      auto [it, fresh] =
          head_.try_emplace(key(cell(ref[i].x_m), cell(ref[i].y_m), cell(ref[i].z_m)), static_cast<int>(i));
      if (!fresh) {
        next_[i] = it->second;
        it->second = static_cast<int>(i);
      }
    }
    // Candidate pairs within the bound, as adjacency lists (CSR).
    adj_start_.assign(dec.size() + 1, 0);
    adj_.clear();
    for (size_t k = 0; k < dec.size(); ++k) {
      for_near(dec[k], [&](int i) {
        if (same_attributes(ref[static_cast<size_t>(i)], dec[k]) &&
            linf(ref[static_cast<size_t>(i)], dec[k]) <= bound_m_)
          adj_.push_back(i);
      });
      adj_start_[k + 1] = static_cast<int>(adj_.size());
    }
    partner_of_ref_.assign(ref.size(), -1);
    partner_of_dec_.assign(dec.size(), -1);
    visit_stamp_.assign(ref.size(), 0);
    int stamp = 0;
    for (size_t k = 0; k < dec.size(); ++k) {
      ++stamp;
      augment(static_cast<int>(k), stamp);
    }
    int fallbacks = 0;
    for (size_t k = 0; k < dec.size(); ++k) {
      ++r->points_checked;
      int i = partner_of_dec_[k];
      if (i < 0) {
        // Over the bound (or no candidate near): the nearest unused candidate at any distance.
        double best_d2 = INFINITY;
        auto consider = [&](int c) {
          if (partner_of_ref_[static_cast<size_t>(c)] >= 0 ||
              !same_attributes(ref[static_cast<size_t>(c)], dec[k]))
            return;
          const double d2 = dist2(ref[static_cast<size_t>(c)], dec[k]);
          if (d2 < best_d2) {
            best_d2 = d2;
            i = c;
          }
        };
        for_near(dec[k], consider);
        if (i < 0 && fallbacks < kMaxFallbacks) {
          ++fallbacks;
          for (size_t c = 0; c < ref.size(); ++c) consider(static_cast<int>(c));
        }
        if (i < 0) {
          ++r->unmatched;
          continue;
        }
        partner_of_ref_[static_cast<size_t>(i)] = static_cast<int>(k);
      }
      const mapio::ChunkPoint& p = ref[static_cast<size_t>(i)];
      const mapio::ChunkPoint& d = dec[k];
      r->max_axis_error_mm = std::max(r->max_axis_error_mm, linf(p, d) * 1e3);
      r->max_error_mm = std::max(r->max_error_mm, std::sqrt(dist2(p, d)) * 1e3);
      r->max_color_error =
          std::max({r->max_color_error, std::abs(p.r - d.r), std::abs(p.g - d.g), std::abs(p.b - d.b)});
    }
  }

 private:
  struct StackFrame {
    int k;
    int edge;  // next adjacency entry to try
  };
  // Kuhn's augmenting path from decoded point k (iterative depth-first search over alternating paths).
  bool augment(int k0, int stamp) {
    stack_.clear();
    stack_.push_back({k0, adj_start_[static_cast<size_t>(k0)]});
    while (!stack_.empty()) {
      StackFrame& f = stack_.back();
      if (f.edge == adj_start_[static_cast<size_t>(f.k) + 1]) {
        stack_.pop_back();
        continue;
      }
      const int i = adj_[static_cast<size_t>(f.edge++)];
      if (visit_stamp_[static_cast<size_t>(i)] == stamp) continue;
      visit_stamp_[static_cast<size_t>(i)] = stamp;
      const int owner = partner_of_ref_[static_cast<size_t>(i)];
      if (owner < 0) {
        // Free: flip the path. Each frame's last tried edge (edge - 1) is its new partner.
        for (auto it = stack_.rbegin(); it != stack_.rend(); ++it) {
          const int ri = adj_[static_cast<size_t>(it->edge - 1)];
          partner_of_ref_[static_cast<size_t>(ri)] = it->k;
          partner_of_dec_[static_cast<size_t>(it->k)] = ri;
        }
        return true;
      }
      stack_.push_back({owner, adj_start_[static_cast<size_t>(owner)]});
    }
    return false;
  }

  template <class F>
  void for_near(const mapio::ChunkPoint& d, F&& f) const {
    const double r = radius_m_;
    for (int64_t cx = cell(d.x_m - r); cx <= cell(d.x_m + r); ++cx)
      for (int64_t cy = cell(d.y_m - r); cy <= cell(d.y_m + r); ++cy)
        for (int64_t cz = cell(d.z_m - r); cz <= cell(d.z_m + r); ++cz) {
          auto it = head_.find(key(cx, cy, cz));
          if (it == head_.end()) continue;
          for (int i = it->second; i >= 0; i = next_[static_cast<size_t>(i)]) f(i);
        }
  }
  bool same_attributes(const mapio::ChunkPoint& p, const mapio::ChunkPoint& d) const {
    return reduced(p.r) == d.r && reduced(p.g) == d.g && reduced(p.b) == d.b && p.flags == d.flags;
  }
  static double linf(const mapio::ChunkPoint& p, const mapio::ChunkPoint& d) {
    return std::max({std::abs(static_cast<double>(p.x_m) - d.x_m),
                     std::abs(static_cast<double>(p.y_m) - d.y_m),
                     std::abs(static_cast<double>(p.z_m) - d.z_m)});
  }
  static double dist2(const mapio::ChunkPoint& p, const mapio::ChunkPoint& d) {
    const double dx = static_cast<double>(p.x_m) - d.x_m, dy = static_cast<double>(p.y_m) - d.y_m,
                 dz = static_cast<double>(p.z_m) - d.z_m;
    return dx * dx + dy * dy + dz * dz;
  }
  uint8_t reduced(uint8_t v) const { return mapio::reduce_color_channel(v, color_bits_); }

  static constexpr int kMaxFallbacks = 64;
  int64_t cell(double v) const { return static_cast<int64_t>(std::floor(v / cell_m_)); }
  static int64_t key(int64_t x, int64_t y, int64_t z) {
    constexpr int64_t kMask = (int64_t{1} << 21) - 1;
    return ((x & kMask) << 42) | ((y & kMask) << 21) | (z & kMask);
  }
  int color_bits_;
  double bound_m_;
  double radius_m_, cell_m_;
  std::unordered_map<int64_t, int> head_;
  std::vector<int> next_;
  std::vector<int> adj_start_, adj_;
  std::vector<int> partner_of_ref_, partner_of_dec_, visit_stamp_;
  std::vector<StackFrame> stack_;
};

// Reads the run back from the ground store (CRC-checked), decodes every chunk and compares each
// segment's decoded points with the points submitted for it (the streamer reorders a batch before
// cutting it into chunks, so chunks are matched as a whole segment).
core::Status verify_store(const std::string& dir, int64_t run_id, const PointStream& map, int color_bits,
                          double bound_m, TransferResult* r) {
  std::map<int32_t, std::vector<std::pair<size_t, int>>> ranges;  // segment -> (first, n) in submit order
  for (const StreamBatch& b : map.batches)
    if (b.n > 0) ranges[b.segment_id].emplace_back(b.first, b.n);
  auto store = mapio::GroundStore::open(dir);
  if (!store.ok()) return store.status();
  std::vector<hwr_lcm::map_chunk_t> chunks;
  mapio::DecodedChunk decoded;
  std::vector<mapio::ChunkPoint> ref, got;
  SegmentMatcher matcher(color_bits, bound_m);
  for (const auto& seg : store->segments(kRobotId, run_id)) {
    HWR_RETURN_IF_ERROR(store->load_segment(kRobotId, run_id, seg.segment_id, seg.version, &chunks));
    ref.clear();
    for (const auto& [first, n] : ranges[seg.segment_id])
      ref.insert(ref.end(), map.points_segment.begin() + static_cast<ptrdiff_t>(first),
                 map.points_segment.begin() + static_cast<ptrdiff_t>(first) + n);
    got.clear();
    for (const hwr_lcm::map_chunk_t& c : chunks) {
      if (c.num_points == 0) continue;
      HWR_RETURN_IF_ERROR(mapio::decode_chunk(c.payload.data(), c.payload.size(), c.num_points,
                                              mapio::ChunkDecodeLimits{}, &decoded));
      got.insert(got.end(), decoded.points.begin(), decoded.points.end());
    }
    if (got.size() != ref.size()) {
      return core::CorruptData("segment " + std::to_string(seg.segment_id) + " holds " +
                               std::to_string(got.size()) + " points, " + std::to_string(ref.size()) +
                               " were submitted");
    }
    matcher.match(ref, got, r);
  }
  if (r->points_checked != static_cast<int64_t>(map.size())) {
    return core::CorruptData("the ground store holds " + std::to_string(r->points_checked) + " points, " +
                             std::to_string(map.size()) + " were submitted");
  }
  r->verified = true;
  return core::Status();
}

std::string make_temp_dir(const std::string& root) {
  std::string t = root + "/hwr-transfer-XXXXXX";
  if (mkdtemp(t.data()) == nullptr) return {};
  return t;
}

}  // namespace

TransferResult run_transfer(const PointStream& map, TransferMode mode, int64_t run_id,
                            const TransferSetup& setup) {
  TransferResult r;
  if (map.batches.empty()) {
    r.error = "empty map";
    return r;
  }
  const std::string dir = make_temp_dir(setup.tmp_root);
  if (dir.empty()) {
    r.error = "cannot create a temporary folder under " + setup.tmp_root;
    return r;
  }
  mapio::GroundStationConfig gcfg;
  gcfg.out_dir = dir;
  auto station = mapio::GroundStation::open(gcfg);
  auto glink = mapio::LcmLink::open(setup.url);
  if (!station.ok() || !glink.ok()) {
    r.error = "ground station: " + (station.ok() ? glink.status().message() : station.status().message());
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
    return r;
  }

  // The ground: hwr-ground's loop (apps/hwr-ground/main.cpp) on its own thread.
  const int64_t target_points = static_cast<int64_t>(map.size());
  std::atomic<int64_t> done_ns{0};
  std::atomic<bool> stop{false}, ground_failed{false};
  mapio::GroundStation& g = *station.value();
  mapio::LcmLink& gl = glink.value();
  gl.subscribe(mapio::kChannelMapChunk, [&](const uint8_t* d, size_t n) {
    g.on_chunk_message(d, n, steady_ns());
    if (done_ns.load(std::memory_order_relaxed) == 0 && g.stats().points_stored >= target_points)
      done_ns.store(steady_ns());
  });
  const bool write_maps = setup.write_ground_maps;
  std::thread ground([&] {
    int64_t last_maps = steady_ns();
    while (!stop.load()) {
      auto h = gl.handle(5);
      if (!h.ok()) {
        ground_failed.store(true);
        return;
      }
      const int64_t t = steady_ns();
      g.service(t, [&](const hwr_lcm::chunk_ack_t& ack) { (void)gl.publish(mapio::kChannelMapAck, ack); });
      if (write_maps && t - last_maps > 1'000'000'000) {
        (void)g.write_maps(false);
        last_maps = t;
      }
    }
  });

  auto streamer = mapio::MapStreamer::start(setup.url, kRobotId, run_id, setup.streamer);
  int64_t t_stop = 0;
  if (!streamer.ok()) {
    r.error = "map streamer: " + streamer.status().message();
  } else {
    mapio::MapStreamer& s = *streamer.value();
    const int64_t bytes0 = (setup.link_byte_counter ? setup.link_byte_counter() : -1);
    auto submit = [&](const StreamBatch& b, double wait_s) {
      return s.submit(b.segment_id, 0, b.T_world_segment, map.points_segment.data() + b.first, nullptr, b.n,
                      b.segment_complete, wait_s);
    };
    bool submitted_all = true;
    if (mode == TransferMode::kDirect) {
      t_stop = steady_ns();
      for (const StreamBatch& b : map.batches) submitted_all = submitted_all && submit(b, 600.0);
    } else {
      const int64_t t_first = map.batches.front().t_ns;
      const int64_t start = steady_ns();
      int64_t submitted = 0;
      for (size_t k = 0; k < map.batches.size(); ++k) {
        const StreamBatch& b = map.batches[k];
        const auto due = std::chrono::steady_clock::time_point(std::chrono::nanoseconds(
            start + static_cast<int64_t>(static_cast<double>(b.t_ns - t_first) / setup.time_compression)));
        std::this_thread::sleep_until(due);
        const int64_t backlog = submitted - s.stats().points;
        r.max_backlog_points = std::max(r.max_backlog_points, backlog);
        if (k + 1 == map.batches.size()) {
          r.backlog_points_at_stop = backlog;
          t_stop = steady_ns();
          r.replay_s = (t_stop - start) * 1e-9;
        }
        if (!submit(b, 0.0)) {
          ++r.submits_waited;
          submitted_all = submitted_all && submit(b, 600.0);
        }
        submitted += b.n;
      }
    }
    if (!submitted_all) r.error = "the streamer refused a batch for 600 s";
    // The last point on the ground.
    const int64_t deadline = t_stop + static_cast<int64_t>(setup.timeout_s * 1e9);
    while (done_ns.load() == 0 && steady_ns() < deadline && !ground_failed.load())
      std::this_thread::sleep_for(std::chrono::microseconds(500));
    if (done_ns.load() != 0) {
      r.latency_s = (done_ns.load() - t_stop) * 1e-9;
      r.ok = r.error.empty();
    } else if (r.error.empty()) {
      r.error = ground_failed.load()
                    ? "the ground station's LCM socket failed"
                    : "not every point was stored within " + std::to_string(setup.timeout_s) + " s";
    }
    (void)s.flush(10.0);  // the last acks, so that the byte count holds the whole exchange
    r.streamer = s.stats();
    const int64_t bytes1 = (setup.link_byte_counter ? setup.link_byte_counter() : -1);
    if (bytes0 >= 0 && bytes1 >= 0) r.link_bytes = bytes1 - bytes0;
    streamer.value().reset();
  }
  stop.store(true);
  ground.join();
  r.points_stored = g.stats().points_stored;
  r.chunks_stored = g.stats().chunks_stored;
  r.duplicates = g.stats().duplicates;
  r.rejected = g.stats().rejected;
  station.value().reset();  // releases the store's lock

  if (r.ok && setup.verify_points) {
    const core::Status st = verify_store(dir, run_id, map, setup.streamer.codec.color_bits,
                                         setup.streamer.codec.max_position_error_m, &r);
    if (!st.ok()) {
      r.ok = false;
      r.error = "verifying the ground store: " + st.message();
    }
  }
  std::error_code ec;
  std::filesystem::remove_all(dir, ec);
  return r;
}

CodecThroughput measure_codec(const PointStream& map, const mapio::MapStreamerConfig& config) {
  CodecThroughput out;
  mapio::ChunkCodecConfig codec = config.codec;
  codec.max_payload_bytes = config.max_chunk_bytes;
  codec.with_point_ids = false;
  std::vector<std::vector<uint8_t>> payloads;
  std::vector<int> counts;
  std::vector<uint8_t> buf;
  // As MapStreamer::Impl::encode_range: halve a chunk until its payload fits.
  auto encode = [&](auto&& self, const mapio::ChunkPoint* pts, int n) -> void {
    auto r = mapio::encode_chunk(pts, n, nullptr, nullptr, codec, &buf);
    if (!r.ok() && r.status().code() == core::ErrorCode::kOutOfRange && n > 1) {
      self(self, pts, n / 2);
      self(self, pts + n / 2, n - n / 2);
      return;
    }
    if (!r.ok()) {
      ++out.errors;
      return;
    }
    payloads.push_back(buf);
    counts.push_back(n);
    out.points += n;
    out.payload_bytes += static_cast<int64_t>(buf.size());
  };
  mapio::SpatialOrder order(config.max_batch_points);
  std::vector<mapio::ChunkPoint> batch;
  batch.reserve(static_cast<size_t>(config.max_batch_points));
  const auto t0 = std::chrono::steady_clock::now();
  for (const StreamBatch& b : map.batches) {
    // As MapStreamer::submit: a batch over max_batch_points goes in pieces, each sorted and cut.
    for (int piece = 0; piece < b.n; piece += config.max_batch_points) {
      const int n = std::min(config.max_batch_points, b.n - piece);
      const auto begin = map.points_segment.begin() + static_cast<ptrdiff_t>(b.first) + piece;
      batch.assign(begin, begin + n);
      if (config.spatial_order) order.sort(batch.data(), nullptr, n);
      for (int first = 0; first < n; first += config.max_points_per_chunk)
        encode(encode, batch.data() + first, std::min(config.max_points_per_chunk, n - first));
    }
  }
  const auto t1 = std::chrono::steady_clock::now();
  mapio::DecodedChunk decoded;
  for (size_t i = 0; i < payloads.size(); ++i) {
    if (!mapio::decode_chunk(payloads[i].data(), payloads[i].size(), counts[i], mapio::ChunkDecodeLimits{},
                             &decoded)
             .ok())
      ++out.errors;
  }
  const auto t2 = std::chrono::steady_clock::now();
  out.chunks = static_cast<int64_t>(payloads.size());
  out.encode_s = std::chrono::duration<double>(t1 - t0).count();
  out.decode_s = std::chrono::duration<double>(t2 - t1).count();
  return out;
}

}  // namespace hwr::bench
