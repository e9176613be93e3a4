// The pure parts of zerog::telemetry: record → IDL samples (units, frames, codes, reuse of
// control::VirtualBody for ω and the energy), the model identity, the configuration check and
// the Cyclone XML built from it.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "zerog/proto/rsi.hpp"
#include "zerog/proto/rsi_si.hpp"
#include "zerog/telemetry/config.hpp"
#include "zerog/telemetry/convert.hpp"
#include "zerog/telemetry/ros2.hpp"

namespace zerog::telemetry {
namespace {

loop::CycleRecord sample_record() {
  loop::CycleRecord r;
  r.cycle = 42;
  r.ipoc = 123456;
  r.t_s = 0.164;
  r.dt_s = 0.004;
  r.state = loop::State::zero_g;
  r.fault = loop::Fault::none;
  r.flags = loop::kIpocGap | loop::kRobotDelayGrew;
  r.limit_flags = control::kSpeedLimited;
  r.model_status = infer::StatusCode::saturated;
  for (int i = 0; i < 6; ++i) {
    r.joints_rad[i] = 0.1 * i;
    r.wrench_measured[i] = 1.0 + i;
    r.wrench_at_eval[i] = 2.0 + i;
    r.predicted[i] = 1.5 + i;
    r.contact[i] = 0.5;
  }
  r.p_base_sensor_m = {1.0, 2.0, 3.0};
  r.q_base_sensor = Eigen::Quaterniond(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitY()));
  r.specific_force_imu = {0.1, 0.2, 9.8};
  r.rate_imu = {0.01, 0.02, 0.03};
  r.ft_samples = 2;
  r.imu_samples = 9;
  r.t_eval_s = 0.156;
  // The reply in SI, made from an RKorr of 1, −2, 0.5 mm and 0.1, −0.2, 0.3 degrees.
  proto::rsi::Reply rkorr;
  rkorr.ipoc = r.ipoc;
  rkorr.has_rkorr = true;
  rkorr.rkorr = {1.0, -2.0, 0.5, 0.1, -0.2, 0.3};
  r.reply = proto::rsi::correction_from_reply(rkorr);
  r.body.p_world_m = {0.5, 0.6, 0.7};
  r.body.q_world_body = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()));
  r.body.v_world_mps = {0.1, -0.2, 0.05};
  r.body.L_world_kgm2ps = {0.3, 0.1, -0.2};
  r.compute_ns = 25'000;
  return r;
}

control::BodyParams sample_body() {
  control::BodyParams b;
  b.mass_kg = 80.0;
  b.inertia_body_kgm2 = Eigen::Vector3d(4.0, 5.0, 6.0).asDiagonal();
  return b;
}

TEST(TelemetryConvert, WrenchCarriesEveryWrenchOfTheRecord) {
  const loop::CycleRecord r = sample_record();
  const WrenchSample s = to_wrench(r);
  EXPECT_EQ(s.cycle, 42u);
  EXPECT_DOUBLE_EQ(s.t_s, 0.164);
  EXPECT_DOUBLE_EQ(s.t_eval_s, 0.156);
  for (int i = 0; i < 6; ++i) {
    EXPECT_EQ(s.measured[i], r.wrench_measured[i]);
    EXPECT_EQ(s.measured_at_eval[i], r.wrench_at_eval[i]);
    EXPECT_EQ(s.predicted[i], r.predicted[i]);
    EXPECT_EQ(s.contact[i], r.contact[i]);
  }
  EXPECT_EQ(s.ft_samples, 2);
  EXPECT_EQ(s.model_status, 1);  // saturated
  EXPECT_EQ(s.flags, r.flags);
}

TEST(TelemetryConvert, ImuAndRobotKeepFramesAndQuaternionOrder) {
  const loop::CycleRecord r = sample_record();
  const ImuSample imu = to_imu(r);
  EXPECT_EQ(imu.specific_force_imu_mps2[2], 9.8);
  EXPECT_EQ(imu.rate_imu_radps[1], 0.02);
  EXPECT_EQ(imu.imu_samples, 9);
  const RobotSample robot = to_robot(r);
  EXPECT_EQ(robot.ipoc, 123456u);
  EXPECT_EQ(robot.joints_rad[5], 0.5);
  EXPECT_EQ(robot.p_base_sensor_m[2], 3.0);
  EXPECT_EQ(robot.q_base_sensor_wxyz[0], r.q_base_sensor.w());
  EXPECT_EQ(robot.q_base_sensor_wxyz[2], r.q_base_sensor.y());
  EXPECT_NEAR(robot.q_base_sensor_wxyz[2], std::sin(0.25), 1e-15);
}

