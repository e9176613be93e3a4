#include "zerog/loop/motion_estimator.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "zerog/model/rotation.hpp"
#include "zerog/robot/forward_kinematics.hpp"
#include "zerog/robot/savitzky_golay.hpp"
#include "zerog/robot/servo.hpp"

namespace zerog::loop {
namespace {

// A first-order low-pass's gain for a step of dt at corner f (the exact discretisation of
// dy/dt = 2πf (x − y) for x held over the step).
double lowpass_gain(double f_hz, double dt_s) {
  return 1.0 - std::exp(-2.0 * std::numbers::pi * f_hz * dt_s);
}

Eigen::Matrix3d row_rotation(const model::FeatureSignals& s) {
  return Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(s.R_base_sensor.data());
}

}  // namespace

zerog::Status check_estimator_config(const MotionEstimatorConfig& c) {
  auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!positive(c.crossover_hz)) return zerog::Status::invalid("crossover_hz", "must be positive");
  if (!positive(c.load_bandwidth_hz))
    return zerog::Status::invalid("load_bandwidth_hz", "must be positive");
  if (!positive(c.excitation_hz))
    return zerog::Status::invalid("excitation_hz", "must be positive");
  if (!(c.servo_hz >= 0.0 && std::isfinite(c.servo_hz)))
    return zerog::Status::invalid("servo_hz", "must be zero (off) or positive");
  if (!(std::isfinite(c.ringing_radps) && c.ringing_radps >= 0.0))
    return zerog::Status::invalid("ringing_radps", "must be >= 0");
  if (!(std::isfinite(c.mode_gain) && c.mode_gain >= 0.0 && c.mode_gain <= 1.0))
    return zerog::Status::invalid("mode_gain", "must be in [0, 1]");
  if (!(std::isfinite(c.ringing_hold_s) && c.ringing_hold_s >= 0.0))
    return zerog::Status::invalid("ringing_hold_s", "must be >= 0 s");
  if (!(positive(c.substep_s) && c.substep_s <= 0.01))
    return zerog::Status::invalid("substep_s", "must be in (0, 0.01] s");
  auto non_negative = [](double v) { return std::isfinite(v) && v >= 0.0; };
  if (!non_negative(c.ft_rate_hz)) return zerog::Status::invalid("ft_rate_hz", "must be >= 0");
  if (!non_negative(c.imu_rate_hz)) return zerog::Status::invalid("imu_rate_hz", "must be >= 0");
  if (!non_negative(c.ft_delay_s)) return zerog::Status::invalid("ft_delay_s", "must be >= 0");
  if (!non_negative(c.imu_delay_s)) return zerog::Status::invalid("imu_delay_s", "must be >= 0");
  if (!c.gravity_base_mps2.allFinite())
    return zerog::Status::invalid("gravity_base_mps2", "must be finite");
  return {};
}

zerog::Status MotionEstimator::configure(const MotionEstimatorConfig& config,
                                         const Eigen::Matrix3d& R_sensor_imu,
                                         const Eigen::Vector3d& p_sensor_imu_m,
                                         const std::optional<robot::RobotModel>& robot) {
  if (zerog::Status st = check_estimator_config(config); !st.ok()) return st;
  config_ = config;
  R_sensor_imu_ = R_sensor_imu;
  p_sensor_imu_m_ = p_sensor_imu_m;
  have_robot_ = robot.has_value();
  elastic_ = have_robot_ && robot->elastic();
  if (have_robot_) robot_ = *robot;
  elasticity_ = {};
  if (have_robot_) {
    // DH row i reads recorded joint input_index[i].
    for (int i = 0; i < robot_.joint_count; ++i)
      elasticity_[static_cast<std::size_t>(robot_.input_index[i])] =
          robot_.elasticity[static_cast<std::size_t>(i)];
  }
  reset();
  return {};
}

