#pragma once
// Parametric welding-workshop scene, in the simulator's `scene` frame (z up, metres).
// Everything here is plain data: scenarios (scenario.hpp) fill it from built-in presets or YAML,
// the renderer (renderer.hpp) turns it into Embree geometry, and scene_ground_truth() turns the
// weld joints into exact plate corners and seam lines.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace hwr::sim {

// Surface appearance; each has its own procedural texture so ORB finds corners on it.
enum class Material : uint8_t {
  kConcrete = 0,  // floor, outdoor ground
  kPaintedWall,   // walls, facades
  kSteel,         // plates (bright, brushed)
  kRustySteel,    // beams, containers
  kWood,          // pallets, benches
  kCardboard,     // clutter boxes
  kPipe,          // painted pipes
  kCount
};

// Axis-aligned box in its own frame, centred at the origin, placed by T_scene_box.
struct BoxSpec {
  std::string name;
  Eigen::Vector3d size_m = Eigen::Vector3d::Ones();
  Eigen::Isometry3d T_scene_box = Eigen::Isometry3d::Identity();
  Material material = Material::kCardboard;
};

// I-beam lying along its local x axis; local z is the web direction (height). Centred at origin.
struct IBeamSpec {
  std::string name;
  double length_m = 3.0;
  double height_m = 0.3;
  double flange_width_m = 0.15;
  double web_thickness_m = 0.01;
  double flange_thickness_m = 0.015;
  Eigen::Isometry3d T_scene_beam = Eigen::Isometry3d::Identity();
  Material material = Material::kRustySteel;
};

// Cylinder along its local z axis, centred at the origin.
struct PipeSpec {
  std::string name;
  double radius_m = 0.1;
  double length_m = 2.0;
  Eigen::Isometry3d T_scene_pipe = Eigen::Isometry3d::Identity();
  Material material = Material::kPipe;
};

// Two steel plates to be welded, of exactly known size.
//  kFillet: base plate lying in the joint frame's xy plane (top face at z = 0, spanning
//           x in [0, length], y in [-base_width, 0]); web plate standing on it along the seam
//           (spanning x in [0, length], its face at y = 0 towards -y, rising to z = web_width).
//           The seam is the line from (0,0,0) to (length,0,0) in the joint frame.
//  kButt:   two plates lying in the xy plane (top faces at z = 0) side by side, separated by
//           gap_m along y around y = 0; the seam is the centre line of the gap on the top face.
// The joint frame is placed in the scene by T_scene_joint.
struct WeldJointSpec {
  enum class Type : uint8_t { kFillet, kButt };
  std::string name;
  Type type = Type::kFillet;
  double length_m = 0.6;      // along the seam
  double base_width_m = 0.3;  // fillet: base plate width; butt: width of each plate
  double web_width_m = 0.2;   // fillet: web plate height; unused for butt
  double thickness_m = 0.01;  // plate thickness
  double gap_m = 0.002;       // butt joint root gap
  Eigen::Isometry3d T_scene_joint = Eigen::Isometry3d::Identity();
};

struct SceneSpec {
  std::string name;
  uint64_t texture_seed = 1;
  // Ground plane z = 0 covering [-extent, extent] in x and y.
  double ground_extent_m = 30.0;
  Material ground_material = Material::kConcrete;
  // Optional closed room around the origin (indoor scenes): walls from z = 0 to room_height.
  bool has_room = true;
  Eigen::Vector2d room_min_xy{-10.0, -6.0};
  Eigen::Vector2d room_max_xy{10.0, 6.0};
  double room_height_m = 4.0;

  std::vector<BoxSpec> boxes;
  std::vector<IBeamSpec> beams;
  std::vector<PipeSpec> pipes;
  std::vector<WeldJointSpec> joints;
};

// Exact ground truth of the welding work pieces, in the scene frame.
struct PlateTruth {
  std::string name;                 // "<joint>/base", "<joint>/web", "<joint>/left", ...
  Eigen::Vector3d size_m;           // length, width, thickness
  Eigen::Isometry3d T_scene_plate;  // plate frame: centred box, x length, y width, z thickness
  // Box corners in the scene frame. Corner i sits at local (sx*L/2, sy*W/2, sz*T/2) with
  // sx = bit 2 of i, sy = bit 1, sz = bit 0 (bit set: +, clear: -).
  std::array<Eigen::Vector3d, 8> corners_scene;
};

struct SeamTruth {
  std::string name;  // joint name
  WeldJointSpec::Type type = WeldJointSpec::Type::kFillet;
  Eigen::Vector3d start_scene;
  Eigen::Vector3d end_scene;
  std::string plate_a;
  std::string plate_b;
};

struct SceneGroundTruth {
  std::vector<PlateTruth> plates;
  std::vector<SeamTruth> seams;
};

}  // namespace hwr::sim
