#pragma once
// One cycle of zerog-rt, without I/O (proto/loop.md). The program (firmware/rt) hands it the
// sensor samples that arrived since the last cycle and the robot's datagram; the cycle predicts
// the payload's wrench, takes the contact wrench (measured − predicted), runs the state machine,
// the watchdogs and the zero-g motion, and returns the reply for the robot. Every robot message
// gets a reply with its IPOC (a zero correction unless zero-g or collection is running).
//
// Time alignment: each cycle's row holds the mean of the F/T and IMU samples that arrived during
// the cycle (the log format's row, proto/log_format.md). The angular acceleration is the central
// difference of the gyroscope rows (model::angular_accel_central), so the model is evaluated on
// the row `delay_rows()` cycles back (2 for the 5-point stencil, 1 for the 3-point one): the
// contact wrench is that many cycles late and less noisy (proto/loop.md, "Noise and delay").
//
// Units: the cycle sees SI only (docs/STYLE.md habit 13). The robot's message comes in as a
// samples::RobotSample (m, rad, rotation matrices) and the answer goes out as a
// samples::RobotCorrection; zerog::rtio converts from and to the wire's KUKA units
// (zerog/proto/rsi_si.hpp), once per message each way. The record keeps the reply in SI too
// (CycleRecord::reply); cycles.csv's writer (zerog/formats/cycles_csv.hpp) and telemetry convert
// it to their units outside the cycle.
//
// Structure (docs/STYLE.md habit 14): the configuration (CycleConfig, const between configure() and
// an accepted proposal) and per-cycle data (CycleData: one part per stage), and stage functions
// (namespace stages) that take both and name their outputs. step() calls them in order: timing
// → row → watchdogs → model → model watchdog → motion → record.
//
// Life cycle (docs/STYLE.md habit 3): construct and configure() at start-up (may allocate, may fail
// with a zerog::Status); add_*/robot_* and step() every cycle: no allocation, no exceptions, no
// locks.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <numbers>
#include <optional>
#include <string>

#include "zerog/control/motion.hpp"
#include "zerog/infer/inference.hpp"
#include "zerog/loop/black_box.hpp"
#include "zerog/loop/cycle_record.hpp"
#include "zerog/loop/motion_estimator.hpp"
#include "zerog/loop/state_machine.hpp"
#include "zerog/model/dictionary.hpp"
#include "zerog/robot/robot_model.hpp"
#include "zerog/samples/robot_sample.hpp"
#include "zerog/samples/sensor_samples.hpp"
#include "zerog/status.hpp"

