#pragma once
// Private to recon: a strong-Wolfe line search on the step length of a descent direction
// (Nocedal & Wright, "Numerical Optimization", 2nd ed., Alg. 3.5 with zoom Alg. 3.6 and the cubic
// interpolation of eq. 3.59). The NDT Newton direction is accepted at alpha = 1 almost every time, so
// the usual cost is one evaluation; when the Hessian was made positive definite far from the optimum
// the search extrapolates (up to alpha_max) or zooms. Same role as the More-Thuente search of the
// thesis (sec. 6.2.1) and PCL: the accepted step satisfies
//   phi(a) <= phi(0) + mu a phi'(0)   and   |phi'(a)| <= eta |phi'(0)|.

#include <algorithm>
#include <cmath>

namespace hwr::recon {

struct NdtLineSearchParams {
  double mu = 1e-4;  // sufficient decrease
  double eta = 0.9;  // curvature (0.9 is the usual choice for Newton directions)
  int max_evaluations = 10;
  double min_bracket = 0;  // the zoom gives up once its bracket on alpha is narrower than this
};

struct NdtLineSearchResult {
  double alpha = 0;             // 0: no step lowered phi
  bool last_evaluated = false;  // alpha is the last one `eval` was called with (its state is current)
  int evaluations = 0;
};

namespace detail {

// Minimiser of the cubic through (a, fa, ga), (b, fb, gb), kept inside the middle 80 % of [a, b];
// the midpoint when the cubic has no minimiser there.
inline double ndt_cubic_step(double a, double fa, double ga, double b, double fb, double gb) {
  const double lo = std::min(a, b), hi = std::max(a, b), width = hi - lo;
  double x = 0.5 * (a + b);
  const double t1 = ga + gb - 3.0 * (fa - fb) / (a - b);
  const double disc = t1 * t1 - ga * gb;
  if (disc >= 0.0 && std::isfinite(disc)) {
    const double t2 = (b > a ? 1.0 : -1.0) * std::sqrt(disc);
    const double den = gb - ga + 2.0 * t2;
    if (den != 0.0) x = b - (b - a) * (gb + t2 - t1) / den;
  }
  if (!std::isfinite(x)) x = 0.5 * (a + b);
  return std::clamp(x, lo + 0.1 * width, hi - 0.1 * width);
}

}  // namespace detail

// `eval(alpha, &phi, &dphi)` evaluates phi and its derivative at alpha and returns false when they
// are not finite (the step is then treated as too long). phi0, dphi0: at alpha = 0, dphi0 < 0.
template <class Eval>
NdtLineSearchResult ndt_line_search(Eval&& eval, double phi0, double dphi0, double alpha_init,
                                    double alpha_max, const NdtLineSearchParams& params) {
  NdtLineSearchResult out;
  if (!(dphi0 < 0.0) || !(alpha_max > 0.0)) return out;
  const double armijo_slope = params.mu * dphi0;
  const double curvature = params.eta * std::abs(dphi0);

  double a_prev = 0.0, f_prev = phi0, g_prev = dphi0;
  double a = std::min(alpha_init, alpha_max);
  double a_lo = 0.0, f_lo = phi0, g_lo = dphi0, a_hi = 0.0, f_hi = 0.0, g_hi = 0.0;
  bool zoom = false;
  while (out.evaluations < params.max_evaluations) {
    double f = 0.0, g = 0.0;
    ++out.evaluations;
    const bool finite = eval(a, &f, &g);
    if (!finite || f > phi0 + a * armijo_slope || (out.evaluations > 1 && f >= f_prev)) {
      a_lo = a_prev, f_lo = f_prev, g_lo = g_prev;
      a_hi = a, f_hi = finite ? f : INFINITY, g_hi = finite ? g : 0.0;
      zoom = true;
      break;
    }
    if (std::abs(g) <= curvature || a >= alpha_max) {
      out.alpha = a;
      out.last_evaluated = true;
      return out;
    }
    if (g >= 0.0) {
      a_lo = a, f_lo = f, g_lo = g;
      a_hi = a_prev, f_hi = f_prev, g_hi = g_prev;
      zoom = true;
      break;
    }
    a_prev = a, f_prev = f, g_prev = g;
    a = std::min(2.0 * a, alpha_max);
  }
  if (!zoom) {  // out of evaluations while extrapolating: a_prev satisfied sufficient decrease
    out.alpha = a_prev;
    out.last_evaluated = out.alpha == a;
    return out;
  }
  double a_last = a;
  while (out.evaluations < params.max_evaluations) {
    const double a_j = std::isfinite(f_hi) ? detail::ndt_cubic_step(a_lo, f_lo, g_lo, a_hi, f_hi, g_hi)
                                           : a_lo + 0.5 * (a_hi - a_lo);
    double f = 0.0, g = 0.0;
    ++out.evaluations;
    const bool finite = eval(a_j, &f, &g);
    a_last = a_j;
    if (!finite || f > phi0 + a_j * armijo_slope || f >= f_lo) {
      a_hi = a_j, f_hi = finite ? f : INFINITY, g_hi = finite ? g : 0.0;
    } else {
      if (std::abs(g) <= curvature) {
        out.alpha = a_j;
        out.last_evaluated = true;
        return out;
      }
      if (g * (a_hi - a_lo) >= 0.0) a_hi = a_lo, f_hi = f_lo, g_hi = g_lo;
      a_lo = a_j, f_lo = f, g_lo = g;
    }
    if (std::abs(a_hi - a_lo) <= std::max(params.min_bracket, 1e-12 * std::max(1.0, a_lo))) break;
  }
  out.alpha = a_lo;  // the lowest phi found that satisfies sufficient decrease (0 if none)
  out.last_evaluated = out.alpha == a_last && out.alpha > 0.0;
  return out;
}

}  // namespace hwr::recon
