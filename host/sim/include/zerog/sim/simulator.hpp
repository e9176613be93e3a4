#pragma once
// The rig simulator: a KR 210 R2700 moving a payload on an ATI Omega191 F/T sensor with a
// STIM300-like IMU, through a PTP trajectory. The physics is computed here, independently of
// zerog::model: joint trajectory → analytic flange twist and its derivative (robot::flange_motion
// on the robot file's arm, robot.hpp) → Newton–Euler for the payload → switchable sensor effects →
// noise and quantisation.
//
// Conventions are those of proto/frames.md, so that zerog::model::predict_wrench with the truth
// parameters reproduces the noise-free simulated wrench (checked in tests/unit/sim).
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "zerog/formats/log.hpp"
#include "zerog/io/model_file.hpp"
#include "zerog/model/effects.hpp"
#include "zerog/sim/design.hpp"
#include "zerog/sim/elastic.hpp"
#include "zerog/sim/trajectory.hpp"

namespace zerog::sim {

/// Effects of the rig that the model library does not have (proto/effects.md lists the library's).
enum class RigEffect : std::uint8_t {
  imu_lever_arm,    ///< rig geometry, not a model effect: IMU origin off the sensor origin
  joint6_friction,  ///< Mz follows the sign of the A6 rate
  swivel_viscous,   ///< Mz drags against the payload's rate about z_S
  hose_drag,        ///< force against the sensor origin's velocity
  dress_pack_bend,  ///< Fx follows sin(A4)·sin(A5)
};
inline constexpr int kRigEffectCount = 5;

/// What the simulator can switch on or off in its truth: an effect of the model library (every
/// one but bias, gravity and linear inertia, which the truth always has; see switchable()) or an
/// effect of the rig.
using SimEffect = std::variant<model::Effect, RigEffect>;

/// Whether the simulator's truth can be without this library effect.
constexpr bool switchable(model::Effect e) {
  return e != model::Effect::bias && e != model::Effect::gravity &&
         e != model::Effect::linear_inertia;
}
inline constexpr int kSimEffectCount =
    static_cast<int>(std::ranges::count_if(model::kAllEffects, switchable)) + kRigEffectCount;

struct SimEffectInfo {
  SimEffect id;
  const char* name;               ///< the library's name (model::info) or the rig effect's
  const char* default_magnitude;  ///< plain words, for --list-effects
  /// The model library's effect, if it is one.
  std::optional<model::Effect> model_effect() const {
    if (const auto* e = std::get_if<model::Effect>(&id)) return *e;
    return std::nullopt;
  }
};
/// The switches: the library's effects in their declaration order, then the rig's.
const std::array<SimEffectInfo, kSimEffectCount>& sim_effect_infos();
const SimEffectInfo& info(SimEffect e);
std::optional<SimEffect> sim_effect_from_name(std::string_view name);

class SimEffectSet {
 public:
  constexpr SimEffectSet() = default;
  constexpr SimEffectSet(std::initializer_list<SimEffect> effects) {
    for (const SimEffect& e : effects) add(e);
  }
  constexpr bool has(model::Effect e) const { return library_.has(e); }
  constexpr bool has(RigEffect e) const { return (rig_bits_ >> static_cast<int>(e)) & 1u; }
  constexpr bool has(const SimEffect& e) const {
    return std::visit([this](auto x) { return has(x); }, e);
  }
  constexpr void add(model::Effect e) { library_.add(e); }
  constexpr void add(RigEffect e) { rig_bits_ |= 1u << static_cast<int>(e); }
  constexpr void add(const SimEffect& e) {
    std::visit([this](auto x) { add(x); }, e);
  }
  constexpr void remove(model::Effect e) { library_.remove(e); }
  constexpr void remove(RigEffect e) { rig_bits_ &= ~(1u << static_cast<int>(e)); }
  constexpr void remove(const SimEffect& e) {
    std::visit([this](auto x) { remove(x); }, e);
  }
  constexpr bool operator==(const SimEffectSet&) const = default;

