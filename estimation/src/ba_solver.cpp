#include "hwr/estimation/ba_solver.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include "hwr/core/se3.hpp"

namespace hwr::estimation {
namespace {

using Mat66 = Eigen::Matrix<double, 6, 6>;
using Mat63 = Eigen::Matrix<double, 6, 3>;
using Mat33 = Eigen::Matrix3d;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Vec3 = Eigen::Vector3d;
using Vec2 = Eigen::Vector2d;
using SpMat = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;
using BlockMap = Eigen::Map<Mat66, 0, Eigen::OuterStride<>>;

constexpr int kDensePreallocCameras = 200;
// Marquardt diagonal clamp and LM constants: the values Ceres uses (min/max_lm_diagonal,
// min_relative_decrease, 1 / max and 1 / min trust-region radius).
constexpr double kMinDiagonal = 1e-6;
constexpr double kMaxDiagonal = 1e32;
constexpr double kMinRelativeDecrease = 1e-3;
constexpr double kMinLambda = 1e-16;
constexpr double kMaxLambda = 1e32;

inline size_t sz(int i) { return static_cast<size_t>(i); }

// Huber loss on s = |r|^2 in the form of Ceres' HuberLoss: rho(s) = s for s <= d^2, else
// 2 d sqrt(s) - d^2. w = rho'(s) is the IRLS weight of the term.
struct Huber {
  double delta = 0;
  double delta2 = 0;
  explicit Huber(double d) : delta(d), delta2(d * d) {}
  void eval(double s, double* rho, double* w) const {
    if (delta <= 0 || s <= delta2) {
      *rho = s;
      *w = 1.0;
    } else {
      const double r = std::sqrt(s);
      *rho = 2.0 * delta * r - delta2;
      *w = delta / r;
    }
  }
  double rho(double s) const { return (delta <= 0 || s <= delta2) ? s : 2.0 * delta * std::sqrt(s) - delta2; }
};

inline double clamp_diag(double d) { return std::min(std::max(d, kMinDiagonal), kMaxDiagonal); }

bool finite_pose(const Eigen::Isometry3d& T) { return T.matrix().topRows<3>().allFinite(); }

// Cost (0.5 sum rho) of every observation at the poses / points that pose(c) / point(p) return.
template <BaCameraModel M, class PoseAt, class PointAt>
double total_cost(const BaProblem& pb, const PoseAt& pose, const PointAt& point, const Huber& huber,
                  bool use_depth, double depth_c) {
  double cost = 0;
  for (const BaObservation& o : pb.observations) {
    const Eigen::Isometry3d& T = pose(o.camera);
    const Vec3& X = point(o.point);
    const Vec2 r = ba_reprojection_residual<M>(T, pb.cameras[sz(o.camera)].K, X, o.uv_px, o.sigma_px);
    cost += huber.rho(r.squaredNorm());
    if (use_depth && o.depth_m > 0) {
      const double rd = ba_depth_residual<M>(T, X, o.depth_m, ba_depth_sigma_m(o.depth_m, depth_c));
      cost += huber.rho(rd * rd);
    }
  }
  return 0.5 * cost;
}

core::Status validate(const BaProblem& pb, const BaOptions& opt, const BaCapacity& cap) {
  const size_t nc = pb.cameras.size(), np = pb.points.size(), no = pb.observations.size();
  if (nc > sz(cap.max_cameras) || np > sz(cap.max_points) || no > sz(cap.max_observations)) {
    return core::OutOfRange("BA problem (" + std::to_string(nc) + " cameras, " + std::to_string(np) +
                            " points, " + std::to_string(no) +
                            " observations) exceeds the solver capacity (" + std::to_string(cap.max_cameras) +
                            ", " + std::to_string(cap.max_points) + ", " +
                            std::to_string(cap.max_observations) + ")");
  }
  if (opt.max_iterations < 0 || !(opt.initial_lambda > 0) || !std::isfinite(opt.initial_lambda) ||
      !(opt.function_tolerance >= 0) || !(opt.gradient_tolerance >= 0) || !(opt.parameter_tolerance >= 0) ||
      !std::isfinite(opt.huber_px)) {
    return core::InvalidArgument(
        "BA options: need max_iterations >= 0, initial_lambda > 0, tolerances >= 0 and a finite huber_px");
  }
  for (size_t c = 0; c < nc; ++c) {
    const BaIntrinsics& K = pb.cameras[c].K;
    const bool k_ok = pb.model == BaCameraModel::kPinhole
                          ? std::isfinite(K.fx) && std::isfinite(K.fy) && std::isfinite(K.cx) &&
                                std::isfinite(K.cy) && K.fx != 0 && K.fy != 0
                          : std::isfinite(K.f) && std::isfinite(K.k1) && std::isfinite(K.k2) && K.f != 0;
    if (!finite_pose(pb.cameras[c].T_cam_world) || !k_ok) {
      return core::InvalidArgument(
          "BA camera " + std::to_string(c) +
          ": non-finite pose or invalid intrinsics (zero or non-finite focal length)");
    }
  }
  for (size_t p = 0; p < np; ++p) {
    if (!pb.points[p].p_world.allFinite()) {
      return core::InvalidArgument("BA point " + std::to_string(p) + ": non-finite coordinates");
    }
  }
  bool has_depth = false;
  for (size_t i = 0; i < no; ++i) {
    const BaObservation& o = pb.observations[i];
    if (o.camera < 0 || sz(o.camera) >= nc || o.point < 0 || sz(o.point) >= np) {
      return core::InvalidArgument("BA observation " + std::to_string(i) + ": camera " +
                                   std::to_string(o.camera) + " / point " + std::to_string(o.point) +
                                   " out of range (" + std::to_string(nc) + " cameras, " +
                                   std::to_string(np) + " points)");
    }
    if (!o.uv_px.allFinite() || !std::isfinite(o.sigma_px) || !(o.sigma_px > 0) ||
        !std::isfinite(o.depth_m) || o.depth_m < 0) {
      return core::InvalidArgument("BA observation " + std::to_string(i) +
                                   ": non-finite uv, sigma_px <= 0 or invalid depth_m");
    }
    has_depth = has_depth || o.depth_m > 0;
  }
  if (has_depth && opt.use_depth && !(opt.depth_sigma_per_m2 > 0 && std::isfinite(opt.depth_sigma_per_m2))) {
    return core::InvalidArgument("BA options: depth observations need depth_sigma_per_m2 > 0");
  }
  return core::Status::Ok();
}

// Block-sparse lower triangle of the reduced camera system (sparse path): one 6x6 block per pair
// of free cameras that observe a common free point, plus every diagonal block. Built per solve.
struct SparseReduced {
  SpMat S;
  std::vector<int> block_base;    // per block: offset of its (0, 0) value in S.valuePtr()
  std::vector<int> block_stride;  // per block: distance between its columns in S.valuePtr()
  std::vector<int> diag_block;    // per free camera
  std::vector<int> pair_begin;    // per point: first entry in pair_block
  std::vector<int> pair_block;    // per pair (a, b <= a) of a point's free-camera slots
  Eigen::SimplicialLDLT<SpMat, Eigen::Lower> ldlt;
  Eigen::VectorXd x;

