// The stages of one cycle (cycle.hpp, namespace stages). Each reads the configuration and its
// inputs, updates its own part of CycleData and returns what it decided.
#include <algorithm>
#include <cmath>

#include "zerog/loop/cycle.hpp"
#include "zerog/model/dictionary.hpp"
#include "zerog/model/rotation.hpp"
#include "zerog/model/signals.hpp"
#include "zerog/robot/forward_kinematics.hpp"

namespace zerog::loop::stages {
namespace {

template <std::size_t N>
void set_zero(std::array<double, N>& a) {
  a.fill(0.0);
}

const Row& row_back(const RowData& rows, int back) {
  return rows.rows[(rows.total - 1 - static_cast<std::uint64_t>(back)) % kHistory];
}

// S in B for this message: RIst, or the kinematics of the joints; checks one against the other.
// (assemble_row has not been called for a message with neither: Cycle::step answers it as
// kPoseMissing.)
void sensor_pose(const CycleConfig& config, const samples::RobotSample& m,
                 const std::array<double, 6>& q_rad, Eigen::Matrix3d& R_base_sensor,
                 Eigen::Vector3d& p_base_sensor_m, RowResult& out,
                 CycleCounters& counters) noexcept {
  if (m.has_pose) {
    R_base_sensor =
        Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(m.R_base_tcp.data());
    p_base_sensor_m = Eigen::Map<const Eigen::Vector3d>(m.p_base_tcp_m.data());
  }
  if (!config.robot) return;
  const robot::Pose kinematics = robot::sensor_pose(*config.robot, q_rad);
  if (!m.has_pose) {
    R_base_sensor = kinematics.R;
    p_base_sensor_m = kinematics.p_m;
    out.flags |= kPoseFromJoints;
    ++counters.poses_from_joints;
    return;
  }
  out.pose_check_m = (p_base_sensor_m - kinematics.p_m).norm();
  out.pose_check_rad =
      Eigen::AngleAxisd(Eigen::Matrix3d(R_base_sensor.transpose() * kinematics.R)).angle();
  if (out.pose_check_m > config.pose_check_position_m ||
      out.pose_check_rad > config.pose_check_angle_rad) {
    out.flags |= kPoseDisagrees;
    ++counters.pose_disagreements;
  }
}

// Collection mode: the axis correction of this cycle (rad).
std::array<double, 6> follow_path(const CycleConfig& config, const JointPath& path, double dt,
                                  std::uint64_t cycle, StateMachine& sm, CollectionData& collection,
                                  std::uint32_t& flags) noexcept {
  std::array<double, 6> delta{};
  if (!collection.on_path) {
    // Approach the path's first point: per axis, brake-distance law v = √(2 a d), ramped.
    const std::array<double, 6> target = path.at(0.0);
    bool arrived = true;
    for (int k = 0; k < 6; ++k) {
      const double d = target[k] - collection.cmd_rad[k];
      const double v_des =
          std::copysign(std::min(config.approach_speed_radps,
                                 std::sqrt(2.0 * config.approach_accel_radps2 * std::abs(d))),
                        d);
      const double dv =
          std::clamp(v_des - collection.v_radps[k], -config.approach_accel_radps2 * dt,
                     config.approach_accel_radps2 * dt);
      collection.v_radps[k] += dv;
      delta[k] = collection.v_radps[k] * dt;
      if (std::abs(delta[k]) > std::abs(d)) delta[k] = d;
      if (std::abs(d - delta[k]) > 1e-6) arrived = false;
    }
    if (arrived) collection.on_path = true;
  } else {
    collection.t_s += dt;
    const std::array<double, 6> target = path.at(collection.t_s);
    for (int k = 0; k < 6; ++k) delta[k] = target[k] - collection.cmd_rad[k];
    if (collection.t_s >= path.duration_s()) {
      sm.command(Command::stop, cycle);
      flags |= kCollectionDone;
    }
  }
  for (int k = 0; k < 6; ++k) {
    delta[k] = std::clamp(delta[k], -config.max_axis_step_rad, config.max_axis_step_rad);
    collection.cmd_rad[k] += delta[k];
  }
  return delta;
}

}  // namespace

Timing timing(const CycleConfig& config, const samples::RobotSample& m, ClockData& clock,
              CycleCounters& counters) noexcept {
  // Duplicates and reordered datagrams are answered (zero) and change nothing.
  Timing out;
  out.dt_s = config.period_s;
  if (!clock.have_ipoc) {
    clock.have_ipoc = true;
    clock.first_ipoc = clock.last_ipoc = m.ipoc;
  } else if (m.ipoc <= clock.last_ipoc) {
    ++counters.ipoc_stale;
    out.stale = true;
    out.flags = kIpocStale;
    return out;
  } else {
    double dt = static_cast<double>(m.ipoc - clock.last_ipoc) * config.ipoc_unit_s;
    const long periods = std::lround(dt / config.period_s);
    if (periods > 1) {
      out.flags |= kIpocGap;
      out.lost_periods = static_cast<std::uint64_t>(periods - 1);
      ++counters.ipoc_gaps;
      counters.datagrams_lost += out.lost_periods;
    }
    // A long gap must not throw the virtual body: at most four periods per step.
    out.dt_s = std::min(dt, 4.0 * config.period_s);
    clock.last_ipoc = m.ipoc;
  }
  if (m.has_delay) {
    out.has_delay = true;
    out.delay_grew = clock.have_delay && m.delay > clock.last_delay;
    if (out.delay_grew) out.flags |= kRobotDelayGrew;
    clock.have_delay = true;
    clock.last_delay = m.delay;
  }
  // The double nearest the robot's time: n units / (units per second) when a second is a whole
  // number of units (KUKA: 1000 ms), a correctly rounded division. n · 0.001 is one ulp off in
  // one cycle of seven (0.036000000000000004), which a nanosecond ROS header stamp cannot carry
  // back (proto/ros2_bags.md, "MCAP from a recording").
  const double n = static_cast<double>(m.ipoc - clock.first_ipoc);
  const double units_per_s = 1.0 / config.ipoc_unit_s;
  out.t_s = units_per_s == std::nearbyint(units_per_s) ? n / units_per_s : n * config.ipoc_unit_s;
  return out;
}

RowResult assemble_row(const CycleConfig& config, const samples::RobotSample& m,
                       const Timing& timing, SensorWindow& window, RowData& rows,
                       CycleCounters& counters) noexcept {
  RowResult out;
  Row& now = rows.rows[rows.total % kHistory];
  const Row* previous = rows.total > 0 ? &rows.rows[(rows.total - 1) % kHistory] : nullptr;
  now.signals.joints_rad = m.joints_rad;
  for (int k = 0; k < 6; ++k) {
    now.signals.joint_vel_radps[k] =
        previous ? (now.signals.joints_rad[k] - previous->signals.joints_rad[k]) / timing.dt_s
                 : 0.0;
  }
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  sensor_pose(config, m, now.signals.joints_rad, out.R_base_sensor, p, out, counters);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) now.signals.R_base_sensor[3 * r + c] = out.R_base_sensor(r, c);
    now.signals.p_base_sensor_m[r] = p[r];
  }
  // The F/T sensor's own temperature wins over the configured one, and is held between its
  // readings (about 1 Hz; the temperature moves slowly), until the sensor says it is stale
  // (older than its maximum age): then the configured one again, flagged, until a fresh one.
  if (window.have_temperature) {
    rows.have_temperature = true;
    rows.temperature_C = window.temperature_C;
    rows.temperature_age_s = window.temperature_age_s;
    rows.temperature_stale = false;
  } else if (window.temperature_stale) {
    rows.have_temperature = false;
    rows.temperature_age_s = 0.0;
    rows.temperature_stale = true;
  }
  if (rows.temperature_stale) {
    out.flags |= kTemperatureStale;
    ++counters.temperature_stale_cycles;
  }
  now.signals.temperature_C = rows.have_temperature ? rows.temperature_C : config.temperature_C;
  now.temperature_measured = rows.have_temperature;
  now.temperature_age_s = rows.temperature_age_s;
  now.t_s = timing.t_s;
  now.signals.t_s = now.t_s;

  // Sensors: the mean of this cycle's valid samples, or hold the last one.
  if (window.ft_n > 0) {
    for (int k = 0; k < 6; ++k) rows.last_wrench[k] = window.ft_sum[k] / window.ft_n;
    rows.have_ft = true;
    counters.ft_samples += static_cast<std::uint64_t>(window.ft_n);
    if (window.ft_warning > 0) out.flags |= kFtWarning;
  } else {
    out.flags |= kFtHeld;
    ++counters.ft_held_cycles;
  }
  if (window.imu_n > 0) {
    for (int k = 0; k < 6; ++k) rows.last_imu[k] = window.imu_sum[k] / window.imu_n;
    rows.have_imu = true;
    counters.imu_samples += static_cast<std::uint64_t>(window.imu_n);
  } else {
    out.flags |= kImuHeld;
    ++counters.imu_held_cycles;
  }
  now.held = out.flags & (kFtHeld | kImuHeld);
  now.ft_n = window.ft_n;
  now.imu_n = window.imu_n;
  out.sensors = {window.ft_n, window.ft_critical, window.ft_saturated, window.imu_n};
  window = SensorWindow{};
  now.wrench = rows.last_wrench;
  for (int k = 0; k < 6; ++k) now.signals.imu[k] = rows.last_imu[k];
  for (int k = 6; k < 9; ++k) now.signals.imu[k] = 0.0;
  ++rows.total;
  return out;
}

