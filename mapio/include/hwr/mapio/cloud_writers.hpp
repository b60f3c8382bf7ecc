#pragma once
// Point-cloud files for the ground station's per-segment and merged maps (issue #5 item 4), readable
// by PCL and Open3D, and minimal readers for exactly these layouts (tests, hwr-bench transfer).
//
// PLY (PLY 1.0, http://paulbourke.net/dataformats/ply/), binary_little_endian, one element:
//   ply
//   format binary_little_endian 1.0
//   element vertex N
//   property float x | y | z
//   property float nx | ny | nz        (only with normals)
//   property uchar red | green | blue
//   end_header
// then N packed records of 15 bytes (27 with normals). The property order is Open3D's.
//
// PCD (PCL's format v0.7, pointclouds.org/documentation/tutorials/pcd_file_format.html), DATA binary:
//   FIELDS x y z rgb [normal_x normal_y normal_z], SIZE 4, TYPE F, COUNT 1, WIDTH N, HEIGHT 1,
//   VIEWPOINT 0 0 0 1 0 0 0, POINTS N; then N packed records of 16 bytes (28 with normals).
//   rgb follows PCL's PointXYZRGB convention: the uint32 (r << 16) | (g << 8) | b, its bytes stored
//   as the float field (alpha byte 0).
//
// Both writers are atomic (PATH.tmp, fsync, rename, folder fsync): a killed writer leaves the old
// file or the complete new one. They stream through a fixed buffer, so a map of millions of points
// is not copied in memory first.

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "hwr/core/status.hpp"

namespace hwr::mapio {

// Points as flat arrays, what the readers return: xyz and rgb hold 3 n values, normals 3 n when
// has_normals (the file declares normal fields, also with 0 points), else none.
struct CloudArrays {
  std::vector<float> xyz;
  std::vector<uint8_t> rgb;
  std::vector<float> normals;
  bool has_normals = false;
  size_t size() const { return xyz.size() / 3; }
};

// xyz: 3 n floats (metres), rgb: 3 n bytes, normals_or_null: 3 n floats, or nullptr for a file
// without normal fields (any non-null pointer declares them, also when n = 0). kInvalidArgument for null
// arrays with n > 0, kIoError naming the path otherwise.
core::Status write_ply(const std::string& path, const float* xyz, const uint8_t* rgb,
                       const float* normals_or_null, size_t n);
core::Status write_pcd(const std::string& path, const float* xyz, const uint8_t* rgb,
                       const float* normals_or_null, size_t n);

// PCL's packing of one colour into PCD's float rgb field, and back.
float pack_pcl_rgb(uint8_t r, uint8_t g, uint8_t b);
void unpack_pcl_rgb(float rgb, uint8_t* r, uint8_t* g, uint8_t* b);

// Read files of exactly the layouts above (PLY comment lines are skipped). kNotFound / kIoError for
// the file, kParseError for another layout, kCorruptData when the data does not match the point
// count (checked before anything is allocated).
core::Status read_ply(const std::string& path, CloudArrays* out);
core::Status read_pcd(const std::string& path, CloudArrays* out);

}  // namespace hwr::mapio
