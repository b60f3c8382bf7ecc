// `hwr-bench sim-render`: single-thread 640x480 RGB-D rendering speed of the simulator on a
// representative welding workshop (room, boxes, I-beams, pipes, four weld joints) along a moving
// camera path. Acceptance: >= 60 frames/s on one core (RelWithDebInfo). `--scene=<preset>` runs a
// scenario preset (lab, outdoor, ...) along its own trajectory instead. `--area-sampling` renders the
// colour integrated over each pixel (sim::RenderOptions::area_sampling, five rays a pixel);
// `--shadows` casts the light's shadows (a shadow ray per lit hit) and `--ambient-occlusion=N` darkens
// nooks and gaps with N rays per hit (sim::RenderOptions::shadows, ambient_occlusion_rays).
//
// Also Google Benchmark micro-benchmarks (run with `hwr-bench micro --benchmark_filter=Sim`).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <memory>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <opencv2/core.hpp>

#include "bench_command.hpp"
#include "hwr/sim/camera_effects.hpp"
#include "hwr/sim/renderer.hpp"
#include "hwr/sim/scenario.hpp"
#include "hwr/sim/trajectory.hpp"

namespace hwr::bench {
namespace {

using sim::Material;

Eigen::Isometry3d pose(double x, double y, double z, double yaw_rad = 0.0) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

// The workshop: 20 m x 12 m x 4 m hall, clutter along the walls, a steel work area in the middle.
sim::SceneSpec workshop_scene() {
  sim::SceneSpec s;
  s.name = "bench_workshop";
  s.texture_seed = 7;
  const struct {
    double x, y, yaw, sx, sy, sz;
    Material m;
  } boxes[] = {
      {-7.5, -4.5, 0.1, 1.2, 0.8, 0.15, Material::kWood},
      {-7.5, -4.5, 0.1, 0.6, 0.4, 0.5, Material::kCardboard},
      {-5.0, 4.8, 0.0, 2.0, 0.8, 0.9, Material::kWood},
      {-2.0, 5.0, 0.3, 0.6, 0.6, 0.6, Material::kCardboard},
      {1.5, 4.6, -0.2, 0.8, 0.5, 0.4, Material::kCardboard},
      {6.0, 4.5, 0.0, 2.4, 1.0, 2.2, Material::kRustySteel},
      {8.0, -4.0, 0.5, 1.0, 1.0, 1.0, Material::kCardboard},
      {4.0, -4.8, 0.0, 1.2, 0.8, 0.15, Material::kWood},
      {-3.0, -4.7, 0.0, 3.0, 0.7, 0.9, Material::kWood},
      {0.0, 0.0, 0.0, 2.0, 1.0, 0.8, Material::kSteel},
  };
  int i = 0;
  for (const auto& b : boxes) {
    sim::BoxSpec box;
    box.name = "box" + std::to_string(i++);
    box.size_m = Eigen::Vector3d(b.sx, b.sy, b.sz);
    box.T_scene_box = pose(b.x, b.y, 0.5 * b.sz, b.yaw);
    box.material = b.m;
    s.boxes.push_back(box);
  }
  for (int k = 0; k < 3; ++k) {
    sim::IBeamSpec beam;
    beam.name = "beam" + std::to_string(k);
    beam.length_m = 4.0;
    beam.T_scene_beam = pose(-6.0 + 3.0 * k, -1.5 - 0.4 * k, 0.15, 0.05 * k);
    s.beams.push_back(beam);
  }
  for (int k = 0; k < 3; ++k) {
    sim::PipeSpec pipe;
    pipe.name = "pipe" + std::to_string(k);
    pipe.radius_m = 0.08 + 0.05 * k;
    pipe.length_m = 6.0;
    // Lying along x on supports near the +y wall, and one vertical riser.
    if (k < 2) {
      pipe.T_scene_pipe = pose(2.0 * k - 1.0, 3.0 + 0.6 * k, 1.2 + 0.5 * k);
      pipe.T_scene_pipe.linear() = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY()).toRotationMatrix();
    } else {
      pipe.length_m = 4.0;
      pipe.T_scene_pipe = pose(9.3, 5.3, 2.0);
    }
    s.pipes.push_back(pipe);
  }
  for (int k = 0; k < 4; ++k) {
    sim::WeldJointSpec j;
    j.name = "joint" + std::to_string(k);
    j.type = (k % 2 == 0) ? sim::WeldJointSpec::Type::kFillet : sim::WeldJointSpec::Type::kButt;
    // Two on the steel table (top at 0.8 m), two on the floor.
    const double z = (k < 2 ? 0.8 : 0.0) + j.thickness_m;
    j.T_scene_joint = pose(k < 2 ? -0.6 + 0.6 * k : 2.5 + 1.2 * (k - 2), k < 2 ? -0.1 : 1.5, z, 0.3 * k);
    s.joints.push_back(j);
  }
  return s;
}

hal::PinholeIntrinsics vga() {
  hal::PinholeIntrinsics K;
  K.width = 640;
  K.height = 480;
  K.fx = K.fy = 525.0;
  K.cx = 319.5;
  K.cy = 239.5;
  return K;
}

// Camera on an ellipse around the hall centre at 1.3-1.7 m, looking at a point that wanders over
// the work area (the robot walking around the weld site).
Eigen::Isometry3d camera_on_path(int i, int n) {
  const double s = 2.0 * M_PI * i / n;
  const Eigen::Vector3d eye(6.5 * std::cos(s), 3.5 * std::sin(s), 1.5 + 0.2 * std::sin(3 * s));
  const Eigen::Vector3d target(1.5 * std::cos(2 * s), 1.0 * std::sin(s), 0.6 + 0.3 * std::cos(s));
  const Eigen::Vector3d z = (target - eye).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = x;
  T.linear().col(1) = z.cross(x);
  T.linear().col(2) = z;
  T.translation() = eye;
  return T;
}

// CPU time of this thread: on a shared machine wall time also counts other processes' slices.
double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return 1e3 * static_cast<double>(ts.tv_sec) + 1e-6 * static_cast<double>(ts.tv_nsec);
}

