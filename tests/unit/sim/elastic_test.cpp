// The elastic robot of the simulator (issue 28, item 1; host/sim/include/zerog/sim/elastic.hpp):
// the joint torques of a flange wrench, the static sag, the ringing after a move at the joint's
// mode and damping, and a run of zerog sim --real-robot against the rigid run (the log keeps the
// motor side, the clean log and the physics the link side).
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <numbers>
#include <random>

#include "zerog/formats/robot_toml.hpp"
#include "zerog/sim/elastic.hpp"
#include "zerog/sim/simulator.hpp"

namespace zerog::sim {
namespace {

// The work F·dp + M·dθ of a force F at a point fixed on the flange (`point_flange_m`, flange
// frame) and a torque M, for joint i's central step from q − h to q + h (h = 1e-5 rad).
double virtual_work(const JointVector& q, std::size_t i, const Eigen::Vector3d& F,
                    const Eigen::Vector3d& M, const Eigen::Vector3d& point_flange_m) {
  constexpr double h = 1e-5;
  JointVector lo = q, hi = q;
  lo[i] -= h;
  hi[i] += h;
  const robot::Pose a = robot::flange_pose(kr210(), lo), b = robot::flange_pose(kr210(), hi);
  const Eigen::AngleAxisd turn(b.R * a.R.transpose());
  const Eigen::Vector3d dp = (b.p_m + b.R * point_flange_m) - (a.p_m + a.R * point_flange_m);
  return F.dot(dp) + M.dot(turn.angle() * turn.axis());
}

// τ = Jᵀ w is the virtual work of the wrench: for a small joint step dq, τ·dq equals the work
// F·dp + M·dθ of the flange's displacement.
TEST(ElasticJointTorques, AreTheVirtualWorkOfTheFlangeWrench) {
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    JointVector q = kr210_home();
    for (double& v : q) v += 0.5 * u(rng);
    const Eigen::Vector3d F(300 * u(rng), 300 * u(rng), 900 * u(rng));
    const Eigen::Vector3d M(80 * u(rng), 80 * u(rng), 80 * u(rng));
    const JointVector tau = joint_torques(q, F, M);
    for (std::size_t i = 0; i < 6; ++i) {
      const double work = virtual_work(q, i, F, M, Eigen::Vector3d::Zero());
      EXPECT_NEAR(tau[i] * 2e-5, work, 1e-8 * std::abs(work) + 1e-10)
          << "joint " << i + 1 << ", trial " << trial;
    }
  }
}

// A wrench on the payload loads the joints by the virtual work of its point on the payload: for a
// small joint step, τ·dq is F·dp + M·dθ of the point (on the flange, turned with it) where the
// force acts; payload_load adds the weight and each push, given in B or in S.
TEST(ElasticJointTorques, AWrenchOnThePayloadIsTheVirtualWorkOfItsPoint) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Eigen::Vector3d p_flange_sensor(0.01, -0.02, 0.09);
  const Eigen::Matrix3d R_flange_sensor =
      Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.2, -0.5, 1.0).normalized()).toRotationMatrix();
  for (int trial = 0; trial < 10; ++trial) {
    JointVector q = kr210_home();
    for (double& v : q) v += 0.5 * u(rng);
    const Eigen::Vector3d F(60 * u(rng), 60 * u(rng), 60 * u(rng));
    const Eigen::Vector3d M(10 * u(rng), 10 * u(rng), 10 * u(rng));
    const Eigen::Vector3d point(0.3 * u(rng), 0.3 * u(rng), 0.2 + 0.2 * u(rng));
    const Eigen::Matrix3d R_base_sensor = robot::flange_pose(kr210(), q).R * R_flange_sensor;
    const JointVector tau = wrench_load(q, R_base_sensor, p_flange_sensor, F, point, M);
    for (std::size_t i = 0; i < 6; ++i) {
      const double work = virtual_work(q, i, F, M, p_flange_sensor + R_flange_sensor * point);
      EXPECT_NEAR(tau[i] * 2e-5, work, 1e-7 * std::abs(work) + 1e-10)
          << "joint " << i + 1 << ", trial " << trial;
    }
    // The same push given in S, and the weight beside it.
    SimConfig c = default_sim_config(1);
    c.p_flange_sensor_m = p_flange_sensor;
    ExternalWrench in_sensor;
    in_sensor.point_sensor_m = point;
    in_sensor.force_sensor_N = R_base_sensor.transpose() * F;
    in_sensor.torque_sensor_Nm = R_base_sensor.transpose() * M;
    const JointVector weight =
        weight_load(q, R_base_sensor, p_flange_sensor, c.payload.com_sensor_m, c.payload.mass_kg);
    const JointVector both = payload_load(q, R_base_sensor, c, {&in_sensor, 1});
    const JointVector none = payload_load(q, R_base_sensor, c, {});
    for (std::size_t i = 0; i < 6; ++i) {
      EXPECT_NEAR(both[i], weight[i] + tau[i], 1e-9 * std::abs(weight[i]) + 1e-9) << i + 1;
      EXPECT_EQ(none[i], weight[i]) << i + 1;
    }
  }
}

