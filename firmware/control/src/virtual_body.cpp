#include "zerog/control/virtual_body.hpp"

namespace zerog::control {
namespace {

// q̇ = ½ q ⊗ (0, ω_body)
Eigen::Vector4d quat_rate(const Eigen::Vector4d& q_wxyz, const Eigen::Vector3d& w) {
  const double qw = q_wxyz[0], qx = q_wxyz[1], qy = q_wxyz[2], qz = q_wxyz[3];
  return 0.5 * Eigen::Vector4d(
                   -qx * w.x() - qy * w.y() - qz * w.z(), qw * w.x() + qy * w.z() - qz * w.y(),
                   qw * w.y() + qz * w.x() - qx * w.z(), qw * w.z() + qx * w.y() - qy * w.x());
}

Eigen::Quaterniond to_quat(const Eigen::Vector4d& v) {
  return Eigen::Quaterniond(v[0], v[1], v[2], v[3]).normalized();
}

}  // namespace

VirtualBody::VirtualBody(const BodyParams& params, const BodyState& initial)
    : params_(params), inertia_inv_body_(params.inertia_body_kgm2.inverse()), state_(initial) {}

Eigen::Vector3d VirtualBody::omega_body() const {
  return inertia_inv_body_ * (state_.q_world_body.conjugate() * state_.L_world_kgm2ps);
}

Eigen::Vector3d VirtualBody::omega_world() const { return state_.q_world_body * omega_body(); }

double VirtualBody::kinetic_energy_J() const {
  const Eigen::Vector3d w = omega_body();
  return 0.5 * params_.mass_kg * state_.v_world_mps.squaredNorm() +
         0.5 * w.dot(params_.inertia_body_kgm2 * w);
}

void VirtualBody::step(const Eigen::Vector3d& force_world_N, const Eigen::Vector3d& torque_world_Nm,
                       double dt_s) {
  // Linear: constant force over the step (exact).
  const Eigen::Vector3d a = force_world_N / params_.mass_kg;
  state_.p_world_m += state_.v_world_mps * dt_s + 0.5 * a * dt_s * dt_s;
  state_.v_world_mps += a * dt_s;
  // Angular: the torque changes L linearly over the step; the attitude follows ω(t) = I⁻¹ Rᵀ L(t).
  const Eigen::Vector3d L0 = state_.L_world_kgm2ps;
  const Eigen::Vector3d dL = torque_world_Nm * dt_s;
  auto rate = [&](const Eigen::Vector4d& q, double frac) {
    const Eigen::Vector3d L = L0 + frac * dL;
    const Eigen::Vector3d w = inertia_inv_body_ * (to_quat(q).conjugate() * L);
    return quat_rate(q, w);
  };
  const Eigen::Quaterniond& q0 = state_.q_world_body;
  const Eigen::Vector4d y(q0.w(), q0.x(), q0.y(), q0.z());
  const Eigen::Vector4d k1 = rate(y, 0.0);
  const Eigen::Vector4d k2 = rate(y + 0.5 * dt_s * k1, 0.5);
  const Eigen::Vector4d k3 = rate(y + 0.5 * dt_s * k2, 0.5);
  const Eigen::Vector4d k4 = rate(y + dt_s * k3, 1.0);
  state_.q_world_body = to_quat(y + dt_s / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4));
  state_.L_world_kgm2ps = L0 + dL;
}

}  // namespace zerog::control
