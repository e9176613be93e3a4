// zerog::robot kinematics: the 7-axis LBR iiwa file against hand-computed poses, both DH
// conventions, the joint order, the flange's motion against finite differences of its pose, the
// Jacobian, the wrist's inverse kinematics, the model checks and the file reader's refusals, and
// no allocation. The KR 210 R2700 file's own checks are in kr210_file_test.cpp.
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
#include "zerog/sim/robot.hpp"
#include "zerog/sim/trajectory.hpp"

namespace zerog::robot {
namespace {

namespace fs = std::filesystem;
constexpr double kPi = std::numbers::pi;

fs::path calib(const char* name) { return fs::path(ZEROG_SOURCE_DIR) / "calib/robots" / name; }

double rotation_error_rad(const Eigen::Matrix3d& A, const Eigen::Matrix3d& B) {
  return Eigen::AngleAxisd(A.transpose() * B).angle();
}

// LBR iiwa 14 R820 (modified DH), poses computed by hand from the link lengths 0.36, 0.42, 0.40,
// 0.126 m: joints 2, 4, 6 turn about +y of the base when the arm is straight, joints 1, 3, 5, 7
// about z.
TEST(RobotForwardKinematics, SevenAxisIiwaAtHandComputedPoses) {
  const RobotModel model = formats::read_robot_file(calib("lbr_iiwa14_r820.robot.toml"));
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
  const RobotModel dh = formats::kr210_r2700();
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
  RobotModel swapped = formats::kr210_r2700();
  // The recording lists A6 first, then A1..A5.
  for (int i = 0; i < 6; ++i) swapped.input_index[i] = (i + 1) % 6;
  ASSERT_TRUE(validate(swapped).ok());
  const std::array<double, 6> q = {0.1, -1.2, 1.4, 0.3, -0.5, 0.7};
  const std::array<double, 6> recorded = {q[5], q[0], q[1], q[2], q[3], q[4]};
  const Pose a = flange_pose(formats::kr210_r2700(), q), b = flange_pose(swapped, recorded);
  EXPECT_LT((a.p_m - b.p_m).norm(), 1e-15);
}

TEST(RobotModelValidate, NamesTheFaultyField) {
  RobotModel m = formats::kr210_r2700();
  EXPECT_TRUE(validate(m).ok());
  m.joint_count = 9;
  EXPECT_EQ(validate(m).setting(), "joint_count");
  m = formats::kr210_r2700();
  m.joints[2].sign = 0.5;
  zerog::Status s = validate(m);
  EXPECT_EQ(s.code(), zerog::StatusCode::invalid_setting);
  EXPECT_EQ(s.setting(), "joints[2].sign");
  EXPECT_EQ(s.message(), "must be +1 or -1");
  EXPECT_EQ(s.text(), "joints[2].sign: must be +1 or -1");
  m = formats::kr210_r2700();
  m.input_index[1] = 0;
  EXPECT_EQ(validate(m).setting(), "input_index[1]");
  m = formats::kr210_r2700();
  m.joints[4].d_m = std::nan("");
  s = validate(m);
  EXPECT_EQ(s.setting(), "joints[4]");
  EXPECT_EQ(s.message(), "has a value that is not a finite number");
  m = formats::kr210_r2700();
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
      formats::read_robot_file(file);
    } catch (const formats::InputError& e) {
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
  const RobotModel model = formats::kr210_r2700();
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
  RobotModel permuted = formats::kr210_r2700(mount);
  permuted.input_index = {5, 4, 3, 2, 1, 0, 6, 7};
  RobotModel iiwa = formats::read_robot_file(calib("lbr_iiwa14_r820.robot.toml"));
  iiwa.flange_sensor = mount;
  for (const RobotModel& model : {formats::kr210_r2700(mount), permuted, iiwa}) {
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

Eigen::Vector3d rotation_log(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

// flange_motion against finite differences of flange_pose along q(t) = q + q̇ t + q̈ t²/2, on the
// KR 210 (standard DH), the same with the recorded joints in reverse order, and the iiwa
// (modified DH, 7 joints) with a flange frame off its last DH frame; its pose is flange_pose's to
// the last bit.
TEST(RobotFlangeMotion, MatchesFiniteDifferencesOfThePose) {
  RobotModel permuted = formats::kr210_r2700();
  permuted.input_index = {5, 4, 3, 2, 1, 0, 6, 7};
  RobotModel iiwa = formats::read_robot_file(calib("lbr_iiwa14_r820.robot.toml"));
  iiwa.last_flange.p_m = {0.02, -0.01, 0.05};
  iiwa.last_flange.R =
      Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, -2, 1).normalized()).toRotationMatrix();
  std::mt19937 gen(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const RobotModel& model : {formats::kr210_r2700(), permuted, iiwa}) {
    const auto n = static_cast<std::size_t>(model.joint_count);
    for (int trial = 0; trial < 30; ++trial) {
      std::array<double, kMaxJoints> q{}, qd{}, qdd{};
      for (std::size_t j = 0; j < n; ++j) {
        q[j] = 2.0 * u(gen);
        qd[j] = u(gen);
        qdd[j] = 2.0 * u(gen);
      }
      // q(t) = q + qd t + qdd t²/2, so q̇(0) = qd and q̈(0) = qdd.
      auto at = [&](double t, std::array<double, kMaxJoints>& qt,
                    std::array<double, kMaxJoints>& qdt) {
        for (std::size_t j = 0; j < n; ++j) {
          qt[j] = q[j] + qd[j] * t + 0.5 * qdd[j] * t * t;
          qdt[j] = qd[j] + qdd[j] * t;
        }
      };
      const auto span = [n](const std::array<double, kMaxJoints>& v) {
        return std::span<const double>(v.data(), n);
      };
      const double h = 1e-5;
      std::array<double, kMaxJoints> qp{}, qm{}, qdp{}, qdm{};
      at(h, qp, qdp);
      at(-h, qm, qdm);
      const FlangeMotion m = flange_motion(model, span(q), span(qd), span(qdd));
      const Pose p0 = flange_pose(model, span(q)), pp = flange_pose(model, span(qp)),
                 pm = flange_pose(model, span(qm));
      EXPECT_EQ(m.p_base_flange_m, p0.p_m);
      EXPECT_EQ(m.R_base_flange, p0.R);
      const Eigen::Vector3d v_fd = (pp.p_m - pm.p_m) / (2 * h);
      const Eigen::Vector3d a_fd = (pp.p_m - 2 * p0.p_m + pm.p_m) / (h * h);
      const Eigen::Vector3d w_fd = rotation_log(pp.R * pm.R.transpose()) / (2 * h);
      EXPECT_LT((m.v_flange_base_mps - v_fd).norm(), 1e-8);
      EXPECT_LT((m.a_flange_base_mps2 - a_fd).norm(), 2e-3);  // second difference: ~ε/h²
      EXPECT_LT((m.omega_base_radps - w_fd).norm(), 1e-8);
      // ω̇ and a against the central differences of the (just verified) analytic ω and v.
      const FlangeMotion mp = flange_motion(model, span(qp), span(qdp), span(qdd));
      const FlangeMotion mm = flange_motion(model, span(qm), span(qdm), span(qdd));
      const Eigen::Vector3d wd_fd = (mp.omega_base_radps - mm.omega_base_radps) / (2 * h);
      EXPECT_LT((m.omega_dot_base_radps2 - wd_fd).norm(), 1e-7);
      const Eigen::Vector3d a_fd2 = (mp.v_flange_base_mps - mm.v_flange_base_mps) / (2 * h);
      EXPECT_LT((m.a_flange_base_mps2 - a_fd2).norm(), 1e-7);
      // A body point: acceleration_of matches the second difference of its position.
      const Eigen::Vector3d lever_flange(0.03, -0.02, 0.31);
      auto point = [&](const Pose& f) { return Eigen::Vector3d(f.p_m + f.R * lever_flange); };
      const Eigen::Vector3d ap_fd = (point(pp) - 2 * point(p0) + point(pm)) / (h * h);
      EXPECT_LT((m.acceleration_of(m.R_base_flange * lever_flange) - ap_fd).norm(), 2e-3);
    }
  }
}

TEST(RobotWristInverseKinematics, ReproducesTheOrientation) {
  const RobotModel model = formats::kr210_r2700();
  std::mt19937 gen(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const sim::JointLimits lim = sim::kr210_table4_limits();
  for (int trial = 0; trial < 200; ++trial) {
    sim::JointVector q{};
    for (int j = 0; j < 6; ++j)
      q[j] = 0.5 * (lim.lower_rad[j] + lim.upper_rad[j]) +
             0.5 * u(gen) * (lim.upper_rad[j] - lim.lower_rad[j]);
    const Eigen::Matrix3d R = flange_pose(model, q).R;
    const auto solutions = wrist_inverse_kinematics(model, q, R);
    EXPECT_GE(solutions[0][4], 0.0);
    EXPECT_LE(solutions[1][4], 0.0);
    bool found_q = false;
    for (const sim::JointVector& s : solutions) {
      for (int j = 0; j < 3; ++j) EXPECT_EQ(s[j], q[j]);  // the arm stays
      EXPECT_LT((flange_pose(model, s).R - R).cwiseAbs().maxCoeff(), 1e-9);
      bool same = true;
      for (int j = 3; j < 6; ++j)
        same = same && std::abs(std::remainder(s[j] - q[j], 2 * kPi)) < 1e-9;
      found_q = found_q || same;
    }
    EXPECT_TRUE(found_q) << "trial " << trial;  // one of the two is the pose we started from
  }
}

TEST(RobotWristInverseKinematics, AtTheSingularity) {
  const RobotModel model = formats::kr210_r2700();
  constexpr double kDeg = kPi / 180.0;
  sim::JointVector q = sim::kr210_home();
  q[3] = 30 * kDeg;
  q[4] = 0.0;  // A4 and A6 turn about the same axis: only their sum is determined
  q[5] = -70 * kDeg;
  const Eigen::Matrix3d R = flange_pose(model, q).R;
  sim::JointVector reference = q;
  reference[3] = 10 * kDeg;  // A4 is kept from the reference
  for (const sim::JointVector& s : wrist_inverse_kinematics(model, reference, R)) {
    EXPECT_NEAR(s[3], 10 * kDeg, 1e-12);
    EXPECT_NEAR(s[4], 0.0, 1e-12);
    EXPECT_NEAR(s[5], -50 * kDeg, 1e-9);  // A4 + A6 unchanged
    EXPECT_LT((flange_pose(model, s).R - R).cwiseAbs().maxCoeff(), 1e-9);
  }
  for (double a5 : {1e-11, 1e-8, 1e-5}) {  // close to it: still exact
    q[4] = a5;
    const Eigen::Matrix3d Rn = flange_pose(model, q).R;
    for (const sim::JointVector& s : wrist_inverse_kinematics(model, q, Rn))
      EXPECT_LT((flange_pose(model, s).R - Rn).cwiseAbs().maxCoeff(), 1e-9) << a5;
  }
}

}  // namespace
}  // namespace zerog::robot
