#include "zerog/rt/runtime.hpp"

#include <time.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <iostream>

#include "zerog/handover/clock.hpp"

namespace zerog::rt {

namespace {

using handover::monotonic_ns;

void sleep_ns(std::int64_t ns) noexcept {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(ns / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(ns % 1'000'000'000);
  while (::clock_nanosleep(CLOCK_MONOTONIC, 0, &ts, &ts) == EINTR) {
  }
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
    : options_(std::move(options)), devices_(devices), supervision_(options_) {
  recorder_side_.compute_window.reserve(4096);
}

// No one to tell here: a caller that wants the recorder's error calls stop() first.
Runtime::~Runtime() { static_cast<void>(stop()); }

Status Runtime::configure(const loop::CycleConfig& config, infer::DeployedModel model,
                          const loop::JointPath* path) {
  if (devices_.robot == nullptr) return {StatusCode::not_ready, "no robot link"};
  // The model's identity, for the supervisor (proto/modbus.md) before the cycle takes the model.
  modbus::fill_model_identity(model, options_.model_file_crc32, cycle_side_.snapshot);
  if (options_.telemetry) {
    telemetry::TelemetryConfig t = *options_.telemetry;
    t.nominal_period_s = config.period_s;
    if (Status st = telemetry::check_config(t); !st.ok()) return std::move(st).within("telemetry");
    supervision_.telemetry = std::make_unique<telemetry::TelemetryChannel>(
        t, telemetry::model_identity(model, options_.model_file_name, options_.model_file_crc32),
        config.body);
  }
  if (Status st = cycle_.configure(config, std::move(model)); !st.ok()) return st;
  supervision_.configured_tunables = cycle_.tunables();
  handover_.supervisor.publish(cycle_side_.snapshot);
  path_ = path;
  cycle_.set_collection_path(path);
  return {};
}

Status Runtime::start(std::vector<Status>& warnings) {
  if (threads_.started) return {StatusCode::already_started, "already started"};
  try {
    recorder_side_.recorder = std::make_unique<Recorder>(options_.recorder);
  } catch (const std::exception& e) {
    return {StatusCode::system_error, e.what()};
  }
  if (supervision_.telemetry != nullptr) {
    if (Status st = supervision_.telemetry->start(); !st.ok())
      return std::move(st).within("telemetry");
  }
  if (options_.realtime.lock_memory) {
    if (Status st = lock_memory(); !st.ok()) warnings.push_back(std::move(st));
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
  threads_.started = true;
  Status error = launch(threads_.recorder, "recorder", &Runtime::recorder_loop, 0, -1);
  if (error.ok() && devices_.imu != nullptr)
    error = launch(threads_.imu, "imu", &Runtime::imu_loop, sensor_priority, -1);
  if (error.ok() && devices_.ft != nullptr)
    error = launch(threads_.ft, "ft", &Runtime::ft_loop, sensor_priority, -1);
  // Whatever robot datagrams piled up while the program started are old: the first cycle
  // starts from now (and a datagram sent after start() began is kept).
  devices_.robot->discard_queued();
  if (error.ok())
    error = launch(threads_.cycle, "cycle", &Runtime::cycle_loop, priority, options_.realtime.cpu);
  if (error.ok() && options_.modbus) {
    supervision_.modbus = std::make_unique<modbus::ModbusServer>(*options_.modbus, *this);
    // A refused setting is named as in the file ("modbus.port"); the server's own failures
    // already say "Modbus server: …".
    Status st = supervision_.modbus->start();
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
  while (!threads_.stop_cycle.load(std::memory_order_relaxed)) cycle_once();
}

void Runtime::discard_samples() noexcept {
  while (handover_.ft->try_pop(cycle_side_.ft_sample)) ++cycle_side_.counters.samples_discarded;
  while (handover_.imu->try_pop(cycle_side_.imu_sample)) ++cycle_side_.counters.samples_discarded;
}

void Runtime::cycle_once() noexcept {
  if (devices_.lockstep != nullptr) {
    lockstep_once();
    return;
  }
  handle_received(devices_.robot->receive_sample(cycle_side_.robot_sample));
}

void Runtime::handle_received(rtio::RobotReceiveStatus received) noexcept {
  rtio::RobotLink& robot = *devices_.robot;
  if (received != rtio::RobotReceiveStatus::message) {
    switch (received) {
      case rtio::RobotReceiveStatus::timeout:
        ++cycle_side_.counters.receive_timeouts;
        cycle_.robot_lost(loop::RobotLoss::timeout);
        break;
      case rtio::RobotReceiveStatus::malformed:
        ++cycle_side_.counters.receive_malformed;
        cycle_.robot_lost(loop::RobotLoss::malformed);
        break;
      default:  // io_error, not_started: nothing came; do not spin
        ++cycle_side_.counters.receive_errors;
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
  while (handover_.ft->try_pop(cycle_side_.ft_sample)) cycle_.add_ft(cycle_side_.ft_sample);
  while (handover_.imu->try_pop(cycle_side_.imu_sample)) cycle_.add_imu(cycle_side_.imu_sample);

  const std::int64_t t0 = monotonic_ns();
  cycle_.step(cycle_side_.robot_sample, cycle_side_.correction);
  const std::int64_t t1 = monotonic_ns();
  const rtio::RobotReplyStatus sent = robot.send_correction(cycle_side_.correction);
  const std::int64_t t2 = monotonic_ns();
  if (sent == rtio::RobotReplyStatus::ok) {
    ++cycle_side_.counters.replies_ok;
  } else {
    ++cycle_side_.counters.replies_failed;
  }
  if (cycle_side_.correction.axis()) ++cycle_side_.counters.axis_replies;

  cycle_.set_compute_ns(t1 - t0);
  const loop::CycleRecord& record = cycle_.last();
  cycle_side_.compute_ns.add(t1 - t0);
  cycle_side_.reply_ns.add(t2 - t_received);
  if ((record.flags & loop::kCollectionDone) != 0) ++cycle_side_.collections_done;
  cycle_side_.slot.record = record;
  // A full ring drops the record (counted by the ring).
  handover_.records->try_push(cycle_side_.slot);
  if (supervision_.telemetry != nullptr)
    supervision_.telemetry->offer(record, t_received);  // full: counted drop
  after_cycle();
}

void Runtime::after_cycle() noexcept {
  // Black box: publish a freshly frozen box to the recorder; release it once dumped and the
  // fault has been reset.
  const std::uint8_t box = handover_.box_state.load(std::memory_order_acquire);
  if (box == 0 && cycle_.black_box().frozen()) {
    handover_.box_state.store(1, std::memory_order_release);
  } else if (box == 2 && cycle_.state_machine().state() != loop::State::fault) {
    cycle_.release_black_box();
    ++cycle_side_.counters.black_box_releases;
    handover_.box_state.store(0, std::memory_order_release);
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
  s.collections_done = cycle_side_.collections_done;
  s.robot_lost = cycle_side_.counters.receive_timeouts + cycle_side_.counters.receive_malformed +
                 cycle_side_.counters.receive_errors;
  s.commands_refused = cycle_.counters().commands_refused;
  handover_.cycle_status.publish(s);

  modbus::fill_from_cycle(cycle_, cycle_side_.snapshot);
  cycle_side_.snapshot.compute_last_s = 1e-9 * static_cast<double>(r.compute_ns);
  cycle_side_.snapshot.robot_lost = s.robot_lost;
  cycle_side_.snapshot.records_dropped = handover_.records->dropped();

  if (supervision_.telemetry != nullptr) {
    const loop::CycleCounters& c = cycle_.counters();
    telemetry::RuntimeHealth h;
    h.robot_lost = s.robot_lost;
    h.datagrams_lost = c.datagrams_lost;
    h.ipoc_gaps = c.ipoc_gaps;
    h.ft_held_cycles = c.ft_held_cycles;
    h.imu_held_cycles = c.imu_held_cycles;
    h.replies_failed = cycle_side_.counters.replies_failed;
    h.record_drops = cycle_side_.snapshot.records_dropped;
    h.commands_refused = c.commands_refused;
    h.transitions = s.transitions;
    h.poses_from_joints = c.poses_from_joints;
    h.pose_disagreements = c.pose_disagreements;
    h.poses_missing = c.poses_missing;
    supervision_.telemetry->set_health(h);
    // The PLC changed the virtual body.
    if (cycle_.tunables_accepted() != cycle_side_.tunables_seen) {
      cycle_side_.tunables_seen = cycle_.tunables_accepted();
      supervision_.telemetry->set_body_params(cycle_.config().body);
    }
    cycle_side_.snapshot.telemetry_dropped = supervision_.telemetry->counters().telemetry_drops;
  }
  handover_.supervisor.publish(cycle_side_.snapshot);
}

void Runtime::update_snapshot(std::int64_t t_received_ns) noexcept {
  // Called when a robot message has arrived: the period since the last one, and once a second
  // the compute-time p99 and the largest jitter of that second.
  const auto nominal_ns = static_cast<std::int64_t>(cycle_.config().period_s * 1e9);
  const SecondWindow::Figures f = cycle_side_.second_window.on_message(
      t_received_ns, nominal_ns, cycle_.last().compute_ns, cycle_.last().cycle > 0);
  if (f.has_period) cycle_side_.snapshot.period_last_s = 1e-9 * static_cast<double>(f.period_ns);
  if (f.second_ended) {
    if (f.has_compute_p99)
      cycle_side_.snapshot.compute_p99_s = 1e-9 * static_cast<double>(f.compute_p99_ns);
    cycle_side_.snapshot.jitter_max_s = 1e-9 * static_cast<double>(f.jitter_max_ns);
  }
}

modbus::SupervisorSnapshot Runtime::snapshot() const {
  handover_.supervisor.read(supervision_.snapshot_read);
  return supervision_.snapshot_read;
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
  ++lockstep_.counters.errors;
  if (lockstep_.counters.error == nullptr) lockstep_.counters.error = what;
  lockstep_.finished.store(true, std::memory_order_release);
}

void Runtime::lockstep_sensors(const rtio::LockstepEvent& event) noexcept {
  lockstep_.event = event;
  const std::uint32_t tick = lockstep_.tick.load(std::memory_order_relaxed) + 1;
  lockstep_.tick.store(tick, std::memory_order_release);
  lockstep_.tick.notify_all();
  const std::int64_t deadline = monotonic_ns() + kSensorGuardNs;
  auto done = [&] {
    return (devices_.ft == nullptr ||
            lockstep_.ft_done_tick.load(std::memory_order_acquire) == tick) &&
           (devices_.imu == nullptr ||
            lockstep_.imu_done_tick.load(std::memory_order_acquire) == tick);
  };
  while (!done()) {
    if (monotonic_ns() > deadline) {
      ++lockstep_.counters.sensor_waits_over;
      return;
    }
    sleep_ns(20'000);
  }
}

void Runtime::lockstep_auto_request() noexcept {
  // What supervise() does in real time, here in the cycle thread so that the cycle it takes
  // effect in is the emulator's, not the main thread's polling.
  if (!(options_.auto_enable_zero_g || options_.auto_collect) || lockstep_.auto_done) return;
  const loop::State target =
      options_.auto_enable_zero_g ? loop::State::zero_g : loop::State::collecting;
  const loop::State state = cycle_.state_machine().state();
  if (state == target || state == loop::State::fault) {
    lockstep_.auto_done = true;
    return;
  }
  auto_request(state, cycle_.ready(), cycle_.last().cycle, lockstep_.requested,
               lockstep_.requested_at);
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
  if (lockstep_.finished.load(std::memory_order_acquire)) {
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
    lockstep_.counters.ended = true;
    lockstep_.finished.store(true, std::memory_order_release);
    return;
  }
  lockstep_sensors(event);
  ++lockstep_.counters.events;
  if (event.kind == rtio::LockstepKind::timeout) {
    ++lockstep_.counters.timeout_events;
    handle_received(rtio::RobotReceiveStatus::timeout);
  } else {
    ++lockstep_.counters.datagram_events;
    // The datagram was sent before the event: it is on its way through loopback.
    rtio::RobotReceiveStatus received = devices_.robot->receive_sample(cycle_side_.robot_sample);
    const std::int64_t deadline = monotonic_ns() + kDatagramGuardNs;
    while (received == rtio::RobotReceiveStatus::timeout) {
      if (monotonic_ns() > deadline) {
        lockstep_fail("the robot's datagram did not arrive within 5 s of its event");
        return;
      }
      ++lockstep_.counters.receive_retries;
      received = devices_.robot->receive_sample(cycle_side_.robot_sample);
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
    lockstep_.tick.wait(seen, std::memory_order_acquire);
    if (threads_.stop_sensors.load(std::memory_order_relaxed)) return;
    const std::uint32_t tick = lockstep_.tick.load(std::memory_order_acquire);
    const std::uint64_t target = lockstep_.event.ft_samples;
    // An answer the emulator's board gives in time (emulated) is waited for however long the
    // host takes; a silent board's request waits the configured timeout.
    const std::chrono::nanoseconds wait =
        lockstep_.event.ft_answers != 0 ? kFtAnswerGuard : std::chrono::nanoseconds(0);
    for (; requested < target && !threads_.stop_sensors.load(std::memory_order_relaxed);
         ++requested) {
      const rtio::FtReadStatus st = ft.read_sample_waiting(sample, wait);
      ++sensors_.counters.ft_reads;
      if (st == rtio::FtReadStatus::sample) handover_.ft->try_push(sample);  // full: counted drop
    }
    seen = tick;
    lockstep_.ft_done_tick.store(tick, std::memory_order_release);
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
    ++sensors_.counters.imu_disconnects;
    connected = false;
    last_attempt_ns = now_ns;
  };
  while (true) {
    lockstep_.tick.wait(seen, std::memory_order_acquire);
    if (threads_.stop_sensors.load(std::memory_order_relaxed)) return;
    const std::uint32_t tick = lockstep_.tick.load(std::memory_order_acquire);
    const rtio::LockstepEvent ev = lockstep_.event;
    if (!connected && ev.imu_plugged != 0 && ev.time_ns - last_attempt_ns >= reopen_ns) {
      last_attempt_ns = ev.time_ns;
      ++sensors_.counters.imu_reopen_attempts;
      ++lockstep_.counters.imu_reopen_attempts;
      if (imu.start() == rtio::ImuStartStatus::ok) {
        ++sensors_.counters.imu_reopens;
        connected = true;
        epoch = ev.imu_epoch;
        base = imu.counters().bytes_read;
        rebase = true;
      }
    }
    if (connected && (ev.imu_plugged == 0 || ev.imu_epoch != epoch)) {
      // Unplugged since the last event: the tty hangs up.
      const rtio::ImuReadStatus st = imu.read_sample(sample);
      ++sensors_.counters.imu_reads;
      if (st == rtio::ImuReadStatus::disconnected) disconnected(ev.time_ns);
    } else if (connected) {
      // Up to the bytes written (waiting for them however slow the host is), or, to re-base,
      // until a read times out.
      const auto target = static_cast<std::int64_t>(ev.imu_bytes) - offset;
      const std::uint64_t limit =
          rebase ? UINT64_MAX
                 : base + static_cast<std::uint64_t>(std::max<std::int64_t>(target, 0));
      const std::chrono::nanoseconds wait = rebase ? std::chrono::nanoseconds(0) : kImuBytesGuard;
      while (!threads_.stop_sensors.load(std::memory_order_relaxed)) {
        const rtio::ImuReadStatus st =
            rebase ? imu.read_sample(sample) : imu.read_sample_upto(sample, limit, wait);
        ++sensors_.counters.imu_reads;
        if (st == rtio::ImuReadStatus::sample) {
          handover_.imu->try_push(sample);
          continue;
        }
        if (st == rtio::ImuReadStatus::timeout) {
          // After a re-open: the bytes before it may be gone. Otherwise the bytes written did
          // not come within the guard (counted: the run is not exact any more).
          const auto read = static_cast<std::int64_t>(imu.counters().bytes_read - base);
          ++lockstep_.counters.imu_rebases;
          offset = static_cast<std::int64_t>(ev.imu_bytes) - read;
          rebase = false;
        } else if (st == rtio::ImuReadStatus::disconnected) {
          disconnected(ev.time_ns);
        }
        break;  // drained, or io_error (counted by the device)
      }
    }
    seen = tick;
    lockstep_.imu_done_tick.store(tick, std::memory_order_release);
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
  while (!threads_.stop_sensors.load(std::memory_order_relaxed)) {
    const rtio::FtReadStatus st = ft.read_sample(sample);
    ++sensors_.counters.ft_reads;
    if (st == rtio::FtReadStatus::sample) handover_.ft->try_push(sample);  // full: counted drop
    next += period_ns;
    const std::int64_t now = monotonic_ns();
    if (next < now - period_ns) {  // fell behind by more than a period: start afresh
      ++sensors_.counters.ft_overruns;
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
  while (!threads_.stop_sensors.load(std::memory_order_relaxed)) {
    const rtio::ImuReadStatus st = imu.read_sample(sample);
    ++sensors_.counters.imu_reads;
    switch (st) {
      case rtio::ImuReadStatus::sample:
        handover_.imu->try_push(sample);
        break;
      case rtio::ImuReadStatus::disconnected:
        ++sensors_.counters.imu_disconnects;
        while (!threads_.stop_sensors.load(std::memory_order_relaxed)) {
          sleep_ns(reopen_ns);
          ++sensors_.counters.imu_reopen_attempts;
          if (imu.start() == rtio::ImuStartStatus::ok) {
            ++sensors_.counters.imu_reopens;
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
    s.records = recorder_side_.recorder->counters().records;
    s.black_boxes = recorder_side_.black_box_paths.size();
    if (!recorder_side_.compute_window.empty()) {
      const auto k = static_cast<std::ptrdiff_t>(
          0.99 * static_cast<double>(recorder_side_.compute_window.size() - 1));
      std::nth_element(recorder_side_.compute_window.begin(),
                       recorder_side_.compute_window.begin() + k,
                       recorder_side_.compute_window.end());
      s.compute_p99_ns = recorder_side_.compute_window[static_cast<std::size_t>(k)];
    }
    recorder_side_.compute_window.clear();
    handover_.recorder_status.publish(s);
  };
  while (true) {
    const bool stopping = threads_.stop_recorder.load(std::memory_order_acquire);
    int taken = 0;
    while (taken < 4096 && handover_.records->try_pop(*recorder_side_.popped)) {
      ++taken;
      recorder_side_.compute_window.push_back(recorder_side_.popped->record.compute_ns);
      if (recorder_side_.failed) continue;
      try {
        recorder_side_.recorder->add(recorder_side_.popped->record);
      } catch (const std::exception& e) {
        recorder_side_.failed = true;
        recorder_side_.error = std::string("recording stopped: ") + e.what();
        std::fprintf(stderr, "zerog-rt: %s\n", recorder_side_.error.c_str());
      }
    }
    if (handover_.box_state.load(std::memory_order_acquire) == 1) {
      // The box is frozen: the cycle thread does not write it until we hand it back.
      try {
        const std::filesystem::path path =
            recorder_side_.recorder->dump_black_box(cycle_.black_box());
        recorder_side_.black_box_paths.push_back(path);
        const loop::Cycle::Box& box = cycle_.black_box();
        std::fprintf(
            stderr, "zerog-rt: black box (%zu cycles, fault %s at cycle %llu) written to %s\n",
            box.size(), box.size() > 0 ? loop::fault_name(box.at(box.size() - 1).fault) : "none",
            static_cast<unsigned long long>(box.size() > 0 ? box.at(box.size() - 1).cycle : 0),
            path.c_str());
      } catch (const std::exception& e) {
        std::fprintf(stderr, "zerog-rt: cannot write the black box: %s\n", e.what());
      }
      handover_.box_state.store(2, std::memory_order_release);
    }
    const std::int64_t now = monotonic_ns();
    if (now >= next_status) {
      publish();
      next_status = now + 1'000'000'000;
    }
    if (stopping && handover_.records->size_approx() == 0) break;
    if (taken == 0) sleep_ns(2'000'000);
  }
  publish();
  if (!recorder_side_.failed) {
    try {
      recorder_side_.recorder->finish();
    } catch (const std::exception& e) {
      recorder_side_.error = std::string("cannot finish the recording: ") + e.what();
    }
  }
}

// --- main thread ----------------------------------------------------------------------------

SupervisorEvents Runtime::supervise() {
  CycleStatus s;
  if (handover_.cycle_status.read(s) == handover::LatestRead::empty) return {};
  supervision_.last_status = s;
  SupervisorEvents ev = supervision_.announcer.update(s);
  // Still waiting (neither there nor given up): ask again (in lockstep the cycle thread asks).
  if (supervision_.announcer.auto_pending() && devices_.lockstep == nullptr)
    auto_request(s.state, s.ready, s.cycle, supervision_.requested, supervision_.requested_at);
  return ev;
}

std::string Runtime::status_line() {
  CycleStatus s = supervision_.last_status;
  handover_.cycle_status.read(s);
  RecorderStatus r = supervision_.last_recorder_status;
  handover_.recorder_status.read(r);
  supervision_.last_recorder_status = r;
  char buffer[256];
  std::snprintf(
      buffer, sizeof buffer,
      "zerog-rt: state %s, fault %s, cycles %llu, robot lost %llu, compute p99 %.1f us, "
      "records %llu (dropped %llu)",
      loop::state_name(s.state), loop::fault_name(s.fault),
      static_cast<unsigned long long>(s.cycle), static_cast<unsigned long long>(s.robot_lost),
      static_cast<double>(r.compute_p99_ns) * 1e-3, static_cast<unsigned long long>(r.records),
      static_cast<unsigned long long>(handover_.records->dropped()));
  return buffer;
}

Status Runtime::stop() {
  if (threads_.stopped || !threads_.started) {
    threads_.stopped = threads_.stopped || !threads_.started;
    return recorder_result();
  }
  // The supervisor first: the cycle it talks to is about to stop.
  if (supervision_.modbus != nullptr) supervision_.modbus->stop();
  threads_.stop_cycle.store(true, std::memory_order_relaxed);
  threads_.cycle.join();
  threads_.stop_sensors.store(true, std::memory_order_relaxed);
  lockstep_.tick.fetch_add(1, std::memory_order_release);  // wakes lockstep sensor threads
  lockstep_.tick.notify_all();
  threads_.ft.join();
  threads_.imu.join();
  threads_.stop_recorder.store(true, std::memory_order_release);
  threads_.recorder.join();
  if (supervision_.telemetry != nullptr)
    supervision_.telemetry->stop();  // publishes what the cycle handed over
  threads_.stopped = true;
  return recorder_result();
}

Status Runtime::recorder_result() const {
  if (recorder_side_.error.empty()) return {};
  return {StatusCode::system_error, recorder_side_.error};
}

}  // namespace zerog::rt
