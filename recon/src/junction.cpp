#include "hwr/recon/junction.hpp"

#include <cmath>
#include <vector>

#include "hwr/core/se3.hpp"

namespace hwr::recon {

struct JunctionAligner::Impl {
  Impl(const JunctionConfig& c, int max_features, NdtAligner n)
      : config(c),
        matcher(max_features, c.lsh),
        ransac(max_features),
        refiner(max_features),
        ndt(std::move(n)),
        matches(static_cast<size_t>(max_features)),
        correspondences(static_cast<size_t>(max_features)),
        inlier_mask(static_cast<size_t>(max_features)) {}
  JunctionConfig config;
  estimation::LshMatcher matcher;
  estimation::PoseRansac ransac;
  estimation::MotionOnlyRefiner refiner;
  NdtAligner ndt;
  std::vector<estimation::FeatureMatch> matches;
  std::vector<estimation::Correspondence> correspondences;
  std::vector<uint8_t> inlier_mask;
};

JunctionAligner::JunctionAligner(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
JunctionAligner::JunctionAligner(JunctionAligner&&) noexcept = default;
JunctionAligner& JunctionAligner::operator=(JunctionAligner&&) noexcept = default;
JunctionAligner::~JunctionAligner() = default;

core::Expected<JunctionAligner> JunctionAligner::create(const JunctionConfig& config, int max_features) {
  if (max_features < 1) return core::InvalidArgument("junction: max_features must be >= 1");
  if (config.min_orb_inliers < 3) return core::InvalidArgument("junction: min_orb_inliers must be >= 3");
  if (!(config.odometry_sigma_rad > 0) || !(config.odometry_sigma_m > 0) ||
      !(config.orb_covariance_scale > 0) || !(config.fusion_gate_chi2 > 0)) {
    return core::InvalidArgument(
        "junction: odometry_sigma_rad, odometry_sigma_m, orb_covariance_scale and fusion_gate_chi2 must be > "
        "0");
  }
  auto ndt = NdtAligner::create(config.ndt);
  if (!ndt.ok()) return ndt.status();
  return JunctionAligner(std::make_unique<Impl>(config, max_features, std::move(ndt.value())));
}

JunctionResult JunctionAligner::align(const estimation::Keyframe& a, const estimation::Keyframe& b,
                                      const hal::PinholeIntrinsics& K, const PointsView& cloud_a_cam,
                                      const PointsView& cloud_b_cam,
                                      const Eigen::Isometry3d& T_a_b_odometry) {
  Impl& m = *impl_;
  JunctionResult out;
  out.T_a_b = T_a_b_odometry;

  // ORB: b's features queried against an LSH index of a's (paper: "matching ORB keypoints between the
  // last frame before segmentation and the first frame of the new map").
  m.matcher.build(a.features);
  const int n_matches = m.matcher.match(b.features, m.matches.data(), static_cast<int>(m.matches.size()));
  out.orb_matches = n_matches;
  // Covariance of the ORB pose, of dxi with T_b_a <- exp(dxi) T_b_a (core::se3_exp: rho, phi).
  Eigen::Matrix<double, 6, 6> cov_b_a = Eigen::Matrix<double, 6, 6>::Zero();
  bool have_cov = false;
  int n = 0;
  for (int i = 0; i < n_matches; ++i) {
    const estimation::Feature& fa = a.features.feature(m.matches[static_cast<size_t>(i)].train);
    const estimation::Feature& fb = b.features.feature(m.matches[static_cast<size_t>(i)].query);
    if (!(fa.depth_m > 0)) continue;  // the 3D side of the correspondence is camera a's point
    estimation::Correspondence& c = m.correspondences[static_cast<size_t>(n++)];
    c.p_world = fa.p_cam_m;  // "world" of the solver = camera a
    c.uv_px = {fb.u_px, fb.v_px};
    c.depth_m = fb.depth_m;
    c.octave = fb.octave;
  }
  if (n >= m.config.min_orb_inliers) {
    const estimation::PoseRansacResult r =
        m.ransac.solve(m.correspondences.data(), n, K, m.config.ransac, m.inlier_mask.data());
    out.orb_inliers = r.ok ? r.inliers : 0;
    if (r.ok && r.inliers >= m.config.min_orb_inliers) {
      out.T_a_b = r.T_cam_world.inverse();  // solver gives T_b_a
      out.seed = JunctionSeed::kOrb;
      // Refine over all matches (Huber, the inlier set re-decided) for the pose and its covariance.
      const estimation::RefineResult rr = m.refiner.refine(m.correspondences.data(), n, K, r.T_cam_world,
                                                           m.config.refine, m.inlier_mask.data());
      if (rr.ok && rr.inliers >= m.config.min_orb_inliers && rr.covariance.allFinite()) {
        out.T_a_b = rr.T_cam_world.inverse();
        out.orb_inliers = rr.inliers;
        cov_b_a = m.config.orb_covariance_scale * rr.covariance;
        have_cov = true;
      } else {
        // The RANSAC inlier mask was overwritten by the failed refinement: recompute it for the
        // reprojection check below.
        m.ransac.solve(m.correspondences.data(), n, K, m.config.ransac, m.inlier_mask.data());
      }
    }
  }
  // RMS reprojection error in b of the ORB inliers (a's keypoints with depth) under a pose T_a_b.
  auto orb_rms_px = [&](const Eigen::Isometry3d& T_a_b) {
    const Eigen::Isometry3d T_b_a = T_a_b.inverse();
    double sum = 0;
    int used = 0;
    for (int i = 0; i < n; ++i) {
      if (!m.inlier_mask[static_cast<size_t>(i)]) continue;
      const estimation::Correspondence& c = m.correspondences[static_cast<size_t>(i)];
      const Eigen::Vector3d p_b = T_b_a * c.p_world;
      if (!(p_b.z() > 0)) continue;
      const double du = K.fx * p_b.x() / p_b.z() + K.cx - c.uv_px.x();
      const double dv = K.fy * p_b.y() / p_b.z() + K.cy - c.uv_px.y();
      sum += du * du + dv * dv;
      ++used;
    }
    return used > 0 ? std::sqrt(sum / used) : 0.0;
  };

  // NDT of b's cloud (source) against a's (target), seeded by the ORB pose (paper: "initial parameters
  // are fed into the NDT point cloud matching method").
  out.ndt = m.ndt.align(cloud_a_cam, cloud_b_cam, out.T_a_b);
  if (out.ndt.converged) {
    const Eigen::Isometry3d delta = out.T_a_b.inverse() * out.ndt.T_target_source;
    const double dt_m = delta.translation().norm();
    const double dr_rad = Eigen::AngleAxisd(delta.linear()).angle();
    bool agrees = std::isfinite(dt_m) && dt_m <= m.config.max_ndt_correction_m &&
                  dr_rad <= m.config.max_ndt_correction_rad;
    // Both measurements must agree: NDT's pose may not reproject the ORB inliers much worse than
    // the ORB pose does (it would have slid along a direction the clouds do not constrain).
    if (agrees && out.seed == JunctionSeed::kOrb) {
      out.orb_rms_px = orb_rms_px(out.T_a_b);
      out.ndt_orb_rms_px = orb_rms_px(out.ndt.T_target_source);
      agrees = out.ndt_orb_rms_px <= m.config.max_ndt_reprojection_ratio * out.orb_rms_px + 0.1;
    }
    if (agrees) {
      out.T_a_b = out.ndt.T_target_source;
      out.ndt_used = true;
    }
  }
  out.T_a_b_measured = out.T_a_b;

  // MAP fusion with the odometry prior, in the left tangent space of T_b_a about the odometry:
  // z = log(T_b_a_meas T_b_a_odo^-1) ~ N(dxi, M), dxi ~ N(0, P)  =>  dxi* = (P^-1 + M^-1)^-1 M^-1 z.
  // M is the ORB covariance also when NDT's pose is used: NDT is only kept where it agrees with
  // ORB to within the ORB inliers' reprojection noise.
  if (m.config.fuse_odometry && have_cov) {
    using Mat6 = Eigen::Matrix<double, 6, 6>;
    using Vec6 = Eigen::Matrix<double, 6, 1>;
    const Eigen::Isometry3d T_b_a_odo = T_a_b_odometry.inverse();
    const Vec6 z = core::se3_log(out.T_a_b_measured.inverse() * T_b_a_odo.inverse());
    Vec6 prior_var;
    const double vt = m.config.odometry_sigma_m * m.config.odometry_sigma_m;
    const double vr = m.config.odometry_sigma_rad * m.config.odometry_sigma_rad;
    prior_var << vt, vt, vt, vr, vr, vr;
    const Mat6 P = prior_var.asDiagonal();
    const Eigen::LDLT<Mat6> innovation(P + cov_b_a);
    if (innovation.info() == Eigen::Success && innovation.isPositive()) {
      out.fusion_chi2 = z.dot(innovation.solve(z));
      if (std::isfinite(out.fusion_chi2) && out.fusion_chi2 <= m.config.fusion_gate_chi2) {
        if (out.ndt_used || m.config.fuse_orb_alone) {
          // Equivalent gain form: dxi* = P (P + M)^-1 z.
          const Vec6 dxi = P * innovation.solve(z);
          out.T_a_b = (core::se3_exp(dxi) * T_b_a_odo).inverse();
          out.fused = true;
        } else {
          // ORB alone agrees with the odometry: it re-measures what the tracker measured from the
          // same keypoints of the same two keyframes, so it adds no independent information
          // (junction.hpp); the odometry stays.
          out.T_a_b = T_a_b_odometry;
          out.odometry_kept = true;
        }
      }
    }
  }
  return out;
}

}  // namespace hwr::recon
