#pragma once
// The payload's motion for the model, every cycle (issue 28, item 2; proto/loop.md, "Motion
// estimator"): the specific force, angular rate and angular acceleration at the IMU that the
// physics reads, estimated from the robot's poses and joints and from the IMU, instead of the
// IMU alone.
//
// Why: the model's inertial terms take the payload's acceleration; from the IMU alone the
// accelerometer's white noise × mass and the gyro's differenced noise × inertia enter every
// prediction (4× and 8× the F/T sensor's own noise in the contact wrench, issue 28). The
// robot's pose (RIst, or the kinematics of AIPos) is nearly noise-free but is the MOTOR side
// of elastic gearboxes, and knows nothing of a tilted base or a sensor mounted off its nominal.
//
// The filter, per cycle, on the row the model is evaluated on (the centre c of the rows
// c−D … c+D, D = Cycle::delay_rows()):
// 1. the motor side's motion at c: a quadratic least-squares fit in time over the 2D+1 rows
//    (robot::LocalPolyFit) of the sensor origin's position (acceleration a_B, B axes), of the
//    rotation vectors r_k = Log(R_cᵀ R_k) (ω_S = ṙ(0), ω̇_S = r̈(0), S axes; as
//    robot::derive_kinematics) and of the joints (the motor's q̇, q̈);
// 2. with an elastic robot (the rig's robot file, robot::RobotModel::elasticity), the link's
//    deflection δ per joint, integrated one row at a time (robot::advance_deflection) from the
//    static sag, driven by the motor's q̈ low-passed at excitation_hz (two first-order stages:
//    the encoders' quantisation differenced must not ring the modes) or, with servo_hz, by a
//    model of the robot's servo fed with the corrections sent (note_command: the controller's
//    own motion, not quantised) plus the measured q̈'s disagreement with it through the same
//    stages, and by the load τ = Jᵀ w
//    of the measured wrench low-passed at load_bandwidth_hz (0.5 Hz: the payload's inertia is
//    part of each mode's effective inertia k/ω², so the wrench's ringing must not load the modes
//    a second time; proto/loop.md, "The joints' load"); the link then turns by J_ω δ and
//    moves with the extra J_ω δ̇, J_ω δ̈, J_v δ̈ (the Jacobian's rate terms neglected);
// 3. the IMU below crossover_hz, compared with the robot at the IMU mean's instant: the
//    difference y = IMU − robot (specific force, I axes) is the sum of two slowly wandering
//    offsets, the accelerometer's bias b_I (fixed in I) and the error of the assumed gravity
//    e_B (fixed in B: a tilted base, a mounting the robot file does not know), y = b_I + R_IB e_B
//    + white noise. A Kalman filter of (b_I, e_B) as random walks tracks both; while the payload
//    turns they separate, so a tilt is not lagged like an offset turning with the IMU. Each
//    walk's variance per row is set from crossover_hz (the steady-state gain K = 1 − exp(−2π f_c
//    Δt) of one offset alone: q = K² r / (1 − K)), half to each; the prior is finite (the first
//    rows average). The rate's offset is fixed in I: a first-order low-pass of the difference
//    (the same gain, K = max(K, 1/n) at the start). ω̇ is the robot's alone.
//    What the IMU corrects: the sag the model of step 2 misses, a tilted base, the mounting;
//    what the robot gives: everything faster, free of the IMU's white noise.
//    Settled: the first rows average, so the share's error falls as 1/√n (one row: the IMU's
//    row noise × 100 kg ≈ 0.9 N per axis in the contact force). The estimate is settled once the
//    variance of the offsets' sum (H P Hᵀ, worst axis) is within kSettledRatio of its steady
//    value, the steady gain K (r = 1; the rate's offset, averaged as 1/n, is there by then too):
//    row 73 (0.88 s) at 0.1 Hz and 12 ms, the share's error then 0.10 N per axis on 100 kg
//    against 0.35 N at row 5 (MotionEstimator.TheImusShareSettlesBeforeItsContactIsTrusted).
//    Before that the contact wrench is not trusted to confirm a push (Cycle:
//    kEstimatorSettling; why: proto/loop.md, "Motion estimator").
// 4. while the arm rings (elastic robot after a push, a stop): within ringing_hold_s of a
//    contact (the zero-g gates open) or a motion limit acting (note_excitation), the gyro's
//    disagreement with the rigid robot's rate, its mean square over kRingingWindow_s (50 ms),
//    sets a schedule
//    s = e² / (e² + (3 ringing_radps)²): near 0 at rest (the gyro's row noise is about 1e-4
//    rad/s), near 1 while the link oscillates against the motor. With s, (a) the gyro's residual
//    against the modelled link rate corrects the modes' rates (δ̇ += s · mode_gain · J_ω⁺ e,
//    main axes A1–A3, damped least squares: a Luenberger observer, gain-scheduled), and (b) the
//    output moves toward the IMU as it comes by s (its rate, specific force and the central
//    difference's ω̇). Why: the modelled ringing misses about 10 % of the real one, and a miss in
//    the mode band closes a loop through the virtual body (measured: proto/loop.md). This is
//    not the Kalman filter with the modes as states that the method calls for; it is the
//    measured-stable step toward it (that filter, on the gyro, was tried and measured worse:
//    proto/loop.md). Away from contacts and limits, step 4 is off: the gyro's disagreement
//    there is its noise and a slow residual of the turning link (a quasi-static deflection's
//    rate), which step 4 would put into the modes and the output (measured: proto/loop.md).
//
// Instants: the row's F/T and IMU values are means of the samples of the window that ended at
// the robot's message (the row's time t_c); n samples at rate f, the last `delay` before the
// message, stand for t_c − (n − 1) / (2 f) − delay. The robot's fit is evaluated at the IMU's
// instant for the comparison of step 3 and at the F/T's for the output, so that the predicted
// wrench is of the measured one's instant. Comparing at the wrong instant is not harmless:
// the offsets of step 3 absorb the lag of a steady turn (a constant in B), and the output then
// has the IMU's instant (measured: proto/loop.md, "Motion estimator").
//
// Delay: the fit is centred on row c, so the estimate is that of the row the model is
// evaluated on: the measured and predicted wrench are of the same instant; the contact wrench
// is D rows late, as with the IMU's central difference (D = 2: 24 ms at 12 ms). Step 3 is
// causal at c (its lag is that of a 0.1 Hz first order, on a signal that moves slower).
//
// Frames (proto/frames.md): B base, S sensor (RIst's TCP), I IMU (the rig's sensor_imu). SI.
// Life cycle: configure() at start-up; update() every cycle: no allocation, no exceptions.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <span>

