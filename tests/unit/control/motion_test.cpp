#include "zerog/control/motion.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace zerog::control {
namespace {

constexpr double kDt = 0.004;

BodyParams body100() {
  BodyParams b;
  b.mass_kg = 100.0;
  b.inertia_body_kgm2 = Eigen::Vector3d(4.0, 6.0, 8.0).asDiagonal();
  return b;
}

MotionLimits loose() {
  MotionLimits l;
  l.max_speed_mps = 10, l.max_angular_speed_radps = 10, l.max_accel_mps2 = 100,
  l.max_angular_accel_radps2 = 100;
  l.workspace_min_m = Eigen::Vector3d::Constant(-100),
  l.workspace_max_m = Eigen::Vector3d::Constant(100);
  return l;
}

TEST(Deadband, ZeroInsideContinuousAtTheEdge) {
  EXPECT_EQ(deadband(Eigen::Vector3d(1, 1, 0), 2.0).norm(), 0.0);
  EXPECT_NEAR(deadband(Eigen::Vector3d(3, 0, 0), 2.0).x(), 1.0, 1e-15);
  EXPECT_NEAR(deadband(Eigen::Vector3d(2.0 + 1e-9, 0, 0), 2.0).norm(), 1e-9, 1e-12);
}

TEST(ContactGate, KeepsTheWholeImpulseOfAPushAndPassesNoNoise) {
  ContactGate g;
  const double dt = 0.012;
  // Confirming cycles pass nothing, the opening cycle releases their impulse.
  EXPECT_EQ(g.step(Eigen::Vector3d(10, 0, 0), dt, 2.0, 1.0, 3).norm(), 0.0);
  EXPECT_EQ(g.step(Eigen::Vector3d(10, 0, 0), dt, 2.0, 1.0, 3).norm(), 0.0);
  EXPECT_FALSE(g.is_open());
  EXPECT_NEAR(g.step(Eigen::Vector3d(10, 0, 0), dt, 2.0, 1.0, 3).x(), 30.0, 1e-12);
  EXPECT_TRUE(g.is_open());
  // Open: passes through, including values below the threshold, until it closes.
  EXPECT_NEAR(g.step(Eigen::Vector3d(1.5, 0, 0), dt, 2.0, 1.0, 3).x(), 1.5, 1e-15);
  for (int i = 0; i < 3; ++i) g.step(Eigen::Vector3d(0.5, 0, 0), dt, 2.0, 1.0, 3);
  EXPECT_FALSE(g.is_open());
  // A spike above the threshold that does not last passes nothing and is forgotten.
  EXPECT_EQ(g.step(Eigen::Vector3d(0, 5, 0), dt, 2.0, 1.0, 3).norm(), 0.0);
  EXPECT_EQ(g.step(Eigen::Vector3d(0, 0.1, 0), dt, 2.0, 1.0, 3).norm(), 0.0);
  EXPECT_EQ(g.step(Eigen::Vector3d(0, 5, 0), dt, 2.0, 1.0, 3).norm(), 0.0);
  EXPECT_EQ(g.step(Eigen::Vector3d(0, 5, 0), dt, 2.0, 1.0, 3).norm(), 0.0);
  EXPECT_NEAR(g.step(Eigen::Vector3d(0, 5, 0), dt, 2.0, 1.0, 3).y(), 15.0, 1e-12);
  // Impulse of a half-sine push of 40 N over 0.5 s: all of it but the edges below 2 N.
  ContactGate h;
  double J = 0.0, J_true = 0.0;
  for (int i = 0; i < 100; ++i) {
    const double t = (i + 0.5) * dt;
    const double F = t < 0.5 ? 40.0 * std::sin(3.141592653589793 * t / 0.5) : 0.0;
    J_true += F * dt;
    J += h.step(Eigen::Vector3d(F, 0, 0), dt, 2.0, 1.0, 3).x() * dt;
  }
  EXPECT_NEAR(J / J_true, 1.0, 0.003);
  // Disabled with a zero threshold.
  ContactGate off;
  EXPECT_EQ(off.step(Eigen::Vector3d(0.1, 0, 0), dt, 0.0, 0.0, 3).x(), 0.1);
}

TEST(ZeroGMotion, PushThroughTheCentreOfMassTranslatesOnly) {
  MotionLimits l = loose();
  l.force_deadband_N = 0;
  ZeroGMotion m(body100(), l, Eigen::Vector3d(0, 0, 0.3));
  m.reset(Eigen::Vector3d(1.0, 0.0, 1.2), Eigen::Quaterniond::Identity());
  // 50 N along x through the virtual centre of mass (0, 0, 0.3): torque about the sensor origin
  // is c × F = (0, 15, 0).
  const Eigen::Vector3d F(50, 0, 0), M = Eigen::Vector3d(0, 0, 0.3).cross(F);
  Eigen::Vector3d moved = Eigen::Vector3d::Zero();
  PoseCorrection c;
  for (int i = 0; i < 100; ++i) {  // 0.4 s push: J = 20 N·s → 0.2 m/s
    ASSERT_EQ(m.step(F, M, kDt, c), kLimitNone);
    moved += c.translation_m;
    EXPECT_LT(c.rotation_rad.norm(), 1e-12);
  }
  EXPECT_NEAR(m.body().state().v_world_mps.x(), 0.2, 1e-12);
  EXPECT_NEAR(moved.x(), 0.5 * 0.2 * 0.4, 1e-12);
  EXPECT_NEAR((m.sensor_position_world() - Eigen::Vector3d(1.0 + moved.x(), 0, 1.2)).norm(), 0.0,
              1e-12);
}

TEST(ZeroGMotion, DampingMakesVelocityAndAngularMomentumDecayExponentially) {
  MotionLimits l = loose();
  l.force_deadband_N = 0;
  l.torque_deadband_Nm = 0;
  l.linear_damping_per_s = 0.5;
  l.angular_damping_per_s = 2.0;
  ZeroGMotion m(body100(), l, Eigen::Vector3d::Zero());
  m.reset(Eigen::Vector3d(1.0, 0.0, 1.2), Eigen::Quaterniond::Identity());
  PoseCorrection c;
  ASSERT_EQ(m.step(Eigen::Vector3d(250, 0, 0), Eigen::Vector3d(0, 0, 25), kDt, c), kLimitNone);
  const Eigen::Vector3d v0 = m.body().state().v_world_mps;
  const Eigen::Vector3d L0 = m.body().state().L_world_kgm2ps;
  ASSERT_GT(v0.norm(), 0.0);
  const int n = 250;  // 1 s of free motion
  for (int i = 0; i < n; ++i) m.step(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), kDt, c);
  EXPECT_NEAR(m.body().state().v_world_mps.norm() / v0.norm(), std::exp(-0.5 * n * kDt), 1e-12);
  EXPECT_NEAR(m.body().state().L_world_kgm2ps.norm() / L0.norm(), std::exp(-2.0 * n * kDt), 1e-12);
}