// What one run renders: a scene and the camera poses of its frames.
struct Workload {
  sim::SceneSpec scene;
  hal::PinholeIntrinsics intrinsics;
  sim::RenderOptions options;
  std::vector<Eigen::Isometry3d> T_scene_cam;
};

core::Expected<Workload> make_workload(const std::string& name, int frames) {
  Workload w;
  if (name == "workshop") {
    w.scene = workshop_scene();
    w.intrinsics = vga();
    for (int i = 0; i < frames; ++i) w.T_scene_cam.push_back(camera_on_path(i, frames));
    return w;
  }
  auto scenario = sim::builtin_scenario(name);
  if (!scenario.ok()) return scenario.status();
  auto trajectory = sim::Trajectory::build(scenario->trajectory);
  if (!trajectory.ok()) return trajectory.status();
  w.scene = scenario->scene;
  w.intrinsics = scenario->camera.intrinsics;
  w.options = scenario->render;
  const Eigen::Isometry3d T_imu_cam = sim::camera_T_imu_cam(scenario->camera);
  for (int i = 0; i < frames; ++i) {
    const double t_s = trajectory->duration_s() * i / std::max(frames - 1, 1);
    w.T_scene_cam.push_back(trajectory->evaluate(t_s).T_scene_imu * T_imu_cam);
  }
  return w;
}

