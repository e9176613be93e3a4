#pragma once
// Forward kinematics of a RobotModel: joint angles → pose of the flange F and of the F/T sensor
// frame S in the robot base frame B (proto/frames.md, proto/robot_kinematics.md).
// Real-time safe: no allocation, no exceptions, bounded time (at most kMaxJoints links).
#include <Eigen/Core>
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

}  // namespace zerog::robot
