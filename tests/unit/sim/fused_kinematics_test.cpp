// Fused kinematics (issue 28, item 3; host/io/include/zerog/io/fused_kinematics.hpp) on the
// elastic simulated robot: the joints (motor side, quantised) and the IMU (white noise, bias
// instability) fused over the whole log give the payload's specific force and angular
// acceleration closer to the truth (the clean log: link side, noise-free) than either alone,
// and the elastic step is what makes the joints usable: the same fusion with a rigid robot file
// (the mutant) loses it.
#include <gtest/gtest.h>

#include <cmath>

#include "zerog/formats/robot_toml.hpp"
#include "zerog/io/fused_kinematics.hpp"
#include "zerog/robot/forward_kinematics.hpp"
#include "zerog/robot/savitzky_golay.hpp"
#include "zerog/sim/design.hpp"
#include "zerog/sim/simulator.hpp"

namespace zerog::io {

using formats::Log;
namespace {

// A constant passes unchanged; a symmetric pulse keeps its centre (zero phase); a sine at the
// cutoff comes out at half its amplitude (each pass -3 dB).
TEST(ZeroPhaseLowpass, PassesAConstantKeepsPhaseAndHalvesTheCutoff) {
  const double dt = 0.01, fc = 2.0;
  std::vector<double> t(4000);
  for (std::size_t i = 0; i < t.size(); ++i) t[i] = dt * static_cast<double>(i);
  std::vector<Eigen::Vector3d> c(t.size(), Eigen::Vector3d(1.0, -2.0, 3.0));
  zero_phase_lowpass(t, c, fc);
  for (const Eigen::Vector3d& v : c)
    EXPECT_NEAR((v - Eigen::Vector3d(1, -2, 3)).norm(), 0.0, 1e-12);
  std::vector<Eigen::Vector3d> pulse(t.size(), Eigen::Vector3d::Zero());
  pulse[2000] = Eigen::Vector3d(1.0, 0.0, 0.0);
  zero_phase_lowpass(t, pulse, fc);
  double moment = 0.0, mass = 0.0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    moment += pulse[i].x() * t[i];
    mass += pulse[i].x();
  }
  EXPECT_NEAR(moment / mass, t[2000], 1e-3 * dt);
  std::vector<Eigen::Vector3d> sine(t.size());
  for (std::size_t i = 0; i < t.size(); ++i)
    sine[i] = Eigen::Vector3d::Constant(std::sin(2.0 * std::numbers::pi * fc * t[i]));
  zero_phase_lowpass(t, sine, fc);
  double peak = 0.0;
  for (std::size_t i = 1000; i < 3000; ++i) peak = std::max(peak, std::abs(sine[i].x()));
  // The discrete pole at fc·dt = 0.02 is within 2 % of the continuous filter's -3 dB.
  EXPECT_NEAR(peak, 0.5, 0.02);
}

struct Errors {
  double force_mps2 = 0.0, accel_radps2 = 0.0;
};

// RMS over the rows (and axes) of the fused signals against the clean log's; the angular
// acceleration against the 5-point difference of the clean gyro, as the floor's.
Errors errors_of(const FusionResult& r, const Log& clean) {
  const std::size_t n = clean.samples.size();
  double sf = 0.0, sa = 0.0;
  std::size_t counted = 0;
  const double dt = clean.samples[1].t_s - clean.samples[0].t_s;
  for (std::size_t i = 50; i + 50 < n; ++i) {
    const auto& s = clean.samples;
    const Eigen::Vector3d dw =
        (s[i - 2].angular_rate_imu_radps - 8.0 * s[i - 1].angular_rate_imu_radps +
         8.0 * s[i + 1].angular_rate_imu_radps - s[i + 2].angular_rate_imu_radps) /
        (12.0 * dt);
    sf += (r.specific_force_mps2[i] - s[i].specific_force_imu_mps2).squaredNorm() / 3.0;
    sa += (r.angular_accel_radps2[i] - dw).squaredNorm() / 3.0;
    ++counted;
  }
  return {std::sqrt(sf / static_cast<double>(counted)),
          std::sqrt(sa / static_cast<double>(counted))};
}

FusionResult fuse(const Log& log, const robot::RobotModel& model) {
  const std::size_t n = log.samples.size();
  std::vector<double> q(6 * n);
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = 0; j < 6; ++j) q[6 * i + j] = log.samples[i].joints_rad[j];
  const RowSignals rows = row_signals(log);
  FusionInput in = fusion_input(rows);
  in.robot = &model;
  in.joint_t_s = rows.t_s;
  in.joints_rad = q;
  const FusionSettings s = fusion_settings(0.012);  // zerog import's defaults at 12 ms
  return fuse_kinematics(in, s);
}

