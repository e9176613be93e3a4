#pragma once
// zerog-rt's threads around one loop::Cycle (proto/rt_config.md, "Threads"):
//
//   F/T thread     FtSensor::read_sample paced at rate_hz (clock_nanosleep, absolute) → ring
//   IMU thread     Imu::read_sample → ring; on `disconnected` re-opens every 100 ms
//   cycle thread   cycle_once(): RobotLink::receive_sample (SI) → drain both rings into the cycle
//                  → step → send_correction → compute time → record ring; timeout/malformed →
//                  robot_lost
//   recorder       record ring → Recorder (cycles.csv, the log); dumps the frozen black box
//   main thread    commands (request), supervise() (--enable-zero-g, --collect), status_line()
//
// Devices are not owned: main starts them (they may block) and hands them over; tests pass
// fakes, or none and feed the rings through ft_ring()/imu_ring(). cycle_once() is the cycle
// thread's whole loop body: real-time safe (no allocation, no locks, no exceptions; proved by
// tests/unit/rt/cycle_once_test.cpp).
#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "zerog/handover/latest_value.hpp"
#include "zerog/handover/spsc_ring.hpp"
#include "zerog/loop/cycle.hpp"
#include "zerog/modbus/server.hpp"
#include "zerog/modbus/target.hpp"
#include "zerog/rt/config.hpp"
#include "zerog/rt/latency.hpp"
#include "zerog/rt/realtime.hpp"
#include "zerog/rt/recorder.hpp"
#include "zerog/rtio/ft_sensor.hpp"
#include "zerog/rtio/imu.hpp"
#include "zerog/rtio/lockstep.hpp"
#include "zerog/rtio/robot_link.hpp"
#include "zerog/telemetry/channel.hpp"