void MotionEstimator::reset() noexcept {
  started_ = false;
  updates_ = 0;
  t_s_ = 0.0;
  t_before_s_ = -1.0;
  wrench_lp_ = {};
  qdd_lp1_ = {};
  qdd_lp2_ = {};
  drive_ = {};
  tau_ = {};
  delta_ = {};
  delta_dot_ = {};
  offset_w_.setZero();
  residual_ms_ = 0.0;
  excited_ = false;
  since_excitation_s_ = std::numeric_limits<double>::infinity();
  offsets_.reset();
  servo_.configure(config_.servo_hz);
}

void ForceOffsets::reset() noexcept {
  bias_I_.setZero();
  error_B_.setZero();
  P_ = Eigen::Matrix<double, 6, 6>::Identity() * kPriorVariance;
  sum_variance_ = 2.0 * kPriorVariance;
  steady_gain_ = 0.0;
}

void ForceOffsets::update(const Eigen::Vector3d& y, const Eigen::Matrix3d& R_IB,
                          double k_steady) noexcept {
  // The Kalman filter of the two offsets x = (b_I, e_B), y = b_I + R_IB e_B + v (header, step
  // 3). Units: the IMU's white noise variance per row is the unit (r = 1); a random walk of
  // variance q per row has the steady-state gain K with q = K² r / (1 − K) (the scalar
  // filter's Riccati equation), shared half and half so that their sum, all a still payload
  // sees, follows at the crossover.
  if (k_steady > 0.0) {
    steady_gain_ = k_steady;
    const double q = 0.5 * k_steady * k_steady / (1.0 - k_steady);
    P_.diagonal().array() += q;
  }
  Eigen::Matrix<double, 3, 6> H;
  H << Eigen::Matrix3d::Identity(), R_IB;
  const Eigen::Matrix3d S = H * P_ * H.transpose() + Eigen::Matrix3d::Identity();
  const Eigen::Matrix<double, 6, 3> PHt = P_ * H.transpose();
  const Eigen::Matrix<double, 6, 3> K = S.ldlt().solve(PHt.transpose()).transpose();
  const Eigen::Vector3d innovation = y - bias_I_ - R_IB * error_B_;
  const Eigen::Matrix<double, 6, 1> dx = K * innovation;
  bias_I_ += dx.head<3>();
  error_B_ += dx.tail<3>();
  // Joseph form: P stays symmetric and positive under rounding over hours of rows.
  const Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Identity() - K * H;
  P_ = A * P_ * A.transpose() + K * K.transpose();
  sum_variance_ = (H * P_ * H.transpose()).diagonal().maxCoeff();
}

// Step 1's result: the motor side's motion at the centre row c, from the quadratic fits of the
// rows' poses and joints (rotation vectors r in c's axes; the rest in B).
struct MotionEstimator::MotorMotion {
  Eigen::Matrix3d R_c;
  Eigen::Vector3d a_B = Eigen::Vector3d::Zero();
  Eigen::Vector3d r0 = Eigen::Vector3d::Zero(), r1 = Eigen::Vector3d::Zero(),
                  r2 = Eigen::Vector3d::Zero();
  std::array<double, robot::kMaxJoints> qdd{};
  /// Attitude and rate (B axes) at an instant τ (≤ 0) from c.
  Eigen::Matrix3d attitude_at(double tau) const {
    return Eigen::Matrix3d(
        R_c * model::rotation_from_vector<double>(r0 + tau * r1 + 0.5 * tau * tau * r2));
  }
  Eigen::Vector3d rate_at(double tau) const { return Eigen::Vector3d(R_c * (r1 + tau * r2)); }
};

// The link side's motion (B axes) at the F/T's instant (the output) and at the IMU's (step 3's
// comparison): the motor side's, then turned and sped up by the joints' deflection (step 2).
struct MotionEstimator::LinkMotion {
  Eigen::Matrix3d R_ft, R_imu;
  Eigen::Vector3d omega_ft, omega_imu;
  Eigen::Vector3d omega_dot_B, a_B;
};

