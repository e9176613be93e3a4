#pragma once
// From contact wrench to robot motion, with the limits that keep a person next to 100 kg safe:
// deadband and force limit on the contact wrench, speed, acceleration and workspace limits on
// the virtual body, and the per-cycle relative correction of the sensor pose (RSI moves only by
// position corrections). SI units; the RSI border converts to mm and degrees.
// Real-time safe: no allocation, no exceptions.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>

#include "zerog/control/virtual_body.hpp"

namespace zerog::control {

struct MotionLimits {
  /// Contact detection (ContactGate): a force at the virtual centre of mass must exceed this for
  /// contact_confirm_cycles cycles in a row to count as a push (0: no gate).
  double force_deadband_N = 2.0;
  /// Likewise for the torque the torque gate judges (torque_gate_input: about the virtual
  /// centre of mass with a force above force_deadband_N, else the smaller of it and the torque
  /// about the sensor origin); what it passes is always the torque about the centre of mass.
  double torque_deadband_Nm = 0.3;
  int contact_confirm_cycles = 3;  ///< cycles above the threshold that confirm a contact
  /// An open gate closes after contact_confirm_cycles cycles below this fraction of the threshold.
  double contact_release_fraction = 0.5;
  double max_contact_force_N = 400.0;  ///< above this: fault (someone or something collided)
  double max_contact_torque_Nm = 80.0;
  double max_speed_mps = 0.25;  ///< of the centre of mass
  double max_angular_speed_radps = 0.6;
  double max_accel_mps2 = 1.5;  ///< commanded change of velocity per second
  double max_angular_accel_radps2 = 3.0;
  /// Viscous damping of the virtual body (0: a free body, as in orbit): the velocity and the
  /// angular momentum decay as e^(−c·t) when nothing pushes, so a test engineer can make a
  /// heavy part settle. Applied exactly per step (v ← v·e^(−c·dt)).
  double linear_damping_per_s = 0.0;
  double angular_damping_per_s = 0.0;
  /// What the contact gates pass drives the body through two first-order low-passes at this
  /// corner (0: directly). Unit gain at DC, so a push's whole impulse still arrives (later by
  /// 2 / (2π f) on average: 0.16 s at 2 Hz); what it removes is the 5–25 Hz band where an elastic
  /// arm's modes sit, through which an open gate can close a loop (the modes' residual in the
  /// contact drives the body, the body's motion drives the modes: proto/loop.md, "The contact
  /// gate on it"). The gates judge the wrench unfiltered, so a push is confirmed as fast.
  double contact_lowpass_hz = 0.0;
  Eigen::Vector3d workspace_min_m{-0.5, -1.5, 0.3};  ///< box for the centre of mass, world
  Eigen::Vector3d workspace_max_m{2.5, 1.5, 2.2};
};

/// What the limits did in one cycle (bits), reported in the cycle status and telemetry.
enum LimitFlags : std::uint32_t {
  kLimitNone = 0,
  kForceOverLimit = 1u << 0,   ///< fault condition: contact force above max_contact_force_N
  kTorqueOverLimit = 1u << 1,  ///< fault condition
  kSpeedLimited = 1u << 2,
  kAngularSpeedLimited = 1u << 3,
  kAccelLimited = 1u << 4,
  kAngularAccelLimited = 1u << 5,
  kWorkspaceLimited = 1u << 6,
};

/// Deadband without a jump at its edge: the vector shrinks by the deadband along its own
/// direction (|x| ≤ d → 0, else x (|x| − d)/|x|).
Eigen::Vector3d deadband(const Eigen::Vector3d& x, double d);

/// The torque the torque gate judges, from the contact wrench in the sensor frame: the torque
/// about the sensor origin, the same about the virtual centre of mass (torque_about), and the
/// force. With a force the force gate counts (above `force_open_N` this cycle, or no force
/// gate) the torque about the centre of mass, as the body takes it. With a smaller force, which the
/// force gate counts as none, the torque about the centre of mass and about the sensor origin
/// should be the same couple; they differ by r × F, the lever of that rejected force, and the
/// smaller of the two is the one without it. The F/T sensor's force noise acts at the sensor (its
/// lever shows about the centre of mass: 0.15 N × 0.25 m ≈ 0.04 N·m, twice the sensor's own torque
/// noise); an error of the predicted acceleration acts at the centre of mass (its lever shows about
/// the sensor origin). So neither reaches the torque gate through the lever, while a couple, or a
/// push off the centre of mass that the force gate counts, still turns the body (proto/loop.md,
/// "Motion estimator", the contact gate). One formula for zerog-rt and `zerog gate`. Real-time
/// safe.
Eigen::Vector3d torque_gate_input(const Eigen::Vector3d& torque_sensor_Nm,
                                  const Eigen::Vector3d& torque_com_Nm,
                                  const Eigen::Vector3d& force_sensor_N, double force_open_N);

/// Contact detection on one part of the contact wrench (force, or torque) that keeps the whole
/// impulse of a real push, where a deadband would shave
/// threshold × duration off it (2 N over a 0.5 s push is 8 % of a 40 N half-sine's impulse).
/// Closed, it passes nothing; a magnitude above `open` for `confirm` cycles in a row opens it and
/// releases, in the opening cycle, the impulse of the cycles that confirmed it. Open, it passes
/// its input unchanged until `confirm` cycles in a row fall below `close`. Noise at a third of
/// the threshold (3σ) stays above it for `confirm` = 3 cycles in a row with a probability of
/// about 1e-8, so a body at rest does not creep. Real-time safe.
class ContactGate {
 public:
  /// Input `x` (N or N·m) over a cycle of `dt_s`; returns what drives the body this cycle.
  /// `open` ≤ 0 disables the gate (pass-through).
  Eigen::Vector3d step(const Eigen::Vector3d& x, double dt_s, double open, double close,
                       int confirm, bool may_open = true) {
    return step(x, x, dt_s, open, close, confirm, may_open);
  }
  /// The same, judging `judged` against the thresholds and passing `passed` (the torque gate:
  /// torque_gate_input judged, the torque about the centre of mass passed). `may_open` false:
  /// a closed gate stays closed and counts no cycle toward confirming (its input is not yet
  /// trusted); an open gate carries on.
  Eigen::Vector3d step(const Eigen::Vector3d& judged, const Eigen::Vector3d& passed, double dt_s,
                       double open, double close, int confirm, bool may_open = true);
  void reset();
  bool is_open() const { return open_; }

