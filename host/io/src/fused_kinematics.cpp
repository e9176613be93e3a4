#include "zerog/io/fused_kinematics.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "zerog/robot/derive_kinematics.hpp"
#include "zerog/robot/forward_kinematics.hpp"

namespace zerog::io {

using formats::Log;
using formats::Sample;

namespace {

// Linear interpolation of per-row vectors at time t (clamped at the ends); `k` walks forward.
Eigen::Vector3d interpolate(std::span<const double> t_s, std::span<const Eigen::Vector3d> v,
                            double t, std::size_t& k) {
  while (k + 1 < t_s.size() && t_s[k + 1] <= t) ++k;
  const std::size_t k1 = std::min(k + 1, t_s.size() - 1);
  const double alpha = k1 == k ? 0.0 : std::clamp((t - t_s[k]) / (t_s[k1] - t_s[k]), 0.0, 1.0);
  return v[k] + alpha * (v[k1] - v[k]);
}

// The d-th Savitzky–Golay derivative of every joint (row-major), three at a time.
void joint_derivative(std::span<const double> t_s, std::span<const double> q, std::size_t J,
                      const robot::SgSettings& sg, int derivative, std::vector<double>& out) {
  const std::size_t n = t_s.size();
  std::vector<Eigen::Vector3d> in(n), d(n);
  for (std::size_t first = 0; first < J; first += 3) {
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t c = 0; c < 3; ++c)
        in[i][static_cast<int>(c)] = first + c < J ? q[i * J + first + c] : 0.0;
    if (!robot::sg_differentiate(t_s, in, sg, derivative, d))
      throw std::runtime_error("fused kinematics: the joint stream is too short to differentiate");
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t c = 0; c < 3 && first + c < J; ++c)
        out[i * J + first + c] = d[i][static_cast<int>(c)];
  }
}

// Step 1: the link's deflection δ of every joint at every joint sample (row-major, recorded
// order).
std::vector<double> deflection(const FusionInput& in, const FusionSettings& s,
                               FusionResult& result) {
  const robot::RobotModel& model = *in.robot;
  const std::size_t J = static_cast<std::size_t>(model.joint_count);
  const std::size_t n = in.joint_t_s.size();
  std::vector<double> delta(n * J, 0.0);
  result.deflection_mean_rad.assign(J, 0.0);
  result.deflection_rms_rad.assign(J, 0.0);
  if (!model.elastic()) return delta;
  result.elastic = true;
  // The elasticity of each recorded joint (DH row i reads recorded joint input_index[i]).
  std::vector<robot::JointElasticity> elasticity(J);
  for (std::size_t i = 0; i < J; ++i)
    elasticity[static_cast<std::size_t>(model.input_index[i])] = model.elasticity[i];

  // The load: the slow part of the measured wrench, at each joint sample, through Jᵀ. (The
  // sensor's bias in it, tens of N, changes the sag by tens of µrad, slowly: the IMU's part of
  // step 3 takes it out; removing a fitted bias first measured no gain.)
  std::vector<Eigen::Vector3d> force(in.force_sensor_N.begin(), in.force_sensor_N.end());
  std::vector<Eigen::Vector3d> torque(in.torque_sensor_Nm.begin(), in.torque_sensor_Nm.end());
  zero_phase_lowpass(in.row_t_s, force, s.load_bandwidth_hz);
  zero_phase_lowpass(in.row_t_s, torque, s.load_bandwidth_hz);
  std::vector<double> tau(n * J, 0.0);
  std::size_t kf = 0, kt = 0;
  const Eigen::Vector3d p_flange_sensor = model.flange_sensor.p_m;
  for (std::size_t i = 0; i < n; ++i) {
    const std::span<const double> q = in.joints_rad.subspan(i * J, J);
    const robot::Pose flange = robot::flange_pose(model, q);
    const Eigen::Matrix3d R_base_sensor = flange.R * model.flange_sensor.R;
    const Eigen::Vector3d F_B = R_base_sensor * interpolate(in.row_t_s, force, in.joint_t_s[i], kf);
    // About the flange origin: M_F = M_S + r_FS × F, r_FS the sensor origin from the flange.
    const Eigen::Vector3d M_B =
        R_base_sensor * interpolate(in.row_t_s, torque, in.joint_t_s[i], kt) +
        (flange.R * p_flange_sensor).cross(F_B);
    robot::joint_torques(model, q, F_B, M_B, std::span<double>(&tau[i * J], J));
  }
  // The motor's acceleration: the Savitzky–Golay second derivative of the joints
  // (s.excitation_sg), so that the encoders' quantisation does not drive the modes.
  std::vector<double> qdd(n * J, 0.0);
  joint_derivative(in.joint_t_s, in.joints_rad, J, s.excitation_sg, 2, qdd);
  for (std::size_t k = 0; k < J; ++k) {
    const robot::JointElasticity& e = elasticity[k];
    if (e.rigid()) continue;
    double d = tau[k] / e.stiffness_Nm_per_rad, v = 0.0;  // settled at the first sample
    delta[k] = d;
    for (std::size_t i = 1; i < n; ++i) {
      robot::advance_deflection(e, d, v, in.joint_t_s[i] - in.joint_t_s[i - 1], s.substep_s,
                                qdd[(i - 1) * J + k], qdd[i * J + k], tau[(i - 1) * J + k],
                                tau[i * J + k]);
      delta[i * J + k] = d;
    }
    double mean = 0.0, square = 0.0;
    for (std::size_t i = 0; i < n; ++i) mean += delta[i * J + k];
    mean /= static_cast<double>(n);
    for (std::size_t i = 0; i < n; ++i) square += std::pow(delta[i * J + k] - mean, 2);
    result.deflection_mean_rad[k] = mean;
    result.deflection_rms_rad[k] = std::sqrt(square / static_cast<double>(n));
  }
  return delta;
}

}  // namespace

