// robot::advance_deflection, the one integration of an elastic joint (firmware/robot): the
// δ̈ it returns is the one its steps moved δ̇ with, so that the motion estimator's link
// acceleration (J δ̈) has no bias of its own (proto/loop.md, "The deflection's acceleration").
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "zerog/robot/robot_model.hpp"
#include "zerog/sim/elastic.hpp"

namespace zerog::robot {
namespace {

// A4 of the KR 210 file: the stiffest mode, where a half step costs the most (ω² h / 2).
JointElasticity wrist() { return sim::kr210_elasticity().joints[3]; }

TEST(AdvanceDeflection, ASteadilyTurningLoadGivesNoAcceleration) {
  // The elastic glide, measured: A4's load turned at about 100 N·m/s, δ̇ 1e-4...2e-4 rad/s, and
  // δ̈ evaluated after the last step was 5e-3...1e-2 rad/s² (ω² h δ̇ / 2 at 1 ms) where the
  // truth had 6e-5. On a load ramp the deflection's true acceleration is zero once the mode
  // has settled on the ramp.
  const JointElasticity j = wrist();
  const double rate_Nm_per_s = -100.0, row_s = 0.012;
  double delta = 0.0, delta_dot = 0.0, accel = 0.0, load = 0.0;
  for (int row = 0; row < 400; ++row) {  // 4.8 s: the mode (55 Hz, ζ 0.05) has settled
    const double next = load + rate_Nm_per_s * row_s;
    accel = advance_deflection(j, delta, delta_dot, row_s, 1e-3, 0.0, 0.0, load, next);
    load = next;
  }
  const double ramp = rate_Nm_per_s / j.stiffness_Nm_per_rad;  // δ̇ on the ramp
  EXPECT_NEAR(delta_dot, ramp, 1e-3 * std::abs(ramp));
  const double w = 2.0 * std::numbers::pi * j.mode_hz;
  const double half_step_bias = w * w * 1e-3 * std::abs(ramp) / 2.0;  // the old answer
  EXPECT_GT(half_step_bias, 5e-3);
  EXPECT_LT(std::abs(accel), 1e-3 * half_step_bias) << "δ̈ " << accel;
}

TEST(AdvanceDeflection, ReturnsTheAccelerationTheSimulatedArmHas) {
  // The emulator's arm (sim::ElasticArm::step, the truth of the HIL) and the estimator's
  // integration, under the same motor acceleration and load held over a 12 ms row (1 ms steps
  // each): after a jolt both ring the same, and the δ̈ each reports agrees.
  sim::ElasticityConfig config = sim::kr210_elasticity();
  sim::ElasticArm arm(config);
  sim::JointVector load{};
  load[3] = -80.0;
  arm.settle(0.0, load);
  const JointElasticity j = config.joints[3];
  double delta = load[3] / j.stiffness_Nm_per_rad, delta_dot = 0.0;
  sim::JointState motor;
  double worst = 0.0, largest = 0.0;
  for (int row = 0; row < 50; ++row) {
    motor.qdd_radps2[3] = row < 3 ? 2.0 : 0.0;  // a jolt, then free ringing
    load[3] = -80.0 - 0.5 * row;                // and the load turning
    // ElasticArm::step holds the row's load; give advance_deflection the same (both ends).
    const sim::JointState link = arm.step(motor, 0.012, load);
    const double accel = advance_deflection(j, delta, delta_dot, 0.012, 1e-3, motor.qdd_radps2[3],
                                            motor.qdd_radps2[3], load[3], load[3]);
    const double truth = link.qdd_radps2[3] - motor.qdd_radps2[3];
    EXPECT_NEAR(delta, arm.deflection_rad()[3], 1e-12);
    worst = std::max(worst, std::abs(accel - truth));
    largest = std::max(largest, std::abs(truth));
  }
  EXPECT_GT(largest, 0.5);  // it rang
  EXPECT_LT(worst, 1e-9 * largest) << "largest δ̈ " << largest;
}

}  // namespace
}  // namespace zerog::robot