#include "zerog/loop/servo_model.hpp"
#include "zerog/model/features.hpp"
#include "zerog/model/predict.hpp"
#include "zerog/robot/robot_model.hpp"
#include "zerog/samples/robot_sample.hpp"
#include "zerog/status.hpp"

namespace zerog::loop {

/// Where the model's payload motion comes from (zerog-rt's [filter] motion).
enum class MotionSource : std::uint8_t {
  imu,    ///< the IMU as it comes (the rows' mean, ω̇ by central difference): the raw path
  fused,  ///< MotionEstimator: the robot's poses and joints, the IMU below the crossover
};

struct MotionEstimatorConfig {
  /// imu by default: on an elastic arm the fused path is stable (step 4) but not yet within
  /// its noise targets (proto/loop.md, "The elastic arm").
  MotionSource source = MotionSource::imu;
  double crossover_hz = 0.1;       ///< below it the IMU, above it the robot
  double load_bandwidth_hz = 0.5;  ///< the measured wrench as the joints' load (header, 2)
  double excitation_hz = 2.0;      ///< the motor's acceleration that drives the modes
  /// The robot's position servo (robot::servo_accel: critically damped, this bandwidth), fed
  /// each cycle with the joint increment of the correction zerog-rt sent (note_command),
  /// interpolated over one cycle: the modes' drive is then this model's acceleration plus the
  /// measured joints' disagreement with it below excitation_hz (header, step 2). 0: the
  /// measured joints' alone.
  double servo_hz = 0.0;
  double substep_s = 1e-3;  ///< the deflection's integration step
  /// Step 4 (header): the gyro's disagreement with the rigid robot (RMS per axis over
  /// kRingingWindow_s) at which the IMU takes a tenth of the output; 0: step 4 off.
  double ringing_radps = 3e-4;
  /// Step 4: the share of the gyro's residual that corrects the modes' rates per row, at full
  /// schedule.
  double mode_gain = 0.5;
  /// Step 4 acts for this long after a contact or a motion limit (note_excitation), s.
  double ringing_hold_s = 1.0;
  /// The rates of the samples that make a row (zerog-rt: [ft] rate_hz, the rig's imu_rate_hz)
  /// and the time from a window's last sample to the robot's message beyond what the count
  /// says (0 in lockstep, where the window's last samples are taken at the message): the
  /// instants the row's means stand for (header, "Instants"). A rate of 0: half a row.
  double ft_rate_hz = 0.0;
  double imu_rate_hz = 0.0;
  double ft_delay_s = 0.0;
  double imu_delay_s = 0.0;
  /// Gravity in B, m/s² (B's z up: a tilt of the base is left to the IMU's share).
  Eigen::Vector3d gravity_base_mps2{0.0, 0.0, -9.80665};
  /// Test mutants (zerog-rt --test-mutant only; the HIL checks must fail on each): the IMU's
  /// share dropped, or the estimate of the row before the model's used (one cycle late).
  bool mutant_without_imu = false;
  bool mutant_one_row_late = false;
  bool mutant_without_ringing = false;  ///< step 4 dropped (the elastic arm then rings up)
  bool mutant_settled_at_once = false;  ///< `settled` from the first row (a false start)
};

/// The correction as the robot receives it: RSI carries 4 decimals of mm and of degrees
/// (proto::rsi::kReplyDecimals; the rotation as KUKA's A, B, C), so the servo model follows the
/// rounded increments the controller executes (at 0.6 rad/s the rounding is as large as the
/// encoders' quantisation in q̈). Real-time safe.
samples::RobotCorrection as_sent_over_rsi(const samples::RobotCorrection& correction) noexcept;

/// Whether `c` can be used: ok(), or invalid_setting naming the field ("crossover_hz", …).
zerog::Status check_estimator_config(const MotionEstimatorConfig& c);

/// How many samples made the centre row's means (0: held from an earlier row).
struct WindowCounts {
  int ft = 0;
  int imu = 0;
};

/// What the estimator says about its last update (for tests and the record).
struct MotionEstimate {
  model::ImuSignals<double> imu;  ///< at the centre row, I axes (what the physics reads)
  /// The robot's part alone (before the IMU's share), I axes.
  Eigen::Vector3d specific_force_robot_imu = Eigen::Vector3d::Zero();
  Eigen::Vector3d angular_rate_robot_imu = Eigen::Vector3d::Zero();
  /// The IMU's share (the filtered difference IMU − robot), I axes; the specific force's is
  /// the sum of its two parts below.
  Eigen::Vector3d specific_force_offset = Eigen::Vector3d::Zero();
  Eigen::Vector3d specific_force_bias_imu = Eigen::Vector3d::Zero();    ///< b_I, I axes
  Eigen::Vector3d specific_force_error_base = Eigen::Vector3d::Zero();  ///< e_B, B axes
  Eigen::Vector3d angular_rate_offset = Eigen::Vector3d::Zero();
  std::array<double, robot::kMaxJoints> deflection_rad{};  ///< δ per recorded joint at c
  /// The servo model's acceleration per recorded joint at c (servo_hz; 0 without), rad/s².
  std::array<double, robot::kMaxJoints> servo_accel_radps2{};
  /// The robot followed the servo model from the last centre row to c (false: the model is off
  /// for a second, loop::ServoModel; true without servo_hz).
  bool servo_followed = true;
  double ringing = 0.0;  ///< step 4's schedule s in [0, 1): the IMU's share of the output
  /// Step 3's share has settled (header): the offsets' variance within kSettledRatio of steady.
  bool settled = false;
  double ft_instant_s = 0.0;   ///< the F/T mean's instant, from the centre row's time (≤ 0)
  double imu_instant_s = 0.0;  ///< the IMU mean's
};

/// Step 3's Kalman filter of the specific force's two offsets (MotionEstimator, header):
/// x = (b_I, e_B), y = b_I + R_IB e_B + v, both random walks.
class ForceOffsets {
 public:
  void reset() noexcept;
  /// One row: `y` = IMU − robot (I axes), `R_IB`, and the steady gain K of the crossover (0 on
  /// the first row: no process noise yet).
  void update(const Eigen::Vector3d& y, const Eigen::Matrix3d& R_IB, double k_steady) noexcept;
  const Eigen::Vector3d& bias_I() const { return bias_I_; }
  const Eigen::Vector3d& error_B() const { return error_B_; }
  /// The offsets' sum's variance (H P Hᵀ, worst axis) within kSettledRatio of the steady gain K
  /// it tends to (header, "Settled").
  bool settled() const {
    return steady_gain_ > 0.0 && sum_variance_ <= kSettledRatio * steady_gain_;
  }