namespace {

// The robot's signals at the IMU (rigid-body transfer from S's origin by r), I axes, for the
// link at attitude R with rate w_B.
void at_imu(const Eigen::Matrix3d& R_sensor_imu, const Eigen::Vector3d& r,
            const Eigen::Vector3d& gravity_B, const Eigen::Matrix3d& R, const Eigen::Vector3d& w_B,
            const Eigen::Vector3d& omega_dot_B, const Eigen::Vector3d& a_B, Eigen::Vector3d& f_I,
            Eigen::Vector3d& w_I) {
  const Eigen::Vector3d f_S = R.transpose() * (a_B - gravity_B);
  const Eigen::Vector3d w_S = R.transpose() * w_B;
  const Eigen::Vector3d wd_S_link = R.transpose() * omega_dot_B;
  f_I = R_sensor_imu.transpose() * (f_S + wd_S_link.cross(r) + w_S.cross(w_S.cross(r)));
  w_I = R_sensor_imu.transpose() * w_S;
}

}  // namespace

bool MotionEstimator::fit_motor_side(std::span<const model::FeatureSignals* const> rows,
                                     MotorMotion& m) const noexcept {
  const std::size_t n = rows.size();
  const std::size_t c = n / 2;
  const double t_c = rows[c]->t_s;
  const double half_span = std::max(rows[n - 1]->t_s - t_c, t_c - rows[0]->t_s);
  robot::LocalPolyFit fit(2);
  for (std::size_t k = 0; k < n; ++k) fit.add(rows[k]->t_s - t_c, half_span);
  if (!fit.solve()) return false;
  m.R_c = row_rotation(*rows[c]);
  // The quadratics' value, slope and curvature at 0.
  const int J = have_robot_ ? robot_.joint_count : 0;
  for (std::size_t k = 0; k < n; ++k) {
    const model::FeatureSignals& row = *rows[k];
    const double tau = row.t_s - t_c;
    const double d0 = fit.weight(tau, 0), d1 = fit.weight(tau, 1), d2 = fit.weight(tau, 2);
    const Eigen::Vector3d p = Eigen::Map<const Eigen::Vector3d>(row.p_base_sensor_m.data());
    m.a_B += d2 * p;
    const Eigen::AngleAxisd turn(Eigen::Matrix3d(m.R_c.transpose() * row_rotation(row)));
    const Eigen::Vector3d r = turn.angle() * turn.axis();
    m.r0 += d0 * r;
    m.r1 += d1 * r;
    m.r2 += d2 * r;
    for (int j = 0; j < J; ++j)
      m.qdd[static_cast<std::size_t>(j)] += d2 * row.joints_rad[static_cast<std::size_t>(j)];
  }
  return true;
}