namespace zerog::rt {

struct RuntimeOptions {
  double ft_rate_hz = 500.0;
  /// Off by default here (tests); zerog-rt takes the configuration's [realtime].
  RealtimeSection realtime{false, 0, -1};
  bool auto_enable_zero_g = false;  ///< --enable-zero-g
  bool auto_collect = false;        ///< --collect: start collecting as soon as the cycle is ready
  RecorderOptions recorder;
  std::chrono::milliseconds imu_reopen_interval{100};
  std::uint32_t model_file_crc32 = 0;  ///< the deploy file's identity (Setup::model_file_crc32)
  /// The Modbus server for the cell PLC (proto/modbus.md), started last and stopped first.
  std::optional<modbus::ServerConfig> modbus;
  /// Live telemetry over DDS (proto/telemetry.md), started before the threads, stopped (drained)
  /// after the cycle thread. nominal_period_s is taken from the loop's configuration.
  std::optional<telemetry::TelemetryConfig> telemetry;
  std::string model_file_name;  ///< named in the telemetry's model identity
};

struct RuntimeDevices {
  rtio::RobotLink* robot = nullptr;  ///< required, started
  rtio::FtSensor* ft = nullptr;      ///< started; null: no F/T thread (tests feed ft_ring())
  rtio::Imu* imu = nullptr;          ///< started; null: no IMU thread
  /// Lockstep with the emulated rig (proto/lockstep.md), opened and hello sent; null: real time.
  /// The cycle thread then handles the emulator's events, and the sensor threads read what the
  /// emulator says was produced before each event instead of pacing themselves.
  rtio::LockstepClient* lockstep = nullptr;
};

/// Lockstep counters (cycle and sensor threads; read after stop()).
struct LockstepCounters {
  std::uint64_t events = 0;  ///< datagram + timeout events handled
  std::uint64_t datagram_events = 0;
  std::uint64_t timeout_events = 0;
  std::uint64_t receive_retries = 0;    ///< receive() timed out although a datagram was sent
  std::uint64_t sensor_waits_over = 0;  ///< sensor threads not done within the guard (must be 0)
  std::uint64_t errors = 0;             ///< wait/ack failures (the run ends)
  std::uint64_t imu_rebases = 0;        ///< IMU byte count re-based after a re-open
  std::uint64_t imu_reopen_attempts = 0;
  bool ended = false;           ///< the emulator sent `end`
  const char* error = nullptr;  ///< the first failure (a static text), if any
};

/// Published by the cycle thread after every cycle (LatestValue), read by the main thread.
struct CycleStatus {
  std::uint64_t cycle = 0;  ///< robot messages handled
  loop::State state = loop::State::idle;
  loop::Fault fault = loop::Fault::none;
  std::uint32_t flags = 0;  ///< of the last record
  bool ready = false;       ///< last record without kNotReady, kFtHeld, kImuHeld
  std::int64_t compute_ns = 0;
  std::uint64_t transitions = 0;  ///< state-machine transitions so far
  loop::Transition last_transition;
  std::uint64_t collections_done = 0;
  std::uint64_t robot_lost = 0;  ///< timeouts + malformed + receive errors
  std::uint64_t commands_refused = 0;
};

/// Published by the recorder thread once a second.
struct RecorderStatus {
  std::uint64_t records = 0;
  std::int64_t compute_p99_ns = 0;  ///< over the records of the last second
  std::uint64_t black_boxes = 0;
};

/// Counted by the cycle thread (read after stop()).
struct CycleThreadCounters {
  std::uint64_t receive_timeouts = 0;
  std::uint64_t receive_malformed = 0;
  std::uint64_t receive_errors = 0;  ///< io_error, not_started
  std::uint64_t replies_ok = 0;
  std::uint64_t replies_failed = 0;  ///< any other RobotReplyStatus
  std::uint64_t axis_replies = 0;
  std::uint64_t samples_discarded = 0;  ///< drained on a lost robot cycle (not averaged)
  std::uint64_t black_box_releases = 0;
};

struct SensorThreadCounters {
  std::uint64_t ft_reads = 0;
  std::uint64_t ft_overruns = 0;  ///< pacing fell behind by more than a period (resynchronised)
  std::uint64_t imu_reads = 0;
  std::uint64_t imu_disconnects = 0;
  std::uint64_t imu_reopen_attempts = 0;
  std::uint64_t imu_reopens = 0;
};

/// What supervise() has to say: stdout lines (the documented announcements) and stderr lines.
struct SupervisorEvents {
  std::vector<std::string> out;
  std::vector<std::string> err;
};

/// The main thread's reading of the cycle's status: the announcements of proto/rt_config.md
/// (stdout: "zero-g enabled at cycle N", "collection started …", "collection finished …") and
/// the notes (stderr: transitions, refused commands, --enable-zero-g/--collect giving up), each
/// once. No threads, no clock: the same statuses give the same lines.
class StatusAnnouncer {
 public:
  /// --enable-zero-g / --collect (at most one): the state they wait for.
  StatusAnnouncer(bool auto_enable_zero_g, bool auto_collect)
      : auto_enable_zero_g_(auto_enable_zero_g), auto_collect_(auto_collect) {}
  /// The lines for the newest status (the changes since the last one).
  SupervisorEvents update(const CycleStatus& s);
  /// --enable-zero-g / --collect has neither reached its state nor given up (on a fault).
  bool auto_pending() const {
    return (auto_enable_zero_g_ || auto_collect_) && !auto_done_ && !auto_gave_up_;
  }
  /// --collect's path has been followed to its end.
  bool collection_finished() const { return collection_finished_; }