FaultRequests watch_robot_and_sensors(const WatchdogConfig& config, State state,
                                      const Timing& timing, const SensorCounts& sensors,
                                      const RowData& rows, WatchdogData& runs) noexcept {
  FaultRequests out;
  const bool active = state == State::zero_g || state == State::collecting;
  // Robot: datagrams lost in one gap, or replies late for several messages in a row.
  if (active && timing.lost_periods >= static_cast<std::uint64_t>(config.robot_fault_cycles))
    out.add(Fault::robot_late);
  if (timing.has_delay) {
    runs.robot_late_run = timing.delay_grew ? runs.robot_late_run + 1 : 0;
    if (active && runs.robot_late_run >= config.robot_late_cycles) out.add(Fault::robot_late);
  }
  // F/T: cycles in a row without a valid sample, for the first reason seen.
  if (sensors.ft_n > 0) {
    runs.ft_bad_run = 0;
    runs.ft_bad_reason = Fault::ft_stale;
  } else {
    if (runs.ft_bad_run == 0 || runs.ft_bad_reason == Fault::ft_stale) {
      runs.ft_bad_reason = sensors.ft_critical > 0    ? Fault::ft_critical
                           : sensors.ft_saturated > 0 ? Fault::ft_saturated
                                                      : Fault::ft_stale;
    }
    // Before the first valid sample the cycle is only not ready (zero-g cannot be enabled);
    // invalid samples (critical, saturated) count from the start.
    const bool counts = rows.have_ft || runs.ft_bad_reason != Fault::ft_stale;
    if (counts && ++runs.ft_bad_run >= config.ft_fault_cycles) out.add(runs.ft_bad_reason);
  }
  // IMU: cycles in a row without a valid sample, once there has been one.
  if (sensors.imu_n > 0) {
    runs.imu_bad_run = 0;
  } else if (rows.have_imu && ++runs.imu_bad_run >= config.imu_fault_cycles) {
    out.add(Fault::imu_stale);
  }
  return out;
}

