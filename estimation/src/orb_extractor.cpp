#include "hwr/estimation/orb_extractor.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <string>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

namespace hwr::estimation {
namespace {

// Keypoints stay this far (level pixels) from a level's border: the orientation patch (radius 15)
// and OpenCV's descriptor border (edgeThreshold) fit inside. ORB-SLAM's EDGE_THRESHOLD.
constexpr int kEdgePx = 19;
constexpr int kPatchRadius = 15;  // 31 x 31 orientation / descriptor patch (ORB sec. 3.2, 4)
constexpr int kFastRadius = 3;    // the FAST-9 circle

}  // namespace

GridOrbExtractor::GridOrbExtractor(const OrbConfig& config, int width, int height)
    : config_(config), width_(width), height_(height) {
  config_.levels = std::max(1, config_.levels);
  config_.scale_factor = std::max(1.001f, config_.scale_factor);
  config_.grid_cell_px = std::max(8, config_.grid_cell_px);
  const int L = config_.levels;
  scale_.resize(static_cast<size_t>(L));
  pyramid_.resize(static_cast<size_t>(L));
  cell_cols_.resize(static_cast<size_t>(L));
  cell_rows_.resize(static_cast<size_t>(L));
  level_budget_.assign(static_cast<size_t>(L), 0);
  config_.max_fast_threshold = std::max(config_.max_fast_threshold, config_.fast_threshold);
  level_threshold_.assign(static_cast<size_t>(L), config_.fast_threshold);
  int max_cells = 1;
  for (int l = 0; l < L; ++l) {
    scale_[static_cast<size_t>(l)] = std::pow(config_.scale_factor, static_cast<float>(l));
    const int w = cvRound(width / scale_[static_cast<size_t>(l)]);
    const int h = cvRound(height / scale_[static_cast<size_t>(l)]);
    pyramid_[static_cast<size_t>(l)].create(std::max(h, 1), std::max(w, 1), CV_8UC1);
    const int region_w = std::max(0, w - 2 * kEdgePx), region_h = std::max(0, h - 2 * kEdgePx);
    cell_cols_[static_cast<size_t>(l)] =
        std::max(1, cvRound(static_cast<double>(region_w) / config_.grid_cell_px));
    cell_rows_[static_cast<size_t>(l)] =
        std::max(1, cvRound(static_cast<double>(region_h) / config_.grid_cell_px));
    max_cells = std::max(max_cells, cell_cols_[static_cast<size_t>(l)] * cell_rows_[static_cast<size_t>(l)]);
  }
  // Level budgets fall geometrically with the level's area ratio 1/s per level (ORB-SLAM's
  // nDesiredFeaturesPerScale), the last level takes the remainder.
  const double inv_s = 1.0 / config_.scale_factor;
  double per_level = config_.max_features * (1.0 - inv_s) / (1.0 - std::pow(inv_s, L));
  int assigned = 0;
  for (int l = 0; l < L - 1; ++l) {
    level_budget_[static_cast<size_t>(l)] = cvRound(per_level);
    assigned += level_budget_[static_cast<size_t>(l)];
    per_level *= inv_s;
  }
  level_budget_[static_cast<size_t>(L) - 1] = std::max(0, config_.max_features - assigned);

  // Intensity-centroid patch: for each row offset v, columns |u| <= umax[v] are in the disc.
  umax_.resize(kPatchRadius + 1);
  for (int v = 0; v <= kPatchRadius; ++v) {
    umax_[static_cast<size_t>(v)] =
        cvFloor(std::sqrt(static_cast<double>(kPatchRadius * kPatchRadius - v * v)) + 0.5);
  }

  const size_t candidate_capacity = static_cast<size_t>(width) * static_cast<size_t>(height) / 16 + 1024;
  fast_kps_.reserve(candidate_capacity);
  candidates_.reserve(candidate_capacity);
  order_.reserve(candidate_capacity);
  cell_count_.resize(static_cast<size_t>(max_cells));
  cell_start_.resize(static_cast<size_t>(max_cells) + 1);
  rank_pick_.reserve(static_cast<size_t>(max_cells));
  selected_.reserve(static_cast<size_t>(config_.max_features) + 64);
  descriptor_rows_.create(std::max(config_.max_features, 1), kOrbDescriptorBytes, CV_8U);
  // One level: descriptors are computed per pyramid level on the extractor's own pyramid.
  orb_ = cv::ORB::create(config_.max_features, config_.scale_factor, 1, kEdgePx, 0, 2, cv::ORB::FAST_SCORE,
                         2 * kPatchRadius + 1, config_.fast_threshold);
  level_kps_.reserve(static_cast<size_t>(config_.max_features) + 64);
}

GridOrbExtractor::~GridOrbExtractor() = default;

// FAST corners of one level into candidates_ (level pixels, cell index set). ORB-SLAM searches a
// cell again at min_fast_threshold when nothing fires at fast_threshold: one FAST pass over the
// level at its threshold, then the cells left empty are searched again at min_fast_threshold, each
// on its own window (the cell plus the FAST circle's radius). When most cells are empty (a dull
// image) one pass over the level at the lower threshold replaces the many small calls and gives the
// same corners (a FAST score is the largest threshold at which the pixel is a corner, and
// non-maximum suppression only compares scores): each cell then keeps its corners scoring at least
// the level threshold when it has any, else all of its corners.
void GridOrbExtractor::detect_level(int level) {
  const cv::Mat& img = pyramid_[static_cast<size_t>(level)];
  candidates_.clear();
  const int w = img.cols, h = img.rows;
  if (w <= 2 * kEdgePx || h <= 2 * kEdgePx) return;
  const int cols = cell_cols_[static_cast<size_t>(level)], rows = cell_rows_[static_cast<size_t>(level)];
  const float cell_w = static_cast<float>(w - 2 * kEdgePx) / static_cast<float>(cols);
  const float cell_h = static_cast<float>(h - 2 * kEdgePx) / static_cast<float>(rows);
  int& threshold = level_threshold_[static_cast<size_t>(level)];
  const int strong = threshold;
  const bool retry = config_.min_fast_threshold > 0 && config_.min_fast_threshold < strong;
  const int cells = cols * rows;
  std::fill(cell_count_.begin(), cell_count_.begin() + cells, 0);  // strong corners per cell

  // FAST on `region` (level pixels); corners inside the keypoint area go to candidates_. Corners
  // of cells that already have strong ones are skipped when add_to_empty_only (window overlap).
  auto add_corners = [&](const cv::Rect& region, int fast_threshold, bool add_to_empty_only) {
    cv::FAST(img(region), fast_kps_, fast_threshold, true);
    for (const auto& kp : fast_kps_) {
      const float x = kp.pt.x + static_cast<float>(region.x), y = kp.pt.y + static_cast<float>(region.y);
      if (x < kEdgePx || y < kEdgePx || x >= w - kEdgePx || y >= h - kEdgePx) continue;
      const int cx = std::min(cols - 1, static_cast<int>((x - kEdgePx) / cell_w));
      const int cy = std::min(rows - 1, static_cast<int>((y - kEdgePx) / cell_h));
      const int cell = cy * cols + cx;
      if (add_to_empty_only && cell_count_[static_cast<size_t>(cell)] > 0) continue;
      candidates_.push_back({x, y, kp.response, cell});
      if (!add_to_empty_only && kp.response >= strong) ++cell_count_[static_cast<size_t>(cell)];
    }
  };
  // The FAST circle needs kFastRadius pixels around each tested pixel, so a searched window
  // reaches kFastRadius beyond the keypoint area.
  const int o = kEdgePx - kFastRadius;
  const cv::Rect level_region(o, o, w - 2 * o, h - 2 * o);
  add_corners(level_region, strong, false);

  // Threshold control for the next frame (OrbConfig::corners_per_feature).
  if (config_.corners_per_feature > 0) {
    const double target =
        config_.corners_per_feature * std::max(1, level_budget_[static_cast<size_t>(level)]);
    const double n = static_cast<double>(candidates_.size());
    if (n > 2.0 * target) threshold = std::min(config_.max_fast_threshold, threshold + 2);
    if (n < 0.5 * target) threshold = std::max(config_.fast_threshold, threshold - 2);
  }
  if (!retry) return;
  int empty = 0;
  for (int c = 0; c < cells; ++c) empty += cell_count_[static_cast<size_t>(c)] == 0 ? 1 : 0;
  if (empty == 0) return;
  if (2 * empty > cells) {
    // Mostly empty: one low-threshold pass over the level, keeping the weak corners of the cells
    // that have no strong one.
    candidates_.clear();
    std::fill(cell_count_.begin(), cell_count_.begin() + cells, 0);
    add_corners(level_region, config_.min_fast_threshold, false);
    size_t kept = 0;
    for (size_t i = 0; i < candidates_.size(); ++i) {
      const Candidate& c = candidates_[i];
      if (c.response < strong && cell_count_[static_cast<size_t>(c.cell)] > 0) continue;
      candidates_[kept++] = c;
    }
    candidates_.resize(kept);
    return;
  }
  for (int cy = 0; cy < rows; ++cy) {
    for (int cx = 0; cx < cols; ++cx) {
      if (cell_count_[static_cast<size_t>(cy * cols + cx)] > 0) continue;
      const int x0 = kEdgePx + static_cast<int>(std::floor(static_cast<float>(cx) * cell_w)) - kFastRadius;
      const int y0 = kEdgePx + static_cast<int>(std::floor(static_cast<float>(cy) * cell_h)) - kFastRadius;
      const int x1 = std::min(
          w - o, kEdgePx + static_cast<int>(std::ceil(static_cast<float>(cx + 1) * cell_w)) + kFastRadius);
      const int y1 = std::min(
          h - o, kEdgePx + static_cast<int>(std::ceil(static_cast<float>(cy + 1) * cell_h)) + kFastRadius);
      if (x1 - x0 <= 2 * kFastRadius || y1 - y0 <= 2 * kFastRadius) continue;
      add_corners(cv::Rect(x0, y0, x1 - x0, y1 - y0), config_.min_fast_threshold, true);
    }
  }
}

// Round-robin over the cells: rank 0 (each cell's strongest corner) of every cell, then rank 1,
// ...; the last, partial rank goes to the strongest. Appends to selected_; returns the count.
int GridOrbExtractor::select_level(int level, int budget) {
  if (budget <= 0 || candidates_.empty()) return 0;
  const int cells = cell_cols_[static_cast<size_t>(level)] * cell_rows_[static_cast<size_t>(level)];
  std::fill(cell_count_.begin(), cell_count_.begin() + cells, 0);
  for (const auto& c : candidates_) ++cell_count_[static_cast<size_t>(c.cell)];
  cell_start_[0] = 0;
  for (int c = 0; c < cells; ++c)
    cell_start_[static_cast<size_t>(c) + 1] =
        cell_start_[static_cast<size_t>(c)] + cell_count_[static_cast<size_t>(c)];
  order_.resize(candidates_.size());
  for (int c = 0; c < cells; ++c) cell_count_[static_cast<size_t>(c)] = 0;
  for (int i = 0; i < static_cast<int>(candidates_.size()); ++i) {
    const int c = candidates_[static_cast<size_t>(i)].cell;
    order_[static_cast<size_t>(cell_start_[static_cast<size_t>(c)] + cell_count_[static_cast<size_t>(c)]++)] =
        i;
  }
  auto stronger = [&](int a, int b) {
    return candidates_[static_cast<size_t>(a)].response > candidates_[static_cast<size_t>(b)].response;
  };
  int max_count = 0;
  for (int c = 0; c < cells; ++c) {
    std::sort(order_.begin() + cell_start_[static_cast<size_t>(c)],
              order_.begin() + cell_start_[static_cast<size_t>(c) + 1], stronger);
    max_count = std::max(max_count, cell_count_[static_cast<size_t>(c)]);
  }
  const float s = scale_[static_cast<size_t>(level)];
  int taken = 0;
  for (int r = 0; r < max_count && taken < budget; ++r) {
    rank_pick_.clear();
    for (int c = 0; c < cells; ++c) {
      if (cell_count_[static_cast<size_t>(c)] > r)
        rank_pick_.push_back(order_[static_cast<size_t>(cell_start_[static_cast<size_t>(c)] + r)]);
    }
    if (taken + static_cast<int>(rank_pick_.size()) > budget) {
      std::sort(rank_pick_.begin(), rank_pick_.end(), stronger);
      rank_pick_.resize(static_cast<size_t>(budget - taken));
    }
    for (int i : rank_pick_) {
      const Candidate& c = candidates_[static_cast<size_t>(i)];
      cv::KeyPoint kp;
      kp.pt = cv::Point2f(c.x * s, c.y * s);
      kp.octave = level;
      kp.response = c.response;
      kp.size = (2 * kPatchRadius + 1) * s;
      kp.angle =
          ic_angle_deg(pyramid_[static_cast<size_t>(level)], static_cast<int>(c.x), static_cast<int>(c.y));
      kp.class_id = static_cast<int>(selected_.size());
      selected_.push_back(kp);
      ++taken;
    }
  }
  return taken;
}

// Orientation by the intensity centroid, theta = atan2(m01, m10) over a disc of radius 15
// (Rosin 1999; ORB sec. 3.2).
float GridOrbExtractor::ic_angle_deg(const cv::Mat& img, int x, int y) const {
  const int step = static_cast<int>(img.step1());
  const uint8_t* center = img.ptr<uint8_t>(y) + x;
  int m01 = 0, m10 = 0;
  for (int u = -kPatchRadius; u <= kPatchRadius; ++u) m10 += u * center[u];
  for (int v = 1; v <= kPatchRadius; ++v) {
    int v_sum = 0;
    const int d = umax_[static_cast<size_t>(v)];
    for (int u = -d; u <= d; ++u) {
      const int below = center[u + v * step], above = center[u - v * step];
      v_sum += below - above;
      m10 += u * (below + above);
    }
    m01 += v * v_sum;
  }
  float a = cv::fastAtan2(static_cast<float>(m01), static_cast<float>(m10));  // degrees, [0, 360)
  return a;
}

core::Status GridOrbExtractor::extract(const cv::Mat& gray, const cv::Mat& depth_m,
                                       const hal::PinholeIntrinsics& K, FrameFeatures* out) {
  if (out == nullptr) return core::InvalidArgument("GridOrbExtractor::extract: out is null");
  out->clear();
  if (gray.empty() || gray.type() != CV_8UC1) {
    return core::InvalidArgument(
        "GridOrbExtractor::extract: gray image must be CV_8UC1 and non-empty, got type " +
        std::to_string(gray.type()));
  }
  if (gray.cols != width_ || gray.rows != height_) {
    return core::InvalidArgument("GridOrbExtractor::extract: image is " + std::to_string(gray.cols) + "x" +
                                 std::to_string(gray.rows) + ", extractor built for " +
                                 std::to_string(width_) + "x" + std::to_string(height_));
  }
  const bool have_depth = !depth_m.empty();
  if (have_depth && (depth_m.type() != CV_32FC1 || depth_m.size() != gray.size())) {
    return core::InvalidArgument(
        "GridOrbExtractor::extract: depth must be CV_32FC1 of the image size (or empty)");
  }
  if (have_depth && !K.valid()) return core::InvalidArgument("GridOrbExtractor::extract: invalid intrinsics");

  const int L = config_.levels;
  if (out->scale_per_octave.size() != static_cast<size_t>(L))
    out->scale_per_octave.resize(static_cast<size_t>(L));
  for (int l = 0; l < L; ++l) out->scale_per_octave[static_cast<size_t>(l)] = scale_[static_cast<size_t>(l)];

  // Pyramid: each level bilinearly resized from the previous one (as OpenCV's ORB builds it);
  // orientation, corners and descriptors all use it. INTER_LINEAR, not INTER_LINEAR_EXACT: the
  // exact variant computes its weights in software floating point on every call (a fifth of the
  // extraction time).
  gray.copyTo(pyramid_[0]);
  for (int l = 1; l < L; ++l) {
    cv::resize(pyramid_[static_cast<size_t>(l) - 1], pyramid_[static_cast<size_t>(l)],
               pyramid_[static_cast<size_t>(l)].size(), 0, 0, cv::INTER_LINEAR);
  }

  const int max_out = std::min(config_.max_features, out->capacity());
  selected_.clear();
  int carry = 0;
  for (int l = 0; l < L; ++l) {
    const int room = max_out - static_cast<int>(selected_.size());
    const int budget = std::min(room, level_budget_[static_cast<size_t>(l)] + carry);
    if (budget <= 0) break;
    detect_level(l);
    const int taken = select_level(l, budget);
    carry = budget - taken;
  }
  if (selected_.empty()) {
    out->build_grid();
    return core::Status::Ok();
  }

  // rBRIEF descriptors (ORB sec. 4), level by level on the pyramid built above: OpenCV's ORB with
  // one level adds a border, Gaussian-smooths and samples its learned pattern, steered by kp.angle.
  // Each level's rows of descriptor_rows_ have the right shape, so OpenCV writes into them without
  // reallocating. OpenCV may drop a keypoint (image border); class_id maps rows back.
  Feature f;
  size_t begin = 0;
  int row0 = 0;
  for (int l = 0; l < L && begin < selected_.size(); ++l) {
    size_t end = begin;
    while (end < selected_.size() && selected_[end].octave == l) ++end;
    if (end == begin) continue;
    level_kps_.assign(selected_.begin() + static_cast<std::ptrdiff_t>(begin),
                      selected_.begin() + static_cast<std::ptrdiff_t>(end));
    const float inv_s = 1.f / scale_[static_cast<size_t>(l)];
    for (auto& kp : level_kps_) {
      // FAST corners sit on integer level pixels: round away the level-0 scaling.
      kp.pt = cv::Point2f(std::round(kp.pt.x * inv_s), std::round(kp.pt.y * inv_s));
      kp.octave = 0;
      kp.size = 2 * kPatchRadius + 1;
    }
    cv::Mat rows = descriptor_rows_.rowRange(row0, row0 + static_cast<int>(end - begin));
    orb_->compute(pyramid_[static_cast<size_t>(l)], level_kps_, rows);
    row0 += static_cast<int>(end - begin);
    begin = end;
    for (int j = 0; j < static_cast<int>(level_kps_.size()) && j < rows.rows; ++j) {
      const cv::KeyPoint& kp = selected_[static_cast<size_t>(level_kps_[static_cast<size_t>(j)].class_id)];
      f.u_px = kp.pt.x;
      f.v_px = kp.pt.y;
      f.octave = kp.octave;
      f.angle_deg = kp.angle;
      f.response = kp.response;
      f.depth_m = 0;
      f.p_cam_m.setZero();
      if (have_depth) {
        const int px = cvRound(kp.pt.x), py = cvRound(kp.pt.y);
        if (px >= 1 && py >= 1 && px < width_ - 1 && py < height_ - 1) {
          const float d = depth_m.at<float>(py, px);
          if (std::isfinite(d) && d >= config_.min_depth_m && d <= config_.max_depth_m) {
            float lo = d, hi = d;
            bool all_valid = true;
            for (int dy = -1; dy <= 1 && all_valid; ++dy) {
              const float* row = depth_m.ptr<float>(py + dy);
              for (int dx = -1; dx <= 1; ++dx) {
                const float q = row[px + dx];
                if (!(std::isfinite(q) && q > 0)) {
                  all_valid = false;
                  break;
                }
                lo = std::min(lo, q);
                hi = std::max(hi, q);
              }
            }
            if (all_valid && hi - lo <= config_.max_depth_spread * d) {
              // Eq. (3): back-projection through the pinhole intrinsics.
              f.depth_m = d;
              f.p_cam_m = Eigen::Vector3d((kp.pt.x - K.cx) * d / K.fx, (kp.pt.y - K.cy) * d / K.fy, d);
            }
          }
        }
      }
      out->push_back(f, rows.ptr<uint8_t>(j));
    }
  }
  out->build_grid();
  return core::Status::Ok();
}

}  // namespace hwr::estimation
