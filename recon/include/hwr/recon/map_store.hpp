#pragma once
// The on-disk map store (issue #4 item 4): closed local maps ("segments") of a run, each with its
// keyframes (poses, ORB features and descriptors, GNSS / magnetometer metadata), its point cloud in
// the segment frame and the junction to the previous segment. The robot writes a segment once, when
// it closes, so its memory stays bounded however long it runs; the relocalization issue reads the
// store back lazily (one segment at a time), mapio streams it.
//
// Layout of a store directory:
//   DIR/store.yaml                    run metadata (format version, robot/run id, intrinsics)
//   DIR/segments/seg_NNNNNN/          one closed segment, complete or absent:
//       segment.yaml                  id, poses, junction, counts, travelled distance, CRC32s
//       keyframes.bin                 keyframe records (little-endian, see map_store.cpp)
//       cloud.bin                     CloudPoint array, segment frame
//       fine.bin                      weld regions and the fine cloud with its counts (format 2 on;
//                                     layout in map_store_binary.hpp)
// Atomicity: a segment is written into DIR/segments/.tmp-seg_NNNNNN-<pid>/, every file fsync'ed,
// then renamed to seg_NNNNNN and the parent directory fsync'ed; a crash at any moment leaves either
// the whole segment or a .tmp- directory that open() deletes. Every read is validated (magic,
// version, sizes against the file length, CRC32 of each payload) before anything is allocated, so a
// corrupt or truncated file is an error, never a crash or a huge allocation.

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "hwr/core/status.hpp"
#include "hwr/hal/pinhole_camera.hpp"
#include "hwr/recon/keyframe_cloud.hpp"
#include "hwr/recon/weld_region.hpp"

namespace hwr::recon {

struct StoreMetadata {
  uint32_t format_version = 2;  // what a new store is created at (map_store.cpp: 1 and 2 are read)
  std::string robot_id = "hwr-0";
  std::string run_id;  // e.g. UTC start time "20261124T195600Z"
  hal::PinholeIntrinsics intrinsics;
  int descriptor_bytes = 32;  // ORB
  // The camera in the IMU frame (the run's extrinsic calibration): relocalization needs the IMU's
  // attitude at each keyframe to turn its stored magnetometer sample (IMU frame) into a heading
  // (relocalization_priors.hpp: R_world_imu = (T_world_cam * T_imu_cam^-1).linear()). A store
  // written before this field existed reads back as identity. Must be rigid (validated on write
  // and read).
  Eigen::Isometry3d T_imu_cam = Eigen::Isometry3d::Identity();
  // Read back: whether store.yaml held T_imu_cam (false for older stores: the identity above is then
  // not a calibration, and a reader should use its own robot's or refuse the magnetometer heading).
  bool T_imu_cam_recorded = false;
};

struct StoredFeature {
  float u_px = 0, v_px = 0;  // keypoint in the keyframe image
  float depth_m = 0;         // 0: no depth
  uint8_t octave = 0;
};

struct StoredKeyframe {
  int32_t id = -1;  // the run's keyframe id
  int64_t t_ns = 0;
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  std::vector<StoredFeature> features;
  std::vector<uint8_t> descriptors;  // features.size() * descriptor_bytes
  // Metadata for relocalization (issue #6); valid flags false when the sensor gave nothing.
  bool gnss_valid = false;
  double lat_deg = 0, lon_deg = 0, alt_m = 0;
  bool mag_valid = false;
  Eigen::Vector3d mag_imu_uT = Eigen::Vector3d::Zero();  // magnetometer, IMU frame
};

struct JunctionRecord {
  bool valid = false;  // false for the first segment and when alignment failed
  int32_t keyframe_before = -1, keyframe_after = -1;
  int orb_matches = 0, orb_inliers = 0;
  bool ndt_converged = false;
  int ndt_iterations = 0;
  double ndt_fitness = 0;
  // The refined junction: pose of this segment's frame in the previous segment's frame.
  Eigen::Isometry3d T_prev_segment_segment = Eigen::Isometry3d::Identity();
  // The estimator's (odometry) value of the same, for comparison.
  Eigen::Isometry3d T_prev_segment_segment_odometry = Eigen::Isometry3d::Identity();
  // The ORB/NDT measurement alone (before fusion with the odometry), and whether it was fused.
  Eigen::Isometry3d T_prev_segment_segment_measured = Eigen::Isometry3d::Identity();
  bool fused = false;
  bool ndt_used = false;       // the measurement is NDT's pose (else ORB's, or the odometry's)
  bool odometry_kept = false;  // ORB's pose alone agreed with the odometry, which was kept (junction.hpp)
};

struct SegmentRecord {
  uint32_t segment_id = 0;
  // The segment frame is the camera frame of its first keyframe; this is its pose in the run's
  // world frame as the estimator had it when the segment closed.
  Eigen::Isometry3d T_world_segment = Eigen::Isometry3d::Identity();
  JunctionRecord junction;
  double travelled_m = 0;  // path length of the keyframes in this segment
  int64_t t_first_ns = 0, t_last_ns = 0;
  std::vector<StoredKeyframe> keyframes;
  std::vector<CloudPoint> points_segment;  // in the segment frame
  // Welding regions (weld_region.hpp, fine_region_map.hpp): the regions with fine voxels in this segment,
  // and the fine cloud inside them: voxel means of side fine_voxel_m in the segment frame, with the
  // number of points merged into each (fine_counts[i] >= 1 for fine_points_segment[i]). Empty (and
  // fine_voxel_m 0) when the mapper kept no fine cloud.
  double fine_voxel_m = 0;
  std::vector<StoredWeldRegion> weld_regions;
  std::vector<CloudPoint> fine_points_segment;
  std::vector<uint32_t> fine_counts;
};

struct SegmentSummary {
  uint32_t segment_id = 0;
  int keyframes = 0;
  int64_t points = 0;
  uint64_t bytes = 0;  // on disk
};

class MapStore {
 public:
  // Opens DIR, creating it (and writing store.yaml from `metadata`) when absent. An existing store
  // keeps its metadata (the argument is then ignored); leftover .tmp- directories are removed.
  // Errors: unwritable directory (kIoError), malformed store.yaml (kParseError), a newer format
  // version (kInvalidArgument).
  static core::Expected<MapStore> open(const std::string& dir, const StoreMetadata& metadata);
  // Opens an existing store read-only (no cleanup, nothing created). kNotFound when absent.
  static core::Expected<MapStore> open_existing(const std::string& dir);

