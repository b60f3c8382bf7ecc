#include "paper_plots.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "hwr/estimation/trajectory_metrics.hpp"

namespace hwr::bench::paper {
namespace {

constexpr int kShift = 4;  // sub-pixel bits of the polylines
constexpr double kSub = 1 << kShift;

// Grid step: 1, 2 or 5 x 10^k m, about `count` steps over the span.
double nice_step(double span, int count) {
  const double raw = std::max(span, 1e-6) / count;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0})
    if (m * p >= raw) return m * p;
  return 10 * p;
}

std::string tick_text(double v, double step) {
  char buf[32];
  const int decimals = step >= 1 ? 0 : static_cast<int>(std::ceil(-std::log10(step) - 1e-9));
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, std::abs(v) < step * 1e-6 ? 0.0 : v);
  return buf;
}

void text(cv::Mat& img, const std::string& s, cv::Point at, double scale, int thickness = 1,
          cv::Scalar colour = cv::Scalar(30, 30, 30)) {
  cv::putText(img, s, at, cv::FONT_HERSHEY_SIMPLEX, scale, colour, thickness, cv::LINE_AA);
}

cv::Size text_size(const std::string& s, double scale, int thickness = 1) {
  int base = 0;
  return cv::getTextSize(s, cv::FONT_HERSHEY_SIMPLEX, scale, thickness, &base);
}

}  // namespace