int run_sim_render(int argc, char** argv) {
  int frames = 300;
  int packet_width = 0;
  std::string scene = "workshop";
  bool area_sampling = false, shadows = false;
  int ambient_occlusion_rays = 0;
  for (int a = 1; a < argc; ++a) {
    if (std::strncmp(argv[a], "--frames=", 9) == 0) {
      frames = std::max(1, std::atoi(argv[a] + 9));
    } else if (std::strncmp(argv[a], "--packet=", 9) == 0) {
      packet_width = std::atoi(argv[a] + 9);
    } else if (std::strncmp(argv[a], "--scene=", 8) == 0) {
      scene = argv[a] + 8;
    } else if (std::strcmp(argv[a], "--area-sampling") == 0) {
      area_sampling = true;
    } else if (std::strcmp(argv[a], "--shadows") == 0) {
      shadows = true;
    } else if (std::strncmp(argv[a], "--ambient-occlusion=", 20) == 0) {
      ambient_occlusion_rays = std::atoi(argv[a] + 20);
      if (ambient_occlusion_rays < 1 || ambient_occlusion_rays > 64) {
        std::fprintf(stderr, "sim-render: --ambient-occlusion takes 1-64 rays\n");
        return 2;
      }
    } else {
      std::fprintf(stderr,
                   "sim-render: unknown argument '%s' (use --frames=N, --packet=0|1|4|8|16, "
                   "--scene=workshop|<scenario preset>, --area-sampling, --shadows, --ambient-occlusion=N)\n",
                   argv[a]);
      return 2;
    }
  }
  auto workload = make_workload(scene, frames);
  if (!workload.ok()) {
    std::fprintf(stderr, "sim-render: scene '%s': %s\n", scene.c_str(),
                 workload.status().to_string().c_str());
    return 2;
  }
  sim::RenderOptions options = workload->options;
  options.packet_width = packet_width;
  options.area_sampling = options.area_sampling || area_sampling;
  options.shadows = options.shadows || shadows;
  if (ambient_occlusion_rays > 0) options.ambient_occlusion_rays = ambient_occlusion_rays;

  const auto t_build0 = std::chrono::steady_clock::now();
  auto renderer = sim::Renderer::create(workload->scene);
  const auto t_build1 = std::chrono::steady_clock::now();
  if (!renderer.ok()) {
    std::fprintf(stderr, "sim-render: %s\n", renderer.status().to_string().c_str());
    return 1;
  }
  const hal::PinholeIntrinsics K = workload->intrinsics;
  cv::Mat bgr, depth;
  (*renderer)->render(workload->T_scene_cam[0], K, options, &bgr, &depth);  // warm-up, allocates

  std::vector<double> ms(frames);
  double valid_fraction = 0.0, cpu_ms = 0.0;
  for (int i = 0; i < frames; ++i) {
    const Eigen::Isometry3d& T_scene_cam = workload->T_scene_cam[i];
    const double c0 = thread_cpu_ms();
    const auto t0 = std::chrono::steady_clock::now();
    (*renderer)->render(T_scene_cam, K, options, &bgr, &depth);
    const auto t1 = std::chrono::steady_clock::now();
    cpu_ms += thread_cpu_ms() - c0;
    ms[i] = std::chrono::duration<double, std::milli>(t1 - t0).count();
    valid_fraction += cv::countNonZero(depth) / static_cast<double>(depth.total());
  }
  double mean = 0.0;
  for (const double m : ms) mean += m;
  mean /= frames;
  std::vector<double> sorted = ms;
  std::sort(sorted.begin(), sorted.end());
  const auto pct = [&](double p) {
    return sorted[std::min<size_t>(sorted.size() - 1, static_cast<size_t>(p * sorted.size()))];
  };
  const double fps = 1000.0 / mean;
  cpu_ms /= frames;
  const int width = options.packet_width == 0 ? (*renderer)->native_packet_width() : options.packet_width;

  std::printf(
      "sim-render: %dx%d RGB-D, one thread, packet width %d, %s scene, colour %s, %s, ambient "
      "occlusion %d rays\n",
      K.width, K.height, width, scene.c_str(),
      options.area_sampling ? "integrated over each pixel (5 rays)" : "at each pixel's centre",
      options.shadows ? "with the light's shadows" : "no shadows", options.ambient_occlusion_rays);
  std::printf("  scene build        %8.1f ms (meshes, BVH, textures)\n",
              std::chrono::duration<double, std::milli>(t_build1 - t_build0).count());
  std::printf("  %-8s %10s %9s %9s %9s %9s %10s %9s %8s\n", "frames", "triangles", "mean ms", "p50 ms",
              "p99 ms", "max ms", "fps", "cpu ms", "valid");
  std::printf("  %-8d %10zu %9.3f %9.3f %9.3f %9.3f %10.1f %9.3f %7.1f%%\n", frames,
              (*renderer)->triangle_count(), mean, pct(0.5), pct(0.99), sorted.back(), fps, cpu_ms,
              100.0 * valid_fraction / frames);
  std::printf("sim_render_area_sampling=%d\nsim_render_shadows=%d\nsim_render_ambient_occlusion_rays=%d\n",
              options.area_sampling ? 1 : 0, options.shadows ? 1 : 0, options.ambient_occlusion_rays);
  std::printf("sim_render_fps=%.1f\n", fps);
  std::printf("sim_render_ms_p99=%.3f\n", pct(0.99));
  std::printf("sim_render_cpu_fps=%.1f\n", 1000.0 / cpu_ms);
  return 0;
}

