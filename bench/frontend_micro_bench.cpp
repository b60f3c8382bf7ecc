// Micro-benchmarks of the visual front end (run with `hwr-bench micro --benchmark_filter=Frontend`):
// grid ORB extraction on a TUM teddy frame (640 x 480, one core), projection matching of ~1000 map
// points, LSH matching, PoseRansac (500 correspondences, 30 % outliers), motion-only refinement,
// two-view triangulation. Timings compare builds and machines; no test depends on them.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "hwr/core/se3.hpp"
#include "hwr/core/so3.hpp"
#include "hwr/estimation/descriptor.hpp"
#include "hwr/estimation/exact_matcher.hpp"
#include "hwr/estimation/lsh_matcher.hpp"
#include "hwr/estimation/motion_only_refiner.hpp"
#include "hwr/estimation/orb_extractor.hpp"
#include "hwr/estimation/pose_ransac.hpp"
#include "hwr/estimation/projection_matcher.hpp"
#include "hwr/estimation/triangulation.hpp"
#include "hwr/hal/tum_dataset.hpp"
#if HWR_WITH_SIM
#include "hwr/sim/scenario.hpp"
#include "hwr/sim/sim_live_log.hpp"
#endif

namespace hwr::estimation {
namespace {

const char* const kTeddyDir = HWR_DATA_DIR "/tum-fr3-teddy-200/rgbd_dataset_freiburg3_teddy";

struct TeddyFrame {
  cv::Mat gray, depth_m;
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  bool ok = false;
};

Eigen::Isometry3d gt_pose_at(const std::vector<core::StampedPose>& gt, int64_t t_ns) {
  auto it = std::lower_bound(gt.begin(), gt.end(), t_ns,
                             [](const core::StampedPose& p, int64_t t) { return p.t_ns < t; });
  if (it == gt.begin() || it == gt.end()) return Eigen::Isometry3d::Identity();
  const double alpha =
      static_cast<double>(t_ns - (it - 1)->t_ns) / static_cast<double>(it->t_ns - (it - 1)->t_ns);
  return core::se3_interpolate((it - 1)->T_world_body, it->T_world_body, alpha);
}

// Teddy frames, loaded once.
const TeddyFrame& teddy(size_t index) {
  static std::vector<TeddyFrame> frames(200);
  TeddyFrame& f = frames.at(index);
  if (f.ok) return f;
  auto ds = hal::TumDataset::open(kTeddyDir);
  if (!ds.ok()) return f;
  hal::RgbdFrame frame;
  if (!ds->load_frame(index, &frame).ok()) return f;
  cv::cvtColor(frame.bgr, f.gray, cv::COLOR_BGR2GRAY);
  f.depth_m = frame.depth_m.clone();
  f.T_world_cam = gt_pose_at(ds->groundtruth(), ds->frame_time_ns(index));
  f.ok = true;
  return f;
}

// Restores OpenCV's thread count when a benchmark that pins it to one thread ends.
struct OneOpenCvThread {
  int saved = cv::getNumThreads();
  OneOpenCvThread() { cv::setNumThreads(1); }
  ~OneOpenCvThread() { cv::setNumThreads(saved); }
};

// Arg: pyramid levels.
void BM_FrontendGridOrbExtract(benchmark::State& state) {
  const TeddyFrame& f = teddy(20);
  if (!f.ok) {
    state.SkipWithError("teddy dataset missing");
    return;
  }
  OneOpenCvThread one_thread;
  OrbConfig cfg;
  cfg.levels = static_cast<int>(state.range(0));
  GridOrbExtractor extractor(cfg, 640, 480);
  FrameFeatures out(cfg.max_features, 640, 480);
  const hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  for (auto _ : state) {
    if (!extractor.extract(f.gray, f.depth_m, K, &out).ok()) state.SkipWithError("extract failed");
    benchmark::DoNotOptimize(out.size());
  }
  int with_depth = 0;
  for (int i = 0; i < out.size(); ++i) with_depth += out.feature(i).depth_m > 0 ? 1 : 0;
  state.counters["features"] = out.size();
  state.counters["with_depth"] = with_depth;
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_FrontendGridOrbExtract)->Arg(8)->Arg(6)->Arg(4)->Unit(benchmark::kMillisecond);

#if HWR_WITH_SIM
// The same on a rendered sim `lab` frame (procedural textures: many more FAST corners than teddy).
// Arg: min_fast_threshold (the retry threshold for cells with no corner at fast_threshold).
void BM_FrontendGridOrbExtractSimLab(benchmark::State& state) {
  static cv::Mat gray, depth_m;
  static hal::PinholeIntrinsics K;
  if (gray.empty()) {
    auto spec = sim::load_scenario("lab");
    auto live = spec.ok() ? sim::open_sim_live_log(spec.value(), 12.0)
                          : core::Expected<sim::SimLiveLog>(spec.status());
    hal::RgbdFrame frame;
    if (!live.ok() || !live->log.load_frame(300, &frame).ok()) {
      state.SkipWithError("sim lab frame could not be rendered");
      return;
    }
    cv::cvtColor(frame.bgr, gray, cv::COLOR_BGR2GRAY);
    depth_m = frame.depth_m.clone();
    K = live->log.info.intrinsics;
  }
  OneOpenCvThread one_thread;
  OrbConfig cfg;
  cfg.min_fast_threshold = static_cast<int>(state.range(0));
  GridOrbExtractor extractor(cfg, gray.cols, gray.rows);
  FrameFeatures out(cfg.max_features, gray.cols, gray.rows);
  for (auto _ : state) {
    if (!extractor.extract(gray, depth_m, K, &out).ok()) state.SkipWithError("extract failed");
    benchmark::DoNotOptimize(out.size());
  }
  state.counters["features"] = out.size();
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_FrontendGridOrbExtractSimLab)->Arg(7)->Arg(20)->Unit(benchmark::kMillisecond);
#endif

struct MatchSetup {
  FrameFeatures a{1000, 640, 480}, b{1000, 640, 480}, c{1000, 640, 480};
  std::vector<MapPointRef> points;
  Eigen::Isometry3d T_b_world = Eigen::Isometry3d::Identity();
  bool ok = false;
};

// Map points from the depth features of teddy frames 15 and 20 (placed with the ground truth),
// matched into frame 25 (b); c is frame 30 for LSH.
const MatchSetup& match_setup() {
  static MatchSetup s;
  if (s.ok) return s;
  const size_t idx[3] = {20, 25, 30};
  FrameFeatures* ff[3] = {&s.a, &s.b, &s.c};
  GridOrbExtractor extractor(OrbConfig{}, 640, 480);
  const hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  for (int k = 0; k < 3; ++k) {
    const TeddyFrame& f = teddy(idx[k]);
    if (!f.ok || !extractor.extract(f.gray, f.depth_m, K, ff[k]).ok()) return s;
  }
  static FrameFeatures extra(1000, 640, 480);
  const TeddyFrame& f15 = teddy(15);
  if (!f15.ok || !extractor.extract(f15.gray, f15.depth_m, K, &extra).ok()) return s;
  for (const auto& [features, T] :
       {std::make_pair(&s.a, teddy(20).T_world_cam), std::make_pair(&extra, f15.T_world_cam)}) {
    for (int i = 0; i < features->size() && s.points.size() < 1000; ++i) {
      const Feature& f = features->feature(i);
      if (f.depth_m > 0) s.points.push_back({T * f.p_cam_m, features->descriptor(i), f.octave});
    }
  }
  s.T_b_world = teddy(25).T_world_cam.inverse();
  s.ok = true;
  return s;
}

void BM_FrontendProjectionMatch(benchmark::State& state) {
  const MatchSetup& s = match_setup();
  if (!s.ok) {
    state.SkipWithError("teddy dataset missing");
    return;
  }
  ProjectionMatcher matcher(1000, 1000);
  std::vector<FeatureMatch> out(1000);
  const hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  int m = 0;
  for (auto _ : state) {
    m = matcher.match(s.points.data(), static_cast<int>(s.points.size()), s.T_b_world, K, s.b,
                      ProjectionMatchConfig{}, out.data(), 1000);
    benchmark::DoNotOptimize(m);
  }
  state.counters["points"] = static_cast<double>(s.points.size());
  state.counters["matches"] = m;
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_FrontendProjectionMatch)->Unit(benchmark::kMicrosecond);

void BM_FrontendLshBuildAndMatch(benchmark::State& state) {
  const MatchSetup& s = match_setup();
  if (!s.ok) {
    state.SkipWithError("teddy dataset missing");
    return;
  }
  LshMatcher lsh(1000, LshConfig{});
  std::vector<FeatureMatch> out(1000);
  int m = 0;
  for (auto _ : state) {
    lsh.build(s.c);
    m = lsh.match(s.a, out.data(), 1000);
    benchmark::DoNotOptimize(m);
  }
  state.counters["matches"] = m;
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_FrontendLshBuildAndMatch)->Unit(benchmark::kMillisecond);

// The relocalizer's pattern: the current keyframe indexed once, then matched with many prior
// keyframes (LSH: match only; exact: every pair each time). Matcher: LshMatcher or ExactMatcher.
template <typename Matcher, typename Config>
void match_only(benchmark::State& state, const Config& config) {
  const MatchSetup& s = match_setup();
  if (!s.ok) {
    state.SkipWithError("teddy dataset missing");
    return;
  }
  Matcher matcher(1000, config);
  matcher.build(s.c);
  std::vector<FeatureMatch> out(1000);
  int m = 0;
  for (auto _ : state) {
    m = matcher.match(s.a, out.data(), 1000);
    benchmark::DoNotOptimize(m);
  }
  state.counters["matches"] = m;
  state.SetItemsProcessed(state.iterations());
}

void BM_FrontendLshMatchOnly(benchmark::State& state) { match_only<LshMatcher>(state, LshConfig{}); }
BENCHMARK(BM_FrontendLshMatchOnly)->Unit(benchmark::kMillisecond);

void BM_FrontendExactMatch(benchmark::State& state) { match_only<ExactMatcher>(state, ExactMatchConfig{}); }
BENCHMARK(BM_FrontendExactMatch)->Unit(benchmark::kMillisecond);

Eigen::Isometry3d bench_pose() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = core::so3_exp(Eigen::Vector3d(0.2, -0.4, 0.1));
  T.translation() = Eigen::Vector3d(0.5, -0.3, 1.2);
  return T;
}

// n correspondences, a fraction of them outliers, 0.7 px noise; depth on all or none.
std::vector<Correspondence> synthetic_correspondences(int n, double outlier_frac, bool depth, uint64_t seed) {
  std::mt19937_64 rng(seed);
  const hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  const Eigen::Isometry3d T_world_cam = bench_pose().inverse();
  std::uniform_real_distribution<double> U(0, 640), V(0, 480), Z(0.8, 5.0), unit(0, 1);
  std::normal_distribution<double> g(0, 0.7);
  std::vector<Correspondence> out;
  for (int i = 0; i < n; ++i) {
    Correspondence c;
    c.octave = i % 4;
    const double u = U(rng), v = V(rng), z = Z(rng);
    c.p_world = T_world_cam * Eigen::Vector3d((u - K.cx) * z / K.fx, (v - K.cy) * z / K.fy, z);
    const bool outlier = unit(rng) < outlier_frac;
    c.uv_px = outlier ? Eigen::Vector2d(U(rng), V(rng)) : Eigen::Vector2d(u + g(rng), v + g(rng));
    if (depth) c.depth_m = outlier ? Z(rng) : z * (1.0 + 0.005 * g(rng));
    out.push_back(c);
  }
  return out;
}

// Arg: 1 = with depth (3D-3D minimal solver), 0 = without (P3P).
void BM_FrontendPoseRansac(benchmark::State& state) {
  const bool depth = state.range(0) != 0;
  const std::vector<Correspondence> c = synthetic_correspondences(500, 0.3, depth, 3);
  PoseRansac ransac(500);
  std::vector<uint8_t> mask(500);
  const hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  PoseRansacResult r;
  for (auto _ : state) {
    r = ransac.solve(c.data(), 500, K, PoseRansacConfig{}, mask.data());
    benchmark::DoNotOptimize(r.inliers);
  }
  state.counters["inliers"] = r.inliers;
  state.counters["iterations"] = r.iterations;
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_FrontendPoseRansac)->Arg(1)->Arg(0)->Unit(benchmark::kMicrosecond);

// Arg: correspondences (10 % outliers, depth on all), default 4 rounds x 10 iterations.
void BM_FrontendMotionOnlyRefine(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const std::vector<Correspondence> c = synthetic_correspondences(n, 0.1, true, 4);
  MotionOnlyRefiner refiner(n);
  std::vector<uint8_t> mask(static_cast<size_t>(n));
  const hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  Eigen::Isometry3d T_init = bench_pose();
  T_init.translation() += Eigen::Vector3d(0.02, -0.01, 0.03);
  RefineResult r;
  for (auto _ : state) {
    r = refiner.refine(c.data(), n, K, T_init, RefineConfig{}, mask.data());
    benchmark::DoNotOptimize(r.inliers);
  }
  state.counters["inliers"] = r.inliers;
  state.counters["lm_iterations"] = r.iterations;
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_FrontendMotionOnlyRefine)->Arg(200)->Arg(500)->Unit(benchmark::kMicrosecond);

void BM_FrontendTriangulateTwoView(benchmark::State& state) {
  const hal::PinholeIntrinsics K = hal::tum_fr3_intrinsics();
  const Eigen::Isometry3d T0 = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T1 = Eigen::Isometry3d::Identity();
  T1.translation() = Eigen::Vector3d(-0.3, 0, 0);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> U(-1, 1), Z(1, 6);
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> obs;
  for (int i = 0; i < 256; ++i) {
    const Eigen::Vector3d p(U(rng), U(rng), Z(rng));
    const Eigen::Vector3d q = T1 * p;
    obs.emplace_back(Eigen::Vector2d(K.fx * p.x() / p.z() + K.cx, K.fy * p.y() / p.z() + K.cy),
                     Eigen::Vector2d(K.fx * q.x() / q.z() + K.cx, K.fy * q.y() / q.z() + K.cy));
  }
  size_t i = 0;
  Eigen::Vector3d p;
  for (auto _ : state) {
    const auto& o = obs[i++ & 255];
    benchmark::DoNotOptimize(
        triangulate_two_view(T0, T1, K, K, o.first, o.second, TriangulationConfig{}, &p));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_FrontendTriangulateTwoView);

void BM_FrontendHammingDistance(benchmark::State& state) {
  std::mt19937 rng(1);
  std::vector<uint8_t> d(256 * kOrbDescriptorBytes);
  for (auto& x : d) x = static_cast<uint8_t>(rng());
  size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(
        hamming_distance(&d[(i & 255) * kOrbDescriptorBytes], &d[((i + 7) & 255) * kOrbDescriptorBytes]));
    ++i;
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_FrontendHammingDistance);

}  // namespace
}  // namespace hwr::estimation
