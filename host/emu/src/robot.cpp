#include "zerog/emu/robot.hpp"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include "zerog/model/rotation.hpp"
#include "zerog/proto/rsi_si.hpp"
#include "zerog/robot/servo.hpp"

namespace zerog::emu {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

std::string text(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

}  // namespace

sim::JointLimits emulator_joint_limits() {
  return {
      {-185.0 * kDeg, -140.0 * kDeg, -120.0 * kDeg, -350.0 * kDeg, -125.0 * kDeg, -350.0 * kDeg},
      {185.0 * kDeg, -5.0 * kDeg, 168.0 * kDeg, 350.0 * kDeg, 125.0 * kDeg, 350.0 * kDeg}};
}

sim::JointVector default_start_joints() {
  return {0.0, -90.0 * kDeg, 90.0 * kDeg, 0.0, 45.0 * kDeg, 0.0};
}

RobotEmulator::RobotEmulator(const RobotConfig& config)
    : config_(config), limits_(emulator_joint_limits()) {
  const RobotConfig& c = config_;
  if (!(std::isfinite(c.physics_rate_hz) && c.physics_rate_hz > 0.0))
    throw std::invalid_argument("physics rate must be positive, is " + text(c.physics_rate_hz));
  if (!(std::isfinite(c.servo_bandwidth_hz) && c.servo_bandwidth_hz > 0.0 &&
        c.servo_bandwidth_hz <= c.physics_rate_hz / 10.0))
    throw std::invalid_argument("servo bandwidth must be in (0, physics rate / 10], is " +
                                text(c.servo_bandwidth_hz) + " Hz");
  if (!c.p_flange_tcp_m.allFinite()) throw std::invalid_argument("TCP offset must be finite");
  if (!(c.singular_threshold > 0.0 && c.max_damping >= 0.0 && c.ik_iterations >= 1))
    throw std::invalid_argument("damped least squares settings out of range");
  for (int i = 0; i < 6; ++i) {
    const double q = c.start_joints_rad[i];
    if (!(std::isfinite(q) && q >= limits_.lower_rad[i] && q <= limits_.upper_rad[i]))
      throw std::invalid_argument("start joint A" + std::to_string(i + 1) + " = " + text(q / kDeg) +
                                  " deg is outside its range [" +
                                  text(limits_.lower_rad[i] / kDeg) + ", " +
                                  text(limits_.upper_rad[i] / kDeg) + "] deg");
  }
  omega_radps_ = 2.0 * std::numbers::pi * c.servo_bandwidth_hz;
  h_s_ = 1.0 / c.physics_rate_hz;
  // x = (q − q_cmd, q̇), ẋ = A x with A = [[0, 1], [−ω², −2ω]] (a double pole at −ω):
  // e^{Ah} = e^{−ωh} [[1 + ωh, h], [−ω² h, 1 − ωh]].
  phi_ = servo_transition(h_s_);
  q_cmd_rad_ = c.start_joints_rad;
  q_setpoint_rad_ = c.start_joints_rad;
  actual_.q_rad = c.start_joints_rad;
}

TcpPose RobotEmulator::tcp_pose(const sim::JointVector& q_rad) const {
  const robot::Pose fp = robot::flange_pose(sim::kr210(), q_rad);
  return {fp.R, fp.p_m + fp.R * config_.p_flange_tcp_m};
}

TcpMotion RobotEmulator::actual_tcp() const {
  const robot::FlangeMotion fm =
      robot::flange_motion(sim::kr210(), actual_.q_rad, actual_.qd_radps, actual_.qdd_radps2);
  TcpMotion m;
  const Eigen::Vector3d lever_base_m = fm.R_base_flange * config_.p_flange_tcp_m;
  m.pose = {fm.R_base_flange, fm.p_base_flange_m + lever_base_m};
  m.v_tcp_base_mps = fm.velocity_of(lever_base_m);
  m.omega_base_radps = fm.omega_base_radps;
  return m;
}

Eigen::Matrix<double, 6, 6> RobotEmulator::jacobian(const sim::JointVector& q_rad) const {
  // Column i is the TCP twist for a unit rate of joint i alone.
  Eigen::Matrix<double, 6, 6> J;
  const sim::JointVector zero{};
  for (int i = 0; i < 6; ++i) {
    sim::JointVector qd{};
    qd[i] = 1.0;
    const robot::FlangeMotion fm = robot::flange_motion(sim::kr210(), q_rad, qd, zero);
    J.block<3, 1>(0, i) = fm.velocity_of(fm.R_base_flange * config_.p_flange_tcp_m);
    J.block<3, 1>(3, i) = fm.omega_base_radps;
  }
  return J;
}

CorrectionOutcome RobotEmulator::clamp_command() {
  CorrectionOutcome out;
  for (int i = 0; i < 6; ++i) {
    const double q = std::clamp(q_cmd_rad_[i], limits_.lower_rad[i], limits_.upper_rad[i]);
    if (q != q_cmd_rad_[i]) out.clamped = true;
    q_cmd_rad_[i] = q;
  }
  if (out.clamped) ++counters_.clamped_commands;
  // The interpolator reaches the new command in one interpolation time, at constant speed.
  for (int i = 0; i < 6; ++i) {
    if (config_.interpolation_s > 0.0) {
      setpoint_rate_[i] = (q_cmd_rad_[i] - q_setpoint_rad_[i]) / config_.interpolation_s;
    } else {
      q_setpoint_rad_[i] = q_cmd_rad_[i];
    }
  }
  return out;
}

CorrectionOutcome RobotEmulator::apply_rkorr(const proto::rsi::Correction& correction) {
  proto::rsi::Reply reply;
  reply.has_rkorr = true;
  reply.rkorr = correction;
  const samples::RobotCorrection si = proto::rsi::correction_from_reply(reply);
  const TcpPose old_pose = tcp_pose(q_cmd_rad_);
  const Eigen::Vector3d p_target =
      old_pose.p_base_tcp_m + Eigen::Map<const Eigen::Vector3d>(si.translation_m.data());
  const Eigen::Matrix3d R_correction =
      Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(si.R_correction.data());
  const Eigen::Matrix3d R_target = R_correction * old_pose.R_base_tcp;

  // Damped least squares with damping only near a singularity (Chiaverini, "Singularity-robust
  // task-priority redundancy resolution", IEEE T-RA 13(3), 1997, eq. 12–13):
  // Δq = Σ σᵢ / (σᵢ² + λ²) vᵢ uᵢᵀ e, λ² = λ_max² (1 − (σ_min / ε)²) for σ_min < ε, else 0.
  // Newton steps from q_cmd: the first is the plain Jacobian step, the next remove its
  // second-order error.
  CorrectionOutcome out;
  out.sigma_min = std::numeric_limits<double>::infinity();
  sim::JointVector q = q_cmd_rad_;
  for (int k = 0; k < config_.ik_iterations; ++k) {
    const TcpPose now = tcp_pose(q);
    Eigen::Matrix<double, 6, 1> e;
    e.head<3>() = p_target - now.p_base_tcp_m;
    const Eigen::AngleAxisd rotation(R_target * now.R_base_tcp.transpose());
    e.tail<3>() = rotation.angle() * rotation.axis();
    if (e.norm() < 1e-13) break;
    const Eigen::JacobiSVD<Eigen::Matrix<double, 6, 6>> svd(
        jacobian(q), Eigen::ComputeFullU | Eigen::ComputeFullV);
    const auto& sigma = svd.singularValues();
    const double sigma_min = sigma[5];
    out.sigma_min = std::min(out.sigma_min, sigma_min);
    double lambda2 = 0.0;
    if (sigma_min < config_.singular_threshold) {
      const double r = sigma_min / config_.singular_threshold;
      lambda2 = config_.max_damping * config_.max_damping * (1.0 - r * r);
      out.near_singular = true;
    }
    const Eigen::Matrix<double, 6, 1> ue = svd.matrixU().transpose() * e;
    Eigen::Matrix<double, 6, 1> scaled;
    for (int i = 0; i < 6; ++i) {
      const double d = sigma[i] * sigma[i] + lambda2;
      scaled[i] = d > 0.0 ? sigma[i] / d * ue[i] : 0.0;
    }
    const Eigen::Matrix<double, 6, 1> dq = svd.matrixV() * scaled;
    for (int i = 0; i < 6; ++i) q[i] += dq[i];
  }
  q_cmd_rad_ = q;
  const CorrectionOutcome clamped = clamp_command();
  out.clamped = clamped.clamped;
  if (out.near_singular) ++counters_.near_singular_cycles;
  ++counters_.rkorr_applied;
  return out;
}

CorrectionOutcome RobotEmulator::apply_akorr(const std::array<double, 6>& akorr_deg) {
  const std::array<double, 6> rad = proto::rsi::joints_to_rad(akorr_deg);
  for (int i = 0; i < 6; ++i) q_cmd_rad_[i] += rad[i];
  ++counters_.akorr_applied;
  return clamp_command();
}

Eigen::Matrix2d RobotEmulator::servo_transition(double tau_s) const {
  return robot::servo_transition(omega_radps_, tau_s);
}

void RobotEmulator::step() {
  const double w = omega_radps_;
  for (int i = 0; i < 6; ++i) {
    double s = q_setpoint_rad_[i];
    double q = actual_.q_rad[i];
    double qd = actual_.qd_radps[i];
    // The set point moves at the interpolator's speed r until it reaches the command (within
    // this step or not), then holds. Over a piece of length τ in which s(t) = s + r t, the
    // servo error (e, z) = (q − s + 2r/ω, q̇ − r) obeys the homogeneous equation, so the step
    // is exact for the ramp too (first-order hold): a set point advanced in stairs of r h
    // would make q̈ a sawtooth, and its value at the step's end would be off by −ω² r h / 2.
    const double remaining = q_cmd_rad_[i] - s;
    const double r = setpoint_rate_[i];
    double ramp_s = 0.0;  // how long in this step the set point still moves
    if (remaining != 0.0 && r * remaining > 0.0) {
      ramp_s = std::min(h_s_, remaining / r);
    } else {
      s = q_cmd_rad_[i];  // reached (or no interpolation): held from here
    }
    auto advance = [&](double tau_s, double rate, const Eigen::Matrix2d& phi) {
      robot::servo_advance(w, tau_s, rate, phi, s, q, qd);
    };
    if (ramp_s >= h_s_) {
      advance(h_s_, r, phi_);
    } else {
      if (ramp_s > 0.0) {
        advance(ramp_s, r, servo_transition(ramp_s));
        s = q_cmd_rad_[i];
      }
      advance(h_s_ - ramp_s, 0.0, ramp_s > 0.0 ? servo_transition(h_s_ - ramp_s) : phi_);
    }
    q_setpoint_rad_[i] = s;
    actual_.q_rad[i] = q;
    actual_.qd_radps[i] = qd;
    actual_.qdd_radps2[i] = robot::servo_accel(w, s, q, qd);
  }
  ++counters_.servo_steps;
}

proto::rsi::RobotMessage RobotEmulator::message(std::uint64_t ipoc, std::uint64_t delay) const {
  const TcpPose pose = tcp_pose(actual_.q_rad);
  samples::RobotSample s;
  s.ipoc = ipoc;
  s.has_delay = true;
  s.delay = delay;
  for (int i = 0; i < 6; ++i) s.joints_rad[i] = actual_.q_rad[i];
  s.has_pose = true;
  s.p_base_tcp_m = {pose.p_base_tcp_m.x(), pose.p_base_tcp_m.y(), pose.p_base_tcp_m.z()};
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) s.R_base_tcp[3 * r + c] = pose.R_base_tcp(r, c);
  }
  return proto::rsi::robot_message_from_sample(s);
}

}  // namespace zerog::emu