 private:
  bool auto_enable_zero_g_, auto_collect_;
  bool auto_done_ = false;
  bool auto_gave_up_ = false;
  std::uint64_t transitions_seen_ = 0;
  std::uint64_t collections_seen_ = 0;
  std::uint64_t refused_seen_ = 0;
  bool collection_finished_ = false;
  /// In zero-g with the contact not yet trusted (kEstimatorSettling, kContactTaring): said.
  bool untrusted_said_ = false;
};

/// One line of `--commands stdin` (proto/rt_config.md): `enable`, `stop`, `reset`, `collect`,
/// `quit`, surrounding blanks ignored.
struct CommandLine {
  enum class Kind : std::uint8_t { none, command, quit, unknown } kind = Kind::none;
  loop::Command command = loop::Command::stop;  ///< valid if kind == command
};
CommandLine parse_command_line(std::string_view line);

/// A CycleRecord as the record ring holds it: copying fixed-size Eigen members cannot throw, but
/// Eigen does not say so (noexcept), which SpscRing requires.
struct RecordSlot {
  loop::CycleRecord record;
  RecordSlot() noexcept {}
  RecordSlot(const RecordSlot&) = default;
  RecordSlot& operator=(const RecordSlot& other) noexcept {
    record = other.record;
    return *this;
  }
};

/// Also the Modbus server's way into the cycle (modbus::SupervisorTarget): commands and
/// proposals go to the cycle's lock-free mailboxes, the snapshot is published by the cycle
/// thread after every cycle (LatestValue; the Modbus thread is its only reader).
class Runtime final : public modbus::SupervisorTarget {
 public:
  using FtRing = handover::SpscRing<rtio::FtSample, 256>;     // 0.5 s at 500 Hz
  using ImuRing = handover::SpscRing<rtio::ImuSample, 1024>;  // 0.5 s at 2 kHz
  using RecordRing = handover::SpscRing<RecordSlot, 4096>;    // 16 s at 4 ms

  Runtime(RuntimeOptions options, RuntimeDevices devices);
  ~Runtime();  ///< stop()
  Runtime(const Runtime&) = delete;
  Runtime& operator=(const Runtime&) = delete;

  /// Start-up: the loop's configuration and model; `path` for collection mode (not owned).
  /// ok(); not_ready without a robot link; invalid_setting for a telemetry setting (named
  /// "telemetry.<field>") or a configuration the loop refuses (loop::Cycle::configure's status:
  /// the CycleConfig field, e.g. "limits.max_speed_mps", or "model: …").
  Status configure(const loop::CycleConfig& config, infer::DeployedModel model,
                   const loop::JointPath* path = nullptr);

  /// Opens the recorder, locks memory (if configured), starts the threads. ok(), or
  /// already_started, or system_error (the recorder, a thread), or the telemetry channel's and
  /// the Modbus server's failures (a refused setting named as in the file: "telemetry.peers",
  /// "modbus.port"); `warnings` gets the real-time set-up warnings (system_error, each naming
  /// its [realtime] key: realtime.lock_memory, realtime.priority, realtime.cpu).
  Status start(std::vector<Status>& warnings);

  /// The cycle thread's loop body: one robot cycle (or one lost one). Real-time safe.
  void cycle_once() noexcept;

  /// A command for the next cycle (any thread): its ticket, 0 if one is already pending.
  std::uint64_t request(loop::Command c) noexcept override { return cycle_.request(c); }
  loop::CommandOutcome command_outcome(std::uint64_t ticket) const noexcept override {
    return cycle_.command_outcome(ticket);
  }

  // modbus::SupervisorTarget (the Modbus server's thread).
  modbus::SupervisorSnapshot snapshot() const override;
  bool propose(const loop::Tunables& t) noexcept override { return cycle_.propose(t); }
  loop::ProposalStatus proposal_status() const noexcept override {
    return cycle_.proposal_status();
  }
  bool withdraw_proposal() noexcept override { return cycle_.withdraw_proposal(); }
  /// The tunables of configure() (the cycle's own copy is the cycle thread's).
  loop::Tunables tunables() const override { return supervision_.configured_tunables; }

  /// Main thread, every few ms: --enable-zero-g and --collect requests, announcements.
  SupervisorEvents supervise();
  /// True once a --collect path has been followed to its end.
  bool collection_finished() const { return supervision_.announcer.collection_finished(); }
  /// Lockstep: true once the emulator ended the run or the lockstep failed (see summary).
  bool lockstep_finished() const { return lockstep_.finished.load(std::memory_order_acquire); }
  /// The once-a-second status line (main thread).
  std::string status_line();

