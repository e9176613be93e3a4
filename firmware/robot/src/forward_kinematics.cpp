#include "zerog/robot/forward_kinematics.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>

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

// The chain from B to the flange F. With `axes`, each DH row's joint axis (unit, B) and a point
// on it: standard DH turns about frame i−1's z through its origin, modified DH about the z after
// Rx(α) Tx(a).
Pose chain(const RobotModel& model, std::span<const double> q_rad,
           std::array<Eigen::Vector3d, kMaxJoints>* axis = nullptr,
           std::array<Eigen::Vector3d, kMaxJoints>* origin = nullptr) {
  Pose pose;  // frame reached so far, in B
  for (int i = 0; i < model.joint_count; ++i) {
    const DhJoint& j = model.joints[i];
    const double theta =
        j.sign * q_rad[static_cast<std::size_t>(model.input_index[i])] + j.theta_offset_rad;
    if (model.convention == DhConvention::dh) {
      // Rz(θ) Tz(d) Tx(a) Rx(α): origin moves by Rz(θ) (a, 0, d).
      if (axis != nullptr) {
        (*axis)[i] = pose.R.col(2);
        (*origin)[i] = pose.p_m;
      }
      const Eigen::Matrix3d Rz = rot_z(theta);
      pose.p_m += pose.R * (Rz * Eigen::Vector3d(j.a_m, 0.0, j.d_m));
      pose.R = pose.R * Rz * rot_x(j.alpha_rad);
    } else {
      // Rx(α_{i−1}) Tx(a_{i−1}) Rz(θ) Tz(d): origin moves by (a, 0, 0) + Rx(α) (0, 0, d).
      const Eigen::Matrix3d Rx = rot_x(j.alpha_rad);
      if (axis != nullptr) {
        (*axis)[i] = pose.R * Rx.col(2);
        (*origin)[i] = pose.p_m + pose.R * Eigen::Vector3d(j.a_m, 0.0, 0.0);
      }
      pose.p_m +=
          pose.R * (Eigen::Vector3d(j.a_m, 0.0, 0.0) + Rx * Eigen::Vector3d(0.0, 0.0, j.d_m));
      pose.R = pose.R * Rx * rot_z(theta);
    }
  }
  pose.p_m += pose.R * model.last_flange.p_m;
  pose.R = pose.R * model.last_flange.R;
  return pose;
}

// F → S: the rig's flange_sensor.
Pose to_sensor(const RobotModel& model, Pose pose) {
  pose.p_m += pose.R * model.flange_sensor.p_m;
  pose.R = pose.R * model.flange_sensor.R;
  return pose;
}

}  // namespace

Pose flange_pose(const RobotModel& model, std::span<const double> q_rad) {
  return chain(model, q_rad);
}

Pose sensor_pose(const RobotModel& model, std::span<const double> q_rad) {
  return to_sensor(model, chain(model, q_rad));
}

void sensor_jacobian(const RobotModel& model, std::span<const double> q_rad,
                     Eigen::Matrix<double, 6, kMaxJoints>& jacobian) {
  std::array<Eigen::Vector3d, kMaxJoints> axis, origin;
  const Pose sensor = to_sensor(model, chain(model, q_rad, &axis, &origin));
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

}  // namespace zerog::robot
