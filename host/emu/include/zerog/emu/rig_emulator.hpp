#pragma once
// The rig as zerog-rt sees it (proto/emulator.md): the robot controller sending RSI datagrams
// over real UDP every cycle and applying the replies, the payload's physics at the physics rate
// feeding the F/T board and the IMU emulators, scripted pushes and injected faults; a truth row
// per robot cycle and a summary.
//
// Threads: run() steps the physics in a thread of its own, against the monotonic clock (late
// steps are caught up in batches; the worst lag is reported), and runs the robot loop in the
// calling thread on its own clock, whatever the other side does. The controller's interpolator
// and servo run on the physics clock, as a real controller's run on the clock of its IPOC ticks:
// the robot loop hands each tick's correction to the physics thread, which applies it exactly at
// the tick's physics step (waiting for the hand-over if the robot loop is behind), and records
// the truth of each tick there. So the emulated robot's motion depends only on the replies, not
// on how the host schedules the two threads. The devices are optional (the caller serves the
// F/T board on its CAN bus and owns the pty): without them the robot loop and the physics run
// alone, as in the unit tests. Emulator code, not real-time code.
#include <netinet/in.h>

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "zerog/emu/physics.hpp"
#include "zerog/emu/robot.hpp"
#include "zerog/emu/scenario.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/io/model_file.hpp"
#include "zerog/rtio/lockstep.hpp"
#include "zerog/sim/simulator.hpp"

namespace zerog::emu {

class AtiBoard;
class Stim300Emulator;

/// "a.b.c.d:port" (IPv4). Throws std::invalid_argument naming `what` and the text.
sockaddr_in parse_endpoint(const std::string& text, const std::string& what);

struct RigEmulatorOptions {
  std::string robot_bind = "127.0.0.1:49153";  ///< the controller's socket (port 0: any)
  std::string rt_address = "127.0.0.1:49152";  ///< where zerog-rt listens
  double duration_s = 20.0;                    ///< run length; 0: until stopped
  std::string imu_link;  ///< the IMU's symlink, to re-plug after imu_unplug (may be empty)
  std::uint64_t first_ipoc = 1'000'000;
  /// Lockstep (proto/lockstep.md): the unix datagram socket zerog-rt --lockstep connects to;
  /// empty: real time. In lockstep the emulator is zerog-rt's clock: one thread, emulated time.
  std::string lockstep_path;
  /// Lockstep: never let emulated time run ahead of the wall clock (for peers that act on the
  /// wall clock beside zerog-rt: the cell PLC over Modbus, a DDS subscriber). The loop's
  /// exchanges stay exact; only when a peer's action lands depends on the host.
  bool lockstep_paced = false;
};

enum class ReplyStatus : std::uint8_t {
  none,        ///< no reply for this cycle (yet)
  ok,          ///< right IPOC, within the cycle: applied
  late,        ///< right IPOC after the cycle ended: counted, not applied
  wrong_ipoc,  ///< only replies with another IPOC came in this cycle
};
const char* reply_status_name(ReplyStatus status);

enum class CorrectionKind : std::uint8_t { none, rkorr, akorr, both };

/// One row of truth.csv: the robot and the payload at the cycle's tick, physics time t_s (all in
/// B, SI), and what the controller sent and received in that cycle.
struct CycleRecord {
  double t_s = 0.0;  ///< cycle start, s since the run started
  std::uint64_t ipoc = 0;
  bool sent = false;  ///< a well-formed datagram for this cycle went out
  ReplyStatus reply = ReplyStatus::none;
  sim::JointVector q_rad{};
  TcpMotion tcp;
  Eigen::Vector3d v_com_base_mps = Eigen::Vector3d::Zero();
  Eigen::Vector3d push_force_base_N = Eigen::Vector3d::Zero();
  Eigen::Vector3d push_torque_com_base_Nm = Eigen::Vector3d::Zero();
  CorrectionKind correction_kind = CorrectionKind::none;
  /// As received: RKorr X, Y, Z (mm), A, B, C (deg); or AKorr A1..A6 (deg) when only AKorr came.
  std::array<double, 6> correction{};
  std::uint64_t delay = 0;  ///< the Delay D sent in this cycle's datagram
};

/// The rig zerog-rt runs on in this emulation (formats::Rig, the `.rig.toml` of `--write-rig`): the
/// simulator's geometry, named kEmulatorRigName, one row per RSI cycle, IMU at 2 kHz.
inline constexpr const char* kEmulatorRigName = "kr210-omega191-stim300-emu";
formats::Rig emulator_rig(const Scenario& scenario, const sim::RigSimulator& simulator);
/// The truth model file (io::ModelFile, the format `zerog export` reads) for emulator_rig().
io::ModelFile emulator_truth(const Scenario& scenario, const sim::RigSimulator& simulator);

/// The header line of truth.csv (no newline).
std::string truth_csv_header();

class RigEmulator {
 public:
  /// `ft` and `imu` may be null (no devices). Throws std::invalid_argument for bad options or a
  /// scenario the robot or the physics refuse.
  RigEmulator(const Scenario& scenario, const RigEmulatorOptions& options, AtiBoard* ft = nullptr,
              Stim300Emulator* imu = nullptr);
  ~RigEmulator();
  RigEmulator(const RigEmulator&) = delete;
  RigEmulator& operator=(const RigEmulator&) = delete;

