// The robot's position servo from a recording (`zerog servo`; host/ident/include/zerog/ident/
// servo_fit.hpp), on recordings of a robot written out in tests/common/servo_recording.hpp.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <vector>

#include "servo_recording.hpp"
#include "zerog/ident/servo_fit.hpp"

namespace zerog::ident {
namespace {

using ::testing::HasSubstr;

using test::servo_pushes;
using test::servo_recording;

TEST(ServoFit, FindsTheBandwidthAndTheTickOfARobotItDidNotMake) {
  for (const double hz : {3.0, 6.5, 12.0}) {
    const ServoFit fit = fit_servo(servo_recording(servo_pushes(2000, 8, 1), hz, 2), {});
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
  const ServoFit fit = fit_servo(servo_recording(servo_pushes(2000, 8, 2), 6.5, 3), {});
  EXPECT_FALSE(fit.known);
  EXPECT_EQ(fit.lag_rows, 3);
  EXPECT_NEAR(fit.hz, 6.5, 0.1);
  EXPECT_THAT(fit.note, HasSubstr("leave servo_hz off"));
  EXPECT_THAT(fit.note, HasSubstr("k + 2 to k + 3"));
}

TEST(ServoFit, NoMotionOrTooShortOrARobotThatIgnoredTheCommandsCannotTell) {
  const ServoFit still = fit_servo(servo_recording(servo_pushes(2000, 0, 3), 6.5, 2), {});
  EXPECT_FALSE(still.known);
  EXPECT_THAT(still.note, HasSubstr("commanded no motion"));
  EXPECT_TRUE(std::isnan(still.hz));

  const ServoFit short_one = fit_servo(servo_recording(servo_pushes(200, 2, 4), 6.5, 2), {});
  EXPECT_FALSE(short_one.known);
  EXPECT_THAT(short_one.note, HasSubstr("too short"));

  // The controller held still (a stop): the joints never moved while zerog-rt commanded.
  std::vector<loop::CycleRecord> ignored = servo_recording(servo_pushes(2000, 8, 5), 6.5, 2);
  for (loop::CycleRecord& r : ignored) r.joints_rad = ignored.front().joints_rad;
  const ServoFit none = fit_servo(ignored, {});
  EXPECT_FALSE(none.known);
  EXPECT_THAT(none.note, HasSubstr("cannot tell"));
}

TEST(ServoFit, OnePushOnlyGivesTheBandwidthWithoutASpread) {
  // One push in the first quarter, then the part at rest.
  std::vector<std::array<double, 6>> dq = servo_pushes(500, 1, 6);
  dq.resize(2000, std::array<double, 6>{});
  const ServoFit fit = fit_servo(servo_recording(dq, 6.5, 2), {});
  ASSERT_TRUE(fit.known) << fit.note;
  EXPECT_NEAR(fit.hz, 6.5, 0.07);
  EXPECT_TRUE(std::isnan(fit.hz_sigma));
  EXPECT_THAT(fit.note, HasSubstr("no spread to quote"));
}

TEST(ServoFit, ALostDatagramStartsANewRunAndCartesianNeedsTheRobot) {
  std::vector<loop::CycleRecord> r = servo_recording(servo_pushes(2000, 8, 7), 6.5, 2);
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
