// Hand-written point-to-distribution NDT: score pass, Newton iterations, levels (see ndt.hpp).
#include "hwr/recon/ndt.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <vector>

#include <Eigen/Eigenvalues>

#include "hwr/core/so3.hpp"
#include "ndt_line_search.hpp"
#include "ndt_target.hpp"

namespace hwr::recon {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

const char* ndt_failure_name(NdtFailure f) {
  switch (f) {
    case NdtFailure::kNone:
      return "none";
    case NdtFailure::kTooFewSourcePoints:
      return "too_few_source_points";
    case NdtFailure::kTooFewTargetVoxels:
      return "too_few_target_voxels";
    case NdtFailure::kNoCorrespondences:
      return "no_correspondences";
    case NdtFailure::kDegenerate:
      return "degenerate";
    case NdtFailure::kMaxIterations:
      return "max_iterations";
    case NdtFailure::kNonFinite:
      return "non_finite";
    case NdtFailure::kInvalidInput:
      return "invalid_input";
    case NdtFailure::kLineSearchFailed:
      return "line_search_failed";
  }
  return "unknown";
}

namespace {

// The source is cut into this many chunks whatever the thread count; chunk sums are added in chunk
// order, so one thread and many give the same bits.
constexpr int kChunks = 64;
// A Gaussian whose exponent d2/2 q^T Sigma^-1 q exceeds this adds less than exp(-20) ~ 2e-9 of its
// peak to the score: skipped (and it does not make the point a correspondence).
constexpr double kMaxExponent = 20.0;
// A line search that finds no lower cost ends the level as converged when the Newton step is below
// this many epsilons (ndt.hpp, kLineSearchFailed).
constexpr double kStallFactor = 10.0;

// Cost, gradient and Hessian of f = -sum s over the pivot parameterisation (ndt.hpp).
struct Sums {
  double cost = 0;
  int correspondences = 0;
  Vector6d gradient = Vector6d::Zero();
  Matrix6d hessian = Matrix6d::Zero();  // upper triangle filled during the pass, symmetrised after
  void clear() {
    cost = 0;
    correspondences = 0;
    gradient.setZero();
    hessian.setZero();
  }
  void add(const Sums& o) {
    cost += o.cost;
    correspondences += o.correspondences;
    gradient += o.gradient;
    hessian += o.hessian;
  }
};

struct PassInput {
  const NdtTarget::Impl* target = nullptr;
  PointsView source;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  // current T_target_source
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  Eigen::Vector3d pivot = Eigen::Vector3d::Zero();  // c
  NdtNeighbours neighbours = NdtNeighbours::kDirect7;
};

// One Gaussian's contribution to a point q (eqs. 6.9, 6.12, 6.13 with the per-point Jacobian
// factored out): with d = q - mu, v = Sigma^-1 d, e = exp(-d2/2 d^T v), a = -d1 d2 e,
//   s += -d1 e,   w += a v,   M += a (Sigma^-1 - d2 v v^T),
// so that the point's gradient is J^T w and its Hessian J^T M J plus the second-derivative term
// of w (see accumulate_point).
struct PointTerms {
  double score = 0;
  bool any = false;
  Eigen::Vector3d w = Eigen::Vector3d::Zero();
  double M[6] = {0, 0, 0, 0, 0, 0};  // xx xy xz yy yz zz
};

inline void add_gaussian(const NdtGaussian& g, const Eigen::Vector3d& q, const NdtScoreConstants& k,
                         PointTerms* pt) {
  const double dx = q.x() - g.mean[0], dy = q.y() - g.mean[1], dz = q.z() - g.mean[2];
  const double i0 = g.icov[0], i1 = g.icov[1], i2 = g.icov[2], i3 = g.icov[3], i4 = g.icov[4], i5 = g.icov[5];
  const double vx = i0 * dx + i1 * dy + i2 * dz;
  const double vy = i1 * dx + i3 * dy + i4 * dz;
  const double vz = i2 * dx + i4 * dy + i5 * dz;
  const double exponent = 0.5 * k.d2 * (dx * vx + dy * vy + dz * vz);
  if (!(exponent <= kMaxExponent)) return;
  const double e = std::exp(-exponent);
  const double a = -k.d1 * k.d2 * e;
  const double ad2 = a * k.d2;
  pt->any = true;
  pt->score += -k.d1 * e;
  pt->w.x() += a * vx;
  pt->w.y() += a * vy;
  pt->w.z() += a * vz;
  pt->M[0] += a * i0 - ad2 * vx * vx;
  pt->M[1] += a * i1 - ad2 * vx * vy;
  pt->M[2] += a * i2 - ad2 * vx * vz;
  pt->M[3] += a * i3 - ad2 * vy * vy;
  pt->M[4] += a * i4 - ad2 * vy * vz;
  pt->M[5] += a * i5 - ad2 * vz * vz;
}

// Adds a point's terms to the sums. With r = q - c, K = [r]x and J = [I, -K]:
//   gradient += (w, r x w)
//   Hessian  += [[M, -M K], [., -K M K + 1/2 (r w^T + w r^T) - (w.r) I]]
// the last two terms being w^T d2q/dphi_i dphi_j (ndt.hpp), the thesis' eq. 6.13 second term.
inline void accumulate_point(const PointTerms& pt, const Eigen::Vector3d& r, Sums* s) {
  s->cost -= pt.score;
  ++s->correspondences;
  const double rx = r.x(), ry = r.y(), rz = r.z();
  const double wx = pt.w.x(), wy = pt.w.y(), wz = pt.w.z();
  s->gradient(0) += wx;
  s->gradient(1) += wy;
  s->gradient(2) += wz;
  s->gradient(3) += ry * wz - rz * wy;  // r x w
  s->gradient(4) += rz * wx - rx * wz;
  s->gradient(5) += rx * wy - ry * wx;
  // Written out (Eigen's 3x3 products were not inlined here). Row i of M K is m_i x r (m_i the
  // i-th row of M); column j of -K M K is (column j of M K) x r.
  const double m00 = pt.M[0], m01 = pt.M[1], m02 = pt.M[2], m11 = pt.M[3], m12 = pt.M[4], m22 = pt.M[5];
  const double a00 = m01 * rz - m02 * ry, a01 = m02 * rx - m00 * rz, a02 = m00 * ry - m01 * rx;
  const double a10 = m11 * rz - m12 * ry, a11 = m12 * rx - m01 * rz, a12 = m01 * ry - m11 * rx;
  const double a20 = m12 * rz - m22 * ry, a21 = m22 * rx - m02 * rz, a22 = m02 * ry - m12 * rx;
  const double wr = wx * rx + wy * ry + wz * rz;
  Matrix6d& H = s->hessian;
  H(0, 0) += m00, H(0, 1) += m01, H(0, 2) += m02, H(1, 1) += m11, H(1, 2) += m12, H(2, 2) += m22;
  H(0, 3) -= a00, H(0, 4) -= a01, H(0, 5) -= a02;
  H(1, 3) -= a10, H(1, 4) -= a11, H(1, 5) -= a12;
  H(2, 3) -= a20, H(2, 4) -= a21, H(2, 5) -= a22;
  // rr = -K M K + 1/2 (r w^T + w r^T) - (w.r) I, upper triangle.
  H(3, 3) += (a10 * rz - a20 * ry) + rx * wx - wr;
  H(3, 4) += (a20 * rx - a00 * rz) + 0.5 * (rx * wy + wx * ry);
  H(3, 5) += (a00 * ry - a10 * rx) + 0.5 * (rx * wz + wx * rz);
  H(4, 4) += (a21 * rx - a01 * rz) + ry * wy - wr;
  H(4, 5) += (a01 * ry - a11 * rx) + 0.5 * (ry * wz + wy * rz);
  H(5, 5) += (a02 * ry - a12 * rx) + rz * wz - wr;
}

void run_chunk(const PassInput& in, int chunk, Sums* s) {
  s->clear();
  const NdtTarget::Impl& tg = *in.target;
  const int n = in.source.n;
  const int begin = static_cast<int>(static_cast<int64_t>(n) * chunk / kChunks);
  const int end = static_cast<int>(static_cast<int64_t>(n) * (chunk + 1) / kChunks);
  const double inv = tg.inv_resolution;
  const NdtScoreConstants& k = tg.constants;
  const bool direct7 = in.neighbours == NdtNeighbours::kDirect7;
  static constexpr int kFace[6][3] = {{-1, 0, 0}, {1, 0, 0}, {0, -1, 0}, {0, 1, 0}, {0, 0, -1}, {0, 0, 1}};
  for (int i = begin; i < end; ++i) {
    const Eigen::Vector3f pf = in.source.at(i);
    if (!pf.allFinite()) continue;
    const Eigen::Vector3d q = in.R * pf.cast<double>() + in.t;
    int64_t ix = 0, iy = 0, iz = 0;
    uint64_t key = 0;
    if (!ndt_voxel_index(q.x(), inv, &ix) || !ndt_voxel_index(q.y(), inv, &iy) ||
        !ndt_voxel_index(q.z(), inv, &iz) || !ndt_pack_key(ix, iy, iz, &key)) {
      continue;
    }
    PointTerms pt;
    const int32_t v = tg.find(key);
    if (v >= 0) {
      if (direct7) {
        const NdtVoxelLinks& links = tg.voxel_links[v];
        for (int j = 0; j < links.count; ++j) add_gaussian(tg.gaussians[links.gaussian[j]], q, k, &pt);
      } else if (tg.voxel_gaussian[v] >= 0) {
        add_gaussian(tg.gaussians[tg.voxel_gaussian[v]], q, k, &pt);
      }
    } else if (direct7) {  // an empty voxel: its face neighbours may still hold Gaussians
      for (const auto& f : kFace) {
        uint64_t nkey = 0;
        if (!ndt_pack_key(ix + f[0], iy + f[1], iz + f[2], &nkey)) continue;
        const int32_t u = tg.find(nkey);
        if (u >= 0 && tg.voxel_gaussian[u] >= 0) add_gaussian(tg.gaussians[tg.voxel_gaussian[u]], q, k, &pt);
      }
    }
    if (pt.any) accumulate_point(pt, q - in.pivot, s);
  }
}

// Fixed workers started once; each pass publishes its input and the workers (and the caller) take
// chunks from an atomic counter. Waiting on a condition variable allocates nothing.
class WorkerPool {
 public:
  WorkerPool(int workers, Sums* chunk_sums) : chunk_sums_(chunk_sums) {
    threads_.reserve(static_cast<size_t>(workers));
    for (int i = 0; i < workers; ++i) threads_.emplace_back([this] { loop(); });
  }
  ~WorkerPool() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    start_.notify_all();
    for (std::thread& t : threads_) t.join();
  }
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  void run(const PassInput& in) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      input_ = &in;
      next_chunk_.store(0, std::memory_order_relaxed);
      pending_ = static_cast<int>(threads_.size());
      ++generation_;
    }
    start_.notify_all();
    work(in);
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [this] { return pending_ == 0; });
    input_ = nullptr;
  }

 private:
  void work(const PassInput& in) {
    for (int c = next_chunk_.fetch_add(1); c < kChunks; c = next_chunk_.fetch_add(1)) {
      run_chunk(in, c, &chunk_sums_[c]);
    }
  }
  void loop() {
    uint64_t seen = 0;
    for (;;) {
      const PassInput* in = nullptr;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        start_.wait(lock, [&] { return stop_ || generation_ != seen; });
        if (stop_) return;
        seen = generation_;
        in = input_;
      }
      work(*in);
      std::lock_guard<std::mutex> lock(mutex_);
      if (--pending_ == 0) done_.notify_one();
    }
  }

  Sums* chunk_sums_;
  std::vector<std::thread> threads_;
  std::mutex mutex_;
  std::condition_variable start_, done_;
  std::atomic<int> next_chunk_{0};
  const PassInput* input_ = nullptr;
  uint64_t generation_ = 0;
  int pending_ = 0;
  bool stop_ = false;
};

