// The robot's position servo from a recording (`zerog servo`; host/ident/include/zerog/ident/
// servo_fit.hpp). The recordings here are made by a servo written out in the test (the
// emulator's formula, robot::servo_advance, stepped per cycle), not by loop::ServoModel, which
// the fit runs: a model that moved the joints at the wrong tick or with the wrong bandwidth
// would not find these.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "zerog/ident/servo_fit.hpp"
#include "zerog/robot/servo.hpp"

namespace zerog::ident {
namespace {

using ::testing::HasSubstr;

constexpr double kCycle = 0.012;
constexpr double kDeg = std::numbers::pi / 180.0;

// AKorr increments (rad) per row: pushes that start and stop the joints, `starts` of them spread
// over the recording (none: nothing commanded).
std::vector<std::array<double, 6>> pushes(std::size_t rows, int starts, unsigned seed) {
  std::vector<std::array<double, 6>> dq(rows, std::array<double, 6>{});
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> rate(-0.3, 0.3);  // rad/s
  for (int p = 0; p < starts; ++p) {
    const std::size_t a = (2 * static_cast<std::size_t>(p) + 1) * rows / (2 * starts + 1);
    const std::size_t b = a + rows / (2 * static_cast<std::size_t>(starts) + 1);
    std::array<double, 6> r{};
    for (double& v : r) v = rate(rng);
    for (std::size_t k = a; k < b && k < rows; ++k) {
      // A half-sine speed profile: starts and stops smoothly, as a push on the part.
      const double s =
          std::sin(std::numbers::pi * static_cast<double>(k - a) / static_cast<double>(b - a));
      for (std::size_t j = 0; j < 6; ++j) dq[k][j] = r[j] * s * kCycle;
    }
  }
  return dq;
}

// The robot: the increment answered at row k ramps the set point over the cycle that ends at row
// k + lag; a critically damped servo of `hz` follows it; AIPos carries 4 decimals of a degree.
std::vector<loop::CycleRecord> record(const std::vector<std::array<double, 6>>& dq, double hz,
                                      int lag) {
  const double w = 2.0 * std::numbers::pi * hz;
  const Eigen::Matrix2d phi = robot::servo_transition(w, kCycle);
  std::array<double, 6> s{}, q{}, qd{};
  for (std::size_t j = 0; j < 6; ++j) s[j] = q[j] = 0.1 * static_cast<double>(j + 1);
  std::vector<loop::CycleRecord> out(dq.size());
  for (std::size_t m = 0; m < dq.size(); ++m) {
    if (m >= static_cast<std::size_t>(lag)) {
      const auto& d = dq[m - static_cast<std::size_t>(lag)];
      for (std::size_t j = 0; j < 6; ++j)
        robot::servo_advance(w, kCycle, d[j] / kCycle, phi, s[j], q[j], qd[j]);
    }
    loop::CycleRecord& r = out[m];
    r.cycle = m + 1;
    r.ipoc = 1000 + 12 * m;
    r.t_s = static_cast<double>(m) * kCycle;
    r.state = loop::State::zero_g;
    for (std::size_t j = 0; j < 6; ++j)
      r.joints_rad[j] = std::round(q[j] / kDeg * 1e4) / 1e4 * kDeg;
    bool any = false;
    for (std::size_t j = 0; j < 6; ++j) {
      r.reply.axes_rad[j] = dq[m][j];
      any = any || dq[m][j] != 0.0;
    }
    r.reply.kind =
        any ? samples::RobotCorrection::Kind::axes : samples::RobotCorrection::Kind::none;
  }
  return out;
}

TEST(ServoFit, FindsTheBandwidthAndTheTickOfARobotItDidNotMake) {
  for (const double hz : {3.0, 6.5, 12.0}) {
    const ServoFit fit = fit_servo(record(pushes(2000, 8, 1), hz, 2), {});
    ASSERT_TRUE(fit.known) << hz << ": " << fit.note;
    EXPECT_EQ(fit.lag_rows, ServoFit::kModelLag) << hz;
    EXPECT_NEAR(fit.hz, hz, 0.01 * hz);
    // The quarters' spread is what is quoted: the truth lies within it, within 4σ.
    EXPECT_EQ(fit.quarters.size(), 4u);
    ASSERT_TRUE(std::isfinite(fit.hz_sigma)) << hz;
    EXPECT_LT(std::abs(fit.hz - hz), std::max(4.0 * fit.hz_sigma, 0.002 * hz)) << hz;
    EXPECT_LE(fit.hz_lo, fit.hz_hi);
    // The bandwidth explains what an instant servo does not.
    EXPECT_LT(fit.best.rms_rad, 0.2 * fit.instant.rms_rad) << hz;
  }
}

TEST(ServoFit, AControllerOneTickLaterIsNamedAndTheModelLeftOff) {
  const ServoFit fit = fit_servo(record(pushes(2000, 8, 2), 6.5, 3), {});
  EXPECT_FALSE(fit.known);
  EXPECT_EQ(fit.lag_rows, 3);
  EXPECT_NEAR(fit.hz, 6.5, 0.1);
  EXPECT_THAT(fit.note, HasSubstr("leave servo_hz off"));
  EXPECT_THAT(fit.note, HasSubstr("k + 2 to k + 3"));
}

TEST(ServoFit, NoMotionOrTooShortOrARobotThatIgnoredTheCommandsCannotTell) {
  const ServoFit still = fit_servo(record(pushes(2000, 0, 3), 6.5, 2), {});
  EXPECT_FALSE(still.known);
  EXPECT_THAT(still.note, HasSubstr("commanded no motion"));
  EXPECT_TRUE(std::isnan(still.hz));

  const ServoFit short_one = fit_servo(record(pushes(200, 2, 4), 6.5, 2), {});
  EXPECT_FALSE(short_one.known);
  EXPECT_THAT(short_one.note, HasSubstr("too short"));

  // The controller held still (a stop): the joints never moved while zerog-rt commanded.
  std::vector<loop::CycleRecord> ignored = record(pushes(2000, 8, 5), 6.5, 2);
  for (loop::CycleRecord& r : ignored) r.joints_rad = ignored.front().joints_rad;
  const ServoFit none = fit_servo(ignored, {});
  EXPECT_FALSE(none.known);
  EXPECT_THAT(none.note, HasSubstr("cannot tell"));
}

TEST(ServoFit, OnePushOnlyGivesTheBandwidthWithoutASpread) {
  // One push in the first quarter, then the part at rest.
  std::vector<std::array<double, 6>> dq = pushes(500, 1, 6);
  dq.resize(2000, std::array<double, 6>{});
  const ServoFit fit = fit_servo(record(dq, 6.5, 2), {});
  ASSERT_TRUE(fit.known) << fit.note;
  EXPECT_NEAR(fit.hz, 6.5, 0.07);
  EXPECT_TRUE(std::isnan(fit.hz_sigma));
  EXPECT_THAT(fit.note, HasSubstr("no spread to quote"));
}

TEST(ServoFit, ALostDatagramStartsANewRunAndCartesianNeedsTheRobot) {
  std::vector<loop::CycleRecord> r = record(pushes(2000, 8, 7), 6.5, 2);
  r[1000].flags |= loop::kIpocGap;
  const ServoFit fit = fit_servo(r, {});
  EXPECT_EQ(fit.runs, 2u);
  EXPECT_TRUE(fit.known) << fit.note;

  r[10].reply.kind = samples::RobotCorrection::Kind::cartesian;
  try {
    fit_servo(r, {});
    FAIL() << "a Cartesian correction without the robot was taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_THAT(e.what(), HasSubstr("row 11"));
    EXPECT_THAT(e.what(), HasSubstr("run.rig.toml"));
  }
}

}  // namespace
}  // namespace zerog::ident
