#pragma once
// Kinematics of the KUKA KR 210 R2700: standard Denavit–Hartenberg forward kinematics to the
// flange, and the flange's angular velocity/acceleration and linear velocity/acceleration computed
// analytically from (q, q̇, q̈) by recursive propagation along the chain.
//
// Frames (proto/frames.md): B robot base, F flange (z out of the flange). All vectors returned
// here are expressed in B. Not real-time code, but allocation-free.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>

namespace zerog::sim {

using JointVector = std::array<double, 6>;  ///< A1..A6, rad (or rad/s, rad/s²)

/// Standard DH parameters of one link: T_i = Rz(θ_i) Tz(d_i) Tx(a_i) Rx(α_i) with
/// θ_i = sign · q_i + offset.
struct DhLink {
  double a_m;
  double alpha_rad;
  double d_m;
  double sign;        ///< +1 or −1: KUKA's joint direction against the DH z axis
  double offset_rad;  ///< θ_i at q_i = 0
};

/// KR 210 R2700, standard (distal) DH as in Siciliano et al., Robotics, §2.8.2:
/// T_i = Rz(θ_i) Tz(d_i) Tx(a_i) Rx(α_i). KUKA's sign conventions are kept so that the joint
/// angles are the controller's A1..A6:
///
///   i |   θ_i      |  d_i    |  a_i    |  α_i
///   1 |  −q1       |  0.675  |  0.350  |  −π/2   A1 positive turns clockwise seen from above
///   2 |   q2       |  0      |  1.150  |   0     A2 = −90°: upper arm vertical
///   3 |   q3 − π/2 |  0      | −0.041  |  −π/2   A3 = +90° (with A2 = −90°): forearm horizontal,
///   4 |  −q4       |  1.200  |  0      |  +π/2   the A4 axis 41 mm below the A3 axis
///   5 |   q5       |  0      |  0      |  −π/2   A5 = +90°: flange pointing down
///   6 |   π − q6   |  0.215  |  0      |   0
///
/// Home (A2 = −90°, A3 = +90°, others 0): flange centre at (1.765, 0, 1.784) m in B, flange z
/// along +x_B, flange x along −z_B, i.e. R_base_flange = Ry(+90°) (KUKA A, B, C = 0, 90°, 0).
inline constexpr std::array<DhLink, 6> kKr210Dh = {{
    {0.350, -1.5707963267948966, 0.675, -1.0, 0.0},
    {1.150, 0.0, 0.0, 1.0, 0.0},
    {-0.041, -1.5707963267948966, 0.0, 1.0, -1.5707963267948966},
    {0.0, 1.5707963267948966, 1.200, -1.0, 0.0},
    {0.0, -1.5707963267948966, 0.0, 1.0, 0.0},
    {0.0, 0.0, 0.215, -1.0, 3.141592653589793},
}};

/// Joint ranges of the experiment (paper 000_…, Table 4), rad.
struct JointLimits {
  JointVector lower_rad;
  JointVector upper_rad;
};
JointLimits kr210_table4_limits();

/// Home pose A1..A6 = (0, −90°, +90°, 0, 0, 0), rad.
JointVector kr210_home();

/// Flange pose only.
struct FlangePose {
  Eigen::Matrix3d R_base_flange = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p_base_flange_m = Eigen::Vector3d::Zero();
};

/// Flange pose and motion, all in base axes (B is inertial: it does not move).
struct FlangeMotion {
  Eigen::Matrix3d R_base_flange = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p_base_flange_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d omega_base_radps = Eigen::Vector3d::Zero();       ///< angular velocity
  Eigen::Vector3d omega_dot_base_radps2 = Eigen::Vector3d::Zero();  ///< angular acceleration
  Eigen::Vector3d v_flange_base_mps = Eigen::Vector3d::Zero();      ///< velocity of flange origin
  Eigen::Vector3d a_flange_base_mps2 = Eigen::Vector3d::Zero();     ///< acceleration of origin

  /// Velocity (m/s, base axes) of the body point at `lever_base_m` from the flange origin.
  Eigen::Vector3d velocity_of(const Eigen::Vector3d& lever_base_m) const;
  /// Acceleration (m/s², base axes) of the body point at `lever_base_m` from the flange origin:
  /// a_F + ω̇ × r + ω × (ω × r).
  Eigen::Vector3d acceleration_of(const Eigen::Vector3d& lever_base_m) const;
};

/// Forward kinematics to the flange. `dh` defaults to the KR 210 R2700.
FlangePose forward_kinematics(const JointVector& q_rad, const std::array<DhLink, 6>& dh = kKr210Dh);

/// Pose, twist and its time derivative of the flange, analytically from joint angles, rates and
/// accelerations (the outward recursion of Newton–Euler, Siciliano et al. §7.5, written in base
/// axes, θ̇_i = sign_i q̇_i):
///   ω_i = ω_{i−1} + θ̇_i z_{i−1},  ω̇_i = ω̇_{i−1} + θ̈_i z_{i−1} + θ̇_i ω_{i−1} × z_{i−1},
///   v_i = v_{i−1} + ω_i × Δp_i,   a_i = a_{i−1} + ω̇_i × Δp_i + ω_i × (ω_i × Δp_i).
FlangeMotion flange_motion(const JointVector& q_rad, const JointVector& qd_radps,
                           const JointVector& qdd_radps2,
                           const std::array<DhLink, 6>& dh = kKr210Dh);

/// Inverse kinematics of the spherical wrist: the joint angles A4..A6 that turn the flange to
/// `R_base_flange` while A1..A3 stay at `q_arm_rad[0..2]` (only the orientation is solved: the
/// flange position follows from the arm pose). With R_3 the orientation of DH frame 3 (from
/// A1..A3) and θ_i = sign_i q_i + offset_i, the wrist of the KR 210 (α4 = +π/2, α5 = −π/2,
/// a4 = a5 = d5 = 0) gives R_3ᵀ R_base_flange Rx(α6)ᵀ = Rz(θ4) Ry(−θ5) Rz(θ6), a ZYZ Euler
/// decomposition (Siciliano et al., Robotics, §2.12.2, eq. 2.74–2.75 with a sign on θ5).
/// Returns the two solutions (the wrist flip): [0] with A5 ≥ 0, [1] with A5 ≤ 0, each a full
/// joint vector (A1..A3 copied, A4 and A6 in (−π, π]). At the wrist singularity (|sin θ5| below
/// 1e-12) only A4 ± A6 is determined: A4 keeps `q_arm_rad[3]` and both solutions are equal.
/// Joint limits are not checked. Not real-time code, but allocation-free.
std::array<JointVector, 2> wrist_inverse_kinematics(const JointVector& q_arm_rad,
                                                    const Eigen::Matrix3d& R_base_flange,
                                                    const std::array<DhLink, 6>& dh = kKr210Dh);

}  // namespace zerog::sim
