// Sensor effects: depth noise statistics against sigma(z) = sigma_c + sigma_q z^2, hole fraction
// against the spec, edge dropout at a known step, exposure gain and noise, determinism by seed.

#include <cmath>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "hwr/sim/camera_effects.hpp"

namespace hwr::sim {
namespace {

DepthNoiseSpec noise_only() {
  DepthNoiseSpec spec;
  spec.hole_fraction = 0.0;
  spec.edge_dropout_ratio = 0.0;
  return spec;
}

// Empirical sigma of the noise on a flat depth image z.
double empirical_sigma(const DepthNoiseSpec& spec, float z, uint64_t seed) {
  cv::Mat depth(480, 640, CV_32FC1, cv::Scalar(z));
  apply_depth_noise(spec, seed, &depth);
  double sum = 0.0, sum2 = 0.0;
  for (int v = 0; v < depth.rows; ++v) {
    for (int u = 0; u < depth.cols; ++u) {
      const double e = depth.at<float>(v, u) - z;
      sum += e;
      sum2 += e * e;
    }
  }
  const double n = static_cast<double>(depth.total());
  EXPECT_NEAR(sum / n, 0.0, 5.0 * std::sqrt(sum2 / n) / std::sqrt(n)) << "noise must be zero-mean";
  return std::sqrt(sum2 / n);
}

TEST(DepthNoise, SigmaFollowsRangeModelAtOneAndFourMetres) {
  const DepthNoiseSpec spec = noise_only();
  for (const float z : {1.0f, 4.0f}) {
    const double model = spec.sigma_const_m + spec.sigma_quad_per_m * z * z;
    const double got = empirical_sigma(spec, z, 11);
    EXPECT_NEAR(got, model, 0.1 * model) << "z = " << z;
    // With 307200 samples the estimate is within about 0.4 % of the truth (float rounding aside).
    EXPECT_NEAR(got, model, 0.02 * model) << "z = " << z;
  }
}

TEST(DepthNoise, GaussianShape) {
  const DepthNoiseSpec spec = noise_only();
  const float z = 2.0f;
  const double sigma = spec.sigma_const_m + spec.sigma_quad_per_m * z * z;
  cv::Mat depth(480, 640, CV_32FC1, cv::Scalar(z));
  apply_depth_noise(spec, 5, &depth);
  int within1 = 0, within2 = 0;
  for (int v = 0; v < depth.rows; ++v) {
    for (int u = 0; u < depth.cols; ++u) {
      const double e = std::abs(depth.at<float>(v, u) - z) / sigma;
      within1 += e < 1.0;
      within2 += e < 2.0;
    }
  }
  const double n = static_cast<double>(depth.total());
  EXPECT_NEAR(within1 / n, 0.6827, 0.005);
  EXPECT_NEAR(within2 / n, 0.9545, 0.003);
}

TEST(DepthNoise, InvalidPixelsStayInvalidAndDisabledSpecIsIdentity) {
  cv::Mat depth(100, 100, CV_32FC1, cv::Scalar(2.0f));
  depth(cv::Rect(10, 10, 30, 30)).setTo(0.0f);
  cv::Mat clean = depth.clone();
  DepthNoiseSpec spec = noise_only();
  spec.enabled = false;
  apply_depth_noise(spec, 1, &depth);
  EXPECT_EQ(cv::norm(depth, clean, cv::NORM_INF), 0.0);
  spec.enabled = true;
  apply_depth_noise(spec, 1, &depth);
  EXPECT_EQ(cv::countNonZero(depth(cv::Rect(10, 10, 30, 30))), 0);
  EXPECT_EQ(cv::countNonZero(depth), 100 * 100 - 30 * 30);
}

TEST(DepthNoise, HoleFractionMatchesSpec) {
  for (const double fraction : {0.01, 0.05, 0.2}) {
    DepthNoiseSpec spec;
    spec.hole_fraction = fraction;
    spec.hole_radius_px = 6;
    double holes = 0.0;
    constexpr int kSeeds = 10;
    for (int seed = 0; seed < kSeeds; ++seed) {
      cv::Mat depth(480, 640, CV_32FC1, cv::Scalar(1.5f));
      apply_depth_noise(spec, seed, &depth);
      holes += 1.0 - cv::countNonZero(depth) / static_cast<double>(depth.total());
    }
    EXPECT_NEAR(holes / kSeeds, fraction, 0.15 * fraction) << "fraction " << fraction;
  }
}

TEST(DepthNoise, HolesAreRoundBlobs) {
  DepthNoiseSpec spec = noise_only();
  spec.hole_fraction = 0.002;
  spec.hole_radius_px = 8;
  cv::Mat depth(480, 640, CV_32FC1, cv::Scalar(1.0f));
  apply_depth_noise(spec, 3, &depth);
  // Every hole pixel has at least 3 hole 4-neighbours or sits on a disc rim: no isolated pixels.
  int holes = 0, isolated = 0;
  for (int v = 1; v + 1 < depth.rows; ++v) {
    for (int u = 1; u + 1 < depth.cols; ++u) {
      if (depth.at<float>(v, u) != 0.0f) continue;
      ++holes;
      const int n = (depth.at<float>(v - 1, u) == 0.0f) + (depth.at<float>(v + 1, u) == 0.0f) +
                    (depth.at<float>(v, u - 1) == 0.0f) + (depth.at<float>(v, u + 1) == 0.0f);
      isolated += n == 0;
    }
  }
  EXPECT_GT(holes, 0);
  EXPECT_EQ(isolated, 0);
}

TEST(DepthNoise, EdgeDropoutRemovesBothSidesOfAStep) {
  DepthNoiseSpec spec = noise_only();
  spec.sigma_const_m = 0.0;
  spec.sigma_quad_per_m = 0.0;
  spec.edge_dropout_ratio = 0.1;
  cv::Mat depth(60, 80, CV_32FC1, cv::Scalar(1.0f));
  depth.colRange(40, 80).setTo(2.0f);
  depth.at<float>(30, 10) = 1.05f;  // a 5 % bump stays
  apply_depth_noise(spec, 9, &depth);
  for (int v = 0; v < depth.rows; ++v) {
    for (int u = 0; u < depth.cols; ++u) {
      const bool at_step = u == 39 || u == 40;
      EXPECT_EQ(depth.at<float>(v, u) == 0.0f, at_step) << u << ", " << v;
    }
  }
}

TEST(DepthNoise, DeterministicBySeed) {
  DepthNoiseSpec spec;
  spec.hole_fraction = 0.03;
  spec.edge_dropout_ratio = 0.05;
  cv::Mat base(240, 320, CV_32FC1);
  for (int v = 0; v < base.rows; ++v) {
    for (int u = 0; u < base.cols; ++u) base.at<float>(v, u) = 0.5f + 0.01f * u + (v > 120 ? 1.0f : 0.0f);
  }
  cv::Mat a = base.clone(), b = base.clone(), c = base.clone();
  apply_depth_noise(spec, 77, &a);
  apply_depth_noise(spec, 77, &b);
  apply_depth_noise(spec, 78, &c);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a, c, cv::NORM_INF), 0.0);
  // Noise at a pixel depends on (seed, pixel) only, not on the image content elsewhere.
  cv::Mat d = base.clone();
  d.rowRange(0, 10).setTo(3.0f);
  spec.hole_fraction = 0.0;
  spec.edge_dropout_ratio = 0.0;
  cv::Mat e = base.clone();
  apply_depth_noise(spec, 5, &d);
  apply_depth_noise(spec, 5, &e);
  EXPECT_EQ(cv::norm(d.rowRange(20, 240), e.rowRange(20, 240), cv::NORM_INF), 0.0);
}

