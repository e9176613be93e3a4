#pragma once
// Deterministic random numbers for the simulator and designs. std::mt19937_64's output sequence
// is fixed by the C++ standard, but the std:: distributions are not, so uniform and normal
// variates are derived here by hand: the same seed gives the same run on every platform.
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>

namespace zerog::sim::detail {

class Rng {
 public:
  explicit Rng(std::uint64_t seed, std::uint64_t stream = 0) : engine_(mix(seed, stream)) {}

  /// Uniform in [0, 1) with 53 random bits.
  double uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  /// ±1 with equal probability.
  double sign() { return uniform() < 0.5 ? -1.0 : 1.0; }
  /// Magnitude uniform in [lo, hi] with a random sign.
  double signed_uniform(double lo, double hi) { return sign() * uniform(lo, hi); }
  /// Standard normal (Box–Muller; both variates used).
  double normal() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    double u1 = uniform();
    while (u1 <= 0.0) u1 = uniform();
    const double u2 = uniform();
    const double r = std::sqrt(-2.0 * std::log(u1));
    spare_ = r * std::sin(2.0 * std::numbers::pi * u2);
    has_spare_ = true;
    return r * std::cos(2.0 * std::numbers::pi * u2);
  }
  std::uint64_t bits() { return engine_(); }

 private:
  // SplitMix64 finaliser: decorrelates neighbouring seeds and separates streams.
  static std::uint64_t mix(std::uint64_t seed, std::uint64_t stream) {
    std::uint64_t z = seed + 0x9E3779B97F4A7C15ull * (stream + 1);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  std::mt19937_64 engine_;
  double spare_ = 0.0;
  bool has_spare_ = false;
};

}  // namespace zerog::sim::detail