  /// Stops the threads in order (cycle, sensors, recorder: it drains and renames its files).
  /// Idempotent. ok(), or system_error with the recorder's error (the recording stopped early or
  /// could not be finished).
  Status stop();

  /// The run's summary as JSON text (after stop(); proto/rt_config.md, "Summary").
  std::string summary_json() const;
  /// Black-box dumps written so far (after stop()).
  const std::vector<std::filesystem::path>& black_box_paths() const {
    return recorder_side_.black_box_paths;
  }
  /// True while a frozen black box waits for the recorder thread's dump (its file may already
  /// exist: the hand-back follows the rename). The box is released only after that.
  bool black_box_pending() const {
    return handover_.box_state.load(std::memory_order_acquire) == 1;
  }

  // Test hooks. The rings' producer side is the sensor thread's; use them only without one.
  FtRing& ft_ring() { return *handover_.ft; }
  ImuRing& imu_ring() { return *handover_.imu; }
  RecordRing& record_ring() { return *handover_.records; }
  const loop::Cycle& cycle() const { return cycle_; }
  const CycleThreadCounters& cycle_thread_counters() const { return cycle_side_.counters; }
  const LatencyHistogram& compute_histogram() const { return cycle_side_.compute_ns; }
  const Recorder* recorder() const { return recorder_side_.recorder.get(); }
  /// The telemetry channel, if configured.
  const telemetry::TelemetryChannel* telemetry() const { return supervision_.telemetry.get(); }
  /// The Modbus server, if configured and started.
  const modbus::ModbusServer* modbus_server() const { return supervision_.modbus.get(); }

 private:
  /// The supervisor snapshot from the cycle just run (cycle thread).
  void update_snapshot(std::int64_t t_received_ns) noexcept;
  /// stop()'s answer: the recorder thread's error, if any.
  Status recorder_result() const;
  void cycle_loop();
  void ft_loop();
  void imu_loop();
  void recorder_loop();
  void discard_samples() noexcept;
  void after_cycle() noexcept;
  /// The cycle's body once receive() has returned (real time and lockstep).
  void handle_received(rtio::RobotReceiveStatus received) noexcept;
  /// Lockstep: one emulator event (proto/lockstep.md).
  void lockstep_once() noexcept;
  void lockstep_fail(const char* what) noexcept;
  /// Lockstep: hands the event's production to the sensor threads and waits until they read it.
  void lockstep_sensors(const rtio::LockstepEvent& event) noexcept;
  /// Lockstep: --enable-zero-g / --collect requested by the cycle thread (deterministic).
  void lockstep_auto_request() noexcept;
  /// --enable-zero-g / --collect: requests the command when idle and ready, once per cycle.
  /// One rule for the main thread (real time) and the cycle thread (lockstep).
  void auto_request(loop::State state, bool ready, std::uint64_t cycle, bool& requested,
                    std::uint64_t& requested_at) noexcept;
  void ft_loop_lockstep();
  void imu_loop_lockstep();

  // What Runtime wires (set at construction and configure()). The cycle is the cycle thread's;
  // the other threads reach it only through its lock-free mailboxes (request, propose).
  RuntimeOptions options_;
  RuntimeDevices devices_;
  loop::Cycle cycle_;
  const loop::JointPath* path_ = nullptr;

