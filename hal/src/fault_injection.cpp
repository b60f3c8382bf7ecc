#include "hwr/hal/fault_injection.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <functional>
#include <limits>
#include <system_error>
#include <utility>

#include <opencv2/core.hpp>

namespace hwr::hal {
namespace {

constexpr const char* kKeys = "dropout, exposure, depth-nan, depth-zero, imu-dropout, seed";

// Shortest decimal text that reads back as exactly the same double (std::to_chars without a
// precision), so format → parse is lossless.
std::string number_text(double v) {
  char buf[64];
  const auto res = std::to_chars(buf, buf + sizeof(buf), v);
  return std::string(buf, res.ptr);
}

std::string trim(const std::string& s) {
  const size_t b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return {};
  const size_t e = s.find_last_not_of(" \t");
  return s.substr(b, e - b + 1);
}

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  size_t start = 0;
  while (true) {
    const size_t p = s.find(sep, start);
    out.push_back(s.substr(start, p == std::string::npos ? std::string::npos : p - start));
    if (p == std::string::npos) return out;
    start = p + 1;
  }
}

// Rules shared by the parser and apply_faults; messages without the token, which the caller adds.
core::Status check_time(const char* what, double v) {
  if (!std::isfinite(v) || v < 0) {
    return core::OutOfRange(std::string(what) + " " + number_text(v) + " must be a finite time >= 0 s");
  }
  return core::Status::Ok();
}

core::Status check_window(double start_s, double duration_s) {
  HWR_RETURN_IF_ERROR(check_time("start", start_s));
  if (!(duration_s > 0) || std::isnan(duration_s)) {
    return core::OutOfRange("duration " + number_text(duration_s) + " must be > 0 s");
  }
  return core::Status::Ok();
}

core::Status check_exposure(const FaultSpec::Exposure& e) {
  HWR_RETURN_IF_ERROR(check_time("time", e.at_s));
  if (!std::isfinite(e.gain) || e.gain <= 0) {
    return core::OutOfRange("gain " + number_text(e.gain) + " must be finite and > 0");
  }
  return core::Status::Ok();
}

core::Status check_holes(const FaultSpec::DepthHoles& h) {
  HWR_RETURN_IF_ERROR(check_window(h.start_s, h.duration_s));
  if (!(h.fraction > 0 && h.fraction <= 1)) {
    return core::OutOfRange("fraction " + number_text(h.fraction) + " must be in (0, 1]");
  }
  return core::Status::Ok();
}

std::string window_text(const char* key, const FaultSpec::Window& w) {
  return std::string(key) + "=" + number_text(w.start_s) + ":" + number_text(w.duration_s);
}
std::string exposure_text(const FaultSpec::Exposure& e) {
  return "exposure=" + number_text(e.at_s) + ":" + number_text(e.gain);
}
std::string holes_text(const FaultSpec::DepthHoles& h) {
  return std::string(h.value_nan ? "depth-nan=" : "depth-zero=") + number_text(h.start_s) + ":" +
         number_text(h.duration_s) + ":" + number_text(h.fraction);
}

core::Status with_token(const std::string& token, const core::Status& st) {
  return core::Status(st.code(), "fault spec token '" + token + "': " + st.message());
}

// Parses "A:B[:C]" into exactly `n` numbers.
core::Status parse_numbers(const std::string& value, size_t n, const char* usage, double* out) {
  if (value.empty()) return core::InvalidArgument(std::string("missing value, expected ") + usage);
  const std::vector<std::string> fields = split(value, ':');
  if (fields.size() != n) {
    return core::InvalidArgument("expected " + std::string(usage) + ", got " + std::to_string(fields.size()) +
                                 " value(s)");
  }
  for (size_t i = 0; i < n; ++i) {
    const std::string f = trim(fields[i]);
    if (f.empty()) return core::InvalidArgument(std::string("missing value, expected ") + usage);
    const char* first = f.data();
    if (*first == '+') ++first;  // from_chars takes no leading '+'
    const auto res = std::from_chars(first, f.data() + f.size(), out[i]);
    if (res.ec != std::errc() || res.ptr != f.data() + f.size() || !std::isfinite(out[i])) {
      return core::InvalidArgument("'" + f + "' is not a finite number (expected " + usage + ")");
    }
  }
  return core::Status::Ok();
}

// Windows as [start, end) offsets from the first sample, in ns; saturated far beyond any log.
struct WindowNs {
  int64_t start = 0, end = 0;
  bool contains(int64_t rel_ns) const { return rel_ns >= start && rel_ns < end; }
};

int64_t seconds_to_ns(double s) {
  constexpr double kMaxS = 4.0e9;  // 4e18 ns: start + duration still fits int64
  return static_cast<int64_t>(std::llround(std::min(s, kMaxS) * 1e9));
}

WindowNs to_ns(double start_s, double duration_s) {
  const int64_t start = seconds_to_ns(start_s);
  return {start, start + seconds_to_ns(duration_s)};
}

// SplitMix64 (Steele, Lea, Flood 2014): the finaliser keys the stream, the sequence draws from it.
uint64_t mix64(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

struct SplitMix64 {
  uint64_t state;
  uint64_t next() { return mix64(state += 0x9E3779B97F4A7C15ull); }
  // Uniform integer in [lo, hi] (modulo bias is negligible for image-sized ranges).
  int uniform(int lo, int hi) { return lo + static_cast<int>(next() % static_cast<uint64_t>(hi - lo + 1)); }
};

// A value no depth pixel holds (the contract's depths are >= 0 or NaN): marks pixels of a hole
// until the hole is complete, so no mask image is needed.
constexpr float kHoleMark = -std::numeric_limits<float>::max();

// Covers round(fraction · pixels) of depth (to within one rectangle row) with random rectangles of
// 1/16 to 1/4 of the image side, then writes `value` into them. Returns the pixels that held a
// valid depth before. No allocation.
uint32_t punch_holes(double fraction, float value, SplitMix64* rng, cv::Mat* depth) {
  const int W = depth->cols, H = depth->rows;
  const int64_t target = std::llround(fraction * static_cast<double>(W) * H);
  const int w_min = std::max(1, W / 16), w_max = std::max(w_min, W / 4);
  const int h_min = std::max(1, H / 16), h_max = std::max(h_min, H / 4);
  int64_t covered = 0;
  uint32_t newly_invalid = 0;
  const auto mark = [&](float& d) {
    if (d == kHoleMark) return;
    if (std::isfinite(d) && d > 0) ++newly_invalid;
    d = kHoleMark;
    ++covered;
  };
  // Random rectangles cover f of the image after about (A/a)·ln(1/(1-f)) draws (a few hundred at
  // f = 0.99); the cap only matters for f → 1, where a row scan finishes the job.
  for (int n = 0; n < 20000 && covered < target; ++n) {
    const int w = rng->uniform(w_min, w_max), h = rng->uniform(h_min, h_max);
    const int x0 = rng->uniform(0, W - w), y0 = rng->uniform(0, H - h);
    for (int y = y0; y < y0 + h && covered < target; ++y) {
      float* row = depth->ptr<float>(y);
      for (int x = x0; x < x0 + w; ++x) mark(row[x]);
    }
  }
  for (int y = 0; y < H && covered < target; ++y) {
    float* row = depth->ptr<float>(y);
    for (int x = 0; x < W && covered < target; ++x) mark(row[x]);
  }
  for (int y = 0; y < H; ++y) {
    float* row = depth->ptr<float>(y);
    for (int x = 0; x < W; ++x) {
      if (row[x] == kHoleMark) row[x] = value;
    }
  }
  return newly_invalid;
}

// The wrapped loader's state: one entry per kept frame, plus the spec's frame faults.
struct FaultedLoader {
  std::function<core::Status(size_t, RgbdFrame*)> original;
  std::vector<size_t> original_index;
  std::vector<int64_t> rel_ns;                          // t - t_first of each kept frame
  std::vector<std::pair<int64_t, double>> exposure_ns;  // (at, gain), sorted by time
  std::vector<std::pair<WindowNs, FaultSpec::DepthHoles>> holes;
  uint64_t seed = 1;
  std::shared_ptr<FaultReport> report;

  double gain_at(int64_t rel) const {
    double gain = 1.0;
    for (const auto& [at, g] : exposure_ns) {
      if (at > rel) break;
      gain = g;
    }
    return gain;
  }

  core::Status operator()(size_t i, RgbdFrame* out) const {
    if (i >= original_index.size()) {
      return core::OutOfRange("faulted replay: frame " + std::to_string(i) + " of " +
                              std::to_string(original_index.size()));
    }
    const size_t j = original_index[i];
    HWR_RETURN_IF_ERROR(original(j, out));
    const double gain = gain_at(rel_ns[i]);
    if (gain != 1.0) {
      // In place and saturating (cv::saturate_cast): same size and type, so no reallocation.
      if (!out->bgr.empty()) out->bgr.convertTo(out->bgr, -1, gain);
      if (!out->right_gray.empty()) out->right_gray.convertTo(out->right_gray, -1, gain);
      report->frames_exposure_changed.fetch_add(1, std::memory_order_relaxed);
    }
    bool punched = false;
    for (size_t k = 0; k < holes.size(); ++k) {
      const auto& [window, h] = holes[k];
      if (!window.contains(rel_ns[i])) continue;
      if (out->depth_m.empty()) continue;
      if (out->depth_m.type() != CV_32FC1) {
        return core::CorruptData("faulted replay: frame " + std::to_string(j) + " depth is not CV_32FC1");
      }
      // Keyed by (seed, entry, original frame): the same frame gets the same holes however the
      // log was cut.
      SplitMix64 rng{mix64(seed ^ mix64(0xD1B54A32D192ED03ull + k)) ^ mix64(j)};
      const float value = h.value_nan ? std::numeric_limits<float>::quiet_NaN() : 0.0f;
      out->invalid_depth_px += punch_holes(h.fraction, value, &rng, &out->depth_m);
      punched = true;
    }
    if (punched) report->frames_with_depth_holes.fetch_add(1, std::memory_order_relaxed);
    return core::Status::Ok();
  }
};

core::Status validate(const FaultSpec& spec) {
  const auto entry_error = [](const std::string& text, const core::Status& st) {
    return core::Status(st.code(), "fault spec entry '" + text + "': " + st.message());
  };
  for (const auto& w : spec.camera_dropouts) {
    const core::Status st = check_window(w.start_s, w.duration_s);
    if (!st.ok()) return entry_error(window_text("dropout", w), st);
  }
  for (const auto& w : spec.imu_dropouts) {
    const core::Status st = check_window(w.start_s, w.duration_s);
    if (!st.ok()) return entry_error(window_text("imu-dropout", w), st);
  }
  for (const auto& e : spec.exposure_jumps) {
    const core::Status st = check_exposure(e);
    if (!st.ok()) return entry_error(exposure_text(e), st);
  }
  for (const auto& h : spec.depth_holes) {
    const core::Status st = check_holes(h);
    if (!st.ok()) return entry_error(holes_text(h), st);
  }
  return core::Status::Ok();
}

int64_t first_sample_ns(const ReplayLog& log) {
  int64_t t = std::numeric_limits<int64_t>::max();
  if (!log.imu.empty()) t = std::min(t, log.imu.front().t_ns);
  if (!log.mag.empty()) t = std::min(t, log.mag.front().t_ns);
  if (!log.gnss.empty()) t = std::min(t, log.gnss.front().t_ns);
  if (!log.frame_t_ns.empty()) t = std::min(t, log.frame_t_ns.front());
  return t;
}

}  // namespace

bool FaultSpec::empty() const {
  return camera_dropouts.empty() && exposure_jumps.empty() && depth_holes.empty() && imu_dropouts.empty();
}

core::Expected<FaultSpec> parse_fault_spec(const std::string& text) {
  FaultSpec spec;
  if (trim(text).empty()) return spec;
  for (const std::string& raw : split(text, ',')) {
    const std::string token = trim(raw);
    if (token.empty()) return core::InvalidArgument("fault spec '" + text + "': empty token");
    const size_t eq = token.find('=');
    if (eq == std::string::npos) {
      return with_token(token,
                        core::InvalidArgument(std::string("expected KEY=VALUE with KEY one of ") + kKeys));
    }
    const std::string key = trim(token.substr(0, eq));
    const std::string value = trim(token.substr(eq + 1));
    double v[3] = {0, 0, 0};
    core::Status st;
    if (key == "dropout" || key == "imu-dropout") {
      st = parse_numbers(value, 2, (key + "=START:DURATION").c_str(), v);
      if (st.ok()) st = check_window(v[0], v[1]);
      if (st.ok()) (key == "dropout" ? spec.camera_dropouts : spec.imu_dropouts).push_back({v[0], v[1]});
    } else if (key == "exposure") {
      st = parse_numbers(value, 2, "exposure=AT:GAIN", v);
      const FaultSpec::Exposure e{v[0], v[1]};
      if (st.ok()) st = check_exposure(e);
      if (st.ok()) spec.exposure_jumps.push_back(e);
    } else if (key == "depth-nan" || key == "depth-zero") {
      st = parse_numbers(value, 3, (key + "=START:DURATION:FRACTION").c_str(), v);
      const FaultSpec::DepthHoles h{v[0], v[1], v[2], key == "depth-nan"};
      if (st.ok()) st = check_holes(h);
      if (st.ok()) spec.depth_holes.push_back(h);
    } else if (key == "seed") {
      if (value.empty()) {
        st = core::InvalidArgument("missing value, expected seed=N");
      } else {
        const auto res = std::from_chars(value.data(), value.data() + value.size(), spec.seed);
        if (res.ec != std::errc() || res.ptr != value.data() + value.size()) {
          st = core::InvalidArgument("'" + value + "' is not an unsigned integer (expected seed=N)");
        }
      }
    } else {
      st = core::InvalidArgument("unknown key '" + key + "' (" + kKeys + ")");
    }
    if (!st.ok()) return with_token(token, st);
  }
  return spec;
}

std::string format_fault_spec(const FaultSpec& spec) {
  std::vector<std::string> tokens;
  for (const auto& w : spec.camera_dropouts) tokens.push_back(window_text("dropout", w));
  for (const auto& e : spec.exposure_jumps) tokens.push_back(exposure_text(e));
  for (const auto& h : spec.depth_holes) tokens.push_back(holes_text(h));
  for (const auto& w : spec.imu_dropouts) tokens.push_back(window_text("imu-dropout", w));
  if (spec.seed != 1) tokens.push_back("seed=" + std::to_string(spec.seed));
  std::string out;
  for (size_t i = 0; i < tokens.size(); ++i) out += (i ? "," : "") + tokens[i];
  return out;
}

core::Expected<ReplayLog> apply_faults(ReplayLog log, const FaultSpec& spec,
                                       std::shared_ptr<FaultReport>* report) {
  HWR_RETURN_IF_ERROR(validate(spec));
  auto shared_report = std::make_shared<FaultReport>();
  if (report != nullptr) *report = shared_report;
  const int64_t t_first = first_sample_ns(log);
  if (t_first == std::numeric_limits<int64_t>::max()) return log;  // nothing to fault

  const auto in_any = [t_first](const std::vector<FaultSpec::Window>& windows, int64_t t_ns) {
    for (const auto& w : windows) {
      if (to_ns(w.start_s, w.duration_s).contains(t_ns - t_first)) return true;
    }
    return false;
  };

  const size_t imu_before = log.imu.size();
  log.imu.erase(std::remove_if(log.imu.begin(), log.imu.end(),
                               [&](const ImuSample& s) { return in_any(spec.imu_dropouts, s.t_ns); }),
                log.imu.end());
  shared_report->imu_removed = imu_before - log.imu.size();

  FaultedLoader loader;
  std::vector<int64_t> kept_t_ns;
  for (size_t j = 0; j < log.frame_t_ns.size(); ++j) {
    const int64_t t = log.frame_t_ns[j];
    if (in_any(spec.camera_dropouts, t)) continue;
    kept_t_ns.push_back(t);
    loader.original_index.push_back(j);
    loader.rel_ns.push_back(t - t_first);
  }
  shared_report->frames_removed = log.frame_t_ns.size() - kept_t_ns.size();
  log.frame_t_ns = std::move(kept_t_ns);

  if (log.load_frame) {
    for (const auto& e : spec.exposure_jumps) loader.exposure_ns.emplace_back(seconds_to_ns(e.at_s), e.gain);
    std::stable_sort(loader.exposure_ns.begin(), loader.exposure_ns.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    for (const auto& h : spec.depth_holes) loader.holes.emplace_back(to_ns(h.start_s, h.duration_s), h);
    loader.seed = spec.seed;
    loader.report = shared_report;
    loader.original = std::move(log.load_frame);
    log.load_frame = std::move(loader);
  }
  return log;
}

}  // namespace hwr::hal
