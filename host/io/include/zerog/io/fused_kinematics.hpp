#pragma once
// Fused kinematics (issue 28, `kinematics = "fused"`, proto/import_mapping.md): the sensor's
// motion from the measured joints AND the IMU, over the whole log (non-causal), so that the
// fitted model and the floors use the best estimate of the motion.
//
// Neither source alone is good enough on a real arm carrying 100 kg:
// - the IMU is the payload's own motion, but its white noise × mass (the accelerometer) and its
//   differenced noise × inertia (the gyro) enter every predicted row;
// - the joints are nearly noise-free (encoder quantisation only) but are the MOTOR side of
//   elastic gearboxes: the link, and the payload with it, sags under the load (a slowly changing
//   tilt of gravity in S) and rings after every move (5-15 Hz main axes).
// The fusion, in three steps (proto/robot_kinematics.md, "Fused kinematics", has the measurements):
// 1. the link's deflection δ per joint from the robot file's elasticity (robot::deflection_accel,
//    the simulator's formula), driven by the motor's acceleration q̈ (the joints' Savitzky–Golay
//    second derivative, excitation_sg) and the load τ = Jᵀ w of the measured wrench
//    low-passed at load_bandwidth_hz (zero phase), integrated by semi-implicit Euler at
//    substep_s from the static sag δ = τ/k at the first sample; a rigid robot has δ = 0;
// 2. the motion by forward kinematics and the Savitzky–Golay differentiator
//    (robot::derive_kinematics, zero lag): the motor's through `sg`, plus the deflection's
//    derive(q + δ) − derive(q) through the wider `accel_sg`; ω̇ from q + δ through `accel_sg`;
//    then ω, ω̇ and the specific force at the IMU;
// 3. a complementary split at `crossover_hz`: below it the IMU, above it the joints. The
//    difference IMU − joints is low-passed (first order, forward then backward: zero phase, each
//    pass −3 dB at the crossover) and added to the joints' signal; ω̇ adds the difference's
//    derivative. What the IMU corrects is the sag the model of step 1 misses (its load, its
//    stiffness) and any slow bias of either source; what the joints give is everything faster,
//    free of the IMU's white noise.
// Frames (proto/frames.md): B base, F flange, S sensor, I IMU. SI units.
#include <Eigen/Core>
#include <span>
#include <vector>

#include "zerog/formats/log.hpp"
#include "zerog/robot/robot_model.hpp"
#include "zerog/robot/savitzky_golay.hpp"

namespace zerog::io {

struct FusionSettings {
  /// Below it the IMU, above it the joints (Hz).
  double crossover_hz = 0.2;
  /// The load's low-pass (Hz): the weight and other slow loads, not the noise of the wrench.
  double load_bandwidth_hz = 3.0;
  /// The motor's acceleration that drives the modes: the joints' Savitzky–Golay second derivative.
  robot::SgSettings excitation_sg;
  /// Savitzky–Golay windows: the motor's motion (ω and the specific force), and the
  /// deflection's motion and ω̇ (wider: the deflection is an ODE's output, free of the encoders'
  /// quantisation, which cancels in derive(q + δ) − derive(q)).
  robot::SgSettings sg;
  robot::SgSettings accel_sg;
  double substep_s = 1e-3;  ///< the deflection's integration step
};

/// Defaults (zerog import's, kinematics = "fused"; robot_kinematics.md, "Fused kinematics").
inline constexpr double kFusedBandwidthHz = 7.0;        ///< the motor's differentiator
inline constexpr double kFusedAccelBandwidthHz = 15.0;  ///< the deflection's and ω̇'s
inline constexpr double kFusedCrossoverHz = 0.2;
inline constexpr double kFusedExcitationHz = 5.0;  ///< a PTP's acceleration is below it

/// The settings for joints sampled every `period_s`: the Savitzky–Golay windows
/// (robot::choose_sg_window, order 3) for the bandwidths given and kFusedExcitationHz.
FusionSettings fusion_settings(double period_s, double bandwidth_hz = kFusedBandwidthHz,
                               double accel_bandwidth_hz = kFusedAccelBandwidthHz,
                               double crossover_hz = kFusedCrossoverHz);

/// What the fusion reads. Spans of the joint stream (its own times) and of the log's rows.
struct FusionInput {
  const robot::RobotModel* robot = nullptr;  ///< with its flange_sensor and elasticity
  std::span<const double> joint_t_s;         ///< the joint stream's times, increasing
  std::span<const double> joints_rad;  ///< row-major, robot->joint_count a row, recorded order
  std::span<const double> row_t_s;     ///< the log's rows, increasing, within the stream
  std::span<const Eigen::Vector3d> imu_specific_force_mps2;  ///< per row, I axes (logged)
  std::span<const Eigen::Vector3d> imu_angular_rate_radps;   ///< per row, I axes (logged)
  std::span<const Eigen::Vector3d> force_sensor_N;           ///< per row, S axes (measured)
  std::span<const Eigen::Vector3d> torque_sensor_Nm;         ///< per row, about S's origin
  Eigen::Matrix3d R_sensor_imu = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p_sensor_imu_m = Eigen::Vector3d::Zero();
};

struct FusionResult {
  /// Per row, I axes.
  std::vector<Eigen::Vector3d> specific_force_mps2, angular_rate_radps, angular_accel_radps2;
  /// The deflection of each joint (recorded order): mean (the sag) and RMS about it (the
  /// ringing and the sag's changes), rad; zero for a rigid robot.
  std::vector<double> deflection_mean_rad, deflection_rms_rad;
  /// RMS over the rows of what the IMU corrected (the low-passed IMU − joints), per signal.
  double correction_specific_force_mps2 = 0.0;
  double correction_angular_rate_radps = 0.0;
  bool elastic = false;  ///< step 1 ran (the robot has elasticity)
};

/// A log's rows as FusionInput reads them (the IMU as logged, the measured wrench), owned.
struct RowSignals {
  std::vector<double> t_s;
  std::vector<Eigen::Vector3d> specific_force_mps2, angular_rate_radps, force_N, torque_Nm;
};
RowSignals row_signals(const formats::Log& log);
/// A FusionInput over `rows` (which must outlive it), its robot, joints and mountings unset.
FusionInput fusion_input(const RowSignals& rows);

/// Runs the three steps. Throws std::runtime_error naming what is wrong (sizes, a stream too
/// short for the differentiator).
FusionResult fuse_kinematics(const FusionInput& in, const FusionSettings& settings);

/// The zero-phase first-order low-pass of step 3 over samples at `t_s` (any spacing), in place:
/// forward then backward, each pass y_i = a y_{i−1} + (1 − a) x_i with a = exp(−2π f_c Δt).
void zero_phase_lowpass(std::span<const double> t_s, std::span<Eigen::Vector3d> values,
                        double cutoff_hz);

}  // namespace zerog::io
