// `hwr-bench transfer` (issue #5 acceptance, last bullet; paper sec. III-C, Table II): how long after
// the robot stops the last map point is on the ground, for maps of 0.1 to 3.8 million points,
//  (a) direct: at the stop the whole map is encoded (Draco chunks, as the streamer cuts them) and sent;
//  (b) ours: the local mapper's batches are streamed while the map fills (mapping timeline of a sim
//      run, optionally time-compressed), and the robot stops after the last batch;
// end to end (encode, link, decode, store) between a MapStreamer and a GroundStation over LCM UDP
// multicast inside a private network namespace whose loopback is shaped by tc tbf (1 Gbit/s, and
// 100 Mbit/s as a second row) with an Ethernet MTU. Also: bytes on the link against raw float xyz +
// rgb (15 B/point), the largest position error of the stored points, and one core's encode
// throughput against the mapping rate.
//
//   hwr-bench transfer [--quick] [--sequences lab[,outdoor]] [--sizes 0.1,0.9,1.7,2.5,3.8]
//                      [--rates 1000,100] [--time-compression X] [--mtu BYTES]
//                      [--chunk-points N] [--chunk-bytes N] [--window-kib N] [--window-chunks N]
//                      [--speed S] [--color-bits B] [--no-ground-maps] [--no-verify] [--codec-only]
//                      [--stream-cache FILE]
// --quick: 0.1 and 0.9 million points at 1 Gbit/s only. --stream-cache: keep the captured point
// stream in FILE (e.g. under /tmp) and reuse it on the next run with the same sequences and sizes.
// --codec-only: the stream and one core's codec figures, no link rows.
//
// The bench re-executes itself under `unshare -rn` (as tests/mapio/private_netns.hpp does); where no
// namespace can be made it says so and measures the codec alone (no link rows).

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "bench_command.hpp"
#include "transfer_bench_link.hpp"
#include "transfer_bench_stream.hpp"

namespace hwr::bench {
namespace {

constexpr const char* kNetnsEnv = "HWR_IN_PRIVATE_NETNS";
// hwr_lcm's production URL (mapio/lcm_link.hpp), here on the namespace's loopback.
constexpr const char* kUrl = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";

// Paper Table II ("average time cost of map transmission in outdoor scene", seconds), quoted exactly.
struct PaperRow {
  double size_m;
  const char* direct_s;
  const char* segmented_s;
};
constexpr PaperRow kPaper[] = {{0.1, "1.25", "1.25"},
                               {0.9, "3.95", "2.32"},
                               {1.7, "9.67", "2.74"},
                               {2.5, "26.79", "2.65"},
                               {3.8, "48.95", "2.38"}};

struct Options {
  bool quick = false;
  std::vector<std::string> sequences{"lab"};
  std::vector<double> sizes_m{0.1, 0.9, 1.7, 2.5, 3.8};
  std::vector<int> rates_mbit{1000, 100};
  double time_compression = 0;  // 0: chosen so the streamed rows fit the time budget
  int mtu = 1500;
  bool verify = true;
  bool codec_only = false;
  std::string stream_cache;
  mapio::MapStreamerConfig streamer;
};

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  for (std::string t; std::getline(ss, t, ',');)
    if (!t.empty()) out.push_back(t);
  return out;
}

int usage(const std::string& why) {
  std::fprintf(stderr, "hwr-bench transfer: %s\n", why.c_str());
  return 2;
}

std::string self_exe() {
  char buf[4096];
  const ssize_t n = readlink("/proc/self/exe", buf, sizeof(buf) - 1);
  if (n <= 0) return {};
  buf[n] = '\0';
  return buf;
}

// Runs this command again inside `unshare -rn` (a private user + network namespace); its exit status.
int rerun_in_private_netns(int argc, char** argv) {
  std::vector<std::string> args = {"unshare", "-rn", self_exe(), "transfer"};
  for (int i = 1; i < argc; ++i) args.emplace_back(argv[i]);
  std::vector<char*> cargs;
  for (auto& a : args) cargs.push_back(a.data());
  cargs.push_back(nullptr);
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t pid = fork();
  if (pid < 0) return 1;
  if (pid == 0) {
    setenv(kNetnsEnv, "1", 1);
    execvp("unshare", cargs.data());
    _exit(127);
  }
  int st = 0;
  if (waitpid(pid, &st, 0) < 0) return 1;
  return WIFEXITED(st) ? WEXITSTATUS(st) : 128;
}

// The namespace's loopback transmit bytes (/proc/net/dev is the calling process's namespace; /sys is
// not remounted by unshare -n and would show the host's).
int64_t loopback_tx_bytes() {
  std::ifstream f("/proc/net/dev");
  std::string line;
  while (std::getline(f, line)) {
    const size_t colon = line.find(':');
    if (colon == std::string::npos) continue;
    std::string name = line.substr(0, colon);
    name.erase(0, name.find_first_not_of(' '));
    if (name != "lo") continue;
    std::istringstream fields(line.substr(colon + 1));
    int64_t v[9] = {};
    for (int64_t& x : v)
      fields >> x;  // rx: bytes packets errs drop fifo frame compressed multicast; tx: bytes
    return fields ? v[8] : -1;
  }
  return -1;
}

bool shape_loopback(int rate_mbit) {
  // Bucket: 2 ms of the rate (at least 16 KiB), queue up to 50 ms: a switch port's worth.
  const long burst = std::max(16L << 10, static_cast<long>(rate_mbit) * 1'000'000 / 8 / 500);
  char cmd[256];
  std::snprintf(cmd, sizeof(cmd), "tc qdisc replace dev lo root tbf rate %dmbit burst %ld latency 50ms",
                rate_mbit, burst);
  return std::system(cmd) == 0;
}

const PaperRow* paper_row(double size_m) {
  for (const PaperRow& p : kPaper)
    if (std::abs(p.size_m - size_m) < 1e-9) return &p;
  return nullptr;
}

struct Row {
  int rate_mbit = 0;
  double size_m = 0;
  size_t points = 0;
  double mapping_s = 0;  // simulated time over which the mapper produced the map
  TransferResult direct, ours;
};

double mib(int64_t b) { return static_cast<double>(b) / (1 << 20); }

}  // namespace

