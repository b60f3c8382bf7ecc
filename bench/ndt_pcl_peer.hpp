#pragma once
// Peer for `hwr-bench ndt` (issue #4 NDT acceptance): PCL 1.13's pcl::NormalDistributionsTransform
// (Magnusson's point-to-distribution NDT, Euler-angle parameters, kd-tree radius search over the
// voxel centroids, More-Thuente line search, one thread). Bench-only: built when
// bench/CMakeLists.txt finds PCL (HWR_HAVE_PCL=1, Debian libpcl-dev); otherwise
// pcl_ndt_available() is false and PclNdtPeer::create says why. PCL's headers stay in
// ndt_pcl_peer.cpp so the rest of hwr-bench compiles without them.

#include <memory>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "hwr/core/status.hpp"
#include "ndt_clouds.hpp"

namespace hwr::bench {

// The NDT settings the bench gives PCL, mapped from the same numbers our NdtConfig gets.
struct PeerNdtSettings {
  std::vector<double> resolutions_m;  // coarse to fine; each level seeded with the previous result
  double outlier_ratio = 0.55;        // setOulierRatio
  double step_size = 0.1;             // setStepSize: More-Thuente's largest step, |dx| of (t, euler)
  // PCL stops when the last step's squared translation <= transformation_epsilon and its
  // cos(rotation angle) >= transformation_rotation_epsilon; the bench sets
  // transformation_epsilon = translation_epsilon_m^2 and rotation epsilon = cos(rotation_epsilon_rad),
  // so both libraries stop on the same step size.
  double translation_epsilon_m = 1e-4;
  double rotation_epsilon_rad = 1e-4;
  int max_iterations = 35;  // per level (setMaximumIterations)
  int min_points_per_voxel = 6;
};

struct PeerNdtResult {
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();
  int iterations = 0;               // getFinalNumIteration, summed over levels
  bool hit_max_iterations = false;  // the finest level ran max_iterations (PCL then still says converged)
  double total_s = 0;  // steady_clock: target voxel grids (setInputTarget/setResolution) + align, all levels
  double target_build_s = 0;  // the part spent building the target voxel grids
  double thread_cpu_s = 0;    // CLOCK_THREAD_CPUTIME_ID over the same span
  // Of which kernel time (getrusage RUSAGE_THREAD). Debian's FLANN opens an OpenMP parallel region
  // (one thread) for every radius query, whose futex calls land here.
  double thread_sys_s = 0;
  double transformation_likelihood = 0;  // getTransformationLikelihood (score per source point)
};

// True when this hwr-bench was built with PCL.
bool pcl_ndt_available();
// "PCL 1.13.0" or a sentence saying why the peer is missing.
std::string pcl_ndt_description();

// Holds one pair of clouds converted to pcl::PointCloud<pcl::PointXYZ> (done once, not timed).
class PclNdtPeer {
 public:
  // Errors: kUnavailable when built without PCL.
  static core::Expected<std::unique_ptr<PclNdtPeer>> create(const XyzCloud& target, const XyzCloud& source);
  virtual ~PclNdtPeer() = default;
  // Fresh pcl::NormalDistributionsTransform, coarse to fine over settings.resolutions_m from the guess.
  virtual PeerNdtResult align(const Eigen::Isometry3d& T_target_source_guess,
                              const PeerNdtSettings& settings) = 0;
};

}  // namespace hwr::bench
