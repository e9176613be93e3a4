#include "zerog/robot/forward_kinematics.hpp"

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

}  // namespace

Pose flange_pose(const RobotModel& model, std::span<const double> q_rad) {
  Pose pose;  // frame reached so far, in B
  for (int i = 0; i < model.joint_count; ++i) {
    const DhJoint& j = model.joints[i];
    const double theta =
        j.sign * q_rad[static_cast<std::size_t>(model.input_index[i])] + j.theta_offset_rad;
    if (model.convention == DhConvention::dh) {
      // Rz(θ) Tz(d) Tx(a) Rx(α): origin moves by Rz(θ) (a, 0, d).
      const Eigen::Matrix3d Rz = rot_z(theta);
      pose.p_m += pose.R * (Rz * Eigen::Vector3d(j.a_m, 0.0, j.d_m));
      pose.R = pose.R * Rz * rot_x(j.alpha_rad);
    } else {
      // Rx(α_{i−1}) Tx(a_{i−1}) Rz(θ) Tz(d): origin moves by (a, 0, 0) + Rx(α) (0, 0, d).
      const Eigen::Matrix3d Rx = rot_x(j.alpha_rad);
      pose.p_m +=
          pose.R * (Eigen::Vector3d(j.a_m, 0.0, 0.0) + Rx * Eigen::Vector3d(0.0, 0.0, j.d_m));
      pose.R = pose.R * Rx * rot_z(theta);
    }
  }
  pose.p_m += pose.R * model.last_flange.p_m;
  pose.R = pose.R * model.last_flange.R;
  return pose;
}

Pose sensor_pose(const RobotModel& model, std::span<const double> q_rad) {
  Pose pose = flange_pose(model, q_rad);
  pose.p_m += pose.R * model.flange_sensor.p_m;
  pose.R = pose.R * model.flange_sensor.R;
  return pose;
}

}  // namespace zerog::robot