TEST(TelemetryConvert, CommandIsInSiAndTheTwistComesFromTheVirtualBody) {
  const loop::CycleRecord r = sample_record();
  const control::BodyParams body = sample_body();
  const CommandSample s = to_command(r, body);
  EXPECT_NEAR(s.rkorr_translation_m[0], 1.0e-3, 1e-18);
  EXPECT_NEAR(s.rkorr_translation_m[1], -2.0e-3, 1e-18);
  EXPECT_NEAR(s.rkorr_abc_rad[0], 0.1 * M_PI / 180.0, 1e-15);
  EXPECT_NEAR(s.rkorr_abc_rad[1], -0.2 * M_PI / 180.0, 1e-15);
  EXPECT_NEAR(s.rkorr_abc_rad[2], 0.3 * M_PI / 180.0, 1e-15);
  EXPECT_EQ(s.akorr_rad[5], 0.0);  // an RKorr reply: no AKorr
  EXPECT_FALSE(s.axis_reply);
  // An AKorr reply: axes in rad as the cycle made them, no RKorr.
  loop::CycleRecord axes = r;
  axes.reply = {};
  axes.reply.kind = samples::RobotCorrection::Kind::axes;
  for (int i = 0; i < 6; ++i) axes.reply.axes_rad[i] = 1e-4 * (i + 1);
  const CommandSample a = to_command(axes, body);
  EXPECT_TRUE(a.axis_reply);
  EXPECT_EQ(a.akorr_rad[5], axes.reply.axes_rad[5]);
  EXPECT_EQ(a.rkorr_translation_m[0], 0.0);
  EXPECT_EQ(a.rkorr_abc_rad[1], 0.0);
  EXPECT_EQ(s.limit_flags, static_cast<std::uint32_t>(control::kSpeedLimited));
  const control::VirtualBody vb(body, r.body);
  const Eigen::Vector3d w = vb.omega_world();
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(s.omega_world_radps[i], w[i]);
    EXPECT_EQ(s.v_world_mps[i], r.body.v_world_mps[i]);
  }
  // Independent check of ω: L = R I Rᵀ ω in the world frame.
  const Eigen::Matrix3d R = r.body.q_world_body.toRotationMatrix();
  const Eigen::Vector3d L =
      R * body.inertia_body_kgm2 * R.transpose() *
      Eigen::Vector3d(s.omega_world_radps[0], s.omega_world_radps[1], s.omega_world_radps[2]);
  EXPECT_NEAR((L - r.body.L_world_kgm2ps).norm(), 0.0, 1e-12);
}

TEST(TelemetryConvert, BodyHasMomentumAndKineticEnergy) {
  const loop::CycleRecord r = sample_record();
  const control::BodyParams body = sample_body();
  const BodySample s = to_body(r, body);
  EXPECT_EQ(s.mass_kg, 80.0);
  EXPECT_NEAR(s.momentum_world_kgmps[1], 80.0 * -0.2, 1e-12);
  EXPECT_EQ(s.L_world_kgm2ps[0], 0.3);
  EXPECT_EQ(s.q_world_body_wxyz[1], r.body.q_world_body.x());
  const control::VirtualBody vb(body, r.body);
  EXPECT_EQ(s.kinetic_energy_J, vb.kinetic_energy_J());
  // ½ m v² + ½ ω·L, computed here from the sample alone.
  double linear = 0.0, rotational = 0.0;
  for (int i = 0; i < 3; ++i) {
    linear += 0.5 * s.mass_kg * s.v_world_mps[i] * s.v_world_mps[i];
    rotational += 0.5 * s.omega_world_radps[i] * s.L_world_kgm2ps[i];
  }
  EXPECT_NEAR(s.kinetic_energy_J, linear + rotational, 1e-12);
  EXPECT_GT(rotational, 0.0);
}