  /// Between the threads, lock-free, one writer and one reader each.
  struct Handover {
    std::unique_ptr<FtRing> ft = std::make_unique<FtRing>();               ///< F/T thread → cycle
    std::unique_ptr<ImuRing> imu = std::make_unique<ImuRing>();            ///< IMU thread → cycle
    std::unique_ptr<RecordRing> records = std::make_unique<RecordRing>();  ///< cycle → recorder
    handover::LatestValue<CycleStatus> cycle_status;                       ///< cycle → main
    handover::LatestValue<RecorderStatus> recorder_status;                 ///< recorder → main
    /// Cycle → Modbus thread (its read in snapshot() const changes the reader's side).
    mutable handover::LatestValue<modbus::SupervisorSnapshot> supervisor;
    /// Black box: 0 recording, 1 frozen (cycle → recorder), 2 dumped (recorder → cycle).
    std::atomic<std::uint8_t> box_state{0};
  };

  /// The cycle thread's own data: its buffers, timing statistics and what it publishes.
  struct CycleThreadData {
    samples::RobotSample robot_sample;    ///< the robot's message, SI (rtio converts)
    samples::RobotCorrection correction;  ///< the cycle's answer, SI
    rtio::FtSample ft_sample;
    rtio::ImuSample imu_sample;
    RecordSlot slot;
    CycleThreadCounters counters;
    LatencyHistogram compute_ns;
    LatencyHistogram reply_ns;  ///< receive returned → reply sent
    std::uint64_t collections_done = 0;
    /// The supervisor snapshot, with one-second statistics of the cycle's timing.
    modbus::SupervisorSnapshot snapshot;
    SecondWindow second_window;       ///< period, compute p99 and jitter of the last second
    std::uint64_t tunables_seen = 0;  ///< Cycle::tunables_accepted() mirrored
  };

  /// The F/T and IMU threads.
  struct SensorThreadsData {
    SensorThreadCounters counters;
  };

  /// Lockstep (proto/lockstep.md): the cycle thread publishes an event's production, then bumps
  /// tick; each sensor thread reads it up to that production and stores the tick in its done
  /// flag. The cycle thread also makes the --enable-zero-g / --collect requests.
  struct LockstepData {
    rtio::LockstepEvent event{};
    std::atomic<std::uint32_t> tick{0};
    std::atomic<std::uint32_t> ft_done_tick{0}, imu_done_tick{0};
    std::atomic<bool> finished{false};
    LockstepCounters counters;
    bool requested = false;
    bool auto_done = false;
    std::uint64_t requested_at = 0;
  };

  /// The recorder thread: the files, the black-box dumps and the compute-time window.
  struct RecorderThreadData {
    std::unique_ptr<Recorder> recorder;
    std::unique_ptr<RecordSlot> popped = std::make_unique<RecordSlot>();
    std::vector<std::int64_t> compute_window;
    std::vector<std::filesystem::path> black_box_paths;
    std::string error;
    bool failed = false;
  };

  /// Supervision: the main thread (announcements, --enable-zero-g / --collect in real time,
  /// the status line), the Modbus server and the telemetry channel with their own threads.
  struct Supervision {
    explicit Supervision(const RuntimeOptions& options)
        : announcer(options.auto_enable_zero_g, options.auto_collect) {}
    StatusAnnouncer announcer;
    std::uint64_t requested_at = 0;
    bool requested = false;
    CycleStatus last_status;
    RecorderStatus last_recorder_status;
    loop::Tunables configured_tunables;  ///< configure()'s (the Modbus thread reads them)
    mutable modbus::SupervisorSnapshot snapshot_read;  ///< the Modbus thread's copy
    std::unique_ptr<modbus::ModbusServer> modbus;
    std::unique_ptr<telemetry::TelemetryChannel> telemetry;
  };

  /// The threads and how they are stopped (stop(): cycle, sensors, recorder, in that order).
  struct Threads {
    std::atomic<bool> stop_cycle{false}, stop_sensors{false}, stop_recorder{false};
    Thread cycle, ft, imu, recorder;
    bool started = false, stopped = false;
  };

  Handover handover_;
  CycleThreadData cycle_side_;
  SensorThreadsData sensors_;
  LockstepData lockstep_;
  RecorderThreadData recorder_side_;
  Supervision supervision_;
  Threads threads_;
};

}  // namespace zerog::rt