HWR_BENCH_COMMAND(sim_render, "sim-render",
                  "simulator 640x480 RGB-D render speed on one thread (--frames=N, --packet=W, --scene=S, "
                  "--area-sampling)",
                  run_sim_render);

// --- Google Benchmark micro-benchmarks -------------------------------------------------------

const sim::Renderer& bench_renderer() {
  static const std::unique_ptr<sim::Renderer> renderer = [] {
    auto r = sim::Renderer::create(workshop_scene());
    if (!r.ok()) {
      std::fprintf(stderr, "sim bench scene: %s\n", r.status().to_string().c_str());
      std::abort();
    }
    return std::move(r).value();
  }();
  return *renderer;
}

// One 640x480 frame; the argument is the packet width (0: native).
void BM_SimRender(benchmark::State& state) {
  const sim::Renderer& renderer = bench_renderer();
  sim::RenderOptions options;
  options.packet_width = static_cast<int>(state.range(0));
  cv::Mat bgr, depth;
  int i = 0;
  for (auto _ : state) {
    renderer.render(camera_on_path(i++ % 300, 300), vga(), options, &bgr, &depth);
    benchmark::DoNotOptimize(bgr.data);
  }
  state.SetItemsProcessed(state.iterations() * 640 * 480);
}
BENCHMARK(BM_SimRender)->Arg(0)->Arg(1)->Arg(4)->Arg(8)->Arg(16)->Unit(benchmark::kMillisecond);

void BM_SimDepthNoise(benchmark::State& state) {
  cv::Mat clean;
  bench_renderer().render(camera_on_path(0, 300), vga(), {}, nullptr, &clean);
  cv::Mat depth = clean.clone();
  sim::DepthNoiseSpec spec;
  spec.edge_dropout_ratio = 0.05;
  uint64_t seed = 0;
  for (auto _ : state) {
    clean.copyTo(depth);
    sim::apply_depth_noise(spec, seed++, &depth);
    benchmark::DoNotOptimize(depth.data);
  }
}
BENCHMARK(BM_SimDepthNoise)->Unit(benchmark::kMillisecond);

void BM_SimExposure(benchmark::State& state) {
  cv::Mat clean;
  bench_renderer().render(camera_on_path(0, 300), vga(), {}, &clean, nullptr);
  cv::Mat bgr = clean.clone();
  sim::ExposureSpec spec;
  spec.gain = 1.2;
  uint64_t seed = 0;
  for (auto _ : state) {
    clean.copyTo(bgr);
    sim::apply_exposure(spec, seed++, &bgr);
    benchmark::DoNotOptimize(bgr.data);
  }
}
BENCHMARK(BM_SimExposure)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace hwr::bench
