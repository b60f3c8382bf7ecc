#pragma once
// Depth noise of a stereo camera as a function of range: sigma(z) = sigma0 + k z^2 (stereo depth
// error grows with the square of the range; the simulator's model, hal/sim camera_effects.hpp, and
// ZED 2i-like). The geometric detector scales its planarity and merge tests with it.

namespace hwr::detect {

struct DepthNoiseModel {
  double sigma0_m = 0.001;  // floor of the noise (metres)
  double k_per_m = 0.0015;  // sigma grows by k z^2 (1/m)
  double sigma_m(double z_m) const { return sigma0_m + k_per_m * z_m * z_m; }
};

}  // namespace hwr::detect
