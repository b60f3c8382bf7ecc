#pragma once
// Deterministic random numbers for the simulator. std::normal_distribution is
// implementation-defined (libstdc++ and libc++ give different streams), so noise is drawn from
// our own generator: xoshiro256** (Blackman & Vigna, 2018) seeded through SplitMix64, normals
// by the Box-Muller transform. Every stream is keyed by (scenario seed, stream id, index) through
// derive_seed(), so enabling one sensor never shifts another sensor's noise, and frame k's noise
// does not depend on which thread rendered it.

#include <cmath>
#include <cstdint>

#include <Eigen/Core>

namespace hwr::sim {

// Stream ids mixed into derive_seed().
enum class RandomStream : uint64_t {
  kImu = 1,
  kMag = 2,
  kGnss = 3,
  kGnssDropouts = 4,
  kDepthNoise = 5,
  kExposure = 6,
  kExposureRight = 7,
  kMagDisturbers = 8,
};

// SplitMix64 finaliser (Steele, Lea, Flood 2014): a bijective 64-bit mix.
constexpr uint64_t splitmix64(uint64_t x) {
  x += 0x9e3779b97f4a7c15ull;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

constexpr uint64_t derive_seed(uint64_t seed, RandomStream stream, uint64_t index = 0) {
  return splitmix64(splitmix64(splitmix64(seed) ^ static_cast<uint64_t>(stream)) ^ index);
}

class Rng {
 public:
  explicit Rng(uint64_t seed) {
    uint64_t x = seed;
    for (uint64_t& s : s_) {
      x += 0x9e3779b97f4a7c15ull;
      s = splitmix64(x);
    }
  }

  uint64_t next_u64() {
    const uint64_t result = rotl(s_[1] * 5, 7) * 9;
    const uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl(s_[3], 45);
    return result;
  }

  // Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(next_u64() >> 11) * 0x1.0p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }

  // Standard normal (Box-Muller; the second value of each pair is kept for the next call).
  double normal() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    const double u1 = 1.0 - uniform();  // (0, 1]: log stays finite
    const double u2 = uniform();
    const double r = std::sqrt(-2.0 * std::log(u1));
    const double a = 2.0 * M_PI * u2;
    spare_ = r * std::sin(a);
    has_spare_ = true;
    return r * std::cos(a);
  }

 private:
  static constexpr uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  uint64_t s_[4];
  double spare_ = 0.0;
  bool has_spare_ = false;
};

// Three independent standard normals, drawn in x, y, z order (function arguments have no fixed
// evaluation order in C++, so never write Vector3d(rng.normal(), rng.normal(), rng.normal())).
inline Eigen::Vector3d normal3(Rng* rng) {
  Eigen::Vector3d v;
  v.x() = rng->normal();
  v.y() = rng->normal();
  v.z() = rng->normal();
  return v;
}

}  // namespace hwr::sim
