#pragma once
// The edge of a plate lying on a support (a bench or the floor, one plate thickness below its face),
// found from the depth observations themselves (recon/plate_fit.hpp, "Edges on a support").
//
// Seen at a grazing angle, a thin plate on a support is hard to tell from it: a depth sensor's noise
// lies along the viewing rays, so near the edge a point of the face and a point of the support are
// moved by centimetres in the plane and by as much as the plate is thick across it, and the support
// beyond a far edge lies partly in the plate's shadow. Counting points on either side of a line
// cannot place the edge then (the band mean does it for points sampled on the face alone). Instead
// each observation is explained as a range measured along its ray: for a candidate edge offset E the
// model is the face (h = 0, s <= E), the plate's side (s = E, -D <= h <= 0) and the support
// (h = -D, s >= E); a ray's true range is its first hit on that model, and
//   cost(E) = sum_i w_i min(((rho_i - rho_i(E)) / sigma(rho_i))^2, 9)
// (a truncated quadratic: a point that fits nothing costs the same wherever the edge is) is
// minimised over a grid of E. s runs outwards along the edge's normal in the face, h along the
// face's outward normal, t along the edge; the viewpoint is where the rays start.
//
// sigma(rho): the robust spread (1.4826 x weighted median absolute deviation) of the range residuals
// of the points well inside the face, in bins of range, so the cost weighs points by the sensor's
// own noise at their range.

#include <vector>

#include <Eigen/Core>

namespace hwr::recon::plate_detail {

// One observation in the edge's frame (s, t, h).
struct RaySample {
  Eigen::Vector3d p = Eigen::Vector3d::Zero();          // the observed point
  Eigen::Vector3d viewpoint = Eigen::Vector3d::Zero();  // where its ray starts
  double weight = 1;
};

// Range noise as a function of range, from observations known to lie on the face (h = 0): the
// residual of each is its range minus its ray's range to the plane h = 0.
class RangeNoise {
 public:
  // Bins of bin_m; a bin with fewer than min_weight of samples takes its nearest filled neighbour.
  // Returns false when no bin is filled.
  bool fit(const std::vector<RaySample>& face_samples, double bin_m = 0.25, double min_weight = 200);
  double sigma_m(double range_m) const;

 private:
  double bin_m_ = 0.25;
  std::vector<double> sigma_;  // per bin, filled
};

struct EdgeOnSupport {
  bool ok = false;
  double edge_s = 0;     // the refined edge offset
  double cost_drop = 0;  // 1 - cost(edge) / cost(start): how much the model prefers it
  double weight = 0;     // of the samples used
};

// samples: the observations within the edge's band (their t inside the edge's extent) in the edge's
// frame; e0: the current edge offset; depth_m: D, the support's depth below the face; search_m: E
// is looked for in [e0 - search_m, e0 + search_m] in steps of step_m.
EdgeOnSupport refine_edge_on_support(const std::vector<RaySample>& samples, const RangeNoise& noise,
                                     double e0, double depth_m, double search_m, double step_m);

}  // namespace hwr::recon::plate_detail
