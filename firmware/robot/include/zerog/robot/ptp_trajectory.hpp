#pragma once
// Synchronized point-to-point (PTP) joint trajectory of a 6-axis arm through path points with
// dwells, with analytic joint angles, rates and accelerations at any time, and the KR 210 R2700's
// PTP limits. zerog-rt's collection mode drives the robot along it; the simulator (host/sim)
// and the emulator move their robot with the same trajectory. Construction allocates and may
// throw (start-up); at() and is_dwell() are real-time safe (no allocation, no exceptions).
#include <array>
#include <cstddef>
#include <vector>

namespace zerog::robot {

/// A1..A6 of a 6-axis arm: rad (or rad/s, rad/s²).
using JointVector6 = std::array<double, 6>;

/// Axis speeds of the KR 210 R2700 at 100 % (deg/s, A1..A6), as used for the 30 % default.
inline constexpr JointVector6 kKr210MaxSpeedDegps = {105.0, 94.0, 100.0, 136.0, 129.0, 206.0};

struct PtpLimits {
  JointVector6 max_speed_radps{};   ///< per axis, already scaled by the override
  JointVector6 max_accel_radps2{};  ///< per axis
  double min_accel_time_s = 0.2;    ///< shortest acceleration phase (bounds the jerk)
};

/// Limits for a speed override (fraction of the axis speeds above, e.g. 0.3). The accelerations
/// (1.2 rad/s² main axes, 2.5 wrist A4/A5, 3.5 A6 at 30 %, scaled linearly with the override)
/// give acceleration phases of 0.5–1 s, like a KUKA PTP at that override.
PtpLimits kr210_ptp_limits(double speed_fraction);

struct JointState {
  JointVector6 q_rad{};
  JointVector6 qd_radps{};
  JointVector6 qdd_radps2{};
};

/// Normalized move profile s(t) ∈ [0, 1] over [0, T]: acceleration phase of length Ta with
/// a(t) = A (1 − cos(2π t / Ta)) / 2 (continuous acceleration, bounded jerk), constant speed,
/// and a mirrored deceleration phase (T ≥ 2 Ta). All joints of a move share it (synchronized PTP).
struct MoveProfile {
  double duration_s = 0.0;
  double accel_time_s = 0.0;
  /// s, ṡ, s̈ at t (clamped to [0, T]).
  void evaluate(double t_s, double& s, double& sd, double& sdd) const;
};

/// Profile for a move by `delta_rad` under `limits`: the slowest joint sets the duration.
MoveProfile plan_move(const JointVector6& delta_rad, const PtpLimits& limits);

/// The whole run: dwell at point 0, move to point 1, dwell, …, dwell at the last point.
class PtpTrajectory {
 public:
  PtpTrajectory(std::vector<JointVector6> points_rad, const PtpLimits& limits, double dwell_s);

  double duration_s() const { return segment_start_s_.empty() ? 0.0 : total_s_; }
  std::size_t num_points() const { return points_.size(); }
  /// Joint state at time t (clamped to [0, duration]). Exact, from the analytic profile.
  JointState at(double t_s) const;
  /// True when no joint moves at time t (inside a dwell).
  bool is_dwell(double t_s) const;
  /// Start time of the move from point k to k + 1.
  double move_start_s(std::size_t k) const { return segment_start_s_[k]; }
  const MoveProfile& move(std::size_t k) const { return moves_[k]; }

 private:
  std::vector<JointVector6> points_;
  std::vector<MoveProfile> moves_;
  std::vector<double> segment_start_s_;  ///< start of move k (after the dwell at point k)
  double dwell_s_;
  double total_s_ = 0.0;
};

}  // namespace zerog::robot
