#include "zerog/sim/kinematics.hpp"

#include <cmath>
#include <numbers>
#include <utility>

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

// Angle wrapped to (−π, π].
double wrap_pi(double x) {
  x = std::remainder(x, 2.0 * std::numbers::pi);
  return x <= -std::numbers::pi ? x + 2.0 * std::numbers::pi : x;
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

std::array<JointVector, 2> wrist_inverse_kinematics(const JointVector& q_arm_rad,
                                                    const Eigen::Matrix3d& R_base_flange,
                                                    const std::array<DhLink, 6>& dh) {
  Eigen::Matrix3d R_base_3 = Eigen::Matrix3d::Identity(), R;
  Eigen::Vector3d p;
  for (int i = 0; i < 3; ++i) {
    dh_transform(dh[i], dh[i].sign * q_arm_rad[i] + dh[i].offset_rad, R, p);
    R_base_3 = R_base_3 * R;
  }
  const double ca6 = std::cos(dh[5].alpha_rad), sa6 = std::sin(dh[5].alpha_rad);
  Eigen::Matrix3d Rx6;
  Rx6 << 1.0, 0.0, 0.0, 0.0, ca6, -sa6, 0.0, sa6, ca6;
  // M = Rz(θ4) Ry(b) Rz(θ6) with b = −θ5: M02 = cθ4 sb, M12 = sθ4 sb, M22 = cb.
  const Eigen::Matrix3d M = R_base_3.transpose() * R_base_flange * Rx6.transpose();
  // |sin θ5| from the third column (accurate near θ5 = 0, where 1 − cos² is not).
  const double c5 = M(2, 2);
  const double s5_abs = std::hypot(M(0, 2), M(1, 2));
  auto to_q = [&](int i, double theta) { return wrap_pi(dh[i].sign * (theta - dh[i].offset_rad)); };
  std::array<JointVector, 2> out;
  for (int k = 0; k < 2; ++k) {
    JointVector q = q_arm_rad;
    double t4 = 0.0, t5 = 0.0;
    if (s5_abs < 1e-12) {
      t4 = dh[3].sign * q_arm_rad[3] + dh[3].offset_rad;  // singular: keep A4
      t5 = c5 > 0.0 ? 0.0 : std::numbers::pi;
    } else {
      const double s5 = k == 0 ? s5_abs : -s5_abs;  // both signs of θ5
      t5 = std::atan2(s5, c5);
      t4 = std::atan2(-M(1, 2) / s5, -M(0, 2) / s5);
    }
    // θ6 from what is left, Rz(θ6) = Ry(−θ5)ᵀ Rz(θ4)ᵀ M: stable near the singularity too.
    const double cb = std::cos(t5), sb = -std::sin(t5), c4 = std::cos(t4), s4 = std::sin(t4);
    Eigen::Matrix3d A;  // Rz(θ4) Ry(b)
    A << c4 * cb, -s4, c4 * sb, s4 * cb, c4, s4 * sb, -sb, 0.0, cb;
    const Eigen::Matrix3d N = A.transpose() * M;
    const double t6 = std::atan2(N(1, 0), N(0, 0));
    q[3] = to_q(3, t4);
    q[4] = to_q(4, t5);
    q[5] = to_q(5, t6);
    out[k] = q;
  }
  if (out[0][4] < out[1][4]) std::swap(out[0], out[1]);
  return out;
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
