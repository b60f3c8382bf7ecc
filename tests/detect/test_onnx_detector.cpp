// The learned detector's ONNX backend (detect/onnx_detector.hpp) and the factory's fallback
// (detect/detector_factory.hpp), end to end on the tiny models tests/detect/make_tiny_yolo.py writes
// into the build tree (their boxes are repeated here). Oracles: the models' known outputs (one score
// depends on the image through the preprocessing: its closed form), the letterbox's closed form, and
// plates rendered analytically (depth_render.hpp) at known depths behind the boxes.

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

#include "depth_render.hpp"
#include "hwr/detect/detector_factory.hpp"
#include "hwr/detect/onnx_detector.hpp"
#include "temp_dir.hpp"

namespace hwr::detect {
namespace {

std::string model_path(const std::string& name) {
  return std::string(HWR_BINARY_DIR) + "/tests/detect/models/" + name;
}

// make_tiny_yolo.py: the first box's score is bias + 0.3 * the mean of the blob's R channel. The
// letterbox of 640 x 480 into 64 x 64 has 48 image rows and 16 grey (114) rows.
double expected_first_score(double bias, double red_0_to_1) {
  const double mean_r = 0.75 * red_0_to_1 + 0.25 * 114.0 / 255.0;
  return bias + 0.3 * mean_r;
}

// The scene: plate A (front at 1.2 m) behind the model's fillet box, image (200, 120) - (410, 290) and
// more; plate B (front at 2.0 m) behind its butt box (40, 40) - (140, 140); a wall at 3 m. Built in the
// camera frame, placed in the world with T_world_cam.
struct Scene {
  hal::PinholeIntrinsics K = testing::vga_intrinsics();
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  cv::Mat depth_m, bgr;
};

Eigen::Vector3d at_pixel(const hal::PinholeIntrinsics& K, double u, double v, double z_m) {
  return Eigen::Vector3d((u - K.cx) / K.fx * z_m, (v - K.cy) / K.fy * z_m, z_m);
}

Scene make_scene(const cv::Scalar& colour_bgr) {
  Scene s;
  s.T_world_cam.translation() = Eigen::Vector3d(1.0, -2.0, 1.4);
  s.T_world_cam.linear() =
      Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.3, 1.0, -0.2).normalized()).toRotationMatrix();
  testing::RenderScene scene;
  const auto add_plate = [&](const Eigen::Vector3d& centre_cam, double half_x, double half_y, int id) {
    testing::RenderBox b;
    Eigen::Isometry3d T_cam_box = Eigen::Isometry3d::Identity();
    T_cam_box.translation() = centre_cam + Eigen::Vector3d(0, 0, 0.005);
    b.T_world_box = s.T_world_cam * T_cam_box;
    b.half_size_m = Eigen::Vector3d(half_x, half_y, 0.005);
    b.id = id;
    scene.boxes.push_back(b);
  };
  add_plate(at_pixel(s.K, 305, 205, 1.2), 0.27, 0.22, 1);  // pixels ~187..423 x 109..301
  add_plate(at_pixel(s.K, 90, 90, 2.0), 0.3, 0.3, 2);      // pixels ~11..169 x 11..169
  add_plate(Eigen::Vector3d(0, 0, 3.0), 10.0, 10.0, 3);
  s.depth_m = testing::render_depth(scene, s.K, s.T_world_cam).depth_m;
  s.bgr = cv::Mat(s.K.height, s.K.width, CV_8UC3, colour_bgr);
  return s;
}

KeyframeView view_of(const Scene& s) {
  KeyframeView v;
  v.keyframe_id = 11;
  v.t_ns = 4242;
  v.K = s.K;
  v.bgr = &s.bgr;
  v.depth_m = &s.depth_m;
  v.T_world_cam = s.T_world_cam;
  return v;
}

OnnxDetectorConfig tiny_config(const std::string& model_file) {
  OnnxDetectorConfig c;
  c.model_path = model_path(model_file);
  c.input_size_px = 64;
  return c;
}

// A detection's box: from the model's image box sampled every second pixel from its first (box_lift):
// its centre on the ray of the sampled pixels' middle, at the plate's depth, z facing the camera.
void expect_detection(const Detection& d, const Scene& s, SeamKind kind, double score, double u_mid,
                      double v_mid, double z_m) {
  EXPECT_EQ(d.source, DetectionSource::kModel);
  EXPECT_EQ(d.kind, kind);
  EXPECT_NEAR(d.confidence, score, 1e-5);
  EXPECT_EQ(d.keyframe_id, 11);
  EXPECT_EQ(d.t_ns, 4242);
  const Eigen::Vector3d expected = at_pixel(s.K, u_mid, v_mid, z_m);
  EXPECT_LT((d.T_cam_box.translation() - expected).norm(), 0.003)
      << d.T_cam_box.translation().transpose() << " vs " << expected.transpose();
  EXPECT_GT(d.T_cam_box.linear().col(2).dot(-Eigen::Vector3d::UnitZ()), 0.9999);
  EXPECT_TRUE(d.T_world_box.isApprox(s.T_world_cam * d.T_cam_box, 1e-12));
  EXPECT_LT((d.seam_world[0] - s.T_world_cam * d.seam_cam[0]).norm(), 1e-12);
  EXPECT_FALSE(d.end_observed[0] || d.end_observed[1]);
}

