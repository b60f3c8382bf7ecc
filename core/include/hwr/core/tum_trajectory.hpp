#pragma once
// TUM RGB-D trajectory files: one pose per line, "timestamp tx ty tz qx qy qz qw", '#' comments.
// The pose maps body points into the trajectory's frame (T_world_body, ARCHITECTURE.md naming).

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "hwr/core/status.hpp"

namespace hwr::core {

struct StampedPose {
  int64_t t_ns = 0;
  Eigen::Isometry3d T_world_body = Eigen::Isometry3d::Identity();
};

// Reads and validates a whole file: every non-comment line must have 8 numbers, a finite
// quaternion of norm within 1e-2 of 1 (normalised on load), and timestamps strictly increasing.
// Errors name the file and line, e.g. "groundtruth.txt:17: expected 8 numbers, got 5".
Expected<std::vector<StampedPose>> read_tum_trajectory(const std::string& path);
// Same, from text already in memory (source_name used in messages).
Expected<std::vector<StampedPose>> parse_tum_trajectory(const std::string& text,
                                                        const std::string& source_name);

// Writes with 9 fractional digits of seconds (nanoseconds survive a round trip) and a header,
// atomically (core/file_io.hpp: a killed writer never leaves a truncated file).
Status write_tum_trajectory(const std::string& path, const std::vector<StampedPose>& poses,
                            const std::string& header_comment = "");

}  // namespace hwr::core
