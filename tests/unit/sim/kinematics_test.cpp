// KR 210 R2700 forward kinematics and the analytic flange twist against finite differences.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <random>

#include "zerog/sim/kinematics.hpp"
#include "zerog/sim/trajectory.hpp"

namespace zerog::sim {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

Eigen::Vector3d rotation_log(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

TEST(Kinematics, HomePose) {
  const FlangePose f = forward_kinematics(kr210_home());
  // A1 axis to A2: 0.350 forward, 0.675 up; upper arm 1.150 up; forearm 1.200 forward and 0.041
  // below the A3 axis; flange 0.215 beyond the wrist centre.
  EXPECT_TRUE(f.p_base_flange_m.isApprox(Eigen::Vector3d(1.765, 0.0, 1.784), 1e-12))
      << f.p_base_flange_m.transpose();
  Eigen::Matrix3d R_expected;
  R_expected << 0, 0, 1, 0, 1, 0, -1, 0, 0;  // Ry(+90°): flange z forward, x down
  EXPECT_TRUE(f.R_base_flange.isApprox(R_expected, 1e-12)) << f.R_base_flange;
}

TEST(Kinematics, KnownPoses) {
  JointVector q = kr210_home();
  q[0] = 90 * kDeg;  // A1 positive turns clockwise seen from above: +x goes to −y
  EXPECT_TRUE(
      forward_kinematics(q).p_base_flange_m.isApprox(Eigen::Vector3d(0.0, -1.765, 1.784), 1e-12));
  q = kr210_home();
  q[4] = 90 * kDeg;  // A5 = +90°: flange points down from the wrist centre
  const FlangePose down = forward_kinematics(q);
  EXPECT_TRUE(down.p_base_flange_m.isApprox(Eigen::Vector3d(1.55, 0.0, 1.569), 1e-12));
  EXPECT_TRUE(down.R_base_flange.col(2).isApprox(Eigen::Vector3d(0, 0, -1), 1e-12));
  q = kr210_home();
  q[2] = 0.0;  // A3 = 0: forearm straight up, the 41 mm offset now points forward
  EXPECT_TRUE(
      forward_kinematics(q).p_base_flange_m.isApprox(Eigen::Vector3d(0.391, 0.0, 3.24), 1e-12));
  q = kr210_home();
  q[3] = 90 * kDeg;  // A4 and A6 turn about the forearm/flange axis: position unchanged
  q[5] = -40 * kDeg;
  EXPECT_TRUE(
      forward_kinematics(q).p_base_flange_m.isApprox(Eigen::Vector3d(1.765, 0.0, 1.784), 1e-12));
}

TEST(Kinematics, AnalyticTwistMatchesFiniteDifferences) {
  std::mt19937 gen(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const JointLimits lim = kr210_table4_limits();
  for (int trial = 0; trial < 50; ++trial) {
    JointVector q{}, qd{}, qdd{};
    for (int j = 0; j < 6; ++j) {
      q[j] = 0.5 * (lim.lower_rad[j] + lim.upper_rad[j]) +
             0.5 * u(gen) * (lim.upper_rad[j] - lim.lower_rad[j]);
      qd[j] = u(gen);
      qdd[j] = 2.0 * u(gen);
    }
    // q(t) = q + qd t + qdd t²/2, so q̇(0) = qd and q̈(0) = qdd.
    auto at = [&](double t, JointVector& qt, JointVector& qdt) {
      for (int j = 0; j < 6; ++j) {
        qt[j] = q[j] + qd[j] * t + 0.5 * qdd[j] * t * t;
        qdt[j] = qd[j] + qdd[j] * t;
      }
    };
    const double h = 1e-5;
    JointVector qp{}, qm{}, qdp{}, qdm{};
    at(h, qp, qdp);
    at(-h, qm, qdm);
    const FlangeMotion m = flange_motion(q, qd, qdd);
    const FlangePose p0 = forward_kinematics(q), pp = forward_kinematics(qp),
                     pm = forward_kinematics(qm);
    EXPECT_TRUE(m.p_base_flange_m.isApprox(p0.p_base_flange_m, 1e-14));
    EXPECT_TRUE(m.R_base_flange.isApprox(p0.R_base_flange, 1e-14));
    const Eigen::Vector3d v_fd = (pp.p_base_flange_m - pm.p_base_flange_m) / (2 * h);
    const Eigen::Vector3d a_fd =
        (pp.p_base_flange_m - 2 * p0.p_base_flange_m + pm.p_base_flange_m) / (h * h);
    const Eigen::Vector3d w_fd =
        rotation_log(pp.R_base_flange * pm.R_base_flange.transpose()) / (2 * h);
    EXPECT_LT((m.v_flange_base_mps - v_fd).norm(), 1e-8);
    EXPECT_LT((m.a_flange_base_mps2 - a_fd).norm(), 2e-3);  // second difference: ~ε/h²
    EXPECT_LT((m.omega_base_radps - w_fd).norm(), 1e-8);
    // ω̇ against the central difference of the (just verified) analytic ω along the path.
    const FlangeMotion mp = flange_motion(qp, qdp, qdd), mm = flange_motion(qm, qdm, qdd);
    const Eigen::Vector3d wd_fd = (mp.omega_base_radps - mm.omega_base_radps) / (2 * h);
    EXPECT_LT((m.omega_dot_base_radps2 - wd_fd).norm(), 1e-7);
    const Eigen::Vector3d a_fd2 = (mp.v_flange_base_mps - mm.v_flange_base_mps) / (2 * h);
    EXPECT_LT((m.a_flange_base_mps2 - a_fd2).norm(), 1e-7);
    // A body point: acceleration_of matches the second difference of its position.
    const Eigen::Vector3d lever_flange(0.03, -0.02, 0.31);
    auto point = [&](const FlangePose& f) {
      return Eigen::Vector3d(f.p_base_flange_m + f.R_base_flange * lever_flange);
    };
    const Eigen::Vector3d ap_fd = (point(pp) - 2 * point(p0) + point(pm)) / (h * h);
    EXPECT_LT((m.acceleration_of(m.R_base_flange * lever_flange) - ap_fd).norm(), 2e-3);
  }
}

TEST(Kinematics, WristInverseKinematicsReproducesTheOrientation) {
  std::mt19937 gen(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const JointLimits lim = kr210_table4_limits();
  for (int trial = 0; trial < 200; ++trial) {
    JointVector q{};
    for (int j = 0; j < 6; ++j)
      q[j] = 0.5 * (lim.lower_rad[j] + lim.upper_rad[j]) +
             0.5 * u(gen) * (lim.upper_rad[j] - lim.lower_rad[j]);
    const Eigen::Matrix3d R = forward_kinematics(q).R_base_flange;
    const auto solutions = wrist_inverse_kinematics(q, R);
    EXPECT_GE(solutions[0][4], 0.0);
    EXPECT_LE(solutions[1][4], 0.0);
    bool found_q = false;
    for (const JointVector& s : solutions) {
      for (int j = 0; j < 3; ++j) EXPECT_EQ(s[j], q[j]);  // the arm stays
      EXPECT_LT((forward_kinematics(s).R_base_flange - R).cwiseAbs().maxCoeff(), 1e-9);
      bool same = true;
      for (int j = 3; j < 6; ++j)
        same = same && std::abs(std::remainder(s[j] - q[j], 2 * std::numbers::pi)) < 1e-9;
      found_q = found_q || same;
    }
    EXPECT_TRUE(found_q) << "trial " << trial;  // one of the two is the pose we started from
  }
}

TEST(Kinematics, WristInverseKinematicsAtTheSingularity) {
  JointVector q = kr210_home();
  q[3] = 30 * kDeg;
  q[4] = 0.0;  // A4 and A6 turn about the same axis: only their sum is determined
  q[5] = -70 * kDeg;
  const Eigen::Matrix3d R = forward_kinematics(q).R_base_flange;
  JointVector reference = q;
  reference[3] = 10 * kDeg;  // A4 is kept from the reference
  const auto solutions = wrist_inverse_kinematics(reference, R);
  for (const JointVector& s : solutions) {
    EXPECT_NEAR(s[3], 10 * kDeg, 1e-12);
    EXPECT_NEAR(s[4], 0.0, 1e-12);
    EXPECT_NEAR(s[5], -50 * kDeg, 1e-9);  // A4 + A6 unchanged
    EXPECT_LT((forward_kinematics(s).R_base_flange - R).cwiseAbs().maxCoeff(), 1e-9);
  }
  for (double a5 : {1e-11, 1e-8, 1e-5}) {  // close to it: still exact
    q[4] = a5;
    const Eigen::Matrix3d Rn = forward_kinematics(q).R_base_flange;
    for (const JointVector& s : wrist_inverse_kinematics(q, Rn))
      EXPECT_LT((forward_kinematics(s).R_base_flange - Rn).cwiseAbs().maxCoeff(), 1e-9) << a5;
  }
}

TEST(Trajectory, ProfileDerivativesAndLimits) {
  const PtpLimits lim = kr210_ptp_limits(0.3);
  const JointLimits range = kr210_table4_limits();
  std::vector<JointVector> points = {kr210_home(), range.lower_rad, range.upper_rad, kr210_home()};
  points.push_back(points.back());
  points.back()[5] += 0.01;  // a tiny move: acceleration-limited branch
  const PtpTrajectory traj(points, lim, 2.0);
  EXPECT_NEAR(traj.at(0.0).q_rad[1], kr210_home()[1], 0.0);
  EXPECT_TRUE(traj.is_dwell(1.0));
  const double h = 1e-5;
  double max_ratio_v = 0.0, max_ratio_a = 0.0;
  for (double t = 0.0; t < traj.duration_s(); t += 0.0137) {
    const JointState s = traj.at(t), sp = traj.at(t + h), sm = traj.at(t - h);
    for (int j = 0; j < 6; ++j) {
      if (t > h) {
        EXPECT_NEAR(s.qd_radps[j], (sp.q_rad[j] - sm.q_rad[j]) / (2 * h), 1e-7) << t;
        EXPECT_NEAR(s.qdd_radps2[j], (sp.qd_radps[j] - sm.qd_radps[j]) / (2 * h), 1e-5) << t;
      }
      max_ratio_v = std::max(max_ratio_v, std::abs(s.qd_radps[j]) / lim.max_speed_radps[j]);
      max_ratio_a = std::max(max_ratio_a, std::abs(s.qdd_radps2[j]) / lim.max_accel_radps2[j]);
    }
  }
  EXPECT_LE(max_ratio_v, 1.0 + 1e-9);
  EXPECT_GT(max_ratio_v, 0.99);  // the slowest joint runs at full speed
  EXPECT_LE(max_ratio_a, 1.0 + 1e-9);
  // Arrives at each point and stays there for the dwell.
  for (std::size_t k = 0; k + 1 < points.size(); ++k) {
    const double arrive = traj.move_start_s(k) + traj.move(k).duration_s;
    const JointState s = traj.at(arrive + 1.0);
    for (int j = 0; j < 6; ++j) {
      EXPECT_NEAR(s.q_rad[j], points[k + 1][j], 1e-12);
      EXPECT_EQ(s.qd_radps[j], 0.0);
    }
  }
  EXPECT_NEAR(traj.duration_s(),
              traj.move_start_s(points.size() - 2) + traj.move(points.size() - 2).duration_s + 2.0,
              1e-12);
}

}  // namespace
}  // namespace zerog::sim
