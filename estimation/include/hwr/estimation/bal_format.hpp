#pragma once
// "Bundle Adjustment in the Large" text files (Agarwal, Snavely, Seitz, Szeliski, ECCV 2010;
// grail.cs.washington.edu/projects/bal), the format of the Ladybug data in shared/data/bal-ladybug:
//
//   <num_cameras> <num_points> <num_observations>
//   <camera_index> <point_index> <x> <y>            (num_observations lines; centred pixels)
//   <R angle-axis (3)> <t (3)> <f> <k1> <k2>        (9 values per camera, one per line)
//   <X> <Y> <Z>                                     (3 values per point, one per line)
//
// The pose is T_cam_world (P = R X + t) and the projection is Snavely's: p = -P.xy / P.z,
// uv = f (1 + k1 |p|^2 + k2 |p|^4) p, i.e. BaCameraModel::kBalRadial with f, k1, k2 in BaIntrinsics
// (held fixed by the solver; fx = fy = f, cx = cy = 0 are filled in too).

#include <string>

#include "hwr/core/status.hpp"
#include "hwr/estimation/ba_problem.hpp"

namespace hwr::estimation {

// Reads a BAL file into a kBalRadial problem (every camera and point free, sigma_px = 1, no depth).
// Errors name the file and line: missing file (kNotFound), a header whose counts are negative,
// above INT_MAX, or more than the file's size can hold (checked before anything is allocated), a
// non-number, a non-finite value, an index out of range, a truncated file, trailing data
// (kParseError / kCorruptData).
core::Expected<BaProblem> read_bal(const std::string& path);

// Writes a problem as BAL text; every value is printed in the shortest form that reads back to the
// same double, so read_bal(write_bal(p)) reproduces p exactly except the rotation, which goes
// through angle-axis (so3_log / so3_exp: equal to ~1e-15). Fixed flags, sigma_px and depth are not
// representable in BAL and are dropped.
// kPinhole problems are converted, not refused: BAL's camera looks down -z with y up, so the pose
// is premultiplied by diag(1, -1, -1), f = fx, k1 = k2 = 0, and the observations become
// (u - cx, -(v - cy) fx / fy). The geometry is preserved exactly; with fx != fy the v residual (and
// its noise) is scaled by fx / fy, so the written problem is lossy in its weighting. Written
// atomically (core::write_file_atomic).
core::Status write_bal(const BaProblem& problem, const std::string& path);

}  // namespace hwr::estimation
