#pragma once
// Fixed-point helpers shared by the quantiser (host/deploy) and the evaluator (firmware): not
// part of the deployed model's interface, only of the two sides of its arithmetic.
// Accumulator bounds (proto/deploy_format.md): inputs are int16 (|a| ≤ 32767), a layer is at
// most kMaxNetworkWidth = 128 wide, so
//   8-bit weights:  |Σ w a| ≤ 128 · 127 · 32767 < 2^29;  bias ≤ 2^30  → fits int32;
//   16-bit weights: |Σ w a| ≤ 128 · 32767² < 2^37;       bias ≤ 2^40  → |acc| < 2^41 in int64,
// and a requantisation multiplier below 2^21 keeps acc · M0 below 2^62.
#include <algorithm>
#include <cmath>
#include <cstdint>

namespace zerog::infer {

inline constexpr double kActMax = 32767.0;  ///< int16 activations use ±32767 (symmetric)
inline constexpr std::int32_t kActMaxInt = 32767;

/// Largest |bias| (accumulator units) the accumulator bound above allows.
constexpr std::int64_t bias_limit(int weight_bits) {
  return weight_bits == 8 ? (std::int64_t{1} << 30) : (std::int64_t{1} << 40);
}
inline constexpr std::int64_t kAccLimit = std::int64_t{1} << 41;

/// A real multiplier M ≈ m0 · 2^−shift, m0 in [2^20, 2^21) where representable.
struct Requant {
  std::int64_t m0 = 0;
  int shift = 0;
};

inline Requant make_requant(double M) {
  Requant r;
  if (!(M > 0.0) || !std::isfinite(M)) return r;  // multiplier 0
  int shift = 0;
  double v = M;
  while (v < double(1 << 20) && shift < 62) {
    v *= 2.0;
    ++shift;
  }
  while (v >= double(1 << 21) && shift > 0) {
    v /= 2.0;
    --shift;
  }
  r.m0 = static_cast<std::int64_t>(std::min(std::nearbyint(v), double(1 << 21)));
  r.shift = shift;
  return r;
}

/// round(acc · M), acc clamped to ±kAccLimit first (cannot trigger within the bounds above).
inline std::int64_t apply(std::int64_t acc, const Requant& r) {
  acc = std::clamp(acc, -kAccLimit, kAccLimit);
  const std::int64_t p = acc * r.m0;
  if (r.shift == 0) return p;
  return (p + (std::int64_t{1} << (r.shift - 1))) >> r.shift;
}

// Activation lookup tables: z in Q16 (value · 2^16) over [−kLutRange, kLutRange], step
// 2^−kLutStepLog2, outputs in units of 1/32767. Linear interpolation error ≤ h² max|f''| / 8:
// tanh (max|f''| = 0.77) 5.9e-6 = 0.19 LSB; sigmoid (0.096) 0.02 LSB. Beyond ±16 the functions
// differ from their limits by < 1.2e-7 (sigmoid) — below one LSB.
inline constexpr int kLutFracBits = 16;
inline constexpr int kLutStepLog2 = 7;
inline constexpr int kLutRange = 16;
inline constexpr int kLutIntervals = 2 * kLutRange << kLutStepLog2;  // 4096
inline constexpr int kLutShift = kLutFracBits - kLutStepLog2;        // 9 bits of fraction
inline constexpr std::int64_t kLutZMax = std::int64_t{kLutRange} << kLutFracBits;

}  // namespace zerog::infer
