// The real-time evaluator: no allocation in the cycle, status instead of exceptions, physics
// equal to model::predict_wrench, never half-configured, and the host sequence helper.
#include "zerog/infer/inference.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "alloc_count.hpp"
#include "infer_fixtures.hpp"
#include "zerog/infer/deploy_file.hpp"

namespace zerog::infer {
namespace {

using model::Activation;
using model::Feature;

DeployedModel model_with(Activation act, int weight_bits) {
  const auto data = test::random_samples(2000, 5);
  DeployedModel m;
  m.rig = test::demo_rig();
  m.physics = test::demo_physics();
  m.network = test::make_network(test::feature_range(Feature::sin_q1, Feature::time), {64, 64}, act,
                                 data, 1.0, 9, weight_bits);
  return m;
}

TEST(Inference, EvaluateDoesNotAllocate) {
  for (Activation act : {Activation::tanh, Activation::sigmoid, Activation::leaky_relu}) {
    for (int bits : {8, 16}) {
      Inference inf;
      ASSERT_EQ(inf.configure(model_with(act, bits)).text(), "");
      const auto samples = test::random_samples(500, 1);
      Wrench w;
      zerog::test::AllocGuard guard("Inference::evaluate");
      for (const auto& s : samples) {
        inf.evaluate(s, w);
        inf.evaluate_reference(s, w);
        inf.evaluate_physics(s, w);
        inf.residual_quantised(s, w);
      }
      guard.stop();
      EXPECT_EQ(guard.allocations(), 0u)
          << model::activation_name(act) << bits << " " << guard.first_call();
      EXPECT_EQ(guard.frees(), 0u) << model::activation_name(act) << bits;
    }
  }
  // The guard works: configure allocates.
  const DeployedModel m = model_with(Activation::tanh, 16);
  zerog::test::AllocGuard guard("Inference::configure");
  Eigen::internal::set_is_malloc_allowed(true);  // configure may use Eigen's heap
  Inference inf;
  const zerog::Status st = inf.configure(m);
  guard.stop();
  ASSERT_TRUE(st.ok()) << st.text();
  EXPECT_GT(guard.allocations(), 0u);
}

TEST(Inference, PhysicsIsModelPredictWrench) {
  Inference inf;
  const DeployedModel m = model_with(Activation::tanh, 16);
  ASSERT_EQ(inf.configure(m).text(), "");
  std::mt19937_64 rng(4);
  for (int i = 0; i < 100; ++i) {
    const model::FeatureSignals s = test::random_signals(rng);
    model::PoseSignals pose;
    pose.R_base_sensor =
        Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(s.R_base_sensor.data());
    pose.t_rel_s = s.t_s;
    pose.temperature_C = s.temperature_C;
    pose.joints_rad = s.joints_rad;
    model::ImuSignals<double> imu;
    imu.specific_force_imu = Eigen::Vector3d(s.imu[0], s.imu[1], s.imu[2]);
    imu.angular_rate_imu = Eigen::Vector3d(s.imu[3], s.imu[4], s.imu[5]);
    imu.angular_accel_imu = Eigen::Vector3d(s.imu[6], s.imu[7], s.imu[8]);
    const Wrench expected = model::predict_wrench<double>(
        m.physics.effects, model::pointers(m.physics), pose, imu, m.rig.geometry());
    Wrench physics, full, residual;
    ASSERT_TRUE(inf.evaluate_physics(s, physics).written());
    EXPECT_EQ(physics, expected);
    ASSERT_TRUE(inf.evaluate(s, full).written());
    ASSERT_TRUE(inf.residual_quantised(s, residual).written());
    EXPECT_LT((full - (expected + residual)).cwiseAbs().maxCoeff(), 1e-9);
  }
}

TEST(Inference, StatusInsteadOfExceptions) {
  Inference inf;
  model::FeatureSignals s;
  Wrench w = Wrench::Constant(7.0);
  EXPECT_EQ(inf.evaluate(s, w).code, StatusCode::not_configured);
  EXPECT_EQ(w, Wrench::Constant(7.0));  // not written
  ASSERT_EQ(inf.configure(model_with(Activation::tanh, 16)).text(), "");
  s.temperature_C = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(inf.evaluate(s, w).code, StatusCode::non_finite);
  EXPECT_EQ(w, Wrench::Constant(7.0));
  std::mt19937_64 rng(8);
  s = test::random_signals(rng);
  EXPECT_EQ(inf.evaluate(s, w).code, StatusCode::ok);
  s.t_s = 1e6;  // far outside the training range: the input saturates, the output is still given
  const Status st = inf.evaluate(s, w);
  EXPECT_EQ(st.code, StatusCode::saturated);
  EXPECT_GE(st.clipped_values, 1);
  EXPECT_TRUE(st.written());
  EXPECT_STREQ(status_name(st.code), "saturated");
}

TEST(Inference, NeverHalfConfigured) {
  Inference inf;
  const DeployedModel good = model_with(Activation::tanh, 16);
  ASSERT_EQ(inf.configure(good).text(), "");
  DeployedModel bad = good;
  bad.network->quantised.layers[1].weights.pop_back();
  const zerog::Status why = inf.configure(bad);
  EXPECT_EQ(why.code(), zerog::StatusCode::invalid_setting);
  EXPECT_NE(why.message().find("quantised weights"), std::string::npos) << why.text();
  ASSERT_TRUE(inf.configured());
  EXPECT_EQ(inf.model().network->quantised.layers[1].weights.size(),
            good.network->quantised.layers[1].weights.size());
  std::mt19937_64 rng(9);
  Wrench w;
  EXPECT_TRUE(inf.evaluate(test::random_signals(rng), w).written());
}

TEST(Inference, SequenceMatchesPerSampleAndShiftsTheImuForTheTimeOffset) {
  DeployedModel m = model_with(Activation::leaky_relu, 16);
  std::vector<model::FeatureSignals> samples = test::random_samples(50, 12);
  for (std::size_t i = 0; i < samples.size(); ++i) samples[i].t_s = 0.012 * static_cast<double>(i);
  Inference inf;
  ASSERT_EQ(inf.configure(m).text(), "");
  std::vector<Wrench> out(samples.size());
  evaluate_sequence(inf, Path::quantised, samples, out);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    Wrench w;
    inf.evaluate(samples[i], w);
    EXPECT_EQ(out[i], w);
  }
  // With tau = one row, the physics of sample i reads the IMU of sample i + 1.
  m.physics.effects.add(model::Effect::imu_time_offset);
  m.physics.block(model::Effect::imu_time_offset)[0] = 0.012;
  ASSERT_EQ(inf.configure(m).text(), "");
  evaluate_sequence(inf, Path::physics_only, samples, out);
  for (std::size_t i = 0; i + 1 < samples.size(); ++i) {
    model::FeatureSignals shifted = samples[i];
    shifted.imu = samples[i + 1].imu;
    Wrench w;
    inf.evaluate_physics(shifted, w);
    EXPECT_LT((out[i] - w).cwiseAbs().maxCoeff(), 1e-9) << i;
  }
}

}  // namespace
}  // namespace zerog::infer

