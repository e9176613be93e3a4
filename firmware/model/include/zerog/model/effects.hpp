#pragma once
// The physical effects of the zerog force model: names, parameters, units, and metadata.
// No I/O, no allocation. Shared by the firmware and every host tool.
//
// Frames (see proto/frames.md): W world (z up), B robot base, F flange, S F/T sensor, I IMU.
#include <array>
#include <cstdint>
#include <optional>
#include <string_view>

#include "zerog/model/user_effects.hpp"

namespace zerog::model {

enum class Effect : std::uint8_t {
  bias,
  gravity,
  base_tilt,
  linear_inertia,
  rotational_inertia,
  imu_time_offset,
  bias_drift,
  temperature_bias,
  crosstalk,
  sensor_rotation,
  cable,
};
inline constexpr int kEffectCount = 11;
inline constexpr int kMaxEffectParams = 36;

/// Reference temperature of the temperature_bias effect, °C.
inline constexpr double kTemperatureReferenceC = 25.0;
/// Standard gravity, m/s², along −z of the world frame.
inline constexpr double kStandardGravity = 9.80665;

struct ParamInfo {
  const char* name;  ///< unique within the effect, e.g. "F0x"
  const char* unit;  ///< SI unit, e.g. "N", "N*m", "kg*m^2", "rad", "s", "N/K"
};

struct EffectInfo {
  Effect id;
  const char* name;           ///< command-line name, e.g. "bias_drift"
  const char* summary;        ///< one line, plain words
  const char* formula;        ///< the contribution, in the notation of proto/effects.md
  const char* signals;        ///< what the effect needs from the log
  const char* residual_hint;  ///< the residual pattern that reveals it when missing
  int num_params;
  const ParamInfo* params;
  std::array<std::optional<Effect>, 2> requires_effects;  ///< effects it builds on
};

/// Metadata of one effect. Real-time safe.
const EffectInfo& info(Effect e);
/// Looks an effect up by its command-line name. Real-time safe.
std::optional<Effect> effect_from_name(std::string_view name);
constexpr int index(Effect e) { return static_cast<int>(e); }

/// A set of effects as a bit mask (fixed size, copyable in the cycle).
class EffectSet {
 public:
  constexpr EffectSet() = default;
  constexpr EffectSet(std::initializer_list<Effect> effects) {
    for (Effect e : effects) add(e);
  }
  constexpr bool has(Effect e) const { return (bits_ >> index(e)) & 1u; }
  constexpr void add(Effect e) { bits_ |= 1u << index(e); }
  constexpr void remove(Effect e) { bits_ &= ~(1u << index(e)); }
  constexpr int size() const { return __builtin_popcount(bits_); }
  constexpr std::uint32_t bits() const { return bits_; }
  constexpr bool operator==(const EffectSet&) const = default;

 private:
  std::uint32_t bits_ = 0;
};

/// All effects, in declaration order (for iteration).
inline constexpr std::array<Effect, kEffectCount> kAllEffects = {Effect::bias,
                                                                 Effect::gravity,
                                                                 Effect::base_tilt,
                                                                 Effect::linear_inertia,
                                                                 Effect::rotational_inertia,
                                                                 Effect::imu_time_offset,
                                                                 Effect::bias_drift,
                                                                 Effect::temperature_bias,
                                                                 Effect::crosstalk,
                                                                 Effect::sensor_rotation,
                                                                 Effect::cable};

/// The paper's analytic model (000_… eq. 1–5): bias, gravity, linear and rotational inertia.
inline constexpr EffectSet kDefaultModel = {Effect::bias, Effect::gravity, Effect::linear_inertia,
                                            Effect::rotational_inertia};
/// The smallest useful model: sensor bias and payload gravity from the pose.
inline constexpr EffectSet kMinimalModel = {Effect::bias, Effect::gravity};

/// Parameter values of a model: one fixed-size block per effect; blocks of effects not in
/// `effects` are ignored. Values in the units of `info(e).params[i].unit`.
struct ModelParams {
  EffectSet effects;
  std::array<std::array<double, kMaxEffectParams>, kEffectCount> values{};
  /// User-defined effects (terms and their coefficients), added after the library effects.
  UserEffects user;

  double* block(Effect e) { return values[index(e)].data(); }
  const double* block(Effect e) const { return values[index(e)].data(); }
};

/// Joints whose angles the cable effect depends on (KUKA A4, A5, A6; zero-based 3, 4, 5).
inline constexpr std::array<int, 3> kCableJoints = {3, 4, 5};

}  // namespace zerog::model
