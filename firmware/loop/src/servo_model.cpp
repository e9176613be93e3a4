#include "zerog/loop/servo_model.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "zerog/robot/servo.hpp"

namespace zerog::loop {

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