// A 1 kN weight hanging at the flange in the home pose loads A2 and A3 (horizontal axes) and
// not A1 (vertical): a check of the sign and the axis, not only of the algebra.
TEST(ElasticJointTorques, AWeightAtHomeLoadsTheHorizontalAxesOnly) {
  const JointVector tau =
      joint_torques(kr210_home(), Eigen::Vector3d(0, 0, -1000), Eigen::Vector3d::Zero());
  EXPECT_NEAR(tau[0], 0.0, 1e-6);
  // At home the flange is 1.765 m from A1 and 1.415 m beyond A2: about 1.4 kN·m on A2.
  EXPECT_GT(std::abs(tau[1]), 1300.0);
  EXPECT_GT(std::abs(tau[2]), 1000.0);
}

// The wrist's default modes are the stiffness over the 100 kg payload's inertia about each wrist
// axis at home (J = uᵀ I_c u + m |(c − P) × u|², P on the axis): within 10 %.
TEST(ElasticDefaults, WristModesAreTheStiffnessOverThePayloadsInertia) {
  const SimConfig c = default_sim_config(1);
  const ElasticityConfig e = kr210_elasticity();
  const robot::Pose f = robot::flange_pose(kr210(), kr210_home());
  const Eigen::Vector3d z = f.R.col(2);
  const Eigen::Vector3d wrist = f.p_m - 0.215 * z;  // A4/A5 axes meet here
  const Eigen::Vector3d com = f.p_m + f.R * (c.p_flange_sensor_m + c.payload.com_sensor_m);
  const Eigen::Matrix3d I = f.R * c.payload.inertia_com_sensor_kgm2 * f.R.transpose();
  // At home A4 and A6 lie along the flange's z (through the wrist centre), A5 along base y.
  const std::array<std::pair<Eigen::Vector3d, Eigen::Vector3d>, 3> axes = {
      {{wrist, z}, {wrist, Eigen::Vector3d::UnitY()}, {f.p_m, z}}};
  for (std::size_t k = 0; k < 3; ++k) {
    const auto& [p, u] = axes[k];
    const double J = u.dot(I * u) + c.payload.mass_kg * ((com - p).cross(u)).squaredNorm();
    const JointElasticity& j = e.joints[3 + k];
    const double f_hz = std::sqrt(j.stiffness_Nm_per_rad / J) / (2.0 * std::numbers::pi);
    EXPECT_NEAR(j.mode_hz, f_hz, 0.1 * f_hz) << "A" << 4 + k << ": J = " << J << " kg m^2";
  }
}

