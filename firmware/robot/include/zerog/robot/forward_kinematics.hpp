#pragma once
// Kinematics of a RobotModel, the one implementation every caller uses (the cycle, the importer,
// decode-rsi, the simulator and the emulator; proto/robot_kinematics.md): joint angles → pose of
// the flange F and of the F/T sensor frame S in the robot base frame B (proto/frames.md), the
// flange's velocity and acceleration from joint rates and accelerations, the sensor's geometric
// Jacobian, joint torques of a flange wrench, and the spherical wrist's inverse kinematics.
// Written for double only: no caller differentiates the kinematics with Jets (the fit's Ceres
// costs take the pose as data). Real-time safe unless stated: no allocation, no exceptions,
// bounded time (at most kMaxJoints links).
#include <Eigen/Core>
#include <array>
#include <span>

#include "zerog/robot/robot_model.hpp"

namespace zerog::robot {

/// A pose in the base frame B: R_base_x (axes of x in B) and p_base_x_m (origin of x in B, m).
struct Pose {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p_m = Eigen::Vector3d::Zero();
};

/// Pose of the flange F in B. `q_rad` holds the recorded joint angles (rad) in the recording's
/// order (RobotModel::input_index maps them to DH rows); it must have at least
/// model.joint_count values (precondition; `model` must have passed validate()).
Pose flange_pose(const RobotModel& model, std::span<const double> q_rad);

/// Pose of the F/T sensor frame S in B: flange_pose · flange_sensor. Same preconditions.
Pose sensor_pose(const RobotModel& model, std::span<const double> q_rad);

/// Pose and motion of the flange F, all in base axes (B is inertial: it does not move).
struct FlangeMotion {
  Eigen::Matrix3d R_base_flange = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p_base_flange_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d omega_base_radps = Eigen::Vector3d::Zero();       ///< angular velocity
  Eigen::Vector3d omega_dot_base_radps2 = Eigen::Vector3d::Zero();  ///< angular acceleration
  Eigen::Vector3d v_flange_base_mps = Eigen::Vector3d::Zero();      ///< velocity of flange origin
  Eigen::Vector3d a_flange_base_mps2 = Eigen::Vector3d::Zero();     ///< acceleration of origin

  /// Velocity (m/s, base axes) of the body point at `lever_base_m` from the flange origin.
  Eigen::Vector3d velocity_of(const Eigen::Vector3d& lever_base_m) const;
  /// Acceleration (m/s², base axes) of the body point at `lever_base_m` from the flange origin:
  /// a_F + ω̇ × r + ω × (ω × r).
  Eigen::Vector3d acceleration_of(const Eigen::Vector3d& lever_base_m) const;
};

/// Pose, twist and its time derivative of the flange from joint angles, rates and accelerations
/// (each in the recording's order, at least model.joint_count values), analytically by the
/// outward recursion of Newton–Euler (Siciliano et al., Robotics, 2009, §7.5) written in base
/// axes, θ̇_i = sign_i q̇_i, z_i the axis of DH row i (standard DH: frame i−1's z; modified DH:
/// the z after Rx(α)):
///   ω_i = ω_{i−1} + θ̇_i z_i,  ω̇_i = ω̇_{i−1} + θ̈_i z_i + θ̇_i ω_{i−1} × z_i,
/// and each offset Δp between frame origins, rigid in the link that carries it, adds
///   v += ω × Δp,  a += ω̇ × Δp + ω × (ω × Δp).
/// The pose is flange_pose's, to the last bit. Same preconditions as flange_pose.
FlangeMotion flange_motion(const RobotModel& model, std::span<const double> q_rad,
                           std::span<const double> qd_radps, std::span<const double> qdd_radps2);

/// The geometric Jacobian of the F/T sensor frame S at `q_rad`, from one pass of the chain: column
/// k (recorded joint k) is the linear velocity of S's origin (rows 0-2) and the angular velocity
/// (rows 3-5) per unit rate of that joint, both in B axes: sign · (z × (p_S − p_axis), z) for
/// the joint's axis z through p_axis (standard DH: frame i−1's z; modified DH: z after Rx(α),
/// through the origin moved by a). Columns joint_count.. are zero. Real-time safe; same
/// preconditions as flange_pose.
void sensor_jacobian(const RobotModel& model, std::span<const double> q_rad,
                     Eigen::Matrix<double, 6, kMaxJoints>& jacobian);

/// Joint torques of a wrench on the flange, τ = Jᵀ w (the virtual work of the wrench over each
/// joint's motion): `force_base_N` in B, `moment_flange_base_Nm` about the flange origin, B axes.
/// J is the flange Jacobian (linear velocity of the flange origin and angular velocity, B axes,
/// per unit rate of each recorded joint) by central differences of flange_pose (step 1e-6 rad).
/// `tau_Nm[k]` is recorded joint k's torque (N·m); `q_rad` and `tau_Nm` hold at least
/// model.joint_count values. Not for the cycle (2 · joint_count forward kinematics).
void joint_torques(const RobotModel& model, std::span<const double> q_rad,
                   const Eigen::Vector3d& force_base_N,
                   const Eigen::Vector3d& moment_flange_base_Nm, std::span<double> tau_Nm);

/// Inverse kinematics of a KUKA-type spherical wrist: the joint angles A4..A6 that turn the
/// flange to `R_base_flange` while A1..A3 stay at `q_arm_rad[0..2]` (only the orientation is
/// solved: the flange position follows from the arm pose). With R_3 the orientation of DH frame
/// 3 (from A1..A3) and θ_i = sign_i q_i + offset_i, a wrist with α4 = +π/2, α5 = −π/2,
/// a4 = a5 = d5 = 0 (the KR 210 R2700's) gives R_3ᵀ R_base_flange Rx(α6)ᵀ = Rz(θ4) Ry(−θ5) Rz(θ6),
/// a ZYZ Euler decomposition (Siciliano et al., Robotics, §2.12.2, eq. 2.74–2.75 with a sign on
/// θ5). Returns the two solutions (the wrist flip): [0] with A5 ≥ 0, [1] with A5 ≤ 0, each a full
/// joint vector (A1..A3 copied, A4 and A6 in (−π, π]). At the wrist singularity (|sin θ5| below
/// 1e-12) only A4 ± A6 is determined: A4 keeps `q_arm_rad[3]` and both solutions are equal. Joint
/// limits are not checked. Preconditions: `model` passed validate(), has 6 joints in standard DH,
/// the identity joint order, such a wrist and a table that ends at the flange (last_flange the
/// identity). Not for the cycle (host design code), but allocation-free.
std::array<std::array<double, 6>, 2> wrist_inverse_kinematics(
    const RobotModel& model, const std::array<double, 6>& q_arm_rad,
    const Eigen::Matrix3d& R_base_flange);

}  // namespace zerog::robot
