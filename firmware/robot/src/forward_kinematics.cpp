#include "zerog/robot/forward_kinematics.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <utility>

namespace zerog::robot {
namespace {

Eigen::Matrix3d rot_z(double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  Eigen::Matrix3d R;
  R << c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0;
  return R;
}

Eigen::Matrix3d rot_x(double angle) {
  const double c = std::cos(angle), s = std::sin(angle);
  Eigen::Matrix3d R;
  R << 1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c;
  return R;
}

// One standard DH transform T = Rz(θ) Tz(d) Tx(a) Rx(α) (Siciliano et al., Robotics, eq. 2.52),
// split into its rotation and the offset of its origin: R = Rz(θ) Rx(α), p = Rz(θ) (a, 0, d).
void dh_transform(const DhJoint& j, double theta, Eigen::Matrix3d& R, Eigen::Vector3d& p) {
  const double ct = std::cos(theta), st = std::sin(theta);
  const double ca = std::cos(j.alpha_rad), sa = std::sin(j.alpha_rad);
  R << ct, -st * ca, st * sa, st, ct * ca, -ct * sa, 0.0, sa, ca;
  p << j.a_m * ct, j.a_m * st, j.d_m;
}

double theta_of(const RobotModel& model, int i, std::span<const double> q) {
  const DhJoint& j = model.joints[static_cast<std::size_t>(i)];
  return j.sign * q[static_cast<std::size_t>(model.input_index[i])] + j.theta_offset_rad;
}

// What the walk along the chain collects besides the pose: the joints' rates and accelerations
// for the flange's motion (empty spans: the pose only), and each DH row's joint axis (unit, B)
// and a point on it for the Jacobian (null: not wanted).
struct WalkOptions {
  std::span<const double> qd_radps;
  std::span<const double> qdd_radps2;
  std::array<Eigen::Vector3d, kMaxJoints>* axis = nullptr;
  std::array<Eigen::Vector3d, kMaxJoints>* origin = nullptr;
};

// The frame reached so far turns about `z` (unit, B) at θ̇, θ̈ of DH row i.
void turn(const RobotModel& model, int i, const WalkOptions& o, const Eigen::Vector3d& z,
          FlangeMotion& m) {
  const std::size_t k = static_cast<std::size_t>(model.input_index[i]);
  const double sign = model.joints[static_cast<std::size_t>(i)].sign;
  const double theta_dot = sign * o.qd_radps[k];
  const double theta_ddot = sign * o.qdd_radps2[k];
  m.omega_dot_base_radps2 += theta_ddot * z + theta_dot * m.omega_base_radps.cross(z);
  m.omega_base_radps += theta_dot * z;
}

// The origin moves by `dp` (B axes), an offset rigid in the link that turns at m's ω, ω̇.
void shift(bool moving, const Eigen::Vector3d& dp, FlangeMotion& m) {
  if (moving) {
    m.a_flange_base_mps2 +=
        m.omega_dot_base_radps2.cross(dp) + m.omega_base_radps.cross(m.omega_base_radps.cross(dp));
    m.v_flange_base_mps += m.omega_base_radps.cross(dp);
  }
  m.p_base_flange_m += dp;
}

// The chain from B to the flange F: the pose always, the rest as `o` asks. The pose's arithmetic
// is the same whatever is asked, so that flange_motion's pose is flange_pose's to the last bit.
FlangeMotion walk(const RobotModel& model, std::span<const double> q_rad, const WalkOptions& o) {
  const bool moving = !o.qd_radps.empty();
  FlangeMotion m;  // frame reached so far, in B
  Eigen::Matrix3d R;
  Eigen::Vector3d p;
  for (int i = 0; i < model.joint_count; ++i) {
    const DhJoint& j = model.joints[static_cast<std::size_t>(i)];
    const double theta = theta_of(model, i, q_rad);
    if (model.convention == DhConvention::dh) {
      // Joint i turns about z_{i−1}, the z axis of the frame reached so far, through its origin;
      // the offset Rz(θ) (a, 0, d) then turns with link i.
      const Eigen::Vector3d z_prev = m.R_base_flange.col(2);
      if (o.axis != nullptr) {
        (*o.axis)[static_cast<std::size_t>(i)] = z_prev;
        (*o.origin)[static_cast<std::size_t>(i)] = m.p_base_flange_m;
      }
      if (moving) turn(model, i, o, z_prev, m);
      dh_transform(j, theta, R, p);
      shift(moving, m.R_base_flange * p, m);
      m.R_base_flange = m.R_base_flange * R;
    } else {
      // Rx(α_{i−1}) Tx(a_{i−1}) Rz(θ) Tz(d): the origin moves by (a, 0, 0) + Rx(α) (0, 0, d),
      // rigid in link i−1 (d lies along joint i's own axis), then joint i turns about the z
      // after Rx(α) through the origin moved by a.
      const Eigen::Matrix3d Rx = rot_x(j.alpha_rad);
      const Eigen::Vector3d z = m.R_base_flange * Rx.col(2);
      if (o.axis != nullptr) {
        (*o.axis)[static_cast<std::size_t>(i)] = z;
        (*o.origin)[static_cast<std::size_t>(i)] =
            m.p_base_flange_m + m.R_base_flange * Eigen::Vector3d(j.a_m, 0.0, 0.0);
      }
      shift(moving,
            m.R_base_flange *
                (Eigen::Vector3d(j.a_m, 0.0, 0.0) + Rx * Eigen::Vector3d(0.0, 0.0, j.d_m)),
            m);
      if (moving) turn(model, i, o, z, m);
      m.R_base_flange = m.R_base_flange * Rx * rot_z(theta);
    }
  }
  // A table that ends at the flange (the usual case) adds nothing; skipping the identity also
  // leaves the signs of zero entries as the chain made them.
  const FrameTransform& last = model.last_flange;
  if (!last.R.isIdentity(0.0) || !last.p_m.isZero(0.0)) {
    shift(moving, m.R_base_flange * last.p_m, m);
    m.R_base_flange = m.R_base_flange * last.R;
  }
  return m;
}

Pose pose_of(const FlangeMotion& m) { return {m.R_base_flange, m.p_base_flange_m}; }

// F → S: the rig's flange_sensor.
Pose to_sensor(const RobotModel& model, Pose pose) {
  pose.p_m += pose.R * model.flange_sensor.p_m;
  pose.R = pose.R * model.flange_sensor.R;
  return pose;
}

// Angle wrapped to (−π, π].
double wrap_pi(double x) {
  x = std::remainder(x, 2.0 * std::numbers::pi);
  return x <= -std::numbers::pi ? x + 2.0 * std::numbers::pi : x;
}

}  // namespace

Eigen::Vector3d FlangeMotion::velocity_of(const Eigen::Vector3d& lever_base_m) const {
  return v_flange_base_mps + omega_base_radps.cross(lever_base_m);
}

Eigen::Vector3d FlangeMotion::acceleration_of(const Eigen::Vector3d& lever_base_m) const {
  return a_flange_base_mps2 + omega_dot_base_radps2.cross(lever_base_m) +
         omega_base_radps.cross(omega_base_radps.cross(lever_base_m));
}

Pose flange_pose(const RobotModel& model, std::span<const double> q_rad) {
  return pose_of(walk(model, q_rad, {}));
}

Pose sensor_pose(const RobotModel& model, std::span<const double> q_rad) {
  return to_sensor(model, flange_pose(model, q_rad));
}

FlangeMotion flange_motion(const RobotModel& model, std::span<const double> q_rad,
                           std::span<const double> qd_radps, std::span<const double> qdd_radps2) {
  return walk(model, q_rad, {qd_radps, qdd_radps2});
}

void sensor_jacobian(const RobotModel& model, std::span<const double> q_rad,
                     Eigen::Matrix<double, 6, kMaxJoints>& jacobian) {
  std::array<Eigen::Vector3d, kMaxJoints> axis, origin;
  const Pose sensor = to_sensor(model, pose_of(walk(model, q_rad, {{}, {}, &axis, &origin})));
  jacobian.setZero();
  for (int i = 0; i < model.joint_count; ++i) {
    const int k = model.input_index[i];
    const double sign = model.joints[i].sign;
    jacobian.col(k).head<3>() = sign * axis[i].cross(sensor.p_m - origin[i]);
    jacobian.col(k).tail<3>() = sign * axis[i];
  }
}
void joint_torques(const RobotModel& model, std::span<const double> q_rad,
                   const Eigen::Vector3d& force_base_N,
                   const Eigen::Vector3d& moment_flange_base_Nm, std::span<double> tau_Nm) {
  constexpr double h = 1e-6;
  const std::size_t n = static_cast<std::size_t>(model.joint_count);
  std::array<double, kMaxJoints> q{};
  std::copy_n(q_rad.begin(), n, q.begin());
  const std::span<const double> joints(q.data(), n);
  const Eigen::Matrix3d R_t = flange_pose(model, joints).R.transpose();
  for (std::size_t k = 0; k < n; ++k) {
    const double q_k = q[k];
    q[k] = q_k + h;
    const Pose a = flange_pose(model, joints);
    q[k] = q_k - h;
    const Pose b = flange_pose(model, joints);
    q[k] = q_k;
    // Flange origin velocity and angular velocity per unit q̇_k (B axes).
    const Eigen::Vector3d v = (a.p_m - b.p_m) / (2.0 * h);
    const Eigen::Matrix3d W = (a.R - b.R) / (2.0 * h) * R_t;
    const Eigen::Vector3d w(W(2, 1), W(0, 2), W(1, 0));  // skew-symmetric part: Ṙ Rᵀ = [ω]×
    tau_Nm[k] = v.dot(force_base_N) + w.dot(moment_flange_base_Nm);
  }
}

std::array<std::array<double, 6>, 2> wrist_inverse_kinematics(
    const RobotModel& model, const std::array<double, 6>& q_arm_rad,
    const Eigen::Matrix3d& R_base_flange) {
  const auto& dh = model.joints;
  Eigen::Matrix3d R_base_3 = Eigen::Matrix3d::Identity(), R;
  Eigen::Vector3d p;
  for (int i = 0; i < 3; ++i) {
    dh_transform(dh[i], dh[i].sign * q_arm_rad[i] + dh[i].theta_offset_rad, R, p);
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
  auto to_q = [&](int i, double theta) {
    return wrap_pi(dh[i].sign * (theta - dh[i].theta_offset_rad));
  };
  std::array<std::array<double, 6>, 2> out;
  for (int k = 0; k < 2; ++k) {
    std::array<double, 6> q = q_arm_rad;
    double t4 = 0.0, t5 = 0.0;
    if (s5_abs < 1e-12) {
      t4 = dh[3].sign * q_arm_rad[3] + dh[3].theta_offset_rad;  // singular: keep A4
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

}  // namespace zerog::robot