// The pose of the parameterisation, T(x) p = Exp(phi) (p - c) + c + t, as an isometry.
Eigen::Isometry3d pose_of(const Vector6d& x, const Eigen::Vector3d& c) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = core::so3_exp(x.tail<3>());
  T.translation() = c - T.linear() * c + x.head<3>();
  return T;
}

bool finite_pose(const Eigen::Isometry3d& T) { return T.matrix().allFinite(); }

struct SourceStats {
  int finite = 0;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();  // source frame
  double rms_radius_m = 0;                             // about the centroid
};

SourceStats source_stats(const PointsView& source) {
  SourceStats st;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (int i = 0; i < source.n; ++i) {
    const Eigen::Vector3f p = source.at(i);
    if (!p.allFinite()) continue;
    ++st.finite;
    sum += p.cast<double>();
  }
  if (st.finite == 0) return st;
  st.centroid = sum / st.finite;
  double r2 = 0;
  for (int i = 0; i < source.n; ++i) {
    const Eigen::Vector3f p = source.at(i);
    if (p.allFinite()) r2 += (p.cast<double>() - st.centroid).squaredNorm();
  }
  st.rms_radius_m = std::sqrt(r2 / st.finite);
  return st;
}

// The state of one level's iterations at the current pose.
struct Evaluation {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  Sums sums;
};

}  // namespace

