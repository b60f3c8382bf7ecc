// config/estimation.yaml (the documented defaults) loads and equals the built-in defaults; bad
// keys and values are errors naming the key.

#include <cstdio>
#include <fstream>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>

#include "hwr/estimation/estimator_config.hpp"

namespace hwr::estimation {
namespace {

std::string write_temp(const std::string& text) {
  const std::string path = ::testing::TempDir() + "hwr_est_cfg_" + std::to_string(::getpid()) + ".yaml";
  std::ofstream(path) << text;
  return path;
}

TEST(EstimatorConfig, GivenTheShippedFileWhenLoadedThenItEqualsTheBuiltInDefaults) {
  auto c = load_estimator_config(HWR_SOURCE_DIR "/config/estimation.yaml");
  ASSERT_TRUE(c.ok()) << c.status().message();
  const PoseEstimatorConfig d;
  EXPECT_EQ(c->tracker.orb.max_features, d.tracker.orb.max_features);
  EXPECT_DOUBLE_EQ(c->tracker.keyframe_translation_m, d.tracker.keyframe_translation_m);
  EXPECT_DOUBLE_EQ(c->tracker.keyframe_rotation_rad, d.tracker.keyframe_rotation_rad);
  EXPECT_EQ(c->tracker.keyframes.capacity, d.tracker.keyframes.capacity);
  EXPECT_EQ(c->tracker.map_point_capacity, d.tracker.map_point_capacity);
  EXPECT_EQ(c->local_ba.window_keyframes, d.local_ba.window_keyframes);
  EXPECT_DOUBLE_EQ(c->local_ba.options.huber_px, d.local_ba.options.huber_px);
  EXPECT_DOUBLE_EQ(c->depth_sigma_per_m2, d.depth_sigma_per_m2);
  EXPECT_DOUBLE_EQ(c->imu_noise.gyro_noise_density, d.imu_noise.gyro_noise_density);
  EXPECT_DOUBLE_EQ(c->static_init.window_s, d.static_init.window_s);
}

TEST(EstimatorConfig, GivenKeyframeThresholdsWhenSetThenTheyAreUsed) {
  const std::string path =
      write_temp("estimation:\n  keyframes:\n    translation_m: 0.5\n    rotation_rad: 0.1\n");
  auto c = load_estimator_config(path);
  std::remove(path.c_str());
  ASSERT_TRUE(c.ok()) << c.status().message();
  EXPECT_DOUBLE_EQ(c->tracker.keyframe_translation_m, 0.5);
  EXPECT_DOUBLE_EQ(c->tracker.keyframe_rotation_rad, 0.1);
}

TEST(EstimatorConfig, GivenAnUnknownKeyOrABadValueThenTheErrorNamesIt) {
  std::string path = write_temp("estimation:\n  orb:\n    max_featurez: 500\n");
  auto c = load_estimator_config(path);
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.status().message().find("max_featurez"), std::string::npos) << c.status().message();
  std::remove(path.c_str());
  path = write_temp("estimation:\n  keyframes:\n    translation_m: -1\n");
  c = load_estimator_config(path);
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.status().message().find("translation_m"), std::string::npos) << c.status().message();
  std::remove(path.c_str());
  path = write_temp("estimation:\n  local_ba:\n    window_keyframes: many\n");
  c = load_estimator_config(path);
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.status().message().find("window_keyframes"), std::string::npos) << c.status().message();
  std::remove(path.c_str());
}

}  // namespace
}  // namespace hwr::estimation