core::Status write_trajectory_png(const std::string& path, const std::string& title,
                                  const std::vector<PlotTrack>& tracks, int width, int height) {
  double x0 = HUGE_VAL, x1 = -HUGE_VAL, y0 = HUGE_VAL, y1 = -HUGE_VAL;
  for (const PlotTrack& t : tracks) {
    for (const core::StampedPose& p : t.poses) {
      const Eigen::Vector3d v = p.T_world_body.translation();
      if (!v.allFinite()) continue;
      x0 = std::min(x0, v.x());
      x1 = std::max(x1, v.x());
      y0 = std::min(y0, v.y());
      y1 = std::max(y1, v.y());
    }
  }
  if (!(x0 <= x1)) return core::InvalidArgument("plot " + path + ": no finite pose to draw");
  // At least 0.5 m shown, 5 % around the data.
  const double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1);
  const double span_x = std::max(0.5, 1.1 * (x1 - x0)), span_y = std::max(0.5, 1.1 * (y1 - y0));

  const int left = 80, right = 30, top = 60, bottom = 70;
  const cv::Rect area(left, top, width - left - right, height - top - bottom);
  // Equal scales: metres per pixel the same on both axes.
  const double px_per_m = std::min(area.width / span_x, area.height / span_y);
  const double half_w = 0.5 * area.width / px_per_m, half_h = 0.5 * area.height / px_per_m;
  const double vx0 = cx - half_w, vx1 = cx + half_w, vy0 = cy - half_h, vy1 = cy + half_h;
  const auto to_px = [&](double x, double y) {
    return cv::Point2d(area.x + (x - vx0) * px_per_m, area.y + area.height - (y - vy0) * px_per_m);
  };

  cv::Mat img(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  // Grid and ticks.
  const double step = nice_step(std::max(vx1 - vx0, vy1 - vy0), 10);
  for (double x = std::ceil(vx0 / step) * step; x <= vx1; x += step) {
    const int u = static_cast<int>(std::lround(to_px(x, 0).x));
    cv::line(img, {u, area.y}, {u, area.y + area.height}, cv::Scalar(225, 225, 225), 1);
    const std::string s = tick_text(x, step);
    text(img, s, {u - text_size(s, 0.45).width / 2, area.y + area.height + 20}, 0.45);
  }
  for (double y = std::ceil(vy0 / step) * step; y <= vy1; y += step) {
    const int v = static_cast<int>(std::lround(to_px(0, y).y));
    cv::line(img, {area.x, v}, {area.x + area.width, v}, cv::Scalar(225, 225, 225), 1);
    const std::string s = tick_text(y, step);
    text(img, s, {area.x - 8 - text_size(s, 0.45).width, v + 5}, 0.45);
  }
  cv::rectangle(img, area, cv::Scalar(80, 80, 80), 1);
  text(img, "x [m]", {area.x + area.width / 2 - 20, height - 18}, 0.6);
  text(img, "y [m]", {8, area.y - 12}, 0.6);
  text(img, title, {area.x, 30}, 0.65, 1);

  // Tracks: the thick ones (ground truth) first, under the estimates.
  std::vector<const PlotTrack*> order;
  for (const PlotTrack& t : tracks) order.push_back(&t);
  std::stable_sort(order.begin(), order.end(),
                   [](const PlotTrack* a, const PlotTrack* b) { return a->thick > b->thick; });
  std::vector<cv::Point2d> drawn;  // every track point, in pixels
  for (const PlotTrack* t : order) {
    std::vector<cv::Point> pts;
    for (const core::StampedPose& p : t->poses) {
      const Eigen::Vector3d v = p.T_world_body.translation();
      if (!v.allFinite()) continue;
      const cv::Point2d q = to_px(v.x(), v.y());
      drawn.push_back(q);
      pts.emplace_back(static_cast<int>(std::lround(q.x * kSub)), static_cast<int>(std::lround(q.y * kSub)));
    }
    if (pts.empty()) continue;
    const cv::Scalar colour(t->bgr[0], t->bgr[1], t->bgr[2]);
    cv::polylines(img, pts, false, colour, t->thick ? 4 : 2, cv::LINE_AA, kShift);
    cv::circle(img, pts.front(), static_cast<int>(6 * kSub), colour, 2, cv::LINE_AA, kShift);
    const cv::Point e = pts.back();
    const int h = static_cast<int>(5 * kSub);
    cv::rectangle(img, cv::Point(e.x - h, e.y - h), cv::Point(e.x + h, e.y + h), colour, 2, cv::LINE_AA,
                  kShift);
  }

  // Legend, in the corner of the plot that hides the fewest drawn points (top right on a tie).
  int legend_w = 0;
  for (const PlotTrack& t : tracks) legend_w = std::max(legend_w, text_size(t.label, 0.5).width);
  legend_w += 70;
  const int row_h = 24;
  const int legend_h = row_h * static_cast<int>(tracks.size() + 1) + 8;
  const int lx0 = area.x + 10, lx1 = area.x + area.width - legend_w - 10;
  const int ly0 = area.y + 10, ly1 = area.y + area.height - legend_h - 10;
  cv::Rect box(lx1, ly0, legend_w, legend_h);
  size_t fewest = SIZE_MAX;
  for (const cv::Point corner :
       {cv::Point(lx1, ly0), cv::Point(lx0, ly0), cv::Point(lx1, ly1), cv::Point(lx0, ly1)}) {
    const cv::Rect candidate(corner.x, corner.y, legend_w, legend_h);
    size_t hidden = 0;
    for (const cv::Point2d& q : drawn)
      if (candidate.contains(cv::Point(static_cast<int>(q.x), static_cast<int>(q.y)))) ++hidden;
    if (hidden < fewest) {
      fewest = hidden;
      box = candidate;
    }
  }
  cv::rectangle(img, box, cv::Scalar(255, 255, 255), cv::FILLED);
  cv::rectangle(img, box, cv::Scalar(120, 120, 120), 1);
  for (size_t i = 0; i < tracks.size(); ++i) {
    const int v = box.y + 18 + row_h * static_cast<int>(i);
    const cv::Scalar colour(tracks[i].bgr[0], tracks[i].bgr[1], tracks[i].bgr[2]);
    cv::line(img, {box.x + 10, v - 5}, {box.x + 50, v - 5}, colour, tracks[i].thick ? 4 : 2, cv::LINE_AA);
    text(img, tracks[i].label, {box.x + 60, v}, 0.5);
  }
  text(img, "o start   [] end", {box.x + 10, box.y + 18 + row_h * static_cast<int>(tracks.size())}, 0.45);

  try {
    if (!cv::imwrite(path, img)) return core::IoError("cannot write " + path);
  } catch (const cv::Exception& e) {
    return core::IoError("cannot write " + path + ": " + e.what());
  }
  return core::Status::Ok();
}

core::Expected<AlignedTrack> align_to_groundtruth(const std::vector<core::StampedPose>& groundtruth,
                                                  const std::vector<core::StampedPose>& estimate) {
  auto ate = estimation::compute_ate(groundtruth, estimate, estimation::AteOptions{});
  if (!ate.ok()) return ate.status();
  AlignedTrack out;
  out.ate_rmse_m = ate->translation_m.rmse;
  out.pairs = ate->pairs;
  out.poses = estimate;
  for (core::StampedPose& p : out.poses) p.T_world_body = ate->T_gt_est * p.T_world_body;
  return out;
}

std::vector<core::StampedPose> groundtruth_span(const std::vector<core::StampedPose>& groundtruth,
                                                const std::vector<core::StampedPose>& estimate) {
  if (estimate.empty()) return groundtruth;
  const int64_t t0 = estimate.front().t_ns, t1 = estimate.back().t_ns;
  std::vector<core::StampedPose> out;
  for (const core::StampedPose& p : groundtruth)
    if (p.t_ns >= t0 && p.t_ns <= t1) out.push_back(p);
  return out;
}

}  // namespace hwr::bench::paper
