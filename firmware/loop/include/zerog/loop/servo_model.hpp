#pragma once
// The robot's position servo as the motion estimator models it ([filter] servo_hz; proto/loop.md,
// "Motion estimator", the servo model): the joint increments zerog-rt commanded, from the
// controller's next tick, interpolated over that cycle, through a critically damped second
// order (robot/servo.hpp, the emulator's formula). Its accelerations drive the elastic arm's
// modes, where the encoders' 1e-4° make the measured joints' useless above 2 Hz. It is trusted
// only while the measured joints follow it.
// Real-time safe after configure(): no allocation, no exceptions.
#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <span>

#include "zerog/robot/robot_model.hpp"
#include "zerog/samples/robot_sample.hpp"

namespace zerog::loop {

/// The joint increment a correction commands from the joints `from_rad`: AKorr as it is; RKorr
/// (B axes: the sensor frame's origin and orientation) by `newton_steps` damped least-squares
/// steps (A2 ∥ A3 kept apart) towards the pose the correction makes of `from_rad`'s, as a
/// controller's inverse kinematics takes it (1: the plain Jacobian step, first order; 2 removes
/// its second-order error). Kind::none: zeros. The servo model's input
/// (MotionEstimator::note_command) and `zerog servo`'s (host/ident, servo_fit.hpp): one formula.
/// Real-time safe.
void commanded_increment(const robot::RobotModel& robot, const samples::RobotCorrection& sent,
                         std::span<const double> from_rad,
                         Eigen::Matrix<double, robot::kMaxJoints, 1>& dq,
                         int newton_steps = 1) noexcept;

class ServoModel {
 public:
  /// `servo_hz` ≤ 0: off (accel_at gives nothing). Forgets the past.
  void configure(double servo_hz) noexcept;
  bool on() const { return omega_radps_ > 0.0; }
  void reset() noexcept;
  /// The model's angle of `joint` after the last advance, relative to where it started (only
  /// differences matter): what `zerog servo` compares with the measured joints.
  double angle(int joint) const { return q_[static_cast<std::size_t>(joint)]; }

  /// The increments `dq_rad` (recorded joints, the first `joints`) commanded in reply to the row
  /// of time `t_row_s`: the model advances over the next cycle (`cycle_s`) with the set point
  /// ramping by them, and keeps its angle and acceleration under that row's time.
  void advance(std::span<const double> dq_rad, int joints, double t_row_s, double cycle_s) noexcept;

  /// The model's acceleration at a row (`qdd`, zero when it has none or is not trusted), looked
  /// up under the time of the row whose reply moved the joints into it (`t_key_s`: a
  /// correction answered at row k moves them from row k + 1 to row k + 2). `joints_rad`: the
  /// row's measured joints, against the model's step since the last row looked up; `dt_s`: the
  /// time since. Returns whether the robot followed the model over that step.
  bool accel_at(double t_key_s, std::span<const double> joints_rad, int joints, double dt_s,
                std::array<double, robot::kMaxJoints>& qdd) noexcept;

 private:
  // The follow check: a step that disagrees by more than kTolerance of the model's step plus
  // kSlack_rad (about ten of the encoders' 1e-4° steps: with 4e-6 the elastic spin tripped it
  // three times in 15 s, A5's step quantised to 4 steps against a modelled 0.5) turns the
  // model off for kDistrust_s: a robot that holds still while zerog-rt commands (a controller
  // that ignores the corrections, a stop) would otherwise ring modes nobody rang.
  static constexpr double kTolerance = 0.2;
  static constexpr double kSlack_rad = 2e-5;
  static constexpr double kDistrust_s = 1.0;
  static constexpr std::size_t kRows = 8;
  struct Row {
    double t_key_s = -1.0;
    std::array<double, robot::kMaxJoints> q{}, qdd{};
  };

  double omega_radps_ = 0.0;
  // The state per recorded joint: set point, angle, rate (only differences matter).
  std::array<double, robot::kMaxJoints> s_{}, q_{}, qd_{};
  std::array<Row, kRows> rows_{};
  std::size_t next_ = 0;
  bool have_last_ = false;
  std::array<double, robot::kMaxJoints> q_last_{}, joints_last_{};
  double distrust_s_ = 0.0;
};

}  // namespace zerog::loop