// The robot file is the one description: the simulator's defaults are its values.
TEST(ElasticDefaults, AreTheRobotFilesValues) {
  const robot::RobotModel file = formats::read_robot_file(std::string(ZEROG_SOURCE_DIR) +
                                                          "/calib/robots/kr210_r2700.robot.toml");
  const ElasticityConfig e = kr210_elasticity();
  ASSERT_EQ(file.joint_count, 6);
  ASSERT_TRUE(file.elastic());
  for (std::size_t i = 0; i < 6; ++i) {
    EXPECT_EQ(file.elasticity[i].stiffness_Nm_per_rad, e.joints[i].stiffness_Nm_per_rad) << i;
    EXPECT_EQ(file.elasticity[i].mode_hz, e.joints[i].mode_hz) << i;
    EXPECT_EQ(file.elasticity[i].damping_ratio, e.joints[i].damping_ratio) << i;
  }
  // A file without elasticity gives none; one with it for some joints only is refused.
  EXPECT_FALSE(formats::read_robot_file(std::string(ZEROG_SOURCE_DIR) +
                                        "/calib/robots/lbr_iiwa14_r820.robot.toml")
                   .elastic());
  const std::string path = ::testing::TempDir() + "/half_elastic.robot.toml";
  {
    std::ofstream f(path);
    f << "format = \"zerog-robot\"\nversion = 1\n[robot]\nconvention = \"dh\"\n"
         "[[robot.joint]]\na_m = 0.1\nalpha_deg = 0\nd_m = 0.2\nstiffness_Nm_per_rad = 1e5\n"
         "mode_hz = 5\ndamping_ratio = 0.1\n"
         "[[robot.joint]]\na_m = 0.1\nalpha_deg = 0\nd_m = 0.2\n";
  }
  try {
    (void)formats::read_robot_file(path);
    FAIL() << "half an elastic robot was read";
  } catch (const std::exception& error) {
    EXPECT_NE(std::string(error.what()).find("robot.joint[2].stiffness_Nm_per_rad"),
              std::string::npos)
        << error.what();
  }
}

PtpTrajectory one_move(double a2_deg) {
  const JointVector home = kr210_home();
  JointVector there = home;
  there[1] += a2_deg * std::numbers::pi / 180.0;
  return PtpTrajectory({home, there}, kr210_ptp_limits(0.3), 3.0);
}

// At rest under a constant load the link sags by τ/k; after a move it rings at the joint's mode
// with the joint's damping (zero crossings and logarithmic decrement of δ).
TEST(ElasticArm, SagsByTheLoadOverTheStiffnessAndRingsAtItsMode) {
  ElasticityConfig c;
  c.enabled = true;
  c.joints[1] = {2.0e6, 8.0, 0.04};
  const PtpTrajectory path = one_move(20.0);
  ElasticArm arm(c);
  JointVector tau{};
  tau[1] = 1500.0;
  arm.settle(0.0, tau);
  EXPECT_DOUBLE_EQ(arm.deflection_rad()[1], 1500.0 / 2.0e6);
  // The move, then its dwell: sample δ − τ/k every millisecond after the motion ends.
  double t = 0.0;
  bool moved = false;  // through the first dwell, the move, to the dwell after it
  while (!moved || path.at(t).qd_radps[1] != 0.0) {
    t += 0.001;
    arm.advance(t, path, tau);
    moved = moved || path.at(t).qd_radps[1] != 0.0;
    ASSERT_LT(t, 60.0);
  }
  std::vector<double> d;
  for (int k = 0; k < 1500; ++k) {
    t += 0.001;
    arm.advance(t, path, tau);
    d.push_back(arm.deflection_rad()[1] - 1500.0 / 2.0e6);
  }
  std::vector<double> crossings;
  for (std::size_t k = 1; k < d.size(); ++k)
    if ((d[k - 1] < 0.0) != (d[k] < 0.0))
      crossings.push_back(static_cast<double>(k - 1) + d[k - 1] / (d[k - 1] - d[k]));
  ASSERT_GE(crossings.size(), 10u);
  const double period_ms = 2.0 * (crossings[9] - crossings[1]) / 8.0;
  const double f_damped = 8.0 * std::sqrt(1.0 - 0.04 * 0.04);
  EXPECT_NEAR(1000.0 / period_ms, f_damped, 0.02 * f_damped);
  // Peaks one period apart: ln(a_k / a_{k+1}) = 2π ζ / sqrt(1 − ζ²).
  double a0 = 0.0, a1 = 0.0;
  const auto p = static_cast<std::size_t>(std::lround(period_ms));
  for (std::size_t k = 0; k < p; ++k) a0 = std::max(a0, std::abs(d[k]));
  for (std::size_t k = p; k < 2 * p; ++k) a1 = std::max(a1, std::abs(d[k]));
  const double zeta = std::log(a0 / a1) / (2.0 * std::numbers::pi);
  EXPECT_NEAR(zeta, 0.04, 0.01);
  // A rigid joint (stiffness 0) never deflects.
  EXPECT_EQ(arm.deflection_rad()[0], 0.0);
}