  BlockMap block(int b) {
    return BlockMap(S.valuePtr() + block_base[sz(b)], Eigen::OuterStride<>(block_stride[sz(b)]));
  }
};

}  // namespace

// The solver proper; SparseBundleAdjuster owns one. All arrays are sized at construction.
struct SparseBundleAdjuster::Workspace {
  BaCapacity cap;
  // Current estimate and the candidate of the step being tried (swapped on acceptance).
  std::vector<Eigen::Isometry3d> T, T_new;  // per camera
  std::vector<Vec3> X, X_new;               // per point
  std::vector<int> cam_var;                 // camera -> free-camera index, -1 if fixed
  // Normal equations in blocks.
  std::vector<Mat66> U;  // H_cc per free camera
  std::vector<Vec6> gc, dc;
  std::vector<Mat33> V, Vinv;  // H_pp per point and the damped inverse
  std::vector<Vec3> gp, dp;
  // Point-major observation order: slots point_begin[p] .. point_begin[p+1] - 1 are point p's.
  std::vector<int> point_begin;  // max_points + 1
  std::vector<int> slot_obs;     // slot -> observation index
  std::vector<int> slot_var;     // slot -> free-camera index when camera and point are free, else -1
  std::vector<Mat63> W, Y;       // H_cp and H_cp V^-1 per slot
  // Dense reduced system (lower triangle, column major) and its right-hand side / solution.
  std::vector<double> S;
  std::vector<double> e;
  std::unique_ptr<SparseReduced> sparse;

  // Problem-dependent sizes of the current solve.
  int n_free_cams = 0;
  int n_free_points = 0;
  bool dense = true;

