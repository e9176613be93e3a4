#include "zerog/robot/derive_kinematics.hpp"

#include <Eigen/Geometry>
#include <cmath>

namespace zerog::robot {
namespace {

// Log map of SO(3): the rotation vector of R (angle ≤ π), through the quaternion for accuracy
// at small angles.
Eigen::Vector3d log_so3(const Eigen::Matrix3d& R) {
  Eigen::Quaterniond q(R);
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();
  const double n = q.vec().norm();
  if (n < 1e-12) return 2.0 * q.vec();
  return q.vec() * (2.0 * std::atan2(n, q.w()) / n);
}

DeriveStatus check_inputs(std::span<const double> times_s, std::size_t n, const SgSettings& sg,
                          std::size_t out_size) {
  if (!valid(sg)) return {DeriveError::settings, 0};
  if (times_s.size() != n || out_size != n) return {DeriveError::sizes, 0};
  if (n < static_cast<std::size_t>(2 * sg.half_width + 1)) return {DeriveError::too_short, 0};
  for (std::size_t i = 0; i < n; ++i)
    if (!std::isfinite(times_s[i]) || (i > 0 && !(times_s[i] > times_s[i - 1])))
      return {DeriveError::time_order, i};
  return {};
}

// The differentiator on any pose source (`pose_at(k)`), writing everything but the pose.
template <typename PoseAt>
void differentiate(std::span<const double> times_s, PoseAt pose_at,
                   const DifferentiatorSettings& settings, std::span<SensorKinematics> out) {
  const std::size_t n = times_s.size();
  const std::size_t m = static_cast<std::size_t>(settings.sg.half_width);
  for (std::size_t c = 0; c < n; ++c) {
    // The window c−M..c+M, shifted inwards at the ends.
    const std::size_t first = sg_window_first(c, n, m);
    const std::size_t last = first + 2 * m;
    const double t_c = times_s[c];
    const double scale = 0.5 * (times_s[last] - times_s[first]);
    LocalPolyFit fit(settings.sg.order);
    for (std::size_t k = first; k <= last; ++k) fit.add(times_s[k] - t_c, scale);
    SensorKinematics& o = out[c];
    o.centred = c >= m && c + m < n;
    if (!fit.solve()) continue;  // cannot happen for strictly increasing times
    const Pose& centre = pose_at(c);
    Eigen::Vector3d rate = Eigen::Vector3d::Zero(), rate2 = Eigen::Vector3d::Zero(),
                    accel = Eigen::Vector3d::Zero();
    for (std::size_t k = first; k <= last; ++k) {
      const Pose& pk = pose_at(k);
      const double tau = times_s[k] - t_c;
      const double w1 = fit.weight(tau, 1), w2 = fit.weight(tau, 2);
      const Eigen::Vector3d r =
          k == c ? Eigen::Vector3d::Zero() : log_so3(centre.R.transpose() * pk.R);  // S axes
      rate += w1 * r;
      rate2 += w2 * r;
      accel += w2 * pk.p_m;
    }
    o.omega_sensor_radps = rate;
    o.omega_dot_sensor_radps2 = rate2;
    o.accel_base_mps2 = accel;
    o.specific_force_sensor_mps2 = centre.R.transpose() * (accel - settings.gravity_base_mps2);
  }
}

}  // namespace

DeriveStatus derive_kinematics(std::span<const double> times_s, std::span<const Pose> poses,
                               const DifferentiatorSettings& settings,
                               std::span<SensorKinematics> out) {
  const DeriveStatus status = check_inputs(times_s, poses.size(), settings.sg, out.size());
  if (!status.ok()) return status;
  for (std::size_t i = 0; i < poses.size(); ++i) out[i].pose_base_sensor = poses[i];
  differentiate(
      times_s, [&](std::size_t k) -> const Pose& { return poses[k]; }, settings, out);
  return {};
}

DeriveStatus derive_kinematics(const RobotModel& model, std::span<const double> times_s,
                               std::span<const double> joints_rad, std::size_t joints_per_row,
                               const DifferentiatorSettings& settings,
                               std::span<SensorKinematics> out) {
  if (model.joint_count < 1 || model.joint_count > kMaxJoints ||
      joints_per_row < static_cast<std::size_t>(model.joint_count))
    return {DeriveError::sizes, 0};
  const std::size_t rows = joints_rad.size() / joints_per_row;
  if (joints_rad.size() != rows * joints_per_row) return {DeriveError::sizes, 0};
  const DeriveStatus status = check_inputs(times_s, rows, settings.sg, out.size());
  if (!status.ok()) return status;
  if (!validate(model).ok()) return {DeriveError::robot_model, 0};
  for (std::size_t i = 0; i < rows; ++i)
    out[i].pose_base_sensor =
        sensor_pose(model, joints_rad.subspan(i * joints_per_row, joints_per_row));
  // The poses live in `out`; the differentiator reads them and writes only the other fields.
  differentiate(
      times_s, [&](std::size_t k) -> const Pose& { return out[k].pose_base_sensor; }, settings,
      out);
  return {};
}

// ------------------------------------------------------------------------------------------

const SourceChoice& SourceChoices::operator[](KinematicSignal s) const {
  switch (s) {
    case KinematicSignal::omega:
      return omega;
    case KinematicSignal::omega_dot:
      return omega_dot;
    case KinematicSignal::specific_force:
      break;
  }
  return specific_force;
}

const char* to_string(KinematicSource source) {
  switch (source) {
    case KinematicSource::imu:
      return "imu";
    case KinematicSource::robot:
      return "robot";
    case KinematicSource::none:
      break;
  }
  return "none";
}

const char* to_string(KinematicSignal signal) {
  switch (signal) {
    case KinematicSignal::omega:
      return "omega";
    case KinematicSignal::omega_dot:
      return "omega_dot";
    case KinematicSignal::specific_force:
      break;
  }
  return "specific_force";
}

SourceChoices choose_sources(KinematicsMode mode, const KinematicsAvailable& a) {
  const SourceChoice none_imu_gyro{KinematicSource::none,
                                   "kinematics = \"imu\" but the log has no gyro"};
  const SourceChoice none_imu_acc{KinematicSource::none,
                                  "kinematics = \"imu\" but the log has no accelerometer"};
  const SourceChoice none_robot{KinematicSource::none,
                                "kinematics = \"robot\" but the log has no joints (with a robot "
                                "model) and no pose"};
  SourceChoices c;
  switch (mode) {
    case KinematicsMode::imu:
      c.omega = a.gyro ? SourceChoice{KinematicSource::imu, "kinematics = \"imu\": the gyro"}
                       : none_imu_gyro;
      c.omega_dot =
          a.gyro ? SourceChoice{KinematicSource::imu,
                                "kinematics = \"imu\": the gyro, differenced by host/ident's "
                                "5-point central difference"}
                 : none_imu_gyro;
      c.specific_force = a.accelerometer ? SourceChoice{KinematicSource::imu,
                                                        "kinematics = \"imu\": the accelerometer"}
                                         : none_imu_acc;
      return c;
    case KinematicsMode::robot: {
      const SourceChoice robot{KinematicSource::robot,
                               "kinematics = \"robot\": forward kinematics and SG differentiator"};
      c.omega = c.omega_dot = c.specific_force = a.robot ? robot : none_robot;
      return c;
    }
    case KinematicsMode::automatic:
      break;
  }
  const SourceChoice nothing{KinematicSource::none, "neither an IMU signal nor the robot"};
  c.omega = a.gyro    ? SourceChoice{KinematicSource::imu,
                                  "auto: the gyro measures the motion itself, free of the robot's "
                                     "model errors"}
            : a.robot ? SourceChoice{KinematicSource::robot, "auto: no gyro, so the robot"}
                      : nothing;
  c.omega_dot = a.gyro    ? SourceChoice{KinematicSource::imu,
                                      "auto: the gyro differenced by Savitzky-Golay at import "
                                         "(measured closer to the truth than the robot's second "
                                         "derivative and than a 5-point difference)"}
                : a.robot ? SourceChoice{KinematicSource::robot, "auto: no gyro, so the robot"}
                          : nothing;
  c.specific_force =
      a.accelerometer ? SourceChoice{KinematicSource::imu,
                                     "auto: the accelerometer senses the true vertical and the "
                                     "arm's deflection"}
      : a.robot       ? SourceChoice{KinematicSource::robot, "auto: no accelerometer, so the robot"}
                      : nothing;
  return c;
}

}  // namespace zerog::robot