std::unique_ptr<OnnxDetector> make_onnx(const OnnxDetectorConfig& c, const hal::PinholeIntrinsics& K) {
  auto d = OnnxDetector::create(c, K);
  EXPECT_TRUE(d.ok()) << d.status().message();
  return d.ok() ? std::move(d.value()) : nullptr;
}

TEST(OnnxDetector, GivenTheEndToEndModelThenItsBoxesAreLiftedOntoThePlatesBehindThemBestFirst) {
  for (const double red : {1.0, 0.0}) {  // a red image, then a blue one: the preprocessing's proof
    const Scene s = make_scene(red > 0 ? cv::Scalar(0, 0, 255) : cv::Scalar(255, 0, 0));
    auto detector = make_onnx(tiny_config("tiny_yolo_e2e.onnx"), s.K);
    ASSERT_NE(detector, nullptr);
    EXPECT_EQ(detector->head().layout, YoloHeadLayout::kEndToEnd);
    EXPECT_EQ(detector->head().candidates, 300);
    EXPECT_EQ(detector->source(), DetectionSource::kModel);
    DetectionList out(8);
    ASSERT_TRUE(detector->detect(view_of(s), &out).ok());
    // Row 1 (butt, 0.9), row 0 (fillet, 0.55 + 0.3 mean R); row 2 is below 0.25, row 3 in the grey band.
    ASSERT_EQ(out.size(), 2) << red;
    // Model (4, 12) - (14, 22) = image (40, 40) - (140, 140): sampled pixels 40..138, middle 89.
    expect_detection(out[0], s, SeamKind::kButt, 0.9, 89, 89, 2.0);
    // Model (20, 20) - (40, 36) = image (200, 120) - (400, 280): middle (299, 199).
    expect_detection(out[1], s, SeamKind::kFillet, expected_first_score(0.55, red), 299, 199, 1.2);
    EXPECT_NEAR(out[1].box_px.x, 204, 3);  // the 3D box projected: the model's box less the quantiles' 4 %
    EXPECT_NEAR(out[1].box_px.x + out[1].box_px.width, 394, 3);
    const ModelDetectorStats& st = detector->last_stats();
    EXPECT_EQ(st.decode.above_threshold, 3);
    EXPECT_EQ(st.decode.outside, 1);
    EXPECT_EQ(st.lifted, 2);
  }
}

TEST(OnnxDetector, GivenTheRawHeadModelThenNmsKeepsOneFilletAndBothButtsLiftedOntoTheirPlates) {
  for (const double red : {1.0, 0.0}) {
    const Scene s = make_scene(red > 0 ? cv::Scalar(0, 0, 255) : cv::Scalar(255, 0, 0));
    auto detector = make_onnx(tiny_config("tiny_yolo_raw.onnx"), s.K);
    ASSERT_NE(detector, nullptr);
    EXPECT_EQ(detector->head().layout, YoloHeadLayout::kRawChannelsFirst);
    EXPECT_EQ(detector->head().candidates, 8);
    DetectionList out(8);
    ASSERT_TRUE(detector->detect(view_of(s), &out).ok());
    ASSERT_EQ(out.size(), 3) << red;
    // Anchor 0 (fillet, (200, 120) - (400, 280)), anchor 3 (butt, (40, 40) - (140, 140), 0.8), anchor 2
    // (butt, (210, 130) - (410, 290), 0.7); anchor 1 (fillet, IoU 0.9 with anchor 0) suppressed.
    const double fillet_score = expected_first_score(0.55, red);
    int fillet = -1, butt = -1, other_butt = -1;
    for (int i = 0; i < out.size(); ++i) {
      if (out[i].kind == SeamKind::kFillet) fillet = i;
      if (out[i].kind == SeamKind::kButt) {
        (std::fabs(out[i].confidence - 0.8f) < 1e-6f ? butt : other_butt) = i;
      }
      if (i > 0) {
        EXPECT_GE(out[i - 1].confidence, out[i].confidence);  // best first
      }
    }
    ASSERT_TRUE(fillet >= 0 && butt >= 0 && other_butt >= 0);
    expect_detection(out[fillet], s, SeamKind::kFillet, fillet_score, 299, 199, 1.2);
    expect_detection(out[butt], s, SeamKind::kButt, 0.8, 89, 89, 2.0);
    expect_detection(out[other_butt], s, SeamKind::kButt, 0.7, 309, 209, 1.2);
    EXPECT_EQ(detector->last_stats().decode.suppressed, 1);
  }
}

