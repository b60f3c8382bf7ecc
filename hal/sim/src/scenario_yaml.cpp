// Scenario <-> YAML. Reading merges a file over a preset (`base:`): every key present replaces the
// field, nested maps merge, lists replace as a whole. Everything goes through core::ConfigMap, so
// unknown keys and wrong types come back as "file:line: key 'a.b.c': ..." errors.

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "hwr/core/config.hpp"
#include "hwr/sim/scenario.hpp"
#include "sim_text.hpp"

namespace hwr::sim {
namespace {

using core::ConfigMap;

constexpr double kDeg = M_PI / 180.0;

// ------------------------------------------------------------------------------- names of enums
constexpr const char* kMaterialNames[] = {"concrete", "painted_wall", "steel", "rusty_steel",
                                          "wood",     "cardboard",    "pipe"};
static_assert(sizeof(kMaterialNames) / sizeof(kMaterialNames[0]) == static_cast<size_t>(Material::kCount));

std::string material_list() {
  std::string s;
  for (const char* n : kMaterialNames) s += (s.empty() ? "" : ", ") + std::string(n);
  return s;
}

// ------------------------------------------------------------------------------- rotations
Eigen::Matrix3d rotation_from_rpy_deg(const Eigen::Vector3d& rpy) {
  return (Eigen::AngleAxisd(rpy.z() * kDeg, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(rpy.y() * kDeg, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(rpy.x() * kDeg, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

// Snaps values within 1e-9 deg of a multiple of 1e-6 deg, so 90.00000000000001 prints as 90.
double tidy_deg(double d) {
  const double r = std::round(d * 1e6) / 1e6;
  return std::abs(r - d) < 1e-9 ? r : d;
}

// R = Rz(yaw) Ry(pitch) Rx(roll); at pitch = +-90 deg roll is set to 0 and yaw absorbs it.
Eigen::Vector3d rpy_deg_from_rotation(const Eigen::Matrix3d& R) {
  double roll, pitch, yaw;
  if (std::abs(R(2, 0)) > 1.0 - 1e-12) {
    pitch = R(2, 0) < 0 ? M_PI / 2 : -M_PI / 2;
    roll = 0.0;
    yaw = std::atan2(-R(0, 1), R(1, 1));
  } else {
    pitch = std::asin(-R(2, 0));
    roll = std::atan2(R(2, 1), R(2, 2));
    yaw = std::atan2(R(1, 0), R(0, 0));
  }
  return {tidy_deg(roll / kDeg), tidy_deg(pitch / kDeg), tidy_deg(yaw / kDeg)};
}

// ------------------------------------------------------------------------------- reading
void read_pose(ConfigMap& m, Eigen::Isometry3d* T) {
  Eigen::Vector3d p = T->translation();
  m.get("position_m", &p);
  T->translation() = p;
  if (m.has("rpy_deg")) {
    Eigen::Vector3d rpy = rpy_deg_from_rotation(T->linear());
    m.get("rpy_deg", &rpy);
    T->linear() = rotation_from_rpy_deg(rpy);
  }
}

void read_material(ConfigMap& m, const char* key, Material* out) {
  if (!m.has(key)) return;
  const std::string sentinel = "\x01";
  std::string name = sentinel;
  m.get(key, &name);
  if (name == sentinel) return;  // type error already recorded
  for (size_t i = 0; i < static_cast<size_t>(Material::kCount); ++i) {
    if (name == kMaterialNames[i]) {
      *out = static_cast<Material>(i);
      return;
    }
  }
  m.record_error(key, "expected one of " + material_list() + ", got '" + name + "'");
}

void read_joint_type(ConfigMap& m, WeldJointSpec::Type* out) {
  if (!m.has("type")) return;
  const std::string sentinel = "\x01";
  std::string name = sentinel;
  m.get("type", &name);
  if (name == sentinel) return;
  if (name == "fillet") {
    *out = WeldJointSpec::Type::kFillet;
  } else if (name == "butt") {
    *out = WeldJointSpec::Type::kButt;
  } else {
    m.record_error("type", "expected fillet or butt, got '" + name + "'");
  }
}

void read_scene(ConfigMap m, SceneSpec* s) {
  m.get("name", &s->name).get("texture_seed", &s->texture_seed).get("ground_extent_m", &s->ground_extent_m);
  read_material(m, "ground_material", &s->ground_material);
  m.get("has_room", &s->has_room).get("room_min_xy", &s->room_min_xy).get("room_max_xy", &s->room_max_xy);
  m.get("room_height_m", &s->room_height_m);
  if (m.has("boxes")) {
    s->boxes.clear();
    for (ConfigMap& b : m.list("boxes")) {
      BoxSpec box;
      b.require("name", &box.name).get("size_m", &box.size_m);
      read_pose(b, &box.T_scene_box);
      read_material(b, "material", &box.material);
      s->boxes.push_back(box);
    }
  }
  if (m.has("beams")) {
    s->beams.clear();
    for (ConfigMap& b : m.list("beams")) {
      IBeamSpec beam;
      b.require("name", &beam.name).get("length_m", &beam.length_m).get("height_m", &beam.height_m);
      b.get("flange_width_m", &beam.flange_width_m).get("web_thickness_m", &beam.web_thickness_m);
      b.get("flange_thickness_m", &beam.flange_thickness_m);
      read_pose(b, &beam.T_scene_beam);
      read_material(b, "material", &beam.material);
      s->beams.push_back(beam);
    }
  }
  if (m.has("pipes")) {
    s->pipes.clear();
    for (ConfigMap& b : m.list("pipes")) {
      PipeSpec pipe;
      b.require("name", &pipe.name).get("radius_m", &pipe.radius_m).get("length_m", &pipe.length_m);
      read_pose(b, &pipe.T_scene_pipe);
      read_material(b, "material", &pipe.material);
      s->pipes.push_back(pipe);
    }
  }
  if (m.has("joints")) {
    s->joints.clear();
    for (ConfigMap& b : m.list("joints")) {
      WeldJointSpec j;
      b.require("name", &j.name);
      read_joint_type(b, &j.type);
      b.get("length_m", &j.length_m).get("base_width_m", &j.base_width_m).get("web_width_m", &j.web_width_m);
      b.get("thickness_m", &j.thickness_m).get("gap_m", &j.gap_m);
      read_pose(b, &j.T_scene_joint);
      s->joints.push_back(j);
    }
  }
}

void read_trajectory(ConfigMap m, TrajectorySpec* t) {
  m.get("cruise_speed_mps", &t->cruise_speed_mps).get("ramp_time_s", &t->ramp_time_s);
  m.get("turn_rate_radps", &t->turn_rate_radps).get("min_turn_time_s", &t->min_turn_time_s);
  m.get("imu_height_m", &t->imu_height_m).get("bob_m_per_mps", &t->bob_m_per_mps);
  m.get("roll_rad_per_mps", &t->roll_rad_per_mps).get("step_length_m", &t->step_length_m);
  if (m.has("waypoints")) {
    t->waypoints.clear();
    for (ConfigMap& w : m.list("waypoints")) {
      Waypoint wp;
      w.require("xy_m", &wp.xy_m).get("dwell_s", &wp.dwell_s);
      wp.has_look_at = w.has("look_at_xy_m");
      w.get("look_at_xy_m", &wp.look_at_xy_m);
      t->waypoints.push_back(wp);
    }
  }
}

void read_camera(ConfigMap m, CameraSpec* c) {
  hal::PinholeIntrinsics& k = c->intrinsics;
  m.get("width", &k.width).get("height", &k.height).get("fx", &k.fx).get("fy", &k.fy).get("cx", &k.cx);
  m.get("cy", &k.cy).get("rate_hz", &c->rate_hz).get("depth_scale", &c->depth_scale);
  ConfigMap mount = m.child("mount");
  mount.get("t_imu_cam_m", &c->t_imu_cam_m).get("pitch_down_deg", &c->pitch_down_deg);
  mount.get("yaw_left_deg", &c->yaw_left_deg).get("roll_deg", &c->roll_deg);
  ConfigMap stereo = m.child("stereo");
  stereo.get("enabled", &c->stereo).get("baseline_m", &c->baseline_m);
}

void read_depth_noise(ConfigMap m, DepthNoiseSpec* d) {
  m.get("enabled", &d->enabled)
      .get("sigma_const_m", &d->sigma_const_m)
      .get("sigma_quad_per_m", &d->sigma_quad_per_m);
  m.get("hole_fraction", &d->hole_fraction).get("hole_radius_px", &d->hole_radius_px);
  m.get("edge_dropout_ratio", &d->edge_dropout_ratio);
}

void read_exposure(ConfigMap m, ExposureSpec* e, std::vector<ExposureEvent>* events) {
  m.get("gain", &e->gain).get("pixel_noise_sigma", &e->pixel_noise_sigma);
  if (m.has("events")) {
    events->clear();
    for (ConfigMap& ev : m.list("events")) {
      ExposureEvent x;
      ev.require("time_s", &x.time_s).require("gain", &x.gain);
      events->push_back(x);
    }
  }
}

void read_render(ConfigMap m, RenderOptions* r) {
  m.get("max_range_m", &r->max_range_m).get("min_range_m", &r->min_range_m);
  m.get("light_dir_scene", &r->light_dir_scene).get("ambient", &r->ambient);
  m.get("area_sampling", &r->area_sampling);
  m.get("shadows", &r->shadows).get("shadow_range_m", &r->shadow_range_m);
  m.get("ambient_occlusion_rays", &r->ambient_occlusion_rays);
  m.get("ambient_occlusion_range_m", &r->ambient_occlusion_range_m);
}

void read_imu(ConfigMap m, ImuSpec* s) {
  m.get("rate_hz", &s->rate_hz).get("gravity_mps2", &s->gravity_mps2);
  ConfigMap n = m.child("noise");
  ImuNoiseSpec& z = s->noise;
  n.get("enabled", &z.enabled).get("gyro_noise_density", &z.gyro_noise_density);
  n.get("accel_noise_density", &z.accel_noise_density).get("gyro_random_walk", &z.gyro_random_walk);
  n.get("accel_random_walk", &z.accel_random_walk).get("gyro_bias_initial_radps", &z.gyro_bias_initial_radps);
  n.get("accel_bias_initial_mps2", &z.accel_bias_initial_mps2);
}

void read_mag(ConfigMap m, MagSpec* s) {
  m.get("enabled", &s->enabled)
      .get("rate_hz", &s->rate_hz)
      .get("earth_field_scene_uT", &s->earth_field_scene_uT);
  m.get("hard_iron_uT", &s->hard_iron_uT).get("noise_enabled", &s->noise_enabled);
  m.get("noise_sigma_uT", &s->noise_sigma_uT);
  ConfigMap d = m.child("disturbance");
  MagDisturbanceSpec& x = s->disturbance;
  d.get("enabled", &x.enabled)
      .get("moment_per_m_uT_m3", &x.moment_per_m_uT_m3)
      .get("spacing_m", &x.spacing_m);
  d.get("min_distance_m", &x.min_distance_m).get("cutoff_begin_m", &x.cutoff_begin_m);
  d.get("cutoff_end_m", &x.cutoff_end_m).get("remanent_fraction", &x.remanent_fraction);
}

void read_gnss(ConfigMap m, GnssSpec* s) {
  m.get("enabled", &s->enabled).get("rate_hz", &s->rate_hz);
  ConfigMap o = m.child("origin");
  o.get("lat_deg", &s->origin.lat_deg)
      .get("lon_deg", &s->origin.lon_deg)
      .get("height_m", &s->origin.height_m);
  m.get("antenna_imu_m", &s->antenna_imu_m).get("noise_enabled", &s->noise_enabled);
  m.get("sigma_h_m", &s->sigma_h_m).get("sigma_v_m", &s->sigma_v_m);
  m.get("correlated_fraction", &s->correlated_fraction).get("correlation_time_s", &s->correlation_time_s);
  if (m.has("dropouts")) {
    s->dropouts.clear();
    for (ConfigMap& d : m.list("dropouts")) {
      GnssDropout x;
      d.require("start_s", &x.start_s).require("end_s", &x.end_s);
      s->dropouts.push_back(x);
    }
  }
  m.get("random_dropouts_per_min", &s->random_dropouts_per_min);
  m.get("random_dropout_min_s", &s->random_dropout_min_s)
      .get("random_dropout_max_s", &s->random_dropout_max_s);
  m.get("num_sv_min", &s->num_sv_min).get("num_sv_max", &s->num_sv_max);
}

core::Expected<ScenarioSpec> parse_impl(const std::string& text, const std::string& source,
                                        const std::string& default_name) {
  auto doc = core::ConfigDocument::parse(text, source);
  if (!doc.ok()) return doc.status();
  ConfigMap root = doc->root();
  ScenarioSpec spec;
  std::string base;
  root.get("base", &base);
  if (!base.empty()) {
    auto preset = builtin_scenario(base);
    if (!preset.ok()) {
      root.record_error("base", preset.status().message());
    } else {
      spec = std::move(preset.value());
    }
  }
  spec.base = base;
  if (!default_name.empty()) spec.name = default_name;
  root.get("name", &spec.name).get("seed", &spec.seed).get("start_time_ns", &spec.start_time_ns);
  root.get("duration_s", &spec.duration_s);
  read_scene(root.child("scene"), &spec.scene);
  read_trajectory(root.child("trajectory"), &spec.trajectory);
  read_camera(root.child("camera"), &spec.camera);
  read_depth_noise(root.child("depth_noise"), &spec.depth_noise);
  read_exposure(root.child("exposure"), &spec.exposure, &spec.exposure_events);
  read_render(root.child("render"), &spec.render);
  read_imu(root.child("imu"), &spec.imu);
  read_mag(root.child("mag"), &spec.mag);
  read_gnss(root.child("gnss"), &spec.gnss);
  HWR_RETURN_IF_ERROR(doc->finish());
  const core::Status st = validate_scenario(spec);
  if (!st.ok()) return core::InvalidArgument(source + ": " + st.message());
  return spec;
}

// ------------------------------------------------------------------------------- writing
using text::num;
using text::quoted;
std::string vec(const Eigen::Vector2d& v) { return text::list(v); }
std::string vec(const Eigen::Vector3d& v) { return text::list(v); }
std::string boolean(bool b) { return b ? "true" : "false"; }

class Emitter {
 public:
  void kv(int indent, const std::string& key, const std::string& value) {
    out_ += std::string(indent, ' ') + key + ": " + value + "\n";
  }
  void map(int indent, const std::string& key) { out_ += std::string(indent, ' ') + key + ":\n"; }
  void item(int indent, const std::string& key, const std::string& value) {
    out_ += std::string(indent, ' ') + "- " + key + ": " + value + "\n";
  }
  void line(const std::string& s) { out_ += s + "\n"; }
  std::string str() const { return out_; }

 private:
  std::string out_;
};

void emit_pose(Emitter* e, int indent, const Eigen::Isometry3d& T) {
  e->kv(indent, "position_m", vec(Eigen::Vector3d(T.translation())));
  e->kv(indent, "rpy_deg", vec(rpy_deg_from_rotation(T.linear())));
}

}  // namespace

core::Expected<ScenarioSpec> parse_scenario_yaml(const std::string& yaml_text,
                                                 const std::string& source_name) {
  return parse_impl(yaml_text, source_name, "");
}

core::Expected<ScenarioSpec> load_scenario_file(const std::string& path) {
  std::string yaml;
  const core::Status st = text::read_file(path, &yaml);
  if (!st.ok()) return core::NotFound(path + ": cannot open scenario file");
  // A file without `name:` is named after itself ("scenarios/lab_fast.yaml" -> "lab_fast").
  std::string stem = path.substr(path.find_last_of('/') + 1);
  stem = stem.substr(0, stem.find_last_of('.'));
  return parse_impl(yaml, path, stem);
}

core::Expected<ScenarioSpec> load_scenario(const std::string& name_or_path) {
  const auto ends_with = [&](const char* suffix) {
    const std::string s(suffix);
    return name_or_path.size() >= s.size() &&
           name_or_path.compare(name_or_path.size() - s.size(), s.size(), s) == 0;
  };
  if (ends_with(".yaml") || ends_with(".yml") || name_or_path.find('/') != std::string::npos) {
    return load_scenario_file(name_or_path);
  }
  return builtin_scenario(name_or_path);
}

std::string scenario_to_yaml(const ScenarioSpec& s) {
  Emitter e;
  e.line("# hwr-sim scenario: every effective parameter (load with hwr-sim --scenario <this file>).");
  e.line("# Frames: scene = ENU (x east, y north, z up); rpy_deg = [roll, pitch, yaw], R = Rz Ry Rx.");
  if (!s.base.empty()) e.kv(0, "base", quoted(s.base));
  e.kv(0, "name", quoted(s.name));
  e.kv(0, "seed", std::to_string(s.seed));
  e.kv(0, "start_time_ns", std::to_string(s.start_time_ns));
  e.kv(0, "duration_s", num(s.duration_s));

  const SceneSpec& sc = s.scene;
  e.map(0, "scene");
  e.kv(2, "name", quoted(sc.name));
  e.kv(2, "texture_seed", std::to_string(sc.texture_seed));
  e.kv(2, "ground_extent_m", num(sc.ground_extent_m));
  e.kv(2, "ground_material", kMaterialNames[static_cast<size_t>(sc.ground_material)]);
  e.kv(2, "has_room", boolean(sc.has_room));
  e.kv(2, "room_min_xy", vec(sc.room_min_xy));
  e.kv(2, "room_max_xy", vec(sc.room_max_xy));
  e.kv(2, "room_height_m", num(sc.room_height_m));
  if (sc.boxes.empty()) e.kv(2, "boxes", "[]");
  if (!sc.boxes.empty()) e.map(2, "boxes");
  for (const BoxSpec& b : sc.boxes) {
    e.item(2, "name", quoted(b.name));
    e.kv(4, "size_m", vec(b.size_m));
    emit_pose(&e, 4, b.T_scene_box);
    e.kv(4, "material", kMaterialNames[static_cast<size_t>(b.material)]);
  }
  if (sc.beams.empty()) e.kv(2, "beams", "[]");
  if (!sc.beams.empty()) e.map(2, "beams");
  for (const IBeamSpec& b : sc.beams) {
    e.item(2, "name", quoted(b.name));
    e.kv(4, "length_m", num(b.length_m));
    e.kv(4, "height_m", num(b.height_m));
    e.kv(4, "flange_width_m", num(b.flange_width_m));
    e.kv(4, "web_thickness_m", num(b.web_thickness_m));
    e.kv(4, "flange_thickness_m", num(b.flange_thickness_m));
    emit_pose(&e, 4, b.T_scene_beam);
    e.kv(4, "material", kMaterialNames[static_cast<size_t>(b.material)]);
  }
  if (sc.pipes.empty()) e.kv(2, "pipes", "[]");
  if (!sc.pipes.empty()) e.map(2, "pipes");
  for (const PipeSpec& p : sc.pipes) {
    e.item(2, "name", quoted(p.name));
    e.kv(4, "radius_m", num(p.radius_m));
    e.kv(4, "length_m", num(p.length_m));
    emit_pose(&e, 4, p.T_scene_pipe);
    e.kv(4, "material", kMaterialNames[static_cast<size_t>(p.material)]);
  }
  if (sc.joints.empty()) e.kv(2, "joints", "[]");
  if (!sc.joints.empty()) e.map(2, "joints");
  for (const WeldJointSpec& j : sc.joints) {
    e.item(2, "name", quoted(j.name));
    e.kv(4, "type", j.type == WeldJointSpec::Type::kFillet ? "fillet" : "butt");
    e.kv(4, "length_m", num(j.length_m));
    e.kv(4, "base_width_m", num(j.base_width_m));
    e.kv(4, "web_width_m", num(j.web_width_m));
    e.kv(4, "thickness_m", num(j.thickness_m));
    e.kv(4, "gap_m", num(j.gap_m));
    emit_pose(&e, 4, j.T_scene_joint);
  }

  const TrajectorySpec& t = s.trajectory;
  e.map(0, "trajectory");
  e.kv(2, "cruise_speed_mps", num(t.cruise_speed_mps));
  e.kv(2, "ramp_time_s", num(t.ramp_time_s));
  e.kv(2, "turn_rate_radps", num(t.turn_rate_radps));
  e.kv(2, "min_turn_time_s", num(t.min_turn_time_s));
  e.kv(2, "imu_height_m", num(t.imu_height_m));
  e.kv(2, "bob_m_per_mps", num(t.bob_m_per_mps));
  e.kv(2, "roll_rad_per_mps", num(t.roll_rad_per_mps));
  e.kv(2, "step_length_m", num(t.step_length_m));
  if (t.waypoints.empty()) e.kv(2, "waypoints", "[]");
  if (!t.waypoints.empty()) e.map(2, "waypoints");
  for (const Waypoint& w : t.waypoints) {
    std::string item = "{xy_m: " + vec(w.xy_m);
    if (w.dwell_s != 0.0) item += ", dwell_s: " + num(w.dwell_s);
    if (w.has_look_at) item += ", look_at_xy_m: " + vec(w.look_at_xy_m);
    e.line("    - " + item + "}");
  }

  const CameraSpec& c = s.camera;
  e.map(0, "camera");
  e.kv(2, "width", std::to_string(c.intrinsics.width));
  e.kv(2, "height", std::to_string(c.intrinsics.height));
  e.kv(2, "fx", num(c.intrinsics.fx));
  e.kv(2, "fy", num(c.intrinsics.fy));
  e.kv(2, "cx", num(c.intrinsics.cx));
  e.kv(2, "cy", num(c.intrinsics.cy));
  e.kv(2, "rate_hz", num(c.rate_hz));
  e.kv(2, "depth_scale", num(c.depth_scale));
  e.map(2, "mount");
  e.kv(4, "t_imu_cam_m", vec(c.t_imu_cam_m));
  e.kv(4, "pitch_down_deg", num(c.pitch_down_deg));
  e.kv(4, "yaw_left_deg", num(c.yaw_left_deg));
  e.kv(4, "roll_deg", num(c.roll_deg));
  e.map(2, "stereo");
  e.kv(4, "enabled", boolean(c.stereo));
  e.kv(4, "baseline_m", num(c.baseline_m));

  const DepthNoiseSpec& d = s.depth_noise;
  e.map(0, "depth_noise");
  e.kv(2, "enabled", boolean(d.enabled));
  e.kv(2, "sigma_const_m", num(d.sigma_const_m));
  e.kv(2, "sigma_quad_per_m", num(d.sigma_quad_per_m));
  e.kv(2, "hole_fraction", num(d.hole_fraction));
  e.kv(2, "hole_radius_px", std::to_string(d.hole_radius_px));
  e.kv(2, "edge_dropout_ratio", num(d.edge_dropout_ratio));

  e.map(0, "exposure");
  e.kv(2, "gain", num(s.exposure.gain));
  e.kv(2, "pixel_noise_sigma", num(s.exposure.pixel_noise_sigma));
  if (s.exposure_events.empty()) e.kv(2, "events", "[]");
  if (!s.exposure_events.empty()) e.map(2, "events");
  for (const ExposureEvent& ev : s.exposure_events) {
    e.line("    - {time_s: " + num(ev.time_s) + ", gain: " + num(ev.gain) + "}");
  }

  e.map(0, "render");
  e.kv(2, "max_range_m", num(s.render.max_range_m));
  e.kv(2, "min_range_m", num(s.render.min_range_m));
  e.kv(2, "light_dir_scene", vec(s.render.light_dir_scene));
  e.kv(2, "ambient", num(s.render.ambient));
  e.kv(2, "area_sampling", boolean(s.render.area_sampling));
  e.kv(2, "shadows", boolean(s.render.shadows));
  e.kv(2, "shadow_range_m", num(s.render.shadow_range_m));
  e.kv(2, "ambient_occlusion_rays", std::to_string(s.render.ambient_occlusion_rays));
  e.kv(2, "ambient_occlusion_range_m", num(s.render.ambient_occlusion_range_m));

  const ImuNoiseSpec& n = s.imu.noise;
  e.map(0, "imu");
  e.kv(2, "rate_hz", num(s.imu.rate_hz));
  e.kv(2, "gravity_mps2", num(s.imu.gravity_mps2));
  e.map(2, "noise");
  e.kv(4, "enabled", boolean(n.enabled));
  e.kv(4, "gyro_noise_density", num(n.gyro_noise_density));
  e.kv(4, "accel_noise_density", num(n.accel_noise_density));
  e.kv(4, "gyro_random_walk", num(n.gyro_random_walk));
  e.kv(4, "accel_random_walk", num(n.accel_random_walk));
  e.kv(4, "gyro_bias_initial_radps", vec(n.gyro_bias_initial_radps));
  e.kv(4, "accel_bias_initial_mps2", vec(n.accel_bias_initial_mps2));

  const MagSpec& m = s.mag;
  e.map(0, "mag");
  e.kv(2, "enabled", boolean(m.enabled));
  e.kv(2, "rate_hz", num(m.rate_hz));
  e.kv(2, "earth_field_scene_uT", vec(m.earth_field_scene_uT));
  e.kv(2, "hard_iron_uT", vec(m.hard_iron_uT));
  e.kv(2, "noise_enabled", boolean(m.noise_enabled));
  e.kv(2, "noise_sigma_uT", num(m.noise_sigma_uT));
  e.map(2, "disturbance");
  e.kv(4, "enabled", boolean(m.disturbance.enabled));
  e.kv(4, "moment_per_m_uT_m3", num(m.disturbance.moment_per_m_uT_m3));
  e.kv(4, "spacing_m", num(m.disturbance.spacing_m));
  e.kv(4, "min_distance_m", num(m.disturbance.min_distance_m));
  e.kv(4, "cutoff_begin_m", num(m.disturbance.cutoff_begin_m));
  e.kv(4, "cutoff_end_m", num(m.disturbance.cutoff_end_m));
  e.kv(4, "remanent_fraction", num(m.disturbance.remanent_fraction));

  const GnssSpec& g = s.gnss;
  e.map(0, "gnss");
  e.kv(2, "enabled", boolean(g.enabled));
  e.kv(2, "rate_hz", num(g.rate_hz));
  e.map(2, "origin");
  e.kv(4, "lat_deg", num(g.origin.lat_deg));
  e.kv(4, "lon_deg", num(g.origin.lon_deg));
  e.kv(4, "height_m", num(g.origin.height_m));
  e.kv(2, "antenna_imu_m", vec(g.antenna_imu_m));
  e.kv(2, "noise_enabled", boolean(g.noise_enabled));
  e.kv(2, "sigma_h_m", num(g.sigma_h_m));
  e.kv(2, "sigma_v_m", num(g.sigma_v_m));
  e.kv(2, "correlated_fraction", num(g.correlated_fraction));
  e.kv(2, "correlation_time_s", num(g.correlation_time_s));
  if (g.dropouts.empty()) e.kv(2, "dropouts", "[]");
  if (!g.dropouts.empty()) e.map(2, "dropouts");
  for (const GnssDropout& dr : g.dropouts) {
    e.line("    - {start_s: " + num(dr.start_s) + ", end_s: " + num(dr.end_s) + "}");
  }
  e.kv(2, "random_dropouts_per_min", num(g.random_dropouts_per_min));
  e.kv(2, "random_dropout_min_s", num(g.random_dropout_min_s));
  e.kv(2, "random_dropout_max_s", num(g.random_dropout_max_s));
  e.kv(2, "num_sv_min", std::to_string(g.num_sv_min));
  e.kv(2, "num_sv_max", std::to_string(g.num_sv_max));
  return e.str();
}

}  // namespace hwr::sim