 private:
  model::EffectSet library_;
  std::uint32_t rig_bits_ = 0;
};

/// The default truth: bias, gravity, linear inertia (always) and rotational inertia.
inline constexpr SimEffectSet kDefaultSimEffects = {model::Effect::rotational_inertia};

/// Applies a list like "base_tilt,cable,-rotational_inertia" to `start`: a name switches an
/// effect on, "-name" off; "all" and "none" switch all of them. Throws naming an unknown name.
SimEffectSet parse_sim_effects(const std::string& list, SimEffectSet start = kDefaultSimEffects);
std::string sim_effect_list_string(const SimEffectSet& effects);

/// Sensor and IMU noise. Defaults: F/T white noise per logged sample; IMU white noise per logged
/// sample, from STIM300 noise densities averaged over one 12 ms period (σ = N / √T for an
/// average over T of white noise with density N, IEEE Std 952 Allan variance): gyro ARW
/// 0.15 °/√h = 4.4e-5 rad/s/√Hz → 4.0e-4 rad/s, accelerometer VRW 0.07 m/s/√h =
/// 1.2e-3 m/s²/√Hz → 1.1e-2 m/s². Rounded up to 5e-4 rad/s and 0.01 m/s². (Logging a single
/// raw 2 kHz sample instead, through the STIM300's 262 Hz filter, would give N·√(262·π/2) ≈
/// 9e-4 rad/s and 0.024 m/s².) With the IMU in the model, σ_acc · m ≈ 1 N enters the
/// true-model reference, four times the F/T noise of the sensor floor.
///
/// Either way the simulator evaluates the IMU's signal at the row time and adds white noise of
/// the σ above to each row. `imu_point_rows` says what that noise stands for, and the log's rig
/// says it (`[imu_sampling]`, proto/log_format.md): false, a row is the mean over its period (the
/// σ above; the rig does not say, as every log before); true, a row is one raw sample
/// (`--set noise.imu_point_rows=1`): the rig says `rows = "point"` with the σ per row, and
/// `stim300_point_rows()` gives the single-sample σ of the STIM300 above.
struct NoiseConfig {
  double force_N = 0.25;
  double torque_Nm = 0.03;
  double accel_mps2 = 0.01;
  double gyro_radps = 5e-4;
  bool quantize = true;         ///< Omega191 resolution (paper 000_… Table 2)
  bool imu_point_rows = false;  ///< IMU rows are point samples (see above)
  /// F/T noise coloured, per axis an AR(1) process from row to row: e_k = φ e_{k−1} +
  /// sqrt(1 − φ²) ε_k (same standard deviation; 0: white). Real sensors' noise is coloured by
  /// their filters and the structure's vibration; the standard deviations of a fit that assumes
  /// white noise are then too small (issue 25).
  double ft_ar1 = 0.0;
  /// Encoder quantisation of the logged joints (and of the pose the controller reports from
  /// them), rad; 0: exact.
  double encoder_rad = 0.0;
  /// IMU bias instability per axis: a first-order Gauss–Markov process of this standard
  /// deviation and correlation time, started at a random value of the same σ (a turn-on bias);
  /// 0: none. The STIM300's datasheet values are in stim300_bias() below.
  double gyro_bias_radps = 0.0;
  double accel_bias_mps2 = 0.0;
  double imu_bias_tau_s = 300.0;
  static NoiseConfig none() { return {0.0, 0.0, 0.0, 0.0, false, false}; }
  /// The defaults with point-sampled IMU rows: one raw 2 kHz STIM300 sample through its 262 Hz
  /// filter, σ = N √(262 π / 2): gyro 9e-4 rad/s, accelerometer 0.024 m/s².
  static NoiseConfig stim300_point_rows() {
    NoiseConfig n;
    n.gyro_radps = 9e-4;
    n.accel_mps2 = 0.024;
    n.imu_point_rows = true;
    return n;
  }
};
/// Omega191 resolution: Fx, Fy 3/8 N, Fz 5/8 N, Mx, My 5/96 N·m, Mz 5/144 N·m.
inline constexpr std::array<double, 6> kOmega191Resolution = {0.375,      0.375,      0.625,
                                                              5.0 / 96.0, 5.0 / 96.0, 5.0 / 144.0};

/// The payload: mass, centre of mass and inertia tensor about it, in the (true) sensor frame S.
struct Payload {
  double mass_kg = 100.0;
  Eigen::Vector3d com_sensor_m{0.03, -0.02, 0.25};
  /// Tensor elements [[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]] (Ixy = −∫xy dm).
  Eigen::Matrix3d inertia_com_sensor_kgm2 = Eigen::Matrix3d::Identity();
};
/// Solid box 0.6 × 0.4 × 0.3 m of `mass_kg`, its axes turned by the rotation vector
/// (0.10, −0.15, 0.20) rad against S so that the products of inertia are non-zero.
Eigen::Matrix3d box_inertia_kgm2(double mass_kg);

/// Sensor temperature: T(t) = T0 + warmup (1 − exp(−t / warmup_tau)) + amplitude sin(2π t /
/// period).
struct TemperatureProfile {
  double base_C = 25.0;
  double warmup_K = 2.0;
  double warmup_tau_s = 300.0;
  double amplitude_K = 3.0;
  double period_s = 600.0;
  double at(double t_s) const;
};

/// A contact during a span of a simulated run (zerog sim --contact): someone pressing on the
/// payload, a snag or a collision, i.e. a wrench the payload model must not explain. Applied at
/// the S origin (its torque is given explicitly), in S or in B, scaled by the shape over time.
struct Contact {
  double start_s = 0.0;
  double duration_s = 0.0;
  Eigen::Matrix<double, 6, 1> wrench = Eigen::Matrix<double, 6, 1>::Zero();  ///< N, N·m
  bool base_frame = false;  ///< wrench axes: B (true) or S (false)
  /// plateau: full wrench between raised-cosine ramps of ramp_s at both ends (a push);
  /// spike: one half-sine over the duration (a collision).
  enum class Shape { plateau, spike } shape = Shape::plateau;
  double ramp_s = 0.1;
  /// 0..1: the share of the wrench at time t (0 outside [start_s, start_s + duration_s]).
  double factor_at(double t_s) const;
};

/// Parses zerog sim --contact: START:DURATION:FX,FY,FZ[,MX,MY,MZ][:sensor|base][:plateau|spike]
/// (s, s, N, N·m). Throws std::invalid_argument naming the part that is wrong.
Contact parse_contact(const std::string& text);

struct SimConfig {
  std::uint64_t seed = 1;
  SimEffectSet effects = kDefaultSimEffects;
  Payload payload;
  NoiseConfig noise;
  TemperatureProfile temperature;
  /// Truth values of every model effect's parameters (all blocks filled, seeded), in the model's
  /// layout and units. The gravity and rotational_inertia blocks are taken from `payload`.
  model::ModelParams params;
  double joint6_friction_Nm = 1.5;  ///< Mz = T tanh(q̇6 / rate)
  double joint6_friction_rate_radps = 0.02;
  double swivel_damping_Nms_per_rad = 2.0;  ///< swivel_viscous: Mz −= b ω_z (ω in S)
  double hose_drag_Ns_per_m = 25.0;         ///< hose_drag: F −= c v (S origin's velocity, S)
  double dress_pack_bend_N = 8.0;           ///< dress_pack_bend: Fx += k sin(q4) sin(q5)
  Eigen::Vector3d imu_lever_arm_m{0.045, -0.030, -0.035};  ///< p_sensor_imu when imu_lever_arm on
  Eigen::Vector3d imu_mount_rotvec_rad = Eigen::Vector3d::Zero();  ///< R_sensor_imu = Exp(·)
  Eigen::Vector3d p_flange_sensor_m{0.0, 0.0, 0.06};
  double floor_z_m = -0.675;
  double period_s = 0.012;
  double dwell_s = 2.0;
  double speed_fraction = 0.3;
  double duration_limit_s = 0.0;  ///< 0: the whole trajectory
  /// Contacts during the run (outside the payload model; the truth file lists them in
  /// extra.contacts).
  std::vector<Contact> contacts;
  /// Joint elasticity (elastic.hpp; off: the rigid robot every run before).
  ElasticityConfig elastic;
};

/// KUKA RSI reports the axis angles (AIPos) with 4 decimals of a degree: 1e-4°
/// (proto/sim_robot.md).
inline constexpr double kRsiJointResolutionRad = 1e-4 * 3.14159265358979323846 / 180.0;
/// STIM300 bias instability (Safran datasheet TS1524 rev. 9, as quoted in proto/sim_robot.md):
/// gyro 0.5 °/h, accelerometer (10 g) 0.05 mg.
inline constexpr double kStim300GyroBiasInstabilityRadps =
    0.5 * 3.14159265358979323846 / 180.0 / 3600.0;
inline constexpr double kStim300AccelBiasInstabilityMps2 = 0.05e-3 * 9.80665;

/// A robot that is not rigid (zerog sim --real-robot, proto/sim_robot.md): the KR 210 class
/// joint elasticity (kr210_elasticity()), and with `sensors` the logged joints quantised to the
/// RSI's resolution and the STIM300's bias instability.
void make_real_robot(SimConfig& config, bool sensors);

/// A configuration with seeded effect magnitudes (each clearly above the noise):
///   bias F0 ±(20..60) N, M0 ±(1..5) N·m; base_tilt alpha, beta ±(2..5) mrad;
///   imu_time_offset tau = 8 ms; bias_drift ±(2..5) N and ±(0.2..0.5) N·m per 600 s;
///   temperature_bias ±(0.5..1.5) N/K, ±(0.05..0.15) N·m/K; crosstalk gains ±0.5 %, couplings
///   ±0.3 % (force-from-torque ÷ 0.2 m, torque-from-force × 0.2 m); sensor_rotation random axis,
///   5..10 mrad; cable ±(0.5..3) N and ±(0.1..0.5) N·m per coefficient.
SimConfig default_sim_config(std::uint64_t seed);

/// Sets one named value, e.g. "imu_time_offset.tau", "gravity.mass", "noise.force",
/// "joint6_friction.torque", "swivel_viscous.damping", "hose_drag.damping",
/// "dress_pack_bend.force". Throws std::invalid_argument listing the valid keys.
void set_config_value(SimConfig& config, const std::string& key, double value);
/// All keys with their current values, for --list-effects.
std::vector<std::pair<std::string, double>> config_values(const SimConfig& config);

/// One term of an outside-library truth effect: `axis` ("Fx".."Mz", sensor frame S) +=
/// coefficient · basis. `basis` is named as the signal dictionary names it
/// (firmware/model/include/zerog/model/dictionary.hpp, proto/user_effects.md): "wz_S",
/// "tanh(qd6/0.02)", "sin(q4)*sin(q5)" (a product lists the lower-numbered signal first).
/// Coefficients in SI: N or N·m per unit of the basis.
struct OutsideTerm {
  std::string axis;
  std::string basis;
  double coefficient;
};
/// The exact law of every outside-library effect switched on in `config` (empty if none), in
/// SimEffect order. The simulator adds these wrenches to the payload's before the sensor's
/// crosstalk: with crosstalk off the noise-free reading gains exactly Σ coefficient · basis.
std::vector<OutsideTerm> outside_terms(const SimConfig& config);
/// The same for one named effect ("joint6_friction", ...) whether switched on or not; empty for
/// an effect the model library has and for imu_lever_arm (rig geometry).
std::vector<OutsideTerm> outside_terms(const SimConfig& config, SimEffect effect);

/// Noise-free IMU signals in the IMU frame I, as logged (including the time offset).
struct ImuTruth {
  Eigen::Vector3d specific_force_imu_mps2 = Eigen::Vector3d::Zero();
  Eigen::Vector3d angular_rate_imu_radps = Eigen::Vector3d::Zero();
  Eigen::Vector3d angular_accel_imu_radps2 = Eigen::Vector3d::Zero();
};

/// An external wrench on the payload (a person's push): a force in the robot base frame B applied
/// at a point of the payload given in the (true) sensor frame S, plus an optional pure torque in
/// B. The sensor carries it through the payload: the reading gains F_S = R_BSᵀ F and
/// M_S = p × F_S + R_BSᵀ M (torque about the S origin), before the sensor's crosstalk.
struct ExternalWrench {
  Eigen::Vector3d force_base_N = Eigen::Vector3d::Zero();
  Eigen::Vector3d point_sensor_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d torque_base_Nm = Eigen::Vector3d::Zero();
  /// A force and torque given in S instead (added to the ones in B): F_S += force_sensor_N,
  /// M_S += p × force_sensor_N + torque_sensor_Nm.
  Eigen::Vector3d force_sensor_N = Eigen::Vector3d::Zero();
  Eigen::Vector3d torque_sensor_Nm = Eigen::Vector3d::Zero();
};

/// The payload's load on the joints of an elastic arm (elastic.hpp) at the link angles
/// `link_q_rad`, S turned R_base_sensor in B: its weight (weight_load) and the external wrenches on
/// it now (wrench_load, their parts in B and in S): the arm carries a person's push as it carries
/// the weight. Its inertia is not a load (weight_load).
JointVector payload_load(const JointVector& link_q_rad, const Eigen::Matrix3d& R_base_sensor,
                         const SimConfig& c, std::span<const ExternalWrench> pushes);

/// What the sensors on the flange read for one joint state, noise-free, with every switched truth
/// effect, and the kinematics they came from.
struct Measurement {
  /// Force (N) and torque about the S origin (N·m) in the true sensor frame S, as the sensor
  /// reads it (bias, drift, temperature, cable, the outside-library effects and crosstalk
  /// included).
  Eigen::Matrix<double, 6, 1> wrench_sensor = Eigen::Matrix<double, 6, 1>::Zero();
  ImuTruth imu;                ///< IMU frame I, of the joint state given for the IMU
  robot::FlangeMotion flange;  ///< of the joint state given for the wrench, base axes
  Eigen::Matrix3d R_base_sensor = Eigen::Matrix3d::Identity();  ///< true S in B
  Eigen::Vector3d p_base_sensor_m = Eigen::Vector3d::Zero();    ///< S origin in B
  Eigen::Vector3d v_com_base_mps = Eigen::Vector3d::Zero();     ///< payload centre of mass, B
};

struct SimStats {
  std::size_t samples = 0;
  double duration_s = 0.0;
  double trajectory_duration_s = 0.0;
  double lowest_point_z_m = 0.0;  ///< over all samples (see design.hpp: lowest_point_z)
  std::size_t samples_below_floor = 0;
  double max_force_N = 0.0;
  double max_torque_Nm = 0.0;
};

struct SimOutput {
  formats::Log log;
  /// The same rows as `log` with every kinematic signal noise-free (IMU specific force and rate
  /// without noise; joints, pose, temperature and time are noise-free in `log` already) and the
  /// wrench columns equal to `log`'s noisy, quantised wrench. The true model on these signals
  /// against that wrench leaves only the F/T sensor's own noise and quantisation: the sensor
  /// floor (docs/insight-loop.md, "Sensor floor and true-model reference"). `zerog sim` writes
  /// it as NAME.clean.csv.
  formats::Log clean_log;
  io::ModelFile truth;
  /// Noise-free analytic angular acceleration in I for each row, delayed like the IMU (not logged).
  std::vector<Eigen::Vector3d> angular_accel_imu_radps2;
  SimStats stats;
};

class RigSimulator {
 public:
  /// Throws std::invalid_argument on a bad configuration or path points outside Table 4 ranges.
  RigSimulator(SimConfig config, std::vector<JointVector> path_points_rad);
  /// For a motion given from outside (measure()): the trajectory is a single dwell at home.
  explicit RigSimulator(SimConfig config);

