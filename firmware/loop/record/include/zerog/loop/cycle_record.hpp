#pragma once
// What one cycle of zerog-rt did (proto/loop.md, "Record CSV"): CycleRecord and its flags, the
// black box's, the recorder's and telemetry's record. zerog::cycle_record holds the type apart
// from the cycle (zerog::loop, cycle.hpp), so that whoever only reads or writes records (the
// cycles.csv writer and reader of zerog::formats, the host's gate rule) does not link the
// real-time cycle. Plain values, fixed size.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>

#include "zerog/control/virtual_body.hpp"
#include "zerog/infer/inference.hpp"
#include "zerog/loop/state.hpp"
#include "zerog/samples/robot_sample.hpp"

namespace zerog::loop {

/// Bits of CycleRecord::flags.
enum CycleFlags : std::uint32_t {
  kFtHeld = 1u << 0,          ///< no valid F/T sample this cycle: the last one was reused
  kImuHeld = 1u << 1,         ///< likewise for the IMU
  kNotReady = 1u << 2,        ///< fewer rows than the model needs: no contact wrench yet
  kModelSaturated = 1u << 3,  ///< the network clipped inputs or activations
  kIpocGap = 1u << 4,         ///< IPOC jumped by more than one period (datagrams lost)
  kIpocStale = 1u << 5,       ///< IPOC not newer than the last one (duplicate or reordered)
  kRobotDelayGrew = 1u << 6,  ///< the robot's Delay counter grew
  kCommandRefused = 1u << 7,  ///< a command this cycle was not allowed in the state
  kCollectionDone = 1u << 8,  ///< collection reached the end of its path (back to idle)
  kFtWarning = 1u << 9,       ///< F/T samples with non-critical status bits were used
  kRobotLost = 1u << 10,      ///< a lost robot cycle (robot_lost()): no message, no reply
  /// The model's row (t_eval_s) had a held sensor value (kFtHeld or kImuHeld when it was this
  /// cycle's row): its contact is not trusted, so `contact` is zero and the body coasts.
  kContactHeld = 1u << 11,
  kPoseFromJoints = 1u << 12,  ///< no RIst: the sensor pose is the kinematics' of AIPos
  kPoseDisagrees = 1u << 13,   ///< RIst and the kinematics disagree (CycleConfig::pose_check_*)
  /// No RIst and no robot configured: the message has no pose. It is answered (zero, its IPOC)
  /// but counts as a lost robot cycle (robot watchdog), and nothing else changes.
  kPoseMissing = 1u << 14,
  /// The F/T sensor's temperature reading is older than its maximum age (samples::FtSample::
  /// temperature_stale: the board stopped answering the thermistor reads): the model gets
  /// CycleConfig::temperature_C again (temperature_measured false) until a fresh reading comes.
  kTemperatureStale = 1u << 15,
  /// The motion estimator's IMU share has not settled yet (MotionEstimate::settled; [filter]
  /// motion = "fused" only): the contact wrench drives an open gate and is checked against the
  /// limits, but a closed contact gate does not open (ZeroGMotion::step's `may_confirm`).
  kEstimatorSettling = 1u << 16,
  /// The contact's tare is being taken ([filter] tare_s; stages::tare_contact): the contact is
  /// not yet zeroed, and a closed contact gate does not open, as with kEstimatorSettling.
  kContactTaring = 1u << 17,
};

/// Everything one cycle did: the black box, the recorder and telemetry take it. Fixed size.
struct CycleRecord {
  std::uint64_t cycle = 0;  ///< robot messages handled, from 1
  std::uint64_t ipoc = 0;
  double t_s = 0.0;   ///< robot time since the first message (IPOC based)
  double dt_s = 0.0;  ///< time step used for the virtual body
  State state = State::idle;
  Fault fault = Fault::none;
  std::uint32_t flags = 0;        ///< CycleFlags
  std::uint32_t limit_flags = 0;  ///< control::LimitFlags
  infer::StatusCode model_status = infer::StatusCode::not_configured;
  // This cycle's row (what is recorded in the log format).
  std::array<double, 6> joints_rad{};
  /// S in B: from RIst (TCP = sensor frame), or from AIPos by forward kinematics
  /// (kPoseFromJoints).
  Eigen::Vector3d p_base_sensor_m = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_base_sensor = Eigen::Quaterniond::Identity();
  /// RIst against the kinematics of AIPos when both are there (else 0): distance of the
  /// origins (m) and angle of the relative rotation (rad).
  double pose_check_m = 0.0;
  double pose_check_rad = 0.0;
  std::array<double, 6> wrench_measured{};     ///< mean F/T of the cycle, sensor frame, N / N·m
  std::array<double, 3> specific_force_imu{};  ///< mean IMU, IMU frame, m/s²
  std::array<double, 3> rate_imu{};            ///< mean gyro, IMU frame, rad/s
  std::uint16_t ft_samples = 0;                ///< valid F/T samples averaged
  std::uint16_t imu_samples = 0;               ///< valid IMU samples averaged
  /// The temperature fed to the model this cycle, °C: the F/T sensor's latest reading when
  /// temperature_measured, else CycleConfig::temperature_C (before the first reading, or while
  /// the reading is stale: kTemperatureStale).
  double temperature_C = 25.0;
  bool temperature_measured = false;
  double temperature_age_s = 0.0;  ///< age of that reading when it came with a sample, s
  // The model, evaluated on the row delay_rows() back (t_eval_s).
  double t_eval_s = 0.0;
  std::array<double, 6> wrench_at_eval{};  ///< measured, that row
  std::array<double, 6> predicted{};       ///< model prediction, that row
  std::array<double, 6> contact{};         ///< measured − predicted (sensor frame, about S)
  /// The reply sent, in SI (as the cycle handed it to zerog::rtio): Kind::none (a zero RKorr),
  /// cartesian (translation in B, m; rotation in B) or axes (AKorr, rad), with the message's
  /// IPOC. cycles.csv writes it in the wire's units (mm, degrees).
  samples::RobotCorrection reply;
  // The virtual body after the step (world = robot base frame).
  control::BodyState body;
  std::int64_t compute_ns = 0;  ///< filled in by the program (time of step())
};

}  // namespace zerog::loop
