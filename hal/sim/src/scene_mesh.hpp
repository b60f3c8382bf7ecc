#pragma once
// Triangle soup of a SceneSpec (private to hwr_sim): one shared vertex array, per-triangle
// material and object id (side arrays indexed by the Embree primID of the single mesh geometry),
// and a per-object table the shader and tests use. Also the validation of specs and the weld
// joint plates shared by the mesh builder and scene_ground_truth().

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "hwr/core/status.hpp"
#include "hwr/sim/scene_spec.hpp"

namespace hwr::sim::detail {

enum class ObjectKind : uint8_t { kGround, kWall, kCeiling, kBox, kBeam, kPipe, kPlate };

struct SceneObject {
  std::string name;  // "ground", "wall/+x", box/beam/pipe name, "<joint>/base", ...
  ObjectKind kind = ObjectKind::kBox;
  Material material = Material::kConcrete;
  // Pipes only: the cylinder axis (smooth shading normals are computed from it).
  Eigen::Vector3d axis_point_scene = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis_dir_scene = Eigen::Vector3d::UnitZ();
  double radius_m = 0.0;
};

struct SceneMesh {
  std::vector<Eigen::Vector3f> vertices_scene;
  std::vector<std::array<uint32_t, 3>> triangles;  // counter-clockwise seen from outside
  std::vector<Material> tri_material;
  std::vector<uint32_t> tri_object;  // index into objects
  std::vector<SceneObject> objects;
};

// Checks every size of the spec (positive, finite, consistent); the message names the object,
// e.g. "joint 'tee_1': thickness_m must be > 0 (got -0.01)".
core::Status validate_scene(const SceneSpec& scene);

// Meshes every primitive of a validated scene.
SceneMesh build_scene_mesh(const SceneSpec& scene);

// Segments of a cylinder tessellated as an inscribed regular polygon whose largest radial
// deviation r (1 - cos(pi / n)) stays below max_error_m.
int pipe_segment_count(double radius_m, double max_error_m);
constexpr double kPipeMaxErrorM = 0.0005;

// The plates of one joint (scene_truth.cpp), exactly as described in scene_spec.hpp.
void append_joint_plates(const WeldJointSpec& joint, std::vector<PlateTruth>* plates);
// A plate from its size and pose, corners filled in.
PlateTruth make_plate(std::string name, const Eigen::Vector3d& size_m,
                      const Eigen::Isometry3d& T_scene_plate);

}  // namespace hwr::sim::detail