 private:
  // Step 3's Kalman filter of the specific force's two offsets, in units of the variance of the
  // IMU's row mean (the STIM300's VRW 0.06 m/s/√h over 12 ms: about (0.009 m/s²)²,
  // proto/sim_robot.md). The prior of each part: σ = 10 such units (≈ 0.1 m/s²: a 10 mrad
  // tilt or a 10 mg bias), broad for their sum (the first rows average), not so broad that the
  // first small turns of the payload split the two by their noise.
  static constexpr double kPriorVariance = 100.0;
  static constexpr double kSettledRatio = 2.0;
  Eigen::Vector3d bias_I_ = Eigen::Vector3d::Zero(), error_B_ = Eigen::Vector3d::Zero();
  Eigen::Matrix<double, 6, 6> P_ = Eigen::Matrix<double, 6, 6>::Identity() * kPriorVariance;
  double sum_variance_ = 2.0 * kPriorVariance;
  double steady_gain_ = 0.0;
};

class MotionEstimator {
 public:
  /// Start-up: the settings, the IMU's pose in S (the rig's sensor_imu) and the robot (its
  /// elasticity and Jacobian; none: the poses alone, a rigid arm). Not real-time safe.
  zerog::Status configure(const MotionEstimatorConfig& config, const Eigen::Matrix3d& R_sensor_imu,
                          const Eigen::Vector3d& p_sensor_imu_m,
                          const std::optional<robot::RobotModel>& robot);
  const MotionEstimatorConfig& config() const { return config_; }
  /// Whether the arm was excited in the last cycle beyond what the robot's joints show: a
  /// push passed on (a contact gate open), a motion limit acting, a path being followed. Step 4
  /// acts within ringing_hold_s of it. Real-time safe.
  void note_excitation(bool excited) noexcept { excited_ = excited; }
  /// The correction sent in reply to the message whose row has time `t_row_s` (none: nothing
  /// commanded; rounded here as RSI carries it, as_sent_over_rsi), at that row's joints, the
  /// robot's cycle `cycle_s`: with servo_hz, the servo model is advanced over the cycle and its
  /// acceleration kept for the next row. Real-time safe.
  void note_command(const samples::RobotCorrection& correction, std::span<const double> joints_rad,
                    double t_row_s, double cycle_s) noexcept;
  /// Forget the past (the next update starts afresh: static sag, the IMU's share averaged anew).
  void reset() noexcept;