  void prepare(const BaProblem& pb, const BaOptions& opt);
  void build_sparse(const BaProblem& pb);
  template <BaCameraModel M>
  double linearize(const BaProblem& pb, const Huber& huber, bool use_depth, double depth_c);
  template <class SubtractPair>
  void eliminate_points(const BaProblem& pb, double lambda, const SubtractPair& subtract_pair);
  bool solve_damped(const BaProblem& pb, double lambda, double* step_norm2, double* predicted_decrease);
  double gradient_max_norm(const BaProblem& pb) const;
  double parameter_norm(const BaProblem& pb) const;
};

SparseBundleAdjuster::SparseBundleAdjuster(const BaCapacity& capacity) : ws_(std::make_unique<Workspace>()) {
  Workspace& ws = *ws_;
  ws.cap.max_cameras = std::max(capacity.max_cameras, 0);
  ws.cap.max_points = std::max(capacity.max_points, 0);
  ws.cap.max_observations = std::max(capacity.max_observations, 0);
  const size_t nc = sz(ws.cap.max_cameras), np = sz(ws.cap.max_points), no = sz(ws.cap.max_observations);
  // Filled with values, not just sized: Eigen's fixed-size types do not initialise themselves, and
  // untouched pages would be faulted in during the first solve instead of here.
  ws.T.assign(nc, Eigen::Isometry3d::Identity());
  ws.T_new.assign(nc, Eigen::Isometry3d::Identity());
  ws.cam_var.assign(nc, -1);
  ws.U.assign(nc, Mat66::Zero());
  ws.gc.assign(nc, Vec6::Zero());
  ws.dc.assign(nc, Vec6::Zero());
  ws.X.assign(np, Vec3::Zero());
  ws.X_new.assign(np, Vec3::Zero());
  ws.V.assign(np, Mat33::Zero());
  ws.Vinv.assign(np, Mat33::Zero());
  ws.gp.assign(np, Vec3::Zero());
  ws.dp.assign(np, Vec3::Zero());
  ws.point_begin.assign(np + 1, 0);
  ws.slot_obs.assign(no, 0);
  ws.slot_var.assign(no, -1);
  ws.W.assign(no, Mat63::Zero());
  ws.Y.assign(no, Mat63::Zero());
  const size_t nd = 6 * std::min<size_t>(nc, kDensePreallocCameras);
  ws.S.assign(nd * nd, 0.0);
  ws.e.assign(6 * nc, 0.0);
}

SparseBundleAdjuster::~SparseBundleAdjuster() = default;
SparseBundleAdjuster::SparseBundleAdjuster(SparseBundleAdjuster&&) noexcept = default;
SparseBundleAdjuster& SparseBundleAdjuster::operator=(SparseBundleAdjuster&&) noexcept = default;

const BaCapacity& SparseBundleAdjuster::capacity() const { return ws_->cap; }

// Copies the estimate in, numbers the free cameras and sorts the observations point-major
// (a stable counting sort, so a point's observations keep their order).
void SparseBundleAdjuster::Workspace::prepare(const BaProblem& pb, const BaOptions& opt) {
  const int nc = static_cast<int>(pb.cameras.size()), np = static_cast<int>(pb.points.size());
  const int no = static_cast<int>(pb.observations.size());
  n_free_cams = 0;
  for (int c = 0; c < nc; ++c) {
    const BaCamera& cam = pb.cameras[sz(c)];
    T[sz(c)] = cam.T_cam_world;
    T_new[sz(c)] = cam.T_cam_world;
    cam_var[sz(c)] = cam.fixed ? -1 : n_free_cams++;
  }
  n_free_points = 0;
  for (int p = 0; p < np; ++p) {
    X[sz(p)] = pb.points[sz(p)].p_world;
    X_new[sz(p)] = X[sz(p)];
    n_free_points += pb.points[sz(p)].fixed ? 0 : 1;
  }
  std::fill(point_begin.begin(), point_begin.begin() + np + 1, 0);
  for (const BaObservation& o : pb.observations) ++point_begin[sz(o.point) + 1];
  for (int p = 0; p < np; ++p) point_begin[sz(p) + 1] += point_begin[sz(p)];
  // point_begin[p] doubles as the fill cursor, then is restored by shifting.
  for (int i = 0; i < no; ++i) {
    const BaObservation& o = pb.observations[sz(i)];
    const int s = point_begin[sz(o.point)]++;
    slot_obs[sz(s)] = i;
    const int v = cam_var[sz(o.camera)];
    slot_var[sz(s)] = (v >= 0 && !pb.points[sz(o.point)].fixed) ? v : -1;
  }
  for (int p = np; p > 0; --p) point_begin[sz(p)] = point_begin[sz(p) - 1];
  point_begin[0] = 0;

  dense = n_free_cams <= opt.dense_reduced_max_cameras;
  if (dense) {
    const size_t n = 6 * sz(n_free_cams);
    if (S.size() < n * n) S.resize(n * n);  // only above the preallocated 200 free cameras
  }
}

// Sparse path: the block pattern of S from the co-observations, the value offsets of every block
// and the symbolic factorisation (AMD ordering). Allocates; runs once per solve.
void SparseBundleAdjuster::Workspace::build_sparse(const BaProblem& pb) {
  if (!sparse) sparse = std::make_unique<SparseReduced>();
  SparseReduced& sp = *sparse;
  const int np = static_cast<int>(pb.points.size());
  const int64_t nb = n_free_cams;
  // Keys col * nb + row (row >= col) of the blocks, sorted column-major.
  std::vector<int64_t> keys;
  keys.reserve(sz(n_free_cams));
  for (int v = 0; v < n_free_cams; ++v) keys.push_back(v * nb + v);
  for (int p = 0; p < np; ++p) {
    const int s0 = point_begin[sz(p)], s1 = point_begin[sz(p) + 1];
    for (int a = s0; a < s1; ++a) {
      const int va = slot_var[sz(a)];
      if (va < 0) continue;
      for (int b = s0; b < a; ++b) {
        const int vb = slot_var[sz(b)];
        if (vb < 0 || vb == va) continue;
        keys.push_back(std::min(va, vb) * nb + std::max(va, vb));
      }
    }
  }
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  const int n_blocks = static_cast<int>(keys.size());
  const int n = 6 * n_free_cams;
  // Blocks per block column.
  std::vector<int> col_blocks(sz(n_free_cams) + 1, 0);
  for (const int64_t k : keys) ++col_blocks[sz(static_cast<int>(k / nb)) + 1];
  sp.S.resize(n, n);
  sp.S.resizeNonZeros(36 * n_blocks);
  int* outer = sp.S.outerIndexPtr();
  int* inner = sp.S.innerIndexPtr();
  sp.block_base.assign(sz(n_blocks), 0);
  sp.block_stride.assign(sz(n_blocks), 0);
  int nnz = 0;
  int kb = 0;
  for (int j = 0; j < n_free_cams; ++j) {
    const int nbj = col_blocks[sz(j) + 1];
    const int first = kb;
    for (int c = 0; c < 6; ++c) {
      outer[6 * j + c] = nnz;
      for (int q = 0; q < nbj; ++q) {
        const int row_block = static_cast<int>(keys[sz(first + q)] % nb);
        for (int r = 0; r < 6; ++r) inner[nnz++] = 6 * row_block + r;
      }
    }
    for (int q = 0; q < nbj; ++q) {
      sp.block_base[sz(first + q)] = outer[6 * j] + 6 * q;
      sp.block_stride[sz(first + q)] = 6 * nbj;
    }
    kb += nbj;
  }
  outer[n] = nnz;
  std::fill(sp.S.valuePtr(), sp.S.valuePtr() + nnz, 0.0);
  auto find_block = [&](int row, int col) {
    const int64_t key = col * nb + row;
    return static_cast<int>(std::lower_bound(keys.begin(), keys.end(), key) - keys.begin());
  };
  sp.diag_block.resize(sz(n_free_cams));
  for (int v = 0; v < n_free_cams; ++v) sp.diag_block[sz(v)] = find_block(v, v);
  sp.pair_begin.assign(sz(np) + 1, 0);
  sp.pair_block.clear();
  for (int p = 0; p < np; ++p) {
    sp.pair_begin[sz(p)] = static_cast<int>(sp.pair_block.size());
    const int s0 = point_begin[sz(p)], s1 = point_begin[sz(p) + 1];
    for (int a = s0; a < s1; ++a) {
      const int va = slot_var[sz(a)];
      if (va < 0) continue;
      for (int b = s0; b <= a; ++b) {
        const int vb = slot_var[sz(b)];
        if (vb < 0) continue;
        sp.pair_block.push_back(find_block(std::max(va, vb), std::min(va, vb)));
      }
    }
  }
  sp.pair_begin[sz(np)] = static_cast<int>(sp.pair_block.size());
  sp.ldlt.analyzePattern(sp.S);
  sp.x.resize(n);
}

// Step 1: residuals, analytic Jacobians and the block normal equations at the current estimate,
// in point-major order, fused (no Jacobian is stored). Returns the cost.
template <BaCameraModel M>
double SparseBundleAdjuster::Workspace::linearize(const BaProblem& pb, const Huber& huber, bool use_depth,
                                                  double depth_c) {
  for (int v = 0; v < n_free_cams; ++v) {
    U[sz(v)].setZero();
    gc[sz(v)].setZero();
  }
  double cost = 0;
  const int np = static_cast<int>(pb.points.size());
  for (int p = 0; p < np; ++p) {
    const bool p_free = !pb.points[sz(p)].fixed;
    Mat33 Vp = Mat33::Zero();
    Vec3 gpp = Vec3::Zero();
    const Vec3& Xp = X[sz(p)];
    const int s1 = point_begin[sz(p) + 1];
    for (int s = point_begin[sz(p)]; s < s1; ++s) {
      const BaObservation& o = pb.observations[sz(slot_obs[sz(s)])];
      const int v = cam_var[sz(o.camera)];
      const Eigen::Isometry3d& Tc = T[sz(o.camera)];
      BaMatrix26 Jc;
      BaMatrix23 Jp;
      const Vec2 r =
          ba_reprojection_residual<M>(Tc, pb.cameras[sz(o.camera)].K, Xp, o.uv_px, o.sigma_px, &Jc, &Jp);
      double rho, w;
      huber.eval(r.squaredNorm(), &rho, &w);
      cost += rho;
      const BaMatrix26 wJc = w * Jc;
      if (v >= 0) {
        U[sz(v)].noalias() += wJc.transpose() * Jc;
        gc[sz(v)].noalias() += wJc.transpose() * r;
      }
      if (p_free) {
        const BaMatrix23 wJp = w * Jp;
        Vp.noalias() += wJp.transpose() * Jp;
        gpp.noalias() += wJp.transpose() * r;
        if (v >= 0) W[sz(s)].noalias() = wJc.transpose() * Jp;
      }
      if (use_depth && o.depth_m > 0) {
        BaMatrix16 Jdc;
        BaMatrix13 Jdp;
        const double rd =
            ba_depth_residual<M>(Tc, Xp, o.depth_m, ba_depth_sigma_m(o.depth_m, depth_c), &Jdc, &Jdp);
        double rho_d, w_d;
        huber.eval(rd * rd, &rho_d, &w_d);
        cost += rho_d;
        const BaMatrix16 wJdc = w_d * Jdc;
        if (v >= 0) {
          U[sz(v)].noalias() += wJdc.transpose() * Jdc;
          gc[sz(v)].noalias() += wJdc.transpose() * rd;
        }
        if (p_free) {
          Vp.noalias() += (w_d * Jdp.transpose()) * Jdp;
          gpp.noalias() += (w_d * rd) * Jdp.transpose();
          if (v >= 0) W[sz(s)].noalias() += wJdc.transpose() * Jdp;
        }
      }
    }
    V[sz(p)] = Vp;
    gp[sz(p)] = gpp;
  }
  return 0.5 * cost;
}

// Step 3, the point part: per free point the damped V^-1, Y = W V^-1, the right-hand side
// e_c += Y g_p and, for every pair of its free-camera slots (a, b <= a), the reduced block
// S(cam a, cam b) -= Y_a W_b^T (stored as the lower block, row >= column).
template <class SubtractPair>
void SparseBundleAdjuster::Workspace::eliminate_points(const BaProblem& pb, double lambda,
                                                       const SubtractPair& subtract_pair) {
  const int np = static_cast<int>(pb.points.size());
  double* rhs = e.data();
  for (int p = 0; p < np; ++p) {
    if (pb.points[sz(p)].fixed) continue;
    Mat33 Vd = V[sz(p)];
    for (int i = 0; i < 3; ++i) Vd(i, i) += lambda * clamp_diag(Vd(i, i));
    const Mat33 Vi = Vd.inverse();
    Vinv[sz(p)] = Vi;
    const Vec3& g = gp[sz(p)];
    const int s0 = point_begin[sz(p)], s1 = point_begin[sz(p) + 1];
    int pair = 0;
    for (int a = s0; a < s1; ++a) {
      const int va = slot_var[sz(a)];
      if (va < 0) continue;
      Mat63& Ya = Y[sz(a)];
      Ya.noalias() = W[sz(a)] * Vi;
      Eigen::Map<Vec6>(rhs + 6 * va).noalias() += Ya * g;
      for (int b = s0; b <= a; ++b) {
        const int vb = slot_var[sz(b)];
        if (vb < 0) continue;
        subtract_pair(p, pair++, a, b, va, vb);
      }
    }
  }
}

// Steps 2-4 for one lambda. Returns false when the damped system is not positive definite (the
// caller then rejects the step and raises lambda).
bool SparseBundleAdjuster::Workspace::solve_damped(const BaProblem& pb, double lambda, double* step_norm2,
                                                   double* predicted_decrease) {
  const int n = 6 * n_free_cams;
  Eigen::Map<Eigen::VectorXd> rhs(e.data(), n);
  for (int v = 0; v < n_free_cams; ++v) rhs.segment<6>(6 * v) = -gc[sz(v)];
  // Contribution of slot pair (a, b) to the lower block (row >= column): Y_a W_b^T, or its
  // transpose Y_b W_a^T when a's camera comes first.
  auto pair_block_value = [this](int a, int b, int va, int vb, Mat66* out) {
    if (va > vb || a == b) {
      out->noalias() = Y[sz(a)] * W[sz(b)].transpose();
    } else if (va < vb) {
      out->noalias() = Y[sz(b)] * W[sz(a)].transpose();
    } else {  // one point observed twice by the same camera
      out->noalias() = Y[sz(a)] * W[sz(b)].transpose() + Y[sz(b)] * W[sz(a)].transpose();
    }
  };
  bool ok = true;
  if (dense) {
    Eigen::Map<Eigen::MatrixXd> Sm(S.data(), n, n);
    for (int j = 0; j < n_free_cams; ++j) Sm.block(6 * j, 6 * j, n - 6 * j, 6).setZero();
    for (int v = 0; v < n_free_cams; ++v) {
      auto blk = Sm.block<6, 6>(6 * v, 6 * v);
      blk = U[sz(v)];
      for (int i = 0; i < 6; ++i) blk(i, i) += lambda * clamp_diag(blk(i, i));
    }
    eliminate_points(pb, lambda, [&](int, int, int a, int b, int va, int vb) {
      if (va > vb || a == b) {
        Sm.block<6, 6>(6 * va, 6 * vb).noalias() -= Y[sz(a)] * W[sz(b)].transpose();
      } else if (va < vb) {
        Sm.block<6, 6>(6 * vb, 6 * va).noalias() -= Y[sz(b)] * W[sz(a)].transpose();
      } else {
        Sm.block<6, 6>(6 * va, 6 * va).noalias() -=
            Y[sz(a)] * W[sz(b)].transpose() + Y[sz(b)] * W[sz(a)].transpose();
      }
    });
    Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>, Eigen::Lower> llt(Sm);
    ok = llt.info() == Eigen::Success;
    if (ok) llt.solveInPlace(rhs);
  } else {
    SparseReduced& sp = *sparse;
    std::fill(sp.S.valuePtr(), sp.S.valuePtr() + sp.S.nonZeros(), 0.0);
    for (int v = 0; v < n_free_cams; ++v) {
      BlockMap blk = sp.block(sp.diag_block[sz(v)]);
      blk = U[sz(v)];
      for (int i = 0; i < 6; ++i) blk(i, i) += lambda * clamp_diag(blk(i, i));
    }
    eliminate_points(pb, lambda, [&](int p, int pair, int a, int b, int va, int vb) {
      Mat66 m;
      pair_block_value(a, b, va, vb, &m);
      sp.block(sp.pair_block[sz(sp.pair_begin[sz(p)] + pair)]) -= m;
    });
    sp.ldlt.factorize(sp.S);
    ok = sp.ldlt.info() == Eigen::Success && (sp.ldlt.vectorD().array() > 0).all();
    if (ok) {
      sp.x = sp.ldlt.solve(rhs);
      rhs = sp.x;
    }
  }
  if (!ok || !rhs.allFinite()) return false;

  // Step 4: cameras from the reduced solve, points by back-substitution.
  double norm2 = 0, pred = 0;
  for (int v = 0; v < n_free_cams; ++v) {
    const Vec6 d = rhs.segment<6>(6 * v);
    dc[sz(v)] = d;
    norm2 += d.squaredNorm();
    const Mat66& Uv = U[sz(v)];
    for (int i = 0; i < 6; ++i) pred += lambda * clamp_diag(Uv(i, i)) * d(i) * d(i);
    pred -= gc[sz(v)].dot(d);
  }
  const int np = static_cast<int>(pb.points.size());
  for (int p = 0; p < np; ++p) {
    if (pb.points[sz(p)].fixed) {
      dp[sz(p)].setZero();
      continue;
    }
    Vec3 b = -gp[sz(p)];
    const int s0 = point_begin[sz(p)], s1 = point_begin[sz(p) + 1];
    for (int s = s0; s < s1; ++s) {
      const int v = slot_var[sz(s)];
      if (v >= 0) b.noalias() -= W[sz(s)].transpose() * dc[sz(v)];
    }
    const Vec3 d = Vinv[sz(p)] * b;
    dp[sz(p)] = d;
    norm2 += d.squaredNorm();
    const Mat33& Vp = V[sz(p)];
    for (int i = 0; i < 3; ++i) pred += lambda * clamp_diag(Vp(i, i)) * d(i) * d(i);
    pred -= gp[sz(p)].dot(d);
  }
  if (!std::isfinite(norm2)) return false;
  // Decrease predicted by the undamped model, L(0) - L(d) = -g^T d - d^T H d / 2, which equals
  // (lambda d^T D d - g^T d) / 2 because (H + lambda D) d = -g (Madsen et al. 2004, eq. 3.14).
  *step_norm2 = norm2;
  *predicted_decrease = 0.5 * pred;
  return true;
}

double SparseBundleAdjuster::Workspace::gradient_max_norm(const BaProblem& pb) const {
  double m = 0;
  for (int v = 0; v < n_free_cams; ++v) m = std::max(m, gc[sz(v)].cwiseAbs().maxCoeff());
  const int np = static_cast<int>(pb.points.size());
  for (int p = 0; p < np; ++p) {
    if (!pb.points[sz(p)].fixed) m = std::max(m, gp[sz(p)].cwiseAbs().maxCoeff());
  }
  return m;
}

// |x| over the free parameters, with a pose counted as (t, rotation angle) like Ceres' angle-axis.
double SparseBundleAdjuster::Workspace::parameter_norm(const BaProblem& pb) const {
  double n2 = 0;
  const int nc = static_cast<int>(pb.cameras.size()), np = static_cast<int>(pb.points.size());
  for (int c = 0; c < nc; ++c) {
    if (cam_var[sz(c)] < 0) continue;
    const Eigen::Isometry3d& Tc = T[sz(c)];
    const double cos_angle = std::clamp(0.5 * (Tc.linear().trace() - 1.0), -1.0, 1.0);
    const double angle = std::acos(cos_angle);
    n2 += Tc.translation().squaredNorm() + angle * angle;
  }
  for (int p = 0; p < np; ++p) {
    if (!pb.points[sz(p)].fixed) n2 += X[sz(p)].squaredNorm();
  }
  return std::sqrt(n2);
}

namespace {

template <BaCameraModel M>
double workspace_cost(const BaProblem& pb, const std::vector<Eigen::Isometry3d>& T,
                      const std::vector<Vec3>& X, const Huber& huber, bool use_depth, double depth_c) {
  return total_cost<M>(
      pb, [&](int c) -> const Eigen::Isometry3d& { return T[sz(c)]; },
      [&](int p) -> const Vec3& { return X[sz(p)]; }, huber, use_depth, depth_c);
}

const char* termination_message(BaTermination t) {
  switch (t) {
    case BaTermination::kFunctionTolerance:
      return "function tol";
    case BaTermination::kGradientTolerance:
      return "gradient tol";
    case BaTermination::kParameterTolerance:
      return "parameter tol";
    case BaTermination::kMaxIterations:
      return "max iterations";
    case BaTermination::kNoFreeParameters:
      return "nothing free";
    case BaTermination::kLambdaOverflow:
      return "lambda overflow";
  }
  return "";
}

}  // namespace

core::Expected<BaSummary> SparseBundleAdjuster::solve(BaProblem* problem, const BaOptions& options) {
  const auto t_start = std::chrono::steady_clock::now();
  auto elapsed_s = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  };
  if (problem == nullptr) return core::InvalidArgument("BA solve: null problem");
  HWR_RETURN_IF_ERROR(validate(*problem, options, ws_->cap));
  Workspace& ws = *ws_;
  const BaProblem& pb = *problem;
  const Huber huber(options.huber_px);
  const bool use_depth = options.use_depth;
  const double depth_c = options.depth_sigma_per_m2;
  const bool pinhole = pb.model == BaCameraModel::kPinhole;