struct NdtAligner::Impl {
  explicit Impl(const NdtConfig& c, std::vector<NdtTarget> t) : config(c), targets(std::move(t)) {
    built.resize(targets.size());
    chunk_sums.assign(kChunks, Sums{});
    if (c.num_threads > 1) pool = std::make_unique<WorkerPool>(c.num_threads - 1, chunk_sums.data());
  }

  // One pass over the source at pose T with pivot c: the total sums, Hessian symmetrised.
  void pass(const NdtTarget::Impl& tg, const PointsView& source, const Eigen::Isometry3d& T,
            const Eigen::Vector3d& pivot, Sums* out) {
    PassInput in;
    in.target = &tg;
    in.source = source;
    in.R = T.linear();
    in.t = T.translation();
    in.pivot = pivot;
    in.neighbours = config.neighbours;
    if (pool) {
      pool->run(in);
    } else {
      for (int c = 0; c < kChunks; ++c) run_chunk(in, c, &chunk_sums[c]);
    }
    out->clear();
    for (int c = 0; c < kChunks; ++c) out->add(chunk_sums[c]);
    out->hessian.triangularView<Eigen::StrictlyLower>() = out->hessian.transpose();
  }

  // One level from *cur (pivot: the moved source centroid); false when alignment must stop, with the
  // result's pose and failure set.
  // `epsilon_scale` multiplies the convergence epsilons (coarse levels stop earlier, ndt.hpp).
  bool level(const NdtTarget::Impl& tg, const PointsView& source, const SourceStats& stats,
             double epsilon_scale, Evaluation* cur, Eigen::Vector3d* pivot, NdtResult* result);
  // Newton iterations at one level. Returns false with *failure set when the level cannot go on; true
  // otherwise, with *converged, or *failure = kLineSearchFailed, or neither (out of iterations).
  bool run_level(const NdtTarget::Impl& tg, const PointsView& source, const Eigen::Vector3d& pivot,
                 double epsilon_scale, Evaluation* cur, int* iterations, bool* converged,
                 NdtFailure* failure);