TEST(OnnxDetector, GivenNoDepthBehindTheBoxesThenNoDetectionsCountedAndGivenMissingImagesThenErrors) {
  Scene s = make_scene(cv::Scalar(0, 0, 255));
  auto detector = make_onnx(tiny_config("tiny_yolo_e2e.onnx"), s.K);
  ASSERT_NE(detector, nullptr);
  DetectionList out(8);
  s.depth_m.setTo(0.0f);
  ASSERT_TRUE(detector->detect(view_of(s), &out).ok());
  EXPECT_EQ(out.size(), 0);
  EXPECT_EQ(detector->last_stats().too_few_depth, 2);

  KeyframeView v = view_of(s);
  v.bgr = nullptr;
  core::Status st = detector->detect(v, &out);
  EXPECT_EQ(st.code(), core::ErrorCode::kInvalidArgument);
  EXPECT_NE(st.message().find("no colour image"), std::string::npos) << st.message();
  v = view_of(s);
  v.depth_m = nullptr;
  st = detector->detect(v, &out);
  EXPECT_NE(st.message().find("no depth image"), std::string::npos) << st.message();
  const cv::Mat grey(s.K.height, s.K.width, CV_8UC1, cv::Scalar(0));
  v = view_of(s);
  v.bgr = &grey;
  EXPECT_EQ(detector->detect(v, &out).code(), core::ErrorCode::kInvalidArgument);
  v = view_of(s);
  v.K.fx += 1.0;
  EXPECT_EQ(detector->detect(v, &out).code(), core::ErrorCode::kInvalidArgument);
  EXPECT_EQ(detector->detect(view_of(s), nullptr).code(), core::ErrorCode::kInvalidArgument);
}

// The unusable model files, each with the error create() gives: code and words of its message.
struct BadModel {
  std::string what, path;
  core::ErrorCode code;
  std::vector<std::string> words;
  int input_size_px = 64;
};

std::vector<BadModel> bad_models(const testing::TempDir& dir) {
  std::ifstream good(model_path("tiny_yolo_e2e.onnx"), std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(good)), std::istreambuf_iterator<char>());
  EXPECT_GT(bytes.size(), 1000u);
  std::ofstream(dir.file("truncated.onnx"), std::ios::binary) << bytes.substr(0, bytes.size() / 2);
  std::mt19937 rng(7);
  std::string noise(4096, '\0');
  for (char& ch : noise) ch = static_cast<char>(rng() & 0xff);
  std::ofstream(dir.file("random.onnx"), std::ios::binary) << noise;
  std::ofstream(dir.file("empty.onnx"), std::ios::binary);
  return {
      {"missing", dir.file("missing.onnx"), core::ErrorCode::kNotFound, {"not found"}},
      {"a folder", dir.path(), core::ErrorCode::kInvalidArgument, {"is not a file"}},
      {"truncated", dir.file("truncated.onnx"), core::ErrorCode::kParseError, {"not a readable ONNX model"}},
      {"random bytes", dir.file("random.onnx"), core::ErrorCode::kParseError, {"not a readable ONNX model"}},
      {"empty", dir.file("empty.onnx"), core::ErrorCode::kParseError, {"not a readable ONNX model"}},
      {"wrong output",
       model_path("tiny_yolo_bad_output.onnx"),
       core::ErrorCode::kInvalidArgument,
       {"incompatible", "[1, 7, 5]", "expected [1, K, 6]"}},
      {"wrong input",
       model_path("tiny_yolo_input16.onnx"),
       core::ErrorCode::kInvalidArgument,
       {"incompatible", "forward pass", "[1, 3, 64, 64]", "input_size_px"}},
  };
}