namespace zerog::loop {

/// Watchdog thresholds, in cycles (proto/loop.md, "Watchdogs"). A count of consecutive bad cycles
/// below the threshold holds (the last good value is reused and the cycle is flagged); reaching
/// it raises the fault, and from then on every reply is a zero correction.
struct WatchdogConfig {
  int ft_fault_cycles = 5;     ///< cycles in a row without a valid F/T sample
  int imu_fault_cycles = 5;    ///< cycles in a row without a valid IMU sample (rate and accel)
  int robot_fault_cycles = 3;  ///< robot cycles lost in a row (timeout, malformed, IPOC gap)
  int robot_late_cycles = 3;   ///< messages in a row whose Delay grew (our replies came late)
  int model_fault_cycles = 1;  ///< cycles in a row the model could not be evaluated
};

/// A joint-space path for collection mode (e.g. a `zerog design` path as a PTP trajectory).
/// at() must be real-time safe.
class JointPath {
 public:
  virtual ~JointPath() = default;
  virtual double duration_s() const = 0;
  /// Joint angles A1..A6 (rad) at t seconds after the start of the path (clamped to the ends).
  virtual std::array<double, 6> at(double t_s) const = 0;
};

struct CycleConfig {
  double period_s = 0.012;      ///< nominal robot cycle (RSI: 0.004 or 0.012)
  double ipoc_unit_s = 0.001;   ///< IPOC counts milliseconds (KUKA)
  int angular_accel_order = 4;  ///< 4: 5-point central difference (delay 2 rows); 2: 3-point (1)
  /// The payload's motion the model reads (motion_estimator.hpp): `fused` (the robot's poses
  /// and joints, the IMU below the crossover) or `imu` (the IMU as it comes). The same rows
  /// either way: the model is evaluated delay_rows() back.
  MotionEstimatorConfig motion;
  /// Sensor temperature fed to the model until the F/T sensor reports its own (FtSample::
  /// temperature_valid: the NETCANOEM thermistor with a configured conversion), and always when
  /// it never does. The sensor's reading wins: it is the temperature of the part that drifts.
  /// A reading the sensor reports stale (too old) is dropped: this value again, kTemperatureStale.
  double temperature_C = 25.0;
  /// The contact's tare (proto/loop.md, "The tare"): each time zero-g is entered, the mean
  /// contact wrench over the first tare_s seconds of trusted rows (after the motion estimator
  /// has settled) is taken as the contact's zero and subtracted from then on; until it is taken
  /// no push is confirmed (kContactTaring). A push held that long restarts it. 0: off.
  double tare_s = 0.0;
  /// TEST ONLY (zerog-rt --test-mutant tare_unguarded): a push held while the tare is taken
  /// does not start it again, so the hand's force becomes the contact's zero.
  bool mutant_tare_unguarded = false;
  WatchdogConfig watchdog;
  control::BodyParams body;      ///< the virtual body
  control::MotionLimits limits;  ///< deadbands, force limit, speed/accel/workspace limits
  Eigen::Vector3d p_sensor_com_m{0.0, 0.0, 0.0};  ///< virtual centre of mass, sensor frame
  /// Collection mode: the largest axis correction per cycle (rad): a path that would need more
  /// is followed late (never jumps). The approach to the path's first point runs at most at
  /// approach_speed_radps per axis with approach_accel_radps2.
  double max_axis_step_rad = 0.01;
  double approach_speed_radps = 0.2;
  double approach_accel_radps2 = 0.5;
  /// The arm (the running rig's robot, proto/robot_kinematics.md; its flange_sensor is the
  /// rig's, so robot::sensor_pose gives the F/T sensor frame S in the base frame B, the frame
  /// RIst reports as the TCP). With it, a message without <RIst> takes the sensor pose from
  /// AIPos by forward kinematics, and a message with both is checked: RIst and the kinematics
  /// disagree when their positions are further apart than pose_check_position_m or their
  /// rotations differ by more than pose_check_angle_rad (kPoseDisagrees, counted; RIst is
  /// used). Without it, a message without RIst carries no pose (kPoseMissing). 6 joints, A1..A6.
  std::optional<robot::RobotModel> robot;
  double pose_check_position_m = 1e-3;                             ///< 1 mm
  double pose_check_angle_rad = 0.1 * (std::numbers::pi / 180.0);  ///< 0.1°
};

/// What a supervisor (the cell PLC over Modbus) may change, only while the cycle is idle: the
/// virtual body, the motion limits and the virtual centre of mass (CycleConfig's fields).
struct Tunables {
  control::BodyParams body;
  control::MotionLimits limits;
  Eigen::Vector3d p_sensor_com_m{0.0, 0.0, 0.0};  ///< virtual centre of mass, sensor frame
};

/// The fate of the last Cycle::propose().
/// What became of a command (Cycle::command_outcome of its ticket).
enum class CommandOutcome : std::uint8_t {
  pending,   ///< not applied yet (the next step() applies it)
  accepted,  ///< the state machine took it
  refused,   ///< refused in that cycle (kCommandRefused, counted)
  unknown,   ///< so many commands came after it that its outcome is no longer kept
};

enum class ProposalStatus : std::uint8_t {
  none,             ///< nothing proposed (or withdrawn)
  pending,          ///< waiting for the next step() or robot_lost()
  accepted,         ///< in use from that cycle on
  refused_state,    ///< not idle: nothing changed
  refused_invalid,  ///< inconsistent values (check_tunables()): nothing changed
};

/// What check_tunables() found: the field it concerns, named as in CycleConfig ("body.mass_kg",
/// "limits.max_speed_mps", "p_sensor_com_m"), and why, without the field's name ("must be
/// positive"); both "" when the tunables can be used. Static strings.
struct TunablesCheck {
  const char* setting = "";
  const char* message = "";
  bool ok() const noexcept { return *message == '\0'; }
};

/// Whether tunables can be used: positive mass, symmetric positive-definite inertia, finite
/// centre of mass, consistent limits. The first field refused, in that order. Real-time safe
/// (no allocation: static strings).
TunablesCheck check_tunables(const Tunables& t) noexcept;

/// Whether `config` can be used (Cycle::configure checks it first): ok(), or invalid_setting
/// naming the refused field as a path in CycleConfig ("period_s", "watchdog.ft_fault_cycles",
/// "limits.max_speed_mps", "body.inertia_body_kgm2", "robot.joints[2].sign") with why. A program
/// that reads the configuration from a file maps the path to the file's key (zerog-rt's
/// rt/config.cpp). Start-up only: not real-time safe (a failure allocates).
zerog::Status check_config(const CycleConfig& config);

/// Why a robot cycle was lost (robot_lost()).
enum class RobotLoss : std::uint8_t { timeout, malformed };

struct CycleCounters {
  std::uint64_t messages = 0;
  std::uint64_t robot_timeouts = 0;
  std::uint64_t robot_malformed = 0;
  std::uint64_t ipoc_gaps = 0;       ///< messages after a gap
  std::uint64_t datagrams_lost = 0;  ///< sum of the gaps (in periods)
  std::uint64_t ipoc_stale = 0;      ///< duplicates and reordered messages
  std::uint64_t ft_samples = 0;      ///< valid F/T samples used
  std::uint64_t ft_invalid = 0;      ///< F/T samples not used (critical, saturated)
  std::uint64_t ft_held_cycles = 0;
  std::uint64_t imu_samples = 0;
  std::uint64_t imu_invalid = 0;
  std::uint64_t imu_held_cycles = 0;
  std::uint64_t sample_overflow = 0;  ///< samples beyond one cycle's accumulator (not averaged)
  std::uint64_t model_saturated = 0;
  std::uint64_t commands_refused = 0;
  /// Faults whose cycles could not be kept: the black box still held an earlier fault that had
  /// not been dumped and released yet.
  std::uint64_t black_boxes_lost = 0;
  std::uint64_t poses_from_joints = 0;   ///< messages without RIst: pose by forward kinematics
  std::uint64_t pose_disagreements = 0;  ///< RIst and the kinematics disagreed (kPoseDisagrees)
  std::uint64_t poses_missing = 0;       ///< messages without RIst and no robot (kPoseMissing)
  /// Cycles whose F/T temperature reading was stale (kTemperatureStale): configured one used.
  std::uint64_t temperature_stale_cycles = 0;
};

/// The stages of one cycle and the data each keeps from cycle to cycle (proto/loop.md, "One
/// cycle"). Every function here is real-time safe (no allocation, no exceptions, no locks); none
/// touches the state machine, the black box or another stage's data: what a stage decides (a
/// fault to raise, flags for the record) is in its output, and Cycle::step acts on it.
namespace stages {

inline constexpr int kHistory = 8;      ///< rows kept (≥ 2 × delay + 1)
inline constexpr int kMaxWindow = 256;  ///< samples averaged per cycle at most

/// One cycle's row (the log format's row, proto/log_format.md): inputs of the model.
struct Row {
  model::FeatureSignals signals;   ///< imu[6..8] (angular acceleration) filled when centred
  std::array<double, 6> wrench{};  ///< F/T, sensor frame, N / N·m
  double t_s = 0.0;
  std::uint32_t held = 0;             ///< kFtHeld | kImuHeld of the cycle that made the row
  int ft_n = 0, imu_n = 0;            ///< samples in the row's means (0: held)
  bool temperature_measured = false;  ///< signals.temperature_C is the F/T sensor's reading
  double temperature_age_s = 0.0;     ///< its age when it came with a sample, s
};

/// The sums of the samples that arrived since the last row (Cycle::add_ft, add_imu).
struct SensorWindow {
  std::array<double, 6> ft_sum{};
  int ft_n = 0, ft_critical = 0, ft_saturated = 0, ft_warning = 0;
  std::array<double, 6> imu_sum{};  ///< specific force (3), rate (3)
  int imu_n = 0;
  bool have_temperature = false;  ///< an F/T sample of this window carried a temperature
  double temperature_C = 0.0;     ///< the latest of them, °C
  double temperature_age_s = 0.0;
  bool temperature_stale = false;  ///< the latest said its temperature is stale (none then)
};

// --- per-cycle data, one part per stage ---------------------------------------------------------

/// timing(): the robot's clock as the messages tell it.
struct ClockData {
  bool have_ipoc = false;
  std::uint64_t first_ipoc = 0, last_ipoc = 0;
  bool have_delay = false;
  std::uint64_t last_delay = 0;
};

/// assemble_row(): the rows so far and the last good sensor values (held when none came).
struct RowData {
  std::array<Row, kHistory> rows{};
  std::uint64_t total = 0;  ///< rows made so far; the newest is rows[(total − 1) % kHistory]
  std::array<double, 6> last_wrench{};
  std::array<double, 6> last_imu{};  ///< specific force (3), rate (3)
  bool have_ft = false, have_imu = false;
  bool have_temperature = false;  ///< the F/T sensor has reported a temperature (held since)
  double temperature_C = 0.0;
  double temperature_age_s = 0.0;
  bool temperature_stale = false;  ///< ... and then said it is stale: dropped until the next
  Row& newest() { return rows[(total - 1) % kHistory]; }
  const Row& newest() const { return rows[(total - 1) % kHistory]; }
};

/// The watchdogs' runs of bad cycles (proto/loop.md, "Watchdogs").
struct WatchdogData {
  int robot_lost_run = 0, robot_late_run = 0;
  int ft_bad_run = 0, imu_bad_run = 0, model_bad_run = 0;
  Fault ft_bad_reason = Fault::ft_stale;
};

/// evaluate_model(): the last evaluation (kept while the model is not evaluated).
struct ModelData {
  infer::StatusCode status = infer::StatusCode::not_configured;
  double t_eval_s = 0.0;
  std::array<double, 6> wrench_at_eval{};
  /// The signal dictionary's kinematics of that evaluation (the centre row's signals and their
  /// central differences). Kept here and rewritten in place, not built afresh every cycle.
  model::KinematicInputs kinematics;
  /// The payload's motion under MotionSource::fused (configured by Cycle::configure).
  MotionEstimator estimator;
  MotionEstimate estimate;  ///< its last update
};

/// tare_contact(): the contact's zero in this spell of zero-g (CycleConfig::tare_s).
struct TareData {
  bool taken = false;              ///< the zero below is being subtracted
  int rows = 0;                    ///< rows summed so far (while not taken)
  double t_s = 0.0;                ///< their time (the rows' dt)
  int over_run = 0;                ///< rows in a row the contact gate would have counted
  std::array<double, 6> sum{};     ///< Σ contact over those rows, sensor frame, N / N·m
  std::array<double, 6> offset{};  ///< the zero taken, sensor frame, N / N·m
};

/// run_motion() in collection mode: approach the path's start, then follow it.
struct CollectionData {
  bool on_path = false;
  double t_s = 0.0;
  std::array<double, 6> cmd_rad{};  ///< joints commanded so far (start + Σ AKorr)
  std::array<double, 6> v_radps{};  ///< approach speed per axis
};

// --- stage outputs ------------------------------------------------------------------------------

/// Faults a stage asks for, in the order found (the first one raised wins).
struct FaultRequests {
  std::array<Fault, 4> faults{};
  int count = 0;
  void add(Fault f) noexcept { faults[static_cast<std::size_t>(count++)] = f; }
};

struct Timing {
  bool stale = false;  ///< IPOC not newer than the last one: answer zero, change nothing
  double dt_s = 0.0;   ///< time step for the body and the row (at most 4 periods)
  double t_s = 0.0;    ///< robot time since the first message
  std::uint64_t lost_periods = 0;  ///< periods lost right before this message (IPOC gap)
  bool has_delay = false;          ///< the message had a Delay
  bool delay_grew = false;         ///< ... and it grew since the last one
  std::uint32_t flags = 0;         ///< kIpocStale, kIpocGap, kRobotDelayGrew
};

/// What the sensors gave this cycle (the watchdogs judge it).
struct SensorCounts {
  int ft_n = 0, ft_critical = 0, ft_saturated = 0;
  int imu_n = 0;
};

struct RowResult {
  std::uint32_t flags = 0;  ///< kFtHeld, kImuHeld, kFtWarning, kPose…, kTemperatureStale
  Eigen::Matrix3d R_base_sensor = Eigen::Matrix3d::Identity();  ///< the new row's, S in B
  double pose_check_m = 0.0;  ///< RIst against the kinematics (CycleRecord::pose_check_*)
  double pose_check_rad = 0.0;
  SensorCounts sensors;
};

struct ModelResult {
  bool evaluated = false;   ///< the model was run this cycle (enough rows, both sensors seen)
  bool written = false;     ///< ... and gave a prediction
  bool ready = false;       ///< a prediction from fresh samples: enable_zero_g may be accepted
  std::uint32_t flags = 0;  ///< kNotReady, kModelSaturated, kContactHeld
  std::array<double, 6> predicted{};  ///< sensor frame, N / N·m (zero unless written)
  std::array<double, 6> contact{};    ///< measured − predicted (zero unless written, not held)
};

/// A command taken from Cycle::request() for this cycle.
struct PendingCommand {
  bool present = false;
  Command command = Command::stop;
  std::uint64_t ticket = 0;
};

struct MotionResult {
  samples::RobotCorrection correction;  ///< the answer, IPOC 0 (zero in fault)
  std::uint32_t flags = 0;              ///< kCommandRefused, kCollectionDone
  std::uint32_t limit_flags = 0;        ///< control::LimitFlags of the zero-g step
  bool command_accepted = false;        ///< for the command's outcome
  Fault fault = Fault::none;            ///< contact over its limit
};

// --- the stages, in the order step() calls them -------------------------------------------------

/// The message's time: dt from the IPOC difference (clamped to 4 periods), gaps and stale
/// messages (counted), the Delay counter. A stale message changes nothing but its counter.
Timing timing(const CycleConfig& config, const samples::RobotSample& message, ClockData& clock,
              CycleCounters& counters) noexcept;

/// This cycle's row: joints (rad) and their speed, the sensor pose S in B (RIst, or the
/// kinematics of the joints; checked against each other), the mean of the window's samples or
/// the last ones held. Empties the window.
RowResult assemble_row(const CycleConfig& config, const samples::RobotSample& message,
                       const Timing& timing, SensorWindow& window, RowData& rows,
                       CycleCounters& counters) noexcept;

/// Robot (IPOC gap, growing Delay) and sensor (F/T, IMU) watchdogs: runs of bad cycles against
/// their thresholds. `state` is the state at the start of the cycle.
FaultRequests watch_robot_and_sensors(const WatchdogConfig& config, State state,
                                      const Timing& timing, const SensorCounts& sensors,
                                      const RowData& rows, WatchdogData& runs) noexcept;

/// The model on the row delay_rows() back (angular acceleration by central difference, IMU time
/// offset, kinematics for the signal dictionary) and the contact wrench.
ModelResult evaluate_model(const CycleConfig& config, infer::Inference& inference, bool use_network,
                           RowData& rows, ModelData& model, CycleCounters& counters) noexcept;

/// The contact's tare (CycleConfig::tare_s; proto/loop.md, "The tare"). Outside zero-g
/// (`state`, the state before this cycle's command) it forgets its zero, and flags the row
/// kContactTaring if this cycle's command is `enabling` zero-g (the body steps on that row).
/// In zero-g, until the zero is taken, the row is flagged so and, when its contact is trusted
/// (written, not held, the estimator settled), summed, unless the contact gate would count it
/// (`limits`' thresholds, the torque as the gate judges it about `p_sensor_com_m`);
/// contact_confirm_cycles such rows in a row start the sum again: a hand on the part is not its
/// zero. After tare_s of rows the mean is the zero; from that row on it is subtracted from every
/// written contact.
void tare_contact(const CycleConfig& config, State state, bool enabling, const Timing& timing,
                  ModelResult& model, TareData& tare) noexcept;

/// The model watchdog: runs of cycles whose evaluation failed.
FaultRequests watch_model(const WatchdogConfig& config, const ModelResult& model,
                          WatchdogData& runs) noexcept;

/// What run_motion() reads: this cycle's number, the collection path and the earlier stages'
/// outputs. References to the caller's values (nothing is copied); build it with designated
/// initialisers, which name every field.
struct MotionInputs {
  const JointPath* path;          ///< collection mode's path (null: none set)
  std::uint64_t cycle;            ///< this cycle's number (state transitions are stamped with it)
  const PendingCommand& command;  ///< the command taken for this cycle (present or not)
  const Timing& timing;           ///< dt for the body and the path
  const Row& now;                 ///< this cycle's row: the pose and joints to start from
  const RowResult& row;           ///< the row's R_base_sensor
  const ModelResult& model;       ///< contact wrench (sensor frame), ready
  const ModelData& model_data;    ///< the last evaluation's status
};

/// What run_motion() changes besides its result: the state machine (commands, collection's
/// end), the virtual body, collection's progress, the watchdogs' runs (reset_fault clears them)
/// and the counters.
struct MotionState {
  StateMachine& sm;
  control::ZeroGMotion& zero_g;
  CollectionData& collection;
  WatchdogData& runs;
  CycleCounters& counters;
};

/// The command of this cycle (if any) and the state's motion: idle follows the sensor, zero-g
/// steps the virtual body with the contact wrench, collection follows `in.path`. A correction
/// (SI) only in zero-g and collection; none in fault.
MotionResult run_motion(const CycleConfig& config, const MotionInputs& in,
                        const MotionState& state) noexcept;

/// What make_record() reads: every stage's output and the state after the cycle. References, as
/// MotionInputs.
struct RecordInputs {
  std::uint64_t cycle;
  const samples::RobotSample& message;
  const Timing& timing;
  const Row& now;
  const RowResult& row;
  const ModelResult& model;
  const ModelData& model_data;
  const MotionResult& motion;
  const StateMachine& sm;
  const control::ZeroGMotion& zero_g;
};

/// The cycle's record from `in`, except `record.reply`: Cycle::step writes the reply sent there
/// (SI, no conversion in the cycle) and make_record leaves it. compute_ns is 0 (the program
/// fills it in).
void make_record(const RecordInputs& in, CycleRecord& record) noexcept;

}  // namespace stages

/// The per-cycle data: what the stages keep from one cycle to the next.
struct CycleData {
  stages::SensorWindow window;
  stages::ClockData clock;
  stages::RowData rows;
  stages::WatchdogData watchdogs;
  stages::ModelData model;
  stages::CollectionData collection;
  stages::TareData tare;
};

class Cycle {
 public:
  /// The black box: at 4 ms, the last second; at 12 ms, the last three.
  static constexpr std::size_t kBlackBoxCycles = 256;
  using Box = BlackBox<CycleRecord, kBlackBoxCycles>;

