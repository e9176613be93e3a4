// The cycle's motion estimator (zerog/loop/motion_estimator.hpp; issue 28, item 2): the robot's
// poses give the motion of the row's sensor means exactly for a motion the fit represents, the
// IMU's share finds a constant offset (a tilted base) and nothing faster, and the cycle with it
// does not allocate. The HIL checks (tests/hil, *_fused cases) measure the noise.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>

#include "alloc_count.hpp"
#include "loop_fixtures.hpp"
#include "zerog/formats/robot_toml.hpp"
#include "zerog/loop/cycle.hpp"
#include "zerog/loop/motion_estimator.hpp"
#include "zerog/model/rotation.hpp"
#include "zerog/proto/rsi.hpp"
#include "zerog/proto/rsi_si.hpp"

namespace zerog::loop {
namespace {

constexpr double kDt = 0.012;
const Eigen::Vector3d kA{0.3, -0.2, 0.1};  // constant acceleration of S's origin, B, m/s²
const Eigen::Vector3d kW{0.0, 0.0, 0.4};   // constant rate about B's z, rad/s

// Row k of a motion with constant acceleration and constant rate about B's z.
model::FeatureSignals row_at(double t) {
  model::FeatureSignals s;
  s.t_s = t;
  const Eigen::Vector3d p = Eigen::Vector3d(1.0, 0.2, 1.5) + 0.5 * kA * t * t;
  const Eigen::Matrix3d R = model::rot_z(kW.z() * t) * model::rot_x(0.3);
  for (int r = 0; r < 3; ++r) {
    s.p_base_sensor_m[r] = p[r];
    for (int c = 0; c < 3; ++c) s.R_base_sensor[3 * r + c] = R(r, c);
  }
  return s;
}

// The specific force and rate of that motion at time t, S axes (IMU = S here).
model::ImuSignals<double> truth_at(double t, const Eigen::Vector3d& g) {
  const Eigen::Matrix3d R = model::rot_z(kW.z() * t) * model::rot_x(0.3);
  model::ImuSignals<double> imu;
  imu.specific_force_imu = R.transpose() * (kA - g);
  imu.angular_rate_imu = R.transpose() * kW;
  return imu;
}

TEST(MotionEstimator, GivesTheMotionAtTheInstantsOfTheRowsMeans) {
  MotionEstimator e;
  MotionEstimatorConfig config;
  config.source = MotionSource::fused;
  config.ft_rate_hz = 250.0;    // 3 samples a row: their mean stands for t − 4 ms
  config.imu_rate_hz = 2000.0;  // 24: t − 5.75 ms
  ASSERT_TRUE(e.configure(config, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero(), {}).ok());
  MotionEstimate out;
  for (int c = 2; c < 40; ++c) {
    std::array<model::FeatureSignals, 5> rows;
    std::array<const model::FeatureSignals*, 5> window;
    for (int j = 0; j < 5; ++j) {
      rows[j] = row_at((c - 2 + j) * kDt);
      window[j] = &rows[j];
    }
    const double t_ft = c * kDt - 0.004, t_imu = c * kDt - 0.00575;
    const model::ImuSignals<double> at_ft = truth_at(t_ft, config.gravity_base_mps2);
    const model::ImuSignals<double> at_imu = truth_at(t_imu, config.gravity_base_mps2);
    ASSERT_TRUE(e.update(window, {}, at_imu, {.ft = 3, .imu = 24}, out));
    EXPECT_NEAR(out.ft_instant_s, -0.004, 1e-12);
    EXPECT_NEAR(out.imu_instant_s, -0.00575, 1e-12);
    EXPECT_LT((out.specific_force_robot_imu - at_ft.specific_force_imu).norm(), 1e-6) << c;
    EXPECT_LT((out.angular_rate_robot_imu - at_ft.angular_rate_imu).norm(), 1e-6) << c;
    EXPECT_LT(out.imu.angular_accel_imu.norm(), 1e-6) << c;
    // Compared at its own instant, the turning IMU agrees with the robot: no offset (at the
    // F/T's instant, 1.75 ms of a 0.4 rad/s turn of 9.8 m/s² would be 7e-3 m/s²).
    EXPECT_LT(out.specific_force_offset.norm(), 1e-6) << c;
    EXPECT_LT(out.angular_rate_offset.norm(), 1e-9) << c;
  }
  // Without counts (held rows) or rates: half a row.
  MotionEstimator half;
  ASSERT_TRUE(half.configure({}, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero(), {}).ok());
  std::array<model::FeatureSignals, 5> rows;
  std::array<const model::FeatureSignals*, 5> window;
  for (int j = 0; j < 5; ++j) {
    rows[j] = row_at(j * kDt);
    window[j] = &rows[j];
  }
  ASSERT_TRUE(half.update(window, {}, truth_at(0.018, config.gravity_base_mps2), {}, out));
  EXPECT_NEAR(out.ft_instant_s, -0.006, 1e-12);
  EXPECT_LT(
      (out.specific_force_robot_imu - truth_at(0.018, config.gravity_base_mps2).specific_force_imu)
          .norm(),
      1e-6);
}

// A tilted base while the payload turns: the gravity error is fixed in B, so in the IMU's axes
// it turns with the payload. The Kalman filter of the two offsets (bias in I, error in B)
// follows it with no lag; an offset low-passed in I axes at 0.1 Hz would trail a 0.064 Hz
// turn by about 30° of phase (an error of half the tilt, 0.015 m/s²).
TEST(MotionEstimator, ATiltedBaseIsFollowedWhileThePayloadTurns) {
  MotionEstimator e;
  MotionEstimatorConfig config;
  config.source = MotionSource::fused;
  ASSERT_TRUE(e.configure(config, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero(), {}).ok());
  const Eigen::Vector3d g_tilted = model::rot_x(0.003) * config.gravity_base_mps2;
  const Eigen::Vector3d bias_I(0.004, -0.002, 0.003);  // and a bias fixed in the IMU
  MotionEstimate out;
  double worst = 0.0;
  for (int c = 2; c < 6000; ++c) {
    std::array<model::FeatureSignals, 5> rows;
    std::array<const model::FeatureSignals*, 5> window;
    for (int j = 0; j < 5; ++j) {
      rows[j] = row_at((c - 2 + j) * kDt);
      window[j] = &rows[j];
    }
    const double t = c * kDt - 0.5 * kDt;
    model::ImuSignals<double> imu = truth_at(t, g_tilted);
    const Eigen::Vector3d clean = imu.specific_force_imu + bias_I;
    imu.specific_force_imu = clean;
    ASSERT_TRUE(e.update(window, {}, imu, {}, out));
    if (c > 3000) worst = std::max(worst, (out.imu.specific_force_imu - clean).norm());
  }
  EXPECT_LT(worst, 1e-4) << "the tilt and the bias each found, turning with their frames";
  // Turning about B's z alone, the bias along that axis (fixed in I too) cannot be told from
  // the error along it; across it, the two are told apart.
  const Eigen::Vector3d axis_I = model::rot_x(0.3).transpose() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d miss = out.specific_force_bias_imu - bias_I;
  EXPECT_LT((miss - miss.dot(axis_I) * axis_I).norm(), 1e-4);
}

// A base tilted by 3 mrad: the IMU sees gravity turned, the robot does not. The IMU's share
// takes the offset in; its white noise it takes in only through the 0.1 Hz low-pass.
TEST(MotionEstimator, TheImusShareFindsATiltAndFiltersItsNoise) {
  for (const bool without_imu : {false, true}) {
    MotionEstimator e;
    MotionEstimatorConfig config;
    config.source = MotionSource::fused;
    config.mutant_without_imu = without_imu;
    ASSERT_TRUE(e.configure(config, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero(), {}).ok());
    const Eigen::Vector3d g_tilted = model::rot_x(0.003) * config.gravity_base_mps2;
    std::uint64_t state = 12345;
    auto noise = [&] {  // uniform, σ = 0.01 m/s²
      state = state * 6364136223846793005ULL + 1442695040888963407ULL;
      return 0.01 * std::sqrt(12.0) * (static_cast<double>(state >> 11) * 0x1.0p-53 - 0.5);
    };
    MotionEstimate out;
    double square = 0.0;
    int n = 0;
    for (int c = 2; c < 2000; ++c) {
      std::array<model::FeatureSignals, 5> rows;
      std::array<const model::FeatureSignals*, 5> window;
      for (int j = 0; j < 5; ++j) {
        rows[j] = row_at(0.0);  // at rest
        rows[j].t_s = (c - 2 + j) * kDt;
        window[j] = &rows[j];
      }
      model::ImuSignals<double> imu = truth_at(0.0, g_tilted);
      const Eigen::Vector3d clean = imu.specific_force_imu;
      imu.specific_force_imu += Eigen::Vector3d(noise(), noise(), noise());
      ASSERT_TRUE(e.update(window, {}, imu, {}, out));
      if (c > 1000) {
        square += (out.imu.specific_force_imu - clean).squaredNorm() / 3.0;
        ++n;
      }
    }
    const double rms = std::sqrt(square / n);
    if (without_imu) {
      EXPECT_GT(rms, 0.02) << "without the IMU the tilt (9.8 m/s² x 3 mrad) stays";
    } else {
      EXPECT_LT(rms, 0.0015) << "the tilt found, the IMU's 0.01 m/s² noise filtered";
    }
  }
}

// Step 4: at rest the gyro's row noise leaves the robot's output alone; a ringing nobody
// excited (no contact, no limit: note_excitation false) is left to the model too; after a push
// (note_excitation true for rows 700-719) the output follows the IMU within a few rows, and
// ringing_hold_s (1 s) after the push step 4 is off again; with the step left out (the mutant)
// it never follows.
TEST(MotionEstimator, AfterAPushWhileTheArmRingsTheImuTakesOver) {
  for (const bool without : {false, true}) {
    MotionEstimator e;
    MotionEstimatorConfig config;
    config.source = MotionSource::fused;
    config.mutant_without_ringing = without;
    ASSERT_EQ(config.ringing_hold_s, 1.0);
    ASSERT_TRUE(e.configure(config, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero(), {}).ok());
    std::uint64_t state = 777;
    auto noise = [&] {  // uniform, σ = 1e-4 rad/s: the emulated gyro's row mean
      state = state * 6364136223846793005ULL + 1442695040888963407ULL;
      return 1e-4 * std::sqrt(12.0) * (static_cast<double>(state >> 11) * 0x1.0p-53 - 0.5);
    };
    MotionEstimate out;
    double worst_rest = 0.0, most_unexcited = 0.0, worst_follow = 0.0, most_after_hold = 0.0;
    double ringing_within_hold = 0.0, most_following = 0.0;  // the former at the last row of it
    for (int c = 2; c < 1000; ++c) {
      std::array<model::FeatureSignals, 5> rows;
      std::array<const model::FeatureSignals*, 5> window;
      for (int j = 0; j < 5; ++j) {
        rows[j] = row_at(0.0);  // the robot at rest
        rows[j].t_s = (c - 2 + j) * kDt;
        window[j] = &rows[j];
      }
      const double t = c * kDt;
      model::ImuSignals<double> imu = truth_at(0.0, config.gravity_base_mps2);
      imu.angular_rate_imu = Eigen::Vector3d(noise(), noise(), noise());  // still, as the robot
      // From row 600 on, the link rings at 6 Hz, 5e-3 rad/s about x, unseen by the robot.
      const Eigen::Vector3d ring =
          c >= 600 ? Eigen::Vector3d(5e-3 * std::sin(2.0 * std::numbers::pi * 6.0 * t), 0.0, 0.0)
                   : Eigen::Vector3d::Zero();
      imu.angular_rate_imu += ring;
      e.note_excitation(c >= 700 && c < 720);
      ASSERT_TRUE(e.update(window, {}, imu, {}, out));
      if (c > 300 && c < 600) worst_rest = std::max(worst_rest, out.ringing);
      if (c >= 600 && c < 700) most_unexcited = std::max(most_unexcited, out.ringing);
      if (c > 740 && c < 800) {
        worst_follow = std::max(worst_follow, (out.imu.angular_rate_imu - ring).norm());
        ringing_within_hold = out.ringing;
        most_following = std::max(most_following, out.ringing);
      }
      // The hold counts from the last excited row (719): 1 s is 83.3 rows of 12 ms.
      if (c > 805) most_after_hold = std::max(most_after_hold, out.ringing);
    }
    EXPECT_EQ(most_unexcited, 0.0) << "a ringing nobody excited leaves step 4 off";
    EXPECT_EQ(most_after_hold, 0.0) << "ringing_hold_s after the push step 4 is off";
    if (without) {
      EXPECT_EQ(most_following, 0.0);
      EXPECT_GT(worst_follow, 4e-3) << "the ringing stays unseen";
    } else {
      EXPECT_LT(worst_rest, 0.02) << "at rest the gyro's noise does not open step 4";
      EXPECT_GT(ringing_within_hold, 0.8);
      EXPECT_LT(worst_follow, 1.5e-3) << "after the push the output follows the gyro";
    }
  }
}

TEST(MotionEstimator, RefusesSettingsThatCannotWork) {
  MotionEstimatorConfig c;
  c.crossover_hz = 0.0;
  EXPECT_EQ(check_estimator_config(c).setting(), "crossover_hz");
  c = {};
  c.mode_gain = 1.5;
  EXPECT_EQ(check_estimator_config(c).setting(), "mode_gain");
  c = {};
  c.substep_s = 0.1;
  EXPECT_EQ(check_estimator_config(c).setting(), "substep_s");
  c = {};
  c.ringing_hold_s = -1.0;
  EXPECT_EQ(check_estimator_config(c).setting(), "ringing_hold_s");
  c = {};
  c.servo_hz = -8.0;
  EXPECT_EQ(check_estimator_config(c).setting(), "servo_hz");
  c.servo_hz = std::numeric_limits<double>::infinity();
  EXPECT_EQ(check_estimator_config(c).setting(), "servo_hz");
  CycleConfig cycle = test::test_cycle_config();
  cycle.motion.excitation_hz = -1.0;
  EXPECT_EQ(check_config(cycle).setting(), "motion.excitation_hz");
}

// The cycle with the fused path and the elastic KR 210 (its deflection stepped every cycle)
// allocates nothing.
// The first rows average the IMU's share, so its error falls as 1/√n: with the STIM300's row
// noise (about 0.009 m/s², proto/sim_robot.md) one row is 0.9 N per axis on 100 kg, well above
// a gate at a third of today's (0.667 N). `settled` comes when the offsets' variance is within
// twice its steady value: about a second of rows (measured here: the first settled row), when
// the share's error is down to about a tenth of a newton; without the IMU there is nothing to
// settle.
TEST(MotionEstimator, TheImusShareSettlesBeforeItsContactIsTrusted) {
  constexpr int kSeeds = 40, kRows = 200, kEarly = 5;
  std::uint64_t state = 777;
  auto noise = [&] {  // uniform, σ = 0.009 m/s²
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return 0.009 * std::sqrt(12.0) * (static_cast<double>(state >> 11) * 0x1.0p-53 - 0.5);
  };
  double early_square = 0.0, settled_square = 0.0;
  int first_min = kRows, first_max = 0;
  for (int seed = 0; seed < kSeeds; ++seed) {
    MotionEstimator e;
    MotionEstimatorConfig config;
    config.source = MotionSource::fused;
    ASSERT_TRUE(e.configure(config, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero(), {}).ok());
    MotionEstimate out;
    int first = -1;
    for (int c = 0; c < kRows; ++c) {
      std::array<model::FeatureSignals, 5> rows;
      std::array<const model::FeatureSignals*, 5> window;
      for (int j = 0; j < 5; ++j) {
        rows[j] = row_at(0.0);
        rows[j].t_s = (c + j) * kDt;
        window[j] = &rows[j];
      }
      model::ImuSignals<double> imu = truth_at(0.0, config.gravity_base_mps2);
      const Eigen::Vector3d clean = imu.specific_force_imu;
      imu.specific_force_imu += Eigen::Vector3d(noise(), noise(), noise());
      ASSERT_TRUE(e.update(window, {}, imu, {}, out));
      const double error_N = 100.0 * (out.imu.specific_force_imu - clean).norm() / std::sqrt(3.0);
      if (c == kEarly) early_square += error_N * error_N;
      if (first < 0 && out.settled) {
        first = c;
        settled_square += error_N * error_N;
      }
      if (first >= 0) {
        ASSERT_TRUE(out.settled) << "settled stays settled (row " << c << ")";
      }
    }
    ASSERT_GE(first, 0) << "seed " << seed << " never settled in " << kRows << " rows";
    first_min = std::min(first_min, first);
    first_max = std::max(first_max, first);
  }
  // Every seed the same row: the variance does not depend on the noise drawn.
  EXPECT_EQ(first_min, first_max);
  EXPECT_GT(first_min, 50);
  EXPECT_LT(first_min, 120);
  const double early = std::sqrt(early_square / kSeeds), late = std::sqrt(settled_square / kSeeds);
  EXPECT_GT(early, 0.25) << "row " << kEarly << ": the share's error per axis, N";
  EXPECT_LT(late, 0.15) << "row " << first_min << " (settled)";
  std::printf(
      "settled at row %d (%.2f s); the share's error per axis on 100 kg: %.3f N at row %d, "
      "%.3f N settled\n",
      first_min, first_min * kDt, early, kEarly, late);

  MotionEstimator without;
  MotionEstimatorConfig config;
  config.source = MotionSource::fused;
  config.mutant_without_imu = true;
  ASSERT_TRUE(
      without.configure(config, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero(), {}).ok());
  std::array<model::FeatureSignals, 5> rows;
  std::array<const model::FeatureSignals*, 5> window;
  for (int j = 0; j < 5; ++j) {
    rows[j] = row_at(0.0);
    rows[j].t_s = j * kDt;
    window[j] = &rows[j];
  }
  MotionEstimate out;
  ASSERT_TRUE(without.update(window, {}, truth_at(0.0, config.gravity_base_mps2), {}, out));
  EXPECT_TRUE(out.settled);
}

// In the cycle: a push from zero-g's first cycle is not confirmed while the estimator settles
// (kEstimatorSettling), then as any push (the gate's confirm cycles from the settled row); the
// IMU path has nothing to settle.
TEST(MotionEstimator, ThePushWaitsForTheEstimatorToSettle) {
  for (const MotionSource source : {MotionSource::fused, MotionSource::imu}) {
    CycleConfig config = test::test_cycle_config();
    config.motion.source = source;
    config.robot = formats::kr210_r2700();
    Cycle c;
    ASSERT_EQ(c.configure(config, test::payload_model()).text(), "");
    test::StaticRobot rig;
    test::start_zero_g(c, rig);
    int settled_at = -1, moved_at = -1;
    for (int i = 0; i < 200 && moved_at < 0; ++i) {
      rig.cycle(c, test::push(30.0, 0.0, 0.0));
      const bool settling = (c.last().flags & kEstimatorSettling) != 0;
      if (!settling && settled_at < 0) settled_at = i;
      if (settling) {
        ASSERT_LT(settled_at, 0) << "the flag came back at cycle " << i;
      }
      if (c.motion().body().state().v_world_mps.norm() > 0.0) moved_at = i;
    }
    if (source == MotionSource::imu) {
      EXPECT_EQ(settled_at, 0);
      EXPECT_EQ(moved_at, c.delay_rows() + 2)
          << "confirmed on the third cycle of the push the model's row (D rows back) sees";
    } else {
      EXPECT_GT(settled_at, 40) << "the estimator started with the first rows, before zero-g";
      EXPECT_EQ(moved_at, settled_at + 2) << "then confirmed as any push";
    }
  }
}

// The servo model follows what the robot receives: as_sent_over_rsi is the wire's resolution
// (the reply formatted and parsed back by zerog::proto::rsi), for a Cartesian and an axis
// correction.
TEST(MotionEstimator, TheServoModelTakesTheCorrectionAsTheWireCarriesIt) {
  samples::RobotCorrection c;
  c.kind = samples::RobotCorrection::Kind::cartesian;
  c.translation_m = {1.23456789e-3, -4.4444444e-4, 7.77777e-6};
  const Eigen::Matrix3d R =
      model::rot_z(0.00731234) * model::rot_y(-0.0012345) * model::rot_x(3.3333e-5);
  for (int r = 0; r < 3; ++r)
    for (int k = 0; k < 3; ++k) c.R_correction[3 * r + k] = R(r, k);
  c.axes_rad = {1.2345678e-3, -2e-7, 0.0, 5.55555e-4, 0.0, -9.87654e-5};
  const samples::RobotCorrection ours = as_sent_over_rsi(c);
  const proto::rsi::Reply r = proto::rsi::reply_from_correction(c);
  std::array<char, 512> text{};
  const proto::rsi::FormatResult f = proto::rsi::format_reply(r.rkorr, 1, text, "zerog");
  ASSERT_EQ(f.status, proto::rsi::FormatStatus::ok);
  proto::rsi::Reply back;
  ASSERT_TRUE(proto::rsi::parse_reply(std::string_view(text.data(), f.size), back).ok());
  const samples::RobotCorrection wire = proto::rsi::correction_from_reply(back);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(ours.translation_m[k], wire.translation_m[k], 1e-15);
  for (int k = 0; k < 9; ++k) EXPECT_NEAR(ours.R_correction[k], wire.R_correction[k], 1e-15);
  EXPECT_NE(ours.translation_m[0], c.translation_m[0]) << "rounded";
  std::array<double, 6> akorr_deg;
  for (int k = 0; k < 6; ++k) akorr_deg[k] = c.axes_rad[k] / proto::rsi::kRadPerDeg;
  const proto::rsi::FormatResult fa = proto::rsi::format_axis_reply(akorr_deg, 1, text, "zerog");
  ASSERT_EQ(fa.status, proto::rsi::FormatStatus::ok);
  ASSERT_TRUE(proto::rsi::parse_reply(std::string_view(text.data(), fa.size), back).ok());
  for (int k = 0; k < 6; ++k)
    EXPECT_NEAR(ours.axes_rad[k], back.akorr_deg[k] * proto::rsi::kRadPerDeg, 1e-15) << k;
}

// The servo model: an axis correction Δ on A1 answered at row 10 takes effect at the next
// tick and is interpolated over that cycle, so the model's acceleration is zero up to row 11
// and at row 12 that of a critically damped servo at the end of a ramp of Δ over one cycle T,
// Δ ω² e^(−ωT) (the ramp response q̈(t) = r ω² t e^(−ωt), r = Δ / T), at row 13 the closed form
// after the ramp; without servo_hz, zero. The measured joints follow the same servo (the ramp
// response q(t) = r (t − 2/ω + (2/ω + t) e^(−ωt)), less its copy one cycle later). A robot that
// holds still instead (its controller ignoring the corrections) turns the model off: no
// acceleration from it, servo_followed false.
TEST(MotionEstimator, TheServoModelFollowsTheCommandFromTheControllersNextTick) {
  for (const double servo_hz : {8.0, 0.0}) {
    for (const bool robot_follows : {true, false}) {
      MotionEstimator e;
      MotionEstimatorConfig config;
      config.source = MotionSource::fused;
      config.servo_hz = servo_hz;
      robot::RobotModel arm = formats::kr210_r2700();
      for (int i = 0; i < 6; ++i) arm.elasticity[i] = {1e6, 8.0, 0.05};
      ASSERT_TRUE(
          e.configure(config, Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero(), arm).ok());
      // 0.0573°: a step RSI carries exactly (4 decimals of a degree), as the model takes it.
      const double delta = 0.0573 * std::numbers::pi / 180.0;
      const double w = 2.0 * std::numbers::pi * 8.0, r = delta / kDt;
      auto ramp = [&](double t) {
        return t <= 0.0 ? 0.0 : r * (t - 2.0 / w + (2.0 / w + t) * std::exp(-w * t));
      };
      std::array<model::FeatureSignals, 20> rows;
      const std::array<double, 6> q{0.1, -1.4, 1.5, 0.2, 0.7, -0.3};
      for (int k = 0; k < 20; ++k) {
        rows[k] = row_at(0.0);
        rows[k].t_s = k * kDt;
        for (int j = 0; j < 6; ++j) rows[k].joints_rad[j] = q[j];
        const double t = (k - 11) * kDt;  // from the tick after row 10's reply
        if (robot_follows) rows[k].joints_rad[0] += ramp(t) - ramp(t - kDt);
      }
      const double ws = 2.0 * std::numbers::pi * servo_hz, decay = std::exp(-ws * kDt);
      MotionEstimate out;
      bool followed_always = true;
      for (int n = 4; n < 16; ++n) {
        std::array<const model::FeatureSignals*, 5> window;
        for (int j = 0; j < 5; ++j) window[j] = &rows[n - 4 + j];
        ASSERT_TRUE(e.update(window, {}, truth_at(0.0, config.gravity_base_mps2), {}, out));
        followed_always = followed_always && out.servo_followed;
        const int c = n - 2;
        // After the ramp (row 13): the ramp's response less the same ramp one cycle later,
        // r ω² (2T e^(−2ωT) − T e^(−ωT)).
        double expected = 0.0;
        if (servo_hz > 0.0 && robot_follows) {
          expected = c == 12   ? delta * ws * ws * decay
                     : c == 13 ? delta * ws * ws * decay * (2.0 * decay - 1.0)
                     : c < 12  ? 0.0
                               : out.servo_accel_radps2[0];
        }
        EXPECT_NEAR(out.servo_accel_radps2[0], expected, 1e-9)
            << "row " << c << ", " << servo_hz << " Hz, robot follows " << robot_follows;
        for (int j = 1; j < 6; ++j) EXPECT_EQ(out.servo_accel_radps2[j], 0.0) << j;
        samples::RobotCorrection cmd;
        if (n == 10) {
          cmd.kind = samples::RobotCorrection::Kind::axes;
          cmd.axes_rad[0] = delta;
        }
        e.note_command(cmd, rows[n].joints_rad, rows[n].t_s, kDt);
      }
      EXPECT_EQ(followed_always, robot_follows || servo_hz == 0.0)
          << servo_hz << " Hz, robot follows " << robot_follows;
    }
  }
}

TEST(MotionEstimator, TheCycleWithItDoesNotAllocate) {
  CycleConfig config = test::test_cycle_config();
  config.motion.source = MotionSource::fused;
  config.motion.servo_hz = 8.0;
  robot::RobotModel arm = formats::kr210_r2700();
  for (int i = 0; i < 6; ++i) arm.elasticity[i] = {1e6, 8.0, 0.05};
  config.robot = arm;
  Cycle c;
  ASSERT_EQ(c.configure(config, test::payload_model()).text(), "");
  test::StaticRobot rig;
  test::start_zero_g(c, rig);
  zerog::test::AllocGuard guard("Cycle::step (fused motion)");
  double most_ringing = 0.0, most_servo = 0.0;
  for (int i = 0; i < 200; ++i) {
    // A push once the estimator has settled (cycles 80-129), so the body moves and the servo
    // model runs; from cycle 100 the gyro shows a 6 Hz ringing the robot does not: step 4 (the
    // gyro's correction of the modes and the blend) runs too.
    rig.imu_sample.rate_rad_s[0] =
        i >= 100 ? 5e-3 * std::sin(2.0 * std::numbers::pi * 6.0 * 0.012 * i) : 0.0;
    rig.cycle(c, test::push(i >= 80 && i < 130 ? 30.0 : 0.0, 5.0, 0.0));
    most_ringing = std::max(most_ringing, c.motion_estimate().ringing);
    for (double a : c.motion_estimate().servo_accel_radps2)
      most_servo = std::max(most_servo, std::abs(a));
  }
  guard.stop();
  EXPECT_GT(most_ringing, 0.5) << "step 4 ran";
  EXPECT_GT(most_servo, 0.0) << "the servo model ran";
  EXPECT_EQ(guard.allocations(), 0u) << guard.first_call();
  EXPECT_EQ(guard.frees(), 0u) << guard.first_call();
  EXPECT_TRUE(std::isfinite(c.last().predicted[0]));
}

}  // namespace
}  // namespace zerog::loop
