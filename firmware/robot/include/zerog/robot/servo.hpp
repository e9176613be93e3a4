#pragma once
// A joint's position servo as a critically damped second order about its set point s:
// q̈ = ω² (s − q) − 2ω q̇, ω = 2π · bandwidth. The rig emulator's controller (host/emu,
// emu::RobotEmulator, proto/emulator.md) moves its joints with it, and zerog-rt's motion
// estimator models the motor side's acceleration from the commanded corrections with it
// (loop::MotionEstimator, [filter] servo_hz; proto/loop.md, "Motion estimator"): one formula.
// Real-time safe: no allocation, no exceptions.
#include <Eigen/Core>

namespace zerog::robot {

/// e^{Aτ} of the servo for x = (q − s, q̇) with a held set point: A = [[0, 1], [−ω², −2ω]] (a
/// double pole at −ω), e^{Aτ} = e^{−ωτ} [[1 + ωτ, τ], [−ω² τ, 1 − ωτ]].
Eigen::Matrix2d servo_transition(double omega_radps, double tau_s);

/// Advances (q, q̇) by τ while the set point moves at `rate` (s(t) = s + rate · t; 0: held),
/// exactly (first-order hold): over such a piece the error (q − s + 2 rate / ω, q̇ − rate) obeys
/// the homogeneous equation. `phi` = servo_transition(ω, τ). `s` is moved on by rate · τ.
void servo_advance(double omega_radps, double tau_s, double rate, const Eigen::Matrix2d& phi,
                   double& s, double& q, double& qd);

/// The servo's acceleration at the state: ω² (s − q) − 2ω q̇.
inline double servo_accel(double omega_radps, double s, double q, double qd) {
  return omega_radps * omega_radps * (s - q) - 2.0 * omega_radps * qd;
}

}  // namespace zerog::robot
