// zerog::robot forward kinematics: the shipped KR 210 R2700 file against the simulator's own
// kinematics (host/sim, the truth), the 7-axis LBR iiwa file against hand-computed poses, the
// model checks and the file reader's refusals, and no allocation.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>

#include "alloc_count.hpp"
#include "zerog/formats/robot_toml.hpp"
#include "zerog/robot/forward_kinematics.hpp"
#include "zerog/sim/kinematics.hpp"

namespace zerog::robot {
namespace {

namespace fs = std::filesystem;
constexpr double kPi = std::numbers::pi;

fs::path calib(const char* name) { return fs::path(ZEROG_SOURCE_DIR) / "calib/robots" / name; }

double rotation_error_rad(const Eigen::Matrix3d& A, const Eigen::Matrix3d& B) {
  return Eigen::AngleAxisd(A.transpose() * B).angle();
}

TEST(RobotForwardKinematics, Kr210FileAgreesWithSimulatorAtRandomJoints) {
  const RobotModel model = io::read_robot_file(calib("kr210_r2700.robot.toml"));
  ASSERT_EQ(model.joint_count, 6);
  const Eigen::Vector3d p_flange_sensor(0.0, 0.0, 0.06);  // the file's [flange_sensor]
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> angle(-kPi, kPi);
  double worst_p = 0.0, worst_R = 0.0;
  for (int trial = 0; trial < 2000; ++trial) {
    sim::JointVector q;
    for (double& v : q) v = angle(rng);
    const sim::FlangePose truth = sim::forward_kinematics(q);
    const Pose flange = flange_pose(model, q);
    const Pose sensor = sensor_pose(model, q);
    worst_p = std::max(worst_p, (flange.p_m - truth.p_base_flange_m).norm());
    worst_R = std::max(worst_R, rotation_error_rad(flange.R, truth.R_base_flange));
    const Eigen::Vector3d p_sensor_truth =
        truth.p_base_flange_m + truth.R_base_flange * p_flange_sensor;
    worst_p = std::max(worst_p, (sensor.p_m - p_sensor_truth).norm());
    worst_R = std::max(worst_R, rotation_error_rad(sensor.R, truth.R_base_flange));
  }
  EXPECT_LT(worst_p, 1e-9);
  EXPECT_LT(worst_R, 1e-9);
  // The built-in copy is the same robot.
  EXPECT_LT((flange_pose(kr210_r2700(), sim::kr210_home()).p_m -
             sim::forward_kinematics(sim::kr210_home()).p_base_flange_m)
                .norm(),
            1e-12);
}

TEST(RobotForwardKinematics, Kr210HomeIsTheDocumentedPose) {
  const Pose home = flange_pose(kr210_r2700(), sim::kr210_home());
  EXPECT_NEAR(home.p_m.x(), 1.765, 1e-12);
  EXPECT_NEAR(home.p_m.y(), 0.0, 1e-12);
  EXPECT_NEAR(home.p_m.z(), 1.784, 1e-12);
  EXPECT_LT(rotation_error_rad(
                home.R, Eigen::AngleAxisd(kPi / 2, Eigen::Vector3d::UnitY()).toRotationMatrix()),
            1e-12);
}

// LBR iiwa 14 R820 (modified DH), poses computed by hand from the link lengths 0.36, 0.42, 0.40,
// 0.126 m: joints 2, 4, 6 turn about +y of the base when the arm is straight, joints 1, 3, 5, 7
// about z.
TEST(RobotForwardKinematics, SevenAxisIiwaAtHandComputedPoses) {
  const RobotModel model = io::read_robot_file(calib("lbr_iiwa14_r820.robot.toml"));
  ASSERT_EQ(model.joint_count, 7);
  ASSERT_EQ(model.convention, DhConvention::mdh);
  struct Case {
    std::array<double, 7> q;
    Eigen::Vector3d p;
    Eigen::Matrix3d R;
  };
  const Eigen::Matrix3d Ry90 =
      Eigen::AngleAxisd(kPi / 2, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Matrix3d Rz90 =
      Eigen::AngleAxisd(kPi / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Case cases[] = {
      // Straight up.
      {{0, 0, 0, 0, 0, 0, 0}, {0, 0, 1.306}, Eigen::Matrix3d::Identity()},
      // Shoulder A2 +90°: everything above it lies along +x at the shoulder height 0.36 m.
      {{0, kPi / 2, 0, 0, 0, 0, 0}, {0.946, 0, 0.36}, Ry90},
      // Elbow A4 +90°: the forearm (0.40 + 0.126) along +x at the elbow height 0.78 m.
      {{0, 0, 0, kPi / 2, 0, 0, 0}, {0.526, 0, 0.78}, Ry90},
      // A1 +90° then A2 +90°: the arm along +y (base turned first).
      {{kPi / 2, kPi / 2, 0, 0, 0, 0, 0}, {0, 0.946, 0.36}, Rz90 * Ry90},
      // A7 +90°: the flange turns about z, stays put.
      {{0, 0, 0, 0, 0, 0, kPi / 2}, {0, 0, 1.306}, Rz90},
  };
  for (const Case& c : cases) {
    const Pose pose = flange_pose(model, c.q);
    EXPECT_LT((pose.p_m - c.p).norm(), 1e-12) << pose.p_m.transpose();
    EXPECT_LT(rotation_error_rad(pose.R, c.R), 1e-12);
  }
}

// The standard and the modified convention describe the same arm: the KR 210 rewritten in
// Craig's form (row i carries a_{i−1}, α_{i−1}; the last row's a, α become the flange frame).
TEST(RobotForwardKinematics, ModifiedDhOfTheKr210MatchesStandard) {
  const RobotModel dh = kr210_r2700();
  RobotModel mdh = dh;
  mdh.convention = DhConvention::mdh;
  for (int i = 0; i < 6; ++i) {
    mdh.joints[i].a_m = i == 0 ? 0.0 : dh.joints[i - 1].a_m;
    mdh.joints[i].alpha_rad = i == 0 ? 0.0 : dh.joints[i - 1].alpha_rad;
  }
  mdh.last_flange.p_m = {dh.joints[5].a_m, 0.0, 0.0};
  mdh.last_flange.R =
      Eigen::AngleAxisd(dh.joints[5].alpha_rad, Eigen::Vector3d::UnitX()).toRotationMatrix();
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> angle(-kPi, kPi);
  for (int trial = 0; trial < 200; ++trial) {
    std::array<double, 6> q;
    for (double& v : q) v = angle(rng);
    const Pose a = flange_pose(dh, q), b = flange_pose(mdh, q);
    EXPECT_LT((a.p_m - b.p_m).norm(), 1e-12);
    EXPECT_LT(rotation_error_rad(a.R, b.R), 1e-12);
  }
}

TEST(RobotForwardKinematics, JointOrderPicksTheRecordedColumns) {
  RobotModel swapped = kr210_r2700();
  // The recording lists A6 first, then A1..A5.
  for (int i = 0; i < 6; ++i) swapped.input_index[i] = (i + 1) % 6;
  ASSERT_TRUE(validate(swapped).ok());
  const std::array<double, 6> q = {0.1, -1.2, 1.4, 0.3, -0.5, 0.7};
  const std::array<double, 6> recorded = {q[5], q[0], q[1], q[2], q[3], q[4]};
  const Pose a = flange_pose(kr210_r2700(), q), b = flange_pose(swapped, recorded);
  EXPECT_LT((a.p_m - b.p_m).norm(), 1e-15);
}

TEST(RobotModelValidate, NamesTheFaultyField) {
  RobotModel m = kr210_r2700();
  EXPECT_TRUE(validate(m).ok());
  m.joint_count = 9;
  EXPECT_EQ(validate(m).setting(), "joint_count");
  m = kr210_r2700();
  m.joints[2].sign = 0.5;
  zerog::Status s = validate(m);
  EXPECT_EQ(s.code(), zerog::StatusCode::invalid_setting);
  EXPECT_EQ(s.setting(), "joints[2].sign");
  EXPECT_EQ(s.message(), "must be +1 or -1");
  EXPECT_EQ(s.text(), "joints[2].sign: must be +1 or -1");
  m = kr210_r2700();
  m.input_index[1] = 0;
  EXPECT_EQ(validate(m).setting(), "input_index[1]");
  m = kr210_r2700();
  m.joints[4].d_m = std::nan("");
  s = validate(m);
  EXPECT_EQ(s.setting(), "joints[4]");
  EXPECT_EQ(s.message(), "has a value that is not a finite number");
  m = kr210_r2700();
  m.flange_sensor.R(0, 0) = 2.0;
  s = validate(m);
  EXPECT_EQ(s.code(), zerog::StatusCode::invalid_setting);
  EXPECT_EQ(s.setting(), "flange_sensor.R");
}

TEST(RobotToml, RefusesBadTablesNamingTheKey) {
  const fs::path dir = fs::temp_directory_path() / "zerog_robot_toml_test";
  fs::create_directories(dir);
  const auto refusal = [&](const std::string& robot_text) -> std::string {
    const fs::path file = dir / "r.robot.toml";
    std::ofstream(file) << "format = \"zerog-robot\"\nversion = 1\n[robot]\n" << robot_text;
    try {
      io::read_robot_file(file);
    } catch (const io::InputError& e) {
      return e.what();
    }
    return "";
  };
  const std::string joint = "[[robot.joint]]\na_m = 0.1\nalpha_deg = 0\nd_m = 0.2\n";
  EXPECT_NE(refusal("convention = \"dhx\"\n" + joint).find("'robot.convention'"),
            std::string::npos);
  EXPECT_NE(refusal("convention = \"dh\"\n" + joint + "sign = 2\n").find("robot.joint[1].sign"),
            std::string::npos);
  EXPECT_NE(refusal("convention = \"dh\"\n" + joint + "colour = 2\n").find("unknown key"),
            std::string::npos);
  EXPECT_NE(refusal("convention = \"dh\"\n" + joint + joint + "column = 1\n")
                .find("robot.joint[2].column"),
            std::string::npos);
  EXPECT_NE(refusal("convention = \"dh\"\n").find("'robot.joint'"), std::string::npos);
  // The ROS names (zerog import --bag reads them) must be strings.
  EXPECT_NE(
      refusal("convention = \"dh\"\n" + joint + "ros_name = 3\n").find("robot.joint[1].ros_name"),
      std::string::npos);
  EXPECT_NE(refusal("convention = \"dh\"\nros_flange = [1]\n" + joint).find("robot.ros_flange"),
            std::string::npos);
  EXPECT_EQ(refusal("convention = \"dh\"\nros_flange = \"tool0\"\n" + joint +
                    "ros_name = \"joint_a1\"\n"),
            "");
  EXPECT_EQ(refusal("convention = \"dh\"\n" + joint), "");
  fs::remove_all(dir);
}

TEST(RobotForwardKinematics, DoesNotAllocate) {
  const RobotModel model = kr210_r2700();
  const std::array<double, 6> q = {0.1, -1.2, 1.4, 0.3, -0.5, 0.7};
  const std::size_t before = test::allocation_count();
  double sum = 0.0;
  for (int i = 0; i < 100; ++i) sum += sensor_pose(model, q).p_m.x();
  EXPECT_EQ(test::allocation_count(), before);
  EXPECT_TRUE(std::isfinite(sum));
}

}  // namespace
}  // namespace zerog::robot

namespace zerog::robot {
namespace {

// sensor_jacobian (the cycle's motion estimator) against central differences of sensor_pose, at
// random joints, on the KR 210 (standard DH, KUKA's joint signs) and the iiwa (modified DH, 7
// joints), with a sensor offset and a permuted joint order.
TEST(RobotForwardKinematics, SensorJacobianIsTheDerivativeOfThePose) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> angle(-1.5, 1.5);
  FrameTransform mount;
  mount.p_m = Eigen::Vector3d(0.01, -0.02, 0.06);
  mount.R = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  RobotModel permuted = kr210_r2700(mount);
  permuted.input_index = {5, 4, 3, 2, 1, 0, 6, 7};
  RobotModel iiwa = io::read_robot_file(calib("lbr_iiwa14_r820.robot.toml"));
  iiwa.flange_sensor = mount;
  for (const RobotModel& model : {kr210_r2700(mount), permuted, iiwa}) {
    for (int trial = 0; trial < 5; ++trial) {
      std::array<double, kMaxJoints> q{};
      for (int k = 0; k < model.joint_count; ++k) q[k] = angle(rng);
      const std::span<const double> joints(q.data(), static_cast<std::size_t>(model.joint_count));
      Eigen::Matrix<double, 6, kMaxJoints> J;
      sensor_jacobian(model, joints, J);
      const Eigen::Matrix3d R_t = sensor_pose(model, joints).R.transpose();
      constexpr double h = 1e-6;
      for (int k = 0; k < model.joint_count; ++k) {
        std::array<double, kMaxJoints> qa = q, qb = q;
        qa[k] += h;
        qb[k] -= h;
        const Pose a = sensor_pose(model, std::span<const double>(qa.data(), joints.size()));
        const Pose b = sensor_pose(model, std::span<const double>(qb.data(), joints.size()));
        const Eigen::Vector3d v = (a.p_m - b.p_m) / (2 * h);
        const Eigen::Matrix3d W = (a.R - b.R) / (2 * h) * R_t;
        const Eigen::Vector3d w(W(2, 1), W(0, 2), W(1, 0));
        EXPECT_LT((J.col(k).head<3>() - v).norm(), 1e-7) << "joint " << k;
        EXPECT_LT((J.col(k).tail<3>() - w).norm(), 1e-7) << "joint " << k;
      }
      for (int k = model.joint_count; k < kMaxJoints; ++k) EXPECT_EQ(J.col(k).norm(), 0.0);
    }
  }
}

}  // namespace
}  // namespace zerog::robot
