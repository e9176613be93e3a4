// The sensor pose in the cycle (issue 15, item 2): from RIst, or from AIPos through the rig's
// robot (zerog::robot) when the controller sends joints only; the check of one against the other
// and its counter; a message with no pose at all. The RIst of these streams comes from host/sim's
// kinematics (the emulator's), an implementation independent of zerog::robot, and passes through
// the real codec (format_robot_message → text → parse_robot_message: 4 decimals, as on the wire).
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "alloc_count.hpp"
#include "loop_fixtures.hpp"
#include "rsi_step.hpp"
#include "zerog/formats/robot_toml.hpp"
#include "zerog/loop/cycle.hpp"
#include "zerog/model/rotation.hpp"
#include "zerog/proto/rsi.hpp"
#include "zerog/robot/robot_model.hpp"
#include "zerog/sim/robot.hpp"

namespace zerog::loop {
namespace {

namespace rsi = proto::rsi;
using test::payload_model;
using test::StaticRobot;
using test::test_cycle_config;

const Eigen::Vector3d kFlangeSensor{0.0, 0.0, 0.06};  // as the emulator's TCP
constexpr int kCycles = 80;
constexpr double kDeg = rsi::kRadPerDeg;

// A moving arm: joints along smooth sines around a pose clear of singularities.
std::array<double, 6> joints_deg(int k) {
  const double t = k * test::kPeriod;
  return {10.0 + 20.0 * std::sin(0.9 * t), -80.0 + 10.0 * std::sin(1.3 * t),
          95.0 + 15.0 * std::sin(0.7 * t), 5.0 + 40.0 * std::sin(1.1 * t),
          40.0 + 25.0 * std::sin(0.5 * t), -20.0 + 60.0 * std::sin(1.7 * t)};
}

// The controller's message for cycle k: RIst from the simulated arm, through the codec's text.
rsi::RobotMessage wire_message(int k, bool with_rist) {
  rsi::RobotMessage m;
  m.joints_deg = joints_deg(k);
  sim::JointVector q{};
  for (int i = 0; i < 6; ++i) q[i] = m.joints_deg[i] * kDeg;
  const robot::Pose f = robot::flange_pose(sim::kr210(), q);
  const Eigen::Vector3d p = f.p_m + f.R * kFlangeSensor;
  const Eigen::Vector3d abc = model::kuka_abc_from_rotation(f.R);
  const rsi::Correction c =
      rsi::correction_from_si({p.x(), p.y(), p.z()}, {abc.x(), abc.y(), abc.z()});
  m.actual_pose = {c.x_mm, c.y_mm, c.z_mm, c.a_deg, c.b_deg, c.c_deg};
  m.has_actual_pose = with_rist;
  m.has_delay = true;
  m.ipoc = 5000 + 12 * static_cast<std::uint64_t>(k);
  std::array<char, 1024> text{};
  const rsi::FormatResult written = rsi::format_robot_message(m, text);
  EXPECT_EQ(written.status, rsi::FormatStatus::ok);
  rsi::RobotMessage parsed;
  const rsi::ParseResult r = rsi::parse_robot_message({text.data(), written.size}, parsed);
  EXPECT_TRUE(r.ok()) << r.reason;
  EXPECT_EQ(parsed.has_actual_pose, with_rist);
  return parsed;
}

robot::FrameTransform tool(const Eigen::Vector3d& p_m,
                           const Eigen::Matrix3d& R = Eigen::Matrix3d::Identity()) {
  robot::FrameTransform t;
  t.p_m = p_m;
  t.R = R;
  return t;
}

// Runs kCycles messages through a configured cycle and keeps each record.
std::vector<CycleRecord> run(Cycle& c, bool with_rist) {
  StaticRobot sensors;  // F/T and IMU samples so that the cycle runs the model
  std::vector<CycleRecord> records;
  for (int k = 0; k < kCycles; ++k) {
    for (int i = 0; i < 4; ++i) c.add_ft(sensors.ft(Eigen::Matrix<double, 6, 1>::Zero()));
    for (int i = 0; i < 24; ++i) c.add_imu(sensors.imu_sample);
    zerog::test::RsiReply reply;
    const rsi::RobotMessage m = wire_message(k, with_rist);
    zerog::test::step_rsi(c, m, reply);
    EXPECT_EQ(reply.ipoc, m.ipoc);
    records.push_back(c.last());
  }
  return records;
}

CycleConfig with_robot(const robot::FrameTransform& flange_sensor) {
  CycleConfig config = test_cycle_config();
  config.robot = formats::kr210_r2700(flange_sensor);
  config.robot->elasticity = {};  // the rigid arm: the pose path alone
  return config;
}

TEST(CyclePose, JointsOnlyStreamGivesTheSensorPoseOfTheRIstStream) {
  Cycle from_rist, from_joints;
  ASSERT_EQ(from_rist.configure(test_cycle_config(), payload_model()).text(), "");
  ASSERT_EQ(from_joints.configure(with_robot(tool(kFlangeSensor)), payload_model()).text(), "");
  const std::vector<CycleRecord> a = run(from_rist, true);
  const std::vector<CycleRecord> b = run(from_joints, false);
  double worst_m = 0.0, worst_rad = 0.0;
  for (int k = 0; k < kCycles; ++k) {
    EXPECT_EQ(a[k].flags & kPoseFromJoints, 0u);
    EXPECT_NE(b[k].flags & kPoseFromJoints, 0u);
    worst_m = std::max(worst_m, (a[k].p_base_sensor_m - b[k].p_base_sensor_m).norm());
    worst_rad = std::max(worst_rad, a[k].q_base_sensor.angularDistance(b[k].q_base_sensor));
  }
  std::printf("joints-only vs RIst stream: at most %.6f mm, %.6f deg apart\n", worst_m * 1e3,
              worst_rad / kDeg);
  EXPECT_LT(worst_m, 0.01e-3) << "mm: " << worst_m * 1e3;  // 0.01 mm
  EXPECT_LT(worst_rad, 0.001 * kDeg) << "deg: " << worst_rad / kDeg;
  EXPECT_GT(worst_m, 0.0);  // RIst is rounded to 4 decimals on the wire: not the same numbers
  EXPECT_EQ(from_joints.counters().poses_from_joints, static_cast<std::uint64_t>(kCycles));
  EXPECT_EQ(from_rist.counters().poses_from_joints, 0u);
  EXPECT_EQ(from_joints.counters().pose_disagreements, 0u);
  EXPECT_EQ(from_joints.counters().poses_missing, 0u);
  // The model ran on those poses: both cycles predict the same wrench.
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(a.back().predicted[k], b.back().predicted[k], 1e-3);
  EXPECT_EQ(a.back().model_status, infer::StatusCode::ok);
}

TEST(CyclePose, BothPresentAndAgreeingIsCheckedQuietly) {
  Cycle c;
  ASSERT_EQ(c.configure(with_robot(tool(kFlangeSensor)), payload_model()).text(), "");
  const std::vector<CycleRecord> r = run(c, true);
  double worst_m = 0.0, worst_rad = 0.0;
  for (const CycleRecord& record : r) {
    EXPECT_EQ(record.flags & (kPoseFromJoints | kPoseDisagrees), 0u);
    worst_m = std::max(worst_m, record.pose_check_m);
    worst_rad = std::max(worst_rad, record.pose_check_rad);
  }
  EXPECT_GT(worst_m, 0.0);  // the check ran
  EXPECT_LT(worst_m, 0.01e-3);
  EXPECT_LT(worst_rad, 0.001 * kDeg);
  EXPECT_EQ(c.counters().pose_disagreements, 0u);
  EXPECT_EQ(c.counters().poses_from_joints, 0u);
}

TEST(CyclePose, AWrongToolFrameIsCountedAsDisagreement) {
  // The rig says the sensor is 5 mm further out than the controller's TCP: every cycle
  // disagrees in position (tolerance 1 mm).
  {
    Cycle c;
    ASSERT_EQ(
        c.configure(with_robot(tool(kFlangeSensor + Eigen::Vector3d(0, 0, 0.005))), payload_model())
            .text(),
        "");
    const std::vector<CycleRecord> r = run(c, true);
    EXPECT_EQ(c.counters().pose_disagreements, static_cast<std::uint64_t>(kCycles));
    EXPECT_NE(r.back().flags & kPoseDisagrees, 0u);
    EXPECT_NEAR(r.back().pose_check_m, 0.005, 1e-5);
    // RIst is still what the cycle uses.
    EXPECT_EQ(r.back().flags & kPoseFromJoints, 0u);
  }
  // Same origin, axes turned by 0.5° about the flange's z: only the angle check sees it.
  {
    Cycle c;
    const Eigen::Matrix3d turned =
        Eigen::AngleAxisd(0.5 * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    ASSERT_EQ(c.configure(with_robot(tool(kFlangeSensor, turned)), payload_model()).text(), "");
    const std::vector<CycleRecord> r = run(c, true);
    EXPECT_EQ(c.counters().pose_disagreements, static_cast<std::uint64_t>(kCycles));
    EXPECT_LT(r.back().pose_check_m, 0.01e-3);
    EXPECT_NEAR(r.back().pose_check_rad, 0.5 * kDeg, 1e-5);
  }
  // The tolerances are the configured ones: 1° lets the 0.5° tool pass.
  {
    CycleConfig config = with_robot(tool(
        kFlangeSensor, Eigen::AngleAxisd(0.5 * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix()));
    config.pose_check_angle_rad = 1.0 * kDeg;
    Cycle c;
    ASSERT_EQ(c.configure(config, payload_model()).text(), "");
    run(c, true);
    EXPECT_EQ(c.counters().pose_disagreements, 0u);
  }
}

TEST(CyclePose, NoRIstAndNoRobotIsAnsweredButCountsAsALostCycle) {
  Cycle c;
  ASSERT_EQ(c.configure(test_cycle_config(), payload_model()).text(), "");
  const std::vector<CycleRecord> r = run(c, false);
  EXPECT_EQ(c.counters().poses_missing, static_cast<std::uint64_t>(kCycles));
  EXPECT_EQ(r.back().flags, static_cast<std::uint32_t>(kPoseMissing));
  EXPECT_FALSE(c.ready());
  EXPECT_EQ(c.counters().messages, static_cast<std::uint64_t>(kCycles));
}

TEST(CyclePose, ConfigureRefusesABadRobotOrTolerance) {
  CycleConfig config = with_robot(tool(kFlangeSensor));
  config.robot->joints[1].sign = 0.5;
  Cycle c;
  zerog::Status st = c.configure(config, payload_model());
  EXPECT_EQ(st.code(), zerog::StatusCode::invalid_setting);
  EXPECT_EQ(st.setting(), "robot.joints[1].sign") << st.text();
  config = with_robot(tool(kFlangeSensor));
  config.robot->joint_count = 5;
  st = c.configure(config, payload_model());
  EXPECT_EQ(st.setting(), "robot.joint_count") << st.text();
  EXPECT_NE(st.message().find("6 axes"), std::string::npos) << st.text();
  config = with_robot(tool(kFlangeSensor));
  config.pose_check_position_m = 0.0;
  EXPECT_EQ(c.configure(config, payload_model()).setting(), "pose_check_position_m");
  config = with_robot(tool(kFlangeSensor));
  config.pose_check_angle_rad = -1.0;
  EXPECT_EQ(c.configure(config, payload_model()).setting(), "pose_check_angle_rad");
}

TEST(CyclePose, KinematicsInTheCycleDoNotAllocate) {
  Cycle c;
  ASSERT_EQ(c.configure(with_robot(tool(kFlangeSensor)), payload_model()).text(), "");
  StaticRobot sensors;
  std::vector<rsi::RobotMessage> messages;
  for (int k = 0; k < 40; ++k) messages.push_back(wire_message(k, k % 2 == 0));
  const samples::FtSample ft = sensors.ft(Eigen::Matrix<double, 6, 1>::Zero());
  zerog::test::AllocGuard guard("Cycle::step with kinematics");
  for (const rsi::RobotMessage& m : messages) {
    for (int i = 0; i < 4; ++i) c.add_ft(ft);
    for (int i = 0; i < 24; ++i) c.add_imu(sensors.imu_sample);
    zerog::test::RsiReply reply;
    zerog::test::step_rsi(c, m, reply);
  }
  guard.stop();
  EXPECT_EQ(guard.allocations(), 0u) << guard.first_call();
  EXPECT_EQ(guard.frees(), 0u) << guard.first_call();
  EXPECT_EQ(c.counters().poses_from_joints, 20u);
}

}  // namespace
}  // namespace zerog::loop