 private:
  bool open_ = false;
  int run_ = 0;
  Eigen::Vector3d pending_impulse_ = Eigen::Vector3d::Zero();
};

/// A relative correction of the sensor pose over one cycle, in the world (robot base) frame:
/// translation (m) and rotation vector (rad) such that R_new = Exp(rotation) R_old.
struct PoseCorrection {
  Eigen::Vector3d translation_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d rotation_rad = Eigen::Vector3d::Zero();
};

/// The zero-g motion generator: contact wrench at the sensor → virtual body → correction.
class ZeroGMotion {
 public:
  /// `p_sensor_com_m`: the virtual centre of mass in the sensor frame (it may differ from the
  /// real payload's); the body's axes start aligned with the sensor's.
  ZeroGMotion(const BodyParams& body, const MotionLimits& limits,
              const Eigen::Vector3d& p_sensor_com_m);

  /// Starts from the sensor's current pose (world frame), at rest.
  void reset(const Eigen::Vector3d& p_world_sensor_m, const Eigen::Quaterniond& q_world_sensor);

  /// One cycle. `force_sensor_N`, `torque_sensor_Nm`: contact wrench in the sensor frame, torque
  /// about the sensor origin. Returns the limit flags; `out` gets the sensor pose correction.
  /// A force/torque over its limit leaves the body untouched and returns a zero correction.
  /// `may_confirm` false: the contact wrench is not yet trusted to start a push (zerog-rt: the
  /// motion estimator settling, loop::kEstimatorSettling): closed gates stay closed, open ones
  /// carry on, and the limits are checked as always.
  std::uint32_t step(const Eigen::Vector3d& force_sensor_N, const Eigen::Vector3d& torque_sensor_Nm,
                     double dt_s, PoseCorrection& out, bool may_confirm = true);

  const VirtualBody& body() const { return body_; }
  /// True while a push is being passed on (force or torque gate open).
  bool in_contact() const { return force_gate_.is_open() || torque_gate_.is_open(); }
  /// Sensor pose implied by the body, world frame.
  Eigen::Vector3d sensor_position_world() const;
  Eigen::Quaterniond sensor_attitude_world() const;

 private:
  VirtualBody body_;
  MotionLimits limits_;
  ContactGate force_gate_, torque_gate_;
  /// contact_lowpass_hz's two stages of the passed force (world) and torque (sensor axes, about
  /// the centre of mass).
  Eigen::Vector3d force_lp1_ = Eigen::Vector3d::Zero(), force_lp2_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d torque_lp1_ = Eigen::Vector3d::Zero(), torque_lp2_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d p_sensor_com_m_;
};

}  // namespace zerog::control