TEST(Exposure, GainWithoutNoiseIsExactSaturatingScale) {
  cv::Mat bgr(16, 16, CV_8UC3);
  for (int v = 0; v < 16; ++v) {
    for (int u = 0; u < 16; ++u) bgr.at<cv::Vec3b>(v, u) = cv::Vec3b(u * 16, v * 16, (u + v) * 8);
  }
  const cv::Mat clean = bgr.clone();
  ExposureSpec spec;
  spec.gain = 1.5;
  spec.pixel_noise_sigma = 0.0;
  apply_exposure(spec, 1, &bgr);
  for (int v = 0; v < 16; ++v) {
    for (int u = 0; u < 16; ++u) {
      for (int c = 0; c < 3; ++c) {
        const int expected = std::min(255, static_cast<int>(std::lround(1.5 * clean.at<cv::Vec3b>(v, u)[c])));
        EXPECT_NEAR(bgr.at<cv::Vec3b>(v, u)[c], expected, 1) << u << "," << v << "," << c;
      }
    }
  }
}

TEST(Exposure, PixelNoiseSigmaAndDeterminism) {
  ExposureSpec spec;
  spec.gain = 1.0;
  spec.pixel_noise_sigma = 5.0;
  cv::Mat a(480, 640, CV_8UC3, cv::Scalar(128, 128, 128));
  cv::Mat b = a.clone(), c = a.clone();
  apply_exposure(spec, 21, &a);
  apply_exposure(spec, 21, &b);
  apply_exposure(spec, 22, &c);
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a, c, cv::NORM_INF), 0.0);
  cv::Scalar mean, stddev;
  cv::meanStdDev(a.reshape(1), mean, stddev);
  EXPECT_NEAR(mean[0], 128.0, 0.1);
  // Rounding to integers adds 1/12 level^2 of variance.
  EXPECT_NEAR(stddev[0], std::sqrt(25.0 + 1.0 / 12.0), 0.1 * 5.0);
  // Channels get independent noise.
  std::vector<cv::Mat> ch;
  cv::split(a, ch);
  cv::Mat b0, b1;
  ch[0].convertTo(b0, CV_64F, 1, -128);
  ch[1].convertTo(b1, CV_64F, 1, -128);
  EXPECT_LT(std::abs(b0.dot(b1) / b0.total()), 0.2);
}

TEST(Exposure, SaturatesAtBothEnds) {
  ExposureSpec spec;
  spec.gain = 1.0;
  spec.pixel_noise_sigma = 40.0;
  cv::Mat img(100, 100, CV_8UC3, cv::Scalar(0, 255, 128));
  apply_exposure(spec, 4, &img);
  double lo, hi;
  cv::minMaxLoc(img.reshape(1), &lo, &hi);
  EXPECT_EQ(lo, 0.0);
  EXPECT_EQ(hi, 255.0);
}

}  // namespace
}  // namespace hwr::sim
