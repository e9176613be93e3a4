#include "zerog/control/motion.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace zerog::control {
namespace {

// Scales v down to at most `max` in norm; sets `flag` in `flags` if it did.
Eigen::Vector3d clamp_norm(const Eigen::Vector3d& v, double max, std::uint32_t flag,
                           std::uint32_t& flags) {
  const double n = v.norm();
  if (n <= max) return v;
  flags |= flag;
  return v * (max / n);
}

Eigen::Vector3d rotation_vector(const Eigen::Quaterniond& q) {
  const Eigen::AngleAxisd aa(q.w() < 0 ? Eigen::Quaterniond(-q.coeffs()) : q);
  return aa.axis() * aa.angle();
}

}  // namespace

Eigen::Vector3d deadband(const Eigen::Vector3d& x, double d) {
  const double n = x.norm();
  if (n <= d) return Eigen::Vector3d::Zero();
  return x * ((n - d) / n);
}

Eigen::Vector3d torque_gate_input(const Eigen::Vector3d& torque_sensor_Nm,
                                  const Eigen::Vector3d& torque_com_Nm,
                                  const Eigen::Vector3d& force_sensor_N, double force_open_N) {
  if (force_open_N > 0.0 && force_sensor_N.norm() <= force_open_N &&
      torque_sensor_Nm.norm() < torque_com_Nm.norm())
    return torque_sensor_Nm;
  return torque_com_Nm;
}

Eigen::Vector3d ContactGate::step(const Eigen::Vector3d& judged, const Eigen::Vector3d& x,
                                  double dt_s, double open, double close, int confirm,
                                  bool may_open) {
  if (open <= 0.0) return x;
  const double n = judged.norm();
  if (open_) {
    run_ = n < close ? run_ + 1 : 0;
    if (run_ >= confirm) reset();
    return x;
  }
  if (n <= open || !may_open) {
    run_ = 0;
    pending_impulse_.setZero();
    return Eigen::Vector3d::Zero();
  }
  ++run_;
  if (run_ < confirm) {
    pending_impulse_ += x * dt_s;
    return Eigen::Vector3d::Zero();
  }
  // Confirmed: this cycle carries its own input plus the impulse held back while confirming.
  const Eigen::Vector3d out = x + pending_impulse_ / dt_s;
  open_ = true;
  run_ = 0;
  pending_impulse_.setZero();
  return out;
}

void ContactGate::reset() {
  open_ = false;
  run_ = 0;
  pending_impulse_.setZero();
}

ZeroGMotion::ZeroGMotion(const BodyParams& body, const MotionLimits& limits,
                         const Eigen::Vector3d& p_sensor_com_m)
    : body_(body), limits_(limits), p_sensor_com_m_(p_sensor_com_m) {}

void ZeroGMotion::reset(const Eigen::Vector3d& p_world_sensor_m,
                        const Eigen::Quaterniond& q_world_sensor) {
  BodyState s;
  s.q_world_body = q_world_sensor.normalized();
  s.p_world_m = p_world_sensor_m + s.q_world_body * p_sensor_com_m_;
  body_.reset(s);
  force_gate_.reset();
  torque_gate_.reset();
  force_lp1_.setZero();
  force_lp2_.setZero();
  torque_lp1_.setZero();
  torque_lp2_.setZero();
}

Eigen::Vector3d ZeroGMotion::sensor_position_world() const {
  const BodyState& s = body_.state();
  return s.p_world_m - s.q_world_body * p_sensor_com_m_;
}

Eigen::Quaterniond ZeroGMotion::sensor_attitude_world() const { return body_.state().q_world_body; }