  /// Start-up: validates the configuration (check_config) and takes the model
  /// (Inference::configure). Returns ok(), or invalid_setting: check_config's, naming the
  /// CycleConfig field, or the model's refusal (infer::validate_model) with its field under
  /// "model." ("model.rig.name"). On failure nothing changes. Not real-time safe.
  zerog::Status configure(const CycleConfig& config, infer::DeployedModel model);
  const CycleConfig& config() const { return config_; }
  /// Rows between the newest row and the one the model is evaluated on.
  int delay_rows() const { return config_.angular_accel_order / 2; }

  /// Collection mode follows this path (not owned; must outlive the cycle). Not real-time safe
  /// to change while collecting: set it in idle. With a path set, every reply is an axis
  /// correction (AKorr; zeros when not collecting) and enable_zero_g is refused: the
  /// controller's RSI context for a collection takes AKorr only (proto/loop.md, step 7).
  void set_collection_path(const JointPath* path) { path_ = path; }

  // --- every cycle (real-time safe) ---------------------------------------------------------
  /// A sample that arrived since the last cycle (valid or not: invalid ones count toward the
  /// watchdog's reason).
  void add_ft(const samples::FtSample& s) noexcept;
  void add_imu(const samples::ImuSample& s) noexcept;
  /// A command (Modbus, CLI), applied at the start of the next step(). Returns its ticket
  /// (≥ 1) for command_outcome(), or 0 if one is already pending. Any thread, lock-free.
  std::uint64_t request(Command c) noexcept;
  /// The outcome of the command with this ticket (any thread, lock-free). The last
  /// kCommandOutcomes outcomes are kept.
  CommandOutcome command_outcome(std::uint64_t ticket) const noexcept;
  static constexpr std::size_t kCommandOutcomes = 8;
  /// New tunables (any one thread, e.g. the Modbus server): taken at the start of the next
  /// step() or robot_lost(), accepted only in State::idle and if check_tunables() passes; the
  /// outcome is proposal_status(). Returns false (and changes nothing) while one is pending.
  bool propose(const Tunables& t) noexcept;
  ProposalStatus proposal_status() const noexcept;
  /// Takes back a proposal the cycle has not taken yet (e.g. the proposer gave up waiting).
  /// True if withdrawn; false if the cycle already decided (see proposal_status()).
  bool withdraw_proposal() noexcept;
  /// The tunables in use (the cycle's thread, or when it is not running).
  Tunables tunables() const { return {config_.body, config_.limits, config_.p_sensor_com_m}; }
  /// Proposals accepted so far (the cycle's thread): a change tells who mirrors the tunables.
  std::uint64_t tunables_accepted() const { return tunables_accepted_; }

