#include "zerog/rt/runtime.hpp"

#include <time.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <nlohmann/json.hpp>

#include "zerog/rtio/clock.hpp"

namespace zerog::rt {

namespace {

using rtio::monotonic_ns;

void sleep_ns(std::int64_t ns) noexcept {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(ns / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(ns % 1'000'000'000);
  while (::clock_nanosleep(CLOCK_MONOTONIC, 0, &ts, &ts) == EINTR) {
  }
}

// Names of rsi::ParseStatus, in enum order (RobotLinkCounters::malformed_by_status).
constexpr const char* kParseStatusNames[] = {"ok",
                                             "too_long",
                                             "truncated",
                                             "syntax",
                                             "unsupported",
                                             "wrong_root",
                                             "unexpected_content",
                                             "too_deep",
                                             "duplicate_element",
                                             "missing_element",
                                             "missing_attribute",
                                             "unknown_attribute",
                                             "duplicate_attribute",
                                             "bad_number"};
static_assert(std::size(kParseStatusNames) == rtio::kParseStatusCount,
              "a ParseStatus was added: name it here");

nlohmann::json latency_json(const LatencyHistogram& h) {
  return {{"count", h.count()},
          {"median", h.quantile(0.5)},
          {"p99", h.quantile(0.99)},
          {"p99_9", h.quantile(0.999)},
          {"max", h.max()}};
}

template <typename Ring>
nlohmann::json ring_json(const Ring& r) {
  return {{"capacity", Ring::capacity()},
          {"pushed", r.pushed()},
          {"popped", r.popped()},
          {"dropped", r.dropped()}};
}

}  // namespace

CommandLine parse_command_line(std::string_view line) {
  const auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\r'; };
  while (!line.empty() && blank(line.back())) line.remove_suffix(1);
  while (!line.empty() && blank(line.front())) line.remove_prefix(1);
  CommandLine out;
  if (line.empty()) return out;
  out.kind = CommandLine::Kind::command;
  if (line == "enable") {
    out.command = loop::Command::enable_zero_g;
  } else if (line == "stop") {
    out.command = loop::Command::stop;
  } else if (line == "reset") {
    out.command = loop::Command::reset_fault;
  } else if (line == "collect") {
    out.command = loop::Command::start_collection;
  } else if (line == "quit") {
    out.kind = CommandLine::Kind::quit;
  } else {
    out.kind = CommandLine::Kind::unknown;
  }
  return out;
}

Runtime::Runtime(RuntimeOptions options, RuntimeDevices devices)
    : options_(std::move(options)),
      devices_(devices),
      ft_ring_(std::make_unique<FtRing>()),
      imu_ring_(std::make_unique<ImuRing>()),
      record_ring_(std::make_unique<RecordRing>()),
      popped_(std::make_unique<RecordSlot>()),
      announcer_(options_.auto_enable_zero_g, options_.auto_collect) {
  compute_window_.reserve(4096);
}

Runtime::~Runtime() { stop(); }

Status Runtime::configure(const loop::CycleConfig& config, infer::DeployedModel model,
                          const loop::JointPath* path) {
  if (devices_.robot == nullptr) return {StatusCode::not_ready, "no robot link"};
  // The model's identity, for the supervisor (proto/modbus.md) before the cycle takes the model.
  modbus::fill_model_identity(model, options_.model_file_crc32, snapshot_);
  if (options_.telemetry) {
    telemetry::TelemetryConfig t = *options_.telemetry;
    t.nominal_period_s = config.period_s;
    if (Status st = telemetry::check_config(t); !st.ok()) return std::move(st).within("telemetry");
    telemetry_ = std::make_unique<telemetry::TelemetryChannel>(
        t, telemetry::model_identity(model, options_.model_file_name, options_.model_file_crc32),
        config.body);
  }
  // loop::Cycle::configure still answers in text (its reason names what it refuses).
  if (std::string why = cycle_.configure(config, std::move(model)); !why.empty())
    return {StatusCode::invalid_setting, std::move(why)};
  configured_tunables_ = cycle_.tunables();
  supervisor_.publish(snapshot_);
  path_ = path;
  cycle_.set_collection_path(path);
  return {};
}

Status Runtime::start(std::vector<std::string>& warnings) {
  if (started_) return {StatusCode::already_started, "already started"};
  try {
    recorder_ = std::make_unique<Recorder>(options_.recorder);
  } catch (const std::exception& e) {
    return {StatusCode::system_error, e.what()};
  }
  if (telemetry_ != nullptr) {
    if (Status st = telemetry_->start(); !st.ok()) return std::move(st).within("telemetry");
  }
  if (options_.realtime.lock_memory) {
    if (std::string w = lock_memory(); !w.empty()) warnings.push_back(std::move(w));
  }
  const int priority = options_.realtime.priority;
  const int sensor_priority = priority > 1 ? priority - 1 : priority;
  std::vector<std::string> refused;
  int sched_error = 0;
  auto launch = [&](Thread& thread, const char* name, void (Runtime::*body)(), int prio,
                    int cpu) -> Status {
    ThreadSetup setup;
    Status st = thread.start(
        name, [this, body] { (this->*body)(); }, prio, cpu, setup);
    if (!st.ok()) return st;
    if (setup.sched_error != 0) {
      refused.emplace_back(name);
      sched_error = setup.sched_error;
    }
    if (setup.affinity_error != 0) {
      warnings.push_back(affinity_warning(name, cpu, setup.affinity_error));
    }
    return {};
  };
  started_ = true;
  Status error = launch(recorder_thread_, "recorder", &Runtime::recorder_loop, 0, -1);
  if (error.ok() && devices_.imu != nullptr)
    error = launch(imu_thread_, "imu", &Runtime::imu_loop, sensor_priority, -1);
  if (error.ok() && devices_.ft != nullptr)
    error = launch(ft_thread_, "ft", &Runtime::ft_loop, sensor_priority, -1);
  // Whatever robot datagrams piled up while the program started are old: the first cycle
  // starts from now (and a datagram sent after start() began is kept).
  devices_.robot->discard_queued();
  if (error.ok())
    error = launch(cycle_thread_, "cycle", &Runtime::cycle_loop, priority, options_.realtime.cpu);
  if (error.ok() && options_.modbus) {
    modbus_ = std::make_unique<modbus::ModbusServer>(*options_.modbus, *this);
    // A refused setting is named as in the file ("modbus.port"); the server's own failures
    // already say "Modbus server: …".
    Status st = modbus_->start();
    error = st.setting().empty() ? std::move(st) : std::move(st).within("modbus");
  }
  if (!refused.empty()) {
    std::string names;
    for (const std::string& n : refused) names += (names.empty() ? "" : ", ") + n;
    warnings.push_back(sched_warning("the " + names + " threads", priority, sched_error));
  }
  if (!error.ok()) (void)stop();
  return error;
}

// --- cycle thread ---------------------------------------------------------------------------

void Runtime::cycle_loop() {
  prefault_stack();
  while (!stop_cycle_.load(std::memory_order_relaxed)) cycle_once();
}

void Runtime::discard_samples() noexcept {
  while (ft_ring_->try_pop(ft_sample_)) ++cycle_counters_.samples_discarded;
  while (imu_ring_->try_pop(imu_sample_)) ++cycle_counters_.samples_discarded;
}

void Runtime::cycle_once() noexcept {
  if (devices_.lockstep != nullptr) {
    lockstep_once();
    return;
  }
  handle_received(devices_.robot->receive_sample(robot_sample_));
}

void Runtime::handle_received(rtio::RobotReceiveStatus received) noexcept {
  rtio::RobotLink& robot = *devices_.robot;
  if (received != rtio::RobotReceiveStatus::message) {
    switch (received) {
      case rtio::RobotReceiveStatus::timeout:
        ++cycle_counters_.receive_timeouts;
        cycle_.robot_lost(loop::RobotLoss::timeout);
        break;
      case rtio::RobotReceiveStatus::malformed:
        ++cycle_counters_.receive_malformed;
        cycle_.robot_lost(loop::RobotLoss::malformed);
        break;
      default:  // io_error, not_started: nothing came; do not spin
        ++cycle_counters_.receive_errors;
        cycle_.robot_lost(loop::RobotLoss::timeout);
        if (devices_.lockstep == nullptr) sleep_ns(1'000'000);
        break;
    }
    // Samples of a lost cycle would make the next row a mean over a longer, older window.
    discard_samples();
    after_cycle();
    return;
  }
  const std::int64_t t_received = monotonic_ns();
  update_snapshot(t_received);
  while (ft_ring_->try_pop(ft_sample_)) cycle_.add_ft(ft_sample_);
  while (imu_ring_->try_pop(imu_sample_)) cycle_.add_imu(imu_sample_);

  const std::int64_t t0 = monotonic_ns();
  cycle_.step(robot_sample_, correction_);
  const std::int64_t t1 = monotonic_ns();
  const rtio::RobotReplyStatus sent = robot.send_correction(correction_);
  const std::int64_t t2 = monotonic_ns();
  if (sent == rtio::RobotReplyStatus::ok) {
    ++cycle_counters_.replies_ok;
  } else {
    ++cycle_counters_.replies_failed;
  }
  if (correction_.axis()) ++cycle_counters_.axis_replies;

  cycle_.set_compute_ns(t1 - t0);
  const loop::CycleRecord& record = cycle_.last();
  compute_ns_.add(t1 - t0);
  reply_ns_.add(t2 - t_received);
  if ((record.flags & loop::kCollectionDone) != 0) ++collections_done_;
  slot_.record = record;
  record_ring_->try_push(slot_);  // a full ring drops the record (counted by the ring)
  if (telemetry_ != nullptr) telemetry_->offer(record, t_received);  // full: counted drop
  after_cycle();
}

void Runtime::after_cycle() noexcept {
  // Black box: publish a freshly frozen box to the recorder; release it once dumped and the
  // fault has been reset.
  const std::uint8_t box = box_state_.load(std::memory_order_acquire);
  if (box == 0 && cycle_.black_box().frozen()) {
    box_state_.store(1, std::memory_order_release);
  } else if (box == 2 && cycle_.state_machine().state() != loop::State::fault) {
    cycle_.release_black_box();
    ++cycle_counters_.black_box_releases;
    box_state_.store(0, std::memory_order_release);
  }

  const loop::CycleRecord& r = cycle_.last();
  const loop::StateMachine& sm = cycle_.state_machine();
  CycleStatus s;
  s.cycle = r.cycle;
  s.state = sm.state();
  s.fault = sm.fault();
  s.flags = r.flags;
  s.ready = cycle_.ready();
  s.compute_ns = r.compute_ns;
  s.transitions = sm.total_transitions();
  if (sm.log_size() > 0) s.last_transition = sm.log_at(sm.log_size() - 1);
  s.collections_done = collections_done_;
  s.robot_lost = cycle_counters_.receive_timeouts + cycle_counters_.receive_malformed +
                 cycle_counters_.receive_errors;
  s.commands_refused = cycle_.counters().commands_refused;
  cycle_status_.publish(s);

  modbus::fill_from_cycle(cycle_, snapshot_);
  snapshot_.compute_last_s = 1e-9 * static_cast<double>(r.compute_ns);
  snapshot_.robot_lost = s.robot_lost;
  snapshot_.records_dropped = record_ring_->dropped();

  if (telemetry_ != nullptr) {
    const loop::CycleCounters& c = cycle_.counters();
    telemetry::RuntimeHealth h;
    h.robot_lost = s.robot_lost;
    h.datagrams_lost = c.datagrams_lost;
    h.ipoc_gaps = c.ipoc_gaps;
    h.ft_held_cycles = c.ft_held_cycles;
    h.imu_held_cycles = c.imu_held_cycles;
    h.replies_failed = cycle_counters_.replies_failed;
    h.record_drops = snapshot_.records_dropped;
    h.commands_refused = c.commands_refused;
    h.transitions = s.transitions;
    h.poses_from_joints = c.poses_from_joints;
    h.pose_disagreements = c.pose_disagreements;
    h.poses_missing = c.poses_missing;
    telemetry_->set_health(h);
    if (cycle_.tunables_accepted() != tunables_seen_) {  // the PLC changed the virtual body
      tunables_seen_ = cycle_.tunables_accepted();
      telemetry_->set_body_params(cycle_.config().body);
    }
    snapshot_.telemetry_dropped = telemetry_->counters().telemetry_drops;
  }
  supervisor_.publish(snapshot_);
}

void Runtime::update_snapshot(std::int64_t t_received_ns) noexcept {
  // Called when a robot message has arrived: the period since the last one, and once a second
  // the compute-time p99 and the largest jitter of that second.
  const auto nominal_ns = static_cast<std::int64_t>(cycle_.config().period_s * 1e9);
  const SecondWindow::Figures f = second_window_.on_message(
      t_received_ns, nominal_ns, cycle_.last().compute_ns, cycle_.last().cycle > 0);
  if (f.has_period) snapshot_.period_last_s = 1e-9 * static_cast<double>(f.period_ns);
  if (f.second_ended) {
    if (f.has_compute_p99) snapshot_.compute_p99_s = 1e-9 * static_cast<double>(f.compute_p99_ns);
    snapshot_.jitter_max_s = 1e-9 * static_cast<double>(f.jitter_max_ns);
  }
}

modbus::SupervisorSnapshot Runtime::snapshot() const {
  supervisor_.read(supervisor_read_);
  return supervisor_read_;
}

// --- lockstep (proto/lockstep.md) -----------------------------------------------------------

namespace {
// How long the cycle thread waits for the emulator's next event, and for the sensor threads to
// read an event's production, before it calls the lockstep broken. Generous: the emulator may
// be slow (a loaded host), never wrong.
constexpr std::chrono::seconds kLockstepGuard{60};
constexpr std::int64_t kSensorGuardNs = 30'000'000'000;
constexpr std::int64_t kDatagramGuardNs = 5'000'000'000;
constexpr std::chrono::nanoseconds kFtAnswerGuard = std::chrono::seconds(5);
constexpr std::chrono::nanoseconds kImuBytesGuard = std::chrono::seconds(5);
}  // namespace

void Runtime::lockstep_fail(const char* what) noexcept {
  ++lockstep_counters_.errors;
  if (lockstep_counters_.error == nullptr) lockstep_counters_.error = what;
  lockstep_finished_.store(true, std::memory_order_release);
}

void Runtime::lockstep_sensors(const rtio::LockstepEvent& event) noexcept {
  lockstep_event_ = event;
  const std::uint32_t tick = lockstep_tick_.load(std::memory_order_relaxed) + 1;
  lockstep_tick_.store(tick, std::memory_order_release);
  lockstep_tick_.notify_all();
  const std::int64_t deadline = monotonic_ns() + kSensorGuardNs;
  auto done = [&] {
    return (devices_.ft == nullptr || ft_done_tick_.load(std::memory_order_acquire) == tick) &&
           (devices_.imu == nullptr || imu_done_tick_.load(std::memory_order_acquire) == tick);
  };
  while (!done()) {
    if (monotonic_ns() > deadline) {
      ++lockstep_counters_.sensor_waits_over;
      return;
    }
    sleep_ns(20'000);
  }
}

void Runtime::lockstep_auto_request() noexcept {
  // What supervise() does in real time, here in the cycle thread so that the cycle it takes
  // effect in is the emulator's, not the main thread's polling.
  if (!(options_.auto_enable_zero_g || options_.auto_collect) || lockstep_auto_done_) return;
  const loop::State target =
      options_.auto_enable_zero_g ? loop::State::zero_g : loop::State::collecting;
  const loop::State state = cycle_.state_machine().state();
  if (state == target || state == loop::State::fault) {
    lockstep_auto_done_ = true;
    return;
  }
  auto_request(state, cycle_.ready(), cycle_.last().cycle, lockstep_requested_,
               lockstep_requested_at_);
}

void Runtime::auto_request(loop::State state, bool ready, std::uint64_t cycle, bool& requested,
                           std::uint64_t& requested_at) noexcept {
  // Once per cycle while idle and ready (a request the cycle refused is asked again).
  if (state != loop::State::idle || !ready || (requested && cycle <= requested_at)) return;
  if (cycle_.request(options_.auto_enable_zero_g ? loop::Command::enable_zero_g
                                                 : loop::Command::start_collection) != 0) {
    requested = true;
    requested_at = cycle;
  }
}

void Runtime::lockstep_once() noexcept {
  rtio::LockstepClient& link = *devices_.lockstep;
  if (lockstep_finished_.load(std::memory_order_acquire)) {
    sleep_ns(1'000'000);  // waiting for stop()
    return;
  }
  rtio::LockstepEvent event;
  const rtio::LockstepStatus st = link.wait(event, kLockstepGuard);
  if (st != rtio::LockstepStatus::ok) {
    lockstep_fail(st == rtio::LockstepStatus::timeout ? "no event from the emulator within 60 s"
                                                      : "the lockstep socket failed");
    return;
  }
  if (event.kind == rtio::LockstepKind::end) {
    lockstep_counters_.ended = true;
    lockstep_finished_.store(true, std::memory_order_release);
    return;
  }
  lockstep_sensors(event);
  ++lockstep_counters_.events;
  if (event.kind == rtio::LockstepKind::timeout) {
    ++lockstep_counters_.timeout_events;
    handle_received(rtio::RobotReceiveStatus::timeout);
  } else {
    ++lockstep_counters_.datagram_events;
    // The datagram was sent before the event: it is on its way through loopback.
    rtio::RobotReceiveStatus received = devices_.robot->receive_sample(robot_sample_);
    const std::int64_t deadline = monotonic_ns() + kDatagramGuardNs;
    while (received == rtio::RobotReceiveStatus::timeout) {
      if (monotonic_ns() > deadline) {
        lockstep_fail("the robot's datagram did not arrive within 5 s of its event");
        return;
      }
      ++lockstep_counters_.receive_retries;
      received = devices_.robot->receive_sample(robot_sample_);
    }
    handle_received(received);
  }
  lockstep_auto_request();
  if (link.done(event.seq, devices_.robot->counters().replies) != rtio::LockstepStatus::ok)
    lockstep_fail("cannot acknowledge an event to the emulator");
}

// --- sensor threads -------------------------------------------------------------------------

void Runtime::ft_loop_lockstep() {
  // Exactly as many requests as the board has produced samples: the board answers each with
  // the next one, so every row gets the samples of its emulated interval.
  rtio::FtSensor& ft = *devices_.ft;
  rtio::FtSample sample;
  std::uint32_t seen = 0;
  std::uint64_t requested = 0;
  while (true) {
    lockstep_tick_.wait(seen, std::memory_order_acquire);
    if (stop_sensors_.load(std::memory_order_relaxed)) return;
    const std::uint32_t tick = lockstep_tick_.load(std::memory_order_acquire);
    const std::uint64_t target = lockstep_event_.ft_samples;
    // An answer the emulator's board gives in time (emulated) is waited for however long the
    // host takes; a silent board's request waits the configured timeout.
    const std::chrono::nanoseconds wait =
        lockstep_event_.ft_answers != 0 ? kFtAnswerGuard : std::chrono::nanoseconds(0);
    for (; requested < target && !stop_sensors_.load(std::memory_order_relaxed); ++requested) {
      const rtio::FtReadStatus st = ft.read_sample_waiting(sample, wait);
      ++sensor_counters_.ft_reads;
      if (st == rtio::FtReadStatus::sample) ft_ring_->try_push(sample);  // full: counted drop
    }
    seen = tick;
    ft_done_tick_.store(tick, std::memory_order_release);
  }
}

void Runtime::imu_loop_lockstep() {
  // Read until the bytes the emulator wrote since it (re)plugged the IMU are read, then what they
  // complete. After a re-open the bytes written before it may be gone (the tty was flushed):
  // the first interval is read until a read times out and the count is re-based on it.
  rtio::Imu& imu = *devices_.imu;
  rtio::ImuSample sample;
  std::uint32_t seen = 0;
  bool connected = true;
  std::uint32_t epoch = 0;                         // the plug our tty belongs to
  std::uint64_t base = imu.counters().bytes_read;  // bytes_read when it was opened
  std::int64_t offset = 0;  // emulator bytes − ours (bytes lost before the open)
  bool rebase = false;
  std::int64_t last_attempt_ns = 0;
  const std::int64_t reopen_ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(options_.imu_reopen_interval).count();
  auto disconnected = [&](std::int64_t now_ns) {
    ++sensor_counters_.imu_disconnects;
    connected = false;
    last_attempt_ns = now_ns;
  };
  while (true) {
    lockstep_tick_.wait(seen, std::memory_order_acquire);
    if (stop_sensors_.load(std::memory_order_relaxed)) return;
    const std::uint32_t tick = lockstep_tick_.load(std::memory_order_acquire);
    const rtio::LockstepEvent ev = lockstep_event_;
    if (!connected && ev.imu_plugged != 0 && ev.time_ns - last_attempt_ns >= reopen_ns) {
      last_attempt_ns = ev.time_ns;
      ++sensor_counters_.imu_reopen_attempts;
      ++lockstep_counters_.imu_reopen_attempts;
      if (imu.start() == rtio::ImuStartStatus::ok) {
        ++sensor_counters_.imu_reopens;
        connected = true;
        epoch = ev.imu_epoch;
        base = imu.counters().bytes_read;
        rebase = true;
      }
    }
    if (connected && (ev.imu_plugged == 0 || ev.imu_epoch != epoch)) {
      // Unplugged since the last event: the tty hangs up.
      const rtio::ImuReadStatus st = imu.read_sample(sample);
      ++sensor_counters_.imu_reads;
      if (st == rtio::ImuReadStatus::disconnected) disconnected(ev.time_ns);
    } else if (connected) {
      // Up to the bytes written (waiting for them however slow the host is), or, to re-base,
      // until a read times out.
      const auto target = static_cast<std::int64_t>(ev.imu_bytes) - offset;
      const std::uint64_t limit =
          rebase ? UINT64_MAX
                 : base + static_cast<std::uint64_t>(std::max<std::int64_t>(target, 0));
      const std::chrono::nanoseconds wait = rebase ? std::chrono::nanoseconds(0) : kImuBytesGuard;
      while (!stop_sensors_.load(std::memory_order_relaxed)) {
        const rtio::ImuReadStatus st =
            rebase ? imu.read_sample(sample) : imu.read_sample_upto(sample, limit, wait);
        ++sensor_counters_.imu_reads;
        if (st == rtio::ImuReadStatus::sample) {
          imu_ring_->try_push(sample);
          continue;
        }
        if (st == rtio::ImuReadStatus::timeout) {
          // After a re-open: the bytes before it may be gone. Otherwise the bytes written did
          // not come within the guard (counted: the run is not exact any more).
          const auto read = static_cast<std::int64_t>(imu.counters().bytes_read - base);
          ++lockstep_counters_.imu_rebases;
          offset = static_cast<std::int64_t>(ev.imu_bytes) - read;
          rebase = false;
        } else if (st == rtio::ImuReadStatus::disconnected) {
          disconnected(ev.time_ns);
        }
        break;  // drained, or io_error (counted by the device)
      }
    }
    seen = tick;
    imu_done_tick_.store(tick, std::memory_order_release);
  }
}

void Runtime::ft_loop() {
  prefault_stack();
  if (devices_.lockstep != nullptr) {
    ft_loop_lockstep();
    return;
  }
  rtio::FtSensor& ft = *devices_.ft;
  const auto period_ns = static_cast<std::int64_t>(1e9 / options_.ft_rate_hz + 0.5);
  std::int64_t next = monotonic_ns();
  rtio::FtSample sample;
  while (!stop_sensors_.load(std::memory_order_relaxed)) {
    const rtio::FtReadStatus st = ft.read_sample(sample);
    ++sensor_counters_.ft_reads;
    if (st == rtio::FtReadStatus::sample) ft_ring_->try_push(sample);  // full: counted drop
    next += period_ns;
    const std::int64_t now = monotonic_ns();
    if (next < now - period_ns) {  // fell behind by more than a period: start afresh
      ++sensor_counters_.ft_overruns;
      next = now;
    }
    timespec ts{};
    ts.tv_sec = static_cast<time_t>(next / 1'000'000'000);
    ts.tv_nsec = static_cast<long>(next % 1'000'000'000);
    while (::clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
    }
  }
}

void Runtime::imu_loop() {
  prefault_stack();
  if (devices_.lockstep != nullptr) {
    imu_loop_lockstep();
    return;
  }
  rtio::Imu& imu = *devices_.imu;
  rtio::ImuSample sample;
  const std::int64_t reopen_ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(options_.imu_reopen_interval).count();
  while (!stop_sensors_.load(std::memory_order_relaxed)) {
    const rtio::ImuReadStatus st = imu.read_sample(sample);
    ++sensor_counters_.imu_reads;
    switch (st) {
      case rtio::ImuReadStatus::sample:
        imu_ring_->try_push(sample);
        break;
      case rtio::ImuReadStatus::disconnected:
        ++sensor_counters_.imu_disconnects;
        while (!stop_sensors_.load(std::memory_order_relaxed)) {
          sleep_ns(reopen_ns);
          ++sensor_counters_.imu_reopen_attempts;
          if (imu.start() == rtio::ImuStartStatus::ok) {
            ++sensor_counters_.imu_reopens;
            break;
          }
        }
        break;
      case rtio::ImuReadStatus::timeout:
        break;
      default:  // io_error, not_started: do not spin
        sleep_ns(1'000'000);
        break;
    }
  }
}

// --- recorder thread ------------------------------------------------------------------------

void Runtime::recorder_loop() {
  std::int64_t next_status = monotonic_ns() + 1'000'000'000;
  auto publish = [&] {
    RecorderStatus s;
    s.records = recorder_->counters().records;
    s.black_boxes = black_box_paths_.size();
    if (!compute_window_.empty()) {
      const auto k =
          static_cast<std::ptrdiff_t>(0.99 * static_cast<double>(compute_window_.size() - 1));
      std::nth_element(compute_window_.begin(), compute_window_.begin() + k, compute_window_.end());
      s.compute_p99_ns = compute_window_[static_cast<std::size_t>(k)];
    }
    compute_window_.clear();
    recorder_status_.publish(s);
  };
  while (true) {
    const bool stopping = stop_recorder_.load(std::memory_order_acquire);
    int taken = 0;
    while (taken < 4096 && record_ring_->try_pop(*popped_)) {
      ++taken;
      compute_window_.push_back(popped_->record.compute_ns);
      if (recording_failed_) continue;
      try {
        recorder_->add(popped_->record);
      } catch (const std::exception& e) {
        recording_failed_ = true;
        recorder_error_ = std::string("recording stopped: ") + e.what();
        std::fprintf(stderr, "zerog-rt: %s\n", recorder_error_.c_str());
      }
    }
    if (box_state_.load(std::memory_order_acquire) == 1) {
      // The box is frozen: the cycle thread does not write it until we hand it back.
      try {
        const std::filesystem::path path = recorder_->dump_black_box(cycle_.black_box());
        black_box_paths_.push_back(path);
        const loop::Cycle::Box& box = cycle_.black_box();
        std::fprintf(
            stderr, "zerog-rt: black box (%zu cycles, fault %s at cycle %llu) written to %s\n",
            box.size(), box.size() > 0 ? loop::fault_name(box.at(box.size() - 1).fault) : "none",
            static_cast<unsigned long long>(box.size() > 0 ? box.at(box.size() - 1).cycle : 0),
            path.c_str());
      } catch (const std::exception& e) {
        std::fprintf(stderr, "zerog-rt: cannot write the black box: %s\n", e.what());
      }
      box_state_.store(2, std::memory_order_release);
    }
    const std::int64_t now = monotonic_ns();
    if (now >= next_status) {
      publish();
      next_status = now + 1'000'000'000;
    }
    if (stopping && record_ring_->size_approx() == 0) break;
    if (taken == 0) sleep_ns(2'000'000);
  }
  publish();
  if (!recording_failed_) {
    try {
      recorder_->finish();
    } catch (const std::exception& e) {
      recorder_error_ = std::string("cannot finish the recording: ") + e.what();
    }
  }
}

// --- main thread ----------------------------------------------------------------------------

SupervisorEvents Runtime::supervise() {
  CycleStatus s;
  if (cycle_status_.read(s) == rtio::LatestRead::empty) return {};
  last_status_ = s;
  SupervisorEvents ev = announcer_.update(s);
  // Still waiting (neither there nor given up): ask again (in lockstep the cycle thread asks).
  if (announcer_.auto_pending() && devices_.lockstep == nullptr)
    auto_request(s.state, s.ready, s.cycle, requested_, requested_at_);
  return ev;
}

std::string Runtime::status_line() {
  CycleStatus s = last_status_;
  cycle_status_.read(s);
  RecorderStatus r = last_recorder_status_;
  recorder_status_.read(r);
  last_recorder_status_ = r;
  char buffer[256];
  std::snprintf(
      buffer, sizeof buffer,
      "zerog-rt: state %s, fault %s, cycles %llu, robot lost %llu, compute p99 %.1f us, "
      "records %llu (dropped %llu)",
      loop::state_name(s.state), loop::fault_name(s.fault),
      static_cast<unsigned long long>(s.cycle), static_cast<unsigned long long>(s.robot_lost),
      static_cast<double>(r.compute_p99_ns) * 1e-3, static_cast<unsigned long long>(r.records),
      static_cast<unsigned long long>(record_ring_->dropped()));
  return buffer;
}

std::string Runtime::stop() {
  if (stopped_ || !started_) {
    stopped_ = stopped_ || !started_;
    return recorder_error_;
  }
  // The supervisor first: the cycle it talks to is about to stop.
  if (modbus_ != nullptr) modbus_->stop();
  stop_cycle_.store(true, std::memory_order_relaxed);
  cycle_thread_.join();
  stop_sensors_.store(true, std::memory_order_relaxed);
  lockstep_tick_.fetch_add(1, std::memory_order_release);  // wakes lockstep sensor threads
  lockstep_tick_.notify_all();
  ft_thread_.join();
  imu_thread_.join();
  stop_recorder_.store(true, std::memory_order_release);
  recorder_thread_.join();
  if (telemetry_ != nullptr) telemetry_->stop();  // publishes what the cycle handed over
  stopped_ = true;
  return recorder_error_;
}

// --- summary --------------------------------------------------------------------------------

std::string Runtime::summary_json() const {
  using nlohmann::json;
  const loop::CycleCounters& c = cycle_.counters();
  json cycles = {{"messages", c.messages},
                 {"robot_timeouts", c.robot_timeouts},
                 {"robot_malformed", c.robot_malformed},
                 {"ipoc_gaps", c.ipoc_gaps},
                 {"datagrams_lost", c.datagrams_lost},
                 {"ipoc_stale", c.ipoc_stale},
                 {"ft_samples", c.ft_samples},
                 {"ft_invalid", c.ft_invalid},
                 {"ft_held_cycles", c.ft_held_cycles},
                 {"imu_samples", c.imu_samples},
                 {"imu_invalid", c.imu_invalid},
                 {"imu_held_cycles", c.imu_held_cycles},
                 {"sample_overflow", c.sample_overflow},
                 {"model_saturated", c.model_saturated},
                 {"commands_refused", c.commands_refused},
                 {"black_boxes_lost", c.black_boxes_lost},
                 {"poses_from_joints", c.poses_from_joints},
                 {"pose_disagreements", c.pose_disagreements},
                 {"poses_missing", c.poses_missing}};
  const CycleThreadCounters& t = cycle_counters_;
  json cycle_thread = {
      {"receive_timeouts", t.receive_timeouts},   {"receive_malformed", t.receive_malformed},
      {"receive_errors", t.receive_errors},       {"replies_ok", t.replies_ok},
      {"replies_failed", t.replies_failed},       {"axis_replies", t.axis_replies},
      {"samples_discarded", t.samples_discarded}, {"black_box_releases", t.black_box_releases}};
  json devices = json::object();
  {
    const rtio::RobotLinkCounters& r = devices_.robot->counters();
    json by_status = json::object();
    for (std::size_t i = 0; i < rtio::kParseStatusCount; ++i) {
      if (r.malformed_by_status[i] != 0) by_status[kParseStatusNames[i]] = r.malformed_by_status[i];
    }
    devices["robot"] = {{"datagrams", r.datagrams},
                        {"messages", r.messages},
                        {"foreign", r.foreign},
                        {"malformed", r.malformed},
                        {"malformed_by_status", by_status},
                        {"timeouts", r.timeouts},
                        {"io_errors", r.io_errors},
                        {"replies", r.replies},
                        {"reply_would_block", r.reply_would_block},
                        {"reply_errors", r.reply_errors},
                        {"bad_corrections", r.bad_corrections},
                        {"discarded_at_start", r.discarded}};
  }
  if (devices_.ft != nullptr) {
    const rtio::FtCounters f = devices_.ft->counters();
    devices["ft"] = {{"requests", f.requests},
                     {"samples", f.samples},
                     {"samples_warning", f.samples_warning},
                     {"samples_critical", f.samples_critical},
                     {"samples_saturated", f.samples_saturated},
                     {"timeouts", f.timeouts},
                     {"stale_frames", f.stale_frames},
                     {"stray_frames", f.stray_frames},
                     {"wrong_length", f.wrong_length},
                     {"out_of_order", f.out_of_order},
                     {"dropped_incomplete", f.dropped_incomplete},
                     {"late_samples", f.late_samples},
                     {"overtaken", f.overtaken},
                     {"error_frames", f.error_frames},
                     {"kernel_drops", f.kernel_drops},
                     {"bad_length", f.bad_length},
                     {"tx_would_block", f.tx_would_block},
                     {"io_errors", f.io_errors},
                     {"thread_reads", sensor_counters_.ft_reads},
                     {"thread_overruns", sensor_counters_.ft_overruns}};
  }
  if (devices_.imu != nullptr) {
    const rtio::ImuCounters i = devices_.imu->counters();
    devices["imu"] = {{"samples", i.samples},
                      {"invalid_samples", i.invalid_samples},
                      {"bytes_read", i.bytes_read},
                      {"bytes_skipped", i.bytes_skipped},
                      {"crc_failures", i.crc_failures},
                      {"sync_losses", i.sync_losses},
                      {"counter_gaps", i.counter_gaps},
                      {"datagrams_missed", i.datagrams_missed},
                      {"timeouts", i.timeouts},
                      {"disconnects", i.disconnects},
                      {"io_errors", i.io_errors},
                      {"thread_reads", sensor_counters_.imu_reads},
                      {"thread_disconnects", sensor_counters_.imu_disconnects},
                      {"reopen_attempts", sensor_counters_.imu_reopen_attempts},
                      {"reopens", sensor_counters_.imu_reopens}};
  }
  json rings = {{"ft", ring_json(*ft_ring_)},
                {"imu", ring_json(*imu_ring_)},
                {"records", ring_json(*record_ring_)}};
  const loop::StateMachine& sm = cycle_.state_machine();
  json transitions = json::array();
  for (std::size_t i = 0; i < sm.log_size(); ++i) {
    const loop::Transition& tr = sm.log_at(i);
    json j = {
        {"cycle", tr.cycle}, {"from", loop::state_name(tr.from)}, {"to", loop::state_name(tr.to)}};
    if (tr.by_fault) {
      j["fault"] = loop::fault_name(tr.fault);
    } else {
      j["command"] = loop::command_name(tr.command);
    }
    transitions.push_back(j);
  }
  json boxes = json::array();
  for (const auto& p : black_box_paths_) boxes.push_back(p.string());
  json recording = nullptr;
  if (recorder_ != nullptr && recorder_->recording()) {
    const RecorderCounters& rc = recorder_->counters();
    recording = {{"log", recorder_->log_path().string()},
                 {"cycles", recorder_->cycles_path().string()},
                 {"records", rc.records},
                 {"log_rows", rc.log_rows},
                 {"skipped_stale", rc.skipped_stale},
                 {"skipped_no_samples", rc.skipped_no_samples},
                 {"rejected", rc.rejected},
                 {"records_dropped", record_ring_->dropped()},
                 {"error", recorder_error_}};
  }
  json out = {{"format", "zerog-rt-summary"},
              {"version", 1},
              {"state", loop::state_name(sm.state())},
              {"fault", loop::fault_name(sm.fault())},
              {"cycles", cycles},
              {"cycle_thread", cycle_thread},
              {"devices", devices},
              {"rings", rings},
              {"transitions", transitions},
              {"transitions_total", sm.total_transitions()},
              {"compute_ns", latency_json(compute_ns_)},
              {"reply_latency_ns", latency_json(reply_ns_)},
              {"black_box_dumps", boxes},
              {"recording", recording}};
  if (telemetry_ != nullptr) {
    const telemetry::ChannelCounters tc = telemetry_->counters();
    out["telemetry"] = {{"domain_id", telemetry_->config().domain_id},
                        {"records_offered", tc.records_offered},
                        {"records_published", tc.records_published},
                        {"dropped", tc.telemetry_drops},
                        {"write_errors", tc.write_errors},
                        {"health_published", tc.health_published}};
  }
  if (devices_.lockstep != nullptr) {
    const LockstepCounters& l = lockstep_counters_;
    out["lockstep"] = {{"events", l.events},
                       {"datagram_events", l.datagram_events},
                       {"timeout_events", l.timeout_events},
                       {"receive_retries", l.receive_retries},
                       {"sensor_waits_over", l.sensor_waits_over},
                       {"imu_rebases", l.imu_rebases},
                       {"imu_reopen_attempts", l.imu_reopen_attempts},
                       {"bad_messages", devices_.lockstep->bad_messages()},
                       {"errors", l.errors},
                       {"ended", l.ended},
                       {"error", l.error != nullptr ? l.error : ""}};
  }
  if (modbus_ != nullptr) {
    const modbus::ServerCounters m = modbus_->counters();
    json exceptions = json::object();
    for (std::size_t code = 1; code < m.exceptions.size(); ++code) {
      if (m.exceptions[code] != 0) exceptions[std::to_string(code)] = m.exceptions[code];
    }
    out["modbus"] = {{"port", modbus_->port()},
                     {"requests", m.requests},
                     {"replies", m.replies},
                     {"exceptions_by_code", exceptions},
                     {"writes_accepted", m.writes_accepted},
                     {"writes_refused", m.writes_refused},
                     {"commands_accepted", m.commands_accepted},
                     {"clients_accepted", m.clients_accepted},
                     {"clients_refused_allowlist", m.clients_refused_allowlist},
                     {"clients_refused_limit", m.clients_refused_limit},
                     {"clients_closed", m.clients_closed},
                     {"request_timeouts", m.request_timeouts},
                     {"idle_timeouts", m.idle_timeouts},
                     {"framing_errors", m.framing_errors},
                     {"send_errors", m.send_errors}};
  }
  return out.dump(1) + "\n";
}

}  // namespace zerog::rt