FusionSettings fusion_settings(double period_s, double bandwidth_hz, double accel_bandwidth_hz,
                               double crossover_hz) {
  FusionSettings s;
  s.crossover_hz = crossover_hz;
  s.sg = robot::choose_sg_window(period_s, bandwidth_hz, robot::kMaxSgOrder, 2);
  s.accel_sg = robot::choose_sg_window(period_s, accel_bandwidth_hz, robot::kMaxSgOrder, 2);
  s.excitation_sg = robot::choose_sg_window(period_s, kFusedExcitationHz, robot::kMaxSgOrder, 2);
  return s;
}

RowSignals row_signals(const Log& log) {
  RowSignals r;
  for (const Sample& s : log.samples) {
    r.t_s.push_back(s.t_s);
    r.specific_force_mps2.push_back(s.specific_force_imu_mps2);
    r.angular_rate_radps.push_back(s.angular_rate_imu_radps);
    r.force_N.push_back(s.force_sensor_N);
    r.torque_Nm.push_back(s.torque_sensor_Nm);
  }
  return r;
}

FusionInput fusion_input(const RowSignals& rows) {
  FusionInput in;
  in.row_t_s = rows.t_s;
  in.imu_specific_force_mps2 = rows.specific_force_mps2;
  in.imu_angular_rate_radps = rows.angular_rate_radps;
  in.force_sensor_N = rows.force_N;
  in.torque_sensor_Nm = rows.torque_Nm;
  return in;
}

void zero_phase_lowpass(std::span<const double> t_s, std::span<Eigen::Vector3d> values,
                        double cutoff_hz) {
  const std::size_t n = values.size();
  if (n < 2) return;
  const double w = 2.0 * std::numbers::pi * cutoff_hz;
  for (std::size_t i = 1; i < n; ++i) {
    const double a = std::exp(-w * (t_s[i] - t_s[i - 1]));
    values[i] = a * values[i - 1] + (1.0 - a) * values[i];
  }
  for (std::size_t i = n - 1; i-- > 0;) {
    const double a = std::exp(-w * (t_s[i + 1] - t_s[i]));
    values[i] = a * values[i + 1] + (1.0 - a) * values[i];
  }
}

