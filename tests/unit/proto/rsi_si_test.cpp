// The RSI border's unit conversions (zerog/proto/rsi_si.hpp): known values with the frames
// named, and round trips both ways.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <numbers>

#include "zerog/proto/rsi_si.hpp"

namespace zerog::proto::rsi {
namespace {

constexpr double kPi = std::numbers::pi;

// Column `c` of a row-major rotation: the direction of T's axis c in B.
std::array<double, 3> axis_in_base(const samples::Rotation& R, int c) {
  return {R[static_cast<std::size_t>(c)], R[static_cast<std::size_t>(3 + c)],
          R[static_cast<std::size_t>(6 + c)]};
}

void expect_vec(const std::array<double, 3>& got, const std::array<double, 3>& want) {
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(got[i], want[i], 1e-15) << i;
}

TEST(RsiSi, MessageToSiKnownValues) {
  RobotMessage m;
  m.ipoc = 4208157;
  m.has_delay = true;
  m.delay = 3;
  m.joints_deg = {0, -90, 90, 180, 45, -30};
  m.actual_pose = {1000, -250, 1.5, 90, 0, 90};  // mm; A = 90°, B = 0, C = 90°
  const samples::RobotSample s = robot_sample_from_message(m);
  EXPECT_EQ(s.ipoc, 4208157u);
  EXPECT_TRUE(s.has_delay);
  EXPECT_EQ(s.delay, 3u);
  EXPECT_DOUBLE_EQ(s.joints_rad[1], -kPi / 2);
  EXPECT_DOUBLE_EQ(s.joints_rad[3], kPi);
  EXPECT_DOUBLE_EQ(s.joints_rad[5], -kPi / 6);
  ASSERT_TRUE(s.has_pose);
  EXPECT_DOUBLE_EQ(s.p_base_tcp_m[0], 1.0);
  EXPECT_DOUBLE_EQ(s.p_base_tcp_m[1], -0.25);
  EXPECT_DOUBLE_EQ(s.p_base_tcp_m[2], 1.5e-3);
  // Rz(90°)·Rx(90°): T's x axis is B's y, T's y axis is B's z, T's z axis is B's x.
  expect_vec(axis_in_base(s.R_base_tcp, 0), {0, 1, 0});
  expect_vec(axis_in_base(s.R_base_tcp, 1), {0, 0, 1});
  expect_vec(axis_in_base(s.R_base_tcp, 2), {1, 0, 0});

  // B = −30° alone (about y): T's x axis tilts up out of B's x-y plane (z = sin 30°).
  m.actual_pose = {0, 0, 0, 0, -30, 0};
  expect_vec(axis_in_base(robot_sample_from_message(m).R_base_tcp, 0), {std::cos(kPi / 6), 0, 0.5});
}

TEST(RsiSi, MessageWithoutRIstHasNoPose) {
  RobotMessage m;
  m.has_actual_pose = false;
  m.actual_pose = {1, 2, 3, 4, 5, 6};  // not read
  const samples::RobotSample s = robot_sample_from_message(m);
  EXPECT_FALSE(s.has_pose);
  EXPECT_EQ(s.p_base_tcp_m, (std::array<double, 3>{0, 0, 0}));
  EXPECT_EQ(s.R_base_tcp, samples::kIdentityRotation);
  EXPECT_FALSE(robot_message_from_sample(s).has_actual_pose);
}

TEST(RsiSi, MessageRoundTrips) {
  RobotMessage m;
  m.ipoc = 12;
  m.joints_deg = {10.5, -80, 95, -170, 40, 359};
  m.actual_pose = {1772.2163, 315.0421, 1500.0, 10.08, -45.5, 179.0};
  const RobotMessage back = robot_message_from_sample(robot_sample_from_message(m));
  EXPECT_EQ(back.ipoc, m.ipoc);
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(back.joints_deg[i], m.joints_deg[i], 1e-12);
  EXPECT_NEAR(back.actual_pose.x_mm, m.actual_pose.x_mm, 1e-12);
  EXPECT_NEAR(back.actual_pose.y_mm, m.actual_pose.y_mm, 1e-12);
  EXPECT_NEAR(back.actual_pose.z_mm, m.actual_pose.z_mm, 1e-12);
  EXPECT_NEAR(back.actual_pose.a_deg, m.actual_pose.a_deg, 1e-9);
  EXPECT_NEAR(back.actual_pose.b_deg, m.actual_pose.b_deg, 1e-9);
  EXPECT_NEAR(back.actual_pose.c_deg, m.actual_pose.c_deg, 1e-9);

  // SI → KUKA → SI: the rotation comes back as the same matrix.
  samples::RobotSample s = robot_sample_from_message(m);
  s.has_delay = true;
  s.delay = 7;
  const samples::RobotSample again = robot_sample_from_message(robot_message_from_sample(s));
  EXPECT_TRUE(again.has_delay);
  EXPECT_EQ(again.delay, 7u);
  for (int i = 0; i < 9; ++i) EXPECT_NEAR(again.R_base_tcp[i], s.R_base_tcp[i], 1e-12) << i;
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(again.p_base_tcp_m[i], s.p_base_tcp_m[i], 1e-15);
}

TEST(RsiSi, CorrectionToKukaKnownValues) {
  samples::RobotCorrection c;
  c.ipoc = 99;
  c.kind = samples::RobotCorrection::Kind::cartesian;
  c.translation_m = {1e-3, -2e-4, 0};
  const double a = kPi / 180;  // 1° about B's z
  c.R_correction = {std::cos(a), -std::sin(a), 0, std::sin(a), std::cos(a), 0, 0, 0, 1};
  Reply r = reply_from_correction(c);
  EXPECT_EQ(r.ipoc, 99u);
  ASSERT_TRUE(r.has_rkorr);
  EXPECT_FALSE(r.has_akorr);
  EXPECT_DOUBLE_EQ(r.rkorr.x_mm, 1.0);
  EXPECT_DOUBLE_EQ(r.rkorr.y_mm, -0.2);
  EXPECT_DOUBLE_EQ(r.rkorr.z_mm, 0.0);
  EXPECT_NEAR(r.rkorr.a_deg, 1.0, 1e-12);
  EXPECT_NEAR(r.rkorr.b_deg, 0.0, 1e-12);
  EXPECT_NEAR(r.rkorr.c_deg, 0.0, 1e-12);

  c.kind = samples::RobotCorrection::Kind::axes;
  c.axes_rad = {kPi / 180, 0, 0, 0, 0, -kPi / 2};
  r = reply_from_correction(c);
  EXPECT_FALSE(r.has_rkorr);
  ASSERT_TRUE(r.has_akorr);
  EXPECT_DOUBLE_EQ(r.akorr_deg[0], 1.0);
  EXPECT_DOUBLE_EQ(r.akorr_deg[5], -90.0);
  EXPECT_DOUBLE_EQ(r.rkorr.x_mm, 0.0);
}

TEST(RsiSi, KukaUnitsIntoTheCallersFieldsAreTheReplysAndOverwriteThem) {
  samples::RobotCorrection c;
  c.translation_m = {1e-3, -2e-4, 3e-4};
  const double a = kPi / 180;
  c.R_correction = {std::cos(a), -std::sin(a), 0, std::sin(a), std::cos(a), 0, 0, 0, 1};
  c.axes_rad = {kPi / 180, 0, 0, 0, 0, -kPi / 2};
  for (const auto kind :
       {samples::RobotCorrection::Kind::none, samples::RobotCorrection::Kind::cartesian,
        samples::RobotCorrection::Kind::axes}) {
    c.kind = kind;
    const Reply r = reply_from_correction(c);
    Correction rkorr{7, 7, 7, 7, 7, 7};  // stale content: every field is written
    std::array<double, 6> akorr_deg{7, 7, 7, 7, 7, 7};
    kuka_units_from_correction(c, rkorr, akorr_deg);
    const std::array<double, 6> rk{rkorr.x_mm,  rkorr.y_mm,  rkorr.z_mm,
                                   rkorr.a_deg, rkorr.b_deg, rkorr.c_deg};
    const std::array<double, 6> rr{r.rkorr.x_mm,  r.rkorr.y_mm,  r.rkorr.z_mm,
                                   r.rkorr.a_deg, r.rkorr.b_deg, r.rkorr.c_deg};
    for (std::size_t i = 0; i < 6; ++i) {
      EXPECT_EQ(rk[i], rr[i]) << static_cast<int>(kind) << " " << i;
      EXPECT_EQ(std::signbit(rk[i]), std::signbit(rr[i])) << static_cast<int>(kind) << " " << i;
      EXPECT_EQ(akorr_deg[i], r.akorr_deg[i]) << static_cast<int>(kind) << " " << i;
    }
  }
}

TEST(RsiSi, NoCorrectionIsPositiveZeros) {
  // A, B, C of the identity would give B = −0 (asin(−0)): "no correction" is written as zeros.
  samples::RobotCorrection none;
  none.ipoc = 5;
  const Reply r = reply_from_correction(none);
  ASSERT_TRUE(r.has_rkorr);
  EXPECT_FALSE(r.has_akorr);
  for (double v :
       {r.rkorr.x_mm, r.rkorr.y_mm, r.rkorr.z_mm, r.rkorr.a_deg, r.rkorr.b_deg, r.rkorr.c_deg}) {
    EXPECT_EQ(v, 0.0);
    EXPECT_FALSE(std::signbit(v));
  }
}

TEST(RsiSi, CorrectionRoundTrips) {
  samples::RobotCorrection c;
  c.kind = samples::RobotCorrection::Kind::cartesian;
  c.ipoc = 3;
  c.translation_m = {0.25e-3, -1e-4, 3e-5};
  RobotMessage tilt;  // any rotation: the one of A = 2°, B = −1°, C = 0.5°
  tilt.actual_pose = {0, 0, 0, 2, -1, 0.5};
  c.R_correction = robot_sample_from_message(tilt).R_base_tcp;
  const samples::RobotCorrection back = correction_from_reply(reply_from_correction(c));
  EXPECT_EQ(back.kind, c.kind);
  EXPECT_EQ(back.ipoc, c.ipoc);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(back.translation_m[i], c.translation_m[i], 1e-18);
  for (int i = 0; i < 9; ++i) EXPECT_NEAR(back.R_correction[i], c.R_correction[i], 1e-14) << i;

  // KUKA → SI → KUKA for an axis reply.
  Reply axes;
  axes.has_akorr = true;
  axes.akorr_deg = {0.01, -0.02, 0.03, 0, 0.5, -1};
  const Reply again = reply_from_correction(correction_from_reply(axes));
  EXPECT_TRUE(again.has_akorr);
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(again.akorr_deg[i], axes.akorr_deg[i], 1e-14);
}

}  // namespace
}  // namespace zerog::proto::rsi
