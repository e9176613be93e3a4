// derive_kinematics: exact on a pose stream of cubic motion with jittered stamps, close to the
// simulator's analytic twist on a real PTP trajectory from joints, the same from joints as from
// the poses they give, typed refusals, and no allocation.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>
#include <vector>

#include "alloc_count.hpp"
#include "zerog/formats/robot_toml.hpp"
#include "zerog/robot/derive_kinematics.hpp"
#include "zerog/sim/design.hpp"
#include "zerog/sim/trajectory.hpp"

namespace zerog::robot {
namespace {

// Rotation about a fixed axis by a cubic angle and a cubic path: every rotation vector relative
// to the centre is a cubic in time, so an order-3 fit is exact.
TEST(DeriveKinematics, ExactOnCubicPoseMotionWithJitteredStamps) {
  const Eigen::Vector3d axis = Eigen::Vector3d(0.3, -0.5, 0.8).normalized();
  const Eigen::Matrix3d R0 =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const auto theta = [](double t) { return 0.2 + 0.5 * t - 0.3 * t * t + 0.1 * t * t * t; };
  const auto theta_d = [](double t) { return 0.5 - 0.6 * t + 0.3 * t * t; };
  const auto theta_dd = [](double t) { return -0.6 + 0.6 * t; };
  const Eigen::Vector3d c0(1.0, -0.5, 1.2), c1(0.2, 0.1, -0.3), c2(-0.4, 0.3, 0.2),
      c3(0.05, -0.1, 0.02);
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> jitter(-0.25, 0.25);
  const double h = 0.004;
  const std::size_t n = 200;
  std::vector<double> t(n);
  std::vector<Pose> poses(n);
  for (std::size_t k = 0; k < n; ++k) {
    t[k] = (static_cast<double>(k) + jitter(rng)) * h;
    poses[k].R = R0 * Eigen::AngleAxisd(theta(t[k]), axis).toRotationMatrix();
    poses[k].p_m = c0 + c1 * t[k] + c2 * t[k] * t[k] + c3 * t[k] * t[k] * t[k];
  }
  DifferentiatorSettings settings;
  settings.sg = {6, 3};
  std::vector<SensorKinematics> out(n);
  ASSERT_TRUE(derive_kinematics(t, poses, settings, out).ok());
  for (std::size_t k = 0; k < n; ++k) {
    const double tk = t[k];
    EXPECT_LT((out[k].omega_sensor_radps - axis * theta_d(tk)).norm(), 1e-9) << k;
    EXPECT_LT((out[k].omega_dot_sensor_radps2 - axis * theta_dd(tk)).norm(), 1e-7) << k;
    const Eigen::Vector3d a = 2.0 * c2 + 6.0 * c3 * tk;
    EXPECT_LT((out[k].accel_base_mps2 - a).norm(), 1e-7) << k;
    EXPECT_LT((out[k].specific_force_sensor_mps2 -
               poses[k].R.transpose() * (a - settings.gravity_base_mps2))
                  .norm(),
              1e-7);
    EXPECT_EQ(out[k].centred, k >= 6 && k + 6 < n);
  }
}

struct PtpRun {
  std::vector<double> t;
  std::vector<double> joints;  // row-major, 6 a row
  std::vector<sim::JointState> truth;
};

PtpRun ptp_run(double period_s, double duration_s) {
  sim::DesignOptions o;
  o.kind = sim::DesignKind::random;
  o.points = 4;
  o.seed = 11;
  const sim::PtpTrajectory trajectory(sim::make_design(o).points_rad, sim::kr210_ptp_limits(0.3),
                                      0.5);
  PtpRun run;
  for (double t = 0.0; t < std::min(duration_s, trajectory.duration_s()); t += period_s) {
    run.t.push_back(t);
    const sim::JointState js = trajectory.at(t);
    run.truth.push_back(js);
    run.joints.insert(run.joints.end(), js.q_rad.begin(), js.q_rad.end());
  }
  return run;
}

// The analytic motion of S (flange_sensor: 0.06 m along the flange z) from the simulator.
struct Truth {
  Eigen::Vector3d omega_S, omega_dot_S, accel_B;
};
Truth truth_of(const sim::JointState& js, const RobotModel& model) {
  const FlangeMotion fm = flange_motion(model, js.q_rad, js.qd_radps, js.qdd_radps2);
  const Eigen::Matrix3d R_BS = fm.R_base_flange * model.flange_sensor.R;
  return {R_BS.transpose() * fm.omega_base_radps, R_BS.transpose() * fm.omega_dot_base_radps2,
          fm.acceleration_of(fm.R_base_flange * model.flange_sensor.p_m)};
}

TEST(DeriveKinematics, FromNoiseFreeJointsMatchesTheSimulatorsAnalyticMotion) {
  FrameTransform flange_sensor;
  flange_sensor.p_m = {0.0, 0.0, 0.06};
  const RobotModel model = formats::kr210_r2700(flange_sensor);
  const double h = 0.004;
  const PtpRun run = ptp_run(h, 30.0);
  DifferentiatorSettings settings;
  settings.sg = choose_sg_window(h, 5.0, 3, 2);
  std::vector<SensorKinematics> out(run.t.size());
  ASSERT_TRUE(derive_kinematics(model, run.t, run.joints, 6, settings, out).ok());
  double e_w = 0.0, e_wd = 0.0, e_a = 0.0, peak_wd = 0.0;
  std::size_t used = 0;
  for (std::size_t k = 0; k < out.size(); ++k) {
    if (!out[k].centred) continue;
    const Truth tr = truth_of(run.truth[k], model);
    e_w = std::max(e_w, (out[k].omega_sensor_radps - tr.omega_S).norm());
    e_wd = std::max(e_wd, (out[k].omega_dot_sensor_radps2 - tr.omega_dot_S).norm());
    e_a = std::max(e_a, (out[k].accel_base_mps2 - tr.accel_B).norm());
    peak_wd = std::max(peak_wd, tr.omega_dot_S.norm());
    ++used;
  }
  ASSERT_GT(used, 5000u);
  ASSERT_GT(peak_wd, 0.5);  // the run accelerates
  // What is left is the fit's bias on the PTP profile (its jerk steps at phase ends).
  EXPECT_LT(e_w, 1e-4);
  EXPECT_LT(e_wd, 0.05 * peak_wd);
  EXPECT_LT(e_a, 0.05);
  // The joint overload is the pose overload on forward-kinematics poses.
  std::vector<Pose> poses(out.size());
  for (std::size_t k = 0; k < out.size(); ++k) poses[k] = out[k].pose_base_sensor;
  std::vector<SensorKinematics> again(out.size());
  ASSERT_TRUE(derive_kinematics(run.t, poses, settings, again).ok());
  for (std::size_t k = 0; k < out.size(); k += 97)
    EXPECT_EQ(again[k].omega_dot_sensor_radps2, out[k].omega_dot_sensor_radps2);
}

TEST(DeriveKinematics, RefusesWithATypedStatus) {
  const RobotModel model = formats::kr210_r2700();
  DifferentiatorSettings settings;
  settings.sg = {3, 3};
  std::vector<double> t = {0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7};
  std::vector<double> q(t.size() * 6, 0.1);
  std::vector<SensorKinematics> out(t.size());
  EXPECT_TRUE(derive_kinematics(model, t, q, 6, settings, out).ok());
  std::vector<double> bad_t = t;
  bad_t[4] = bad_t[3];
  const DeriveStatus s = derive_kinematics(model, bad_t, q, 6, settings, out);
  EXPECT_EQ(s.code, DeriveError::time_order);
  EXPECT_EQ(s.sample, 4u);
  EXPECT_EQ(derive_kinematics(model, t, q, 5, settings, out).code, DeriveError::sizes);
  std::vector<SensorKinematics> short_out(3);
  EXPECT_EQ(derive_kinematics(model, std::span(t).first(3), std::span(q).first(18), 6, settings,
                              short_out)
                .code,
            DeriveError::too_short);
  settings.sg = {3, 5};
  EXPECT_EQ(derive_kinematics(model, t, q, 6, settings, out).code, DeriveError::settings);
  settings.sg = {3, 3};
  RobotModel broken = model;
  broken.joints[0].sign = 0.0;
  EXPECT_EQ(derive_kinematics(broken, t, q, 6, settings, out).code, DeriveError::robot_model);
}

TEST(DeriveKinematics, DoesNotAllocate) {
  const RobotModel model = formats::kr210_r2700();
  const PtpRun run = ptp_run(0.012, 3.0);
  DifferentiatorSettings settings;
  settings.sg = {8, 3};
  std::vector<SensorKinematics> out(run.t.size());
  test::AllocGuard guard("derive_kinematics");
  const DeriveStatus status = derive_kinematics(model, run.t, run.joints, 6, settings, out);
  guard.stop();
  EXPECT_EQ(guard.allocations(), 0u) << guard.first_call();
  EXPECT_EQ(guard.frees(), 0u) << guard.first_call();
  EXPECT_TRUE(status.ok());
}

}  // namespace
}  // namespace zerog::robot