namespace zerog::infer {
namespace {

// User-defined effects (proto/user_effects.md) in the deployed model: written, loaded, and added
// by the evaluator to the physics as c · basis along their axis (values computed here by hand),
// allocation-free.
TEST(Inference, UserTermsRoundTripAndAddTheirLaw) {
  DeployedModel m;
  m.rig = test::demo_rig();
  m.physics = test::demo_physics();
  model::UserEffects& u = m.physics.user;
  u.num_effects = 1;
  const std::string name = "swivel";
  std::copy(name.begin(), name.end(), u.names[0].begin());
  const char* error = nullptr;
  std::size_t pos = 0;
  u.num_terms = 2;
  ASSERT_TRUE(model::parse_basis("tanh(qd6/0.02)", u.terms[0].basis, error, pos));
  u.terms[0].axis = 5;
  ASSERT_TRUE(model::parse_basis("vx_B", u.terms[1].basis, error, pos));
  u.terms[1].axis = 1;  // force along base y
  u.terms[1].frame = model::TermFrame::base;
  u.coeff[0] = 1.5;
  u.coeff[1] = -25.0;
  const LoadResult loaded = load_deployed_model(serialise_deployed_model(m), m.rig);
  ASSERT_TRUE(loaded.ok()) << loaded.message;
  ASSERT_EQ(loaded.model->physics.user.num_terms, 2);
  EXPECT_EQ(loaded.model->physics.user.terms[1], u.terms[1]);
  EXPECT_EQ(loaded.model->physics.user.coeff[1], -25.0);

  Inference with, without;
  ASSERT_EQ(with.configure(*loaded.model).text(), "");
  DeployedModel plain = m;
  plain.physics.user = {};
  ASSERT_EQ(without.configure(plain).text(), "");
  std::mt19937_64 rng(8);
  std::size_t allocations = 0;
  for (int i = 0; i < 50; ++i) {
    const model::FeatureSignals s = test::random_signals(rng);
    model::KinematicInputs k;
    k.features = s;
    k.features.joint_vel_radps[5] = 0.01 * (i - 25);
    k.v_base_sensor_mps = {-0.2 + 0.01 * i, 0.1, 0.3};
    const model::ImuSignals<double> imu = imu_signals(s);
    Wrench a, b;
    zerog::test::AllocGuard guard("Inference::evaluate with a user law");
    const bool written = with.evaluate(Path::physics_only, s, imu, a, &k).written();
    guard.stop();
    ASSERT_TRUE(written);
    allocations += guard.allocations() + guard.frees();
    ASSERT_TRUE(without.evaluate(Path::physics_only, s, imu, b, &k).written());
    const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> R(s.R_base_sensor.data());
    Wrench law = Wrench::Zero();
    law[5] = 1.5 * std::tanh(k.features.joint_vel_radps[5] / 0.02);
    law.head<3>() += -25.0 * k.v_base_sensor_mps[0] * R.row(1).transpose();  // vx_B along base y
    EXPECT_LT((a - b - law).cwiseAbs().maxCoeff(), 1e-9) << i;
  }
  EXPECT_EQ(allocations, 0u);
  // A bad basis in the file is refused, naming the term; a non-finite value is never written.
  std::string bytes = serialise_deployed_model(m);
  const std::string body_from = "tanh(qd6/0.02)", body_to = "tanh(q6/0.02)";
  const std::size_t at = bytes.find(body_from);
  ASSERT_NE(at, std::string::npos);
  bytes.replace(at, body_from.size(), body_to);
  const LoadResult refused = load_deployed_model(bytes, m.rig);
  EXPECT_FALSE(refused.ok());
  DeployedModel bad = m;
  bad.physics.user.coeff[0] = std::numeric_limits<double>::infinity();
  EXPECT_THROW(serialise_deployed_model(bad), std::invalid_argument);
}

}  // namespace
}  // namespace zerog::infer
