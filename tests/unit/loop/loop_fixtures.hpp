#pragma once
// Shared by the zerog::loop and zerog::rt tests (and rtio_bench): a payload model, the cycle
// configuration of the same virtual body, and a robot standing still whose F/T samples are the
// model's payload wrench plus a contact the test chooses. Needs zerog::loop and zerog::proto
// (zerog::rt's additions are in tests/unit/rt/rt_fixtures.hpp). Test code; header-only.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <array>

#include "zerog/infer/inference.hpp"
#include "zerog/loop/cycle.hpp"
#include "zerog/model/rotation.hpp"
#include "zerog/proto/rsi.hpp"
#include "zerog/samples/sensor_samples.hpp"

// By path: some tests that include the fixtures get zerog::proto from zerog::rt and do not link
// zerog_test_rsi_step (rt, rtio_bench, the soak).
#include "../../common/rsi_step.hpp"

namespace zerog::loop::test {

inline constexpr double kMass = 100.0;
inline constexpr double kPeriod = 0.012;

/// The rig the loop tests' model is fitted for (no poses: the sensor and the IMU at the flange).
inline infer::RigDescription test_rig_description() {
  infer::RigDescription rig;
  rig.name = "test-rig";
  rig.robot = "KR 210 R2700";
  rig.sample_period_s = kPeriod;
  return rig;
}

/// Bias, 100 kg payload (centre of mass off the sensor axis), rotational inertia.
inline infer::DeployedModel payload_model(
    const infer::RigDescription& rig = test_rig_description()) {
  infer::DeployedModel m;
  m.rig = rig;
  m.physics.effects = model::kDefaultModel;
  double* bias = m.physics.block(model::Effect::bias);
  const double b[6] = {12.0, -7.0, 30.0, 1.5, -0.5, 0.25};
  for (int k = 0; k < 6; ++k) bias[k] = b[k];
  double* g = m.physics.block(model::Effect::gravity);
  g[0] = kMass;
  g[1] = 0.03;
  g[2] = -0.02;
  g[3] = 0.25;
  double* I = m.physics.block(model::Effect::rotational_inertia);
  I[0] = 4.0;
  I[1] = 5.0;
  I[2] = 6.0;
  return m;
}

/// The virtual body of the payload model (mass, inertia, centre of mass), at the 12 ms cycle.
inline CycleConfig test_cycle_config() {
  CycleConfig c;
  c.period_s = kPeriod;
  c.body.mass_kg = kMass;
  c.body.inertia_body_kgm2 = Eigen::Vector3d(4.0, 5.0, 6.0).asDiagonal();
  c.p_sensor_com_m = Eigen::Vector3d(0.03, -0.02, 0.25);
  return c;
}

/// A robot standing still at one pose; F/T samples are the payload's wrench (as the model
/// predicts it, so the contact is exactly what the test adds) plus a contact wrench the test
/// chooses, IMU samples measure gravity only.
class StaticRobot {
 public:
  explicit StaticRobot(const infer::DeployedModel& model = payload_model()) {
    EXPECT_EQ(truth_.configure(model).text(), "");
    message.actual_pose = {1500.0, 200.0, 1200.0, 10.0, 20.0, -30.0};
    message.joints_deg = {5.0, -80.0, 95.0, 10.0, 40.0, -20.0};
    message.has_delay = true;
    message.ipoc = 1'000'000;
    const proto::rsi::PoseSi pose = proto::rsi::to_si(message.actual_pose);
    R = model::rotation_from_kuka_abc(pose.abc_rad[0], pose.abc_rad[1], pose.abc_rad[2]);
    model::FeatureSignals s;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) s.R_base_sensor[3 * r + c] = R(r, c);
    }
    const Eigen::Vector3d f_imu = R.transpose() * Eigen::Vector3d(0, 0, model::kStandardGravity);
    for (int k = 0; k < 3; ++k) s.imu[k] = f_imu[k];
    infer::Wrench w;
    EXPECT_TRUE(truth_.evaluate_physics(s, w).written());
    for (int k = 0; k < 6; ++k) payload[k] = w[k];
    imu_sample.rate_valid = imu_sample.accel_valid = true;
    for (int k = 0; k < 3; ++k) imu_sample.accel_m_s2[k] = f_imu[k];
  }

  /// An F/T sample: payload + `contact` (sensor frame; torque about the sensor origin).
  samples::FtSample ft(const Eigen::Matrix<double, 6, 1>& contact) const {
    samples::FtSample s;
    s.valid = true;
    for (int k = 0; k < 6; ++k) s.wrench_si[k] = payload[k] + contact[k];
    return s;
  }

  /// Feeds `n_ft` F/T samples (payload + contact) and `n_imu` IMU samples to `c`, then one
  /// robot message (the next IPOC after it); returns the reply.
  zerog::test::RsiReply cycle(Cycle& c, const Eigen::Matrix<double, 6, 1>& contact, int n_ft = 4,
                              int n_imu = 24) {
    const samples::FtSample sample = ft(contact);
    for (int i = 0; i < n_ft; ++i) c.add_ft(sample);
    for (int i = 0; i < n_imu; ++i) c.add_imu(imu_sample);
    zerog::test::RsiReply reply;
    zerog::test::step_rsi(c, message, reply);
    message.ipoc += 12;
    return reply;
  }
  /// The same with no contact.
  zerog::test::RsiReply quiet(Cycle& c, int n_ft = 4, int n_imu = 24) {
    return cycle(c, Eigen::Matrix<double, 6, 1>::Zero(), n_ft, n_imu);
  }

  proto::rsi::RobotMessage message;
  Eigen::Matrix3d R;  ///< R_base_sensor of the pose
  std::array<double, 6> payload{};
  samples::ImuSample imu_sample;

 private:
  infer::Inference truth_;
};

/// A push through the virtual centre of mass (sensor frame; torque about the sensor origin).
inline Eigen::Matrix<double, 6, 1> push(double fx, double fy, double fz) {
  const Eigen::Vector3d F(fx, fy, fz);
  Eigen::Matrix<double, 6, 1> w;
  w << F, test_cycle_config().p_sensor_com_m.cross(F);
  return w;
}

/// Six quiet cycles, then zero-g enabled and one more: the cycle is in zero-g (asserted).
inline void start_zero_g(Cycle& c, StaticRobot& rig) {
  for (int i = 0; i < 6; ++i) rig.quiet(c);
  ASSERT_TRUE(c.request(Command::enable_zero_g));
  rig.quiet(c);
  ASSERT_EQ(c.state_machine().state(), State::zero_g);
}

}  // namespace zerog::loop::test