// zerog sim --real-robot against the rigid run of the same seed: the logged joints are the motor
// side (the same path, quantised to the encoder's step), the clean log's joints the link side
// (sagging by tenths of a milliradian under 100 kg), and the true model on the logged pose no
// longer reaches the sensor floor while on the clean log's it does.
// The four random poses both RealRobot runs follow.
std::vector<JointVector> four_poses() {
  DesignOptions o;
  o.kind = DesignKind::random;
  o.points = 4;
  o.seed = 3;
  return make_design(o).points_rad;
}

TEST(RealRobot, LogsTheMotorSideAndMovesThePayloadWithTheLink) {
  SimConfig rigid = default_sim_config(5);
  rigid.duration_limit_s = 30.0;
  SimConfig real = rigid;
  make_real_robot(real, true);
  const auto points = four_poses();
  const SimOutput a = RigSimulator(rigid, points).run();
  const SimOutput b = RigSimulator(real, points).run();
  ASSERT_EQ(a.log.samples.size(), b.log.samples.size());
  double max_enc = 0.0, max_sag = 0.0;
  for (std::size_t k = 0; k < a.log.samples.size(); ++k)
    for (std::size_t i = 0; i < 6; ++i) {
      max_enc = std::max(max_enc,
                         std::abs(b.log.samples[k].joints_rad[i] - a.log.samples[k].joints_rad[i]));
      max_sag = std::max(
          max_sag, std::abs(b.clean_log.samples[k].joints_rad[i] - a.log.samples[k].joints_rad[i]));
    }
  EXPECT_LE(max_enc, 0.5 * real.noise.encoder_rad + 1e-15);
  EXPECT_GT(max_sag, 1e-4);
  EXPECT_LT(max_sag, 1e-2);
  EXPECT_TRUE(b.truth.extra.contains("elastic_robot"));
  EXPECT_TRUE(b.truth.extra["noise"].contains("imu_bias"));
  EXPECT_FALSE(a.truth.extra.contains("elastic_robot"));
}

// A contact on the payload (zerog sim --contact) loads the elastic arm as the weight does: the
// link side of the run with a 150 N push held over it differs from the run without by the push's
// own sag, τ_push/k at each row (quasi-static: the path and its ringing are the same in both).
TEST(RealRobot, AContactLoadsTheArmAsTheWeightDoes) {
  SimConfig plain = default_sim_config(5);
  plain.duration_limit_s = 20.0;
  make_real_robot(plain, false);
  SimConfig pushed = plain;
  Contact k;
  k.start_s = 0.0;
  k.duration_s = 30.0;
  k.base_frame = true;
  k.wrench << 60.0, 120.0, -60.0, 0.0, 0.0, 15.0;
  pushed.contacts = {k};
  const auto points = four_poses();
  const RigSimulator sim(plain, points);
  const SimOutput a = sim.run();
  const SimOutput b = RigSimulator(pushed, points).run();
  ASSERT_EQ(a.clean_log.samples.size(), b.clean_log.samples.size());
  double worst = 0.0, largest = 0.0;
  for (std::size_t r = 200; r < a.clean_log.samples.size(); r += 25) {  // from 2.4 s
    const JointVector& q = b.clean_log.samples[r].joints_rad;
    const Measurement m = sim.measure(sim.trajectory().at(a.clean_log.samples[r].t_s), 0.0);
    const JointVector tau =
        wrench_load(q, m.R_base_sensor, plain.p_flange_sensor_m, k.wrench.head<3>(),
                    Eigen::Vector3d::Zero(), k.wrench.tail<3>());
    for (std::size_t i = 0; i < 6; ++i) {
      const double sag = tau[i] / plain.elastic.joints[i].stiffness_Nm_per_rad;
      largest = std::max(largest, std::abs(sag));
      worst = std::max(worst, std::abs(q[i] - a.clean_log.samples[r].joints_rad[i] - sag));
    }
  }
  EXPECT_GT(largest, 1e-5);  // rad
  EXPECT_LT(worst, 0.1 * largest);
}

}  // namespace
}  // namespace zerog::sim
