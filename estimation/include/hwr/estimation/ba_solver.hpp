#pragma once
// Hand-written sparse bundle adjustment (paper eq. 5; issue #3 item 6): Levenberg-Marquardt over
// the camera poses and points of a BaProblem (ba_problem.hpp), with the Schur complement on
// fixed-size blocks (Triggs et al., "Bundle Adjustment - A Modern Synthesis", 2000, Sec. 6.1).
//
// Algorithm, per iteration:
//  1. Linearise at the current estimate, observation by observation in point-major order, and
//     accumulate directly into fixed-size blocks: U_c = H_cc (6x6 per free camera), W_o = H_cp
//     (6x3 per observation), V_p = H_pp (3x3 per free point), gradients g_c, g_p. Huber loss by
//     iteratively reweighted least squares: each term is weighted by rho'(|r|^2) (Ceres does the
//     same for Huber: rho'' <= 0, so its Triggs correction reduces to this scaling).
//  2. Damp (Marquardt): U_c + lambda D_c, V_p + lambda D_p, D = diag(H) clamped to [1e-6, 1e32]
//     (the diagonal Ceres' LM strategy uses; lambda plays the role of 1/trust-region radius).
//  3. Eliminate the points: S = sum_c U_c - sum_p sum_{a,b in obs(p)} W_a V_p^-1 W_b^T,
//     e = -g_c + sum W_a V_p^-1 g_p. S is assembled densely and solved by an in-place Eigen::LLT
//     when there are <= BaOptions::dense_reduced_max_cameras free cameras, otherwise block-sparse
//     (6x6 blocks for co-observing camera pairs) and solved by Eigen::SimplicialLDLT (AMD order).
//  4. Back-substitute dp = V_p^-1 (-g_p - sum W_a^T dc_a); update T_cam_world <- exp(dc) T_cam_world
//     (left perturbation, ba_problem.hpp), p_world <- p_world + dp.
//  5. Accept when the gain ratio (actual / predicted decrease) > 1e-3; lambda update of Nielsen
//     (1999) / Madsen-Nielsen-Tingleff (2004) Sec. 3.2: accept -> lambda *= max(1/3, 1-(2 rho-1)^3),
//     nu = 2; reject -> lambda *= nu, nu *= 2. This is Ceres' LM trust-region update expressed in
//     lambda, so both solvers take comparable steps.
// Stops (converged) on |dcost| <= function_tolerance * cost, max|g| <= gradient_tolerance, or
// |dx| <= parameter_tolerance (|x| + parameter_tolerance) (Ceres' definitions); otherwise on
// max_iterations (not converged).
//
// Gauge: fixed cameras (fixed = true) and fixed points are constants. A problem with no fixed
// camera (e.g. a BAL file) is gauge-free (7 DoF: rotation, translation, scale): the Marquardt
// damping keeps the damped system positive definite and the solver converges to one of the
// equivalent minima; fix a camera (and give depth or a second fixed pose for scale) to pin it.
//
// Firmware rule: all workspace is sized from BaCapacity at construction; a solve() of a problem
// within capacity allocates nothing on the dense-reduced path (tests/estimation/test_ba_solver.cpp
// proves it with AllocationScope, for 9 and 49 free cameras). The dense buffer covers
// min(max_cameras, 200) free cameras; raising dense_reduced_max_cameras above 200 makes a larger
// problem grow it once. The sparse path (more free cameras than
// dense_reduced_max_cameras, e.g. the end-of-run full BA) allocates its sparse matrix and
// factorisation per solve. Not thread-safe: one solver per thread.

#include <memory>
#include <string>

#include "hwr/core/status.hpp"
#include "hwr/estimation/ba_problem.hpp"

namespace hwr::estimation {

// Reported to BaOptions::iteration_callback after the initial evaluation (iteration 0, accepted) and
// after every LM iteration; cost is the cost of the current estimate (after the step if accepted).
struct BaIterationInfo {
  int iteration = 0;
  double cost = 0;
  double lambda = 0;
  bool step_accepted = false;
  double elapsed_s = 0;  // since solve() was called
};
using BaIterationCallback = void (*)(const BaIterationInfo& info, void* user);

struct BaOptions {
  int max_iterations = 50;
  double huber_px = 2.0;  // Huber threshold on the whitened residual norm (px for sigma 1 px); <= 0: squared
  double depth_sigma_per_m2 = 0.0015;  // depth sigma = c * z^2, Kinect-like (Khoshelham 2012)
  bool use_depth = true;
  double function_tolerance = 1e-6;
  double gradient_tolerance = 1e-10;
  double parameter_tolerance = 1e-8;
  double initial_lambda = 1e-4;
  int dense_reduced_max_cameras = 200;
  BaIterationCallback iteration_callback = nullptr;  // optional, e.g. cost history for the bench
  void* callback_user = nullptr;
};

enum class BaTermination {
  kFunctionTolerance,
  kGradientTolerance,
  kParameterTolerance,
  kMaxIterations,
  kNoFreeParameters,
  kLambdaOverflow,  // damping grew past 1e32 without a successful step
};

struct BaSummary {
  double initial_cost = 0;
  double final_cost = 0;
  int iterations = 0;
  int successful_steps = 0;
  bool converged = false;
  double solve_s = 0;
  // Short reason (<= 15 characters, so it stays in std::string's inline buffer: no allocation).
  std::string message;
  BaTermination termination = BaTermination::kMaxIterations;
  bool dense_reduced_system = true;  // false: block-sparse S + SimplicialLDLT
  int free_cameras = 0;
  int free_points = 0;
};

struct BaCapacity {
  int max_cameras = 0;
  int max_points = 0;
  int max_observations = 0;
};

class SparseBundleAdjuster {
 public:
  // Preallocates the workspace (including the dense reduced system for
  // min(max_cameras, 200) free cameras).
  explicit SparseBundleAdjuster(const BaCapacity& capacity);
  ~SparseBundleAdjuster();
  SparseBundleAdjuster(SparseBundleAdjuster&&) noexcept;
  SparseBundleAdjuster& operator=(SparseBundleAdjuster&&) noexcept;
  SparseBundleAdjuster(const SparseBundleAdjuster&) = delete;
  SparseBundleAdjuster& operator=(const SparseBundleAdjuster&) = delete;

  const BaCapacity& capacity() const;

  // Refines the free poses and points of *problem in place. Errors (nothing is modified): a problem
  // above capacity (kOutOfRange); an observation whose camera/point index is out of range, a
  // non-finite value, sigma_px <= 0, negative depth (kInvalidArgument); a non-finite initial cost.
  core::Expected<BaSummary> solve(BaProblem* problem, const BaOptions& options);

  // Cost of the problem as it is: 0.5 * sum rho(|r|^2) over the reprojection (and, with
  // options.use_depth, depth) residuals, rho the Huber loss of options.huber_px - the definition
  // Ceres uses. NaN if an observation refers to a camera or point that does not exist.
  double evaluate_cost(const BaProblem& problem, const BaOptions& options) const;

 private:
  struct Workspace;
  std::unique_ptr<Workspace> ws_;
};

}  // namespace hwr::estimation
