#pragma once
// Point clouds for `hwr-bench ndt`: small readers for the real scans in ../shared/data (PLY binary
// little-endian, PCD ascii / binary / binary_compressed, the libpointmatcher CSV), the voxel-grid
// downsampling both NDTs are fed (done once, before any timing, so ours and PCL get the same
// points), and rigid transforms. Bench-only; no PCL here, so the bench loads its data the same way
// whether or not the PCL peer is built.

#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "hwr/core/status.hpp"

namespace hwr::bench {

// Packed xyz, metres: point i at xyz[3i .. 3i+2].
struct XyzCloud {
  std::vector<float> xyz;
  int size() const { return static_cast<int>(xyz.size() / 3); }
  Eigen::Vector3f at(int i) const { return {xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]}; }
  void push(const Eigen::Vector3f& p) { xyz.insert(xyz.end(), {p.x(), p.y(), p.z()}); }
};

// PLY "format binary_little_endian 1.0" or "ascii 1.0" with float/double x, y, z properties on the
// vertex element (other vertex properties are skipped; only the vertex element is read).
core::Expected<XyzCloud> read_ply_xyz(const std::string& path);
// PCD v0.7 with x, y, z fields of type F size 4; DATA ascii, binary or binary_compressed (LZF,
// struct-of-arrays layout after decompression, as PCL writes it).
core::Expected<XyzCloud> read_pcd_xyz(const std::string& path);
// CSV with a header line whose first three columns are x, y, z (libpointmatcher's example clouds).
core::Expected<XyzCloud> read_csv_xyz(const std::string& path);
// Whitespace-separated 4x4 row-major matrix (small_gicp's T_target_source.txt).
core::Expected<Eigen::Isometry3d> read_matrix4_txt(const std::string& path);
// The gT00..gT33 row of `reading` in libpointmatcher's carCloudList.csv.
core::Expected<Eigen::Isometry3d> read_pointmatcher_pose(const std::string& list_csv,
                                                         const std::string& reading);

// One point per occupied cubic voxel of side leaf_m (origin at 0): the centroid of its points,
// non-finite points dropped; output in ascending voxel-key order (deterministic).
XyzCloud voxel_downsample(const XyzCloud& in, double leaf_m);
// p' = T p for every point.
XyzCloud transformed(const XyzCloud& in, const Eigen::Isometry3d& T);
// Points with |p| (distance from the sensor) within [min_m, max_m].
XyzCloud range_filtered(const XyzCloud& in, double min_m, double max_m);

// Root mean square of the distance from each point of `source` mapped by T to its nearest point in
// `target` (brute force over a voxel hash of target, cells of side cell_m; points without a
// neighbour within cell_m are skipped); used to check ground-truth conventions. NaN when no point
// has a neighbour.
double rms_nearest_distance(const XyzCloud& target, const XyzCloud& source, const Eigen::Isometry3d& T,
                            double cell_m);

}  // namespace hwr::bench