  /// No robot message this time (receive timeout or a malformed datagram from the robot).
  /// Counts toward the robot watchdog. Nothing is sent.
  void robot_lost(RobotLoss why) noexcept;
  /// One robot message (SI, as zerog::rtio hands it): runs the cycle and fills `correction`
  /// (always, with message.ipoc; Kind::none unless zero-g or collection is running).
  /// The cycle takes no protocol type: the RSI endpoint (zerog::rtio) converts the wire's
  /// KUKA units at the border, and so do the tests that hold RSI messages
  /// (tests/common/rsi_step.hpp).
  void step(const samples::RobotSample& message, samples::RobotCorrection& correction) noexcept;

  /// The record of the last step() (or robot_lost()).
  const CycleRecord& last() const { return *record_; }
  /// The motion estimator's last update ([filter] motion = "fused"; tests and diagnostics).
  const MotionEstimate& motion_estimate() const { return data_.model.estimate; }
  /// The last cycle had its model rows and fresh samples of both sensors: enable_zero_g can be
  /// accepted (what zerog-rt's status and the Modbus `ready` input show).
  bool ready() const noexcept {
    return record_->cycle > 0 &&
           (record_->flags & (kNotReady | kFtHeld | kImuHeld | kPoseMissing)) == 0;
  }
  /// The program's measured time of the last step(): into its record and, if that cycle is the
  /// black box's newest entry (also the fault cycle of a frozen box), there too.
  void set_compute_ns(std::int64_t ns) noexcept;
  const StateMachine& state_machine() const { return sm_; }
  const Box& black_box() const { return box_; }
  /// After a fault has been dumped: let the black box record again (outside the cycle).
  void release_black_box() { box_.release(); }
  const CycleCounters& counters() const { return counters_; }
  const control::ZeroGMotion& motion() const { return motion_; }
  const infer::Inference& inference() const { return inference_; }