  NdtConfig config;
  // align()'s targets, one per level, and what each was last built from (target_version != 0).
  struct BuiltFrom {
    const float* xyz = nullptr;
    int n = -1, stride_floats = 0;
    double resolution_m = 0;
    uint64_t version = 0;
  };
  std::vector<NdtTarget> targets;
  std::vector<BuiltFrom> built;
  std::vector<Sums> chunk_sums;
  std::unique_ptr<WorkerPool> pool;
  Evaluation trial;  // the line search's last evaluation
};

bool NdtAligner::Impl::run_level(const NdtTarget::Impl& tg, const PointsView& source,
                                 const Eigen::Vector3d& pivot, double epsilon_scale, Evaluation* cur,
                                 int* iterations, bool* converged, NdtFailure* failure) {
  *converged = false;
  const double eps_t = config.translation_epsilon_m * epsilon_scale;
  const double eps_r = config.rotation_epsilon_rad * epsilon_scale;
  pass(tg, source, cur->T, pivot, &cur->sums);
  if (cur->sums.correspondences == 0) {
    *failure = NdtFailure::kNoCorrespondences;
    return false;
  }
  if (!std::isfinite(cur->sums.cost) || !cur->sums.gradient.allFinite() || !cur->sums.hessian.allFinite()) {
    *failure = NdtFailure::kNonFinite;
    return false;
  }
  NdtLineSearchParams ls;
  for (int it = 0; it < config.max_iterations; ++it) {
    const Vector6d& g = cur->sums.gradient;
    // Newton direction H dx = -g. Where H is not positive definite (far from the optimum, or a
    // direction the scene does not constrain) its eigenvalues are replaced by their absolute values,
    // floored at 1e-9 of the largest: the direction is then always a descent direction, and a
    // negative-curvature direction is followed downhill instead of up to the saddle.
    Eigen::SelfAdjointEigenSolver<Matrix6d> es(cur->sums.hessian);
    Vector6d lambda = es.eigenvalues().cwiseAbs();
    const double lambda_max = lambda.maxCoeff();
    if (!(lambda_max > 0.0) || !std::isfinite(lambda_max)) {
      *failure = NdtFailure::kNonFinite;
      return false;
    }
    lambda = lambda.cwiseMax(1e-9 * lambda_max);
    const Vector6d dx = -(es.eigenvectors() * (es.eigenvectors().transpose() * g).cwiseQuotient(lambda));
    const double dx_norm = dx.norm();
    const double dphi0 = g.dot(dx);
    // Converged when the Newton step is below the epsilons: it is not taken (the pose is within the
    // epsilons of where it would lead), which saves the pass that would only confirm it.
    if (dx.head<3>().norm() < eps_t && dx.tail<3>().norm() < eps_r) {
      *converged = true;
      return true;
    }
    if (!(dphi0 < 0.0)) {  // only when g = 0 (the direction is a descent direction otherwise)
      *converged = true;
      return true;
    }
    // phi(a) = f(T(a dx) * T). Moving along the ray, the point displacement is dphi x (q - c) + dt,
    // which is the left perturbation (dt - a dphi x dt, dphi) at the trial pose, hence phi'(a).
    const Eigen::Vector3d dt = dx.head<3>(), dr = dx.tail<3>();
    const Eigen::Isometry3d T0 = cur->T;
    auto eval = [&](double a, double* phi, double* dphi) {
      trial.T = pose_of(a * dx, pivot) * T0;
      pass(tg, source, trial.T, pivot, &trial.sums);
      Vector6d dir;
      dir.head<3>() = dt - a * dr.cross(dt);
      dir.tail<3>() = dr;
      *phi = trial.sums.cost;
      *dphi = trial.sums.gradient.dot(dir);
      return std::isfinite(*phi) && std::isfinite(*dphi) && trial.sums.hessian.allFinite();
    };
    const double alpha_max = config.max_step / dx_norm;
    // The zoom stops once its bracket is narrower than the epsilons along dx.
    ls.min_bracket = std::min(eps_t, eps_r) / dx_norm;
    const NdtLineSearchResult r = ndt_line_search(eval, cur->sums.cost, dphi0, 1.0, alpha_max, ls);
    ++*iterations;
    if (r.alpha > 0.0) {
      if (!r.last_evaluated) {
        trial.T = pose_of(r.alpha * dx, pivot) * T0;
        pass(tg, source, trial.T, pivot, &trial.sums);
      }
      if (!finite_pose(trial.T)) {
        *failure = NdtFailure::kNonFinite;
        return false;
      }
      cur->T = trial.T;
      cur->sums = trial.sums;
    }
    if (r.alpha == 0.0) {
      // No lower cost along the Newton step: the cost jumps where points cross voxel faces (their
      // neighbourhoods change) and the pose sits at such a jump. Within kStallFactor times the
      // epsilons of the Newton target that is convergence (the jumps outweigh what the rest of the
      // step would gain); farther, the level ends not converged.
      if (dx.head<3>().norm() < kStallFactor * eps_t && dx.tail<3>().norm() < kStallFactor * eps_r) {
        *converged = true;
        return true;
      }
      *failure = NdtFailure::kLineSearchFailed;
      return true;
    }
    // Converged when the step taken moves less than the epsilons (also where the line search could
    // only lower the cost by a step that small: the jumps of the cost are then below the epsilons).
    const Vector6d step = r.alpha * dx;
    if (step.head<3>().norm() < eps_t && step.tail<3>().norm() < eps_r) {
      *converged = true;
      return true;
    }
    if (cur->sums.correspondences == 0) {
      *failure = NdtFailure::kNoCorrespondences;
      return false;
    }
  }
  return true;
}

