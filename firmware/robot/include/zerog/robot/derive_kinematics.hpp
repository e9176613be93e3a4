#pragma once
// The F/T sensor's motion from the robot: a joint stream (forward kinematics) or a pose stream
// → angular velocity ω and acceleration ω̇ of the sensor frame S, linear acceleration of the S
// origin, and the specific force there, for the model's inertial effects when the IMU is missing
// or worse (issue 13, item 2; proto/robot_kinematics.md). And the rule that picks, per signal,
// the IMU or the robot (kinematics = "imu" | "robot" | "auto").
//
// Frames (proto/frames.md): B robot base, taken as inertial (the robot's base does not move);
// S the F/T sensor frame. Units SI.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <span>
#include <string>

#include "zerog/robot/forward_kinematics.hpp"
#include "zerog/robot/robot_model.hpp"
#include "zerog/robot/savitzky_golay.hpp"

namespace zerog::robot {

/// Standard gravity, m/s² (ISO 80000-3): the same value as zerog::model::kStandardGravity.
inline constexpr double kGravityMps2 = 9.80665;

struct DifferentiatorSettings {
  SgSettings sg;  ///< window and polynomial order (choose_sg_window picks M from a bandwidth)
  /// Gravity in B, m/s². Default: B's z axis up, no tilt.
  Eigen::Vector3d gravity_base_mps2{0.0, 0.0, -kGravityMps2};
};

/// The sensor's motion at one sample.
struct SensorKinematics {
  Pose
      pose_base_sensor;  ///< S in B as given (pose overload) or from forward kinematics; unsmoothed
  Eigen::Vector3d omega_sensor_radps = Eigen::Vector3d::Zero();  ///< ω of S relative to B, S axes
  Eigen::Vector3d omega_dot_sensor_radps2 = Eigen::Vector3d::Zero();  ///< dω/dt, S axes
  /// Acceleration of the S origin relative to B (inertial), B axes, m/s².
  Eigen::Vector3d accel_base_mps2 = Eigen::Vector3d::Zero();
  /// Specific force at the S origin, a − g, S axes, m/s² (what an accelerometer at S reads).
  Eigen::Vector3d specific_force_sensor_mps2 = Eigen::Vector3d::Zero();
  /// False within M samples of either end: the window was shifted inwards and the fit evaluated
  /// off its centre (no lag, but more noise than sg_noise_gain states).
  bool centred = true;
};

enum class DeriveError : std::uint8_t {
  ok,
  settings,     ///< SgSettings not valid()
  sizes,        ///< inputs and output of different lengths, or too few joints per row
  too_short,    ///< fewer samples than the window (2M+1)
  time_order,   ///< time stamps not finite and strictly increasing
  robot_model,  ///< the RobotModel did not pass validate()
};

struct DeriveStatus {
  DeriveError code = DeriveError::ok;
  std::size_t sample = 0;  ///< the offending sample (time_order)
  bool ok() const { return code == DeriveError::ok; }
};

/// From poses of S in B at `times_s` (strictly increasing, s; need not be uniform), one
/// SensorKinematics per sample into `out` (same length as `times_s` and `poses`).
///
/// Per centre sample c, with the window's samples k: positions are fitted directly (p(τ));
/// orientations as rotation vectors relative to the centre, r_k = Log(R_cᵀ R_k) (so R_k =
/// R_c Exp(r_k), r in S axes). With the fitted r(τ): ω_S = ṙ(0) and ω̇_S = r̈(0), exact at
/// r(0) = 0 since ω = J_r(r) ṙ with J_r(0) = I and ω̇(0) = r̈(0) − ½ ṙ(0) × ṙ(0) = r̈(0)
/// (J_r the right Jacobian of SO(3), Sola et al., "A micro Lie theory", 2018, eq. 143); the
/// noise-sized r(0) of the fit is neglected. a_B = p̈(0); specific force = R_cᵀ (a_B − g_B).
/// Lag 0 (centred window); noise gains and bandwidth as savitzky_golay.hpp states, per axis.
/// Host and start-up code (no allocation, but O(N·M) work: not for the cycle).
DeriveStatus derive_kinematics(std::span<const double> times_s, std::span<const Pose> poses,
                               const DifferentiatorSettings& settings,
                               std::span<SensorKinematics> out);

/// Specific force at a point P fixed in S, from S's motion: f_P = f_S + ω̇ × r + ω × (ω × r)
/// (rigid-body acceleration transfer), r = p_SP the point in S; everything in S axes, SI. For an
/// IMU off the sensor origin (r = the rig's sensor_imu offset). Real-time safe.
inline Eigen::Vector3d specific_force_at_point(const SensorKinematics& k,
                                               const Eigen::Vector3d& r_sensor_point_m) {
  return k.specific_force_sensor_mps2 + k.omega_dot_sensor_radps2.cross(r_sensor_point_m) +
         k.omega_sensor_radps.cross(k.omega_sensor_radps.cross(r_sensor_point_m));
}

/// From joint angles: row i of `joints_rad` (row-major, `joints_per_row` values a row, rad, in
/// the recording's order) is the robot's joint vector at times_s[i]. Forward kinematics gives
/// each row's pose of S (written to out[i].pose_base_sensor), then the pose overload's
/// differentiator runs on those poses. Same guarantees.
DeriveStatus derive_kinematics(const RobotModel& model, std::span<const double> times_s,
                               std::span<const double> joints_rad, std::size_t joints_per_row,
                               const DifferentiatorSettings& settings,
                               std::span<SensorKinematics> out);

// ------------------------------------------------------------------------------------------
// Which source feeds which signal.

/// The log's `kinematics` setting.
enum class KinematicsMode : std::uint8_t { imu, robot, automatic };
/// The three inertial signals of the model: ω (rotational inertia, gyroscopic term), ω̇
/// (rotational inertia) and specific force (linear inertia, gravity with the IMU).
enum class KinematicSignal : std::uint8_t { omega, omega_dot, specific_force };
/// imu: the gyro (ω; ω̇ differenced: by Savitzky–Golay at import under kinematics = "auto", by
/// host/ident's 5-point central difference of the angular-rate column,
/// model::angular_accel_central, as zerog-rt's cycle computes it, under "imu") or the
/// accelerometer (specific force); robot: derive_kinematics; none: not available.
enum class KinematicSource : std::uint8_t { none, imu, robot };

/// What a log has.
struct KinematicsAvailable {
  bool gyro = false;           ///< IMU angular rate
  bool accelerometer = false;  ///< IMU specific force
  bool robot = false;          ///< joints with a robot model, or the pose of S
};

struct SourceChoice {
  KinematicSource source = KinematicSource::none;
  std::string reason;  ///< one sentence: why this source (for the fit's report)
};

struct SourceChoices {
  SourceChoice omega;
  SourceChoice omega_dot;
  SourceChoice specific_force;
  const SourceChoice& operator[](KinematicSignal s) const;
};

/// The rule (proto/robot_kinematics.md, "Choosing the source", measured by
/// tests/unit/robot/source_compare_test.cpp):
///   imu   — every signal from the IMU where it has the sensor; none where it has not.
///   robot — every signal from the robot; none if there is no robot.
///   auto  — each signal from the IMU where the IMU has the sensor, else from the robot:
///           ω: the gyro (it measures the motion itself, arm elasticity and all; in the rigid
///           simulator the robot is 2.5–5.5× closer, but both stay below 1.2e-3 rad/s, whose
///           gyroscopic torque is negligible); ω̇: the gyro differenced by Savitzky–Golay at
///           import (zerog import writes it as the log's imu_dw*_radps2 columns; measured 2×
///           closer than the robot's second derivative, which host/ident's 5-point difference
///           of the gyro is not);
///           specific force: the accelerometer (it senses the true vertical and the arm's
///           deflection; in the rigid simulator the robot is up to 2.7× closer).
/// Configuration time (allocates the reasons).
SourceChoices choose_sources(KinematicsMode mode, const KinematicsAvailable& available);

const char* to_string(KinematicSource source);
const char* to_string(KinematicSignal signal);

}  // namespace zerog::robot
