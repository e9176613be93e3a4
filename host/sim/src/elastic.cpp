#include "zerog/sim/elastic.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "zerog/model/effects.hpp"
#include "zerog/robot/forward_kinematics.hpp"

namespace zerog::sim {

ElasticityConfig kr210_elasticity() {
  // The robot file's elasticity (calib/robots/kr210_r2700.robot.toml; proto/sim_robot.md gives
  // the sources: stiffness of the KUKA KR240-2 from Dumas et al., modes and damping assumed).
  ElasticityConfig c;
  c.enabled = true;
  for (std::size_t i = 0; i < c.joints.size(); ++i) c.joints[i] = kr210().elasticity[i];
  return c;
}

JointVector joint_torques(const JointVector& q_rad, const Eigen::Vector3d& force_base_N,
                          const Eigen::Vector3d& moment_flange_base_Nm) {
  JointVector tau{};
  robot::joint_torques(kr210(), q_rad, force_base_N, moment_flange_base_Nm, tau);
  return tau;
}

ElasticArm::ElasticArm(const ElasticityConfig& config) : config_(config) {}

void ElasticArm::settle(double t_s, const JointVector& tau) {
  t_s_ = t_s;
  for (std::size_t i = 0; i < 6; ++i) {
    const JointElasticity& j = config_.joints[i];
    delta_[i] = j.stiffness_Nm_per_rad > 0.0 ? tau[i] / j.stiffness_Nm_per_rad : 0.0;
    delta_dot_[i] = 0.0;
    delta_ddot_[i] = 0.0;
  }
  tau_last_ = tau;
}

void ElasticArm::integrate(double dt, const JointVector& motor_qdd, const JointVector& load) {
  for (std::size_t i = 0; i < 6; ++i) {
    const JointElasticity& j = config_.joints[i];
    if (j.rigid()) continue;
    const double acc = robot::deflection_accel(j, delta_[i], delta_dot_[i], motor_qdd[i], load[i]);
    delta_dot_[i] += dt * acc;  // semi-implicit Euler: velocity first
    delta_[i] += dt * delta_dot_[i];
    delta_ddot_[i] = acc;
  }
}

JointState ElasticArm::link_of(JointState motor) const {
  for (std::size_t i = 0; i < 6; ++i) {
    motor.q_rad[i] += delta_[i];
    motor.qd_radps[i] += delta_dot_[i];
    motor.qdd_radps2[i] += delta_ddot_[i];
  }
  return motor;
}

JointState ElasticArm::advance(double t_s, const PtpTrajectory& motor, const JointVector& tau) {
  const double span = t_s - t_s_;
  const int steps = span > 0.0 ? static_cast<int>(std::ceil(span / config_.substep_s - 1e-9)) : 0;
  const double dt = steps > 0 ? span / steps : 0.0;
  for (int s = 1; s <= steps; ++s) {
    // The load continues its last slope over the interval: a load held constant would step at
    // every row and ring the wrist's modes at the row rate.
    const double along = static_cast<double>(s) / steps;
    JointVector load{};
    for (std::size_t i = 0; i < 6; ++i) load[i] = tau[i] + along * (tau[i] - tau_last_[i]);
    integrate(dt, motor.at(t_s_ + dt * s).qdd_radps2, load);
  }
  t_s_ = t_s;
  tau_last_ = tau;
  return link_of(motor.at(t_s));
}

JointState ElasticArm::step(const JointState& motor, double dt, const JointVector& tau) {
  const int steps = std::max(1, static_cast<int>(std::ceil(dt / config_.substep_s - 1e-9)));
  for (int s = 0; s < steps; ++s) integrate(dt / steps, motor.qdd_radps2, tau);
  t_s_ += dt;
  tau_last_ = tau;
  return link_of(motor);
}

JointVector weight_load(const JointVector& link_q_rad, const Eigen::Matrix3d& R_base_sensor,
                        const Eigen::Vector3d& p_flange_sensor_m,
                        const Eigen::Vector3d& com_sensor_m, double mass_kg) {
  const Eigen::Vector3d force(0.0, 0.0, -model::kStandardGravity * mass_kg);
  return wrench_load(link_q_rad, R_base_sensor, p_flange_sensor_m, force, com_sensor_m,
                     Eigen::Vector3d::Zero());
}

JointVector wrench_load(const JointVector& link_q_rad, const Eigen::Matrix3d& R_base_sensor,
                        const Eigen::Vector3d& p_flange_sensor_m,
                        const Eigen::Vector3d& force_base_N, const Eigen::Vector3d& point_sensor_m,
                        const Eigen::Vector3d& torque_base_Nm) {
  const robot::Pose f = robot::flange_pose(kr210(), link_q_rad);
  const Eigen::Vector3d lever = f.R * p_flange_sensor_m + R_base_sensor * point_sensor_m;
  return joint_torques(link_q_rad, force_base_N, lever.cross(force_base_N) + torque_base_Nm);
}

}  // namespace zerog::sim
