#pragma once
// The zero-gravity dynamics of a virtual free body (paper 000_… eq. 6–7, with the gyroscopic
// term): m v̇ = F, I ω̇ + ω × I ω = M, the contact torque taken about the virtual centre of mass.
// Real-time safe: fixed-size state, no allocation, no exceptions.
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace zerog::control {

/// Mass properties of the simulated object (they may differ from the real payload's:
/// semi-physical simulation, 000_… §5).
struct BodyParams {
  double mass_kg = 100.0;
  /// Inertia tensor about the centre of mass, in body axes (symmetric positive definite).
  Eigen::Matrix3d inertia_body_kgm2 = Eigen::Matrix3d::Identity() * 5.0;
};

/// State of the body: centre-of-mass position and attitude in the world frame, linear velocity
/// (world) and angular momentum (world). The angular momentum is the state rather than the
/// rate, so a torque-free body keeps it exactly whatever the step size.
struct BodyState {
  Eigen::Vector3d p_world_m = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_world_body = Eigen::Quaterniond::Identity();
  Eigen::Vector3d v_world_mps = Eigen::Vector3d::Zero();
  Eigen::Vector3d L_world_kgm2ps = Eigen::Vector3d::Zero();
};

/// Moves a torque given about point A to point B for the same force: M_B = M_A + (p_A − p_B) × F
/// (all vectors in one frame).
inline Eigen::Vector3d torque_about(const Eigen::Vector3d& torque_A, const Eigen::Vector3d& force,
                                    const Eigen::Vector3d& p_A, const Eigen::Vector3d& p_B) {
  return torque_A + (p_A - p_B).cross(force);
}

class VirtualBody {
 public:
  explicit VirtualBody(const BodyParams& params, const BodyState& initial = {});

  /// Advances by dt under a constant contact force (world, N) and torque about the centre of
  /// mass (world, N·m). Linear part: exact for a constant force. Angular part: L += M dt, then
  /// the attitude by 4th-order Runge–Kutta of q̇ = ½ q ⊗ ω with ω = I⁻¹ (Rᵀ L) (body), which is
  /// Euler's equation I ω̇ + ω × I ω = M written for L. Real-time safe.
  void step(const Eigen::Vector3d& force_world_N, const Eigen::Vector3d& torque_world_Nm,
            double dt_s);

  const BodyState& state() const { return state_; }
  const BodyParams& params() const { return params_; }
  void reset(const BodyState& s) { state_ = s; }

  /// Angular velocity in body axes, rad/s.
  Eigen::Vector3d omega_body() const;
  Eigen::Vector3d omega_world() const;
  Eigen::Vector3d linear_momentum_world() const { return params_.mass_kg * state_.v_world_mps; }
  double kinetic_energy_J() const;

 private:
  BodyParams params_;
  Eigen::Matrix3d inertia_inv_body_;
  BodyState state_;
};

}  // namespace zerog::control
