// The rig simulator: static physics, noise, determinism, truth file, and consistency with the
// model library (the one place the simulator's output meets zerog::model::predict_wrench).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>

#include "zerog/formats/log.hpp"
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

model::RigGeometry geometry(const formats::Rig& rig) {
  model::RigGeometry g;
  g.R_sensor_imu = rig.sensor_imu.q.normalized().toRotationMatrix();
  g.p_sensor_imu_m = rig.sensor_imu.p_m;
  return g;
}

model::PoseSignals pose_of(const formats::Sample& s, double t0) {
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
    const formats::Sample& s = out.log.samples[k];
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

// Every switchable effect but those outside the model library.
SimEffectSet all_in_the_model() {
  SimEffectSet set = parse_sim_effects("all", {});
  for (const auto& i : sim_effect_infos())
    if (!outside_terms(default_sim_config(1), i.id).empty()) set.remove(i.id);
  return set;
}

struct EffectCase {
  const char* name;
  SimEffectSet effects;
};

TEST(Simulator, ReproducedByTheModelLibraryForEachEffect) {
  const std::vector<JointVector> path = short_path();
  const EffectCase cases[] = {
      {"point mass", {}},
      {"rotational_inertia", {Effect::rotational_inertia}},
      {"base_tilt", {Effect::base_tilt}},
      {"imu_time_offset", {Effect::imu_time_offset}},
      {"bias_drift", {Effect::bias_drift}},
      {"temperature_bias", {Effect::temperature_bias}},
      {"crosstalk", {Effect::crosstalk}},
      {"sensor_rotation", {Effect::sensor_rotation}},
      {"cable", {Effect::cable}},
      {"imu_lever_arm", {RigEffect::imu_lever_arm}},
      {"all in the model", all_in_the_model()},
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
      if (!c.effects.has(i.id) || !i.model_effect() || *i.model_effect() == Effect::base_tilt)
        continue;
      without.effects.remove(*i.model_effect());
      removed = true;
    }
    if (c.effects.has(RigEffect::imu_lever_arm)) {
      // The rig knows the lever arm; a rig without it misses ω̇ × r and ω × (ω × r).
      formats::Rig no_lever = out.log.rig;
      no_lever.sensor_imu.p_m.setZero();
      SimOutput moved = out;
      moved.log.rig = no_lever;
      EXPECT_GT(max_abs(model_minus_sim(sim, moved, out.truth.params), 0, 3), 5.0) << c.name;
    }
    // Drift and temperature are slow: they show over a full run (SlowEffectsShowOverAFullRun).
    const bool slow = c.effects.has(Effect::bias_drift) || c.effects.has(Effect::temperature_bias);
    if (removed && !slow && std::string(c.name) != "all in the model") {
      const std::vector<Vec6> dw = model_minus_sim(sim, out, without);
      EXPECT_GT(std::max(max_abs(dw, 0, 3) / 0.25, max_abs(dw, 3, 6) / 0.03), 10.0) << c.name;
    }
  }
}