  ws.prepare(pb, options);
  BaSummary summary;
  summary.free_cameras = ws.n_free_cams;
  summary.free_points = ws.n_free_points;
  summary.dense_reduced_system = ws.dense;

  auto linearize = [&] {
    return pinhole ? ws.linearize<BaCameraModel::kPinhole>(pb, huber, use_depth, depth_c)
                   : ws.linearize<BaCameraModel::kBalRadial>(pb, huber, use_depth, depth_c);
  };
  auto candidate_cost = [&] {
    return pinhole
               ? workspace_cost<BaCameraModel::kPinhole>(pb, ws.T_new, ws.X_new, huber, use_depth, depth_c)
               : workspace_cost<BaCameraModel::kBalRadial>(pb, ws.T_new, ws.X_new, huber, use_depth, depth_c);
  };
  auto report = [&](int iteration, double cost, double lambda, bool accepted) {
    if (options.iteration_callback == nullptr) return;
    BaIterationInfo info;
    info.iteration = iteration;
    info.cost = cost;
    info.lambda = lambda;
    info.step_accepted = accepted;
    info.elapsed_s = elapsed_s();
    options.iteration_callback(info, options.callback_user);
  };

  double cost = linearize();
  if (!std::isfinite(cost)) {
    return core::InvalidArgument(
        "BA solve: the initial cost is not finite (a point on a camera's z = 0 plane, or an overflow)");
  }
  summary.initial_cost = cost;
  double lambda = options.initial_lambda;
  report(0, cost, lambda, true);

