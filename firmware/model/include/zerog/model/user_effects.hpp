#pragma once
// User-defined effects: named sets of terms, each a fitted coefficient times a basis from the
// signal dictionary (dictionary.hpp), added to one axis of the predicted wrench — in the sensor
// frame S, or along a base-frame direction turned into S. Linear in their coefficients. They add
// to the sensor's output after the library effects (a load that passes through a crosstalk of
// E is off by E times itself). File format: proto/user_effects.md.
//
// Fixed-size value types (copyable in the cycle); user_wrench and user_design are real-time safe.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string_view>

#include "zerog/model/dictionary.hpp"

namespace zerog::model {

inline constexpr int kMaxUserTerms = 48;
inline constexpr int kMaxUserEffects = 8;
inline constexpr int kUserNameSize = 48;  ///< bytes of an effect name, with its terminating zero

/// Names of the wrench axes, index 0..5: Fx Fy Fz (N), Mx My Mz (N·m).
inline constexpr std::array<const char*, 6> kWrenchAxisNames = {"Fx", "Fy", "Fz", "Mx", "My", "Mz"};
/// The index of an axis name, or −1. Real-time safe.
constexpr int wrench_axis_from_name(std::string_view name) {
  for (int k = 0; k < 6; ++k)
    if (name == kWrenchAxisNames[static_cast<std::size_t>(k)]) return k;
  return -1;
}

/// Which frame a term's axis is in.
enum class TermFrame : std::uint8_t {
  sensor,  ///< axis k of the sensor-frame wrench
  base,    ///< direction e_k of the base frame, turned into S: F_S += c b R_BSᵀ e_k (M alike)
};

struct UserTerm {
  Basis basis;
  std::uint8_t axis = 0;  ///< 0..5: Fx Fy Fz Mx My Mz (in `frame`)
  TermFrame frame = TermFrame::sensor;
  std::uint8_t effect = 0;  ///< index into UserEffects::names
  bool operator==(const UserTerm&) const = default;
};

/// The user-defined effects of a model and their coefficients (one per term).
struct UserEffects {
  int num_effects = 0;
  std::array<std::array<char, kUserNameSize>, kMaxUserEffects> names{};
  int num_terms = 0;
  std::array<UserTerm, kMaxUserTerms> terms{};
  /// Coefficient of each term: the wrench axis's unit (N or N·m) divided by the basis's unit.
  std::array<double, kMaxUserTerms> coeff{};

  bool empty() const { return num_terms == 0; }
};

/// The wrench direction (sensor frame) of a term: a unit axis of S, or R_BSᵀ e_k for a base-frame
/// axis (force or torque part). Real-time safe.
Eigen::Matrix<double, 6, 1> term_direction(const UserTerm& t, const Eigen::Matrix3d& R_base_sensor);

/// ∂w/∂coeff: column j is term j's basis value times its direction (6 × num_terms used,
/// column-major into `out`, which holds 6 × kMaxUserTerms). Real-time safe.
void user_design(const UserEffects& u, const DictionarySignals& s,
                 const Eigen::Matrix3d& R_base_sensor, double* out);

/// Σ_j coeff_j · basis_j · direction_j: the wrench the user effects add (sensor frame). Real-time
/// safe.
Eigen::Matrix<double, 6, 1> user_wrench(const UserEffects& u, const DictionarySignals& s,
                                        const Eigen::Matrix3d& R_base_sensor);

/// What every term needs from the log (bit mask of 1 << SignalSource).
unsigned user_sources(const UserEffects& u);

}  // namespace zerog::model