TEST(Simulator, BaseTiltMatchesTheModelInStaticPoses) {
  // With the IMU the tilt cannot be seen; from the pose alone (gravity model) it must match.
  const std::vector<JointVector> path = short_path();
  const RigSimulator sim(quiet_config({Effect::base_tilt, Effect::rotational_inertia}), path);
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
  SimConfig c = quiet_config({RigEffect::joint6_friction, Effect::rotational_inertia});
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

// The law of one outside effect evaluated from the simulator's own kinematics: flange twist from
// the joint state, the true sensor frame, the sensor origin's velocity. Independent of
// outside_terms (written from the brief's formulas).
Vec6 outside_law(RigEffect effect, const Measurement& m, const JointState& js) {
  Vec6 w = Vec6::Zero();
  const Eigen::Matrix3d& R = m.R_base_sensor;
  switch (effect) {
    case RigEffect::swivel_viscous:
      w[5] = -2.0 * (R.transpose() * m.flange.omega_base_radps).z();
      break;
    case RigEffect::hose_drag: {
      // S origin: flange origin + R_BF p_FS; its velocity v_F + ω × (R_BF p_FS).
      const Eigen::Vector3d lever = m.p_base_sensor_m - m.flange.p_base_flange_m;
      const Eigen::Vector3d v_base =
          m.flange.v_flange_base_mps + m.flange.omega_base_radps.cross(lever);
      w.head<3>() = -25.0 * (R.transpose() * v_base);
      break;
    }
    case RigEffect::dress_pack_bend:
      w[0] = 8.0 * std::sin(js.q_rad[3]) * std::sin(js.q_rad[4]);
      break;
    default:
      ADD_FAILURE() << "no law for " << info(effect).name;
  }
  return w;
}

TEST(Simulator, OutsideEffectsAddExactlyTheirLaw) {
  const std::vector<JointVector> path = short_path();
  for (RigEffect e :
       {RigEffect::swivel_viscous, RigEffect::hose_drag, RigEffect::dress_pack_bend}) {
    SCOPED_TRACE(info(e).name);
    // Sensor rotation and an IMU lever arm on, so that "in S" and "of the S origin" matter.
    const SimEffectSet base = {Effect::rotational_inertia, Effect::sensor_rotation, Effect::cable,
                               Effect::bias_drift};
    SimEffectSet with = base;
    with.add(e);
    const RigSimulator off(quiet_config(base), path);
    const RigSimulator on(quiet_config(with), path);
    EXPECT_FALSE(info(e).model_effect().has_value());
    double largest = 0.0, sum2 = 0.0;
    int n = 0;
    for (double t = 0.0; t < on.trajectory().duration_s(); t += 0.25) {
      const JointState js = on.trajectory().at(t);
      const Measurement m = on.measure(js, t);
      const Vec6 added = m.wrench_sensor - off.measure(js, t).wrench_sensor;
      const Vec6 law = outside_law(e, m, js);
      EXPECT_LT((added - law).cwiseAbs().maxCoeff(), 1e-9) << "t = " << t;
      EXPECT_LT((on.outside_wrench_at(t) - law).cwiseAbs().maxCoeff(), 1e-12) << "t = " << t;
      largest = std::max(largest, law.cwiseAbs().maxCoeff());
      sum2 += law.squaredNorm();
      ++n;
    }
    ASSERT_GT(n, 80);
    // Clearly above the F/T noise (0.25 N, 0.03 N·m) on this short path.
    EXPECT_GT(largest, e == RigEffect::swivel_viscous ? 0.5 : 5.0);
    std::printf("  %-16s largest %.3g, RMS over axes %.3g (N or N*m)\n", info(e).name, largest,
                std::sqrt(sum2 / n));
  }
}

TEST(Simulator, OutsideEffectsGoThroughTheCrosstalk) {
  const std::vector<JointVector> path = short_path();
  const RigSimulator sim(quiet_config({RigEffect::hose_drag, Effect::crosstalk}), path);
  const SimConfig& c = sim.config();
  const Eigen::Map<const Eigen::Matrix<double, 6, 6, Eigen::RowMajor>> E(
      c.params.block(Effect::crosstalk));
  const double t = 3.3;
  const Measurement m = sim.measure(sim.trajectory().at(t), t);
  const Vec6 law = outside_law(RigEffect::hose_drag, m, sim.trajectory().at(t));
  ASSERT_GT(law.norm(), 1.0);
  EXPECT_LT((sim.outside_wrench_at(t) - (Vec6(law) + E * law)).norm(), 1e-9);
}

TEST(Simulator, OutsideTermsAreTheLaw) {
  SimConfig c = default_sim_config(7);
  c.effects = parse_sim_effects("-rotational_inertia");
  EXPECT_TRUE(outside_terms(c).empty());
  const auto expect_terms = [](const std::vector<OutsideTerm>& got,
                               const std::vector<OutsideTerm>& want) {
    ASSERT_EQ(got.size(), want.size());
    for (std::size_t k = 0; k < want.size(); ++k) {
      EXPECT_EQ(got[k].axis, want[k].axis) << k;
      EXPECT_EQ(got[k].basis, want[k].basis) << k;
      EXPECT_EQ(got[k].coefficient, want[k].coefficient) << k;
    }
  };
  expect_terms(outside_terms(c, RigEffect::joint6_friction), {{"Mz", "tanh(qd6/0.02)", 1.5}});
  expect_terms(outside_terms(c, RigEffect::swivel_viscous), {{"Mz", "wz_S", -2.0}});
  expect_terms(outside_terms(c, RigEffect::hose_drag),
               {{"Fx", "vx_S", -25.0}, {"Fy", "vy_S", -25.0}, {"Fz", "vz_S", -25.0}});
  expect_terms(outside_terms(c, RigEffect::dress_pack_bend), {{"Fx", "sin(q4)*sin(q5)", 8.0}});
  for (const SimEffect e :
       std::initializer_list<SimEffect>{Effect::cable, Effect::crosstalk, RigEffect::imu_lever_arm})
    EXPECT_TRUE(outside_terms(c, e).empty()) << info(e).name;

  // Switched on, in SimEffect order; the values follow set_config_value.
  c.effects = parse_sim_effects("dress_pack_bend,swivel_viscous,cable");
  set_config_value(c, "swivel_viscous.damping", 3.5);
  set_config_value(c, "dress_pack_bend.force", -6.0);
  expect_terms(outside_terms(c), {{"Mz", "wz_S", -3.5}, {"Fx", "sin(q4)*sin(q5)", -6.0}});
  c.effects = parse_sim_effects("all");
  set_config_value(c, "hose_drag.damping", 40.0);
  set_config_value(c, "joint6_friction.rate", 0.05);
  const std::vector<OutsideTerm> all = outside_terms(c);
  ASSERT_EQ(all.size(), 6u);
  EXPECT_EQ(all[0].basis, "tanh(qd6/0.05)");
  EXPECT_EQ(all[2].coefficient, -40.0);
}

TEST(Simulator, OutsideEffectsInTheTruthFileAndSettable) {
  SimConfig c = default_sim_config(2);
  c.effects = parse_sim_effects("swivel_viscous,hose_drag");
  set_config_value(c, "swivel_viscous.damping", 1.25);
  set_config_value(c, "hose_drag.damping", 30.0);
  set_config_value(c, "dress_pack_bend.force", 4.5);
  EXPECT_EQ(c.swivel_damping_Nms_per_rad, 1.25);
  EXPECT_EQ(c.hose_drag_Ns_per_m, 30.0);
  EXPECT_EQ(c.dress_pack_bend_N, 4.5);
  EXPECT_THROW(set_config_value(c, "hose_drag.drag", 1.0), std::invalid_argument);
  bool listed = false;
  for (const auto& [key, value] : config_values(c))
    if (key == "dress_pack_bend.force") listed = value == 4.5;
  EXPECT_TRUE(listed);
  c.duration_limit_s = 1.0;
  const io::ModelFile t = RigSimulator(c, short_path()).truth();
  const nlohmann::json& x = t.extra["outside_model"];
  EXPECT_TRUE(x["swivel_viscous"]["enabled"].get<bool>());
  EXPECT_EQ(x["swivel_viscous"]["damping_Nms_per_rad"].get<double>(), 1.25);
  EXPECT_TRUE(x["hose_drag"]["enabled"].get<bool>());
  EXPECT_EQ(x["hose_drag"]["damping_Ns_per_m"].get<double>(), 30.0);
  EXPECT_FALSE(x["dress_pack_bend"]["enabled"].get<bool>());
  EXPECT_EQ(x["dress_pack_bend"]["force_N"].get<double>(), 4.5);
  EXPECT_FALSE(x["joint6_friction"]["enabled"].get<bool>());
  EXPECT_EQ(x["hose_drag"]["terms"][1]["axis"].get<std::string>(), "Fy");
  EXPECT_EQ(x["hose_drag"]["terms"][1]["basis"].get<std::string>(), "vy_S");
  EXPECT_EQ(x["hose_drag"]["terms"][1]["coefficient"].get<double>(), -30.0);
  EXPECT_EQ(x["dress_pack_bend"]["terms"][0]["basis"].get<std::string>(), "sin(q4)*sin(q5)");
  // Outside the library: the model effects of the truth are the default ones.
  const model::EffectSet expected = {Effect::bias, Effect::gravity, Effect::linear_inertia,
                                     Effect::rotational_inertia};
  EXPECT_EQ(t.params.effects, expected);
  // And by name on the command line.
  EXPECT_EQ(parse_sim_effects("hose_drag,dress_pack_bend,-rotational_inertia"),
            SimEffectSet({RigEffect::hose_drag, RigEffect::dress_pack_bend}));
  ASSERT_TRUE(sim_effect_from_name("swivel_viscous").has_value());
  EXPECT_EQ(*sim_effect_from_name("swivel_viscous"), SimEffect{RigEffect::swivel_viscous});
}

// The simulator's switches are the model library's effects (by the library's own names) and the
// rig's: a library effect the truth can be without has a switch, the three it always has do not.
TEST(Simulator, SwitchesAreTheLibrarysEffectsThenTheRigs) {
  std::size_t k = 0;
  const auto& infos = sim_effect_infos();
  for (Effect e : model::kAllEffects) {
    if (!switchable(e)) {
      EXPECT_FALSE(sim_effect_from_name(model::info(e).name).has_value()) << model::info(e).name;
      continue;
    }
    ASSERT_LT(k, infos.size());
    EXPECT_EQ(infos[k].id, SimEffect{e});
    EXPECT_STREQ(infos[k].name, model::info(e).name);
    EXPECT_EQ(infos[k].model_effect(), e);
    EXPECT_NE(infos[k].default_magnitude, nullptr) << infos[k].name;
    ++k;
  }
  for (int r = 0; r < kRigEffectCount; ++r, ++k) {
    ASSERT_LT(k, infos.size());
    EXPECT_EQ(infos[k].id, SimEffect{static_cast<RigEffect>(r)});
    EXPECT_FALSE(infos[k].model_effect().has_value()) << infos[k].name;
    EXPECT_EQ(&info(infos[k].id), &infos[k]);
  }
  EXPECT_EQ(k, infos.size());
  try {
    parse_sim_effects("cable,-gravity");
    ADD_FAILURE() << "gravity cannot be switched off";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("always in the truth"), std::string::npos) << e.what();
  }
  EXPECT_THROW(info(SimEffect{Effect::bias}), std::invalid_argument);
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
  for (const formats::Sample& s : out.log.samples) {
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
    without.effects.remove(*info(*sim_effect_from_name(name)).model_effect());
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

// The clean log (the sensor floor's input): the same rows with every signal noise-free and the
// noisy wrench. Checked against a run of the same seed without noise: its signals are the clean
// ones exactly, and the noisy log's IMU differs from them by the configured noise.
TEST(Simulator, CleanLogHasNoiseFreeSignalsAndTheNoisyWrench) {
  SimConfig c = default_sim_config(7);
  c.effects = parse_sim_effects("cable,imu_time_offset");
  const SimOutput out = RigSimulator(c, short_path()).run();
  SimConfig quiet = c;
  quiet.noise = NoiseConfig::none();
  const SimOutput ref = RigSimulator(quiet, short_path()).run();
  ASSERT_EQ(out.clean_log.samples.size(), out.log.samples.size());
  ASSERT_EQ(ref.log.samples.size(), out.log.samples.size());
  EXPECT_EQ(out.clean_log.columns, out.log.columns);
  EXPECT_EQ(out.clean_log.rig.name, out.log.rig.name);
  double ss_acc = 0, ss_gyro = 0, ss_force = 0;
  const std::size_t n = out.log.samples.size();
  for (std::size_t i = 0; i < n; ++i) {
    const formats::Sample &clean = out.clean_log.samples[i], &noisy = out.log.samples[i],
                          &quiet_s = ref.log.samples[i];
    // Noise-free signals: those of the run without noise, bit for bit.
    ASSERT_TRUE(clean.specific_force_imu_mps2 == quiet_s.specific_force_imu_mps2) << i;
    ASSERT_TRUE(clean.angular_rate_imu_radps == quiet_s.angular_rate_imu_radps) << i;
    ASSERT_EQ(clean.t_s, noisy.t_s);
    ASSERT_EQ(clean.joints_rad, noisy.joints_rad);
    ASSERT_TRUE(clean.p_base_sensor_m == noisy.p_base_sensor_m);
    ASSERT_TRUE(clean.q_base_sensor.coeffs() == noisy.q_base_sensor.coeffs());
    ASSERT_EQ(clean.temperature_C, noisy.temperature_C);
    // The wrench: the noisy one of the log, bit for bit.
    ASSERT_TRUE(clean.force_sensor_N == noisy.force_sensor_N) << i;
    ASSERT_TRUE(clean.torque_sensor_Nm == noisy.torque_sensor_Nm) << i;
    ss_acc += (noisy.specific_force_imu_mps2 - clean.specific_force_imu_mps2).squaredNorm();
    ss_gyro += (noisy.angular_rate_imu_radps - clean.angular_rate_imu_radps).squaredNorm();
    ss_force += (noisy.force_sensor_N - quiet_s.force_sensor_N).squaredNorm();
  }
  // What separates the logs is the IMU noise; what separates the wrench from the noise-free one
  // is the F/T noise and quantisation (0.25 N and steps of 3/8..5/8 N: about 0.29 N).
  const double dn = 3.0 * static_cast<double>(n);
  EXPECT_NEAR(std::sqrt(ss_acc / dn), c.noise.accel_mps2, 0.05 * c.noise.accel_mps2);
  EXPECT_NEAR(std::sqrt(ss_gyro / dn), c.noise.gyro_radps, 0.05 * c.noise.gyro_radps);
  EXPECT_NEAR(std::sqrt(ss_force / dn), 0.29, 0.03);
}

TEST(Simulator, WritesALogThatReadsBack) {
  const fs::path dir = fs::temp_directory_path() / "zerog_sim_log_test";
  fs::create_directories(dir);
  SimConfig c = default_sim_config(5);
  c.effects = parse_sim_effects("imu_lever_arm,temperature_bias");
  c.duration_limit_s = 3.0;
  const SimOutput out = RigSimulator(c, short_path()).run();
  formats::write_log(out.log, dir / "run.csv");
  io::write_model(out.truth, dir / "run.truth.json");
  const formats::Log back = formats::read_log(dir / "run.csv");
  ASSERT_EQ(back.samples.size(), out.log.samples.size());
  EXPECT_TRUE(back.columns.joints && back.columns.full_imu() && back.columns.temperature);
  EXPECT_TRUE(back.rig.sensor_imu.p_m.isApprox(c.imu_lever_arm_m, 1e-12));
  EXPECT_NEAR(back.samples.back().force_sensor_N.z(), out.log.samples.back().force_sensor_N.z(),
              1e-5);
  const io::ModelFile truth = io::read_model(dir / "run.truth.json");
  EXPECT_TRUE(truth.params.effects.has(Effect::temperature_bias));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace zerog::sim