TEST(ZeroGMotion, OffCentrePushAlsoTurnsAboutTheVirtualCentreOfMass) {
  MotionLimits l = loose();
  l.force_deadband_N = 0, l.torque_deadband_Nm = 0;
  ZeroGMotion m(body100(), l, Eigen::Vector3d(0, 0, 0.3));
  m.reset(Eigen::Vector3d::Zero(), Eigen::Quaterniond::Identity());
  // Force along x at the sensor origin: 0.3 m below the centre of mass → torque about it
  // (0,0,−0.3) × (F,0,0) = (0, −0.3 F, 0).
  PoseCorrection c;
  m.step(Eigen::Vector3d(10, 0, 0), Eigen::Vector3d::Zero(), kDt, c);
  const Eigen::Vector3d L = m.body().state().L_world_kgm2ps;
  EXPECT_NEAR(L.y(), -0.3 * 10 * kDt, 1e-12);
  EXPECT_NEAR(L.x(), 0.0, 1e-15);
  Eigen::Vector3d turned = c.rotation_rad;
  for (int i = 0; i < 99; ++i) {
    m.step(Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), kDt, c);
    turned += c.rotation_rad;
  }
  EXPECT_LT(turned.y(), 0.0);  // turns about −y at about L / Iyy
  EXPECT_NEAR(turned.y(), -0.3 * 10 * kDt / 6.0 * 99 * kDt, 1e-4);
}

TEST(ZeroGMotion, ForceOverTheLimitStopsTheBody) {
  ZeroGMotion m(body100(), loose(), Eigen::Vector3d::Zero());
  m.reset(Eigen::Vector3d::Zero(), Eigen::Quaterniond::Identity());
  PoseCorrection c;
  const std::uint32_t f = m.step(Eigen::Vector3d(500, 0, 0), Eigen::Vector3d::Zero(), kDt, c);
  EXPECT_TRUE(f & kForceOverLimit);
  EXPECT_EQ(c.translation_m.norm(), 0.0);
  EXPECT_EQ(m.body().state().v_world_mps.norm(), 0.0);
}

TEST(ZeroGMotion, SpeedAccelerationAndWorkspaceLimits) {
  MotionLimits l = loose();
  l.force_deadband_N = 0;
  l.max_speed_mps = 0.1;
  l.max_accel_mps2 = 1.0;
  l.workspace_max_m = Eigen::Vector3d(0.05, 100, 100);
  ZeroGMotion m(body100(), l, Eigen::Vector3d::Zero());
  m.reset(Eigen::Vector3d::Zero(), Eigen::Quaterniond::Identity());
  PoseCorrection c;
  std::uint32_t seen = 0;
  for (int i = 0; i < 200; ++i) {
    seen |= m.step(Eigen::Vector3d(300, 0, 0), Eigen::Vector3d::Zero(), kDt, c);
    EXPECT_LE(m.body().state().v_world_mps.norm(), 0.1 + 1e-12);
    EXPECT_LE(c.translation_m.norm(), 0.1 * kDt + 1e-12);
    EXPECT_LE(m.body().state().p_world_m.x(), 0.05 + 1e-12);
  }
  EXPECT_TRUE(seen & kAccelLimited);  // 300 N / 100 kg = 3 m/s² > 1 m/s²
  EXPECT_TRUE(seen & kSpeedLimited);
  EXPECT_TRUE(seen & kWorkspaceLimited);
}

TEST(ZeroGMotion, AngularSpeedAndAccelerationLimits) {
  MotionLimits l = loose();
  l.torque_deadband_Nm = 0;
  l.max_angular_speed_radps = 0.2;
  l.max_angular_accel_radps2 = 1.0;
  ZeroGMotion m(body100(), l, Eigen::Vector3d::Zero());
  m.reset(Eigen::Vector3d::Zero(), Eigen::Quaterniond::Identity());
  PoseCorrection c;
  std::uint32_t seen = 0;
  for (int i = 0; i < 200; ++i) {
    seen |= m.step(Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, 40), kDt, c);  // 10 rad/s² free
    EXPECT_LE(m.body().omega_world().norm(), 0.2 + 1e-9);
    EXPECT_LE(c.rotation_rad.norm(), 0.2 * kDt + 1e-9);
  }
  EXPECT_TRUE(seen & kAngularAccelLimited);
  EXPECT_TRUE(seen & kAngularSpeedLimited);
}

}  // namespace
}  // namespace zerog::control