  BaTermination termination = BaTermination::kMaxIterations;
  bool done = false;
  if (ws.n_free_cams == 0 && ws.n_free_points == 0) {
    termination = BaTermination::kNoFreeParameters;
    done = true;
  } else if (ws.gradient_max_norm(pb) <= options.gradient_tolerance) {
    termination = BaTermination::kGradientTolerance;
    done = true;
  }
  if (!done && !ws.dense) ws.build_sparse(pb);

  double nu = 2.0;
  const int nc = static_cast<int>(pb.cameras.size()), np = static_cast<int>(pb.points.size());
  for (int iter = 1; !done && iter <= options.max_iterations; ++iter) {
    summary.iterations = iter;
    double step_norm2 = 0, predicted = 0;
    bool accepted = false;
    if (ws.solve_damped(pb, lambda, &step_norm2, &predicted)) {
      const double x_norm = ws.parameter_norm(pb);
      if (std::sqrt(step_norm2) <= options.parameter_tolerance * (x_norm + options.parameter_tolerance)) {
        termination = BaTermination::kParameterTolerance;
        break;
      }
      // Candidate: T <- exp(dxi) T (left perturbation), p <- p + dp.
      for (int c = 0; c < nc; ++c) {
        const int v = ws.cam_var[sz(c)];
        if (v >= 0) ws.T_new[sz(c)] = core::se3_exp(ws.dc[sz(v)]) * ws.T[sz(c)];
      }
      for (int p = 0; p < np; ++p) {
        if (!pb.points[sz(p)].fixed) ws.X_new[sz(p)] = ws.X[sz(p)] + ws.dp[sz(p)];
      }
      const double new_cost = candidate_cost();
      const double rho = (cost - new_cost) / predicted;
      accepted = std::isfinite(new_cost) && predicted > 0 && rho > kMinRelativeDecrease;
      const bool tiny_change =
          std::isfinite(new_cost) && std::abs(cost - new_cost) <= options.function_tolerance * cost;
      if (accepted || (tiny_change && new_cost < cost)) {
        std::swap(ws.T, ws.T_new);
        std::swap(ws.X, ws.X_new);
        cost = new_cost;
        ++summary.successful_steps;
        accepted = true;
      }
      if (tiny_change) {
        termination = BaTermination::kFunctionTolerance;
        report(iter, cost, lambda, accepted);
        break;
      }
      if (accepted) {
        const double t = 2.0 * rho - 1.0;
        lambda = std::max(lambda * std::max(1.0 / 3.0, 1.0 - t * t * t), kMinLambda);
        nu = 2.0;
        cost = linearize();
        if (ws.gradient_max_norm(pb) <= options.gradient_tolerance) {
          termination = BaTermination::kGradientTolerance;
          report(iter, cost, lambda, accepted);
          break;
        }
      }
    }
    if (!accepted) {
      lambda *= nu;
      nu *= 2.0;
      if (lambda > kMaxLambda) {
        termination = BaTermination::kLambdaOverflow;
        report(iter, cost, lambda, accepted);
        break;
      }
    }
    report(iter, cost, lambda, accepted);
  }