int run_transfer_command(int argc, char** argv) {
  Options o;
  bool sizes_given = false, rates_given = false, no_ground_maps = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const bool v = i + 1 < argc;
    if (a == "--quick") {
      o.quick = true;
    } else if (a == "--sequences" && v) {
      o.sequences = split(argv[++i]);
    } else if (a == "--sizes" && v) {
      o.sizes_m.clear();
      for (const auto& s : split(argv[++i])) o.sizes_m.push_back(std::atof(s.c_str()));
      sizes_given = true;
    } else if (a == "--rates" && v) {
      o.rates_mbit.clear();
      for (const auto& s : split(argv[++i])) o.rates_mbit.push_back(std::atoi(s.c_str()));
      rates_given = true;
    } else if (a == "--time-compression" && v) {
      o.time_compression = std::atof(argv[++i]);
    } else if (a == "--mtu" && v) {
      o.mtu = std::atoi(argv[++i]);
    } else if (a == "--chunk-points" && v) {
      o.streamer.max_points_per_chunk = std::atoi(argv[++i]);
    } else if (a == "--chunk-bytes" && v) {
      o.streamer.max_chunk_bytes = static_cast<size_t>(std::atol(argv[++i]));
    } else if (a == "--window-kib" && v) {
      o.streamer.link.window_bytes = static_cast<size_t>(std::atol(argv[++i])) << 10;
    } else if (a == "--window-chunks" && v) {
      o.streamer.link.window_chunks = std::atoi(argv[++i]);
    } else if (a == "--speed" && v) {
      o.streamer.codec.speed = std::atoi(argv[++i]);
    } else if (a == "--color-bits" && v) {
      o.streamer.codec.color_bits = std::atoi(argv[++i]);
    } else if (a == "--no-ground-maps") {
      no_ground_maps = true;
    } else if (a == "--no-verify") {
      o.verify = false;
    } else if (a == "--codec-only") {
      o.codec_only = true;
    } else if (a == "--stream-cache" && v) {
      o.stream_cache = argv[++i];
    } else {
      return usage("unknown or incomplete option '" + a + "'");
    }
  }
  if (o.quick) {
    if (!sizes_given) o.sizes_m = {0.1, 0.9};
    if (!rates_given) o.rates_mbit = {1000};
  }
  if (o.sequences.empty() || o.sizes_m.empty() || o.rates_mbit.empty())
    return usage("--sequences, --sizes and --rates need at least one value each");
  for (double s : o.sizes_m)
    if (!(s > 0 && s <= 50)) return usage("--sizes are millions of points in (0, 50]");
  for (int r : o.rates_mbit)
    if (r <= 0) return usage("--rates are Mbit/s > 0");
  if (o.time_compression < 0) return usage("--time-compression must be > 0 (0: automatic)");

  // The link rows need a private network namespace: re-run inside one.
  bool have_netns = std::getenv(kNetnsEnv) != nullptr;
  if (!have_netns) {
    if (std::system("unshare -rn true >/dev/null 2>&1") == 0) return rerun_in_private_netns(argc, argv);
    std::printf(
        "hwr-bench transfer: cannot create a private network namespace here (unshare -rn failed): the link "
        "rows are SKIPPED (UDP multicast is only used inside one); the codec figures follow.\n");
  } else {
    char cmd[200];
    std::snprintf(cmd, sizeof(cmd),
                  "ip link set lo up && ip link set lo mtu %d && ip route add 224.0.0.0/4 dev lo", o.mtu);
    if (std::system(cmd) != 0) {
      std::fprintf(stderr, "hwr-bench transfer: cannot set up the namespace's loopback (%s)\n", cmd);
      return 1;
    }
  }
  const auto bench_t0 = std::chrono::steady_clock::now();

  // 1. The point stream: the pipeline once per sequence, until the largest map is there.
  const size_t max_points =
      static_cast<size_t>(*std::max_element(o.sizes_m.begin(), o.sizes_m.end()) * 1e6 + 0.5);
  std::vector<PointStream> streams;
  std::string cache_key = "sequences";
  for (const auto& n : o.sequences) cache_key += ":" + n;
  if (!o.stream_cache.empty()) {
    auto cached = load_point_streams(o.stream_cache, cache_key);
    size_t cached_points = 0;
    bool cut_short = false;
    if (cached.ok()) {
      for (const auto& c : cached.value()) {
        cached_points += c.size();
        cut_short = cut_short || c.cut_short;
      }
    }
    if (cached.ok() && (cached_points >= max_points || !cut_short)) {
      streams = std::move(cached.value());
      std::printf("point stream read from %s (captured by an earlier run)\n", o.stream_cache.c_str());
    } else if (cached.status().code() != core::ErrorCode::kNotFound) {
      std::fprintf(stderr, "hwr-bench transfer: %s; capturing again\n", cached.status().message().c_str());
    }
  }
  const bool from_cache = !streams.empty();
  size_t captured = 0;
  for (const auto& s : streams) captured += s.size();
  for (const std::string& name : o.sequences) {
    if (from_cache) break;
    if (captured >= max_points) {
      std::printf("sequence %s not needed: %zu points already streamed\n", name.c_str(), captured);
      continue;
    }
    std::fprintf(stderr, "hwr-bench transfer: running %s through the pipeline...\n", name.c_str());
    auto s = capture_point_stream(name, max_points - captured);
    if (!s.ok()) {
      std::fprintf(stderr, "hwr-bench transfer: %s: %s\n", name.c_str(), s.status().message().c_str());
      return 1;
    }
    captured += s->size();
    streams.push_back(std::move(s.value()));
  }
  if (!from_cache && !o.stream_cache.empty()) {
    const core::Status st = save_point_streams(o.stream_cache, cache_key, streams);
    if (!st.ok()) std::fprintf(stderr, "hwr-bench transfer: %s\n", st.message().c_str());
  }
  int64_t stream_ns = 0;
  for (const auto& s : streams) {
    std::printf(
        "%s: %zu frames mapped in %.1f s of wall time, %zu points streamed in %zu batches over %.1f s "
        "of simulated time (%.0f points/s)%s\n",
        s.name.c_str(), s.frames, s.pipeline_wall_s, s.size(), s.batches.size(), s.duration_ns * 1e-9,
        s.size() / std::max(1e-9, s.duration_ns * 1e-9), s.cut_short ? "; stopped there, enough points" : "");
    stream_ns += s.duration_ns;
  }
  const double mapping_rate = static_cast<double>(captured) / std::max(1e-9, stream_ns * 1e-9);
  if (captured < max_points)
    std::printf("the stream has %zu points: larger maps loop it with new segment ids\n", captured);

  // 2. One core's codec throughput, on the largest map (as the streamer cuts it).
  const PointStream largest = first_points(streams, max_points);
  const CodecThroughput codec = measure_codec(largest, o.streamer);
  const double encode_rate = static_cast<double>(codec.points) / std::max(1e-9, codec.encode_s);
  const double decode_rate = static_cast<double>(codec.points) / std::max(1e-9, codec.decode_s);
  std::printf(
      "codec, one core, %.2fM points in %lld chunks (<= %d points, <= %zu bytes, speed %d, %.1f mm): "
      "encode %.2fM points/s, decode %.2fM points/s, %.3f bytes/point (raw 15), %lld errors\n",
      codec.points * 1e-6, static_cast<long long>(codec.chunks), o.streamer.max_points_per_chunk,
      o.streamer.max_chunk_bytes, o.streamer.codec.speed, o.streamer.codec.max_position_error_m * 1e3,
      encode_rate * 1e-6, decode_rate * 1e-6,
      static_cast<double>(codec.payload_bytes) / std::max<int64_t>(1, codec.points),
      static_cast<long long>(codec.errors));
  // The same chunks with lossless colour (one Draco kd-tree cloud per chunk), for the bytes it costs.
  mapio::MapStreamerConfig lossless_config = o.streamer;
  lossless_config.codec.color_bits = 8;
  const CodecThroughput lossless = measure_codec(largest, lossless_config);
  const double lossless_ratio = static_cast<double>(lossless.payload_bytes) /
                                (15.0 * static_cast<double>(std::max<int64_t>(1, lossless.points)));
  std::printf("lossless colour (color_bits 8): %.3f bytes/point, %.2fx fewer than raw\n",
              15.0 * lossless_ratio, 1.0 / lossless_ratio);
  std::printf("mapping rate %.0f points/s: one core encodes %.1fx faster -> %s\n", mapping_rate,
              encode_rate / mapping_rate, encode_rate >= mapping_rate ? "keeps up" : "DOES NOT keep up");

  // 3. The transfers.
  std::vector<Row> rows;
  double compression = o.time_compression;
  if (have_netns && !o.codec_only) {
    std::vector<PointStream> maps;
    double replay_sim_s = 0;
    for (double s : o.sizes_m) {
      maps.push_back(first_points(streams, static_cast<size_t>(s * 1e6 + 0.5)));
      replay_sim_s += (maps.back().duration_ns - maps.back().batches.front().t_ns) * 1e-9;
    }
    if (compression == 0) {
      // Streamed rows replay the mapping timeline: at most ~280 s of them in all (~35 s with --quick),
      // and the compressed mapping rate stays under a third of one core's encode rate.
      const double budget_s = o.quick ? 35.0 : 280.0;
      compression = std::max(1.0, replay_sim_s * static_cast<double>(o.rates_mbit.size()) / budget_s);
      compression = std::min(compression, std::max(1.0, encode_rate / mapping_rate / 3.0));
    }
    std::printf(
        "streamed rows replay the mapping timeline %.2fx faster than simulated time (%.0f points/s "
        "submitted, %.1f s of replay per link rate)\n",
        compression, mapping_rate * compression, replay_sim_s / compression);
    TransferSetup setup;
    setup.url = kUrl;
    setup.streamer = o.streamer;
    setup.time_compression = compression;
    setup.verify_points = o.verify;
    setup.write_ground_maps = !no_ground_maps;
    setup.link_byte_counter = loopback_tx_bytes;
    int64_t run_id = 0;
    for (int rate : o.rates_mbit) {
      if (!shape_loopback(rate)) {
        std::fprintf(stderr, "hwr-bench transfer: tc tbf on lo failed; %d Mbit/s rows skipped\n", rate);
        continue;
      }
      for (size_t k = 0; k < o.sizes_m.size(); ++k) {
        Row row;
        row.rate_mbit = rate;
        row.size_m = o.sizes_m[k];
        row.points = maps[k].size();
        row.mapping_s = maps[k].duration_ns * 1e-9;
        std::fprintf(stderr, "hwr-bench transfer: %d Mbit/s, %.1fM points: direct...\n", rate, row.size_m);
        row.direct = run_transfer(maps[k], TransferMode::kDirect, run_id++, setup);
        std::fprintf(stderr, "hwr-bench transfer: %d Mbit/s, %.1fM points: streamed...\n", rate, row.size_m);
        row.ours = run_transfer(maps[k], TransferMode::kStreamed, run_id++, setup);
        for (const TransferResult* r : {&row.direct, &row.ours})
          if (!r->ok)
            std::printf("FAILED (%d Mbit/s, %.1fM points): %s\n", rate, row.size_m, r->error.c_str());
        rows.push_back(std::move(row));
      }
    }
  }

  // 4. The table beside the paper's, then key=value lines.
  if (!rows.empty()) {
    std::printf(
        "\nTable II: last point on the ground after the robot stops [s] (paper: outdoor scene, wired "
        "link)\n");
    std::printf("%6s %6s | %7s %7s | %8s %8s | %7s %9s %8s %9s %7s %8s %8s %8s\n", "size", "link", "paper",
                "paper", "direct", "ours", "raw", "payload", "link", "raw/link", "resend", "err ax",
                "backlog", "mapping");
    std::printf("%6s %6s | %7s %7s | %8s %8s | %7s %9s %8s %9s %7s %8s %8s %8s\n", "[Mpt]", "[Mb/s]",
                "direct", "segm.", "[s]", "[s]", "[MiB]", "[MiB]", "[MiB]", "", "", "[mm]", "[pts]", "[s]");
  }
  std::vector<std::string> keys;
  double lat_ours_max = 0, lat_direct_max = 0, ratio_max = 0, payload_ratio_max = 0, err_axis_max = 0,
         err_max = 0;
  int64_t unmatched = 0, backlog_max = 0, backlog_any_max = 0, waited = 0, failures = 0, resends = 0;
  int color_err_max = 0;
  double direct_ratio_max = 0;
  bool all_verified = !rows.empty();
  char line[320];
  for (const Row& row : rows) {
    const PaperRow* p = paper_row(row.size_m);
    const TransferResult& d = row.direct;
    const TransferResult& s = row.ours;
    const int64_t raw = 15 * static_cast<int64_t>(row.points);
    const double ratio =
        s.link_bytes > 0 ? static_cast<double>(s.link_bytes) / static_cast<double>(raw) : NAN;
    std::printf("%6.1f %6d | %7s %7s | %8.3f %8.3f | %7.1f %9.2f %8.2f %9.2f %7lld %8.3f %8lld %8.1f\n",
                row.size_m, row.rate_mbit, p ? p->direct_s : "-", p ? p->segmented_s : "-",
                d.ok ? d.latency_s : NAN, s.ok ? s.latency_s : NAN, mib(raw), mib(s.streamer.payload_bytes),
                mib(s.link_bytes), 1.0 / ratio,
                static_cast<long long>(s.streamer.resends + d.streamer.resends), s.max_axis_error_mm,
                static_cast<long long>(s.backlog_points_at_stop), row.mapping_s);
    failures += (d.ok ? 0 : 1) + (s.ok ? 0 : 1);
    if (s.ok) lat_ours_max = std::max(lat_ours_max, s.latency_s);
    if (d.ok) lat_direct_max = std::max(lat_direct_max, d.latency_s);
    // The link bytes of "ours" (the product; resends included); direct's are reported apart, since
    // a whole map sent at once overruns a busy ground station's receive ring and pays resends.
    if (s.link_bytes > 0) ratio_max = std::max(ratio_max, static_cast<double>(s.link_bytes) / raw);
    if (d.link_bytes > 0)
      direct_ratio_max = std::max(direct_ratio_max, static_cast<double>(d.link_bytes) / raw);
    for (const TransferResult* r : {&d, &s}) {
      payload_ratio_max = std::max(payload_ratio_max, static_cast<double>(r->streamer.payload_bytes) / raw);
      err_axis_max = std::max(err_axis_max, r->max_axis_error_mm);
      err_max = std::max(err_max, r->max_error_mm);
      color_err_max = std::max(color_err_max, r->max_color_error);
      unmatched += r->unmatched;
      resends += r->streamer.resends;
      all_verified = all_verified && r->verified;
    }
    backlog_max = std::max(backlog_max, s.backlog_points_at_stop);
    backlog_any_max = std::max(backlog_any_max, s.max_backlog_points);
    waited += s.submits_waited;
    const std::string tag = std::to_string(row.rate_mbit) + "mbit_" + [&] {
      char b[16];
      std::snprintf(b, sizeof(b), "%.1fm", row.size_m);
      return std::string(b);
    }();
    std::snprintf(line, sizeof(line),
                  "latency_s_direct_%s=%.4f\nlatency_s_ours_%s=%.4f\nlink_bytes_ratio_%s=%.4f\n"
                  "payload_bytes_ratio_%s=%.4f\nresends_%s=%lld\nbacklog_points_at_stop_%s=%lld",
                  tag.c_str(), d.ok ? d.latency_s : NAN, tag.c_str(), s.ok ? s.latency_s : NAN, tag.c_str(),
                  ratio, tag.c_str(), static_cast<double>(s.streamer.payload_bytes) / raw, tag.c_str(),
                  static_cast<long long>(s.streamer.resends + d.streamer.resends), tag.c_str(),
                  static_cast<long long>(s.backlog_points_at_stop));
    keys.push_back(line);
  }
  if (!rows.empty()) {
    std::printf(
        "direct: encoding starts at the stop; ours: batches submitted on the mapping timeline (x%.2f), the "
        "stop "
        "is the last batch's submit. raw = 15 B/point (float xyz + rgb); payload, link: of ours; link = "
        "bytes "
        "on the shaped loopback (IP/UDP/LCM headers, acks and resends included; MTU %d); resend: both modes; "
        "err ax = largest per-axis distance of a stored point to the submitted point it pairs with (decoded "
        "from the ground store); backlog = points submitted but not yet encoded just before the last "
        "batch.\n",
        compression, o.mtu);
  }
  for (const auto& k : keys) std::printf("%s\n", k.c_str());
  if (!rows.empty()) {
    std::printf("last_point_latency_s_max=%.4f\n", lat_ours_max);
    std::printf("direct_latency_s_max=%.4f\n", lat_direct_max);
    std::printf("bytes_ratio_vs_raw=%.4f\n", ratio_max);
    std::printf("bytes_reduction_vs_raw_min=%.2f\n", ratio_max > 0 ? 1.0 / ratio_max : NAN);
    std::printf("payload_ratio_vs_raw=%.4f\n", payload_ratio_max);
    std::printf("direct_bytes_ratio_vs_raw=%.4f\n", direct_ratio_max);
    std::printf("max_position_error_mm=%.4f\n", all_verified ? err_axis_max : NAN);
    std::printf("max_position_error_euclid_mm=%.4f\n", all_verified ? err_max : NAN);
    std::printf("color_bits=%d\n", o.streamer.codec.color_bits);
    std::printf("max_color_error=%d\n", all_verified ? color_err_max : -1);
    std::printf("decoded_points_unmatched=%lld\n", static_cast<long long>(unmatched));
    std::printf("resends=%lld\n", static_cast<long long>(resends));
    std::printf("backlog_points_at_stop_max=%lld\n", static_cast<long long>(backlog_max));
    std::printf("backlog_points_at_any_submit_max=%lld\n", static_cast<long long>(backlog_any_max));
    std::printf("streamed_submits_that_waited=%lld\n", static_cast<long long>(waited));
    std::printf("transfer_failures=%lld\n", static_cast<long long>(failures));
    std::printf("time_compression=%.3f\n", compression);
  } else {
    std::printf("transfer_rows=0\n");
    std::printf("payload_ratio_vs_raw=%.4f\n",
                static_cast<double>(codec.payload_bytes) / (15.0 * static_cast<double>(codec.points)));
  }
  std::printf("payload_ratio_lossless_color=%.4f\n", lossless_ratio);
  std::printf("encode_points_per_s_one_core=%.0f\n", encode_rate);
  std::printf("decode_points_per_s_one_core=%.0f\n", decode_rate);
  std::printf("mapping_points_per_s=%.0f\n", mapping_rate);
  std::printf("encode_keeps_up=%d\n", encode_rate >= mapping_rate ? 1 : 0);
  std::printf("bench_wall_s=%.1f\n",
              std::chrono::duration<double>(std::chrono::steady_clock::now() - bench_t0).count());
  return failures == 0 ? 0 : 1;
}

HWR_BENCH_COMMAND(
    transfer, "transfer",
    "map transmission (paper Table II): last point on the ground after the stop, direct vs "
    "streamed, 0.1-3.8M points over 1 Gbit/s and 100 Mbit/s (tbf, private netns); bytes vs raw, "
    "position error, encode rate vs mapping rate [--quick] [--sequences lab,outdoor] [--sizes ...] "
    "[--rates 1000,100] [--time-compression X] [--chunk-points N] [--chunk-bytes N] "
    "[--window-kib N] [--speed S] [--color-bits B]",
    run_transfer_command);

}  // namespace hwr::bench