// Three seeds of a 3-minute OA run on the elastic robot (zerog sim --real-robot). The IMU alone
// is its white noise (about 0.010 m/s² a row at 12 ms: 1 N at 100 kg); the fusion must be at
// most 30 % of it in specific force and 12 % of the differenced gyro in angular acceleration,
// and the rigid mutant (the same fusion, the robot file without elasticity) must be worse than
// the elastic fusion by 80 % in specific force (measured: 0.0022 against 0.0056 m/s², three seeds).
TEST(FusedKinematics, BeatsTheImuAndNeedsTheElasticity) {
  for (const std::uint64_t seed : {3u, 8u, 21u}) {
    sim::SimConfig config = sim::default_sim_config(seed);
    config.duration_limit_s = 180.0;
    sim::make_real_robot(config, true);
    sim::DesignOptions o;
    o.kind = sim::DesignKind::oa;
    const sim::SimOutput out = sim::RigSimulator(config, sim::make_design(o).points_rad).run();
    robot::RobotModel elastic = formats::kr210_r2700(to_frame_transform(out.log.rig.flange_sensor));
    for (std::size_t j = 0; j < 6; ++j) elastic.elasticity[j] = config.elastic.joints[j];
    robot::RobotModel rigid = formats::kr210_r2700(to_frame_transform(out.log.rig.flange_sensor));
    rigid.elasticity = {};

    // The IMU as logged (ω̇ its 5-point difference, as host/ident forms it).
    FusionResult imu;
    const std::size_t n = out.log.samples.size();
    imu.specific_force_mps2.resize(n);
    imu.angular_accel_radps2.resize(n);
    const double dt = out.log.samples[1].t_s - out.log.samples[0].t_s;
    for (std::size_t i = 2; i + 2 < n; ++i) {
      const auto& s = out.log.samples;
      imu.specific_force_mps2[i] = s[i].specific_force_imu_mps2;
      imu.angular_accel_radps2[i] =
          (s[i - 2].angular_rate_imu_radps - 8.0 * s[i - 1].angular_rate_imu_radps +
           8.0 * s[i + 1].angular_rate_imu_radps - s[i + 2].angular_rate_imu_radps) /
          (12.0 * dt);
    }
    const Errors e_imu = errors_of(imu, out.clean_log);
    const FusionResult fused = fuse(out.log, elastic);
    const Errors e_fused = errors_of(fused, out.clean_log);
    const Errors e_rigid = errors_of(fuse(out.log, rigid), out.clean_log);
    EXPECT_TRUE(fused.elastic);
    EXPECT_LT(e_fused.force_mps2, 0.30 * e_imu.force_mps2) << "seed " << seed;
    EXPECT_LT(e_fused.accel_radps2, 0.12 * e_imu.accel_radps2) << "seed " << seed;
    EXPECT_GT(e_rigid.force_mps2, 1.8 * e_fused.force_mps2) << "rigid mutant, seed " << seed;
    std::printf(
        "seed %llu: specific force RMS imu %.4f fused %.4f rigid-mutant %.4f m/s^2; "
        "angular accel imu %.4f fused %.4f rad/s^2\n",
        static_cast<unsigned long long>(seed), e_imu.force_mps2, e_fused.force_mps2,
        e_rigid.force_mps2, e_imu.accel_radps2, e_fused.accel_radps2);
  }
}

}  // namespace
}  // namespace zerog::io
