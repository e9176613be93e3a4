// The shipped KR 210 R2700 robot file (calib/robots/kr210_r2700.robot.toml), the one description
// of the arm that the simulator, the emulator and the tests move: its rows against the published
// R2700 DH table and KUKA's joint directions its comment cites, the copy built into zerog
// (formats::kr210_r2700) against the file on disk, and the poses its geometry gives by hand.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <numbers>

#include "zerog/formats/robot_toml.hpp"
#include "zerog/robot/forward_kinematics.hpp"
#include "zerog/sim/robot.hpp"
#include "zerog/sim/simulator.hpp"

namespace zerog::robot {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kDeg = kPi / 180.0;

RobotModel file_model() {
  return formats::read_robot_file(std::filesystem::path(ZEROG_SOURCE_DIR) /
                                  "calib/robots/kr210_r2700.robot.toml");
}

// The file's comment cites the R2700 arm's published DH table (the KR 90 R2700, same geometry:
// d1 0.675, a1 0.350, a2 1.15, d4 1.2, d6 0.215) and KUKA's joint directions (A1, A4, A6 turn
// negatively about the DH z axis). The 41 mm a3 is not in that table (the file says so): it is
// checked by the poses below, which the arm's drawing gives.
TEST(Kr210RobotFile, IsThePublishedArm) {
  const RobotModel m = file_model();
  ASSERT_EQ(m.joint_count, 6);
  EXPECT_EQ(m.convention, DhConvention::dh);
  struct Row {
    double a_m, alpha_deg, d_m, theta_offset_deg, sign;
  };
  const Row rows[6] = {{0.350, -90, 0.675, 0, -1}, {1.150, 0, 0.0, 0, 1},
                       {-0.041, -90, 0.0, -90, 1}, {0.0, 90, 1.200, 0, -1},
                       {0.0, -90, 0.0, 0, 1},      {0.0, 0, 0.215, 180, -1}};
  for (int i = 0; i < 6; ++i) {
    const DhJoint& j = m.joints[static_cast<std::size_t>(i)];
    EXPECT_EQ(j.a_m, rows[i].a_m) << "A" << i + 1;
    EXPECT_EQ(j.alpha_rad, rows[i].alpha_deg * kDeg) << "A" << i + 1;
    EXPECT_EQ(j.d_m, rows[i].d_m) << "A" << i + 1;
    EXPECT_EQ(j.theta_offset_rad, rows[i].theta_offset_deg * kDeg) << "A" << i + 1;
    EXPECT_EQ(j.sign, rows[i].sign) << "A" << i + 1;
    EXPECT_EQ(m.input_index[static_cast<std::size_t>(i)], i);
  }
  EXPECT_TRUE(m.last_flange.R.isIdentity(0.0));
  EXPECT_TRUE(m.last_flange.p_m.isZero(0.0));
  // The file's sensor frame is the simulated rig's.
  EXPECT_EQ(m.flange_sensor.p_m, sim::default_sim_config(1).p_flange_sensor_m);
  EXPECT_TRUE(m.flange_sensor.R.isIdentity(0.0));
}

// zerog's built-in copy is the file's text (firmware/formats/CMakeLists.txt copies it at
// configure time): every field equal, the elasticity too.
TEST(Kr210RobotFile, TheBuiltInArmIsTheFile) {
  const RobotModel disk = file_model();
  FrameTransform mount;
  mount.p_m = {0.01, 0.02, 0.03};
  const RobotModel built_in = formats::kr210_r2700(mount);
  EXPECT_EQ(built_in.convention, disk.convention);
  ASSERT_EQ(built_in.joint_count, disk.joint_count);
  for (std::size_t i = 0; i < kMaxJoints; ++i) {
    const DhJoint &a = built_in.joints[i], &b = disk.joints[i];
    EXPECT_EQ(a.a_m, b.a_m);
    EXPECT_EQ(a.alpha_rad, b.alpha_rad);
    EXPECT_EQ(a.d_m, b.d_m);
    EXPECT_EQ(a.theta_offset_rad, b.theta_offset_rad);
    EXPECT_EQ(a.sign, b.sign);
    EXPECT_EQ(built_in.input_index[i], disk.input_index[i]);
    EXPECT_EQ(built_in.elasticity[i].stiffness_Nm_per_rad, disk.elasticity[i].stiffness_Nm_per_rad);
    EXPECT_EQ(built_in.elasticity[i].mode_hz, disk.elasticity[i].mode_hz);
    EXPECT_EQ(built_in.elasticity[i].damping_ratio, disk.elasticity[i].damping_ratio);
  }
  EXPECT_TRUE(built_in.elastic());
  EXPECT_EQ(built_in.last_flange.R, disk.last_flange.R);
  EXPECT_EQ(built_in.last_flange.p_m, disk.last_flange.p_m);
  EXPECT_EQ(built_in.flange_sensor.p_m, mount.p_m);  // the caller's mounting, not the file's
  // The simulator's arm is the built-in one with the flange as sensor frame.
  EXPECT_EQ(sim::kr210().joints[2].a_m, disk.joints[2].a_m);
  EXPECT_TRUE(sim::kr210().flange_sensor.p_m.isZero(0.0));
}

TEST(Kr210RobotFile, HomePose) {
  const Pose f = flange_pose(file_model(), sim::kr210_home());
  // A1 axis to A2: 0.350 forward, 0.675 up; upper arm 1.150 up; forearm 1.200 forward and 0.041
  // below the A3 axis; flange 0.215 beyond the wrist centre.
  EXPECT_TRUE(f.p_m.isApprox(Eigen::Vector3d(1.765, 0.0, 1.784), 1e-12)) << f.p_m.transpose();
  Eigen::Matrix3d R_expected;
  R_expected << 0, 0, 1, 0, 1, 0, -1, 0, 0;  // Ry(+90°): flange z forward, x down
  EXPECT_TRUE(f.R.isApprox(R_expected, 1e-12)) << f.R;
}

TEST(Kr210RobotFile, KnownPoses) {
  const RobotModel m = file_model();
  sim::JointVector q = sim::kr210_home();
  q[0] = 90 * kDeg;  // A1 positive turns clockwise seen from above: +x goes to −y
  EXPECT_TRUE(flange_pose(m, q).p_m.isApprox(Eigen::Vector3d(0.0, -1.765, 1.784), 1e-12));
  q = sim::kr210_home();
  q[4] = 90 * kDeg;  // A5 = +90°: flange points down from the wrist centre
  const Pose down = flange_pose(m, q);
  EXPECT_TRUE(down.p_m.isApprox(Eigen::Vector3d(1.55, 0.0, 1.569), 1e-12));
  EXPECT_TRUE(down.R.col(2).isApprox(Eigen::Vector3d(0, 0, -1), 1e-12));
  q = sim::kr210_home();
  q[2] = 0.0;  // A3 = 0: forearm straight up, the 41 mm offset now points forward
  EXPECT_TRUE(flange_pose(m, q).p_m.isApprox(Eigen::Vector3d(0.391, 0.0, 3.24), 1e-12));
  q = sim::kr210_home();
  q[3] = 90 * kDeg;  // A4 and A6 turn about the forearm/flange axis: position unchanged
  q[5] = -40 * kDeg;
  EXPECT_TRUE(flange_pose(m, q).p_m.isApprox(Eigen::Vector3d(1.765, 0.0, 1.784), 1e-12));
}

}  // namespace
}  // namespace zerog::robot
