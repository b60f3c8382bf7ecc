// SceneSpec -> triangles. Boxes (and the boxes of beams and plates) share their 8 corners; the
// ground, walls and ceiling are single quads; pipes are inscribed polygons with end-cap fans.

#include "scene_mesh.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <utility>

namespace hwr::sim::detail {
namespace {

std::string label(const char* kind, const std::string& name, size_t index) {
  std::ostringstream os;
  if (name.empty()) {
    os << kind << " #" << index;
  } else {
    os << kind << " '" << name << "'";
  }
  return os.str();
}

core::Status check_positive(const std::string& what, const char* field, double value) {
  if (std::isfinite(value) && value > 0.0) return core::Status::Ok();
  std::ostringstream os;
  os << what << ": " << field << " must be > 0 (got " << value << ")";
  return core::InvalidArgument(os.str());
}

core::Status check_pose(const std::string& what, const char* field, const Eigen::Isometry3d& T) {
  const Eigen::Matrix3d R = T.linear();
  const bool finite = T.matrix().allFinite();
  if (finite && (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-6 &&
      R.determinant() > 0.0) {
    return core::Status::Ok();
  }
  return core::InvalidArgument(what + ": " + field +
                               " is not a finite rigid transform (rotation must be orthonormal)");
}

core::Status check_material(const std::string& what, Material material) {
  if (static_cast<int>(material) < static_cast<int>(Material::kCount)) return core::Status::Ok();
  return core::InvalidArgument(what + ": material id " + std::to_string(static_cast<int>(material)) +
                               " is out of range");
}

class MeshBuilder {
 public:
  explicit MeshBuilder(SceneMesh* mesh) : mesh_(mesh) {}

  uint32_t add_object(SceneObject object) {
    mesh_->objects.push_back(std::move(object));
    return static_cast<uint32_t>(mesh_->objects.size() - 1);
  }

  uint32_t add_vertex(const Eigen::Vector3d& p_scene) {
    mesh_->vertices_scene.push_back(p_scene.cast<float>());
    return static_cast<uint32_t>(mesh_->vertices_scene.size() - 1);
  }

  // Triangle (a, b, c), flipped if needed so that its normal points along outward_scene.
  void add_triangle(uint32_t a, uint32_t b, uint32_t c, const Eigen::Vector3d& outward_scene,
                    uint32_t object) {
    const auto& v = mesh_->vertices_scene;
    const Eigen::Vector3d n = (v[b] - v[a]).cast<double>().cross((v[c] - v[a]).cast<double>());
    if (n.dot(outward_scene) < 0.0) std::swap(b, c);
    mesh_->triangles.push_back({a, b, c});
    mesh_->tri_material.push_back(mesh_->objects[object].material);
    mesh_->tri_object.push_back(object);
  }

  // Quad a-b-c-d in cyclic order.
  void add_quad(uint32_t a, uint32_t b, uint32_t c, uint32_t d, const Eigen::Vector3d& outward_scene,
                uint32_t object) {
    add_triangle(a, b, c, outward_scene, object);
    add_triangle(a, c, d, outward_scene, object);
  }

  // Centred box of size_m placed by T_scene_box; corner i at (bit 2, bit 1, bit 0) = (x, y, z) signs.
  void add_box(const Eigen::Vector3d& size_m, const Eigen::Isometry3d& T_scene_box, uint32_t object) {
    uint32_t c[8];
    for (int i = 0; i < 8; ++i) {
      const Eigen::Vector3d sign((i & 4) ? 1.0 : -1.0, (i & 2) ? 1.0 : -1.0, (i & 1) ? 1.0 : -1.0);
      c[i] = add_vertex(T_scene_box * (0.5 * sign.cwiseProduct(size_m)));
    }
    const Eigen::Matrix3d R = T_scene_box.linear();
    add_quad(c[0], c[1], c[3], c[2], -R.col(0), object);  // -x
    add_quad(c[4], c[5], c[7], c[6], R.col(0), object);   // +x
    add_quad(c[0], c[1], c[5], c[4], -R.col(1), object);  // -y
    add_quad(c[2], c[3], c[7], c[6], R.col(1), object);   // +y
    add_quad(c[0], c[2], c[6], c[4], -R.col(2), object);  // -z
    add_quad(c[1], c[3], c[7], c[5], R.col(2), object);   // +z
  }

  void add_pipe(const PipeSpec& pipe, uint32_t object) {
    const int n = pipe_segment_count(pipe.radius_m, kPipeMaxErrorM);
    const Eigen::Isometry3d& T = pipe.T_scene_pipe;
    const Eigen::Vector3d axis = T.linear().col(2);
    const double h = 0.5 * pipe.length_m;
    const uint32_t first = static_cast<uint32_t>(mesh_->vertices_scene.size());
    for (int k = 0; k < n; ++k) {
      const double theta = 2.0 * M_PI * k / n;
      const double x = pipe.radius_m * std::cos(theta), y = pipe.radius_m * std::sin(theta);
      add_vertex(T * Eigen::Vector3d(x, y, -h));
      add_vertex(T * Eigen::Vector3d(x, y, h));
    }
    const uint32_t centre_lo = add_vertex(T * Eigen::Vector3d(0, 0, -h));
    const uint32_t centre_hi = add_vertex(T * Eigen::Vector3d(0, 0, h));
    for (int k = 0; k < n; ++k) {
      const int k1 = (k + 1) % n;
      const uint32_t lo0 = first + 2 * k, hi0 = lo0 + 1;
      const uint32_t lo1 = first + 2 * k1, hi1 = lo1 + 1;
      const double theta_mid = 2.0 * M_PI * (k + 0.5) / n;
      const Eigen::Vector3d radial =
          T.linear() * Eigen::Vector3d(std::cos(theta_mid), std::sin(theta_mid), 0.0);
      add_quad(lo0, lo1, hi1, hi0, radial, object);
      add_triangle(centre_lo, lo0, lo1, -axis, object);
      add_triangle(centre_hi, hi0, hi1, axis, object);
    }
  }

 private:
  SceneMesh* mesh_;
};

}  // namespace

int pipe_segment_count(double radius_m, double max_error_m) {
  if (radius_m <= max_error_m) return 8;
  const double n = M_PI / std::acos(1.0 - max_error_m / radius_m);
  return std::clamp(static_cast<int>(std::ceil(n)), 8, 1024);
}

core::Status validate_scene(const SceneSpec& scene) {
  HWR_RETURN_IF_ERROR(check_positive("scene '" + scene.name + "'", "ground_extent_m", scene.ground_extent_m));
  HWR_RETURN_IF_ERROR(check_material("ground", scene.ground_material));
  if (scene.has_room) {
    const std::string what = "room of scene '" + scene.name + "'";
    HWR_RETURN_IF_ERROR(check_positive(what, "room_height_m", scene.room_height_m));
    HWR_RETURN_IF_ERROR(
        check_positive(what, "room_max_xy.x - room_min_xy.x", scene.room_max_xy.x() - scene.room_min_xy.x()));
    HWR_RETURN_IF_ERROR(
        check_positive(what, "room_max_xy.y - room_min_xy.y", scene.room_max_xy.y() - scene.room_min_xy.y()));
  }
  for (size_t i = 0; i < scene.boxes.size(); ++i) {
    const BoxSpec& b = scene.boxes[i];
    const std::string what = label("box", b.name, i);
    HWR_RETURN_IF_ERROR(check_positive(what, "size_m.x", b.size_m.x()));
    HWR_RETURN_IF_ERROR(check_positive(what, "size_m.y", b.size_m.y()));
    HWR_RETURN_IF_ERROR(check_positive(what, "size_m.z", b.size_m.z()));
    HWR_RETURN_IF_ERROR(check_pose(what, "T_scene_box", b.T_scene_box));
    HWR_RETURN_IF_ERROR(check_material(what, b.material));
  }
  for (size_t i = 0; i < scene.beams.size(); ++i) {
    const IBeamSpec& b = scene.beams[i];
    const std::string what = label("beam", b.name, i);
    HWR_RETURN_IF_ERROR(check_positive(what, "length_m", b.length_m));
    HWR_RETURN_IF_ERROR(check_positive(what, "height_m", b.height_m));
    HWR_RETURN_IF_ERROR(check_positive(what, "flange_width_m", b.flange_width_m));
    HWR_RETURN_IF_ERROR(check_positive(what, "web_thickness_m", b.web_thickness_m));
    HWR_RETURN_IF_ERROR(check_positive(what, "flange_thickness_m", b.flange_thickness_m));
    HWR_RETURN_IF_ERROR(
        check_positive(what, "flange_width_m - web_thickness_m", b.flange_width_m - b.web_thickness_m));
    HWR_RETURN_IF_ERROR(
        check_positive(what, "height_m - 2 flange_thickness_m", b.height_m - 2.0 * b.flange_thickness_m));
    HWR_RETURN_IF_ERROR(check_pose(what, "T_scene_beam", b.T_scene_beam));
    HWR_RETURN_IF_ERROR(check_material(what, b.material));
  }
  for (size_t i = 0; i < scene.pipes.size(); ++i) {
    const PipeSpec& p = scene.pipes[i];
    const std::string what = label("pipe", p.name, i);
    HWR_RETURN_IF_ERROR(check_positive(what, "radius_m", p.radius_m));
    HWR_RETURN_IF_ERROR(check_positive(what, "length_m", p.length_m));
    HWR_RETURN_IF_ERROR(check_pose(what, "T_scene_pipe", p.T_scene_pipe));
    HWR_RETURN_IF_ERROR(check_material(what, p.material));
  }
  for (size_t i = 0; i < scene.joints.size(); ++i) {
    const WeldJointSpec& j = scene.joints[i];
    const std::string what = label("joint", j.name, i);
    HWR_RETURN_IF_ERROR(check_positive(what, "length_m", j.length_m));
    HWR_RETURN_IF_ERROR(check_positive(what, "base_width_m", j.base_width_m));
    HWR_RETURN_IF_ERROR(check_positive(what, "thickness_m", j.thickness_m));
    if (j.type == WeldJointSpec::Type::kFillet) {
      HWR_RETURN_IF_ERROR(check_positive(what, "web_width_m", j.web_width_m));
    } else if (j.type == WeldJointSpec::Type::kButt) {
      if (!std::isfinite(j.gap_m) || j.gap_m < 0.0) {
        std::ostringstream os;
        os << what << ": gap_m must be >= 0 (got " << j.gap_m << ")";
        return core::InvalidArgument(os.str());
      }
    } else {
      return core::InvalidArgument(what + ": unknown joint type " + std::to_string(static_cast<int>(j.type)));
    }
    HWR_RETURN_IF_ERROR(check_pose(what, "T_scene_joint", j.T_scene_joint));
  }
  return core::Status::Ok();
}

SceneMesh build_scene_mesh(const SceneSpec& scene) {
  SceneMesh mesh;
  MeshBuilder b(&mesh);

  {
    SceneObject ground;
    ground.name = "ground";
    ground.kind = ObjectKind::kGround;
    ground.material = scene.ground_material;
    const uint32_t id = b.add_object(std::move(ground));
    const double e = scene.ground_extent_m;
    const uint32_t v0 = b.add_vertex({-e, -e, 0}), v1 = b.add_vertex({e, -e, 0});
    const uint32_t v2 = b.add_vertex({e, e, 0}), v3 = b.add_vertex({-e, e, 0});
    b.add_quad(v0, v1, v2, v3, Eigen::Vector3d::UnitZ(), id);
  }

  if (scene.has_room) {
    const double x0 = scene.room_min_xy.x(), y0 = scene.room_min_xy.y();
    const double x1 = scene.room_max_xy.x(), y1 = scene.room_max_xy.y();
    const double h = scene.room_height_m;
    struct Wall {
      const char* name;
      Eigen::Vector2d a, b;
      Eigen::Vector3d inward;
    };
    const Wall walls[4] = {{"wall/-x", {x0, y0}, {x0, y1}, Eigen::Vector3d::UnitX()},
                           {"wall/+x", {x1, y0}, {x1, y1}, -Eigen::Vector3d::UnitX()},
                           {"wall/-y", {x0, y0}, {x1, y0}, Eigen::Vector3d::UnitY()},
                           {"wall/+y", {x0, y1}, {x1, y1}, -Eigen::Vector3d::UnitY()}};
    for (const Wall& w : walls) {
      SceneObject object;
      object.name = w.name;
      object.kind = ObjectKind::kWall;
      object.material = Material::kPaintedWall;
      const uint32_t id = b.add_object(std::move(object));
      const uint32_t v0 = b.add_vertex({w.a.x(), w.a.y(), 0}), v1 = b.add_vertex({w.b.x(), w.b.y(), 0});
      const uint32_t v2 = b.add_vertex({w.b.x(), w.b.y(), h}), v3 = b.add_vertex({w.a.x(), w.a.y(), h});
      b.add_quad(v0, v1, v2, v3, w.inward, id);
    }
    SceneObject ceiling;
    ceiling.name = "ceiling";
    ceiling.kind = ObjectKind::kCeiling;
    ceiling.material = Material::kPaintedWall;
    const uint32_t id = b.add_object(std::move(ceiling));
    const uint32_t v0 = b.add_vertex({x0, y0, h}), v1 = b.add_vertex({x1, y0, h});
    const uint32_t v2 = b.add_vertex({x1, y1, h}), v3 = b.add_vertex({x0, y1, h});
    b.add_quad(v0, v1, v2, v3, -Eigen::Vector3d::UnitZ(), id);
  }

  for (const BoxSpec& box : scene.boxes) {
    SceneObject object;
    object.name = box.name;
    object.kind = ObjectKind::kBox;
    object.material = box.material;
    b.add_box(box.size_m, box.T_scene_box, b.add_object(std::move(object)));
  }

  for (const IBeamSpec& beam : scene.beams) {
    SceneObject object;
    object.name = beam.name;
    object.kind = ObjectKind::kBeam;
    object.material = beam.material;
    const uint32_t id = b.add_object(std::move(object));
    // Two flanges at the top and bottom of the web direction (local z), the web between them.
    const double zf = 0.5 * (beam.height_m - beam.flange_thickness_m);
    for (const double z : {-zf, zf}) {
      b.add_box({beam.length_m, beam.flange_width_m, beam.flange_thickness_m},
                beam.T_scene_beam * Eigen::Translation3d(0, 0, z), id);
    }
    b.add_box({beam.length_m, beam.web_thickness_m, beam.height_m - 2.0 * beam.flange_thickness_m},
              beam.T_scene_beam, id);
  }

  for (const PipeSpec& pipe : scene.pipes) {
    SceneObject object;
    object.name = pipe.name;
    object.kind = ObjectKind::kPipe;
    object.material = pipe.material;
    object.axis_point_scene = pipe.T_scene_pipe.translation();
    object.axis_dir_scene = pipe.T_scene_pipe.linear().col(2);
    object.radius_m = pipe.radius_m;
    b.add_pipe(pipe, b.add_object(std::move(object)));
  }

  std::vector<PlateTruth> plates;
  for (const WeldJointSpec& joint : scene.joints) append_joint_plates(joint, &plates);
  for (const PlateTruth& plate : plates) {
    SceneObject object;
    object.name = plate.name;
    object.kind = ObjectKind::kPlate;
    object.material = Material::kSteel;
    b.add_box(plate.size_m, plate.T_scene_plate, b.add_object(std::move(object)));
  }
  return mesh;
}

}  // namespace hwr::sim::detail