  const SimConfig& config() const { return config_; }
  const PtpTrajectory& trajectory() const { return trajectory_; }
  formats::Rig rig() const;
  /// The truth as a model file: model effects that are on, their exact values, and extras.
  io::ModelFile truth() const;
  /// Model effects of the truth (bias, gravity, linear_inertia and the switched ones).
  model::EffectSet truth_model_effects() const;

  /// The physics for any joint state (the one implementation: wrench_at, imu_at and run use it).
  /// `js` at time `t_s` (the time drives bias_drift and temperature_bias) gives the wrench, with
  /// the external wrenches `pushes` added; `js_imu` gives the IMU signals. With imu_time_offset
  /// on, the IMU reports the motion of tau earlier: pass the joint state of t_s − tau as `js_imu`
  /// (only the caller knows an arbitrary motion's past); otherwise pass `js` again.
  /// Not real-time code, but allocation-free.
  Measurement measure(const JointState& js, const JointState& js_imu, double t_s,
                      std::span<const ExternalWrench> pushes = {}) const;
  /// measure(js, js, t_s, pushes).
  Measurement measure(const JointState& js, double t_s,
                      std::span<const ExternalWrench> pushes = {}) const;
  /// The IMU's time offset tau (s) when imu_time_offset is on, else 0.
  double imu_delay_s() const;

