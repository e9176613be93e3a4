// Acceptance of the learned residual (the results table, zerog::learn::run_results): on a
// simulated KR210/100 kg run whose truth holds joint6_friction (outside the physics library) and
// cable, physics + residual network (float) beats physics only and both paper methods on
// held-out RMS, force and torque. Training budgets are cut (the table itself uses the defaults)
// to keep the test near a minute.
#include <gtest/gtest.h>

#include <string>

#include "zerog/learn/results.hpp"

namespace zerog {
namespace {

TEST(Results, PhysicsPlusResidualBeatsPhysicsAndBothPaperMethodsOnHeldOutData) {
  learn::ResultsOptions o;
  o.seed = 42;
  o.max_iterations = 40;
  o.max_train_samples = 2500;
  o.adam_iterations = 5000;
  const learn::Results r = learn::run_results(o);
  const std::string table = learn::format_markdown(r);
  const auto& phys = r.method("physics");
  // The firmware's quantised inference, not only the float reference, beats the others.
  for (const char* mine : {"residual", "residual-quantised"}) {
    const auto& res = r.method(mine);
    ASSERT_TRUE(res.available) << mine << ": " << res.note;
    for (const char* other : {"physics", "paper-bp", "paper-zp"}) {
      const auto& m = r.method(other);
      ASSERT_TRUE(m.available) << other;
      EXPECT_LT(res.all.force_rms, m.all.force_rms) << mine << " vs " << other << "\n" << table;
      EXPECT_LT(res.all.torque_rms, m.all.torque_rms) << mine << " vs " << other << "\n" << table;
    }
  }
  // Quantised against float on the held-out data: within 0.1 N and 0.01 N*m (the issue's
  // bound); zerog::infer's own tests hold 1/8 of an Omega191 count on random inputs.
  EXPECT_GE(r.quantised_vs_float_max_N, 0.0);
  EXPECT_LE(r.quantised_vs_float_max_N, 0.1);
  EXPECT_LE(r.quantised_vs_float_max_Nm, 0.01);
  const auto& res = r.method("residual-quantised");
  // The friction is a torque: the network removes most of what physics leaves above the
  // true-model reference.
  const auto& reference = r.method("true-model-reference");
  EXPECT_LT(res.all.torque_rms - reference.all.torque_rms,
            0.3 * (phys.all.torque_rms - reference.all.torque_rms))
      << table;
  // No method beats the sensor floor (the F/T noise alone), and it lies below the reference.
  const auto& sensor = r.method("sensor-floor");
  ASSERT_TRUE(sensor.available);
  for (const auto& m : r.methods) {
    if (!m.available || m.key == "sensor-floor") continue;
    EXPECT_GT(m.stat.force_rms, sensor.stat.force_rms) << m.key << "\n" << table;
    EXPECT_GT(m.moving.force_rms, sensor.moving.force_rms) << m.key << "\n" << table;
    EXPECT_GT(m.stat.torque_rms, sensor.stat.torque_rms) << m.key << "\n" << table;
    EXPECT_GT(m.moving.torque_rms, sensor.moving.torque_rms) << m.key << "\n" << table;
  }
  EXPECT_NE(table.find("| sensor floor ("), std::string::npos) << table;
  EXPECT_NE(table.find("| true-model reference ("), std::string::npos) << table;
  // The ladder reaches the cable (the physics model can fit it) and the quantised column is
  // marked, whether or not the firmware inference is linked yet.
  EXPECT_NE(r.physics_effects.find("cable"), std::string::npos) << r.physics_effects;
  EXPECT_NE(table.find("quantised"), std::string::npos);
  EXPECT_NE(table.find("000_… Table 5"), std::string::npos);
  EXPECT_NE(table.find("001_… Table 4"), std::string::npos);
}

}  // namespace
}  // namespace zerog
