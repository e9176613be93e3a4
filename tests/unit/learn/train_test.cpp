// `zerog train` on a short simulated run: each kind trains and predicts, training is
// deterministic for a seed, the network file round-trips, and bad options give clear errors.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "zerog/ident/compare.hpp"
#include "zerog/ident/fit.hpp"
#include "zerog/learn/network_file.hpp"
#include "zerog/learn/predict.hpp"
#include "zerog/learn/signals.hpp"
#include "zerog/learn/train.hpp"
#include "zerog/sim/design.hpp"
#include "zerog/sim/simulator.hpp"

namespace zerog {
namespace {

struct SimRun {
  formats::Log log;
  ident::Dataset data;
  io::ModelFile truth;
};

/// 240 s of the OA calibration run (about 20,000 samples, 30 dwells) with joint6_friction.
const SimRun& short_run() {
  static const SimRun run = [] {
    sim::SimConfig cfg = sim::default_sim_config(5);
    cfg.effects = sim::parse_sim_effects("joint6_friction");
    cfg.duration_limit_s = 240.0;
    sim::DesignOptions d;
    d.workspace.floor_z_m = cfg.floor_z_m;
    const sim::RigSimulator s(cfg, sim::make_design(d).points_rad);
    sim::SimOutput out = s.run();
    SimRun r{std::move(out.log), {}, std::move(out.truth)};
    r.data = ident::make_dataset(r.log);
    return r;
  }();
  return run;
}

learn::TrainOptions quick(learn::NetworkKind kind) {
  learn::TrainOptions o;
  o.kind = kind;
  o.max_train_samples = 600;
  o.max_iterations = 15;
  o.adam_iterations = 300;
  return o;
}

double rms(const std::vector<ident::Wrench>& pred, const ident::Dataset& data, int axis) {
  double ss = 0;
  for (std::size_t i = 0; i < data.size(); ++i)
    ss += std::pow(data.measured[i][axis] - pred[i][axis], 2);
  return std::sqrt(ss / static_cast<double>(data.size()));
}

TEST(Train, PaperBpIsDeterministicForASeedAndRoundTripsThroughItsFile) {
  const SimRun& r = short_run();
  auto o = quick(learn::NetworkKind::paper_bp);
  const learn::NetworkFile a = learn::train(r.data, r.log, o);
  o.threads = 1;
  const learn::NetworkFile b = learn::train(r.data, r.log, o);
  EXPECT_EQ(a.params, b.params);  // bitwise, 2 threads against 1
  o.seed = 2;
  const learn::NetworkFile c = learn::train(r.data, r.log, o);
  EXPECT_NE(a.params, c.params);
  EXPECT_EQ(a.shape.width, (std::vector<int>{21, 8, 6}));
  for (double p : a.params) EXPECT_EQ(p, static_cast<double>(static_cast<float>(p)));
  // Predicts the big gravity wrench to a fraction of its size, even after 15 iterations.
  const auto pred = learn::predictions(a, r.data, r.log);
  EXPECT_LT(rms(pred, r.data, 2), 60.0);  // Fz swings by ±981 N

  const auto path = std::filesystem::temp_directory_path() / "zerog_learn_test_bp.json";
  learn::write_network(a, path);
  const learn::NetworkFile back = learn::read_network(path);
  std::filesystem::remove(path);
  EXPECT_EQ(back.params, a.params);
  EXPECT_EQ(back.inputs, a.inputs);
  EXPECT_EQ(back.output_axes, a.output_axes);
  EXPECT_EQ(back.normalisation.input_scale, a.normalisation.input_scale);
  EXPECT_EQ(back.seed, a.seed);
  EXPECT_EQ(back.kind, learn::NetworkKind::paper_bp);
  const auto again = learn::predictions(back, r.data, r.log);
  EXPECT_EQ(again[100], pred[100]);
}

TEST(Train, PaperZpFitsTheStaticPosesAndItsToolLoad) {
  const SimRun& r = short_run();
  const learn::NetworkFile n = learn::train(r.data, r.log, quick(learn::NetworkKind::paper_zp));
  EXPECT_EQ(n.shape.width, (std::vector<int>{9, 45, 90, 5}));
  ASSERT_TRUE(n.tool_load.has_value());
  EXPECT_GE(n.tool_load->poses, 20);
  EXPECT_EQ(n.output_axes, (std::vector<int>{0, 1, 2, 3, 4}));
  const auto pred = learn::predictions(n, r.data, r.log);
  for (std::size_t i = 0; i < pred.size(); ++i) ASSERT_TRUE(pred[i].allFinite()) << i;
}

TEST(Train, ResidualLowersTheMzErrorOfThePhysicsModel) {
  const SimRun& r = short_run();
  ident::FitOptions fo;
  fo.effects = model::kDefaultModel;
  fo.covariance = false;
  const ident::FitResult fit = ident::fit(r.data, fo);
  ASSERT_TRUE(fit.usable);
  auto o = quick(learn::NetworkKind::residual);
  o.physics = io::ModelFile{};
  o.physics->params = fit.params;
  o.inputs = learn::parse_features("sign_qd6,qd6");
  o.max_iterations = 40;
  const learn::NetworkFile n = learn::train(r.data, r.log, o);
  ASSERT_TRUE(n.physics.has_value());
  std::vector<ident::Wrench> phys(r.data.size());
  for (std::size_t i = 0; i < phys.size(); ++i) phys[i] = ident::predict(fit.params, r.data, i);
  const auto pred = learn::predictions(n, r.data, r.log);
  EXPECT_LT(rms(pred, r.data, 5), 0.8 * rms(phys, r.data, 5));
  // Outputs without validation gain are switched off and add nothing.
  for (const auto& axis : n.training.at("outputs_switched_off")) {
    int a = 0;
    while (ident::kAxisNames[static_cast<std::size_t>(a)] != axis.get<std::string>()) ++a;
    for (std::size_t i = 0; i < pred.size(); i += 997) EXPECT_EQ(pred[i][a], phys[i][a]);
  }
}

TEST(Train, BadOptionsGiveClearErrors) {
  const SimRun& r = short_run();
  auto o = quick(learn::NetworkKind::residual);
  try {
    learn::train(r.data, r.log, o);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("physics model"), std::string::npos) << e.what();
  }
  o = quick(learn::NetworkKind::paper_bp);
  o.hidden = 0;
  try {
    learn::train(r.data, r.log, o);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--hidden"), std::string::npos) << e.what();
  }
  // No static dwell left for paper-zp.
  o = quick(learn::NetworkKind::paper_zp);
  const std::vector<std::uint8_t> moving_only(r.data.moving.begin(), r.data.moving.end());
  o.usable = &moving_only;
  try {
    learn::train(r.data, r.log, o);
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("static dwells"), std::string::npos) << e.what();
  }
  // A log without IMU columns cannot feed paper-bp.
  formats::Log no_imu = r.log;
  no_imu.columns.specific_force = false;
  no_imu.columns.angular_rate = false;
  const ident::Dataset d = ident::make_dataset(no_imu);
  try {
    learn::train(d, no_imu, quick(learn::NetworkKind::paper_bp));
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("IMU"), std::string::npos) << e.what();
  }
  // A network document with a missing key names it.
  nlohmann::json j = {{"format", "zerog-network"}, {"version", 1}, {"kind", "paper-bp"}};
  try {
    learn::network_from_json(j, "net.json");
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("net.json: key 'shape.width'"), std::string::npos)
        << e.what();
  }
  j["kind"] = "paper-xx";
  EXPECT_THROW(learn::network_from_json(j, "net.json"), std::runtime_error);
}

}  // namespace
}  // namespace zerog