std::uint32_t ZeroGMotion::step(const Eigen::Vector3d& force_sensor_N,
                                const Eigen::Vector3d& torque_sensor_Nm, double dt_s,
                                PoseCorrection& out, bool may_confirm) {
  out = PoseCorrection{};
  std::uint32_t flags = kLimitNone;
  if (force_sensor_N.norm() > limits_.max_contact_force_N) flags |= kForceOverLimit;
  if (torque_sensor_Nm.norm() > limits_.max_contact_torque_Nm) flags |= kTorqueOverLimit;
  if (flags) return flags;

  // The contact wrench (measured − predicted) is the person's push on the payload as the sensor
  // passes it on: sensor frame, torque about the sensor origin. It drives the virtual body.
  // The contact gates pass the wrench at the virtual centre of mass, where it drives
  // translation and rotation. The torque gate judges torque_gate_input: about the centre of
  // mass when the force counts, else the smaller of that and the torque about the sensor
  // origin (a rejected force's lever is not a torque).
  const Eigen::Quaterniond R = body_.state().q_world_body;
  const Eigen::Vector3d M_com_raw =
      torque_about(torque_sensor_Nm, force_sensor_N, Eigen::Vector3d::Zero(), p_sensor_com_m_);
  const Eigen::Vector3d M_judged =
      torque_gate_input(torque_sensor_Nm, M_com_raw, force_sensor_N, limits_.force_deadband_N);
  const double release = limits_.contact_release_fraction;
  const int confirm = limits_.contact_confirm_cycles;
  Eigen::Vector3d F_world =
      R * force_gate_.step(force_sensor_N, dt_s, limits_.force_deadband_N,
                           release * limits_.force_deadband_N, confirm, may_confirm);
  Eigen::Vector3d M_com_sensor =
      torque_gate_.step(M_judged, M_com_raw, dt_s, limits_.torque_deadband_Nm,
                        release * limits_.torque_deadband_Nm, confirm, may_confirm);
  if (limits_.contact_lowpass_hz > 0.0) {
    // Exact first-order steps: y += (1 − e^(−2π f dt)) (x − y), twice.
    const double k = 1.0 - std::exp(-2.0 * std::numbers::pi * limits_.contact_lowpass_hz * dt_s);
    force_lp1_ += k * (F_world - force_lp1_);
    force_lp2_ += k * (force_lp1_ - force_lp2_);
    torque_lp1_ += k * (M_com_sensor - torque_lp1_);
    torque_lp2_ += k * (torque_lp1_ - torque_lp2_);
    F_world = force_lp2_;
    M_com_sensor = torque_lp2_;
  }
  const Eigen::Vector3d M_world = R * M_com_sensor;

  const Eigen::Vector3d p_sensor_before = sensor_position_world();
  const Eigen::Quaterniond q_before = sensor_attitude_world();
  const BodyState body_before = body_.state();
  const Eigen::Vector3d v_before = body_before.v_world_mps;
  const Eigen::Vector3d w_before = body_.omega_world();
  body_.step(F_world, M_world, dt_s);

  // Limits act on the body's state, so the simulated object itself obeys them (and its
  // momentum records that it was held back).
  BodyState s = body_.state();
  // Damping (MotionLimits): exact decay over the step, before the limits look at the velocities.
  const bool damped = limits_.linear_damping_per_s > 0.0 || limits_.angular_damping_per_s > 0.0;
  if (damped) {
    s.v_world_mps *= std::exp(-limits_.linear_damping_per_s * dt_s);
    s.L_world_kgm2ps *= std::exp(-limits_.angular_damping_per_s * dt_s);
  }
  const Eigen::Vector3d dv =
      clamp_norm(s.v_world_mps - v_before, limits_.max_accel_mps2 * dt_s, kAccelLimited, flags);
  s.v_world_mps = clamp_norm(v_before + dv, limits_.max_speed_mps, kSpeedLimited, flags);
  const Eigen::Matrix3d Rw = s.q_world_body.toRotationMatrix();
  const Eigen::Matrix3d I_world = Rw * body_.params().inertia_body_kgm2 * Rw.transpose();
  Eigen::Vector3d w_after = I_world.inverse() * s.L_world_kgm2ps;
  const Eigen::Vector3d dw = clamp_norm(w_after - w_before, limits_.max_angular_accel_radps2 * dt_s,
                                        kAngularAccelLimited, flags);
  w_after = clamp_norm(w_before + dw, limits_.max_angular_speed_radps, kAngularSpeedLimited, flags);
  s.L_world_kgm2ps = I_world * w_after;
  // Over the cycle the body moved with the limited velocities (trapezoid rule), not the free ones.
  if (flags & (kAccelLimited | kSpeedLimited)) {
    s.p_world_m = body_before.p_world_m + 0.5 * (v_before + s.v_world_mps) * dt_s;
  }
  if (flags & (kAngularAccelLimited | kAngularSpeedLimited)) {
    const Eigen::Vector3d turn = 0.5 * (w_before + w_after) * dt_s;
    const double angle = turn.norm();
    const Eigen::Quaterniond dq = angle > 0
                                      ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, turn / angle))
                                      : Eigen::Quaterniond::Identity();
    s.q_world_body = (dq * body_before.q_world_body).normalized();
  }
  // Workspace: a centre of mass leaving the box is put back on its face and stops moving out.
  for (int k = 0; k < 3; ++k) {
    if (s.p_world_m[k] < limits_.workspace_min_m[k] ||
        s.p_world_m[k] > limits_.workspace_max_m[k]) {
      s.p_world_m[k] =
          std::clamp(s.p_world_m[k], limits_.workspace_min_m[k], limits_.workspace_max_m[k]);
      s.v_world_mps[k] = 0.0;
      flags |= kWorkspaceLimited;
    }
  }
  if (flags != kLimitNone || damped) body_.reset(s);

  out.translation_m = sensor_position_world() - p_sensor_before;
  out.rotation_rad = rotation_vector(sensor_attitude_world() * q_before.conjugate());
  return flags;
}

}  // namespace zerog::control