  // Write the estimate back (fixed parameters are unchanged by construction).
  for (int c = 0; c < nc; ++c) {
    if (ws.cam_var[sz(c)] >= 0) problem->cameras[sz(c)].T_cam_world = ws.T[sz(c)];
  }
  for (int p = 0; p < np; ++p) {
    if (!pb.points[sz(p)].fixed) problem->points[sz(p)].p_world = ws.X[sz(p)];
  }
  summary.final_cost = cost;
  summary.termination = termination;
  summary.converged =
      termination == BaTermination::kFunctionTolerance || termination == BaTermination::kGradientTolerance ||
      termination == BaTermination::kParameterTolerance || termination == BaTermination::kNoFreeParameters;
  summary.message = termination_message(termination);
  summary.solve_s = elapsed_s();
  return summary;
}

double SparseBundleAdjuster::evaluate_cost(const BaProblem& problem, const BaOptions& options) const {
  const size_t nc = problem.cameras.size(), np = problem.points.size();
  for (const BaObservation& o : problem.observations) {
    if (o.camera < 0 || sz(o.camera) >= nc || o.point < 0 || sz(o.point) >= np) {
      return std::numeric_limits<double>::quiet_NaN();
    }
  }
  const Huber huber(options.huber_px);
  auto pose = [&](int c) -> const Eigen::Isometry3d& { return problem.cameras[sz(c)].T_cam_world; };
  auto point = [&](int p) -> const Vec3& { return problem.points[sz(p)].p_world; };
  return problem.model == BaCameraModel::kPinhole
             ? total_cost<BaCameraModel::kPinhole>(problem, pose, point, huber, options.use_depth,
                                                   options.depth_sigma_per_m2)
             : total_cost<BaCameraModel::kBalRadial>(problem, pose, point, huber, options.use_depth,
                                                     options.depth_sigma_per_m2);
}

}  // namespace hwr::estimation
