// Exact weld-joint ground truth: the plates as boxes and the seam line, from the joint geometry
// described in scene_spec.hpp. The renderer meshes the very same plates, so what the camera sees
// is what this file reports.

#include <utility>

#include "hwr/sim/renderer.hpp"
#include "scene_mesh.hpp"

namespace hwr::sim {
namespace detail {

PlateTruth make_plate(std::string name, const Eigen::Vector3d& size_m,
                      const Eigen::Isometry3d& T_scene_plate) {
  PlateTruth plate;
  plate.name = std::move(name);
  plate.size_m = size_m;
  plate.T_scene_plate = T_scene_plate;
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3d sign((i & 4) ? 1.0 : -1.0, (i & 2) ? 1.0 : -1.0, (i & 1) ? 1.0 : -1.0);
    plate.corners_scene[i] = T_scene_plate * (0.5 * sign.cwiseProduct(size_m));
  }
  return plate;
}

void append_joint_plates(const WeldJointSpec& joint, std::vector<PlateTruth>* plates) {
  const double L = joint.length_m;
  const double t = joint.thickness_m;
  const double bw = joint.base_width_m;
  Eigen::Isometry3d T_joint_plate = Eigen::Isometry3d::Identity();
  if (joint.type == WeldJointSpec::Type::kFillet) {
    // Base: x in [0, L], y in [-bw, 0], z in [-t, 0]; plate axes = joint axes.
    T_joint_plate.translation() = Eigen::Vector3d(0.5 * L, -0.5 * bw, -0.5 * t);
    plates->push_back(make_plate(joint.name + "/base", {L, bw, t}, joint.T_scene_joint * T_joint_plate));
    // Web: x in [0, L], y in [0, t], z in [0, web_width]. Plate axes x = x_joint, y = z_joint
    // (width runs up), z = -y_joint, so the plate's +z face is the y = 0 face towards the seam.
    const double ww = joint.web_width_m;
    T_joint_plate.linear() << 1, 0, 0,  //
        0, 0, -1,                       //
        0, 1, 0;
    T_joint_plate.translation() = Eigen::Vector3d(0.5 * L, 0.5 * t, 0.5 * ww);
    plates->push_back(make_plate(joint.name + "/web", {L, ww, t}, joint.T_scene_joint * T_joint_plate));
  } else {
    // Butt: "left" at +y (joint x forward, z up), "right" at -y, the gap centred on y = 0.
    const double y_c = 0.5 * joint.gap_m + 0.5 * bw;
    T_joint_plate.translation() = Eigen::Vector3d(0.5 * L, y_c, -0.5 * t);
    plates->push_back(make_plate(joint.name + "/left", {L, bw, t}, joint.T_scene_joint * T_joint_plate));
    T_joint_plate.translation() = Eigen::Vector3d(0.5 * L, -y_c, -0.5 * t);
    plates->push_back(make_plate(joint.name + "/right", {L, bw, t}, joint.T_scene_joint * T_joint_plate));
  }
}

}  // namespace detail

SceneGroundTruth scene_ground_truth(const SceneSpec& scene) {
  SceneGroundTruth truth;
  truth.plates.reserve(2 * scene.joints.size());
  truth.seams.reserve(scene.joints.size());
  for (const WeldJointSpec& joint : scene.joints) {
    const size_t first = truth.plates.size();
    detail::append_joint_plates(joint, &truth.plates);
    SeamTruth seam;
    seam.name = joint.name;
    seam.type = joint.type;
    seam.start_scene = joint.T_scene_joint * Eigen::Vector3d::Zero();
    seam.end_scene = joint.T_scene_joint * Eigen::Vector3d(joint.length_m, 0.0, 0.0);
    seam.plate_a = truth.plates[first].name;
    seam.plate_b = truth.plates[first + 1].name;
    truth.seams.push_back(std::move(seam));
  }
  return truth;
}

}  // namespace hwr::sim
