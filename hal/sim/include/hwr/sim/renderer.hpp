#pragma once
// Embree ray-cast renderer of a SceneSpec: noise-free colour and metric z-depth from a pinhole
// camera. Depth is the distance along the optical axis (what RGB-D cameras and TUM report), not
// along the ray. Images are written into caller-owned cv::Mat buffers that are (re)allocated
// only when their size or type differs, so a render loop allocates nothing after the first frame.

#include <memory>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "hwr/core/status.hpp"
#include "hwr/hal/pinhole_camera.hpp"
#include "hwr/sim/scene_spec.hpp"

namespace hwr::sim {

struct RenderOptions {
  double max_range_m = 20.0;  // depth beyond this is 0 (invalid), colour still shaded
  double min_range_m = 0.1;   // depth nearer than this is 0
  // Light: a directional sun/ceiling light plus ambient, Lambertian shading of the texture.
  Eigen::Vector3d light_dir_scene{0.3, 0.2, -1.0};
  double ambient = 0.35;
  // Embree ray packet width: 0 picks the widest the CPU runs natively (16, 8, 4); 1, 4, 8, 16
  // force one (every width renders the same image; for benchmarks and tests).
  int packet_width = 0;
  // Colour integrated over each pixel's area, as a camera's pixel collects the light falling on all
  // of it: false samples the pixel centre only (a feature narrower than a pixel shows only where it
  // covers a centre, fully dark or not at all: a 2 mm butt gap seen from 1.5-2.5 m at 20-35 deg down
  // is 0.3-0.5 px across); true
  // averages the centre and four rotated-grid samples at (+-1/8, -+3/8) px and (+-3/8, +-1/8) px, a
  // box filter over the pixel (5 rays a pixel: about 5x the render time, hwr-bench sim-render
  // --area-sampling). Depth is the centre ray's either way.
  bool area_sampling = false;
  // Shadows of the directional light: a surface point from which a ray towards the light meets
  // another surface within shadow_range_m gets the ambient term only (a shadow ray per lit hit,
  // about 1.4x the render time, hwr-bench sim-render --shadows). The range stands in for lamps
  // hanging under a ceiling: the room's ceiling and far walls (beyond it) cast none, nearby work
  // pieces do, and so does a plate over the root gap of a butt joint, whose bottom and walls a real
  // lamp barely lights. False: every surface facing the light is lit (no shadows at all).
  bool shadows = false;
  double shadow_range_m = 2.0;
  // Ambient occlusion: the ambient term of a surface point scaled by the share of this many fixed,
  // cosine-weighted directions over its surface that meet no other surface within
  // ambient_occlusion_range_m (0: off, up to 64). Nooks and narrow gaps get less of the room's
  // diffuse light: the bottom of a 2 mm root gap between 8 mm plates sees an eighth of the sky
  // (sin(atan(1 / 8)), cosine weighted).
  // Each direction is one more ray per hit (hwr-bench sim-render --ambient-occlusion N).
  int ambient_occlusion_rays = 0;
  double ambient_occlusion_range_m = 0.05;
  // Colour of pixels whose ray hits nothing (outdoor sky).
  Eigen::Vector3d background_bgr{200.0, 180.0, 160.0};
};

class Renderer {
 public:
  // Builds the Embree scene (triangle meshes for every primitive) and the procedural textures
  // (seeded by scene.texture_seed). Errors: Embree device/scene creation failures, invalid specs
  // (non-positive sizes), each with a message naming the object.
  static core::Expected<std::unique_ptr<Renderer>> create(const SceneSpec& scene);
  virtual ~Renderer() = default;

  // Renders the view of a camera at T_scene_cam (OpenCV camera axes: x right, y down, z forward).
  // bgr: CV_8UC3; depth_m: CV_32FC1 (0 = no surface within [min, max] range). Each call runs on
  // the calling thread; concurrent calls on one renderer are safe (the Embree scene is committed
  // and read-only, scratch is thread-local), which hwr-sim --threads relies on.
  // Either output may be null. Lens distortion in `intrinsics` is ignored (rectified images).
  virtual void render(const Eigen::Isometry3d& T_scene_cam, const hal::PinholeIntrinsics& intrinsics,
                      const RenderOptions& options, cv::Mat* bgr, cv::Mat* depth_m) const = 0;

  // Distance along a ray to the first surface, +inf when nothing is hit (for tests and for the
  // simulator's own checks). dir_scene need not be normalised; the distance is in metres.
  virtual double cast_ray(const Eigen::Vector3d& origin_scene, const Eigen::Vector3d& dir_scene) const = 0;

  // Number of triangles in the scene.
  virtual size_t triangle_count() const = 0;

  // Packet width render() uses when RenderOptions::packet_width is 0 (from the Embree device's
  // native ray-packet support on this CPU).
  virtual int native_packet_width() const = 0;
};

// Exact plate corners and seams of the scene's weld joints, in the scene frame.
SceneGroundTruth scene_ground_truth(const SceneSpec& scene);

}  // namespace hwr::sim