void MotionEstimator::deflect(const MotorMotion& m, const model::FeatureSignals& centre,
                              const std::array<double, 6>& wrench,
                              const model::ImuSignals<double>& imu_at_c, double dt, double schedule,
                              const std::array<double, robot::kMaxJoints>& servo_qdd,
                              LinkMotion& link, MotionEstimate& out) noexcept {
  const int J = have_robot_ ? robot_.joint_count : 0;
  Eigen::Matrix<double, 6, robot::kMaxJoints> jac;
  robot::sensor_jacobian(robot_, std::span<const double>(centre.joints_rad.data(), 6), jac);
  const double k_load = started_ ? lowpass_gain(config_.load_bandwidth_hz, dt) : 1.0;
  for (int i = 0; i < 6; ++i) wrench_lp_[i] += k_load * (wrench[i] - wrench_lp_[i]);
  const Eigen::Vector3d F_B = m.R_c * Eigen::Vector3d(wrench_lp_[0], wrench_lp_[1], wrench_lp_[2]);
  const Eigen::Vector3d M_B = m.R_c * Eigen::Vector3d(wrench_lp_[3], wrench_lp_[4], wrench_lp_[5]);
  const double k_exc = started_ ? lowpass_gain(config_.excitation_hz, dt) : 0.0;
  Eigen::Vector3d theta = Eigen::Vector3d::Zero(), dw = Eigen::Vector3d::Zero(),
                  dwd = Eigen::Vector3d::Zero(), da = Eigen::Vector3d::Zero();
  for (int j = 0; j < J; ++j) {
    const std::size_t u = static_cast<std::size_t>(j);
    const double tau1 = jac.col(j).head<3>().dot(F_B) + jac.col(j).tail<3>().dot(M_B);
    // The drive: the servo model's acceleration (zero without one) plus the measured joints'
    // disagreement with it through the two stages.
    const double qdd0 = drive_[u];
    qdd_lp1_[u] += k_exc * (m.qdd[u] - servo_qdd[u] - qdd_lp1_[u]);
    qdd_lp2_[u] += k_exc * (qdd_lp1_[u] - qdd_lp2_[u]);
    drive_[u] = servo_qdd[u] + qdd_lp2_[u];
    const robot::JointElasticity& e = elasticity_[u];
    double ddot = 0.0;
    if (!started_) {
      delta_[u] = e.rigid() ? 0.0 : tau1 / e.stiffness_Nm_per_rad;  // the static sag
      delta_dot_[u] = 0.0;
    } else {
      ddot = robot::advance_deflection(e, delta_[u], delta_dot_[u], dt, config_.substep_s, qdd0,
                                       drive_[u], tau_[u], tau1);
    }
    tau_[u] = tau1;
    const Eigen::Vector3d Jv = jac.col(j).head<3>(), Jw = jac.col(j).tail<3>();
    theta += Jw * delta_[u];
    dw += Jw * delta_dot_[u];
    dwd += Jw * ddot;
    da += Jv * ddot;
    out.deflection_rad[u] = delta_[u];
  }
  // 4a. The gyro corrects the main axes' modelled rates while the arm rings.
  if (started_ && schedule > 0.0 && config_.mode_gain > 0.0) {
    const Eigen::Vector3d w_gyro_B =
        link.R_imu * R_sensor_imu_ * (imu_at_c.angular_rate_imu - offset_w_);
    const Eigen::Vector3d e = w_gyro_B - (link.omega_imu + dw);
    Eigen::Matrix<double, 3, robot::kMaxJoints> Jw =
        Eigen::Matrix<double, 3, robot::kMaxJoints>::Zero();
    for (int j = 0; j < std::min(J, kObservedAxes); ++j)
      if (!elasticity_[static_cast<std::size_t>(j)].rigid()) Jw.col(j) = jac.col(j).tail<3>();
    const Eigen::Matrix3d A = Jw * Jw.transpose() + kDamping * Eigen::Matrix3d::Identity();
    const Eigen::Matrix<double, robot::kMaxJoints, 1> d = Jw.transpose() * A.ldlt().solve(e);
    const double g = schedule * config_.mode_gain;
    for (int j = 0; j < std::min(J, kObservedAxes); ++j) {
      delta_dot_[static_cast<std::size_t>(j)] += g * d[j];
      dw += jac.col(j).tail<3>() * (g * d[j]);
    }
  }
  const Eigen::Matrix3d turn = model::rotation_from_vector<double>(theta);
  link.R_ft = turn * link.R_ft;
  link.R_imu = turn * link.R_imu;
  link.omega_ft += dw;
  link.omega_imu += dw;
  link.omega_dot_B += dwd;
  link.a_B += da;
}

void MotionEstimator::track_offsets(const model::ImuSignals<double>& imu_at_c,
                                    const Eigen::Vector3d& f_I_cmp,
                                    const Eigen::Vector3d& omega_I_cmp,
                                    const Eigen::Matrix3d& R_link_imu, double dt) noexcept {
  ++updates_;
  if (config_.mutant_without_imu) return;
  const double k_steady = started_ ? lowpass_gain(config_.crossover_hz, dt) : 1.0;
  const double k = std::max(k_steady, 1.0 / static_cast<double>(updates_));
  offset_w_ += k * (imu_at_c.angular_rate_imu - omega_I_cmp - offset_w_);
  offsets_.update(imu_at_c.specific_force_imu - f_I_cmp,
                  R_sensor_imu_.transpose() * R_link_imu.transpose(), started_ ? k_steady : 0.0);
}

