#include "zerog/sim/kinematics.hpp"

#include <cmath>
#include <numbers>

namespace zerog::sim {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// One DH transform T_i = Rz(θ) Tz(d) Tx(a) Rx(α), split into rotation and translation.
void dh_transform(const DhLink& link, double theta, Eigen::Matrix3d& R, Eigen::Vector3d& p) {
  const double ct = std::cos(theta), st = std::sin(theta);
  const double ca = std::cos(link.alpha_rad), sa = std::sin(link.alpha_rad);
  R << ct, -st * ca, st * sa, st, ct * ca, -ct * sa, 0.0, sa, ca;
  p << link.a_m * ct, link.a_m * st, link.d_m;
}

}  // namespace

JointLimits kr210_table4_limits() {
  return {{-150 * kDeg, -138 * kDeg, -10 * kDeg, -180 * kDeg, -120 * kDeg, -180 * kDeg},
          {150 * kDeg, -70 * kDeg, 130 * kDeg, 180 * kDeg, 120 * kDeg, 180 * kDeg}};
}

JointVector kr210_home() { return {0.0, -90 * kDeg, 90 * kDeg, 0.0, 0.0, 0.0}; }

Eigen::Vector3d FlangeMotion::velocity_of(const Eigen::Vector3d& lever_base_m) const {
  return v_flange_base_mps + omega_base_radps.cross(lever_base_m);
}

Eigen::Vector3d FlangeMotion::acceleration_of(const Eigen::Vector3d& lever_base_m) const {
  return a_flange_base_mps2 + omega_dot_base_radps2.cross(lever_base_m) +
         omega_base_radps.cross(omega_base_radps.cross(lever_base_m));
}

FlangePose forward_kinematics(const JointVector& q_rad, const std::array<DhLink, 6>& dh) {
  FlangePose pose;
  Eigen::Matrix3d R;
  Eigen::Vector3d p;
  for (int i = 0; i < 6; ++i) {
    dh_transform(dh[i], dh[i].sign * q_rad[i] + dh[i].offset_rad, R, p);
    pose.p_base_flange_m += pose.R_base_flange * p;
    pose.R_base_flange = pose.R_base_flange * R;
  }
  return pose;
}

FlangeMotion flange_motion(const JointVector& q_rad, const JointVector& qd_radps,
                           const JointVector& qdd_radps2, const std::array<DhLink, 6>& dh) {
  FlangeMotion m;
  Eigen::Matrix3d R;
  Eigen::Vector3d p;
  for (int i = 0; i < 6; ++i) {
    // Joint i turns about z_{i−1}, the z axis of the frame reached so far.
    const Eigen::Vector3d z_prev = m.R_base_flange.col(2);
    const double theta_dot = dh[i].sign * qd_radps[i];
    const double theta_ddot = dh[i].sign * qdd_radps2[i];
    m.omega_dot_base_radps2 += theta_ddot * z_prev + theta_dot * m.omega_base_radps.cross(z_prev);
    m.omega_base_radps += theta_dot * z_prev;

    dh_transform(dh[i], dh[i].sign * q_rad[i] + dh[i].offset_rad, R, p);
    // Origin of frame i relative to frame i−1, in base axes: Δp = R_{0,i−1} (Rz(θ) [a cθ, a sθ,
    // d]).
    const Eigen::Vector3d dp = m.R_base_flange * p;
    m.a_flange_base_mps2 +=
        m.omega_dot_base_radps2.cross(dp) + m.omega_base_radps.cross(m.omega_base_radps.cross(dp));
    m.v_flange_base_mps += m.omega_base_radps.cross(dp);
    m.p_base_flange_m += dp;
    m.R_base_flange = m.R_base_flange * R;
  }
  return m;
}

}  // namespace zerog::sim
