// The PTP trajectory of the simulated KR 210: its derivatives, speed and acceleration limits and
// its dwells.
#include <gtest/gtest.h>

#include <cmath>

#include "zerog/sim/robot.hpp"
#include "zerog/sim/trajectory.hpp"

namespace zerog::sim {
namespace {

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