  /// One row: `rows` are the 2D+1 rows c−D … c+D (oldest first, times increasing), `wrench`
  /// the measured wrench of row c (S, N and N·m), `imu_at_c` the IMU at row c (the rows' mean,
  /// aligned to the F/T as the model wants it; ω̇ unused). False (and `out` untouched) if the
  /// rows' times do not determine the fit. Real-time safe.
  bool update(std::span<const model::FeatureSignals* const> rows,
              const std::array<double, 6>& wrench, const model::ImuSignals<double>& imu_at_c,
              const WindowCounts& counts, MotionEstimate& out) noexcept;

 private:
  MotionEstimatorConfig config_;
  Eigen::Matrix3d R_sensor_imu_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p_sensor_imu_m_ = Eigen::Vector3d::Zero();
  bool have_robot_ = false;
  bool elastic_ = false;
  robot::RobotModel robot_;
  std::array<robot::JointElasticity, robot::kMaxJoints> elasticity_{};  ///< per recorded joint

  // State at the last update's centre row.
  bool started_ = false;
  double t_s_ = 0.0;
  double t_before_s_ = -1.0;  ///< the centre row's before t_s_ (the servo model's key, step 2)
  std::uint64_t updates_ = 0;
  std::array<double, 6> wrench_lp_{};
  std::array<double, robot::kMaxJoints> qdd_lp1_{}, qdd_lp2_{};  ///< the excitation's stages
  std::array<double, robot::kMaxJoints> drive_{};  ///< the modes' drive at t_s_ (step 2)
  ServoModel servo_;                               ///< servo_hz (note_command, step 2)
  std::array<double, robot::kMaxJoints> tau_{};    ///< the load at t_s_
  std::array<double, robot::kMaxJoints> delta_{}, delta_dot_{};
  Eigen::Vector3d offset_w_ = Eigen::Vector3d::Zero();
  double residual_ms_ = 0.0;  ///< step 4: the gyro's mean-square disagreement, (rad/s)²
  bool excited_ = false;      ///< note_excitation's last word
  /// Rows' time since it was true (infinite: never, as after reset()).
  double since_excitation_s_ = std::numeric_limits<double>::infinity();
  static constexpr double kRingingWindow_s = 0.05;  ///< step 4's mean square
  static constexpr int kObservedAxes = 3;           ///< step 4a: A1–A3 (A5 is not observed)
  static constexpr double kDamping = 1e-6;          ///< step 4a's least squares (A2 ∥ A3)
  ForceOffsets offsets_;                            ///< step 3's specific-force offsets

  // update()'s phases (motion_estimator.cpp): 1, 2 with 4a, 3.
  struct MotorMotion;
  struct LinkMotion;
  bool fit_motor_side(std::span<const model::FeatureSignals* const> rows,
                      MotorMotion& m) const noexcept;
  void deflect(const MotorMotion& m, const model::FeatureSignals& centre,
               const std::array<double, 6>& wrench, const model::ImuSignals<double>& imu_at_c,
               double dt, double schedule, const std::array<double, robot::kMaxJoints>& servo_qdd,
               LinkMotion& link, MotionEstimate& out) noexcept;
  void track_offsets(const model::ImuSignals<double>& imu_at_c, const Eigen::Vector3d& f_I_cmp,
                     const Eigen::Vector3d& omega_I_cmp, const Eigen::Matrix3d& R_link_imu,
                     double dt) noexcept;
};

}  // namespace zerog::loop
