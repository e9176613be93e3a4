#pragma once
// The payload's physics for zerog-emu: host/sim's RigSimulator::measure (the one implementation
// of the payload's wrench and the IMU signals) driven by the emulated robot's joint state, plus
// scripted pushes by a person and the F/T sensor's noise (proto/emulator.md).
//
// Frames (proto/frames.md): B robot base (the scenario's "world" axes: the push is given in B),
// S the true sensor frame, I the IMU frame. Emulator code, not real-time; step() does not
// allocate.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <optional>
#include <random>
#include <span>
#include <vector>

#include "zerog/sim/simulator.hpp"

namespace zerog::emu {

enum class PushProfile : std::uint8_t {
  half_sine,  ///< F(t) = F_peak sin(π (t − start) / duration)
  constant,   ///< F(t) = F for the whole duration
};
const char* push_profile_name(PushProfile profile);

/// A scripted push on the payload, active on [start_s, start_s + duration_s).
struct Push {
  double start_s = 0.0;
  double duration_s = 0.2;
  Eigen::Vector3d force_world_N = Eigen::Vector3d::Zero();    ///< peak or constant, base frame B
  Eigen::Vector3d torque_world_Nm = Eigen::Vector3d::Zero();  ///< pure torque, B, same profile
  /// Where the force acts, in S; absent: the payload's centre of mass.
  std::optional<Eigen::Vector3d> point_sensor_m;
  PushProfile profile = PushProfile::half_sine;

  /// The profile at time t: in [0, 1] inside the push, 0 outside.
  double factor(double t_s) const;
  /// ∫ factor dt over the push (s): duration · 2/π for the half sine, duration for constant.
  double factor_integral_s() const;
  /// Impulse J = ∫ F dt (N·s, B) and angular impulse of the pure torque ∫ M dt (N·m·s, B).
  Eigen::Vector3d impulse_N_s() const { return force_world_N * factor_integral_s(); }
  Eigen::Vector3d torque_impulse_Nms() const { return torque_world_Nm * factor_integral_s(); }
};

inline constexpr std::size_t kMaxPushes = 64;  ///< per scenario

/// One evaluation of the physics.
struct PhysicsSample {
  sim::Measurement truth;  ///< noise-free sensor wrench (S) and IMU signals (I), kinematics
  std::array<double, 6> wrench_sensor_noisy{};  ///< truth + F/T noise: N, N·m about S
  Eigen::Vector3d push_force_base_N = Eigen::Vector3d::Zero();  ///< all pushes now, B
  /// All pushes' torque about the payload's centre of mass now (B): Σ r × F + M, with r the
  /// lever from the centre of mass to the point of the force.
  Eigen::Vector3d push_torque_com_base_Nm = Eigen::Vector3d::Zero();
};

/// The integrals of one push as the physics stepped through it (rectangle rule at the physics
/// rate): impulse (N·s, B) and angular impulse about the moving centre of mass (N·m·s, B).
struct PushIntegral {
  Eigen::Vector3d impulse_N_s = Eigen::Vector3d::Zero();
  Eigen::Vector3d angular_impulse_com_Nms = Eigen::Vector3d::Zero();
};

class PayloadPhysics {
 public:
  /// Throws std::invalid_argument for more than kMaxPushes pushes, a push with a non-positive
  /// duration, a negative start or a non-finite vector, or a non-positive physics rate (and what
  /// RigSimulator refuses).
  PayloadPhysics(sim::SimConfig config, std::vector<Push> pushes, double physics_rate_hz);

  const sim::RigSimulator& simulator() const { return simulator_; }
  const std::vector<Push>& pushes() const { return pushes_; }
  double physics_rate_hz() const { return rate_hz_; }

  /// Noise-free physics for joint state `js` at time t with the pushes active then; `js_imu` is
  /// the state the IMU reports (of t − tau with imu_time_offset, see RigSimulator::measure).
  PhysicsSample evaluate(const sim::JointState& js, const sim::JointState& js_imu,
                         double t_s) const;

  /// One physics step at t = step count / rate for the servo's (motor-side) joint state `js`:
  /// with SimConfig::elastic on, moves the link side by one step of the elastic arm
  /// (sim/elastic.hpp, loaded by the payload's weight and the active pushes, sim::payload_load)
  /// and evaluates the payload on it; keeps the joint history the IMU time offset needs,
  /// evaluates, adds seeded F/T white noise (SimConfig::noise force_N, torque_Nm per sample) and
  /// integrates the pushes. Call once per step, in order. Does not allocate.
  PhysicsSample step(const sim::JointState& js);
  std::uint64_t steps() const { return steps_; }
  /// One entry per push, in scenario order.
  const std::vector<PushIntegral>& push_integrals() const { return integrals_; }

 private:
  using ActivePushes = std::array<sim::ExternalWrench, kMaxPushes>;
  /// The pushes active at t_s as external wrenches (at their point, or the centre of mass) into
  /// `active`; returns how many.
  std::size_t active_pushes(double t_s, ActivePushes& active) const;
  /// evaluate() with the pushes active at t_s already listed (step() lists them once).
  PhysicsSample evaluate(const sim::JointState& js, const sim::JointState& js_imu, double t_s,
                         std::span<const sim::ExternalWrench> active) const;
  sim::RigSimulator simulator_;
  std::vector<Push> pushes_;
  double rate_hz_;
  std::vector<sim::JointState> history_;  // ring of the last delay_steps_ + 1 states
  std::size_t delay_steps_ = 0;
  std::uint64_t steps_ = 0;
  std::vector<PushIntegral> integrals_;
  sim::ElasticArm arm_;      // the link side when SimConfig::elastic is on
  sim::JointVector load_{};  // the payload's weight and pushes on the joints, of the last step
  bool settled_ = false;     // the arm started at its static sag
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
};

}  // namespace zerog::emu
