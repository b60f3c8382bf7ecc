// The PCL 1.13 NDT peer of `hwr-bench ndt` (see ndt_pcl_peer.hpp). The only file of hwr-bench that
// includes PCL headers.

#include "ndt_pcl_peer.hpp"

#include <chrono>
#include <cmath>

#include "thread_clock.hpp"

#ifndef HWR_HAVE_PCL
#define HWR_HAVE_PCL 0
#endif
#if HWR_HAVE_PCL
// bench/CMakeLists.txt builds this file with -Wno-maybe-uninitialized (GCC): PCL's NDT template,
// instantiated here, trips it inside Eigen's JacobiSVD, and a pragma cannot reach that warning.
#include <pcl/point_cloud.h>
#include <pcl/pcl_config.h>
#include <pcl/point_types.h>
#include <pcl/registration/ndt.h>
#include <pcl/search/kdtree.h>
#endif

namespace hwr::bench {
namespace {

#if HWR_HAVE_PCL

pcl::PointCloud<pcl::PointXYZ>::Ptr to_pcl(const XyzCloud& c) {
  pcl::PointCloud<pcl::PointXYZ>::Ptr out(new pcl::PointCloud<pcl::PointXYZ>);
  out->resize(static_cast<size_t>(c.size()));
  for (int i = 0; i < c.size(); ++i)
    (*out)[static_cast<size_t>(i)] = pcl::PointXYZ(c.xyz[3 * i], c.xyz[3 * i + 1], c.xyz[3 * i + 2]);
  out->width = static_cast<uint32_t>(c.size());
  out->height = 1;
  out->is_dense = true;
  return out;
}

class PclNdtPeerImpl final : public PclNdtPeer {
 public:
  PclNdtPeerImpl(const XyzCloud& target, const XyzCloud& source)
      : target_(to_pcl(target)), source_(to_pcl(source)) {}

  PeerNdtResult align(const Eigen::Isometry3d& T_target_source_guess,
                      const PeerNdtSettings& settings) override {
    using Ndt = pcl::NormalDistributionsTransform<pcl::PointXYZ, pcl::PointXYZ>;
    PeerNdtResult r;
    Eigen::Matrix4f guess = T_target_source_guess.matrix().cast<float>();
    const double c0 = thread_cpu_s(), k0 = thread_sys_s();
    const auto t0 = std::chrono::steady_clock::now();
    Ndt ndt;
    ndt.setOulierRatio(settings.outlier_ratio);
    ndt.setStepSize(settings.step_size);
    ndt.setTransformationEpsilon(settings.translation_epsilon_m * settings.translation_epsilon_m);
    ndt.setTransformationRotationEpsilon(std::cos(settings.rotation_epsilon_rad));
    ndt.setMaximumIterations(settings.max_iterations);
    ndt.setMinPointPerVoxel(static_cast<unsigned>(settings.min_points_per_voxel));
    // Registration::align() would otherwise build a kd-tree over the raw target that NDT never
    // queries (NDT searches its own voxel-centroid tree); PCL is not charged for it.
    ndt.setSearchMethodTarget(pcl::search::KdTree<pcl::PointXYZ>::Ptr(new pcl::search::KdTree<pcl::PointXYZ>),
                              /*force_no_recompute=*/true);
    pcl::PointCloud<pcl::PointXYZ> aligned;
    std::chrono::steady_clock::duration build{};
    for (size_t level = 0; level < settings.resolutions_m.size(); ++level) {
      const auto b0 = std::chrono::steady_clock::now();
      // setResolution rebuilds the voxel grid (init()) once a source is set; the first level sets
      // the resolution, then the target (init()), then the source.
      ndt.setResolution(static_cast<float>(settings.resolutions_m[level]));
      if (level == 0) {
        ndt.setInputTarget(target_);
        ndt.setInputSource(source_);
      }
      build += std::chrono::steady_clock::now() - b0;
      ndt.align(aligned, guess);
      r.iterations += ndt.getFinalNumIteration();
      r.hit_max_iterations = ndt.getFinalNumIteration() >= settings.max_iterations;
      guess = ndt.getFinalTransformation();
    }
    const auto t1 = std::chrono::steady_clock::now();
    r.thread_cpu_s = thread_cpu_s() - c0;
    r.thread_sys_s = thread_sys_s() - k0;
    r.total_s = std::chrono::duration<double>(t1 - t0).count();
    r.target_build_s = std::chrono::duration<double>(build).count();
    r.transformation_likelihood = ndt.getTransformationLikelihood();
    const Eigen::Matrix4d m = guess.cast<double>();
    r.T_target_source.setIdentity();
    // Re-orthonormalise (PCL accumulates the pose in float).
    r.T_target_source.linear() = Eigen::Quaterniond(m.block<3, 3>(0, 0)).normalized().toRotationMatrix();
    r.T_target_source.translation() = m.block<3, 1>(0, 3);
    return r;
  }

 private:
  pcl::PointCloud<pcl::PointXYZ>::Ptr target_, source_;
};

#endif

}  // namespace

bool pcl_ndt_available() { return HWR_HAVE_PCL != 0; }

std::string pcl_ndt_description() {
#if HWR_HAVE_PCL
  return "PCL " PCL_VERSION_PRETTY
         " pcl::NormalDistributionsTransform<PointXYZ, PointXYZ> (float, one thread)";
#else
  return "PCL not found at configure time (install libpcl-dev: toolchain/install-deps.sh --with-bench-peers, "
         "then re-run cmake); running ours only";
#endif
}

core::Expected<std::unique_ptr<PclNdtPeer>> PclNdtPeer::create(const XyzCloud& target,
                                                               const XyzCloud& source) {
#if HWR_HAVE_PCL
  return std::unique_ptr<PclNdtPeer>(new PclNdtPeerImpl(target, source));
#else
  (void)target;
  (void)source;
  return core::Unavailable(pcl_ndt_description());
#endif
}

}  // namespace hwr::bench