TEST(TelemetryConvert, TimingFlagsAndJitter) {
  loop::CycleRecord r = sample_record();
  const TimingSample s = to_timing(r, 0.0041, 0.004, 7);
  EXPECT_DOUBLE_EQ(s.period_s, 0.0041);
  EXPECT_NEAR(s.jitter_s, 0.0001, 1e-15);
  EXPECT_DOUBLE_EQ(s.compute_s, 25e-6);
  EXPECT_TRUE(s.ipoc_gap);
  EXPECT_TRUE(s.robot_late);
  EXPECT_FALSE(s.robot_lost);
  EXPECT_EQ(s.datagrams_lost, 7u);
  const TimingSample first = to_timing(r, 0.0, 0.004, 0);
  EXPECT_EQ(first.jitter_s, 0.0);  // no period known: no jitter
}

TEST(TelemetryConvert, HealthCodesAndCounters) {
  loop::CycleRecord r = sample_record();
  r.state = loop::State::fault;
  r.fault = loop::Fault::contact_over_limit;
  ChannelCounters c;
  c.records_offered = 10;
  c.records_published = 8;
  c.telemetry_drops = 2;
  RuntimeHealth h;
  h.datagrams_lost = 3;
  h.record_drops = 4;
  h.poses_from_joints = 7;
  h.pose_disagreements = 8;
  h.poses_missing = 9;
  const HealthSample s = to_health(5, &r, c, h);
  EXPECT_EQ(s.health_seq, 5u);
  EXPECT_EQ(s.state, 3);
  EXPECT_EQ(s.fault, 6);
  EXPECT_STREQ(state_code_name(s.state), "fault");
  EXPECT_STREQ(fault_code_name(s.fault), "contact_over_limit");
  EXPECT_STREQ(state_code_name(9), "?");
  EXPECT_EQ(s.telemetry_drops, 2u);
  EXPECT_EQ(s.records_offered, 10u);
  EXPECT_EQ(s.datagrams_lost, 3u);
  EXPECT_EQ(s.record_drops, 4u);
  EXPECT_EQ(s.poses_from_joints, 7u);
  EXPECT_EQ(s.pose_disagreements, 8u);
  EXPECT_EQ(s.poses_missing, 9u);
  const HealthSample none = to_health(1, nullptr, c, h);
  EXPECT_EQ(none.cycle, 0u);
}

TEST(TelemetryConvert, ModelIdentityNamesRigEffectsAndNetwork) {
  infer::DeployedModel m;
  m.rig.name = "kr210-test";
  m.rig.robot = "KR 210 R2700";
  m.physics.effects = {model::Effect::bias, model::Effect::gravity, model::Effect::cable};
  infer::DeployedNetwork n;
  n.features = {model::Feature::sin_q1, model::Feature::sin_q2};
  n.output_axes = {2, 5};
  n.shape.width = {2, 8, 2};
  n.shape.activation = {model::Activation::leaky_relu, model::Activation::identity};
  n.quantised.weight_bits = 8;
  m.network = n;
  m.provenance_json = R"({"fit":"x"})";
  const ModelIdentityInfo info = model_identity(m, "model.zgm", 0xDEADBEEFu);
  EXPECT_EQ(info.rig_name, "kr210-test");
  EXPECT_EQ(info.effects, (std::vector<std::string>{"bias", "gravity", "cable"}));
  EXPECT_TRUE(info.has_network);
  EXPECT_EQ(info.network_width, (std::vector<std::int32_t>{2, 8, 2}));
  EXPECT_EQ(info.network_activations, (std::vector<std::string>{"leaky_relu", "identity"}));
  EXPECT_EQ(info.network_features, (std::vector<std::string>{"sin_q1", "sin_q2"}));
  EXPECT_EQ(info.network_outputs, (std::vector<std::string>{"Fz", "Mz"}));
  EXPECT_EQ(info.weight_bits, 8);
  EXPECT_EQ(info.deploy_crc32, 0xDEADBEEFu);

  std::vector<char*> storage;
  const zerog_telemetry_ModelIdentity s = model_identity_sample(info, storage);
  EXPECT_STREQ(s.rig_name, "kr210-test");
  ASSERT_EQ(s.effects._length, 3u);
  EXPECT_STREQ(s.effects._buffer[2], "cable");
  ASSERT_EQ(s.network_features._length, 2u);
  EXPECT_STREQ(s.network_features._buffer[1], "sin_q2");
  ASSERT_EQ(s.network_outputs._length, 2u);
  EXPECT_STREQ(s.network_outputs._buffer[0], "Fz");
  ASSERT_EQ(s.network_width._length, 3u);
  EXPECT_EQ(s.network_width._buffer[1], 8);
  EXPECT_EQ(s.deploy_crc32, 0xDEADBEEFu);
  EXPECT_STREQ(s.provenance_json, R"({"fit":"x"})");
}

