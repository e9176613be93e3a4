#pragma once
// A robot that is not rigid (issue 28): each joint's link follows its motor through a torsional
// spring and damper, so the payload lags, overshoots and rings after a motion, and sags under
// its own weight, while the encoders (motor side) report the commanded path.
//
// Per joint i, in the controller's joint coordinates (q = motor angle, q + δ = link angle), with
// the link's effective inertia J_i about the axis taken constant through its natural frequency
// ω_i = sqrt(k_i / J_i):
//
//   J_i (q̈_i + δ̈_i) = −k_i δ_i − d_i δ̇_i + τ_i        (d_i = 2 ζ_i sqrt(k_i J_i))
//   δ̈_i = ω_i² (τ_i / k_i − δ_i) − 2 ζ_i ω_i δ̇_i − q̈_i
//
// τ_i is the payload's load on joint i: τ = Jᵀ(q) w, the flange Jacobian's transpose applied to
// the wrench the payload's weight exerts on the flange (force in B, moment about the flange
// origin), i.e. the virtual work of the load over the joint's motion; the payload's inertia is in
// J_i. At rest δ = τ / k (the static sag).
// Simplifications (documented in proto/sim_robot.md): the joints are decoupled (no inertia
// coupling between axes), J_i does not change with the pose, the arm's own weight is not a load
// (its sag is a fixed function of the pose that the controller's absolute-accuracy calibration
// absorbs), and the load is taken from the previous row (12 ms earlier).
//
// Frames (proto/frames.md): B robot base (inertial), F flange. Not real-time code, allocation-free.
#include <Eigen/Core>
#include <array>

#include "zerog/robot/robot_model.hpp"
#include "zerog/sim/robot.hpp"
#include "zerog/sim/trajectory.hpp"

namespace zerog::sim {

/// One joint's elasticity (the robot model's: stiffness 0 is a rigid joint).
using JointElasticity = robot::JointElasticity;

struct ElasticityConfig {
  bool enabled = false;
  std::array<JointElasticity, 6> joints{};
  double substep_s = 0.001;  ///< integration step (semi-implicit Euler); ω·dt ≤ 0.1 at 15 Hz
};

/// The KR 210 R2700's elasticity as its robot file gives it (kr210(); proto/sim_robot.md has the
/// sources), enabled.
ElasticityConfig kr210_elasticity();

/// Joint torques (N·m, controller joint coordinates) of a wrench on the flange: τ = Jᵀ w, with
/// robot::joint_torques on the simulated arm (kr210()).
JointVector joint_torques(const JointVector& q_rad, const Eigen::Vector3d& force_base_N,
                          const Eigen::Vector3d& moment_flange_base_Nm);

/// The payload's weight as a load on the joints: m g (g = −9.80665 m/s² along B's z) at its
/// centre of mass `com_sensor_m` (in the sensor frame S, at `p_flange_sensor_m` on the flange, S
/// turned R_base_sensor in B), through joint_torques at the link angles. Its inertia is not a
/// load: it is part of each link's effective inertia k/ω².
JointVector weight_load(const JointVector& link_q_rad, const Eigen::Matrix3d& R_base_sensor,
                        const Eigen::Vector3d& p_flange_sensor_m,
                        const Eigen::Vector3d& com_sensor_m, double mass_kg);

/// A wrench on the payload as a load on the joints: the force `force_base_N` (B) at
/// `point_sensor_m` (S) and the torque `torque_base_Nm` (B), carried through the payload to the
/// flange (a hand's push loads the arm as the weight does), through joint_torques at the link
/// angles.
JointVector wrench_load(const JointVector& link_q_rad, const Eigen::Matrix3d& R_base_sensor,
                        const Eigen::Vector3d& p_flange_sensor_m,
                        const Eigen::Vector3d& force_base_N, const Eigen::Vector3d& point_sensor_m,
                        const Eigen::Vector3d& torque_base_Nm);

class ElasticArm {
 public:
  explicit ElasticArm(const ElasticityConfig& config);
  /// Static equilibrium under the load torques `tau` at time t_s (δ = τ/k, δ̇ = 0).
  void settle(double t_s, const JointVector& tau);
  /// Integrates from the last time to t_s under the motor path `motor` (its accelerations at each
  /// sub-step) and the load torques `tau` (the newest known, continued along their slope since the
  /// previous call's); returns the link state at t_s:
  /// q + δ, q̇ + δ̇, q̈ + δ̈.
  JointState advance(double t_s, const PtpTrajectory& motor, const JointVector& tau);
  /// One step of `dt` for a motor state given from outside (the emulator's servo): the motor's
  /// acceleration and the load held over the step (sub-divided to substep_s); returns the link
  /// state at the step's end.
  JointState step(const JointState& motor, double dt, const JointVector& tau);
  const JointVector& deflection_rad() const { return delta_; }
  bool enabled() const { return config_.enabled; }

 private:
  void integrate(double dt, const JointVector& motor_qdd, const JointVector& load);
  JointState link_of(JointState motor) const;
  ElasticityConfig config_;
  double t_s_ = 0.0;
  JointVector delta_{};
  JointVector delta_dot_{};
  JointVector delta_ddot_{};
  JointVector tau_last_{};  ///< the load of the previous call
};

}  // namespace zerog::sim
