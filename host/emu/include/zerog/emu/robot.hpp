#pragma once
// The robot controller's side of RSI, without sockets: a KR 210 R2700 whose commanded joints take
// RSI corrections (RKorr, AKorr) and whose actual joints follow them with servo lag
// (proto/emulator.md, proto/rsi.md "How the emulator applies corrections").
//
// Frames (proto/frames.md): B robot base; the TCP is the F/T sensor frame S, at
// RobotConfig::p_flange_tcp_m on the flange with the flange's axes. The arm is the simulator's
// (sim::kr210(), the robot file), moved by zerog::robot's kinematics (flange_pose,
// flange_motion). Emulator code: not real-time, but the per-step and
// per-cycle calls do not allocate.
#include <Eigen/Core>
#include <array>
#include <cstdint>

#include "zerog/proto/rsi.hpp"
#include "zerog/sim/robot.hpp"
#include "zerog/sim/trajectory.hpp"

namespace zerog::emu {

/// Axis ranges of the emulated controller, rad: the KR 210 R2700's A1 ±185°, A2 −140°..−5°,
/// A3 −120°..+168°, and wide wrist ranges A4 ±350°, A5 ±125°, A6 ±350°.
sim::JointLimits emulator_joint_limits();

/// Default start pose A1..A6 = 0, −90°, 90°, 0, 45°, 0 (rad): clear of the wrist singularity,
/// the sensor about 1.6 m above the base, the flange tilted 45° down.
sim::JointVector default_start_joints();

struct RobotConfig {
  double physics_rate_hz = 2000.0;  ///< servo integration rate
  double servo_bandwidth_hz = 8.0;  ///< critically damped, ω = 2π · bandwidth
  sim::JointVector start_joints_rad = default_start_joints();
  Eigen::Vector3d p_flange_tcp_m{0.0, 0.0, 0.06};  ///< TCP (= sensor origin S) in the flange
  /// Damped least squares: below this smallest singular value of the TCP Jacobian the damping
  /// rises from 0 to max_damping (and the cycle counts as near-singular).
  double singular_threshold = 0.02;
  double max_damping = 0.02;
  int ik_iterations = 4;  ///< Newton steps per correction (1 = the plain linear step)
  /// The controller's interpolator: each correction is spread evenly over this time (one RSI
  /// cycle) instead of stepping the servo's set point at once. 0: step at once. A stepped set
  /// point makes the servo jerk the payload at the cycle rate (ω² Δq: 5 m/s² for 2 mm per
  /// cycle at 8 Hz), which no KUKA controller does.
  double interpolation_s = 0.0;
};

/// A TCP pose: S in B.
struct TcpPose {
  Eigen::Matrix3d R_base_tcp = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p_base_tcp_m = Eigen::Vector3d::Zero();
};

/// Pose and twist of the TCP (base axes).
struct TcpMotion {
  TcpPose pose;
  Eigen::Vector3d v_tcp_base_mps = Eigen::Vector3d::Zero();
  Eigen::Vector3d omega_base_radps = Eigen::Vector3d::Zero();
};

/// What applying one correction did.
struct CorrectionOutcome {
  bool clamped = false;        ///< a commanded joint hit its range and was clamped
  bool near_singular = false;  ///< the Jacobian's smallest singular value was below threshold
  double sigma_min = 0.0;      ///< smallest singular value seen (RKorr only)
};

struct RobotCounters {
  std::uint64_t rkorr_applied = 0;
  std::uint64_t akorr_applied = 0;
  std::uint64_t clamped_commands = 0;      ///< corrections that were clamped at a joint range
  std::uint64_t near_singular_cycles = 0;  ///< RKorr corrections solved near a singularity
  std::uint64_t servo_steps = 0;
};

class RobotEmulator {
 public:
  /// Throws std::invalid_argument naming the value: non-positive or non-finite rates, a servo
  /// bandwidth above a tenth of the physics rate, a start pose outside the ranges.
  explicit RobotEmulator(const RobotConfig& config = {});

  const RobotConfig& config() const { return config_; }

  /// RKorr (mm, degrees): a relative correction of the commanded TCP pose in the base frame B:
  /// p_new = p_old + (X, Y, Z)/1000, R_new = R_corr R_old with R_corr = Rz(A) Ry(B) Rx(C).
  /// Solved for the joints by damped least squares on the TCP's geometric Jacobian at q_cmd,
  /// iterated from q_cmd to the new pose; the result is clamped to the joint ranges.
  CorrectionOutcome apply_rkorr(const proto::rsi::Correction& correction);
  /// AKorr A1..A6 (degrees): added to the commanded joints, then clamped.
  CorrectionOutcome apply_akorr(const std::array<double, 6>& akorr_deg);

  /// One servo step of 1 / physics_rate_hz: the interpolator moves the set point toward the
  /// command at constant speed, and each actual joint follows the set point through
  /// q̈ = ω² (q_set − q) − 2ω q̇, integrated exactly for the set point as it moves within the step
  /// (a ramp until it reaches the command, then held). So q, q̇ and q̈ are those of the
  /// continuous servo at the step's end, and q̈ is the derivative of q̇.
  void step();

  const sim::JointVector& commanded() const { return q_cmd_rad_; }
  const sim::JointState& actual() const { return actual_; }
  const RobotCounters& counters() const { return counters_; }

  /// TCP pose of joint angles `q` (forward kinematics plus the flange → TCP offset).
  TcpPose tcp_pose(const sim::JointVector& q_rad) const;
  /// Pose and twist of the actual TCP.
  TcpMotion actual_tcp() const;
  /// 6 × 6 geometric Jacobian of the TCP at `q`: rows vx, vy, vz (m/s) and ωx, ωy, ωz (rad/s)
  /// in B per unit joint rate (columns A1..A6), from robot::flange_motion.
  Eigen::Matrix<double, 6, 6> jacobian(const sim::JointVector& q_rad) const;

  /// The controller's message of the actual state: RIst = TCP pose (mm; A, B, C in degrees),
  /// AIPos = actual joints (degrees), Delay D = `delay`, IPOC = `ipoc`.
  proto::rsi::RobotMessage message(std::uint64_t ipoc, std::uint64_t delay) const;

 private:
  CorrectionOutcome clamp_command();
  /// e^{Aτ} of the servo for (q − q_set, q̇) with a held set point.
  Eigen::Matrix2d servo_transition(double tau_s) const;

  RobotConfig config_;
  sim::JointLimits limits_;
  double omega_radps_ = 0.0;
  double h_s_ = 0.0;
  Eigen::Matrix2d phi_ = Eigen::Matrix2d::Identity();  // servo_transition(h_s_)
  sim::JointVector q_cmd_rad_{};                       // the command: start + all corrections
  sim::JointVector q_setpoint_rad_{};  // the interpolator's set point the servo follows
  sim::JointVector setpoint_rate_{};   // its speed toward q_cmd_rad_ (rad/s)
  sim::JointState actual_;
  RobotCounters counters_;
};

}  // namespace zerog::emu