samples::RobotCorrection as_sent_over_rsi(const samples::RobotCorrection& correction) noexcept {
  samples::RobotCorrection sent = correction;
  constexpr double kDeg = std::numbers::pi / 180.0;
  const double scale = std::pow(10.0, samples::kRsiCorrectionDecimals);
  auto digits = [scale](double v, double unit) {
    return std::round(v / unit * scale) / scale * unit;
  };
  for (double& v : sent.translation_m) v = digits(v, 1e-3);
  for (double& v : sent.axes_rad) v = digits(v, kDeg);
  Eigen::Matrix3d R;
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) R(r, k) = sent.R_correction[static_cast<std::size_t>(3 * r + k)];
  Eigen::Vector3d abc = model::kuka_abc_from_rotation(R);
  for (int k = 0; k < 3; ++k) abc[k] = digits(abc[k], kDeg);
  R = model::rotation_from_kuka_abc(abc[0], abc[1], abc[2]);
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) sent.R_correction[static_cast<std::size_t>(3 * r + k)] = R(r, k);
  return sent;
}

void MotionEstimator::note_command(const samples::RobotCorrection& correction,
                                   std::span<const double> joints_rad, double t_row_s,
                                   double cycle_s) noexcept {
  if (!(config_.servo_hz > 0.0) || !have_robot_ || !(cycle_s > 0.0)) return;
  // As the robot receives it (RSI's digits), not as the cycle computed it.
  const samples::RobotCorrection sent = as_sent_over_rsi(correction);
  Eigen::Matrix<double, robot::kMaxJoints, 1> dq;
  // From the measured joints, first order: from the controller's set point, tracked with
  // exact inverse kinematics (as `zerog servo` reconstructs it), the elastic glide and spin
  // were the same (seeds 11-15, the joints' load then at 3 Hz: glide 2.15-3.03x force, spin
  // 1.42-1.64x torque).
  commanded_increment(robot_, sent, joints_rad, dq);
  servo_.advance(std::span<const double>(dq.data(), robot::kMaxJoints), robot_.joint_count, t_row_s,
                 cycle_s);
}

