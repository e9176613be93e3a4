#pragma once
// The catalogue of network input features: named quantities computed from one sample's signals.
// One implementation, used by training on the host (zerog::learn) and by the firmware's network
// inference, so both feed the network exactly the same numbers. Real-time safe: no allocation,
// no exceptions (compute_features, feature_name, feature_from_name).
#include <array>
#include <cstdint>
#include <span>
#include <string_view>

namespace zerog::model {

/// One network input. Frames as in proto/frames.md; units SI.
enum class Feature : std::uint8_t {
  // sin and cos of the joint angles A1..A6 (dimensionless)
  sin_q1,
  sin_q2,
  sin_q3,
  sin_q4,
  sin_q5,
  sin_q6,
  cos_q1,
  cos_q2,
  cos_q3,
  cos_q4,
  cos_q5,
  cos_q6,
  // joint velocities A1..A6, rad/s
  qd1,
  qd2,
  qd3,
  qd4,
  qd5,
  qd6,
  // smooth sign of the joint velocity: tanh(qd_j / 0.02 rad/s) (friction-like, dimensionless)
  sign_qd1,
  sign_qd2,
  sign_qd3,
  sign_qd4,
  sign_qd5,
  sign_qd6,
  // sensor origin in the base frame, m
  px,
  py,
  pz,
  // unit gravity direction in the sensor frame: R_base_sensorᵀ (0, 0, −1) (no base tilt)
  gx,
  gy,
  gz,
  // elements of R_base_sensor, row-major (r12 = row 1, column 2)
  r11,
  r12,
  r13,
  r21,
  r22,
  r23,
  r31,
  r32,
  r33,
  // IMU specific force a − g, m/s² (IMU frame)
  fx,
  fy,
  fz,
  // IMU angular rate, rad/s (IMU frame)
  wx,
  wy,
  wz,
  // IMU angular acceleration (derivative of the gyroscope), rad/s² (IMU frame)
  wdx,
  wdy,
  wdz,
  // sensor temperature, °C
  temperature,
  // time since the start of the log, s
  time,
};

inline constexpr int kFeatureCount = static_cast<int>(Feature::time) + 1;

/// Scale of the smooth sign feature: sign_qd_j = tanh(qd_j / kSignVelocityScale_radps).
inline constexpr double kSignVelocityScale_radps = 0.02;

/// The signals of one sample that features are computed from. Plain fixed-size value type.
struct FeatureSignals {
  std::array<double, 6> joints_rad{};                              ///< A1..A6, rad
  std::array<double, 6> joint_vel_radps{};                         ///< A1..A6, rad/s
  std::array<double, 9> R_base_sensor{1, 0, 0, 0, 1, 0, 0, 0, 1};  ///< row-major
  std::array<double, 3> p_base_sensor_m{};                         ///< sensor origin in base, m
  /// IMU frame: specific force (3, m/s²), angular rate (3, rad/s), angular acceleration (3, rad/s²)
  std::array<double, 9> imu{};
  double temperature_C = 25.0;  ///< sensor temperature, °C
  double t_s = 0.0;             ///< time since the start of the log, s
};

/// The feature's name as used in files and on the command line ("sin_q1", "qd3", "sign_qd6",
/// "px", "gx", "r11", "fx", "wx", "wdx", "temperature", "time"). Never null. Real-time safe.
const char* feature_name(Feature f);

/// Looks a name up; returns false (and leaves `out`) if unknown. Real-time safe.
bool feature_from_name(std::string_view name, Feature& out);

/// Value of one feature. Real-time safe.
double feature_value(const FeatureSignals& s, Feature f);

/// Writes features.size() values to `out`, in the order of `features`. Real-time safe.
void compute_features(const FeatureSignals& s, std::span<const Feature> features, double* out);

}  // namespace zerog::model
