#pragma once
// The signal dictionary: named kinematic and environmental signals of one sample, and the bases
// (a signal, a function of one, or a product of two) that user-defined effects and the
// discovery of missing physics are built from. One implementation, shared by the host tools
// (fit, diagnose, discovery) and the firmware. Names, units and how each signal is computed:
// proto/user_effects.md. Frames as in proto/frames.md: S sensor, B robot base, I IMU.
//
// Real-time safe: dictionary_signals, basis_value, format_basis (into a caller's buffer) and
// parse_basis allocate nothing and throw nothing.
#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "zerog/model/features.hpp"

namespace zerog::model {

struct RigGeometry;  // predict.hpp

/// The base signals, SI. Joint velocities and accelerations and the sensor's linear velocity
/// come from central differences of the logged joint angles and sensor position; angular rate,
/// angular acceleration and linear acceleration from the IMU (moved to the sensor origin).
// clang-format off
enum class Signal : std::uint8_t {
  q1, q2, q3, q4, q5, q6,                    ///< joint angles A1..A6, rad
  qd1, qd2, qd3, qd4, qd5, qd6,              ///< joint velocities, rad/s
  qdd1, qdd2, qdd3, qdd4, qdd5, qdd6,        ///< joint accelerations, rad/s²
  vx_S, vy_S, vz_S, vx_B, vy_B, vz_B,        ///< velocity of the S origin, m/s (in S, in B)
  ax_S, ay_S, az_S, ax_B, ay_B, az_B,        ///< acceleration of the S origin (no g), m/s²
  wx_S, wy_S, wz_S, wx_B, wy_B, wz_B,        ///< angular velocity of S, rad/s (in S, in B)
  wdx_S, wdy_S, wdz_S, wdx_B, wdy_B, wdz_B,  ///< angular acceleration of S, rad/s²
  gx_S, gy_S, gz_S,                          ///< unit gravity direction in S (R_BSᵀ (0,0,−1))
  px_B, py_B, pz_B,                          ///< S origin in B, m
  temperature,                               ///< sensor temperature − 25 °C, K
  time,                                      ///< time since the start of the log, s
};
// clang-format on
inline constexpr int kSignalCount = static_cast<int>(Signal::time) + 1;

/// What a signal needs from the log.
enum class SignalSource : std::uint8_t { joints, position, imu, pose, temperature, time };

struct SignalInfo {
  const char* name;  ///< as written in effect files, e.g. "qd6", "wz_S"
  const char* unit;  ///< SI unit, e.g. "rad/s", "m/s^2", "1"
  SignalSource source;
  bool angle;     ///< a joint angle: sin() and cos() apply
  bool velocity;  ///< a velocity: sign() and tanh(x/eps) apply
};
const SignalInfo& signal_info(Signal s);
bool signal_from_name(std::string_view name, Signal& out);

/// A function of one signal: the value, sin or cos of an angle, sign or tanh(x/eps) of a
/// velocity (eps in the signal's unit; sign(0) = 0).
enum class FactorOp : std::uint8_t { value, sin, cos, sign, tanh };
struct Factor {
  Signal signal = Signal::q1;
  FactorOp op = FactorOp::value;
  double eps = 0.0;  ///< tanh only, > 0
  bool operator==(const Factor&) const = default;
};
/// A basis function: one factor, or the product of two.
struct Basis {
  Factor a;
  Factor b;
  bool product = false;
  bool operator==(const Basis&) const = default;
};

/// The values of every base signal of one sample.
using DictionarySignals = std::array<double, kSignalCount>;

/// The inputs the dictionary is computed from: the network's feature signals (joints and their
/// velocities, pose, IMU in its own frame, temperature, time) plus what only the dictionary
/// needs. Velocities here are central differences (see proto/user_effects.md).
struct KinematicInputs {
  FeatureSignals features;                    ///< joint_vel_radps: central differences here
  std::array<double, 6> joint_acc_radps2{};   ///< A1..A6, rad/s²
  std::array<double, 3> v_base_sensor_mps{};  ///< velocity of the S origin in B, m/s
};

/// Velocity and acceleration of `n` values at the middle of three rows taken at t0 < t1 < t2:
/// v = (x2 − x0) / (t2 − t0), a = 2 ((x2 − x1)/h1 − (x1 − x0)/h0) / (h0 + h1) with h0 = t1 − t0,
/// h1 = t2 − t1 (the parabola through the three points). `a` may be null. The one difference
/// rule of the dictionary, for the host's logs and the firmware's rows. Real-time safe.
void central_differences(const double* x0, const double* x1, const double* x2, int n, double t0,
                         double t1, double t2, double* v, double* a);

/// All base signals of one sample. The IMU's specific force f_I and rate ω_I are moved to the
/// sensor origin with the rig geometry: ω_S = R_SI ω_I, a_S = R_SI f_I + g_S + ω̇_S × r +
/// ω_S × (ω_S × r), r = −p_SI (rigid body), g_S = R_BSᵀ (0, 0, −9.80665). Real-time safe.
DictionarySignals dictionary_signals(const KinematicInputs& in, const RigGeometry& rig);

/// Value of a basis for one sample. Real-time safe.
double basis_value(const Basis& b, const DictionarySignals& s);

/// The unit of a basis ("rad/s", "1", "m/s*rad/s"); `out` gets at most `size` − 1 characters
/// and a terminating zero. Real-time safe.
void basis_unit(const Basis& b, char* out, std::size_t size);
/// The basis as text ("tanh(qd6/0.02)", "sin(q5)*cos(q4)", "wz_S"), as parse_basis reads it.
void format_basis(const Basis& b, char* out, std::size_t size);

/// Parses a basis written as format_basis writes it (blanks around '*' allowed). Returns false
/// and sets `error` (a static string) and `error_pos` (0-based character offset) if it cannot.
/// Real-time safe.
bool parse_basis(std::string_view text, Basis& out, const char*& error, std::size_t& error_pos);

/// What a basis needs from the log (the union of its factors' sources, as a bit mask of
/// 1 << SignalSource).
unsigned basis_sources(const Basis& b);

}  // namespace zerog::model
