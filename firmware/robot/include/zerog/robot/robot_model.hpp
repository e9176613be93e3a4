#pragma once
// The robot arm as zerog needs it (proto/robot_kinematics.md): a Denavit–Hartenberg chain of
// revolute joints from the robot base frame B to the flange frame F, and the F/T sensor frame S
// in F (the rig's `flange_sensor`, proto/frames.md). Any number of joints up to kMaxJoints
// (a 6-axis KR 210 R2700 and a 7-axis LBR iiwa are both described in calib/robots/).
//
// A pure value type: no parsing here (the host reads it from a robot file with
// zerog/formats/robot_toml.hpp, the shipped KR 210 R2700 with formats::kr210_r2700()), no
// allocation; validate() once at configuration.
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <string>

#include "zerog/status.hpp"

namespace zerog::robot {

/// Most joints a RobotModel can hold (fixed capacity: the cycle passes fixed-size values).
inline constexpr int kMaxJoints = 8;

/// Which DH convention the table is written in.
///   dh  (standard, distal; Siciliano et al., Robotics, 2009, §2.8.2, eq. 2.52):
///        T_{i−1,i} = Rz(θ_i) Tz(d_i) Tx(a_i) Rx(α_i)
///   mdh (modified, proximal; Craig, Introduction to Robotics, 3rd ed., §3.4, eq. 3.6):
///        T_{i−1,i} = Rx(α_{i−1}) Tx(a_{i−1}) Rz(θ_i) Tz(d_i)
/// For mdh, row i holds a_{i−1} and α_{i−1} (the values written on joint i's row of Craig's
/// table), so that each row is one joint either way.
enum class DhConvention : std::uint8_t { dh, mdh };

/// One revolute joint's row of the table. The joint angle q (rad, as the controller reports
/// it) enters as θ_i = sign · q + theta_offset_rad.
struct DhJoint {
  double a_m = 0.0;               ///< link length, m
  double alpha_rad = 0.0;         ///< link twist, rad
  double d_m = 0.0;               ///< link offset, m
  double theta_offset_rad = 0.0;  ///< θ_i at q = 0, rad
  double sign = 1.0;              ///< +1 or −1: the controller's joint direction against z
};

/// One joint's elasticity (proto/sim_robot.md; a robot file's optional stiffness_Nm_per_rad,
/// mode_hz, damping_ratio): the link follows the motor through a torsional spring k and damper,
/// its effective inertia k / ω² (ω = 2π mode_hz). stiffness 0: a rigid joint.
struct JointElasticity {
  double stiffness_Nm_per_rad = 0.0;  ///< k_i
  double mode_hz = 0.0;               ///< the link's natural frequency on the joint spring
  double damping_ratio = 0.0;         ///< ζ_i
  bool rigid() const { return stiffness_Nm_per_rad <= 0.0; }
};

/// The link's deflection acceleration δ̈ of one elastic joint (controller joint coordinates: q =
/// motor angle, q + δ = link angle), with the link's inertia J taken constant through its natural
/// frequency ω = sqrt(k / J):
///   J (q̈ + δ̈) = −k δ − d δ̇ + τ   (d = 2 ζ sqrt(k J))   ⇒   δ̈ = ω² (τ / k − δ) − 2 ζ ω δ̇ − q̈
/// τ is the load torque on the joint (N·m), q̈ the motor's acceleration. At rest δ = τ / k. The
/// one formula of the elastic joint: the simulator's arm and the fused kinematics' deflection
/// both step it. 0 for a rigid joint.
inline double deflection_accel(const JointElasticity& j, double delta_rad, double delta_dot_radps,
                               double motor_qdd_radps2, double load_Nm) {
  if (j.rigid()) return 0.0;
  const double w = 2.0 * std::numbers::pi * j.mode_hz;
  return w * w * (load_Nm / j.stiffness_Nm_per_rad - delta_rad) -
         2.0 * j.damping_ratio * w * delta_dot_radps - motor_qdd_radps2;
}

/// One elastic joint's deflection δ and its rate δ̇ carried over `span_s` seconds by
/// semi-implicit Euler steps of at most `substep_s` (δ̇ += h δ̈, then δ += h δ̇), the motor's
/// acceleration and the load taken linear between their values at the span's start (`qdd0`,
/// `load0`) and end (`qdd1`, `load1`). Returns δ̈ of the last sub-step, the one that moved δ̇
/// (as sim::ElasticArm's link acceleration): deflection_accel evaluated again after the last
/// step would take δ a half step ahead of the inputs, and on a stiff mode that half step is
/// large: a load turning at a steady rate makes δ̇ steady and δ̈ zero, but that evaluation
/// gives ω² h δ̇ / 2 (A4 of the KR 210, 55 Hz, 1 ms, δ̇ 1e-4 rad/s: 6e-3 rad/s², measured as
/// a steady angular acceleration of the estimate on the elastic glide: proto/loop.md, "The
/// deflection's acceleration"). The one integration of deflection_accel: the fused kinematics
/// of `zerog import` (whole log) and the cycle's motion estimator (one row at a time) both call
/// it. Real-time safe; a rigid joint stays at 0.
inline double advance_deflection(const JointElasticity& j, double& delta_rad,
                                 double& delta_dot_radps, double span_s, double substep_s,
                                 double qdd0_radps2, double qdd1_radps2, double load0_Nm,
                                 double load1_Nm) {
  if (j.rigid()) return 0.0;
  const int steps =
      span_s > 0.0 ? std::max(1, static_cast<int>(std::ceil(span_s / substep_s - 1e-9))) : 0;
  if (steps == 0) return deflection_accel(j, delta_rad, delta_dot_radps, qdd1_radps2, load1_Nm);
  const double h = span_s / steps;
  double accel = 0.0;
  for (int m = 1; m <= steps; ++m) {
    const double along = (m - 0.5) / steps;  // inputs linear between the two ends
    const double qdd = qdd0_radps2 + along * (qdd1_radps2 - qdd0_radps2);
    const double load = load0_Nm + along * (load1_Nm - load0_Nm);
    accel = deflection_accel(j, delta_rad, delta_dot_radps, qdd, load);
    delta_dot_radps += h * accel;
    delta_rad += h * delta_dot_radps;
  }
  return accel;
}

/// A rigid transform: the pose of a child frame in a parent frame.
struct FrameTransform {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();  ///< child axes in parent (R_parent_child)
  Eigen::Vector3d p_m = Eigen::Vector3d::Zero();    ///< child origin in parent, m
};

struct RobotModel {
  DhConvention convention = DhConvention::dh;
  int joint_count = 0;  ///< 1..kMaxJoints
  std::array<DhJoint, kMaxJoints> joints{};
  /// Joint order: DH row i takes the recorded joint value q[input_index[i]] (0-based column of
  /// the recording's joint vector). A permutation of 0..joint_count−1; identity by default.
  std::array<int, kMaxJoints> input_index{0, 1, 2, 3, 4, 5, 6, 7};
  /// Flange frame F in the last DH frame (identity when the table ends at the flange).
  FrameTransform last_flange;
  /// F/T sensor frame S in the flange frame F (the rig's `flange_sensor`).
  FrameTransform flange_sensor;
  /// Each DH row's joint elasticity (all rigid unless the robot file gives it).
  std::array<JointElasticity, kMaxJoints> elasticity{};
  /// True when some joint is elastic.
  bool elastic() const {
    for (int i = 0; i < joint_count; ++i)
      if (!elasticity[static_cast<std::size_t>(i)].rigid()) return true;
    return false;
  }
};

/// Checks a model before use: ok(), or invalid_setting naming the field refused as a path in
/// RobotModel ("joint_count", "joints[2]", "joints[2].sign", "input_index[1]", "flange_sensor",
/// "last_flange.R") with why, without the field's name ("must be +1 or -1"). Configuration time:
/// a failure allocates its message (the check itself does not).
zerog::Status validate(const RobotModel& model);

}  // namespace zerog::robot
