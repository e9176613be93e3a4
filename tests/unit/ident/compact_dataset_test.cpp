// The compact dataset (issue 16): Dataset keeps the logged quaternion, the time and the joint
// angles, and forms the pose signals (rotation matrix, time since start) and the joint velocities
// on demand. These tests hold it to the formulas that filled the stored fields before, bit for
// bit, on simulator logs of several seeds, and hold its memory per sample to a stated bound.
#include <gtest/gtest.h>

#include <array>
#include <string>

#include "zerog/ident/dataset.hpp"
#include "zerog/model/predict.hpp"
#include "zerog/sim/design.hpp"
#include "zerog/sim/simulator.hpp"

namespace zerog::ident {
namespace {

using model::Effect;

// A simulator run of `seconds` with every library effect on (seed `seed`).
formats::Log sim_log(unsigned seed, double seconds) {
  sim::SimConfig c = sim::default_sim_config(seed);
  c.effects = sim::parse_sim_effects(
      "all,-joint6_friction,-swivel_viscous,-hose_drag,"
      "-dress_pack_bend");
  c.duration_limit_s = seconds;
  return sim::RigSimulator(c, sim::make_design(sim::DesignOptions{}).points_rad).run().log;
}

// The pose signals of sample i as make_dataset stored them before issue 16 (the formula the
// on-demand Dataset::pose replaced), straight from the log.
model::PoseSignals stored_pose(const formats::Log& log, std::size_t i) {
  const formats::Sample& s = log.samples[i];
  model::PoseSignals p;
  p.R_base_sensor = s.q_base_sensor.normalized().toRotationMatrix();
  p.t_rel_s = s.t_s - log.samples.front().t_s;
  p.temperature_C = log.columns.temperature ? s.temperature_C : model::kTemperatureReferenceC;
  p.joints_rad = s.joints_rad;
  return p;
}

// The joint velocities as make_dataset stored them before: backward differences, row 0 taking
// row 1's, zero without joints or time.
std::array<double, 6> stored_joint_vel(const formats::Log& log, std::size_t i) {
  std::array<double, 6> v{};
  if (log.columns.static_rows || !log.columns.joints) return v;
  const std::size_t r = i == 0 ? 1 : i;
  const formats::Sample &s = log.samples[r], &s0 = log.samples[r - 1];
  const double dt = s.t_s - s0.t_s;
  for (std::size_t j = 0; j < 6; ++j) v[j] = (s.joints_rad[j] - s0.joints_rad[j]) / dt;
  return v;
}

// Every library effect with parameters away from zero (an IMU time offset too, so that the IMU
// rows are interpolated). With linear_inertia the payload's weight comes from the accelerometer
// (specific force), not from the attitude: `accelerometer` false leaves it (and what builds on
// it) out, so that the rotation matrix reaches the prediction.
model::ModelParams all_effects(bool accelerometer) {
  model::ModelParams p;
  for (Effect e : model::kAllEffects) {
    bool needs_accelerometer = e == Effect::linear_inertia;
    for (const auto& req : model::info(e).requires_effects)
      needs_accelerometer = needs_accelerometer || req == Effect::linear_inertia;
    if (needs_accelerometer && !accelerometer) continue;
    p.effects.add(e);
    double* b = p.block(e);
    for (int k = 0; k < model::info(e).num_params; ++k) b[k] = 1e-3 * (k + 1);
  }
  double* g = p.block(Effect::gravity);
  g[0] = 100.0, g[1] = 0.01, g[2] = -0.02, g[3] = 0.15;
  if (p.effects.has(Effect::imu_time_offset)) p.block(Effect::imu_time_offset)[0] = 0.004;
  return p;
}

// First row where `same(i)` fails; -1 if none.
template <typename F>
long first_row_not(std::size_t n, F same) {
  for (std::size_t i = 0; i < n; ++i)
    if (!same(i)) return static_cast<long>(i);
  return -1;
}

TEST(CompactDataset, PredictionsAndSignalsEqualTheStoredFormulasBitForBit) {
  const std::array<model::ModelParams, 2> models = {all_effects(true), all_effects(false)};
  ASSERT_FALSE(models[1].effects.has(Effect::linear_inertia));
  ASSERT_TRUE(models[1].effects.has(Effect::gravity) && models[1].effects.has(Effect::cable));
  for (unsigned seed : {1u, 2u, 3u}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    formats::Log log = sim_log(seed, 30.0);
    ASSERT_TRUE(log.columns.joints && log.columns.temperature && !log.columns.static_rows);
    // The same log without temperature and joints: the constants and zeros of those cases.
    formats::Log partial = log;
    partial.columns.temperature = false;
    partial.columns.joints = false;
    for (const formats::Log* l : {&log, &partial}) {
      const Dataset d = make_dataset(*l);
      ASSERT_EQ(d.size(), l->samples.size());
      const std::size_t n = d.size();
      EXPECT_EQ(first_row_not(n,
                              [&](std::size_t i) {
                                const model::PoseSignals a = d.pose(i), b = stored_pose(*l, i);
                                return a.R_base_sensor == b.R_base_sensor &&
                                       a.t_rel_s == b.t_rel_s &&
                                       a.temperature_C == b.temperature_C &&
                                       a.joints_rad == b.joints_rad;
                              }),
                -1)
          << "pose";
      EXPECT_EQ(
          first_row_not(
              n, [&](std::size_t i) { return d.joint_vel_radps(i) == stored_joint_vel(*l, i); }),
          -1)
          << "joint velocities";
      // The prediction (and so the residual, measured − predicted) of every sample, each model
      // with the pose signals as they were stored.
      for (const model::ModelParams& params : models) {
        const auto ptrs = model::pointers(params);
        const double* tau = params.effects.has(Effect::imu_time_offset)
                                ? params.block(Effect::imu_time_offset)
                                : nullptr;
        EXPECT_EQ(first_row_not(n,
                                [&](std::size_t i) {
                                  const Wrench want = model::predict_wrench<double>(
                                      params.effects, ptrs, stored_pose(*l, i),
                                      d.imu_at<double>(i, tau), d.rig);
                                  const Wrench got = predict(params, d, i);
                                  return got == want && d.measured[i] - got == d.measured[i] - want;
                                }),
                  -1)
            << "prediction, linear_inertia " << params.effects.has(Effect::linear_inertia);
      }
    }
  }
}

// The bytes a sample costs, from the vectors' capacity (make_dataset reserves the sample count):
// with every column group t_s 8, quaternion 32, temperature 8, joints 48, IMU 72, wrench 48,
// motion flag 1, position 24 = 241 (337 before issue 16: the matrix, t_rel_s and the joint
// velocities stored); 233 without the temperature column.
TEST(CompactDataset, BytesPerSampleStayUnderTheBound) {
  const formats::Log log = sim_log(1, 30.0);
  const Dataset d = make_dataset(log);
  const double per_sample = static_cast<double>(d.bytes()) / static_cast<double>(d.size());
  EXPECT_LE(per_sample, 241.0) << "bytes a sample";
  formats::Log no_temperature = log;
  no_temperature.columns.temperature = false;
  const Dataset t = make_dataset(no_temperature);
  EXPECT_LE(static_cast<double>(t.bytes()) / static_cast<double>(t.size()), 233.0)
      << "bytes a sample without temperature";
}

}  // namespace
}  // namespace zerog::ident