 private:
  void raise(Fault f) noexcept;
  void raise_all(const stages::FaultRequests& requests) noexcept;
  /// One more robot cycle without a usable message: the robot_late watchdog's run grows.
  void grow_lost_run() noexcept;
  /// The black box keeps a lost cycle too: the last record marked `flags`, with the state now.
  void push_lost_record(std::uint32_t flags) noexcept;
  /// Where this cycle's record is written, which becomes last(): the black box's next slot if
  /// the record goes into the box (`kept`, and the box is not frozen), else spare_. `carry`:
  /// starts as a copy of the last record (a lost cycle keeps what it has nothing new for).
  CycleRecord& open_record(bool kept, bool carry) noexcept;
  /// The record from open_record(true, ...) into the black box (if not frozen); frozen there if
  /// a fault was raised in this cycle.
  void keep_record() noexcept;
  /// A message without any pose (kPoseMissing): answered, counted as a lost robot cycle.
  void pose_missing() noexcept;
  /// A message not newer than the last one (kIpocStale): answered (zero), nothing else.
  void stale_message() noexcept;
  /// The zero correction answered with `ipoc` (idle, fault, a cycle that ends early): AKorr
  /// zeros when a collection path is set, else RKorr zeros.
  samples::RobotCorrection zero_reply(std::uint64_t ipoc) const noexcept;
  /// One cycle for message `m`; its answer (SI) is last().reply, which step() hands on.
  void run(const samples::RobotSample& m) noexcept;
  /// The pending command (request()), taken for this cycle.
  stages::PendingCommand take_command() noexcept;
  void publish_outcome(const stages::PendingCommand& c, bool accepted) noexcept;

