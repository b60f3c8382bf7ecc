#pragma once
// The point stream of `hwr-bench transfer` (issue #5, Table II reproduction): what the local mapper
// hands its MapStreamSink while a sim sequence runs through the pipeline, every batch stamped with
// the simulated time of the frame during which it was produced (the mapping timeline), and the maps
// of N points the bench transfers, cut from the front of that stream.

#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "hwr/core/status.hpp"
#include "hwr/mapio/chunk_codec.hpp"

namespace hwr::bench {

struct StreamBatch {
  int32_t segment_id = 0;
  Eigen::Isometry3d T_world_segment = Eigen::Isometry3d::Identity();
  int64_t t_ns = 0;  // simulated time since the sequence's first frame
  bool segment_complete = false;
  size_t first = 0;  // index of the batch's first point in PointStream::points_segment
  int n = 0;
};

struct PointStream {
  std::string name;                               // the sequence
  std::vector<mapio::ChunkPoint> points_segment;  // every batch's points, in stream order
  std::vector<StreamBatch> batches;
  int64_t duration_ns = 0;  // simulated time of the stream (first frame to the last batch)
  size_t frames = 0;        // frames run through the pipeline
  double pipeline_wall_s = 0;
  bool cut_short = false;  // the capture stopped once max_points were streamed

  size_t size() const { return points_segment.size(); }
};

// Runs the sim sequence `name` (bench_sequences.hpp) through the estimator and a LocalMapper with the
// default settings and records its MapStreamSink batches. Stops feeding frames once max_points
// points were streamed (0: the whole sequence).
core::Expected<PointStream> capture_point_stream(const std::string& name, size_t max_points);

// The streams one after the other (each later stream's segment ids and times moved past the ones
// before), repeated with new segment ids and later times until at least n points are there, then
// cut after point n. The batch holding point n is cut there and marked segment_complete: the robot
// stops and its last segment closes.
PointStream first_points(const std::vector<PointStream>& streams, size_t n);

// A capture kept between runs (--stream-cache FILE, e.g. under /tmp): the streams and the key they were
// made for (sequences and point budget). load_point_streams returns kNotFound when the file is missing
// or was made for another key, kCorruptData when it is damaged.
core::Status save_point_streams(const std::string& path, const std::string& key,
                                const std::vector<PointStream>& s);
core::Expected<std::vector<PointStream>> load_point_streams(const std::string& path, const std::string& key);

}  // namespace hwr::bench
