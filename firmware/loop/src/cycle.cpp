#include "zerog/loop/cycle.hpp"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

namespace zerog::loop {
namespace {

bool positive_finite(double x) { return std::isfinite(x) && x > 0.0; }

// Internal values of Cycle::proposal_state_ besides the ProposalStatus ones.
constexpr std::uint8_t kProposalWriting = 100;  // the proposer is filling proposal_
constexpr std::uint8_t kProposalTaking = 101;   // the cycle is reading proposal_

constexpr std::uint8_t status_byte(ProposalStatus s) { return static_cast<std::uint8_t>(s); }

}  // namespace

TunablesCheck check_tunables(const Tunables& t) noexcept {
  if (!positive_finite(t.body.mass_kg)) return {"body.mass_kg", "must be positive"};
  const Eigen::Matrix3d& I = t.body.inertia_body_kgm2;
  if (!I.allFinite() || (I - I.transpose()).norm() > 1e-9 * I.norm() ||
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(I, Eigen::EigenvaluesOnly)
              .eigenvalues()
              .minCoeff() <= 0.0)
    return {"body.inertia_body_kgm2", "must be symmetric positive definite"};
  if (!t.p_sensor_com_m.allFinite()) return {"p_sensor_com_m", "must be finite"};
  const control::MotionLimits& l = t.limits;
  if (!(l.force_deadband_N >= 0.0)) return {"limits.force_deadband_N", "must be zero or positive"};
  if (!(l.torque_deadband_Nm >= 0.0))
    return {"limits.torque_deadband_Nm", "must be zero or positive"};
  if (l.contact_confirm_cycles < 1) return {"limits.contact_confirm_cycles", "must be at least 1"};
  if (!(l.contact_release_fraction >= 0.0 && l.contact_release_fraction <= 1.0))
    return {"limits.contact_release_fraction", "must be in 0..1"};
  const std::pair<const char*, double> positive[] = {
      {"limits.max_contact_force_N", l.max_contact_force_N},
      {"limits.max_contact_torque_Nm", l.max_contact_torque_Nm},
      {"limits.max_speed_mps", l.max_speed_mps},
      {"limits.max_angular_speed_radps", l.max_angular_speed_radps},
      {"limits.max_accel_mps2", l.max_accel_mps2},
      {"limits.max_angular_accel_radps2", l.max_angular_accel_radps2}};
  for (const auto& [setting, value] : positive) {
    if (!positive_finite(value)) return {setting, "must be positive"};
  }
  if (!(l.force_deadband_N < l.max_contact_force_N))
    return {"limits.force_deadband_N", "must be below max_contact_force_N"};
  if (!(l.torque_deadband_Nm < l.max_contact_torque_Nm))
    return {"limits.torque_deadband_Nm", "must be below max_contact_torque_Nm"};
  if (!(l.linear_damping_per_s >= 0.0 && std::isfinite(l.linear_damping_per_s)))
    return {"limits.linear_damping_per_s", "must be zero or positive"};
  if (!(l.angular_damping_per_s >= 0.0 && std::isfinite(l.angular_damping_per_s)))
    return {"limits.angular_damping_per_s", "must be zero or positive"};
  if (!(l.contact_lowpass_hz >= 0.0 && std::isfinite(l.contact_lowpass_hz)))
    return {"limits.contact_lowpass_hz", "must be zero (off) or positive"};
  if (!l.workspace_min_m.allFinite()) return {"limits.workspace_min_m", "must be finite"};
  if (!l.workspace_max_m.allFinite()) return {"limits.workspace_max_m", "must be finite"};
  if (!(l.workspace_min_m.array() < l.workspace_max_m.array()).all())
    return {"limits.workspace_max_m", "must be above workspace_min_m on every axis"};
  return {};
}

Status check_config(const CycleConfig& c) {
  if (!positive_finite(c.period_s))
    return Status::invalid("period_s", "must be a positive number of seconds");
  if (!positive_finite(c.ipoc_unit_s))
    return Status::invalid("ipoc_unit_s", "must be a positive number of seconds");
  if (!(c.tare_s >= 0.0 && c.tare_s <= 60.0))
    return Status::invalid("tare_s", "must be 0 (off) to 60 s");
  if (c.angular_accel_order != 2 && c.angular_accel_order != 4)
    return Status::invalid("angular_accel_order",
                           "must be 2 or 4, is " + std::to_string(c.angular_accel_order));
  const WatchdogConfig& w = c.watchdog;
  for (const auto& [setting, cycles] :
       {std::pair{"watchdog.ft_fault_cycles", w.ft_fault_cycles},
        std::pair{"watchdog.imu_fault_cycles", w.imu_fault_cycles},
        std::pair{"watchdog.robot_fault_cycles", w.robot_fault_cycles},
        std::pair{"watchdog.robot_late_cycles", w.robot_late_cycles},
        std::pair{"watchdog.model_fault_cycles", w.model_fault_cycles}}) {
    if (cycles < 1)
      return Status::invalid(setting, "must be at least 1, is " + std::to_string(cycles));
  }
  if (const TunablesCheck t = check_tunables({c.body, c.limits, c.p_sensor_com_m}); !t.ok())
    return Status::invalid(t.setting, t.message);
  for (const auto& [setting, value] : {std::pair{"max_axis_step_rad", c.max_axis_step_rad},
                                       std::pair{"approach_speed_radps", c.approach_speed_radps},
                                       std::pair{"approach_accel_radps2", c.approach_accel_radps2},
                                       std::pair{"pose_check_position_m", c.pose_check_position_m},
                                       std::pair{"pose_check_angle_rad", c.pose_check_angle_rad}}) {
    if (!positive_finite(value)) return Status::invalid(setting, "must be positive");
  }
  if (Status st = check_estimator_config(c.motion); !st.ok()) return std::move(st).within("motion");
  if (c.robot) {
    if (Status st = robot::validate(*c.robot); !st.ok()) return std::move(st).within("robot");
    if (c.robot->joint_count != 6)
      return Status::invalid("robot.joint_count",
                             "RSI reports 6 axes (AIPos A1..A6); the robot has " +
                                 std::to_string(c.robot->joint_count));
  }
  return {};
}

Status Cycle::configure(const CycleConfig& config, infer::DeployedModel model) {
  if (Status st = check_config(config); !st.ok()) return st;
  const bool network = model.network.has_value();
  if (Status st = inference_.configure(std::move(model)); !st.ok())
    return std::move(st).within("model");
  const infer::RigDescription& rig = inference_.model().rig;
  if (Status st = data_.model.estimator.configure(
          config.motion, rig.q_sensor_imu.toRotationMatrix(), rig.p_sensor_imu_m, config.robot);
      !st.ok())
    return std::move(st).within("motion");
  config_ = config;
  use_network_ = network;
  motion_ = control::ZeroGMotion(config.body, config.limits, config.p_sensor_com_m);
  configured_ = true;
  return {};
}

void Cycle::add_ft(const samples::FtSample& s) noexcept {
  stages::SensorWindow& window = data_.window;
  if (s.temperature_valid) {  // read apart from the gauges: good even when the gauges are not
    window.have_temperature = true;
    window.temperature_C = s.temperature_C;
    window.temperature_age_s = s.temperature_age_s;
    window.temperature_stale = false;
  } else if (s.temperature_stale) {  // the sensor's reading is too old: not to be used any more
    window.have_temperature = false;
    window.temperature_stale = true;
  }
  if (!s.valid) {
    ++counters_.ft_invalid;
    if (s.status == samples::FtSampleStatus::critical) ++window.ft_critical;
    if (s.status == samples::FtSampleStatus::saturated) ++window.ft_saturated;
    return;
  }
  if (window.ft_n >= stages::kMaxWindow) {
    ++counters_.sample_overflow;
    return;
  }
  for (int k = 0; k < 6; ++k) window.ft_sum[k] += s.wrench_si[k];
  ++window.ft_n;
  if (s.status == samples::FtSampleStatus::warning) ++window.ft_warning;
}

void Cycle::add_imu(const samples::ImuSample& s) noexcept {
  stages::SensorWindow& window = data_.window;
  if (!s.rate_valid || !s.accel_valid) {
    ++counters_.imu_invalid;
    return;
  }
  if (window.imu_n >= stages::kMaxWindow) {
    ++counters_.sample_overflow;
    return;
  }
  for (int k = 0; k < 3; ++k) {
    window.imu_sum[k] += s.accel_m_s2[k];
    window.imu_sum[3 + k] += s.rate_rad_s[k];
  }
  ++window.imu_n;
}

void Cycle::set_compute_ns(std::int64_t ns) noexcept {
  record_->compute_ns = ns;
  if (box_.size() > 0 && box_.newest().cycle == record_->cycle) box_.newest().compute_ns = ns;
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
  if (f == Fault::none || sm_.state() == State::fault) return;
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
  } else if (!check_tunables(proposal_).ok()) {
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

void Cycle::raise_all(const stages::FaultRequests& requests) noexcept {
  for (int i = 0; i < requests.count; ++i) raise(requests.faults[static_cast<std::size_t>(i)]);
}

stages::PendingCommand Cycle::take_command() noexcept {
  const std::uint64_t p = pending_.exchange(0, std::memory_order_acq_rel);
  if (p == 0) return {};
  return {true, static_cast<Command>((p & 0xffu) - 1), p >> 8};
}

void Cycle::publish_outcome(const stages::PendingCommand& c, bool accepted) noexcept {
  if (!c.present) return;
  outcomes_[c.ticket % kCommandOutcomes].store(c.ticket << 2 | (accepted ? 1u : 2u),
                                               std::memory_order_release);
}

void Cycle::robot_lost(RobotLoss why) noexcept {
  take_proposal();
  if (why == RobotLoss::timeout) {
    ++counters_.robot_timeouts;
  } else {
    ++counters_.robot_malformed;
  }
  if (!data_.clock.have_ipoc) return;  // the robot has not started its RSI session yet
  grow_lost_run();
  push_lost_record(kRobotLost);
}

void Cycle::pose_missing() noexcept {
  ++counters_.poses_missing;
  if (data_.clock.have_ipoc) grow_lost_run();
  push_lost_record(kPoseMissing);
}

void Cycle::stale_message() noexcept {
  record_->flags = kIpocStale;
  record_->state = sm_.state();
  record_->fault = sm_.fault();
  if (!box_.frozen()) box_.commit();  // kept; a pending freeze waits for keep_record()
}

void Cycle::grow_lost_run() noexcept {
  ++data_.watchdogs.robot_lost_run;
  const State s = sm_.state();
  if ((s == State::zero_g || s == State::collecting) &&
      data_.watchdogs.robot_lost_run >= config_.watchdog.robot_fault_cycles) {
    raise(Fault::robot_late);
  }
}

void Cycle::push_lost_record(std::uint32_t flags) noexcept {
  CycleRecord& record = open_record(true, true);
  record.flags = flags;
  record.state = sm_.state();
  record.fault = sm_.fault();
  keep_record();
}

CycleRecord& Cycle::open_record(bool kept, bool carry) noexcept {
  CycleRecord& record = kept && !box_.frozen() ? box_.next() : spare_;
  if (carry && &record != record_) record = *record_;
  record_ = &record;
  return record;
}

void Cycle::keep_record() noexcept {
  if (!box_.frozen()) box_.commit();
  if (freeze_pending_) {
    box_.freeze();
    freeze_pending_ = false;
  }
}

samples::RobotCorrection Cycle::zero_reply(std::uint64_t ipoc) const noexcept {
  // A session with a collection path talks AKorr throughout, zeros when not moving: the
  // controller's context for it (an AXISCORR object) takes AKorr and nothing else
  // (firmware/rt/deploy/kuka/README.md, "Calibration collection"). Otherwise RKorr zeros.
  samples::RobotCorrection c;
  c.ipoc = ipoc;
  if (path_ != nullptr) c.kind = samples::RobotCorrection::Kind::axes;
  return c;
}

void Cycle::step(const samples::RobotSample& m, samples::RobotCorrection& correction) noexcept {
  run(m);
  correction = record_->reply;
}

void Cycle::run(const samples::RobotSample& m) noexcept {
  // The answer is the record's reply (the record keeps the reply sent). A cycle that ends early
  // answers a zero correction with this IPOC (and keeps the last record's other fields); the
  // full cycle, run_motion's correction. The record is written where it is kept (open_record).
  const auto open_early = [this, &m](bool kept) noexcept -> CycleRecord& {
    CycleRecord& record = open_record(kept, true);
    record.cycle = cycle_;
    record.ipoc = m.ipoc;
    record.limit_flags = 0;
    record.reply = zero_reply(m.ipoc);
    return record;
  };
  ++cycle_;
  ++counters_.messages;
  take_proposal();

  if (!configured_) {
    CycleRecord& record = open_early(false);  // not into the black box
    data_.watchdogs.robot_lost_run = 0;
    raise(Fault::model_invalid);
    record.state = sm_.state();
    record.fault = sm_.fault();
    return;
  }
  if (!m.has_pose && !config_.robot) {
    open_early(true);
    pose_missing();
    return;
  }
  data_.watchdogs.robot_lost_run = 0;

  const State state_before = sm_.state();
  const stages::Timing timing = stages::timing(config_, m, data_.clock, counters_);
  if (timing.stale) {
    open_early(true);
    stale_message();
    return;
  }
  const stages::RowResult row =
      stages::assemble_row(config_, m, timing, data_.window, data_.rows, counters_);
  raise_all(stages::watch_robot_and_sensors(config_.watchdog, state_before, timing, row.sensors,
                                            data_.rows, data_.watchdogs));
  stages::ModelResult model =
      stages::evaluate_model(config_, inference_, use_network_, data_.rows, data_.model, counters_);
  raise_all(stages::watch_model(config_.watchdog, model, data_.watchdogs));
  const stages::PendingCommand command = take_command();
  stages::tare_contact(config_, sm_.state(),
                       command.present && command.command == Command::enable_zero_g, timing, model,
                       data_.tare);
  const stages::Row& now = data_.rows.newest();
  const stages::MotionResult motion = stages::run_motion(config_,
                                                         {.path = path_,
                                                          .cycle = cycle_,
                                                          .command = command,
                                                          .timing = timing,
                                                          .now = now,
                                                          .row = row,
                                                          .model = model,
                                                          .model_data = data_.model},
                                                         {.sm = sm_,
                                                          .zero_g = motion_,
                                                          .collection = data_.collection,
                                                          .runs = data_.watchdogs,
                                                          .counters = counters_});
  // The arm may ring beyond what its joints show after this cycle's push, limit or path: the
  // motion estimator's step 4 (motion_estimator.hpp) acts for a while after it.
  data_.model.estimator.note_excitation(motion_.in_contact() || motion.limit_flags != 0 ||
                                        sm_.state() == State::collecting);
  publish_outcome(command, motion.command_accepted);
  raise(motion.fault);
  // Every field is written below (make_record and the reply): nothing is carried over.
  CycleRecord& record = open_record(true, false);
  // In fault, every reply is a zero correction (proto/loop.md, "Watchdogs").
  if (sm_.state() == State::fault ||
      motion.correction.kind == samples::RobotCorrection::Kind::none) {
    record.reply = zero_reply(m.ipoc);
  } else {
    record.reply = motion.correction;
    record.reply.ipoc = m.ipoc;
  }
  // The motion estimator's servo model follows what the robot was told ([filter] servo_hz).
  data_.model.estimator.note_command(record.reply, now.signals.joints_rad, now.t_s,
                                     config_.period_s);
  stages::make_record({.cycle = cycle_,
                       .message = m,
                       .timing = timing,
                       .now = now,
                       .row = row,
                       .model = model,
                       .model_data = data_.model,
                       .motion = motion,
                       .sm = sm_,
                       .zero_g = motion_},
                      record);
  keep_record();
}

}  // namespace zerog::loop