  // Configuration (const between configure() and an accepted proposal).
  CycleConfig config_;
  infer::Inference inference_;
  bool configured_ = false;
  bool use_network_ = false;
  const JointPath* path_ = nullptr;

  // Per-cycle data.
  CycleData data_;
  StateMachine sm_;
  control::ZeroGMotion motion_{control::BodyParams{}, control::MotionLimits{},
                               Eigen::Vector3d::Zero()};
  std::uint64_t cycle_ = 0;
  Box box_;
  bool freeze_pending_ = false;
  /// The last cycle's record: stages::make_record's, or a lost cycle's (robot_lost(), a stale
  /// message, no pose), which keeps the fields that cycle has nothing new for. It is the black
  /// box's newest entry (written there in place, not copied), or spare_ when it is not in the
  /// box (the box is frozen, or the cycle is not kept: not configured).
  CycleRecord* record_ = &spare_;
  CycleRecord spare_;
  CycleCounters counters_;

  /// 0: none, else ticket << 8 | (1 + Command).
  std::atomic<std::uint64_t> pending_{0};
  std::atomic<std::uint64_t> tickets_{0};
  /// Outcome of ticket t in slot t % kCommandOutcomes: t << 2 | 1 (accepted) or 2 (refused).
  std::array<std::atomic<std::uint64_t>, kCommandOutcomes> outcomes_{};

  void take_proposal() noexcept;
  /// ProposalStatus, or kProposalWriting / kProposalTaking while one side owns proposal_.
  std::atomic<std::uint8_t> proposal_state_{0};
  Tunables proposal_;
  std::uint64_t tunables_accepted_ = 0;
};

}  // namespace zerog::loop