  /// Opens and binds the controller's sockets (the main one and the one robot_foreign sends
  /// from). Throws std::runtime_error naming the address and the reason.
  void bind();
  /// The bound port of the main socket (after bind()).
  std::uint16_t robot_port() const;

  /// Runs until the duration has passed or `stop` is set. Call once, after bind().
  void run(const std::atomic<bool>& stop);

  const std::vector<CycleRecord>& cycles() const { return loop_.records; }
  std::string truth_csv() const;
  nlohmann::json summary() const;
  const RobotEmulator& robot() const { return handover_.robot; }
  const PayloadPhysics& physics() const { return physics_; }

 private:
  struct ScheduledSend {
    std::chrono::steady_clock::time_point at;
    std::string bytes;
    bool foreign = false;  // from the second socket
  };
  struct FaultState {
    bool active = false, done = false;
    double applied_start_s = -1.0, applied_end_s = -1.0;
    std::int64_t first_cycle = -1, last_cycle = -1;
    std::uint64_t cycles_hit = 0;  // robot faults: cycles it changed
    std::string note;              // e.g. "no device"
  };
  void physics_loop(const std::atomic<bool>& stop);
  /// Lockstep: the whole run in this thread, on emulated time.
  void run_lockstep(const std::atomic<bool>& stop);
  /// Lockstep: the sends and zerog-rt receive timeouts due before `limit`, in time order; the
  /// replies they bring go to cycle `window`.
  void lockstep_events_before(std::chrono::steady_clock::time_point limit, std::uint64_t window);
  /// Lockstep: tells zerog-rt of one event at `at` and waits until it has handled it and its
  /// replies are in.
  void lockstep_exchange(rtio::LockstepKind kind, std::chrono::steady_clock::time_point at,
                         std::uint64_t window);
  /// The truth of each tick (truth_.ticks) into its record, after the run.
  void merge_tick_truth();
  /// Emulated time in lockstep, else the steady clock.
  std::chrono::steady_clock::time_point now() const;
  /// Physics step k (k = 0: the start state). False if the run stopped while it waited.
  bool physics_step(std::uint64_t k, const std::atomic<bool>& stop);
  void device_faults(double t_s);
  void start_cycle(std::uint64_t n);
  /// The physics step at which tick n's correction takes effect and its truth is taken: the
  /// first at or after t = n · cycle.
  std::uint64_t tick_step(std::uint64_t n) const;
  /// Physics thread, handover_.mutex held: applies the corrections of the ticks at or before step
  /// k, waiting for the robot loop to hand them over. False if it stopped before.
  bool apply_due_corrections(std::uint64_t k, std::unique_lock<std::mutex>& lock,
                             const std::atomic<bool>& stop);
  void apply_correction(const proto::rsi::Reply& reply);
  void handle_datagram(std::uint64_t n, const char* data, std::size_t size);
  void receive_pending(std::uint64_t n);
  /// Sends one scheduled datagram to zerog-rt now (from the foreign port if it is foreign),
  /// counted.
  void transmit(const ScheduledSend& s);
  void send_due(std::chrono::steady_clock::time_point now);
  std::chrono::steady_clock::time_point cycle_start(std::uint64_t n) const;
  // summary()'s parts, one per owner of what they report.
  /// "datagrams", "replies" and "robot": the robot loop's counts, the robot's, its clamps.
  void robot_loop_summary(nlohmann::json& s) const;
  nlohmann::json lockstep_summary() const;
  nlohmann::json pushes_summary() const;
  nlohmann::json faults_summary() const;
  nlohmann::json physics_summary() const;
  nlohmann::json devices_summary() const;

  /// Hands loop_.pending over to the physics thread as tick n's correction (none if empty).
  void hand_over(std::uint64_t n);

  struct Counts {
    std::uint64_t datagrams_sent = 0;  ///< every datagram that went out (malformed included)
    std::uint64_t good_sent = 0;
    std::uint64_t malformed_sent = 0;
    std::uint64_t duplicates_sent = 0;
    std::uint64_t foreign_sent = 0;
    std::uint64_t send_errors = 0;
    std::uint64_t reply_datagrams = 0;
    std::uint64_t ok = 0, late = 0, wrong_ipoc = 0, malformed = 0, duplicate = 0;
    std::uint64_t from_elsewhere = 0;   ///< replies from an address other than rt_address
    std::uint64_t foreign_replies = 0;  ///< replies to the foreign socket
    std::uint64_t before_first_ok = 0;
    std::int64_t first_ok_cycle = -1;
  };
  /// The truth of one tick, as the physics thread took it at tick_step(n).
  struct TickTruth {
    sim::JointVector q_rad{};
    TcpMotion tcp;
    Eigen::Vector3d v_com_base_mps = Eigen::Vector3d::Zero();
    Eigen::Vector3d push_force_base_N = Eigen::Vector3d::Zero();
    Eigen::Vector3d push_torque_com_base_Nm = Eigen::Vector3d::Zero();
  };
  struct LockstepCounts {
    std::uint64_t events = 0, datagram_events = 0, timeout_events = 0;
    double slowest_ack_s = 0.0;  ///< real time zerog-rt took for one event (information)
  };