TEST(TelemetryConfig, ChecksNameTheSetting) {
  // The field comes apart from the reason: zerog-rt names its key "telemetry.<field>" from it.
  const auto expect_setting = [](const Status& st, const std::string& setting,
                                 const std::string& why) {
    EXPECT_EQ(st.code(), StatusCode::invalid_setting) << st.text();
    EXPECT_EQ(st.setting(), setting) << st.text();
    EXPECT_NE(st.message().find(why), std::string::npos) << st.text();
  };
  TelemetryConfig c;
  EXPECT_EQ(check_config(c).text(), "");
  c.domain_id = 233;
  expect_setting(check_config(c), "domain_id", "233 is outside 0..232");
  EXPECT_EQ(check_config(c).text(), "domain_id: 233 is outside 0..232");
  c = {};
  c.interface = "eth0\"/><x";
  expect_setting(check_config(c), "interface", "is not an interface name");
  c = {};
  c.allow_multicast = false;
  expect_setting(check_config(c), "peers", "at least one unicast peer");
  c.peers = {"127.0.0.1", "bad<peer"};
  expect_setting(check_config(c), "peers", "\"bad<peer\"");
  c = {};
  c.topic_prefix = "zerog.";
  expect_setting(check_config(c), "topic_prefix", "only letters");
  c = {};
  c.health_period_s = 0.0;
  expect_setting(check_config(c), "health_period_s", "positive");
  c = {};
  c.nominal_period_s = std::nan("");
  expect_setting(check_config(c), "nominal_period_s", "positive");
  c = {};
  c.poll_period_s = 1.0;
  expect_setting(check_config(c), "poll_period_s", "(0, 0.1]");
}

TEST(TelemetryRos2, StampIsTheCycleTimeToTheNanosecond) {
  RosTime t = ros_time(0.164);
  EXPECT_EQ(t.sec_, 0);
  EXPECT_EQ(t.nanosec_, 164'000'000u);
  t = ros_time(12345.678901234);
  EXPECT_EQ(t.sec_, 12345);
  EXPECT_EQ(t.nanosec_, 678'901'234u);
  t = ros_time(0.0);
  EXPECT_EQ(t.sec_, 0);
  EXPECT_EQ(t.nanosec_, 0u);
  EXPECT_EQ(ros_dds_topic("/zerog", "wrench"), "rt/zerog/wrench");
  EXPECT_EQ(ros_dds_topic("/", "wrench"), "rt/wrench");
}

TEST(TelemetryRos2, MessagesCarryTheRecordInRosOrderAndFrames) {
  const loop::CycleRecord r = sample_record();
  TelemetryConfig c;
  c.sensor_frame = "ft";
  const Ros2Frames frames(c);
  Ros2CycleMessages m;
  to_ros2(r, sample_body(), frames, m);
  EXPECT_STREQ(m.wrench.header_.frame_id_, "ft");
  EXPECT_EQ(m.wrench.header_.stamp_.nanosec_, 164'000'000u);
  EXPECT_EQ(m.wrench.wrench_.force_.x_, r.wrench_measured[0]);
  EXPECT_EQ(m.wrench.wrench_.torque_.z_, r.wrench_measured[5]);
  EXPECT_EQ(m.wrench_at_eval.wrench_.force_.y_, r.wrench_at_eval[1]);
  EXPECT_EQ(m.wrench_predicted.wrench_.torque_.x_, r.predicted[3]);
  EXPECT_EQ(m.wrench_contact.wrench_.force_.z_, r.contact[2]);
  EXPECT_STREQ(m.imu.header_.frame_id_, "imu_link");
  EXPECT_EQ(m.imu.linear_acceleration_.z_, 9.8);
  EXPECT_EQ(m.imu.angular_velocity_.y_, 0.02);
  EXPECT_EQ(m.imu.orientation_covariance_[0], -1.0);
  ASSERT_EQ(m.joints.name_._length, 6u);
  EXPECT_STREQ(m.joints.name_._buffer[2], "joint_a3");
  EXPECT_EQ(m.joints.position_._buffer[5], r.joints_rad[5]);
  // ROS's quaternion order is x, y, z, w.
  EXPECT_STREQ(m.sensor_pose.header_.frame_id_, "base_link");
  EXPECT_EQ(m.sensor_pose.pose_.orientation_.y_, r.q_base_sensor.y());
  EXPECT_EQ(m.sensor_pose.pose_.orientation_.w_, r.q_base_sensor.w());
  EXPECT_EQ(m.sensor_pose.pose_.position_.z_, 3.0);
  EXPECT_EQ(m.body_pose.pose_.orientation_.x_, r.body.q_world_body.x());
  EXPECT_EQ(m.body_twist.twist_.linear_.y_, -0.2);
  const CommandSample command = to_command(r, sample_body());
  EXPECT_EQ(m.body_twist.twist_.angular_.z_, command.omega_world_radps[2]);
}