FusionResult fuse_kinematics(const FusionInput& in, const FusionSettings& s) {
  if (in.robot == nullptr) throw std::runtime_error("fused kinematics: no robot");
  const std::size_t J = static_cast<std::size_t>(in.robot->joint_count);
  const std::size_t n = in.joint_t_s.size(), rows = in.row_t_s.size();
  if (in.joints_rad.size() != n * J || in.imu_specific_force_mps2.size() != rows ||
      in.imu_angular_rate_radps.size() != rows || in.force_sensor_N.size() != rows ||
      in.torque_sensor_Nm.size() != rows)
    throw std::runtime_error("fused kinematics: the joint stream and the rows disagree in size");
  FusionResult result;
  const std::vector<double> delta = deflection(in, s, result);

  // Step 2: the link's motion. The motor's part through s.sg (the encoders' quantisation
  // filtered); the deflection's, a smooth ODE output, through the wider s.accel_sg as
  // derive(q + δ) − derive(q) on the same samples, in which the quantisation cancels; ω̇ all
  // through s.accel_sg.
  std::vector<double> q_link(in.joints_rad.begin(), in.joints_rad.end());  // q + δ
  for (std::size_t i = 0; i < q_link.size(); ++i) q_link[i] += delta[i];
  std::vector<robot::SensorKinematics> motor(n), link_wide(n), motor_wide(n);
  robot::DifferentiatorSettings with;
  with.sg = s.sg;
  robot::DeriveStatus status =
      robot::derive_kinematics(*in.robot, in.joint_t_s, in.joints_rad, J, with, motor);
  with.sg = s.accel_sg;
  if (status.ok())
    status = robot::derive_kinematics(*in.robot, in.joint_t_s, q_link, J, with, link_wide);
  if (status.ok() && result.elastic)
    status = robot::derive_kinematics(*in.robot, in.joint_t_s, in.joints_rad, J, with, motor_wide);
  if (!status.ok())
    throw std::runtime_error("fused kinematics: deriving the joints' motion failed (code " +
                             std::to_string(static_cast<int>(status.code)) + ", sample " +
                             std::to_string(status.sample) + ")");
  std::vector<Eigen::Vector3d> omega_S(n), omega_dot_S(n), force_S(n);
  for (std::size_t i = 0; i < n; ++i) {
    robot::SensorKinematics k = motor[i];
    if (result.elastic) {
      k.omega_sensor_radps += link_wide[i].omega_sensor_radps - motor_wide[i].omega_sensor_radps;
      k.specific_force_sensor_mps2 +=
          link_wide[i].specific_force_sensor_mps2 - motor_wide[i].specific_force_sensor_mps2;
    }
    k.omega_dot_sensor_radps2 = link_wide[i].omega_dot_sensor_radps2;
    omega_S[i] = k.omega_sensor_radps;
    omega_dot_S[i] = k.omega_dot_sensor_radps2;
    force_S[i] = robot::specific_force_at_point(k, in.p_sensor_imu_m);
  }
  // Onto the rows, at the IMU: ω_I = R_SIᵀ ω_S, f_I = R_SIᵀ (f_S + ω̇ × r + ω × (ω × r)).
  const Eigen::Matrix3d R_is = in.R_sensor_imu.transpose();
  result.specific_force_mps2.resize(rows);
  result.angular_rate_radps.resize(rows);
  result.angular_accel_radps2.resize(rows);
  std::size_t k1 = 0, k2 = 0, k3 = 0;
  std::vector<Eigen::Vector3d> df(rows), dw(rows);
  for (std::size_t r = 0; r < rows; ++r) {
    const double t = in.row_t_s[r];
    result.specific_force_mps2[r] = R_is * interpolate(in.joint_t_s, force_S, t, k1);
    result.angular_rate_radps[r] = R_is * interpolate(in.joint_t_s, omega_S, t, k2);
    result.angular_accel_radps2[r] = R_is * interpolate(in.joint_t_s, omega_dot_S, t, k3);
    df[r] = in.imu_specific_force_mps2[r] - result.specific_force_mps2[r];
    dw[r] = in.imu_angular_rate_radps[r] - result.angular_rate_radps[r];
  }
  // Step 3: below the crossover the IMU.
  zero_phase_lowpass(in.row_t_s, df, s.crossover_hz);
  zero_phase_lowpass(in.row_t_s, dw, s.crossover_hz);
  double sf = 0.0, sw = 0.0;
  for (std::size_t r = 0; r < rows; ++r) {
    result.specific_force_mps2[r] += df[r];
    result.angular_rate_radps[r] += dw[r];
    sf += df[r].squaredNorm() / 3.0;
    sw += dw[r].squaredNorm() / 3.0;
    if (rows < 3) continue;
    const std::size_t a = r == 0 ? 0 : r - 1, b = r + 1 == rows ? r : r + 1;
    result.angular_accel_radps2[r] += (dw[b] - dw[a]) / (in.row_t_s[b] - in.row_t_s[a]);
  }
  result.correction_specific_force_mps2 = std::sqrt(sf / static_cast<double>(rows));
  result.correction_angular_rate_radps = std::sqrt(sw / static_cast<double>(rows));
  return result;
}

}  // namespace zerog::io