  const StoreMetadata& metadata() const { return metadata_; }
  const std::string& dir() const { return dir_; }

  // Writes a segment atomically (see above). kInvalidArgument if the id already exists or a
  // keyframe's descriptor size does not match; kIoError on any write/fsync/rename failure (the
  // temp directory is removed).
  core::Status write_segment(const SegmentRecord& segment);
  // Complete segments, sorted by id (reads segment.yaml only).
  core::Expected<std::vector<SegmentSummary>> list_segments() const;
  // Reads and validates one segment. kNotFound, kCorruptData (CRC / size mismatch, truncation),
  // kParseError.
  core::Expected<SegmentRecord> read_segment(uint32_t segment_id) const;
  // Reads and validates one segment's segment.yaml and keyframes.bin, not its cloud
  // (points_segment stays empty; cloud.bin is not opened): the prior map's index (issue #6,
  // prior_map.hpp) without the clouds in memory. Errors as read_segment's for those two files.
  core::Expected<SegmentRecord> read_keyframes(uint32_t segment_id) const;
  // Reads and validates one segment's segment.yaml and cloud.bin only (keyframes and the fine cloud
  // stay empty; keyframes.bin and fine.bin are not opened): what a prior map loads to search.
  // Errors as read_segment's for those two files.
  core::Expected<SegmentRecord> read_cloud(uint32_t segment_id) const;

 private:
  struct Parts {
    bool keyframes = true, cloud = true, fine = true;
  };
  core::Expected<SegmentRecord> read_segment_files(uint32_t segment_id, Parts parts) const;
  MapStore(std::string dir, StoreMetadata metadata) : dir_(std::move(dir)), metadata_(std::move(metadata)) {}
  std::string dir_;
  StoreMetadata metadata_;
};

}  // namespace hwr::recon
