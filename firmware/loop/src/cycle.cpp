#include "zerog/loop/cycle.hpp"

#include "zerog/model/dictionary.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "zerog/model/rotation.hpp"
#include "zerog/model/signals.hpp"
#include "zerog/robot/forward_kinematics.hpp"

namespace zerog::loop {
namespace {

bool positive_finite(double x) { return std::isfinite(x) && x > 0.0; }

std::string check_config(const CycleConfig& c) {
  if (!positive_finite(c.period_s)) return "period_s must be a positive number of seconds";
  if (!positive_finite(c.ipoc_unit_s)) return "ipoc_unit_s must be a positive number of seconds";
  if (c.angular_accel_order != 2 && c.angular_accel_order != 4)
    return "angular_accel_order must be 2 or 4";
  const WatchdogConfig& w = c.watchdog;
  if (w.ft_fault_cycles < 1 || w.imu_fault_cycles < 1 || w.robot_fault_cycles < 1 ||
      w.robot_late_cycles < 1 || w.model_fault_cycles < 1)
    return "watchdog cycle counts must be at least 1";
  if (const char* why = check_tunables({c.body, c.limits, c.p_sensor_com_m}); *why != '\0')
    return why;
  if (!positive_finite(c.max_axis_step_rad) || !positive_finite(c.approach_speed_radps) ||
      !positive_finite(c.approach_accel_radps2))
    return "collection step, speed and acceleration must be positive";
  if (!positive_finite(c.pose_check_position_m) || !positive_finite(c.pose_check_angle_rad))
    return "pose check tolerances must be positive";
  if (c.robot) {
    if (const robot::RobotStatus st = robot::validate(*c.robot); !st.ok())
      return "robot: " + st.field + ": " + st.message;
    if (c.robot->joint_count != 6)
      return "robot: RSI reports 6 axes (AIPos A1..A6); the robot has " +
             std::to_string(c.robot->joint_count);
  }
  return {};
}

// Internal values of Cycle::proposal_state_ besides the ProposalStatus ones.
constexpr std::uint8_t kProposalWriting = 100;  // the proposer is filling proposal_
constexpr std::uint8_t kProposalTaking = 101;   // the cycle is reading proposal_

constexpr std::uint8_t status_byte(ProposalStatus s) { return static_cast<std::uint8_t>(s); }

template <std::size_t N>
void set_zero(std::array<double, N>& a) {
  a.fill(0.0);
}

}  // namespace

const char* check_tunables(const Tunables& t) noexcept {
  if (!positive_finite(t.body.mass_kg)) return "body mass must be positive";
  const Eigen::Matrix3d& I = t.body.inertia_body_kgm2;
  if (!I.allFinite() || (I - I.transpose()).norm() > 1e-9 * I.norm() ||
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(I, Eigen::EigenvaluesOnly)
              .eigenvalues()
              .minCoeff() <= 0.0)
    return "body inertia must be symmetric positive definite";
  if (!t.p_sensor_com_m.allFinite()) return "virtual centre of mass must be finite";
  const control::MotionLimits& l = t.limits;
  if (!(l.force_deadband_N >= 0.0) || !(l.torque_deadband_Nm >= 0.0))
    return "deadbands must be zero or positive";
  if (l.contact_confirm_cycles < 1) return "contact_confirm_cycles must be at least 1";
  if (!(l.contact_release_fraction >= 0.0 && l.contact_release_fraction <= 1.0))
    return "contact_release_fraction must be in 0..1";
  if (!positive_finite(l.max_contact_force_N) || !positive_finite(l.max_contact_torque_Nm) ||
      !positive_finite(l.max_speed_mps) || !positive_finite(l.max_angular_speed_radps) ||
      !positive_finite(l.max_accel_mps2) || !positive_finite(l.max_angular_accel_radps2))
    return "motion limits must be positive";
  if (!(l.force_deadband_N < l.max_contact_force_N) ||
      !(l.torque_deadband_Nm < l.max_contact_torque_Nm))
    return "deadbands must be below the contact limits";
  if (!(l.linear_damping_per_s >= 0.0 && std::isfinite(l.linear_damping_per_s)) ||
      !(l.angular_damping_per_s >= 0.0 && std::isfinite(l.angular_damping_per_s)))
    return "damping must be zero or positive";
  if (!l.workspace_min_m.allFinite() || !l.workspace_max_m.allFinite() ||
      !(l.workspace_min_m.array() < l.workspace_max_m.array()).all())
    return "workspace_min must be below workspace_max on every axis";
  return "";
}

std::string Cycle::configure(const CycleConfig& config, infer::DeployedModel model) {
  if (std::string why = check_config(config); !why.empty()) return why;
  const bool network = model.network.has_value();
  if (std::string why = inference_.configure(std::move(model)); !why.empty()) return why;
  config_ = config;
  use_network_ = network;
  motion_ = control::ZeroGMotion(config.body, config.limits, config.p_sensor_com_m);
  configured_ = true;
  return {};
}

void Cycle::add_ft(const samples::FtSample& s) noexcept {
  if (!s.valid) {
    ++counters_.ft_invalid;
    if (s.status == samples::FtSampleStatus::critical) ++window_.ft_critical;
    if (s.status == samples::FtSampleStatus::saturated) ++window_.ft_saturated;
    return;
  }
  if (window_.ft_n >= kMaxWindow) {
    ++counters_.sample_overflow;
    return;
  }
  for (int k = 0; k < 6; ++k) window_.ft_sum[k] += s.wrench_si[k];
  ++window_.ft_n;
  if (s.status == samples::FtSampleStatus::warning) ++window_.ft_warning;
}

void Cycle::add_imu(const samples::ImuSample& s) noexcept {
  if (!s.rate_valid || !s.accel_valid) {
    ++counters_.imu_invalid;
    return;
  }
  if (window_.imu_n >= kMaxWindow) {
    ++counters_.sample_overflow;
    return;
  }
  for (int k = 0; k < 3; ++k) {
    window_.imu_sum[k] += s.accel_m_s2[k];
    window_.imu_sum[3 + k] += s.rate_rad_s[k];
  }
  ++window_.imu_n;
}

void Cycle::set_compute_ns(std::int64_t ns) noexcept {
  record_.compute_ns = ns;
  if (box_.size() > 0 && box_.newest().cycle == record_.cycle) box_.newest().compute_ns = ns;
}

std::uint64_t Cycle::request(Command c) noexcept {
  if (pending_.load(std::memory_order_acquire) != 0) return 0;
  const std::uint64_t ticket = tickets_.fetch_add(1, std::memory_order_relaxed) + 1;
  std::uint64_t expected = 0;
  const std::uint64_t packed = ticket << 8 | static_cast<std::uint64_t>(1 + static_cast<int>(c));
  return pending_.compare_exchange_strong(expected, packed, std::memory_order_acq_rel) ? ticket : 0;
}

CommandOutcome Cycle::command_outcome(std::uint64_t ticket) const noexcept {
  const std::uint64_t slot = outcomes_[ticket % kCommandOutcomes].load(std::memory_order_acquire);
  if (slot >> 2 == ticket) {
    return (slot & 3u) == 1u ? CommandOutcome::accepted : CommandOutcome::refused;
  }
  // Not decided yet (still pending, or taken by the cycle that is deciding it now), or decided
  // so long ago that a later ticket took its slot.
  return slot >> 2 > ticket ? CommandOutcome::unknown : CommandOutcome::pending;
}

void Cycle::raise(Fault f) noexcept {
  if (sm_.state() == State::fault) return;
  sm_.raise(f, cycle_);
  // The box still holds an earlier fault that has not been dumped and released: this fault's
  // cycles cannot be kept. Counted, never silent.
  if (box_.frozen()) {
    ++counters_.black_boxes_lost;
    return;
  }
  freeze_pending_ = true;
}

bool Cycle::propose(const Tunables& t) noexcept {
  std::uint8_t seen = proposal_state_.load(std::memory_order_acquire);
  do {
    if (seen == status_byte(ProposalStatus::pending) || seen == kProposalWriting ||
        seen == kProposalTaking)
      return false;
  } while (
      !proposal_state_.compare_exchange_weak(seen, kProposalWriting, std::memory_order_acq_rel));
  proposal_ = t;
  proposal_state_.store(status_byte(ProposalStatus::pending), std::memory_order_release);
  return true;
}

ProposalStatus Cycle::proposal_status() const noexcept {
  const std::uint8_t s = proposal_state_.load(std::memory_order_acquire);
  if (s == kProposalTaking) return ProposalStatus::pending;
  if (s == kProposalWriting) return ProposalStatus::none;
  return static_cast<ProposalStatus>(s);
}

bool Cycle::withdraw_proposal() noexcept {
  std::uint8_t expected = status_byte(ProposalStatus::pending);
  return proposal_state_.compare_exchange_strong(expected, status_byte(ProposalStatus::none),
                                                 std::memory_order_acq_rel);
}

void Cycle::take_proposal() noexcept {
  std::uint8_t expected = status_byte(ProposalStatus::pending);
  if (!proposal_state_.compare_exchange_strong(expected, kProposalTaking,
                                               std::memory_order_acq_rel))
    return;
  ProposalStatus outcome = ProposalStatus::accepted;
  if (sm_.state() != State::idle) {
    outcome = ProposalStatus::refused_state;
  } else if (*check_tunables(proposal_) != '\0') {
    outcome = ProposalStatus::refused_invalid;
  } else {
    config_.body = proposal_.body;
    config_.limits = proposal_.limits;
    config_.p_sensor_com_m = proposal_.p_sensor_com_m;
    // Idle: the body is reset to the sensor's pose every cycle, so nothing moving is lost.
    motion_ = control::ZeroGMotion(config_.body, config_.limits, config_.p_sensor_com_m);
    ++tunables_accepted_;
  }
  proposal_state_.store(status_byte(outcome), std::memory_order_release);
}

void Cycle::robot_lost(RobotLoss why) noexcept {
  take_proposal();
  if (why == RobotLoss::timeout) {
    ++counters_.robot_timeouts;
  } else {
    ++counters_.robot_malformed;
  }
  if (!have_ipoc_) return;  // the robot has not started its RSI session yet
  grow_lost_run();
  push_lost_record(kRobotLost);
}

void Cycle::pose_missing() noexcept {
  ++counters_.poses_missing;
  if (have_ipoc_) grow_lost_run();
  record_.rkorr = proto::rsi::Correction{};
  push_lost_record(kPoseMissing);
}

void Cycle::grow_lost_run() noexcept {
  ++robot_lost_run_;
  const State s = sm_.state();
  if ((s == State::zero_g || s == State::collecting) &&
      robot_lost_run_ >= config_.watchdog.robot_fault_cycles) {
    raise(Fault::robot_late);
  }
}

void Cycle::push_lost_record(std::uint32_t flags) noexcept {
  record_.flags = flags;
  record_.state = sm_.state();
  record_.fault = sm_.fault();
  box_.push(record_);
  if (freeze_pending_) {
    box_.freeze();
    freeze_pending_ = false;
  }
}

void Cycle::sensor_pose(const proto::rsi::RobotMessage& m, const std::array<double, 6>& q_rad,
                        Eigen::Matrix3d& R_base_sensor, Eigen::Vector3d& p_base_sensor_m,
                        std::uint32_t& flags) noexcept {
  record_.pose_check_m = 0.0;
  record_.pose_check_rad = 0.0;
  if (m.has_actual_pose) {
    const proto::rsi::PoseSi pose = proto::rsi::to_si(m.actual_pose);
    R_base_sensor =
        model::rotation_from_kuka_abc(pose.abc_rad[0], pose.abc_rad[1], pose.abc_rad[2]);
    p_base_sensor_m = Eigen::Map<const Eigen::Vector3d>(pose.position_m.data());
  }
  if (!config_.robot) return;  // step() has sent a message without RIst to pose_missing()
  const robot::Pose kinematics = robot::sensor_pose(*config_.robot, q_rad);
  if (!m.has_actual_pose) {
    R_base_sensor = kinematics.R;
    p_base_sensor_m = kinematics.p_m;
    flags |= kPoseFromJoints;
    ++counters_.poses_from_joints;
    return;
  }
  record_.pose_check_m = (p_base_sensor_m - kinematics.p_m).norm();
  record_.pose_check_rad =
      Eigen::AngleAxisd(Eigen::Matrix3d(R_base_sensor.transpose() * kinematics.R)).angle();
  if (record_.pose_check_m > config_.pose_check_position_m ||
      record_.pose_check_rad > config_.pose_check_angle_rad) {
    flags |= kPoseDisagrees;
    ++counters_.pose_disagreements;
  }
}

void Cycle::apply_command(std::uint64_t cycle, const Row& now, bool ready,
                          std::uint32_t& flags) noexcept {
  const std::uint64_t p = pending_.exchange(0, std::memory_order_acq_rel);
  if (p == 0) return;
  const auto c = static_cast<Command>((p & 0xffu) - 1);
  const std::uint64_t ticket = p >> 8;
  bool allowed = true;
  if (c == Command::enable_zero_g && !ready) allowed = false;
  if (c == Command::start_collection && path_ == nullptr) allowed = false;
  if (allowed) allowed = sm_.command(c, cycle);
  outcomes_[ticket % kCommandOutcomes].store(ticket << 2 | (allowed ? 1u : 2u),
                                             std::memory_order_release);
  if (!allowed) {
    flags |= kCommandRefused;
    ++counters_.commands_refused;
    return;
  }
  if (c == Command::enable_zero_g) {
    const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> R(
        now.signals.R_base_sensor.data());
    motion_.reset(Eigen::Map<const Eigen::Vector3d>(now.signals.p_base_sensor_m.data()),
                  Eigen::Quaterniond(Eigen::Matrix3d(R)));
  }
  if (c == Command::start_collection) {
    collection_on_path_ = false;
    collection_t_s_ = 0.0;
    collection_cmd_rad_ = now.signals.joints_rad;
    set_zero(collection_v_radps_);
  }
  if (c == Command::reset_fault) {
    robot_lost_run_ = robot_late_run_ = 0;
    ft_bad_run_ = imu_bad_run_ = model_bad_run_ = 0;
  }
}

bool Cycle::evaluate(std::uint32_t& flags) noexcept {
  const int D = delay_rows();
  const int n = 2 * D + 1;
  // Rows centre − D … centre + D (= newest), oldest first, in contiguous arrays.
  std::array<double, 3 * 5> f{}, w{};
  const std::uint64_t newest = rows_total_ - 1;
  for (int j = 0; j < n; ++j) {
    const Row& r = rows_[(newest - static_cast<std::uint64_t>(n - 1 - j)) % kHistory];
    for (int k = 0; k < 3; ++k) {
      f[3 * j + k] = r.signals.imu[k];
      w[3 * j + k] = r.signals.imu[3 + k];
    }
  }
  Row& centre = rows_[(newest - static_cast<std::uint64_t>(D)) % kHistory];
  const Row& first = rows_[(newest - static_cast<std::uint64_t>(2 * D)) % kHistory];
  const Row& last = rows_[newest % kHistory];
  const double row_dt = (last.t_s - first.t_s) / (2.0 * D);
  const double dt = row_dt > 0.0 ? row_dt : config_.period_s;
  const Eigen::Vector3d wdot =
      model::angular_accel_central(w.data() + 3 * D, 3, config_.angular_accel_order, dt);
  for (int k = 0; k < 3; ++k) centre.signals.imu[6 + k] = wdot[k];

  // The physics reads the IMU at t + tau (imu_time_offset), within the rows we have.
  model::ImuSignals<double> physics_imu;
  const double index = D + inference_.imu_time_offset_s() / dt;
  physics_imu.specific_force_imu = model::interpolate_uniform<3>(f.data(), n, index);
  physics_imu.angular_rate_imu = model::interpolate_uniform<3>(w.data(), n, index);
  physics_imu.angular_accel_imu = wdot;

  // The signal dictionary's kinematics at the centre row (user-defined effects): central
  // differences of the joints and the sensor position over its neighbours.
  model::KinematicInputs kinematics;
  kinematics.features = centre.signals;
  {
    const Row& before = rows_[(newest - static_cast<std::uint64_t>(D + 1)) % kHistory];
    const Row& after = rows_[(newest - static_cast<std::uint64_t>(D - 1)) % kHistory];
    if (after.t_s > centre.t_s && centre.t_s > before.t_s) {
      model::central_differences(before.signals.joints_rad.data(), centre.signals.joints_rad.data(),
                                 after.signals.joints_rad.data(), 6, before.t_s, centre.t_s,
                                 after.t_s, kinematics.features.joint_vel_radps.data(),
                                 kinematics.joint_acc_radps2.data());
      model::central_differences(before.signals.p_base_sensor_m.data(),
                                 centre.signals.p_base_sensor_m.data(),
                                 after.signals.p_base_sensor_m.data(), 3, before.t_s, centre.t_s,
                                 after.t_s, kinematics.v_base_sensor_mps.data(), nullptr);
    }
  }
  infer::Wrench predicted;
  const infer::Path path = use_network_ ? infer::Path::quantised : infer::Path::physics_only;
  const infer::Status st =
      inference_.evaluate(path, centre.signals, physics_imu, predicted, &kinematics);
  record_.model_status = st.code;
  record_.t_eval_s = centre.t_s;
  record_.wrench_at_eval = centre.wrench;
  if (!st.written()) {
    set_zero(record_.predicted);
    set_zero(record_.contact);
    return false;
  }
  if (st.code == infer::StatusCode::saturated) {
    flags |= kModelSaturated;
    ++counters_.model_saturated;
  }
  for (int k = 0; k < 6; ++k) {
    record_.predicted[k] = predicted[k];
    record_.contact[k] = centre.wrench[k] - predicted[k];
  }
  // A held sensor value is stale while the other inputs (pose, the other sensor) are fresh:
  // measured − predicted would then be a contact nobody applied (the motion of the last cycles
  // missing from one side). Such a row drives nothing: zero contact, the body coasts.
  if (centre.held != 0) {
    flags |= kContactHeld;
    set_zero(record_.contact);
  }
  return true;
}

void Cycle::run_zero_g(double dt, CycleReply& reply) noexcept {
  const Eigen::Vector3d F(record_.contact[0], record_.contact[1], record_.contact[2]);
  const Eigen::Vector3d M(record_.contact[3], record_.contact[4], record_.contact[5]);
  control::PoseCorrection c;
  record_.limit_flags = motion_.step(F, M, dt, c);
  if ((record_.limit_flags & (control::kForceOverLimit | control::kTorqueOverLimit)) != 0) {
    raise(Fault::contact_over_limit);
    return;
  }
  const Eigen::Vector3d abc =
      model::kuka_abc_from_rotation(model::rotation_from_vector(Eigen::Vector3d(c.rotation_rad)));
  reply.rkorr = proto::rsi::correction_from_si(
      {c.translation_m[0], c.translation_m[1], c.translation_m[2]}, {abc[0], abc[1], abc[2]});
}

void Cycle::run_collection(double dt, std::uint32_t& flags, CycleReply& reply) noexcept {
  reply.axis = true;
  std::array<double, 6> delta{};
  if (!collection_on_path_) {
    // Approach the path's first point: per axis, brake-distance law v = √(2 a d), ramped.
    const std::array<double, 6> target = path_->at(0.0);
    bool arrived = true;
    for (int k = 0; k < 6; ++k) {
      const double d = target[k] - collection_cmd_rad_[k];
      const double v_des =
          std::copysign(std::min(config_.approach_speed_radps,
                                 std::sqrt(2.0 * config_.approach_accel_radps2 * std::abs(d))),
                        d);
      const double dv =
          std::clamp(v_des - collection_v_radps_[k], -config_.approach_accel_radps2 * dt,
                     config_.approach_accel_radps2 * dt);
      collection_v_radps_[k] += dv;
      delta[k] = collection_v_radps_[k] * dt;
      if (std::abs(delta[k]) > std::abs(d)) delta[k] = d;
      if (std::abs(d - delta[k]) > 1e-6) arrived = false;
    }
    if (arrived) collection_on_path_ = true;
  } else {
    collection_t_s_ += dt;
    const std::array<double, 6> target = path_->at(collection_t_s_);
    for (int k = 0; k < 6; ++k) delta[k] = target[k] - collection_cmd_rad_[k];
    if (collection_t_s_ >= path_->duration_s()) {
      sm_.command(Command::stop, cycle_);
      flags |= kCollectionDone;
    }
  }
  for (int k = 0; k < 6; ++k) {
    delta[k] = std::clamp(delta[k], -config_.max_axis_step_rad, config_.max_axis_step_rad);
    collection_cmd_rad_[k] += delta[k];
    reply.akorr_deg[k] = delta[k] / proto::rsi::kRadPerDeg;
  }
}

void Cycle::step(const proto::rsi::RobotMessage& m, CycleReply& reply) noexcept {
  reply = CycleReply{};
  reply.ipoc = m.ipoc;
  ++cycle_;
  ++counters_.messages;
  std::uint32_t flags = 0;
  record_.cycle = cycle_;
  record_.ipoc = m.ipoc;
  record_.limit_flags = 0;
  record_.axis_reply = false;
  take_proposal();

  if (!configured_) {
    robot_lost_run_ = 0;
    raise(Fault::model_invalid);
    record_.state = sm_.state();
    record_.fault = sm_.fault();
    return;
  }
  if (!m.has_actual_pose && !config_.robot) {
    pose_missing();
    return;
  }
  robot_lost_run_ = 0;

  // Robot time. Duplicates and reordered datagrams are answered (zero) and change nothing.
  double dt = config_.period_s;
  if (!have_ipoc_) {
    have_ipoc_ = true;
    first_ipoc_ = last_ipoc_ = m.ipoc;
  } else if (m.ipoc <= last_ipoc_) {
    ++counters_.ipoc_stale;
    record_.flags = kIpocStale;
    record_.rkorr = reply.rkorr;
    record_.state = sm_.state();
    record_.fault = sm_.fault();
    box_.push(record_);
    return;
  } else {
    dt = static_cast<double>(m.ipoc - last_ipoc_) * config_.ipoc_unit_s;
    const long periods = std::lround(dt / config_.period_s);
    if (periods > 1) {
      flags |= kIpocGap;
      ++counters_.ipoc_gaps;
      counters_.datagrams_lost += static_cast<std::uint64_t>(periods - 1);
      const State s = sm_.state();
      if ((s == State::zero_g || s == State::collecting) &&
          periods - 1 >= config_.watchdog.robot_fault_cycles)
        raise(Fault::robot_late);
    }
    // A long gap must not throw the virtual body: at most four periods per step.
    dt = std::min(dt, 4.0 * config_.period_s);
    last_ipoc_ = m.ipoc;
  }
  const State active_state = sm_.state();
  const bool active = active_state == State::zero_g || active_state == State::collecting;
  if (m.has_delay) {
    if (have_delay_ && m.delay > last_delay_) {
      flags |= kRobotDelayGrew;
      ++robot_late_run_;
    } else {
      robot_late_run_ = 0;
    }
    have_delay_ = true;
    last_delay_ = m.delay;
    if (active && robot_late_run_ >= config_.watchdog.robot_late_cycles) raise(Fault::robot_late);
  }

  // This cycle's row.
  Row& now = rows_[rows_total_ % kHistory];
  const Row* previous = rows_total_ > 0 ? &rows_[(rows_total_ - 1) % kHistory] : nullptr;
  now.signals.joints_rad = proto::rsi::joints_to_rad(m.joints_deg);
  for (int k = 0; k < 6; ++k) {
    now.signals.joint_vel_radps[k] =
        previous ? (now.signals.joints_rad[k] - previous->signals.joints_rad[k]) / dt : 0.0;
  }
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  sensor_pose(m, now.signals.joints_rad, R, p, flags);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) now.signals.R_base_sensor[3 * r + c] = R(r, c);
    now.signals.p_base_sensor_m[r] = p[r];
  }
  now.signals.temperature_C = config_.temperature_C;
  now.t_s = static_cast<double>(m.ipoc - first_ipoc_) * config_.ipoc_unit_s;
  now.signals.t_s = now.t_s;

  // Sensors: the mean of this cycle's valid samples, or hold the last one.
  if (window_.ft_n > 0) {
    for (int k = 0; k < 6; ++k) last_wrench_[k] = window_.ft_sum[k] / window_.ft_n;
    have_ft_ = true;
    ft_bad_run_ = 0;
    ft_bad_reason_ = Fault::ft_stale;
    counters_.ft_samples += static_cast<std::uint64_t>(window_.ft_n);
    if (window_.ft_warning > 0) flags |= kFtWarning;
  } else {
    flags |= kFtHeld;
    ++counters_.ft_held_cycles;
    if (ft_bad_run_ == 0 || ft_bad_reason_ == Fault::ft_stale) {
      ft_bad_reason_ = window_.ft_critical > 0    ? Fault::ft_critical
                       : window_.ft_saturated > 0 ? Fault::ft_saturated
                                                  : Fault::ft_stale;
    }
    // Before the first valid sample the cycle is only not ready (zero-g cannot be enabled);
    // invalid samples (critical, saturated) count from the start.
    const bool counts = have_ft_ || ft_bad_reason_ != Fault::ft_stale;
    if (counts && ++ft_bad_run_ >= config_.watchdog.ft_fault_cycles) raise(ft_bad_reason_);
  }
  if (window_.imu_n > 0) {
    for (int k = 0; k < 6; ++k) last_imu_[k] = window_.imu_sum[k] / window_.imu_n;
    have_imu_ = true;
    imu_bad_run_ = 0;
    counters_.imu_samples += static_cast<std::uint64_t>(window_.imu_n);
  } else {
    flags |= kImuHeld;
    ++counters_.imu_held_cycles;
    if (have_imu_ && ++imu_bad_run_ >= config_.watchdog.imu_fault_cycles) raise(Fault::imu_stale);
  }
  now.held = flags & (kFtHeld | kImuHeld);
  record_.ft_samples = static_cast<std::uint16_t>(window_.ft_n);
  record_.imu_samples = static_cast<std::uint16_t>(window_.imu_n);
  window_ = Window{};
  now.wrench = last_wrench_;
  for (int k = 0; k < 6; ++k) now.signals.imu[k] = last_imu_[k];
  for (int k = 6; k < 9; ++k) now.signals.imu[k] = 0.0;
  ++rows_total_;

  // The model, on the row delay_rows() back.
  const bool rows_ready = rows_total_ >= static_cast<std::uint64_t>(2 * delay_rows() + 1);
  bool ready = rows_ready && have_ft_ && have_imu_;
  if (ready) {
    if (evaluate(flags)) {
      model_bad_run_ = 0;
    } else {
      ready = false;
      if (++model_bad_run_ >= config_.watchdog.model_fault_cycles) raise(Fault::model_invalid);
    }
  } else {
    flags |= kNotReady;
    set_zero(record_.predicted);
    set_zero(record_.contact);
  }
  ready = ready && (flags & (kFtHeld | kImuHeld)) == 0;

  apply_command(cycle_, now, ready, flags);
  switch (sm_.state()) {
    case State::idle: {
      motion_.reset(Eigen::Map<const Eigen::Vector3d>(now.signals.p_base_sensor_m.data()),
                    Eigen::Quaterniond(R));
      break;
    }
    case State::zero_g:
      if (record_.model_status == infer::StatusCode::ok ||
          record_.model_status == infer::StatusCode::saturated) {
        run_zero_g(dt, reply);
      }
      break;
    case State::collecting:
      run_collection(dt, flags, reply);
      break;
    case State::fault:
      break;
  }
  if (sm_.state() == State::fault) {
    reply.axis = false;
    reply.rkorr = proto::rsi::Correction{};
    set_zero(reply.akorr_deg);
  }

  // The record.
  record_.t_s = now.t_s;
  record_.dt_s = dt;
  record_.flags = flags;
  record_.state = sm_.state();
  record_.fault = sm_.fault();
  record_.joints_rad = now.signals.joints_rad;
  record_.p_base_sensor_m = Eigen::Map<const Eigen::Vector3d>(now.signals.p_base_sensor_m.data());
  record_.q_base_sensor = Eigen::Quaterniond(R);
  record_.wrench_measured = now.wrench;
  for (int k = 0; k < 3; ++k) {
    record_.specific_force_imu[k] = now.signals.imu[k];
    record_.rate_imu[k] = now.signals.imu[3 + k];
  }
  record_.axis_reply = reply.axis;
  record_.rkorr = reply.rkorr;
  record_.akorr_deg = reply.akorr_deg;
  record_.body = motion_.body().state();
  record_.compute_ns = 0;
  box_.push(record_);
  if (freeze_pending_) {
    box_.freeze();
    freeze_pending_ = false;
  }
}

}  // namespace zerog::loop