  /// Noise-free logged IMU signals at row time t of the trajectory (the true signals at t − tau).
  ImuTruth imu_at(double t_s) const;
  /// Noise-free sensor wrench at t of the trajectory (force N, torque N·m about S, true sensor
  /// frame S).
  Eigen::Matrix<double, 6, 1> wrench_at(double t_s) const;
  /// The part of wrench_at(t_s) that the switched-on outside-library effects add (joint6_friction,
  /// swivel_viscous, hose_drag, dress_pack_bend), as the sensor reads it: through the crosstalk
  /// when that is on. Zero if none is on. What the truth model file cannot predict.
  Eigen::Matrix<double, 6, 1> outside_wrench_at(double t_s) const;

  /// Runs the whole trajectory (or up to duration_limit_s). `progress` gets the fraction done.
  SimOutput run(const std::function<void(double)>& progress = {}) const;

 private:
  Eigen::Matrix<double, 6, 1> wrench_of(const JointState& js, const robot::FlangeMotion& fm,
                                        double t_s, std::span<const ExternalWrench> pushes,
                                        Measurement* kinematics) const;
  ImuTruth imu_of(const robot::FlangeMotion& fm) const;
  /// The outside-library effects' wrench on the payload (before crosstalk), S.
  Eigen::Matrix<double, 6, 1> outside_wrench_of(const JointState& js, const robot::FlangeMotion& fm,
                                                const Eigen::Matrix3d& R_base_sensor) const;

  SimConfig config_;
  PtpTrajectory trajectory_;
  Eigen::Matrix3d R_world_base_;
  Eigen::Matrix3d R_nominal_true_;  ///< sensor mounting rotation Exp(r)
  Eigen::Matrix3d R_sensor_imu_;    ///< rig: IMU axes in the nominal sensor frame
  Eigen::Vector3d p_sensor_imu_m_;  ///< rig: IMU origin in the nominal sensor frame
};

}  // namespace zerog::sim
