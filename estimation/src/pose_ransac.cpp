#include "hwr/estimation/pose_ransac.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/SVD>

namespace hwr::estimation {
namespace {

// splitmix64 (Steele et al., OOPSLA 2014): a tiny, allocation-free, seedable generator.
struct SplitMix64 {
  uint64_t s;
  uint64_t next() {
    uint64_t z = (s += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  int below(int n) { return static_cast<int>(next() % static_cast<uint64_t>(n)); }
};

// Adjugate of a 3 x 3 matrix (transposed cofactors), defined for singular matrices too.
Eigen::Matrix3d adjugate(const Eigen::Matrix3d& A) {
  Eigen::Matrix3d C;
  C(0, 0) = A(1, 1) * A(2, 2) - A(1, 2) * A(2, 1);
  C(0, 1) = A(0, 2) * A(2, 1) - A(0, 1) * A(2, 2);
  C(0, 2) = A(0, 1) * A(1, 2) - A(0, 2) * A(1, 1);
  C(1, 0) = A(1, 2) * A(2, 0) - A(1, 0) * A(2, 2);
  C(1, 1) = A(0, 0) * A(2, 2) - A(0, 2) * A(2, 0);
  C(1, 2) = A(0, 2) * A(1, 0) - A(0, 0) * A(1, 2);
  C(2, 0) = A(1, 0) * A(2, 1) - A(1, 1) * A(2, 0);
  C(2, 1) = A(0, 1) * A(2, 0) - A(0, 0) * A(2, 1);
  C(2, 2) = A(0, 0) * A(1, 1) - A(0, 1) * A(1, 0);
  return C;
}

// Real roots of c3 x^3 + c2 x^2 + c1 x + c0 (c3 != 0), Newton-polished. Returns the count.
int real_cubic_roots(double c3, double c2, double c1, double c0, double roots[3]) {
  const double a = c2 / c3, b = c1 / c3, c = c0 / c3;
  // Depressed cubic t^3 + p t + q with x = t - a / 3.
  const double p = b - a * a / 3.0;
  const double q = 2.0 * a * a * a / 27.0 - a * b / 3.0 + c;
  const double disc = q * q / 4.0 + p * p * p / 27.0;
  int n = 0;
  if (disc > 0) {
    const double sq = std::sqrt(disc);
    roots[n++] = std::cbrt(-q / 2.0 + sq) + std::cbrt(-q / 2.0 - sq) - a / 3.0;
  } else if (p == 0) {
    roots[n++] = -a / 3.0;
  } else {
    // Three real roots (trigonometric form).
    const double r = std::sqrt(-p / 3.0);
    const double phi = std::acos(std::clamp(-q / (2.0 * r * r * r), -1.0, 1.0));
    for (int k = 0; k < 3; ++k) roots[n++] = 2.0 * r * std::cos((phi - 2.0 * M_PI * k) / 3.0) - a / 3.0;
  }
  for (int k = 0; k < n; ++k) {
    double x = roots[k];
    for (int it = 0; it < 3; ++it) {
      const double f = ((x + a) * x + b) * x + c;
      const double df = (3.0 * x + 2.0 * a) * x + b;
      if (df == 0) break;
      x -= f / df;
    }
    roots[k] = x;
  }
  return n;
}

}  // namespace

bool rigid_fit_3d3d(const Eigen::Vector3d* src, const Eigen::Vector3d* dst, const double* weights, int n,
                    Eigen::Isometry3d* T_dst_src) {
  if (n < 3) return false;
  double wsum = 0;
  Eigen::Vector3d mu_s = Eigen::Vector3d::Zero(), mu_d = Eigen::Vector3d::Zero();
  for (int i = 0; i < n; ++i) {
    const double w = weights ? weights[i] : 1.0;
    wsum += w;
    mu_s += w * src[i];
    mu_d += w * dst[i];
  }
  if (!(wsum > 0)) return false;
  mu_s /= wsum;
  mu_d /= wsum;
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  for (int i = 0; i < n; ++i) {
    const double w = weights ? weights[i] : 1.0;
    S.noalias() += w * (dst[i] - mu_d) * (src[i] - mu_s).transpose();
  }
  // Umeyama 1991, eq. (39)-(40): R = U diag(1, 1, det(U V^T)) V^T.
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(S, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d sv = svd.singularValues();
  if (!(sv(1) > 1e-12 * std::max(sv(0), 1e-300))) return false;  // collinear
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) D(2, 2) = -1;
  const Eigen::Matrix3d R = svd.matrixU() * D * svd.matrixV().transpose();
  T_dst_src->setIdentity();
  T_dst_src->linear() = R;
  T_dst_src->translation() = mu_d - R * mu_s;
  return true;
}

// Lambda Twist (Persson & Nordberg, ECCV 2018). With unit bearings y_k and depths lambda_k, the
// distances between the points give lambda_i^2 + lambda_j^2 + b_ij lambda_i lambda_j = a_ij
// (b_ij = -2 y_i.y_j, a_ij = |x_i - x_j|^2), i.e. lambda^T M_ij lambda = a_ij. Two homogeneous
// combinations D1 = a23 M12 - a12 M23, D2 = a23 M13 - a13 M23 vanish at the solution; a
// degenerate member D0 = D1 + gamma D2 of their pencil (det = 0, a cubic in gamma) factors into two
// planes through the origin, each meets the conic D1 (or D2) in two rays, and the sum of the three
// constraints fixes the scale along each ray. Gauss-Newton polishes lambda; Umeyama gives the pose.
int p3p_lambda_twist(const Eigen::Vector3d bearings[3], const Eigen::Vector3d x_world[3],
                     std::array<Eigen::Isometry3d, 4>* solutions) {
  Eigen::Vector3d y[3];
  for (int k = 0; k < 3; ++k) {
    const double nk = bearings[k].norm();
    if (!(nk > 0)) return 0;
    y[k] = bearings[k] / nk;
  }
  const double a12 = (x_world[0] - x_world[1]).squaredNorm();
  const double a13 = (x_world[0] - x_world[2]).squaredNorm();
  const double a23 = (x_world[1] - x_world[2]).squaredNorm();
  const double b12 = -2.0 * y[0].dot(y[1]), b13 = -2.0 * y[0].dot(y[2]), b23 = -2.0 * y[1].dot(y[2]);
  const double a_max = std::max({a12, a13, a23});
  if (!(std::min({a12, a13, a23}) > 1e-12 * a_max) || !(a_max > 0)) return 0;

  Eigen::Matrix3d M12, M13, M23;
  M12 << 1, b12 / 2, 0, b12 / 2, 1, 0, 0, 0, 0;
  M13 << 1, 0, b13 / 2, 0, 0, 0, b13 / 2, 0, 1;
  M23 << 0, 0, 0, 0, 1, b23 / 2, 0, b23 / 2, 1;
  const Eigen::Matrix3d D1 = a23 * M12 - a12 * M23;
  const Eigen::Matrix3d D2 = a23 * M13 - a13 * M23;
  const Eigen::Matrix3d Msum = M12 + M13 + M23;
  const double a_sum = a12 + a13 + a23;

  // det(D1 + g D2) = det D1 + g tr(adj(D1) D2) + g^2 tr(adj(D2) D1) + g^3 det D2.
  const double c0 = D1.determinant(), c3 = D2.determinant();
  const double c1 = (adjugate(D1) * D2).trace(), c2 = (adjugate(D2) * D1).trace();
  const double c_max = std::max({std::abs(c0), std::abs(c1), std::abs(c2), std::abs(c3)});
  if (!(c_max > 0)) return 0;

  // Candidate degenerate members, as (D0, D_restrict): D_restrict is the pencil member that does
  // not vanish on D0's planes.
  Eigen::Matrix3d D0s[4], Drs[4];
  int n_members = 0;
  double roots[3];
  int n_roots = 0;
  if (std::abs(c3) > 1e-10 * c_max) {
    n_roots = real_cubic_roots(c3, c2, c1, c0, roots);
  } else {
    // gamma = infinity is a root (D2 itself is degenerate); the others solve the quadratic.
    D0s[n_members] = D2;
    Drs[n_members++] = D1;
    if (std::abs(c2) > 1e-10 * c_max) {
      const double disc = c1 * c1 - 4 * c2 * c0;
      if (disc >= 0) {
        roots[n_roots++] = (-c1 + std::sqrt(disc)) / (2 * c2);
        roots[n_roots++] = (-c1 - std::sqrt(disc)) / (2 * c2);
      }
    }
  }
  for (int k = 0; k < n_roots; ++k) {
    const double g = roots[k];
    if (!std::isfinite(g)) continue;
    if (std::abs(g) <= 1) {
      D0s[n_members] = D1 + g * D2;
      Drs[n_members++] = D2;
    } else {
      D0s[n_members] = D1 / g + D2;
      Drs[n_members++] = D1;
    }
  }

  double lambdas[8][3];
  int n_lambda = 0;
  for (int mi = 0; mi < n_members && n_lambda < 8; ++mi) {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(D0s[mi]);
    if (eig.info() != Eigen::Success) continue;
    // The eigenvalue nearest zero belongs to the planes' common line; the other two must differ
    // in sign for real planes.
    const Eigen::Vector3d ev = eig.eigenvalues();
    int k0 = 0;
    for (int k = 1; k < 3; ++k) {
      if (std::abs(ev(k)) < std::abs(ev(k0))) k0 = k;
    }
    int ka = (k0 + 1) % 3, kb = (k0 + 2) % 3;
    if (std::abs(ev(kb)) > std::abs(ev(ka))) std::swap(ka, kb);
    const double sa = ev(ka), sb = ev(kb);
    if (sa == 0 || sb * sa > 1e-12 * sa * sa) continue;
    const double s = std::sqrt(std::max(0.0, -sb / sa));
    const Eigen::Vector3d ea = eig.eigenvectors().col(ka), eb = eig.eigenvectors().col(kb);
    for (int sign = -1; sign <= 1; sign += 2) {
      if (s == 0 && sign > 0) break;                      // a double plane
      const Eigen::Vector3d normal = ea + sign * s * eb;  // (ea -/+ s eb) . lambda = 0
      // Orthonormal basis (p, q) of the plane.
      Eigen::Vector3d p = normal.unitOrthogonal();
      Eigen::Vector3d q = normal.cross(p).normalized();
      const Eigen::Matrix3d& D = Drs[mi];
      const double g00 = p.dot(D * p), g01 = p.dot(D * q), g11 = q.dot(D * q);
      const double g_scale = std::max({std::abs(g00), std::abs(g01), std::abs(g11)});
      if (!(g_scale > 0)) continue;
      double disc = g01 * g01 - g00 * g11;
      if (disc < -1e-12 * g_scale * g_scale) continue;
      disc = std::sqrt(std::max(0.0, disc));
      Eigen::Vector3d dirs[2];
      int n_dirs = 0;
      if (std::abs(g00) >= std::abs(g11)) {
        dirs[n_dirs++] = ((-g01 + disc) / g00) * p + q;
        if (disc > 0) dirs[n_dirs++] = ((-g01 - disc) / g00) * p + q;
      } else {
        dirs[n_dirs++] = p + ((-g01 + disc) / g11) * q;
        if (disc > 0) dirs[n_dirs++] = p + ((-g01 - disc) / g11) * q;
      }
      for (int di = 0; di < n_dirs && n_lambda < 8; ++di) {
        const double form = dirs[di].dot(Msum * dirs[di]);
        if (!(form > 0)) continue;
        Eigen::Vector3d lam = std::sqrt(a_sum / form) * dirs[di];
        if (lam.sum() < 0) lam = -lam;
        if (!(lam.minCoeff() > 0)) continue;
        // Gauss-Newton on the three distance constraints.
        for (int it = 0; it < 5; ++it) {
          const Eigen::Vector3d F(lam(0) * lam(0) + lam(1) * lam(1) + b12 * lam(0) * lam(1) - a12,
                                  lam(0) * lam(0) + lam(2) * lam(2) + b13 * lam(0) * lam(2) - a13,
                                  lam(1) * lam(1) + lam(2) * lam(2) + b23 * lam(1) * lam(2) - a23);
          Eigen::Matrix3d J;
          J << 2 * lam(0) + b12 * lam(1), 2 * lam(1) + b12 * lam(0), 0,  //
              2 * lam(0) + b13 * lam(2), 0, 2 * lam(2) + b13 * lam(0),   //
              0, 2 * lam(1) + b23 * lam(2), 2 * lam(2) + b23 * lam(1);
          const Eigen::FullPivLU<Eigen::Matrix3d> lu(J);
          if (!lu.isInvertible()) break;
          const Eigen::Vector3d step = lu.solve(F);
          lam -= step;
          if (step.norm() < 1e-15 * lam.norm()) break;
        }
        const Eigen::Vector3d F(lam(0) * lam(0) + lam(1) * lam(1) + b12 * lam(0) * lam(1) - a12,
                                lam(0) * lam(0) + lam(2) * lam(2) + b13 * lam(0) * lam(2) - a13,
                                lam(1) * lam(1) + lam(2) * lam(2) + b23 * lam(1) * lam(2) - a23);
        if (!(lam.minCoeff() > 0) || !(F.cwiseAbs().maxCoeff() < 1e-6 * a_max)) continue;
        bool duplicate = false;
        for (int k = 0; k < n_lambda && !duplicate; ++k) {
          duplicate = (Eigen::Vector3d(lambdas[k][0], lambdas[k][1], lambdas[k][2]) - lam).norm() <=
                      1e-9 * lam.norm();
        }
        if (duplicate) continue;
        for (int k = 0; k < 3; ++k) lambdas[n_lambda][k] = lam(k);
        ++n_lambda;
      }
    }
  }

  int n_sol = 0;
  for (int k = 0; k < n_lambda && n_sol < 4; ++k) {
    const Eigen::Vector3d X_cam[3] = {lambdas[k][0] * y[0], lambdas[k][1] * y[1], lambdas[k][2] * y[2]};
    Eigen::Isometry3d T;
    if (rigid_fit_3d3d(x_world, X_cam, nullptr, 3, &T)) (*solutions)[static_cast<size_t>(n_sol++)] = T;
  }
  return n_sol;
}

PoseRansac::PoseRansac(int max_correspondences)
    : max_n_(std::max(max_correspondences, 0)),
      bearing_(static_cast<size_t>(max_n_)),
      p_cam_(static_cast<size_t>(max_n_)),
      thr2_px2_(static_cast<size_t>(max_n_)),
      pool_(static_cast<size_t>(max_n_)),
      in_pool_(static_cast<size_t>(max_n_)),
      mask_scratch_(static_cast<size_t>(max_n_)),
      best_mask_(static_cast<size_t>(max_n_)),
      inlier_c_(static_cast<size_t>(max_n_)),
      refine_mask_(static_cast<size_t>(max_n_)),
      refiner_(max_correspondences) {}

// MSAC cost (Torr & Zisserman 2000): inliers cost their normalised squared reprojection error,
// outliers 1. Writes the inlier mask and counts (all, and within the sampling pool).
double PoseRansac::score(const Eigen::Isometry3d& T, int n, const PoseRansacConfig& cfg, uint8_t* mask,
                         int* inliers, int* pool_inliers) const {
  const Eigen::Matrix3d R = T.linear();
  const Eigen::Vector3d t = T.translation();
  double cost = 0;
  int count = 0, pool_count = 0;
  for (int i = 0; i < n; ++i) {
    const Correspondence& c = c_[i];
    const Eigen::Vector3d p = R * c.p_world + t;
    bool in = false;
    double e = 1.0;
    if (p.z() > 1e-6) {
      const double du = K_.fx * p.x() / p.z() + K_.cx - c.uv_px.x();
      const double dv = K_.fy * p.y() / p.z() + K_.cy - c.uv_px.y();
      const double r = (du * du + dv * dv) / thr2_px2_[static_cast<size_t>(i)];
      in = r <= 1.0;
      if (in && c.depth_m > 0) in = std::abs(p.z() - c.depth_m) <= cfg.inlier_depth_frac * c.depth_m;
      if (in) e = r;
    }
    mask[i] = in ? 1 : 0;
    cost += e;
    count += in ? 1 : 0;
    pool_count += (in && in_pool_[static_cast<size_t>(i)]) ? 1 : 0;
  }
  *inliers = count;
  *pool_inliers = pool_count;
  return cost;
}

PoseRansacResult PoseRansac::solve(const Correspondence* c, int n, const hal::PinholeIntrinsics& K,
                                   const PoseRansacConfig& cfg, uint8_t* inlier_mask) {
  PoseRansacResult result;
  for (int i = 0; i < n; ++i) inlier_mask[i] = 0;
  const int m = std::min(n, max_n_);
  if (m < 3 || !K.valid()) return result;
  c_ = c;
  K_ = K;

  int n_depth = 0;
  for (int i = 0; i < m; ++i) {
    const Correspondence& ci = c[i];
    // K^-1 (u, v, 1); with depth, eq. (3) back-projection.
    bearing_[static_cast<size_t>(i)] =
        Eigen::Vector3d((ci.uv_px.x() - K.cx) / K.fx, (ci.uv_px.y() - K.cy) / K.fy, 1.0);
    if (ci.depth_m > 0) {
      p_cam_[static_cast<size_t>(i)] = bearing_[static_cast<size_t>(i)] * ci.depth_m;
      ++n_depth;
    }
    const double tol = cfg.inlier_px * std::pow(cfg.scale_factor, std::max(ci.octave, 0));
    thr2_px2_[static_cast<size_t>(i)] = tol * tol;
  }
  const bool use_p3p = n_depth < 3 || static_cast<double>(n_depth) < cfg.min_depth_fraction * m;
  result.used_p3p = use_p3p;
  int pool_size = 0;
  for (int i = 0; i < m; ++i) {
    const bool in = use_p3p || c[i].depth_m > 0;
    in_pool_[static_cast<size_t>(i)] = in ? 1 : 0;
    if (in) pool_[static_cast<size_t>(pool_size++)] = i;
  }

  SplitMix64 rng{cfg.seed};
  double best_cost = std::numeric_limits<double>::infinity();
  int best_inliers = 0;
  Eigen::Isometry3d best_T = Eigen::Isometry3d::Identity();
  const double log_fail = std::log(std::max(1e-12, 1.0 - cfg.confidence));
  int needed = cfg.max_iterations;
  int it = 0;
  std::array<Eigen::Isometry3d, 4> hyps;
  for (; it < needed && it < cfg.max_iterations; ++it) {
    int s[3];
    s[0] = pool_[static_cast<size_t>(rng.below(pool_size))];
    do s[1] = pool_[static_cast<size_t>(rng.below(pool_size))];
    while (s[1] == s[0]);
    do s[2] = pool_[static_cast<size_t>(rng.below(pool_size))];
    while (s[2] == s[0] || s[2] == s[1]);
    const Eigen::Vector3d xw[3] = {c[s[0]].p_world, c[s[1]].p_world, c[s[2]].p_world};
    int n_hyp = 0;
    if (use_p3p) {
      const Eigen::Vector3d b[3] = {bearing_[static_cast<size_t>(s[0])], bearing_[static_cast<size_t>(s[1])],
                                    bearing_[static_cast<size_t>(s[2])]};
      n_hyp = p3p_lambda_twist(b, xw, &hyps);
    } else {
      const Eigen::Vector3d pc[3] = {p_cam_[static_cast<size_t>(s[0])], p_cam_[static_cast<size_t>(s[1])],
                                     p_cam_[static_cast<size_t>(s[2])]};
      n_hyp = rigid_fit_3d3d(xw, pc, nullptr, 3, &hyps[0]) ? 1 : 0;
    }
    for (int h = 0; h < n_hyp; ++h) {
      int inl = 0, pool_inl = 0;
      const double cost = score(hyps[static_cast<size_t>(h)], m, cfg, mask_scratch_.data(), &inl, &pool_inl);
      if (cost < best_cost) {
        best_cost = cost;
        best_inliers = inl;
        best_T = hyps[static_cast<size_t>(h)];
        std::copy(mask_scratch_.begin(), mask_scratch_.begin() + m, best_mask_.begin());
        // Adaptive stopping: N = log(1 - p) / log(1 - w^3), w the inlier ratio of the pool.
        const double w = static_cast<double>(pool_inl) / pool_size;
        const double w3 = w * w * w;
        if (w3 >= 1.0 - 1e-12) {
          needed = 0;
        } else if (w3 > 1e-12) {
          needed = static_cast<int>(
              std::min<double>(cfg.max_iterations, std::ceil(log_fail / std::log(1.0 - w3))));
        }
      }
    }
  }
  result.iterations = it;
  if (best_inliers < 3) return result;

  // Final fit on all inliers (Gauss-Newton on reprojection + depth), then the inliers again.
  if (cfg.refine) {
    RefineConfig rc;
    rc.rounds = 1;
    rc.iterations_per_round = 10;
    rc.scale_factor = cfg.scale_factor;
    rc.min_inliers = 3;
    for (int pass = 0; pass < 2; ++pass) {
      int k = 0;
      for (int i = 0; i < m; ++i) {
        if (best_mask_[static_cast<size_t>(i)]) inlier_c_[static_cast<size_t>(k++)] = c[i];
      }
      if (k < 3) break;
      const RefineResult r = refiner_.refine(inlier_c_.data(), k, K, best_T, rc, refine_mask_.data());
      if (!r.T_cam_world.matrix().allFinite()) break;
      int inl = 0, pool_inl = 0;
      const double cost = score(r.T_cam_world, m, cfg, mask_scratch_.data(), &inl, &pool_inl);
      // Keep the least-squares pose unless it loses inliers (the MSAC cost of a 3-point
      // hypothesis can be lower while its pose is worse).
      if (inl < best_inliers && cost > best_cost) break;
      best_cost = cost;
      best_inliers = inl;
      best_T = r.T_cam_world;
      std::copy(mask_scratch_.begin(), mask_scratch_.begin() + m, best_mask_.begin());
    }
  }
  result.T_cam_world = best_T;
  result.inliers = best_inliers;
  result.ok = best_inliers >= std::max(cfg.min_inliers, 3);
  std::copy(best_mask_.begin(), best_mask_.begin() + m, inlier_mask);
  return result;
}

}  // namespace hwr::estimation