  Scenario scenario_;
  RigEmulatorOptions options_;

  // Set by the constructor, t0 by run() before the physics thread starts; read by every thread
  // after that, never written.
  struct Setup {
    AtiBoard* ft = nullptr;
    Stim300Emulator* imu = nullptr;
    bool lockstep = false;  // options_.lockstep_path given: one thread, emulated time
    std::uint64_t cycle_ms = 12;
    std::uint64_t cycles_total = 0;  // 0: until stopped
    std::chrono::steady_clock::time_point t0{};
  } setup_;

  // Opened by bind(), closed by the destructor. The robot loop (in lockstep: the one thread) is
  // the only one to send or receive; the physics thread never touches a socket.
  struct Sockets {
    sockaddr_in bind_addr{};
    sockaddr_in rt_addr{};
    int fd = -1;
    int foreign_fd = -1;
    std::uint16_t robot_port = 0;
    int lockstep_fd = -1;
    std::string lockstep_bound;       // the socket file this emulator made (removed at destruction)
    std::vector<char> lockstep_peer;  // zerog-rt's address (sockaddr_un bytes), from its hello
  } sockets_;

  // Shared by the robot loop and the physics thread, everything but robot_done under `mutex`:
  // the robot, and each tick's correction (or none) handed over from the robot loop to the
  // physics thread, in tick order from tick 1 (tick 0 starts the run, nothing to apply).
  // summary() and robot() read the robot after the run.
  struct Handover {
    explicit Handover(const RobotConfig& config) : robot(config) {}
    mutable std::mutex mutex;
    RobotEmulator robot;
    std::deque<std::optional<proto::rsi::Reply>> handed;
    std::uint64_t ticks_handed = 0;  // ticks 1..ticks_handed are in handed or applied
    std::condition_variable handed_cv;
    std::atomic<bool> robot_done{false};  // set by run() to end the physics thread
  } handover_;

  PayloadPhysics physics_;  // stepped by the physics thread only (evaluate() is const)

  // The robot loop's (run()'s thread; in lockstep: the one thread); read by summary(), cycles()
  // and truth_csv() after the run.
  struct RobotLoopState {
    std::vector<CycleRecord> records;
    std::vector<ScheduledSend> sends;
    std::uint64_t delay_count = 0;
    /// The timely reply of the cycle, applied at the next cycle's tick.
    std::optional<proto::rsi::Reply> pending;
    bool any_ok = false;
    std::int64_t reorder_held = -1;  // cycle whose datagram is held for after the next one
    std::string held_bytes;
    Counts counts;
    std::uint64_t stale_datagrams = 0;  // datagrams made while the physics was behind the tick
    double worst_datagram_lag_s = 0.0;
  } loop_;

  std::vector<FaultState> faults_;  // per scenario fault; robot faults: robot loop, devices:
                                    // physics thread (read after it is joined)

  // The physics thread's (in lockstep: the one thread); read after it is joined, but
  // physics_steps_done, which the robot loop reads while it runs. After the join run() adds the
  // clamps of the corrections the physics did not reach.
  struct PhysicsThreadState {
    std::uint64_t next_apply_tick = 1;
    std::uint64_t handover_waits = 0;  // steps that waited for the robot loop's hand-over
    std::uint64_t clamped_cycles = 0, near_singular_cycles = 0;
    double worst_lag_s = 0.0;
    std::uint64_t late_batches = 0;
    std::uint64_t largest_batch = 0;
    std::uint64_t imu_samples = 0;
    std::uint64_t imu_dropped = 0;
    std::atomic<std::uint64_t> physics_steps_done{0};  // the last physics step evaluated
  } physics_thread_;

  // The truth of each tick, taken by the physics thread at tick_step(n), under `mutex` (run()
  // reads how many there are while it waits for the last); merged into loop_.records after the
  // run.
  struct TruthTicks {
    std::mutex mutex;
    std::vector<TickTruth> ticks;
  } truth_;

  // Lockstep only: run_lockstep's, the one thread; summary() reads it after the run.
  struct LockstepState {
    std::chrono::steady_clock::time_point now{};
    std::chrono::steady_clock::time_point last_rt_event{};  // zerog-rt's last receive returned
    std::chrono::nanoseconds rt_receive_timeout{0};
    std::chrono::nanoseconds rt_ft_sample_timeout{0};
    double ft_rate_hz = 0.0;
    std::uint64_t ft_produced = 0;
    const std::atomic<bool>* stop = nullptr;  // run()'s stop flag
    LockstepCounts counts;
  } lockstep_;
};

}  // namespace zerog::emu
