#include "zerog/loop/servo_model.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/Geometry>

#include "zerog/robot/forward_kinematics.hpp"
#include "zerog/robot/servo.hpp"

namespace zerog::loop {

void commanded_increment(const robot::RobotModel& robot, const samples::RobotCorrection& sent,
                         std::span<const double> from_rad,
                         Eigen::Matrix<double, robot::kMaxJoints, 1>& dq,
                         int newton_steps) noexcept {
  // The damping keeps A2 ∥ A3 (the KR 210's singular direction at full stretch) finite.
  constexpr double kDamping = 1e-6;
  dq.setZero();
  const int n = std::min(robot.joint_count, robot::kMaxJoints);
  if (sent.kind == samples::RobotCorrection::Kind::axes) {
    for (int j = 0; j < std::min(n, 6); ++j) dq[j] = sent.axes_rad[static_cast<std::size_t>(j)];
    return;
  }
  if (sent.kind != samples::RobotCorrection::Kind::cartesian) return;
  const Eigen::Matrix3d R_correction =
      Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(sent.R_correction.data());
  const Eigen::Vector3d t = Eigen::Map<const Eigen::Vector3d>(sent.translation_m.data());
  std::array<double, robot::kMaxJoints> q{};
  for (std::size_t j = 0; j < std::min(static_cast<std::size_t>(n), from_rad.size()); ++j)
    q[j] = from_rad[j];
  // The pose the correction makes (only needed beyond the first step).
  Eigen::Vector3d p_target = t;
  Eigen::Matrix3d R_target = R_correction;
  if (newton_steps > 1) {
    const robot::Pose from = robot::sensor_pose(robot, q);
    p_target += from.p_m;
    R_target = R_correction * from.R;
  }
  Eigen::Matrix<double, 6, robot::kMaxJoints> jac;
  for (int k = 0; k < newton_steps; ++k) {
    Eigen::Matrix<double, 6, 1> e;
    if (k == 0) {
      // The first step's error is the correction itself (no pose to compute).
      const Eigen::AngleAxisd turn{R_correction};
      e << t, turn.angle() * turn.axis();
    } else {
      const robot::Pose now = robot::sensor_pose(robot, q);
      const Eigen::AngleAxisd turn{Eigen::Matrix3d(R_target * now.R.transpose())};
      e << p_target - now.p_m, turn.angle() * turn.axis();
    }
    robot::sensor_jacobian(robot, q, jac);
    const Eigen::Matrix<double, 6, 6> A =
        jac * jac.transpose() + kDamping * Eigen::Matrix<double, 6, 6>::Identity();
    const Eigen::Matrix<double, robot::kMaxJoints, 1> step = jac.transpose() * A.ldlt().solve(e);
    dq += step;
    for (int j = 0; j < n; ++j) q[static_cast<std::size_t>(j)] += step[j];
  }
}

void ServoModel::configure(double servo_hz) noexcept {
  omega_radps_ = servo_hz > 0.0 ? 2.0 * std::numbers::pi * servo_hz : 0.0;
  reset();
}

void ServoModel::reset() noexcept {
  s_ = {};
  q_ = {};
  qd_ = {};
  rows_ = {};
  next_ = 0;
  have_last_ = false;
  distrust_s_ = 0.0;
}

void ServoModel::advance(std::span<const double> dq_rad, int joints, double t_row_s,
                         double cycle_s) noexcept {
  if (!on() || !(cycle_s > 0.0)) return;
  const double w = omega_radps_;
  const Eigen::Matrix2d phi = robot::servo_transition(w, cycle_s);
  Row& row = rows_[next_];
  next_ = (next_ + 1) % kRows;
  row.t_key_s = t_row_s;
  for (int j = 0; j < joints; ++j) {
    const std::size_t u = static_cast<std::size_t>(j);
    // The interpolator spreads the increment over the cycle: a ramp, stepped exactly.
    robot::servo_advance(w, cycle_s, dq_rad[u] / cycle_s, phi, s_[u], q_[u], qd_[u]);
    row.q[u] = q_[u];
    row.qdd[u] = robot::servo_accel(w, s_[u], q_[u], qd_[u]);
  }
}

bool ServoModel::accel_at(double t_key_s, std::span<const double> joints_rad, int joints,
                          double dt_s, std::array<double, robot::kMaxJoints>& qdd) noexcept {
  qdd = {};
  const Row* row = nullptr;
  for (const Row& r : rows_) {
    if (on() && r.t_key_s == t_key_s) row = &r;
  }
  bool followed = true;
  if (row != nullptr && have_last_) {
    for (int j = 0; j < joints; ++j) {
      const std::size_t u = static_cast<std::size_t>(j);
      const double model_step = row->q[u] - q_last_[u];
      const double measured_step = joints_rad[u] - joints_last_[u];
      if (std::abs(model_step - measured_step) > kTolerance * std::abs(model_step) + kSlack_rad)
        followed = false;
    }
  }
  have_last_ = row != nullptr;
  if (row != nullptr) {
    for (int j = 0; j < joints; ++j) {
      const std::size_t u = static_cast<std::size_t>(j);
      q_last_[u] = row->q[u];
      joints_last_[u] = joints_rad[u];
    }
  }
  distrust_s_ = followed ? std::max(0.0, distrust_s_ - dt_s) : kDistrust_s;
  if (row != nullptr && distrust_s_ == 0.0) qdd = row->qdd;
  return followed;
}

}  // namespace zerog::loop
