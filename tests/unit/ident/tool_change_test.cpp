// Tool change (paper 001_… §3.2, Appendix A): the sensor model of a normal calibration run is
// frozen and only the new tool's mass and centre of mass are fitted on the static poses of the
// 15 attitudes of 001_… Appendix C, all on the independent simulator with its default noise.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>

#include "zerog/ident/fit.hpp"
#include "zerog/sim/design.hpp"
#include "zerog/sim/simulator.hpp"

namespace zerog::ident {
namespace {

using model::Effect;
constexpr double kDeg = std::numbers::pi / 180.0;

// A figure of the "Tool change" paragraph (docs/learned-residual.md), in the test's JSON output
// (--gtest_output=json: scripts/figures.py tool-change writes and checks the paragraph from it).
void record_figure(const std::string& key, double value) {
  char text[32];
  std::snprintf(text, sizeof text, "%.17g", value);
  ::testing::Test::RecordProperty("fig_" + key, text);
}

bool has_warning(const FitResult& r, const std::string& kind) {
  for (const auto& w : r.warnings)
    if (w.kind == kind) return true;
  return false;
}

// The new tool: 60 kg, centre of mass moved by (+50, −40, −70) mm from the 100 kg payload's.
sim::SimConfig tool_config(const sim::SimConfig& sensor, std::uint64_t noise_seed) {
  sim::SimConfig c = sim::default_sim_config(noise_seed);  // other noise
  c.params = sensor.params;                                // the same sensor (bias, …)
  c.effects = sensor.effects;
  c.payload.mass_kg = 60.0;
  c.payload.com_sensor_m = Eigen::Vector3d(0.08, -0.06, 0.18);
  c.payload.inertia_com_sensor_kgm2 = sim::box_inertia_kgm2(60.0);
  return c;
}

sim::AttitudeDesign appendix_c_design() {
  sim::AttitudeDesignOptions o;
  o.arm_rad = {-90 * kDeg, -80 * kDeg, 125 * kDeg};  // zerog design --attitudes' default --arm
  return sim::design_from_attitudes(
      sim::read_attitudes(std::string(ZEROG_SOURCE_DIR) +
                          "/calib/poses/001_appendix_c_attitudes.csv"),
      o);
}

TEST(ToolChange, RecoversMassAndCentreOfMassWithTheSensorModelFrozen) {
  const sim::AttitudeDesign poses = appendix_c_design();
  ASSERT_EQ(poses.design.points_rad.size(), 15u);
  sim::DesignOptions oa;
  oa.kind = sim::DesignKind::oa;
  const auto calibration_points = sim::make_design(oa).points_rad;
  {
    const sim::SimConfig tool = tool_config(sim::default_sim_config(1), 1);
    const Eigen::Vector3d shift =
        tool.payload.com_sensor_m - sim::default_sim_config(1).payload.com_sensor_m;
    record_figure("tool_mass_kg", tool.payload.mass_kg);
    for (int k = 0; k < 3; ++k)
      record_figure(std::string("com_shift_") + "xyz"[k] + "_mm", 1000.0 * shift[k]);
  }
  for (std::uint64_t seed : {1u, 2u, 3u}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    // 1. The sensor model from a normal calibration run with the 100 kg payload.
    const sim::SimConfig sensor = sim::default_sim_config(seed);
    const Dataset cal = make_dataset(sim::RigSimulator(sensor, calibration_points).run().log);
    FitOptions fo;
    fo.effects = model::kDefaultModel;
    const FitResult base = fit(cal, fo);
    ASSERT_TRUE(base.usable) << base.termination;

    // 2. A new tool through the 15 attitudes; only gravity is re-identified.
    const sim::RigSimulator tool_sim(tool_config(sensor, seed + 100), poses.design.points_rad);
    const Dataset run = make_dataset(tool_sim.run().log);
    const ToolChangeResult tc = fit_tool_change(run, base.params, {});
    ASSERT_TRUE(tc.fit.usable) << tc.fit.termination;
    EXPECT_EQ(tc.dwells, 15u);
    EXPECT_GT(tc.static_samples, 15u * 150u);  // 2 s dwells of 12 ms rows
    EXPECT_LT(tc.static_samples, run.size());
    EXPECT_EQ(tc.fit.num_params, 4);
    EXPECT_GT(tc.spread_deg, 30.0);
    EXPECT_FALSE(has_warning(tc.fit, "poses_alike"));
    EXPECT_FALSE(has_warning(tc.fit, "poorly_identified"));
    EXPECT_FALSE(has_warning(tc.fit, "rank_deficient"));
    EXPECT_TRUE(has_warning(tc.fit, "kept_inertia"));

    const double* g = tc.fit.params.block(Effect::gravity);
    const double mass_error = (g[0] - 60.0) / 60.0;
    const Eigen::Vector3d com_error =
        Eigen::Vector3d(g[1], g[2], g[3]) - tool_sim.config().payload.com_sensor_m;
    std::printf(
        "seed %llu: mass %.5f kg (error %+.4f %%), centre of mass error (%+.4f, %+.4f, "
        "%+.4f) mm; paper 001: 8.5 %%\n",
        static_cast<unsigned long long>(seed), g[0], 100.0 * mass_error, 1000.0 * com_error.x(),
        1000.0 * com_error.y(), 1000.0 * com_error.z());
    const std::string key = "seed" + std::to_string(seed) + "_";
    record_figure(key + "mass_error_pct", 100.0 * mass_error);
    record_figure(key + "com_error_mm", 1000.0 * com_error.cwiseAbs().maxCoeff());
    EXPECT_LT(std::abs(mass_error), 0.01);              // the acceptance: 1 %
    EXPECT_LT(com_error.cwiseAbs().maxCoeff(), 0.002);  // and 2 mm
    ASSERT_TRUE(tc.fit.std.has_value());
    for (int k = 0; k < 4; ++k) EXPECT_TRUE(std::isfinite((*tc.fit.std)[1][k]));
    // The frozen sensor model is carried over unchanged and has no std of its own here.
    for (Effect e : {Effect::bias, Effect::rotational_inertia}) {
      for (int k = 0; k < model::info(e).num_params; ++k) {
        EXPECT_EQ(tc.fit.params.block(e)[k], base.params.block(e)[k]);
        EXPECT_TRUE(std::isnan((*tc.fit.std)[model::index(e)][k]));
      }
    }
    EXPECT_EQ(tc.fit.params.effects, base.params.effects);

    // 3. The same tool after the sensor's zero point drifted since the calibration, in the
    //    simulated truth: 2 N and 0.2 N*m per axis, signs chosen for the largest mass error on
    //    these attitudes. The frozen zero point is now wrong; mass and centre of mass absorb it
    //    (docs/learned-residual.md, "Tool change").
    sim::SimConfig drifted = tool_config(sensor, seed + 100);  // the same noise as in 2.
    const double drift[6] = {2.0, -2.0, 2.0, 0.2, -0.2, 0.2};
    for (int i = 0; i < 6; ++i) drifted.params.block(Effect::bias)[i] += drift[i];
    const sim::RigSimulator drift_sim(drifted, poses.design.points_rad);
    for (int i = 0; i < 6; ++i)
      EXPECT_NEAR(
          drift_sim.truth().params.block(Effect::bias)[i] - sensor.params.block(Effect::bias)[i],
          drift[i], 1e-12);
    const ToolChangeResult td = fit_tool_change(make_dataset(drift_sim.run().log), base.params, {});
    ASSERT_TRUE(td.fit.usable) << td.fit.termination;
    const double* gd = td.fit.params.block(Effect::gravity);
    const double drift_mass_error = (gd[0] - 60.0) / 60.0;
    const Eigen::Vector3d drift_com_error =
        Eigen::Vector3d(gd[1], gd[2], gd[3]) - drift_sim.config().payload.com_sensor_m;
    std::printf(
        "seed %llu, zero point drifted by (2, -2, 2) N, (0.2, -0.2, 0.2) N*m: mass error "
        "%+.4f %%, centre of mass error (%+.4f, %+.4f, %+.4f) mm\n",
        static_cast<unsigned long long>(seed), 100.0 * drift_mass_error,
        1000.0 * drift_com_error.x(), 1000.0 * drift_com_error.y(), 1000.0 * drift_com_error.z());
    record_figure(key + "drift_mass_error_pct", 100.0 * drift_mass_error);
    record_figure(key + "drift_com_error_mm", 1000.0 * drift_com_error.cwiseAbs().maxCoeff());
    record_figure("drift_force_N", drift[0]);
    record_figure("drift_torque_Nm", drift[3]);
    // Measured over seeds 1-3: 0.232-0.245 % and 0.354-0.377 mm (largest component).
    EXPECT_NEAR(100.0 * drift_mass_error, 0.24, 0.02);
    EXPECT_NEAR(1000.0 * drift_com_error.cwiseAbs().maxCoeff(), 0.37, 0.04);
  }
}

TEST(ToolChange, WarnsWhenThePosesAreAlike) {
  // Three poses that differ by A1 only: a turn about the vertical leaves gravity in S unchanged,
  // so the centre of mass along it cannot be identified.
  sim::JointVector q = sim::kr210_home();
  q[4] = 60 * kDeg;
  std::vector<sim::JointVector> points;
  for (double a1 : {-30.0, 0.0, 30.0}) {
    q[0] = a1 * kDeg;
    points.push_back(q);
  }
  sim::SimConfig c = tool_config(sim::default_sim_config(4), 5);
  const sim::RigSimulator simulator(c, points);
  model::ModelParams base = simulator.truth().params;  // the exact sensor model
  base.effects = model::kDefaultModel;
  base.block(Effect::gravity)[0] = 100.0;  // the old tool
  const ToolChangeResult tc = fit_tool_change(make_dataset(simulator.run().log), base, {});
  EXPECT_EQ(tc.dwells, 3u);
  EXPECT_LT(tc.spread_deg, 1.0);
  EXPECT_TRUE(has_warning(tc.fit, "poses_alike"));
  EXPECT_TRUE(has_warning(tc.fit, "poorly_identified") || has_warning(tc.fit, "rank_deficient"));
  // The mass itself is still identified by the force (the bias is known).
  EXPECT_NEAR(tc.fit.params.block(Effect::gravity)[0], 60.0, 0.6);
}

TEST(ToolChange, FrozenEffectsNeedStartValuesAndSomethingToFit) {
  sim::SimConfig c = sim::default_sim_config(6);
  const sim::RigSimulator simulator(c, {sim::kr210_home()});
  const Dataset d = make_dataset(simulator.run().log);
  FitOptions fo;
  fo.effects = {Effect::bias, Effect::gravity};
  fo.frozen = {Effect::bias};
  EXPECT_THROW(fit(d, fo), std::runtime_error);  // no initial values for bias
  const model::ModelParams truth = simulator.truth().params;
  fo.initial = &truth;
  fo.frozen = {Effect::bias, Effect::gravity};
  EXPECT_THROW(fit(d, fo), std::runtime_error);  // nothing left to fit
  model::ModelParams no_gravity = truth;
  no_gravity.effects = {Effect::bias};
  EXPECT_THROW(fit_tool_change(d, no_gravity, {}), std::runtime_error);
}

}  // namespace
}  // namespace zerog::ident