core::Expected<NdtAligner> NdtAligner::create(const NdtConfig& config) {
  std::vector<NdtTarget> targets;
  for (double resolution : config.resolutions_m) {
    if (!targets.empty() && (resolution == 0.0 || !config.target_per_level)) break;
    auto target = NdtTarget::create(config);  // checks the config (a list without levels fails here)
    if (!target.ok()) return target.status();
    targets.push_back(std::move(target.value()));
  }
  return NdtAligner(std::make_unique<Impl>(config, std::move(targets)));
}

NdtAligner::NdtAligner(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
NdtAligner::NdtAligner(NdtAligner&&) noexcept = default;
NdtAligner& NdtAligner::operator=(NdtAligner&&) noexcept = default;
NdtAligner::~NdtAligner() = default;

const NdtConfig& NdtAligner::config() const { return impl_->config; }

double NdtAligner::evaluate(const NdtTarget& target, const PointsView& source, const Vector6d& x,
                            Vector6d* gradient, Matrix6d* hessian, const Eigen::Vector3d& pivot_m) {
  Sums s;
  impl_->pass(*target.impl_, source, pose_of(x, pivot_m), pivot_m, &s);
  if (gradient != nullptr) *gradient = s.gradient;
  if (hessian != nullptr) *hessian = s.hessian;
  return s.cost;
}

namespace {

bool valid_view(const PointsView& v, int max_points) {
  return v.n >= 0 && (v.n == 0 || v.xyz != nullptr) && v.stride_floats >= 3 && v.n <= max_points;
}

// Checks shared by align() and align_level(); false with the result filled when alignment cannot start.
bool check_inputs(const NdtConfig& config, const PointsView& source, const Eigen::Isometry3d& guess,
                  SourceStats* stats, NdtResult* result) {
  result->T_target_source = finite_pose(guess) ? guess : Eigen::Isometry3d::Identity();
  if (!finite_pose(guess)) {
    result->failure = NdtFailure::kNonFinite;
    return false;
  }
  if (!valid_view(source, config.max_source_points)) {
    result->failure = NdtFailure::kInvalidInput;
    return false;
  }
  *stats = source_stats(source);
  result->nonfinite_points = source.n - stats->finite;
  if (stats->finite < config.min_source_points) {
    result->failure = NdtFailure::kTooFewSourcePoints;
    return false;
  }
  return true;
}

// Fills the result from the finest level's final evaluation: score, fitness, the degeneracy test and
// the Hessian moved to the origin pivot.
void finish(const NdtConfig& config, const Evaluation& cur, const Eigen::Vector3d& pivot,
            const SourceStats& stats, NdtResult* result) {
  result->T_target_source = cur.T;
  result->score = -cur.sums.cost;
  result->correspondences = cur.sums.correspondences;
  result->fitness = cur.sums.correspondences > 0 ? result->score / cur.sums.correspondences : 0.0;
  result->inlier_ratio =
      stats.finite > 0 ? static_cast<double>(cur.sums.correspondences) / stats.finite : 0.0;

  // Pivot c -> origin: dt_c = dt_0 + Exp(dphi) c - c, so H_0 = A^T H_c A with A = [[I, -[c]x], [0, I]]
  // plus the translation gradient times d2(Exp(phi) c)/dphi^2 in the rotation block.
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Identity();
  A.topRightCorner<3, 3>() = -core::hat(pivot);
  Eigen::Matrix<double, 6, 6> H0 = A.transpose() * cur.sums.hessian * A;
  const Eigen::Vector3d gt = cur.sums.gradient.head<3>();
  Eigen::Matrix3d extra = 0.5 * (pivot * gt.transpose() + gt * pivot.transpose());
  extra.diagonal().array() -= gt.dot(pivot);
  H0.bottomRightCorner<3, 3>() += extra;
  result->hessian = H0;

  // Degeneracy, judged at a converged pose only (elsewhere the Hessian may be indefinite for other
  // reasons): eigenvalues of the pivot Hessian with its rotation block in m^-2 (rotation scaled by
  // the source's RMS radius L: D H D, D = diag(1, 1, 1, 1/L, 1/L, 1/L)).
  if (!result->converged) return;
  const double L = std::max(stats.rms_radius_m, 1e-6);
  Eigen::Matrix<double, 6, 1> d;
  d << 1, 1, 1, 1 / L, 1 / L, 1 / L;
  const Eigen::Matrix<double, 6, 6> Hs = d.asDiagonal() * cur.sums.hessian * d.asDiagonal();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> es(Hs, Eigen::EigenvaluesOnly);
  const Eigen::Matrix<double, 6, 1> ev = es.eigenvalues();
  result->eigenvalue_ratio = ev(5) > 0 ? ev(0) / ev(5) : 0.0;
  if (!(ev(0) > config.degenerate_eigenvalue_ratio * ev(5))) {
    result->converged = false;
    result->failure = NdtFailure::kDegenerate;
  }
}

}  // namespace

bool NdtAligner::Impl::level(const NdtTarget::Impl& tg, const PointsView& source, const SourceStats& stats,
                             double epsilon_scale, Evaluation* cur, Eigen::Vector3d* pivot,
                             NdtResult* result) {
  // A failing level fails the whole alignment, whatever the coarser levels reached.
  if (tg.gaussian_count < 2) {
    result->T_target_source = cur->T;
    result->converged = false;
    result->failure = NdtFailure::kTooFewTargetVoxels;
    return false;
  }
  *pivot = cur->T * stats.centroid;
  ++result->levels;
  bool converged = false;
  NdtFailure failure = NdtFailure::kNone;
  if (!run_level(tg, source, *pivot, epsilon_scale, cur, &result->iterations, &converged, &failure)) {
    result->T_target_source = cur->T;
    result->converged = false;
    result->failure = failure;
    return false;
  }
  result->converged = converged;
  result->failure =
      converged ? NdtFailure::kNone : (failure != NdtFailure::kNone ? failure : NdtFailure::kMaxIterations);
  return true;
}

NdtResult NdtAligner::align_level(const NdtTarget& target, const PointsView& source,
                                  const Eigen::Isometry3d& T_target_source_guess) {
  NdtResult result;
  SourceStats stats;
  if (!check_inputs(impl_->config, source, T_target_source_guess, &stats, &result)) return result;
  Evaluation cur;
  cur.T = result.T_target_source;
  Eigen::Vector3d pivot = Eigen::Vector3d::Zero();
  if (!impl_->level(*target.impl_, source, stats, 1.0, &cur, &pivot, &result)) return result;
  finish(impl_->config, cur, pivot, stats, &result);
  return result;
}

NdtResult NdtAligner::align_prebuilt(const NdtTarget* const* levels, int n_levels, const PointsView& source,
                                     const Eigen::Isometry3d& T_target_source_guess) {
  NdtResult result;
  SourceStats stats;
  if (!check_inputs(impl_->config, source, T_target_source_guess, &stats, &result)) return result;
  if (levels == nullptr || n_levels < 1) {
    result.failure = NdtFailure::kInvalidInput;
    return result;
  }
  for (int l = 0; l < n_levels; ++l) {
    if (levels[l] == nullptr || !(levels[l]->resolution_m() > 0)) {
      result.failure = NdtFailure::kInvalidInput;
      return result;
    }
  }
  Evaluation cur;
  cur.T = result.T_target_source;
  Eigen::Vector3d pivot = Eigen::Vector3d::Zero();
  const double finest_m = levels[n_levels - 1]->resolution_m();
  for (int l = 0; l < n_levels; ++l) {
    // A coarse level only seeds the next one: its epsilons grow with its voxel side (as in align()).
    const double epsilon_scale = std::max(1.0, levels[l]->resolution_m() / finest_m);
    if (!impl_->level(*levels[l]->impl_, source, stats, epsilon_scale, &cur, &pivot, &result)) return result;
  }
  finish(impl_->config, cur, pivot, stats, &result);
  return result;
}

NdtResult NdtAligner::align(const PointsView& target, const PointsView& source,
                            const Eigen::Isometry3d& T_target_source_guess, uint64_t target_version) {
  NdtResult result;
  SourceStats stats;
  const NdtConfig& config = impl_->config;
  if (!check_inputs(config, source, T_target_source_guess, &stats, &result)) return result;
  if (!valid_view(target, config.max_target_points)) {
    result.failure = NdtFailure::kInvalidInput;
    return result;
  }
  Evaluation cur;
  cur.T = result.T_target_source;
  Eigen::Vector3d pivot = Eigen::Vector3d::Zero();
  double finest_m = 0;
  for (double resolution : config.resolutions_m) {
    if (resolution == 0.0) break;
    finest_m = resolution;
  }
  for (size_t l = 0; l < config.resolutions_m.size(); ++l) {
    const double resolution = config.resolutions_m[l];
    if (resolution == 0.0) break;
    const size_t slot = config.target_per_level ? l : 0;
    NdtTarget& level_target = impl_->targets[slot];
    Impl::BuiltFrom& from = impl_->built[slot];
    const bool reuse = target_version != 0 && from.version == target_version && from.xyz == target.xyz &&
                       from.n == target.n && from.stride_floats == target.stride_floats &&
                       from.resolution_m == resolution;
    if (!reuse) {
      from = Impl::BuiltFrom{};
      if (!level_target.build(target, resolution).ok()) {  // capacity: the only error a valid view can give
        result.T_target_source = cur.T;
        result.converged = false;
        result.failure = NdtFailure::kInvalidInput;
        return result;
      }
      if (target_version != 0)
        from = Impl::BuiltFrom{target.xyz, target.n, target.stride_floats, resolution, target_version};
    }
    // A coarse level only seeds the next one: its epsilons grow with its voxel side.
    const double epsilon_scale = std::max(1.0, resolution / finest_m);
    if (!impl_->level(*level_target.impl_, source, stats, epsilon_scale, &cur, &pivot, &result))
      return result;
  }
  finish(config, cur, pivot, stats, &result);
  return result;
}

}  // namespace hwr::recon