TEST(OnnxDetector, GivenAMissingCorruptOrIncompatibleModelThenCreateSaysWhichWithThePath) {
  const testing::TempDir dir("hwr_onnx");
  const hal::PinholeIntrinsics K = testing::vga_intrinsics();
  for (const BadModel& bad : bad_models(dir)) {
    OnnxDetectorConfig c = tiny_config("");
    c.model_path = bad.path;
    const auto d = OnnxDetector::create(c, K);
    ASSERT_FALSE(d.ok()) << bad.what;
    EXPECT_EQ(d.status().code(), bad.code) << bad.what << ": " << d.status().to_string();
    EXPECT_NE(d.status().message().find("'" + bad.path + "'"), std::string::npos) << d.status().message();
    for (const std::string& w : bad.words) {
      EXPECT_NE(d.status().message().find(w), std::string::npos) << bad.what << ": " << d.status().message();
    }
  }
  // The 16 x 16 model is usable at its own size: the error was the input size.
  OnnxDetectorConfig sixteen = tiny_config("tiny_yolo_input16.onnx");
  sixteen.input_size_px = 16;
  EXPECT_TRUE(OnnxDetector::create(sixteen, K).ok());
  // No path, bad config values.
  OnnxDetectorConfig c = tiny_config("tiny_yolo_e2e.onnx");
  c.model_path.clear();
  EXPECT_EQ(OnnxDetector::create(c, K).status().code(), core::ErrorCode::kInvalidArgument);
  c = tiny_config("tiny_yolo_e2e.onnx");
  c.class_names.clear();
  EXPECT_NE(OnnxDetector::create(c, K).status().message().find("class_names"), std::string::npos);
  c = tiny_config("tiny_yolo_e2e.onnx");
  c.score_threshold = 1.5f;
  EXPECT_NE(OnnxDetector::create(c, K).status().message().find("score_threshold"), std::string::npos);
  // The raw model's [1, 6, 8] is no head for 3 classes.
  c = tiny_config("tiny_yolo_raw.onnx");
  c.class_names = {"fillet", "butt", "bead"};
  const auto three = OnnxDetector::create(c, K);
  ASSERT_FALSE(three.ok());
  EXPECT_NE(three.status().message().find("[1, 6, 8]"), std::string::npos) << three.status().message();
}

TEST(DetectorFactory, GivenAnUnusableModelThenTheGeometricDetectorWithTheModelsErrorAsTheReason) {
  const testing::TempDir dir("hwr_onnx");
  const Scene s = make_scene(cv::Scalar(0, 0, 255));
  for (const BadModel& bad : bad_models(dir)) {
    DetectorChoice choice;
    choice.backend = DetectorBackend::kOnnx;
    choice.model = tiny_config("");
    choice.model.model_path = bad.path;
    auto made = make_detector(choice, s.K);
    ASSERT_TRUE(made.ok()) << made.status().message();
    EXPECT_EQ(made->backend, DetectorBackend::kGeometry) << bad.what;
    ASSERT_NE(made->detector, nullptr);
    EXPECT_EQ(made->detector->source(), DetectionSource::kGeometry);
    EXPECT_TRUE(made->fell_back());
    // The reason is the ONNX backend's own error, code and message.
    EXPECT_EQ(made->fallback_reason, OnnxDetector::create(choice.model, s.K).status().to_string())
        << bad.what;
    // The fallback runs (this scene has no fillet).
    DetectionList out(8);
    EXPECT_TRUE(made->detector->detect(view_of(s), &out).ok());
  }
}

TEST(DetectorFactory, GivenAUsableModelOrGeometryThenThatDetectorWithNoFallback) {
  const Scene s = make_scene(cv::Scalar(0, 0, 255));
  DetectorChoice choice;
  choice.backend = DetectorBackend::kOnnx;
  choice.model = tiny_config("tiny_yolo_raw.onnx");
  auto made = make_detector(choice, s.K);
  ASSERT_TRUE(made.ok());
  EXPECT_EQ(made->backend, DetectorBackend::kOnnx);
  EXPECT_FALSE(made->fell_back());
  EXPECT_EQ(made->detector->source(), DetectionSource::kModel);
  DetectionList out(8);
  ASSERT_TRUE(made->detector->detect(view_of(s), &out).ok());
  EXPECT_EQ(out.size(), 3);

  choice.backend = DetectorBackend::kGeometry;  // the model is not even looked at
  choice.model.model_path = "/nonexistent.onnx";
  made = make_detector(choice, s.K);
  ASSERT_TRUE(made.ok());
  EXPECT_EQ(made->backend, DetectorBackend::kGeometry);
  EXPECT_FALSE(made->fell_back());

  EXPECT_FALSE(make_detector(choice, hal::PinholeIntrinsics{}).ok());  // not even geometry: an error
  EXPECT_STREQ(detector_backend_name(DetectorBackend::kTensorRt), "tensorrt");
}

TEST(DetectorFactory, GivenTensorRtInABuildWithoutItThenGeometryBecauseBuiltWithoutTensorRt) {
  if (tensorrt_built()) GTEST_SKIP() << "this build has TensorRT";
  DetectorChoice choice;
  choice.backend = DetectorBackend::kTensorRt;
  choice.model.model_path = "/opt/models/welds.engine";
  auto made = make_detector(choice, testing::vga_intrinsics());
  ASSERT_TRUE(made.ok());
  EXPECT_EQ(made->backend, DetectorBackend::kGeometry);
  EXPECT_NE(made->fallback_reason.find("built without TensorRT"), std::string::npos) << made->fallback_reason;
  EXPECT_NE(made->fallback_reason.find("/opt/models/welds.engine"), std::string::npos);
}

}  // namespace
}  // namespace hwr::detect