bool MotionEstimator::update(std::span<const model::FeatureSignals* const> rows,
                             const std::array<double, 6>& wrench,
                             const model::ImuSignals<double>& imu_at_c, const WindowCounts& counts,
                             MotionEstimate& out) noexcept {
  const std::size_t n = rows.size();
  if (n < 3 || n % 2 == 0) return false;
  const std::size_t c = n / 2;
  const model::FeatureSignals& centre = *rows[c];
  const double t_c = centre.t_s;
  const double half_span = std::max(rows[n - 1]->t_s - t_c, t_c - rows[0]->t_s);
  if (!(half_span > 0.0)) return false;
  if (started_ && !(t_c > t_s_)) return false;

  // 1. The motor side's motion at c: a quadratic fit over the rows.
  MotorMotion motor;
  if (!fit_motor_side(rows, motor)) return false;
  // The instants the centre row's means stand for (header, "Instants").
  const double row_dt = t_c - rows[c - 1]->t_s;
  auto instant = [row_dt](int n_samples, double rate_hz, double delay_s) {
    if (n_samples > 0 && rate_hz > 0.0)
      return -0.5 * static_cast<double>(n_samples - 1) / rate_hz - delay_s;
    return -0.5 * row_dt - delay_s;
  };
  const double t_ft = instant(counts.ft, config_.ft_rate_hz, config_.ft_delay_s);
  const double t_imu = instant(counts.imu, config_.imu_rate_hz, config_.imu_delay_s);
  LinkMotion link{.R_ft = motor.attitude_at(t_ft),
                  .R_imu = motor.attitude_at(t_imu),
                  .omega_ft = motor.rate_at(t_ft),
                  .omega_imu = motor.rate_at(t_imu),
                  .omega_dot_B = motor.R_c * motor.r2,
                  .a_B = motor.a_B};
  const Eigen::Vector3d omega_B_imu_motor = link.omega_imu;  // step 4's reference

  const bool ringing_on =
      config_.ringing_radps > 0.0 && !config_.mutant_without_ringing && !config_.mutant_without_imu;
  const double dt = started_ ? t_c - t_s_ : 0.0;
  since_excitation_s_ = excited_ ? 0.0 : since_excitation_s_ + dt;
  const bool after_excitation = since_excitation_s_ <= config_.ringing_hold_s;
  const double threshold = 3.0 * config_.ringing_radps;
  const double schedule = ringing_on && after_excitation
                              ? residual_ms_ / (residual_ms_ + threshold * threshold)
                              : 0.0;  // last row's
  // 2. The link's deflection at c (and 4a).
  // The servo model's acceleration at c: the entry of the row two before c
  // (ServoModel::accel_at), which is the centre before the last one when the rows come one by
  // one.
  std::array<double, robot::kMaxJoints> servo_qdd{};
  const bool consecutive = started_ && rows[c - 1]->t_s == t_s_;
  out.servo_followed =
      servo_.accel_at(consecutive ? t_before_s_ : -2.0, centre.joints_rad,
                      have_robot_ ? std::min(robot_.joint_count, 6) : 0, dt, servo_qdd);
  out.servo_accel_radps2 = servo_qdd;
  if (elastic_) deflect(motor, centre, wrench, imu_at_c, dt, schedule, servo_qdd, link, out);

  // The robot's signals at the IMU, I axes, at the F/T's instant (the output) and at the IMU's
  // (the comparison of step 3).
  Eigen::Vector3d f_I, omega_I, f_I_cmp, omega_I_cmp;
  at_imu(R_sensor_imu_, p_sensor_imu_m_, config_.gravity_base_mps2, link.R_ft, link.omega_ft,
         link.omega_dot_B, link.a_B, f_I, omega_I);
  at_imu(R_sensor_imu_, p_sensor_imu_m_, config_.gravity_base_mps2, link.R_imu, link.omega_imu,
         link.omega_dot_B, link.a_B, f_I_cmp, omega_I_cmp);
  const Eigen::Vector3d omega_dot_I =
      R_sensor_imu_.transpose() * link.R_ft.transpose() * link.omega_dot_B;

  // 4. How much the gyro disagrees with the rigid robot (the next row's schedule).
  if (ringing_on && started_) {
    const Eigen::Vector3d e =
        imu_at_c.angular_rate_imu - offset_w_ -
        R_sensor_imu_.transpose() * link.R_imu.transpose() * omega_B_imu_motor;
    residual_ms_ +=
        (1.0 - std::exp(-dt / kRingingWindow_s)) * (e.squaredNorm() / 3.0 - residual_ms_);
  }

  // 3. The IMU below the crossover.
  track_offsets(imu_at_c, f_I_cmp, omega_I_cmp, link.R_imu, dt);
  const Eigen::Vector3d offset_f =
      offsets_.bias_I() + R_sensor_imu_.transpose() * link.R_ft.transpose() * offsets_.error_B();
  t_before_s_ = started_ ? t_s_ : -1.0;
  started_ = true;
  t_s_ = t_c;

  out.ft_instant_s = t_ft;
  out.imu_instant_s = t_imu;
  out.specific_force_robot_imu = f_I;
  out.angular_rate_robot_imu = omega_I;
  out.specific_force_offset = offset_f;
  out.specific_force_bias_imu = offsets_.bias_I();
  out.specific_force_error_base = offsets_.error_B();
  out.angular_rate_offset = offset_w_;
  // Without the IMU (the test mutant) there is no share to settle.
  out.settled = config_.mutant_without_imu || config_.mutant_settled_at_once || offsets_.settled();
  out.imu.specific_force_imu = f_I + offset_f;
  out.imu.angular_rate_imu = omega_I + offset_w_;
  out.imu.angular_accel_imu = omega_dot_I;
  // 4b. Toward the IMU as it comes while the arm rings.
  out.ringing = schedule;
  out.imu.specific_force_imu +=
      schedule * (imu_at_c.specific_force_imu - out.imu.specific_force_imu);
  out.imu.angular_rate_imu += schedule * (imu_at_c.angular_rate_imu - out.imu.angular_rate_imu);
  out.imu.angular_accel_imu += schedule * (imu_at_c.angular_accel_imu - out.imu.angular_accel_imu);
  return true;
}

}  // namespace zerog::loop
