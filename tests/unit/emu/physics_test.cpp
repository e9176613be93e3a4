// The emulator's payload physics (host/emu physics.hpp over host/sim RigSimulator::measure): the
// push's sign and lever, contact = measured − predicted with zerog::model, measure() on a
// trajectory is wrench_at/imu_at, push profiles and impulses, the IMU time offset from the joint
// history, and the F/T noise.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "zerog/emu/physics.hpp"
#include "zerog/emu/robot.hpp"
#include "zerog/model/predict.hpp"

namespace zerog::emu {
namespace {

using Vec6 = Eigen::Matrix<double, 6, 1>;

sim::SimConfig quiet(sim::SimEffectSet effects = sim::kDefaultSimEffects) {
  sim::SimConfig c = sim::default_sim_config(7);
  c.effects = effects;
  c.noise = sim::NoiseConfig::none();
  return c;
}

sim::JointState static_state(const sim::JointVector& q) {
  sim::JointState js;
  js.q_rad = q;
  return js;
}

TEST(Physics, PushReachesTheSensorThroughThePayload) {
  const sim::RigSimulator simulator(quiet());
  const sim::JointState js = static_state({0.2, -1.3, 1.7, 0.4, 0.9, -0.6});
  const sim::ExternalWrench push{Eigen::Vector3d(30.0, -12.0, 45.0),
                                 Eigen::Vector3d(0.1, 0.25, 0.4), Eigen::Vector3d(-2.0, 1.5, 3.0)};
  const sim::Measurement without = simulator.measure(js, 3.0);
  const sim::Measurement with = simulator.measure(js, 3.0, {&push, 1});
  const Eigen::Matrix3d R_BS = with.R_base_sensor;
  const Eigen::Vector3d F_S = R_BS.transpose() * push.force_base_N;
  Vec6 expected;
  expected << F_S, push.point_sensor_m.cross(F_S) + R_BS.transpose() * push.torque_base_Nm;
  EXPECT_LT((with.wrench_sensor - without.wrench_sensor - expected).norm(), 1e-9);
  // Sign: pushing the payload up (+z in B) unloads a sensor that holds it against gravity.
  const sim::JointState down =
      static_state({0.0, -1.5707963267948966, 1.5707963267948966, 0.0, 1.5707963267948966, 0.0});
  const sim::ExternalWrench up{Eigen::Vector3d(0.0, 0.0, 100.0), Eigen::Vector3d::Zero(),
                               Eigen::Vector3d::Zero()};
  const sim::Measurement w0 = simulator.measure(down, 0.0);
  const sim::Measurement w1 = simulator.measure(down, 0.0, {&up, 1});
  const Eigen::Vector3d gravity_S =
      w0.R_base_sensor.transpose() * Eigen::Vector3d(0.0, 0.0, -model::kStandardGravity);
  EXPECT_LT(gravity_S.dot(w1.wrench_sensor.head<3>() - w0.wrench_sensor.head<3>()), 0.0);
}

TEST(Physics, ContactIsMeasuredMinusPredicted) {
  // What zerog-rt computes: the model with the truth parameters predicts the payload alone; the
  // rest of the reading is the push, in S, torque about the S origin. A moving robot, too.
  const sim::SimEffectSet effects = {model::Effect::rotational_inertia, model::Effect::cable,
                                     model::Effect::bias_drift, model::Effect::temperature_bias};
  const std::vector<Push> pushes = {
      {0.0, 1.0, Eigen::Vector3d(20.0, 35.0, -10.0), Eigen::Vector3d(1.0, -2.0, 0.5),
       Eigen::Vector3d(0.2, 0.1, 0.3), PushProfile::constant},
      {0.0, 1.0, Eigen::Vector3d(-5.0, 0.0, 15.0), Eigen::Vector3d::Zero(), std::nullopt,
       PushProfile::constant}};
  const PayloadPhysics physics(quiet(effects), pushes, 2000.0);
  const io::ModelFile truth = physics.simulator().truth();
  const formats::Rig rig = physics.simulator().rig();
  model::RigGeometry geometry;
  geometry.R_sensor_imu = rig.sensor_imu.q.toRotationMatrix();
  geometry.p_sensor_imu_m = rig.sensor_imu.p_m;

  sim::JointState js = static_state({0.3, -1.1, 1.6, -0.5, 0.8, 0.7});
  js.qd_radps = {0.2, -0.1, 0.3, 0.4, -0.5, 0.6};
  js.qdd_radps2 = {-0.3, 0.2, 0.1, -0.6, 0.4, 0.5};
  const double t = 0.4;
  const PhysicsSample s = physics.evaluate(js, js, t);

  model::PoseSignals pose;
  pose.R_base_sensor = s.truth.flange.R_base_flange;  // nominal S: the flange's axes
  pose.t_rel_s = t;
  pose.temperature_C = physics.simulator().config().temperature.at(t);
  pose.joints_rad = js.q_rad;
  model::ImuSignals<double> imu;
  imu.specific_force_imu = s.truth.imu.specific_force_imu_mps2;
  imu.angular_rate_imu = s.truth.imu.angular_rate_imu_radps;
  imu.angular_accel_imu = s.truth.imu.angular_accel_imu_radps2;
  const Vec6 predicted = model::predict_wrench(truth.params.effects, model::pointers(truth.params),
                                               pose, imu, geometry);
  const Vec6 contact = s.truth.wrench_sensor - predicted;

  const Eigen::Matrix3d R_SB = s.truth.R_base_sensor.transpose();
  const Eigen::Vector3d com = physics.simulator().config().payload.com_sensor_m;
  Vec6 expected = Vec6::Zero();
  for (const Push& p : pushes) {
    const Eigen::Vector3d F_S = R_SB * p.force_world_N;
    expected.head<3>() += F_S;
    expected.tail<3>() += p.point_sensor_m.value_or(com).cross(F_S) + R_SB * p.torque_world_Nm;
  }
  EXPECT_LT((contact - expected).norm(), 1e-8) << contact.transpose() << "\n"
                                               << expected.transpose();
  // And the sample's own account of the push (B; torque about the centre of mass).
  EXPECT_LT((s.push_force_base_N - Eigen::Vector3d(15.0, 35.0, 5.0)).norm(), 1e-12);
  const Eigen::Vector3d lever = s.truth.R_base_sensor * (Eigen::Vector3d(0.2, 0.1, 0.3) - com);
  const Eigen::Vector3d torque_com =
      lever.cross(pushes[0].force_world_N) + pushes[0].torque_world_Nm;
  EXPECT_LT((s.push_torque_com_base_Nm - torque_com).norm(), 1e-12);
}

TEST(Physics, MeasureOnTheTrajectoryIsWrenchAtAndImuAt) {
  sim::SimConfig c = quiet(sim::parse_sim_effects("all", {}));
  sim::DesignOptions design;
  design.kind = sim::DesignKind::random;
  design.points = 2;
  design.seed = 5;
  const std::vector<sim::JointVector> path = sim::make_design(design).points_rad;
  const sim::RigSimulator simulator(c, path);
  const double tau = simulator.imu_delay_s();
  EXPECT_GT(tau, 0.0);
  ASSERT_GT(simulator.trajectory().duration_s(), 5.0);
  for (double t : {0.0, 1.0, 2.7, 3.3, 4.1}) {
    const sim::Measurement m =
        simulator.measure(simulator.trajectory().at(t), simulator.trajectory().at(t - tau), t);
    EXPECT_EQ(m.wrench_sensor, simulator.wrench_at(t)) << t;
    const sim::ImuTruth imu = simulator.imu_at(t);
    EXPECT_EQ(m.imu.specific_force_imu_mps2, imu.specific_force_imu_mps2) << t;
    EXPECT_EQ(m.imu.angular_rate_imu_radps, imu.angular_rate_imu_radps) << t;
    EXPECT_EQ(m.imu.angular_accel_imu_radps2, imu.angular_accel_imu_radps2) << t;
  }
}

TEST(Physics, PushProfilesAndImpulses) {
  Push half;
  half.start_s = 0.5;
  half.duration_s = 0.2;
  half.force_world_N = {0.0, 40.0, 0.0};
  half.torque_world_Nm = {0.0, 0.0, 3.0};
  EXPECT_EQ(half.factor(0.49), 0.0);
  EXPECT_NEAR(half.factor(0.6), 1.0, 1e-12);
  EXPECT_EQ(half.factor(0.7000001), 0.0);
  EXPECT_NEAR(half.impulse_N_s().y(), 40.0 * 0.2 * 2.0 / std::numbers::pi, 1e-12);
  EXPECT_NEAR(half.torque_impulse_Nms().z(), 3.0 * 0.2 * 2.0 / std::numbers::pi, 1e-12);
  Push constant = half;
  constant.profile = PushProfile::constant;
  constant.start_s = 1.0;
  constant.point_sensor_m = Eigen::Vector3d(0.3, 0.0, 0.25);  // off the centre of mass
  EXPECT_EQ(constant.factor(1.1), 1.0);
  EXPECT_NEAR(constant.impulse_N_s().y(), 8.0, 1e-12);

  // Stepped by the physics, the integrals match (rectangle rule at 2 kHz).
  PayloadPhysics physics(quiet(), {half, constant}, 2000.0);
  const sim::JointState js = static_state(default_start_joints());
  PhysicsSample last;
  for (int k = 0; k < 2600; ++k) last = physics.step(js);
  EXPECT_EQ(physics.steps(), 2600u);
  const std::vector<PushIntegral>& in = physics.push_integrals();
  EXPECT_LT((in[0].impulse_N_s - half.impulse_N_s()).norm(), 1e-3 * half.impulse_N_s().norm());
  // At the centre of mass only the pure torque turns the payload.
  EXPECT_LT((in[0].angular_impulse_com_Nms - half.torque_impulse_Nms()).norm(), 1e-3);
  EXPECT_LT((in[1].impulse_N_s - constant.impulse_N_s()).norm(), 1e-9);
  // Off the centre of mass the lever adds r × J (the robot stands still: r is constant).
  const Eigen::Vector3d r =
      last.truth.R_base_sensor *
      (*constant.point_sensor_m - physics.simulator().config().payload.com_sensor_m);
  EXPECT_LT((in[1].angular_impulse_com_Nms -
             (r.cross(constant.impulse_N_s()) + constant.torque_impulse_Nms()))
                .norm(),
            1e-9);
  Push instant;
  instant.duration_s = 0.0;
  EXPECT_THROW(PayloadPhysics(quiet(), {instant}, 2000.0), std::invalid_argument);
}

TEST(Physics, ImuReportsTheMotionOfTauEarlier) {
  sim::SimConfig c = quiet({model::Effect::rotational_inertia, model::Effect::imu_time_offset});
  PayloadPhysics physics(c, {}, 2000.0);
  const int delay = static_cast<int>(std::lround(physics.simulator().imu_delay_s() * 2000.0));
  EXPECT_EQ(delay, 16);  // 8 ms
  RobotEmulator robot;
  robot.apply_akorr({5.0, -3.0, 4.0, 10.0, -8.0, 12.0});
  std::vector<sim::JointState> states;
  for (int k = 0; k < 200; ++k) {
    if (k > 0) robot.step();
    states.push_back(robot.actual());
    const PhysicsSample s = physics.step(robot.actual());
    const sim::JointState& earlier = states[static_cast<std::size_t>(std::max(0, k - delay))];
    const sim::Measurement m = physics.simulator().measure(robot.actual(), earlier, k / 2000.0);
    EXPECT_EQ(s.truth.imu.angular_rate_imu_radps, m.imu.angular_rate_imu_radps) << k;
    EXPECT_EQ(s.truth.wrench_sensor, m.wrench_sensor) << k;
  }
  // The delay is visible: the IMU lags the robot.
  const PhysicsSample now = physics.evaluate(states.back(), states.back(), 0.1);
  const PhysicsSample lagged = physics.step(robot.actual());
  EXPECT_GT((now.truth.imu.angular_rate_imu_radps - lagged.truth.imu.angular_rate_imu_radps).norm(),
            1e-3);
}

// The robot that is not rigid in the emulator (proto/sim_robot.md): with SimConfig::elastic on,
// the payload sits on the link side. At rest it sags by the weight's τ/k (the wrench is the
// rigid one at the sagged joints, not at the servo's); after the servo moves, the link rings on
// and the IMU sees it while the servo's joints stand still.
TEST(Physics, TheElasticArmSagsAndRingsUnderTheServo) {
  sim::SimConfig c = quiet();
  c.elastic = sim::kr210_elasticity();
  PayloadPhysics elastic(c, {}, 2000.0);
  PayloadPhysics rigid(quiet(), {}, 2000.0);
  RobotEmulator robot;
  const sim::JointState rest = robot.actual();
  const PhysicsSample sagged = elastic.step(rest);
  const sim::JointVector tau =
      sim::weight_load(rest.q_rad, rigid.step(rest).truth.R_base_sensor, c.p_flange_sensor_m,
                       c.payload.com_sensor_m, c.payload.mass_kg);
  sim::JointState expected = rest;
  for (std::size_t i = 0; i < 6; ++i)
    expected.q_rad[i] += tau[i] / c.elastic.joints[i].stiffness_Nm_per_rad;
  // τ/k at the sagged pose (the load changes with the sag: within a tenth of a percent).
  const sim::Measurement at_sag = rigid.simulator().measure(expected, 0.0);
  EXPECT_LT((sagged.truth.wrench_sensor - at_sag.wrench_sensor).norm(), 0.05);
  EXPECT_GT((sagged.truth.wrench_sensor - rigid.evaluate(rest, rest, 0.0).truth.wrench_sensor)
                .head<3>()
                .norm(),
            0.05);
  // A correction moves the servo; once it stands still again, the link still rings.
  robot.apply_akorr({0.0, 2.0, 0.0, 0.0, 0.0, 0.0});
  for (int k = 0; k < 4000; ++k) {
    robot.step();
    elastic.step(robot.actual());
  }
  // What the gyro sees beyond the servo's own (settling) motion: the link's ringing.
  double ringing = 0.0;
  for (int k = 0; k < 200; ++k) {
    robot.step();
    const sim::JointState& a = robot.actual();
    ringing = std::max(ringing, (elastic.step(a).truth.imu.angular_rate_imu_radps -
                                 rigid.evaluate(a, a, 0.0).truth.imu.angular_rate_imu_radps)
                                    .norm());
  }
  EXPECT_GT(ringing, 1e-6);  // rad/s
  EXPECT_LT(ringing, 1e-1);
}

// A person's push loads the elastic arm as the payload's weight does (sim::payload_load): held,
// the link settles at (τ_weight + τ_push)/k, and the sensor with it. Without the push in the load
// (the emulator before 2026-11-30) the sensor stays at the weight's sag, a tenth of a millimetre
// from there for this 150 N push.
TEST(Physics, APushLoadsTheElasticArmAsTheWeightDoes) {
  sim::SimConfig c = quiet();
  c.elastic = sim::kr210_elasticity();
  Push push;
  push.start_s = 0.1;
  push.duration_s = 5.0;
  push.profile = PushProfile::constant;
  push.force_world_N = Eigen::Vector3d(60.0, 120.0, -60.0);
  push.torque_world_Nm = Eigen::Vector3d(0.0, 0.0, 15.0);
  push.point_sensor_m = Eigen::Vector3d(0.2, 0.0, 0.3);
  PayloadPhysics pushed(c, {push}, 2000.0);
  PayloadPhysics still(c, {}, 2000.0);
  const sim::JointState rest = RobotEmulator().actual();
  PhysicsSample a, b;
  for (int k = 0; k <= 8000; ++k) {  // 4 s: 3.9 s into the push, the ringing damped (ζ 0.05)
    a = pushed.step(rest);
    b = still.step(rest);
  }
  // The static deflection under weight and push, at the deflected pose (two fixed-point passes).
  sim::JointState link = rest;
  for (int pass = 0; pass < 3; ++pass) {
    const sim::Measurement m = still.simulator().measure(link, link, 4.0);
    const sim::ExternalWrench w{push.force_world_N, *push.point_sensor_m, push.torque_world_Nm};
    const sim::JointVector tau = sim::payload_load(link.q_rad, m.R_base_sensor, c, {&w, 1});
    for (std::size_t i = 0; i < 6; ++i)
      link.q_rad[i] = rest.q_rad[i] + tau[i] / c.elastic.joints[i].stiffness_Nm_per_rad;
  }
  const Eigen::Vector3d expected = still.simulator().measure(link, link, 4.0).p_base_sensor_m;
  const double moved = (expected - b.truth.p_base_sensor_m).norm();  // the push's share
  EXPECT_GT(moved, 5e-5);                                            // m
  EXPECT_LT((a.truth.p_base_sensor_m - expected).norm(), 0.05 * moved);
}

TEST(Physics, FtNoiseHasTheConfiguredSigma) {
  sim::SimConfig c = quiet();
  c.noise.force_N = 0.25;
  c.noise.torque_Nm = 0.03;
  PayloadPhysics physics(c, {}, 2000.0);
  const sim::JointState js = static_state(default_start_joints());
  double sf = 0.0, st = 0.0;
  const int n = 4000;
  for (int k = 0; k < n; ++k) {
    const PhysicsSample s = physics.step(js);
    for (int i = 0; i < 3; ++i) {
      const double ef = s.wrench_sensor_noisy[i] - s.truth.wrench_sensor[i];
      const double et = s.wrench_sensor_noisy[3 + i] - s.truth.wrench_sensor[3 + i];
      sf += ef * ef;
      st += et * et;
    }
  }
  EXPECT_NEAR(std::sqrt(sf / (3 * n)), 0.25, 0.025);
  EXPECT_NEAR(std::sqrt(st / (3 * n)), 0.03, 0.003);
}

}  // namespace
}  // namespace zerog::emu
