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

// While its input is not trusted (zerog-rt: the motion estimator settling), a closed gate stays
// closed and counts nothing toward confirming; once trusted it needs its whole `confirm` run;
// an open gate carries on and closes as before. ZeroGMotion holds both gates the same way and
// still checks the limits.
TEST(ContactGate, WhileItsInputIsNotTrustedAClosedGateStaysClosed) {
  const double dt = 0.012;
  const Eigen::Vector3d push(10, 0, 0);
  ContactGate g;
  for (int i = 0; i < 10; ++i) EXPECT_EQ(g.step(push, dt, 2.0, 1.0, 3, false).norm(), 0.0);
  EXPECT_FALSE(g.is_open());
  EXPECT_EQ(g.step(push, dt, 2.0, 1.0, 3).norm(), 0.0);
  EXPECT_EQ(g.step(push, dt, 2.0, 1.0, 3).norm(), 0.0);
  EXPECT_NEAR(g.step(push, dt, 2.0, 1.0, 3).x(), 30.0, 1e-12) << "the held cycles add nothing";
  EXPECT_NEAR(g.step(push, dt, 2.0, 1.0, 3, false).x(), 10.0, 1e-15) << "open carries on";
  for (int i = 0; i < 3; ++i) g.step(Eigen::Vector3d(0.5, 0, 0), dt, 2.0, 1.0, 3, false);
  EXPECT_FALSE(g.is_open());

  ZeroGMotion m(body100(), loose(), Eigen::Vector3d::Zero());
  m.reset(Eigen::Vector3d::Zero(), Eigen::Quaterniond::Identity());
  PoseCorrection c;
  for (int i = 0; i < 10; ++i) EXPECT_EQ(m.step(push, Eigen::Vector3d(0, 0, 2), kDt, c, false), 0u);
  EXPECT_FALSE(m.in_contact());
  EXPECT_EQ(m.body().state().v_world_mps.norm(), 0.0);
  EXPECT_EQ(m.body().state().L_world_kgm2ps.norm(), 0.0);
  EXPECT_TRUE(m.step(Eigen::Vector3d(500, 0, 0), Eigen::Vector3d::Zero(), kDt, c, false) &
              kForceOverLimit);
  for (int i = 0; i < 3; ++i) m.step(push, Eigen::Vector3d(0, 0, 2), kDt, c);
  EXPECT_TRUE(m.in_contact());
  EXPECT_GT(m.body().state().v_world_mps.norm(), 0.0);
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

// The torque gate judges torque_gate_input: a force the force gate rejects is no force, so its
// lever about the centre of mass is no torque (seed 11's false contact in ten quiet minutes:
// |F| 0.46-0.55 N under a 0.61 N force gate, 0.25 m below the centre of mass, made 0.15-0.17 N·m
// about it against a 0.147 N·m torque gate, while the torque at the sensor was 0.04 N·m). A
// couple still turns the body, and a push the force gate counts still turns it about the centre
// of mass, from the same cycle and with the whole angular impulse.
TEST(ZeroGMotion, TheTorqueGateJudgesTheForceTheForceGateCounts) {
  MotionLimits l = loose();
  l.force_deadband_N = 0.61, l.torque_deadband_Nm = 0.147;
  const Eigen::Vector3d com(0.0, 0.0, 0.25);
  PoseCorrection c;
  {  // 0.55 N along x for 10 cycles: under the force gate; about the centre of mass 0.1375 N·m
     // with the sensor's torque noise of 0.03 N·m on y on top: 0.1675 N·m.
    ZeroGMotion m(body100(), l, com);
    m.reset(Eigen::Vector3d::Zero(), Eigen::Quaterniond::Identity());
    for (int i = 0; i < 10; ++i)
      ASSERT_EQ(m.step(Eigen::Vector3d(0.55, 0, 0), Eigen::Vector3d(0, 0.03, 0), kDt, c),
                kLimitNone);
    EXPECT_FALSE(m.in_contact());
    EXPECT_EQ(m.body().state().L_world_kgm2ps, Eigen::Vector3d::Zero());
    EXPECT_EQ(m.body().state().v_world_mps, Eigen::Vector3d::Zero());
  }
  {  // A couple of 0.15 N·m about x, no force: confirmed in the third cycle, all three kept.
    ZeroGMotion m(body100(), l, com);
    m.reset(Eigen::Vector3d::Zero(), Eigen::Quaterniond::Identity());
    for (int i = 0; i < 3; ++i)
      m.step(Eigen::Vector3d::Zero(), Eigen::Vector3d(0.15, 0, 0), kDt, c);
    EXPECT_TRUE(m.in_contact());
    EXPECT_NEAR(m.body().state().L_world_kgm2ps.x(), 3 * 0.15 * kDt, 1e-12);
  }
  {  // 10 N along x through the sensor origin (no torque there), 0.25 m below the centre of
     // mass: the force gate counts it, so the torque about the centre of mass, (0, -2.5, 0) N·m,
     // is judged and passed, from the cycle the force is confirmed, with the whole impulse.
    ZeroGMotion m(body100(), l, com);
    m.reset(Eigen::Vector3d::Zero(), Eigen::Quaterniond::Identity());
    for (int i = 0; i < 3; ++i) m.step(Eigen::Vector3d(10, 0, 0), Eigen::Vector3d::Zero(), kDt, c);
    const BodyState s = m.body().state();
    EXPECT_NEAR(s.v_world_mps.x(), 3 * 10 * kDt / 100.0, 1e-12);
    EXPECT_NEAR(s.L_world_kgm2ps.y(), -3 * 2.5 * kDt, 1e-12);
  }
  // The judged torque itself. With a force at or under the threshold, the smaller of the
  // torque about the sensor origin and about the centre of mass: the sensor's force noise
  // shows about the centre of mass, the prediction's acceleration error (a force at the centre
  // of mass) about the sensor origin.
  const Eigen::Vector3d M(0.01, 0.02, 0.03), F(0.5, 0, 0);
  const auto about_com = [&](const Eigen::Vector3d& m) {
    return torque_about(m, F, Eigen::Vector3d::Zero(), com);
  };
  EXPECT_EQ(torque_gate_input(M, about_com(M), F, 0.61), M);
  const Eigen::Vector3d lever = com.cross(F);  // 0.5 N acting at the centre of mass
  EXPECT_LT(torque_gate_input(M + lever, about_com(M + lever), F, 0.61).norm(), 1e-15 + M.norm());
  EXPECT_EQ(torque_gate_input(M + lever, about_com(M + lever), F, 0.61), about_com(M + lever));
  // Above the threshold, or with no force gate, about the centre of mass.
  EXPECT_EQ(torque_gate_input(M, about_com(M), F, 0.4), about_com(M));
  EXPECT_EQ(torque_gate_input(M, about_com(M), F, 0.0), about_com(M));
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