ModelResult evaluate_model(const CycleConfig& config, infer::Inference& inference, bool use_network,
                           RowData& rows, ModelData& model, CycleCounters& counters) noexcept {
  const int D = config.angular_accel_order / 2;
  const int n = 2 * D + 1;
  const bool rows_ready = rows.total >= static_cast<std::uint64_t>(n);
  if (!(rows_ready && rows.have_ft && rows.have_imu)) return {.flags = kNotReady};
  // Rows centre − D … centre + D (= newest), oldest first, in contiguous arrays (the first 3 n
  // values; not zeroed first, every one read is written here).
  std::array<double, 3 * 5> f, w;
  for (int j = 0; j < n; ++j) {
    const Row& r = row_back(rows, n - 1 - j);
    for (int k = 0; k < 3; ++k) {
      f[3 * j + k] = r.signals.imu[k];
      w[3 * j + k] = r.signals.imu[3 + k];
    }
  }
  Row& centre = rows.rows[(rows.total - 1 - static_cast<std::uint64_t>(D)) % kHistory];
  const Row& first = row_back(rows, 2 * D);
  const Row& last = row_back(rows, 0);
  const double row_dt = (last.t_s - first.t_s) / (2.0 * D);
  const double dt = row_dt > 0.0 ? row_dt : config.period_s;
  const Eigen::Vector3d wdot =
      model::angular_accel_central(w.data() + 3 * D, 3, config.angular_accel_order, dt);
  for (int k = 0; k < 3; ++k) centre.signals.imu[6 + k] = wdot[k];

  // The physics reads the IMU at t + tau (imu_time_offset), within the rows we have.
  model::ImuSignals<double> physics_imu;
  const double index = D + inference.imu_time_offset_s() / dt;
  physics_imu.specific_force_imu = model::interpolate_uniform<3>(f.data(), n, index);
  physics_imu.angular_rate_imu = model::interpolate_uniform<3>(w.data(), n, index);
  physics_imu.angular_accel_imu = wdot;
  // The fused path (motion_estimator.hpp): the same rows, the robot's poses and joints, the
  // IMU below the crossover. Its test mutant "one row late" takes the estimate of the row
  // before the model's (the rows c−D−1 … c+D−1) and advances on those.
  if (config.motion.source == MotionSource::fused) {
    const int late = config.motion.mutant_one_row_late ? 1 : 0;
    std::array<const model::FeatureSignals*, 5> window;
    for (int j = 0; j < n; ++j)
      window[static_cast<std::size_t>(j)] = &row_back(rows, n - 1 - j + late).signals;
    const Row& at = row_back(rows, D + late);
    if (rows.total >= static_cast<std::uint64_t>(n + late) &&
        model.estimator.update(std::span(window.data(), static_cast<std::size_t>(n)), at.wrench,
                               physics_imu, {.ft = at.ft_n, .imu = at.imu_n}, model.estimate)) {
      physics_imu = model.estimate.imu;
    }
  }

  // The signal dictionary's kinematics at the centre row (user-defined effects): central
  // differences of the joints and the sensor position over its neighbours.
  model::KinematicInputs& kinematics = model.kinematics;
  kinematics.features = centre.signals;
  {
    const Row& before = row_back(rows, D + 1);
    const Row& after = row_back(rows, D - 1);
    if (!(after.t_s > centre.t_s && centre.t_s > before.t_s)) {
      set_zero(kinematics.joint_acc_radps2);
      set_zero(kinematics.v_base_sensor_mps);
    } else {
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
  const infer::Path path = use_network ? infer::Path::quantised : infer::Path::physics_only;
  const infer::Status st =
      inference.evaluate(path, centre.signals, physics_imu, predicted, &kinematics);
  model.status = st.code;
  model.t_eval_s = centre.t_s;
  model.wrench_at_eval = centre.wrench;
  if (!st.written()) return {.evaluated = true};
  // The result is built from its parts at the end (not a zeroed result filled in): every cycle.
  std::uint32_t flags = 0;
  if (st.code == infer::StatusCode::saturated) {
    flags |= kModelSaturated;
    ++counters.model_saturated;
  }
  std::array<double, 6> prediction, contact;
  for (int k = 0; k < 6; ++k) {
    prediction[k] = predicted[k];
    contact[k] = centre.wrench[k] - predicted[k];
  }
  // A held sensor value is stale while the other inputs (pose, the other sensor) are fresh:
  // measured − predicted would then be a contact nobody applied (the motion of the last cycles
  // missing from one side). Such a row drives nothing: zero contact, the body coasts.
  if (centre.held != 0) {
    flags |= kContactHeld;
    set_zero(contact);
  }
  // The first rows of the fused path average the IMU's share: its error is the IMU's row noise
  // × mass over √n (0.9 N per axis at one row, 100 kg), above a gate set from the settled noise.
  if (config.motion.source == MotionSource::fused && !model.estimate.settled)
    flags |= kEstimatorSettling;
  // Ready for zero-g: a prediction, and this cycle's samples fresh.
  return {.evaluated = true,
          .written = true,
          .ready = rows.newest().held == 0,
          .flags = flags,
          .predicted = prediction,
          .contact = contact};
}

void tare_contact(const CycleConfig& config, State state, bool enabling, const Timing& timing,
                  ModelResult& model, TareData& tare) noexcept {
  if (config.tare_s <= 0.0) return;
  if (state != State::zero_g) {
    tare = TareData{};
    // The row that enters zero-g steps the body too: no push confirmed on it either.
    if (enabling) model.flags |= kContactTaring;
    return;
  }
  // A held row's contact is zero (evaluate_model): the body coasts, with or without a tare.
  const bool measured = model.written && (model.flags & kContactHeld) == 0;
  if (tare.taken) {
    if (measured) {
      for (int k = 0; k < 6; ++k) model.contact[k] -= tare.offset[k];
    }
    return;
  }
  model.flags |= kContactTaring;
  if (!measured || (model.flags & kEstimatorSettling) != 0) return;
  // What the contact gate would count this row (ZeroGMotion::step's judgement, unconfirmed).
  const control::MotionLimits& limits = config.limits;
  const Eigen::Vector3d F(model.contact[0], model.contact[1], model.contact[2]);
  const Eigen::Vector3d M(model.contact[3], model.contact[4], model.contact[5]);
  const Eigen::Vector3d M_com =
      control::torque_about(M, F, Eigen::Vector3d::Zero(), config.p_sensor_com_m);
  const Eigen::Vector3d M_judged = control::torque_gate_input(M, M_com, F, limits.force_deadband_N);
  const bool over =
      F.norm() > limits.force_deadband_N || M_judged.norm() > limits.torque_deadband_Nm;
  // A row the gate would count is no part of the zero; a push the gate would confirm starts
  // the tare again once it has let go (a hand on the part).
  if (over && !config.mutant_tare_unguarded) {
    if (++tare.over_run >= limits.contact_confirm_cycles) tare = TareData{};
    return;
  }
  tare.over_run = 0;
  for (int k = 0; k < 6; ++k) tare.sum[k] += model.contact[k];
  ++tare.rows;
  tare.t_s += timing.dt_s;
  if (tare.t_s + 0.5 * timing.dt_s < config.tare_s) return;
  tare.taken = true;
  for (int k = 0; k < 6; ++k) {
    tare.offset[k] = tare.sum[k] / tare.rows;
    model.contact[k] -= tare.offset[k];
  }
  model.flags &= ~static_cast<std::uint32_t>(kContactTaring);
}

FaultRequests watch_model(const WatchdogConfig& config, const ModelResult& model,
                          WatchdogData& runs) noexcept {
  FaultRequests out;
  if (!model.evaluated) return out;
  if (model.written) {
    runs.model_bad_run = 0;
  } else if (++runs.model_bad_run >= config.model_fault_cycles) {
    out.add(Fault::model_invalid);
  }
  return out;
}

MotionResult run_motion(const CycleConfig& config, const MotionInputs& in,
                        const MotionState& state) noexcept {
  const PendingCommand& command = in.command;
  const Row& now = in.now;
  StateMachine& sm = state.sm;
  control::ZeroGMotion& motion = state.zero_g;
  CollectionData& collection = state.collection;
  MotionResult out;
  if (command.present) {
    const Command c = command.command;
    bool allowed = true;
    if (c == Command::enable_zero_g && !in.model.ready) allowed = false;
    if (c == Command::start_collection && in.path == nullptr) allowed = false;
    // A session with a collection path answers with axis corrections only (below): its RSI
    // context on the controller takes AKorr and no RKorr (firmware/rt/deploy/kuka/README.md).
    if (c == Command::enable_zero_g && in.path != nullptr) allowed = false;
    if (allowed) allowed = sm.command(c, in.cycle);
    out.command_accepted = allowed;
    if (!allowed) {
      out.flags |= kCommandRefused;
      ++state.counters.commands_refused;
    } else if (c == Command::enable_zero_g) {
      const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> R(
          now.signals.R_base_sensor.data());
      motion.reset(Eigen::Map<const Eigen::Vector3d>(now.signals.p_base_sensor_m.data()),
                   Eigen::Quaterniond(Eigen::Matrix3d(R)));
    } else if (c == Command::start_collection) {
      collection.on_path = false;
      collection.t_s = 0.0;
      collection.cmd_rad = now.signals.joints_rad;
      set_zero(collection.v_radps);
    } else if (c == Command::reset_fault) {
      WatchdogData& runs = state.runs;
      runs.robot_lost_run = runs.robot_late_run = 0;
      runs.ft_bad_run = runs.imu_bad_run = runs.model_bad_run = 0;
    }
  }
  switch (sm.state()) {
    case State::idle:
      motion.reset(Eigen::Map<const Eigen::Vector3d>(now.signals.p_base_sensor_m.data()),
                   Eigen::Quaterniond(in.row.R_base_sensor));
      break;
    case State::zero_g: {
      if (in.model_data.status != infer::StatusCode::ok &&
          in.model_data.status != infer::StatusCode::saturated)
        break;
      const Eigen::Vector3d F(in.model.contact[0], in.model.contact[1], in.model.contact[2]);
      const Eigen::Vector3d M(in.model.contact[3], in.model.contact[4], in.model.contact[5]);
      control::PoseCorrection c;
      out.limit_flags = motion.step(F, M, in.timing.dt_s, c,
                                    (in.model.flags & (kEstimatorSettling | kContactTaring)) == 0);
      if ((out.limit_flags & (control::kForceOverLimit | control::kTorqueOverLimit)) != 0) {
        out.fault = Fault::contact_over_limit;
        break;
      }
      out.correction.kind = samples::RobotCorrection::Kind::cartesian;
      out.correction.translation_m = {c.translation_m[0], c.translation_m[1], c.translation_m[2]};
      const Eigen::Matrix3d R = model::rotation_from_vector(Eigen::Vector3d(c.rotation_rad));
      for (int r = 0; r < 3; ++r) {
        for (int k = 0; k < 3; ++k) out.correction.R_correction[3 * r + k] = R(r, k);
      }
      break;
    }
    case State::collecting:
      out.correction.kind = samples::RobotCorrection::Kind::axes;
      out.correction.axes_rad =
          follow_path(config, *in.path, in.timing.dt_s, in.cycle, sm, collection, out.flags);
      break;
    case State::fault:
      break;
  }
  return out;
}

void make_record(const RecordInputs& in, CycleRecord& record) noexcept {
  const Row& now = in.now;
  const RowResult& row = in.row;
  const ModelResult& model = in.model;
  const ModelData& model_data = in.model_data;
  const MotionResult& motion = in.motion;
  record.cycle = in.cycle;
  record.ipoc = in.message.ipoc;
  record.t_s = now.t_s;
  record.dt_s = in.timing.dt_s;
  record.flags = in.timing.flags | row.flags | model.flags | motion.flags;
  record.state = in.sm.state();
  record.fault = in.sm.fault();
  record.limit_flags = motion.limit_flags;
  record.model_status = model_data.status;
  record.joints_rad = now.signals.joints_rad;
  record.p_base_sensor_m = Eigen::Map<const Eigen::Vector3d>(now.signals.p_base_sensor_m.data());
  record.q_base_sensor = Eigen::Quaterniond(row.R_base_sensor);
  record.pose_check_m = row.pose_check_m;
  record.pose_check_rad = row.pose_check_rad;
  record.wrench_measured = now.wrench;
  for (int k = 0; k < 3; ++k) {
    record.specific_force_imu[k] = now.signals.imu[k];
    record.rate_imu[k] = now.signals.imu[3 + k];
  }
  record.ft_samples = static_cast<std::uint16_t>(row.sensors.ft_n);
  record.imu_samples = static_cast<std::uint16_t>(row.sensors.imu_n);
  record.temperature_C = now.signals.temperature_C;
  record.temperature_measured = now.temperature_measured;
  record.temperature_age_s = now.temperature_age_s;
  record.t_eval_s = model_data.t_eval_s;
  record.wrench_at_eval = model_data.wrench_at_eval;
  record.predicted = model.predicted;
  record.contact = model.contact;
  record.body = in.zero_g.body().state();
  record.compute_ns = 0;
}

}  // namespace zerog::loop::stages