TEST(TelemetryRos2, DiagnosticsHoldHealthAndModel) {
  loop::CycleRecord r = sample_record();
  r.state = loop::State::fault;
  r.fault = loop::Fault::ft_stale;
  const HealthSample h = to_health(7, &r, ChannelCounters{3, 3, 0, 0, 1}, RuntimeHealth{});
  ModelIdentityInfo model;
  model.rig_name = "rig";
  model.effects = {"gravity", "inertia"};
  model.deploy_crc32 = 0xABCD;
  const Ros2Diagnostics d = ros2_diagnostics(h, model);
  Ros2DiagnosticsStorage storage;
  const RosDiagnosticArray a = diagnostics_message(d, storage);
  ASSERT_EQ(a.status_._length, 2u);
  EXPECT_EQ(a.status_._buffer[0].level_, 2);  // ERROR in the fault state
  EXPECT_STREQ(a.status_._buffer[0].message_, "state fault, fault ft_stale");
  EXPECT_STREQ(a.status_._buffer[1].name_, "zerog-rt: model");
  bool crc = false;
  for (std::uint32_t i = 0; i < a.status_._buffer[1].values_._length; ++i) {
    const auto& kv = a.status_._buffer[1].values_._buffer[i];
    if (std::strcmp(kv.key_, "deploy_crc32") == 0) crc = std::strcmp(kv.value_, "0x0000abcd") == 0;
  }
  EXPECT_TRUE(crc);
}

TEST(TelemetryRos2, ConfigRefusesNamesRosRefuses) {
  TelemetryConfig c;
  c.ros_namespace = "zerog";
  EXPECT_EQ(check_config(c).setting(), "ros_namespace");
  c = {};
  c.sensor_frame = "/ft_sensor";
  EXPECT_EQ(check_config(c).setting(), "sensor_frame");
  c = {};
  c.base_frame = "base link";
  EXPECT_EQ(check_config(c).setting(), "base_frame");
  c = {};
  c.joint_names.pop_back();
  EXPECT_EQ(check_config(c).setting(), "joint_names");
  c.ros2 = false;  // not checked when off
  EXPECT_TRUE(check_config(c).ok());
}

TEST(TelemetryConfig, CycloneXmlForLoopbackWithoutMulticast) {
  TelemetryConfig c;
  c.interface = "lo";
  c.allow_multicast = false;
  c.peers = {"127.0.0.1", "10.0.0.2"};
  ASSERT_EQ(check_config(c).text(), "");
  EXPECT_EQ(cyclone_xml(c),
            "<CycloneDDS><Domain id=\"any\"><General><Interfaces><NetworkInterface "
            "name=\"lo\"/></Interfaces><AllowMulticast>false</AllowMulticast></General>"
            "<Discovery><ParticipantIndex>auto</ParticipantIndex><Peers><Peer "
            "address=\"127.0.0.1\"/><Peer address=\"10.0.0.2\"/></Peers></Discovery></Domain>"
            "</CycloneDDS>");
  const TelemetryConfig defaults;
  EXPECT_EQ(cyclone_xml(defaults),
            "<CycloneDDS><Domain id=\"any\"><General><AllowMulticast>true</AllowMulticast>"
            "</General></Domain></CycloneDDS>");
}

}  // namespace
}  // namespace zerog::telemetry
