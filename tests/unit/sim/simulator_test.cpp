// The rig simulator: static physics, noise, determinism, truth file, and consistency with the
// model library (the one place the simulator's output meets zerog::model::predict_wrench).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "zerog/io/log.hpp"
#include "zerog/io/model_file.hpp"
#include "zerog/model/predict.hpp"
#include "zerog/sim/simulator.hpp"

namespace zerog::sim {
namespace {

namespace fs = std::filesystem;
using model::Effect;
using Vec6 = Eigen::Matrix<double, 6, 1>;

// Five random feasible points: about 25 s of moves and dwells, every joint moving.
std::vector<JointVector> short_path() {
  DesignOptions o;
  o.kind = DesignKind::random;
  o.points = 5;
  o.seed = 11;
  return make_design(o).points_rad;
}

SimConfig quiet_config(SimEffectSet effects) {
  SimConfig c = default_sim_config(3);
  c.effects = effects;
  c.noise = NoiseConfig::none();
  // A turned IMU (known to the rig) exercises the IMU-to-sensor rotation.
  c.imu_mount_rotvec_rad = Eigen::Vector3d(0.3, -0.2, 1.4);
  return c;
}

model::RigGeometry geometry(const io::Rig& rig) {
  model::RigGeometry g;
  g.R_sensor_imu = rig.sensor_imu.q.normalized().toRotationMatrix();
  g.p_sensor_imu_m = rig.sensor_imu.p_m;
  return g;
}

model::PoseSignals pose_of(const io::Sample& s, double t0) {
  model::PoseSignals p;
  p.R_base_sensor = s.q_base_sensor.normalized().toRotationMatrix();
  p.t_rel_s = s.t_s - t0;
  p.temperature_C = s.temperature_C;
  p.joints_rad = s.joints_rad;
  return p;
}

// Model prediction with `params` on every simulated sample minus the simulated wrench.
// The IMU signals are the logged ones with the analytic angular acceleration; with an IMU time
// offset the model reads the IMU series at t + tau, evaluated exactly by the simulator.
std::vector<Vec6> model_minus_sim(const RigSimulator& sim, const SimOutput& out,
                                  const model::ModelParams& params) {
  const model::RigGeometry rig = geometry(out.log.rig);
  const double tau =
      params.effects.has(Effect::imu_time_offset) ? params.block(Effect::imu_time_offset)[0] : 0.0;
  std::vector<Vec6> diff;
  for (std::size_t k = 0; k < out.log.samples.size(); ++k) {
    const io::Sample& s = out.log.samples[k];
    model::ImuSignals<double> imu;
    if (tau == 0.0) {
      imu.specific_force_imu = s.specific_force_imu_mps2;
      imu.angular_rate_imu = s.angular_rate_imu_radps;
      imu.angular_accel_imu = out.angular_accel_imu_radps2[k];
    } else {
      const ImuTruth later = sim.imu_at(s.t_s + tau);
      imu.specific_force_imu = later.specific_force_imu_mps2;
      imu.angular_rate_imu = later.angular_rate_imu_radps;
      imu.angular_accel_imu = later.angular_accel_imu_radps2;
    }
    const Vec6 predicted = model::predict_wrench(params.effects, model::pointers(params),
                                                 pose_of(s, out.log.samples.front().t_s), imu, rig);
    Vec6 measured;
    measured << s.force_sensor_N, s.torque_sensor_Nm;
    diff.push_back(predicted - measured);
  }
  return diff;
}

double max_abs(const std::vector<Vec6>& d, int from = 0, int to = 6) {
  double m = 0.0;
  for (const Vec6& v : d) m = std::max(m, v.segment(from, to - from).cwiseAbs().maxCoeff());
  return m;
}

struct EffectCase {
  const char* name;
  SimEffectSet effects;
};

TEST(Simulator, ReproducedByTheModelLibraryForEachEffect) {
  const std::vector<JointVector> path = short_path();
  const EffectCase cases[] = {
      {"point mass", {}},
      {"rotational_inertia", {SimEffect::rotational_inertia}},
      {"base_tilt", {SimEffect::base_tilt}},
      {"imu_time_offset", {SimEffect::imu_time_offset}},
      {"bias_drift", {SimEffect::bias_drift}},
      {"temperature_bias", {SimEffect::temperature_bias}},
      {"crosstalk", {SimEffect::crosstalk}},
      {"sensor_rotation", {SimEffect::sensor_rotation}},
      {"cable", {SimEffect::cable}},
      {"imu_lever_arm", {SimEffect::imu_lever_arm}},
      {"all in the model", parse_sim_effects("all,-joint6_friction", {})},
  };
  for (const EffectCase& c : cases) {
    const RigSimulator sim(quiet_config(c.effects), path);
    const SimOutput out = sim.run();
    ASSERT_GT(out.log.samples.size(), 1000u);
    const std::vector<Vec6> d = model_minus_sim(sim, out, out.truth.params);
    EXPECT_LT(max_abs(d), 1e-6) << c.name;

    // And the effect is clearly visible: leaving it out of the model costs far more than noise.
    model::ModelParams without = out.truth.params;
    bool removed = false;
    for (const auto& i : sim_effect_infos()) {
      if (!c.effects.has(i.id) || !i.model_effect || *i.model_effect == Effect::base_tilt) continue;
      without.effects.remove(*i.model_effect);
      removed = true;
    }
    if (c.effects.has(SimEffect::imu_lever_arm)) {
      // The rig knows the lever arm; a rig without it misses ω̇ × r and ω × (ω × r).
      io::Rig no_lever = out.log.rig;
      no_lever.sensor_imu.p_m.setZero();
      SimOutput moved = out;
      moved.log.rig = no_lever;
      EXPECT_GT(max_abs(model_minus_sim(sim, moved, out.truth.params), 0, 3), 5.0) << c.name;
    }
    // Drift and temperature are slow: they show over a full run (SlowEffectsShowOverAFullRun).
    const bool slow =
        c.effects.has(SimEffect::bias_drift) || c.effects.has(SimEffect::temperature_bias);
    if (removed && !slow && std::string(c.name) != "all in the model") {
      const std::vector<Vec6> dw = model_minus_sim(sim, out, without);
      EXPECT_GT(std::max(max_abs(dw, 0, 3) / 0.25, max_abs(dw, 3, 6) / 0.03), 10.0) << c.name;
    }
  }
}

TEST(Simulator, BaseTiltMatchesTheModelInStaticPoses) {
  // With the IMU the tilt cannot be seen; from the pose alone (gravity model) it must match.
  const std::vector<JointVector> path = short_path();
  const RigSimulator sim(quiet_config({SimEffect::base_tilt, SimEffect::rotational_inertia}), path);
  const SimOutput out = sim.run();
  model::ModelParams p = out.truth.params;
  p.effects = {Effect::bias, Effect::gravity, Effect::base_tilt};
  const std::vector<Vec6> d = model_minus_sim(sim, out, p);
  p.effects.remove(Effect::base_tilt);
  const std::vector<Vec6> d_untilted = model_minus_sim(sim, out, p);
  int static_samples = 0;
  double worst = 0.0, untilted = 0.0;
  for (std::size_t k = 0; k < d.size(); ++k) {
    if (!sim.trajectory().is_dwell(out.log.samples[k].t_s)) continue;
    ++static_samples;
    worst = std::max(worst, d[k].cwiseAbs().maxCoeff());
    untilted = std::max(untilted, d_untilted[k].head<3>().cwiseAbs().maxCoeff());
  }
  EXPECT_GT(static_samples, 500);
  EXPECT_LT(worst, 1e-6);
  EXPECT_GT(untilted, 2.0);  // 2..5 mrad × 981 N
}

TEST(Simulator, Joint6FrictionIsOutsideTheModel) {
  const std::vector<JointVector> path = short_path();
  SimConfig c = quiet_config({SimEffect::joint6_friction, SimEffect::rotational_inertia});
  const RigSimulator sim(c, path);
  const SimOutput out = sim.run();
  const std::vector<Vec6> d = model_minus_sim(sim, out, out.truth.params);
  EXPECT_LT(max_abs(d, 0, 5), 1e-6);  // only Mz
  double max_mz = 0.0;
  for (std::size_t k = 0; k < d.size(); ++k) {
    const double qd6 = sim.trajectory().at(out.log.samples[k].t_s).qd_radps[5];
    EXPECT_NEAR(-d[k][5], 1.5 * std::tanh(qd6 / 0.02), 1e-6);
    max_mz = std::max(max_mz, std::abs(d[k][5]));
  }
  EXPECT_GT(max_mz, 1.4);
  EXPECT_FALSE(out.truth.params.effects.has(Effect::crosstalk));
  EXPECT_TRUE(out.truth.extra["outside_model"]["joint6_friction"]["enabled"].get<bool>());
}

TEST(Simulator, StaticSampleIsWeightWithinNoise) {
  SimConfig c = default_sim_config(4);  // default noise and quantisation
  const RigSimulator sim(c, short_path());
  const SimOutput out = sim.run();
  const Eigen::Vector3d F0(c.params.block(Effect::bias)), M0(c.params.block(Effect::bias) + 3);
  const double m = c.payload.mass_kg;
  const Eigen::Vector3d& com = c.payload.com_sensor_m;
  int n = 0;
  Vec6 sum = Vec6::Zero(), sum2 = Vec6::Zero();
  for (const io::Sample& s : out.log.samples) {
    if (!sim.trajectory().is_dwell(s.t_s)) continue;
    const Eigen::Matrix3d R = s.q_base_sensor.toRotationMatrix();
    const Eigen::Vector3d g_s = R.transpose() * Eigen::Vector3d(0, 0, -model::kStandardGravity);
    Vec6 r;
    r << s.force_sensor_N - F0 - m * g_s, s.torque_sensor_Nm - M0 - com.cross(m * g_s);
    for (int i = 0; i < 6; ++i) {
      const double sigma = i < 3 ? 0.25 : 0.03;
      EXPECT_LT(std::abs(r[i]), 5 * sigma + kOmega191Resolution[i]) << "axis " << i;
    }
    sum += r;
    sum2 += r.cwiseProduct(r);
    ++n;
    // IMU at rest: specific force is "up" with magnitude g, no rotation.
    EXPECT_NEAR(s.specific_force_imu_mps2.norm(), model::kStandardGravity, 0.06);
    EXPECT_LT(s.angular_rate_imu_radps.cwiseAbs().maxCoeff(), 5 * 5e-4);
  }
  ASSERT_GT(n, 500);
  for (int i = 0; i < 6; ++i) {
    const double sd = std::sqrt(sum2[i] / n - (sum[i] / n) * (sum[i] / n));
    const double expected =
        std::sqrt(std::pow(i < 3 ? 0.25 : 0.03, 2) + std::pow(kOmega191Resolution[i], 2) / 12.0);
    EXPECT_NEAR(sd, expected, 0.1 * expected) << "axis " << i;
    EXPECT_LT(std::abs(sum[i] / n), 4 * expected / std::sqrt(n)) << "axis " << i;
  }
}

TEST(Simulator, DeterministicForASeed) {
  const std::vector<JointVector> path = short_path();
  SimConfig c = default_sim_config(9);
  c.effects = parse_sim_effects("all");
  c.duration_limit_s = 10.0;
  const SimOutput a = RigSimulator(c, path).run();
  const SimOutput b = RigSimulator(c, path).run();
  ASSERT_EQ(a.log.samples.size(), b.log.samples.size());
  EXPECT_EQ(a.log.samples.size(), 834u);  // 10 s at 12 ms, both ends
  for (std::size_t k = 0; k < a.log.samples.size(); ++k) {
    EXPECT_EQ(a.log.samples[k].force_sensor_N, b.log.samples[k].force_sensor_N);
    EXPECT_EQ(a.log.samples[k].angular_rate_imu_radps, b.log.samples[k].angular_rate_imu_radps);
  }
  EXPECT_EQ(a.truth.params.values, b.truth.params.values);
  const SimConfig other = [&] {
    SimConfig o = default_sim_config(10);
    o.effects = c.effects;
    o.duration_limit_s = 10.0;
    return o;
  }();
  const SimOutput d = RigSimulator(other, path).run();
  EXPECT_NE(a.log.samples[100].force_sensor_N, d.log.samples[100].force_sensor_N);
  EXPECT_NE(a.truth.params.values, d.truth.params.values);
}

TEST(Simulator, TruthFileAndOverrides) {
  SimConfig c = default_sim_config(2);
  c.effects = parse_sim_effects("cable,imu_time_offset,-rotational_inertia");
  set_config_value(c, "imu_time_offset.tau", 0.01);
  set_config_value(c, "gravity.mass", 80.0);
  set_config_value(c, "rotational_inertia.Ixy", 0.25);
  EXPECT_THROW(set_config_value(c, "no_such.key", 1.0), std::invalid_argument);
  EXPECT_THROW(parse_sim_effects("cabel"), std::invalid_argument);
  EXPECT_EQ(c.payload.inertia_com_sensor_kgm2(1, 0), 0.25);
  c.duration_limit_s = 1.0;
  const RigSimulator sim(c, short_path());
  const io::ModelFile t = sim.truth();
  const model::EffectSet expected = {Effect::bias, Effect::gravity, Effect::linear_inertia,
                                     Effect::cable, Effect::imu_time_offset};
  EXPECT_EQ(t.params.effects, expected);
  EXPECT_EQ(t.params.block(Effect::imu_time_offset)[0], 0.01);
  EXPECT_EQ(t.params.block(Effect::gravity)[0], 80.0);
  EXPECT_EQ(t.params.block(Effect::gravity)[3], 0.25);  // cz
  EXPECT_EQ(t.params.block(Effect::rotational_inertia)[3], 0.25);
  EXPECT_EQ(t.extra["seed"].get<int>(), 2);
  EXPECT_TRUE(t.extra["payload"]["point_mass"].get<bool>());
  // Round trip through the model file format.
  const io::ModelFile back = io::model_from_json(io::to_json(t), "truth");
  EXPECT_EQ(back.params.effects, expected);
  for (Effect e : model::kAllEffects) {
    if (!expected.has(e)) continue;
    for (int i = 0; i < model::info(e).num_params; ++i)
      EXPECT_EQ(back.params.block(e)[i], t.params.block(e)[i]);
  }
  // The default payload: inertia tensor of a tilted box, products of inertia non-zero.
  const Eigen::Matrix3d I = box_inertia_kgm2(100.0);
  EXPECT_NEAR(I.trace(), 100.0 / 12.0 * 2 * (0.36 + 0.16 + 0.09), 1e-12);
  EXPECT_GT(std::abs(I(0, 1)), 0.05);
  EXPECT_GT(std::abs(I(1, 2)), 0.05);
}

TEST(Simulator, SlowEffectsShowOverAFullRun) {
  const Design oa = make_design(DesignOptions{});
  for (const char* name : {"bias_drift", "temperature_bias"}) {
    SimConfig c = quiet_config(parse_sim_effects(name));
    const RigSimulator sim(c, oa.points_rad);
    const SimOutput out = sim.run();
    EXPECT_LT(max_abs(model_minus_sim(sim, out, out.truth.params)), 1e-6) << name;
    model::ModelParams without = out.truth.params;
    without.effects.remove(*info(*sim_effect_from_name(name)).model_effect);
    const std::vector<Vec6> d = model_minus_sim(sim, out, without);
    // Per sample a few σ at the end of the run; a fit over ~70k samples sees it at once.
    EXPECT_GT(max_abs(d, 0, 3), 3 * 0.25) << name;
  }
}

TEST(Simulator, OaRunLengthAndFloor) {
  const Design oa = make_design(DesignOptions{});
  const RigSimulator sim(default_sim_config(1), oa.points_rad);
  const SimOutput out = sim.run();
  // Paper 000 §4.2: ~10–15 minutes of 12 ms samples.
  EXPECT_GT(out.stats.duration_s, 600.0);
  EXPECT_LT(out.stats.duration_s, 900.0);
  EXPECT_EQ(out.stats.samples_below_floor, 0u);
  EXPECT_GT(out.stats.max_force_N, 900.0);
}

TEST(Simulator, WritesALogThatReadsBack) {
  const fs::path dir = fs::temp_directory_path() / "zerog_sim_log_test";
  fs::create_directories(dir);
  SimConfig c = default_sim_config(5);
  c.effects = parse_sim_effects("imu_lever_arm,temperature_bias");
  c.duration_limit_s = 3.0;
  const SimOutput out = RigSimulator(c, short_path()).run();
  io::write_log(out.log, dir / "run.csv");
  io::write_model(out.truth, dir / "run.truth.json");
  const io::Log back = io::read_log(dir / "run.csv");
  ASSERT_EQ(back.samples.size(), out.log.samples.size());
  EXPECT_TRUE(back.columns.joints && back.columns.imu && back.columns.temperature);
  EXPECT_TRUE(back.rig.sensor_imu.p_m.isApprox(c.imu_lever_arm_m, 1e-12));
  EXPECT_NEAR(back.samples.back().force_sensor_N.z(), out.log.samples.back().force_sensor_N.z(),
              1e-5);
  const io::ModelFile truth = io::read_model(dir / "run.truth.json");
  EXPECT_TRUE(truth.params.effects.has(Effect::temperature_bias));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace zerog::sim
