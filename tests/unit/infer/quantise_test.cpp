// Quantised vs float network: the largest difference over many realistic random inputs, for
// networks of the papers' shapes with trained-like random weights and for a network fitted here,
// with 16-bit (deployed default) and 8-bit weights. Bound: proto/deploy_format.md.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cstdio>
#include <string>

#include "infer_fixtures.hpp"
#include "zerog/infer/inference.hpp"

namespace zerog::infer {
namespace {

using model::Activation;
using model::Feature;
using test::feature_range;

// The bound the deployed (16-bit) network must meet, from the Omega191 resolution (3/8 N,
// 5/96 N·m): one eighth of a count, so quantisation never moves a prediction by a visible step.
constexpr double kForceBound_N = 0.375 / 8;        // 0.047 N
constexpr double kTorqueBound_Nm = 0.0520833 / 8;  // 0.0065 N·m
// The brief's bound, which 8-bit weights are measured against.
constexpr double kForceBrief_N = 0.1;
constexpr double kTorqueBrief_Nm = 0.01;

struct MaxError {
  double force_N = 0.0, torque_Nm = 0.0;
  int saturated = 0;
};

MaxError measure(const DeployedNetwork& net, std::size_t n, std::uint64_t seed) {
  DeployedModel m;
  m.rig = test::demo_rig();
  m.physics = test::demo_physics();
  m.network = net;
  Inference inf;
  EXPECT_EQ(inf.configure(m).text(), "");
  std::mt19937_64 rng(seed);
  MaxError e;
  for (std::size_t i = 0; i < n; ++i) {
    const model::FeatureSignals s = test::random_signals(rng);
    Wrench q, f;
    const Status st = inf.residual_quantised(s, q);
    EXPECT_TRUE(st.written());
    if (st.code == StatusCode::saturated) ++e.saturated;
    EXPECT_TRUE(inf.residual_reference(s, f).written());
    const Wrench d = (q - f).cwiseAbs();
    e.force_N = std::max(e.force_N, d.head<3>().maxCoeff());
    e.torque_Nm = std::max(e.torque_Nm, d.tail<3>().maxCoeff());
  }
  return e;
}

struct Case {
  const char* name;
  std::vector<Feature> features;
  std::vector<int> hidden;
  Activation activation;
  double gain;
};

std::vector<Case> cases() {
  std::vector<Feature> bp = feature_range(Feature::r11, Feature::wdz);  // pose + IMU (000_…)
  bp.insert(bp.end(), {Feature::px, Feature::py, Feature::pz});
  std::vector<Feature> joints = feature_range(Feature::sin_q1, Feature::sign_qd6);
  std::vector<Feature> all = feature_range(Feature::sin_q1, Feature::temperature);
  return {
      {"zp_45_90_leaky_relu",
       feature_range(Feature::r11, Feature::r33),
       {45, 90},
       Activation::leaky_relu,
       1.0},
      {"zp_45_90_leaky_relu_gain3",
       feature_range(Feature::r11, Feature::r33),
       {45, 90},
       Activation::leaky_relu,
       3.0},
      {"bp_8_sigmoid", bp, {8}, Activation::sigmoid, 1.0},
      {"bp_8_sigmoid_gain4", bp, {8}, Activation::sigmoid, 4.0},
      {"joints_32_32_tanh", joints, {32, 32}, Activation::tanh, 1.0},
      {"joints_32_32_tanh_gain3", joints, {32, 32}, Activation::tanh, 3.0},
      {"all_128_128_128_leaky_relu", all, {128, 128, 128}, Activation::leaky_relu, 1.0},
      {"all_64_identity", all, {64}, Activation::identity, 1.0},
  };
}

TEST(Quantise, SixteenBitWeightsStayWithinAnEighthOfTheSensorResolution) {
  const auto data = test::random_samples(4000, 11);
  std::uint64_t seed = 100;
  for (const Case& c : cases()) {
    const DeployedNetwork net =
        test::make_network(c.features, c.hidden, c.activation, data, c.gain, ++seed, 16);
    const MaxError e = measure(net, 20000, seed + 1000);
    std::printf("  16-bit %-28s max |q - f|: %.2e N  %.2e N*m  (saturated samples %d)\n", c.name,
                e.force_N, e.torque_Nm, e.saturated);
    EXPECT_LE(e.force_N, kForceBound_N) << c.name;
    EXPECT_LE(e.torque_Nm, kTorqueBound_Nm) << c.name;
  }
}

TEST(Quantise, EightBitWeightsStayWithinTheirMeasuredBoundAndMissTheBriefs) {
  // Not the deployed default: proto/deploy_format.md's table, measured here. Worst over these
  // networks: 0.28 N and 0.068 N*m (of 20,000 samples each); asserted with a 1.4x margin, so a
  // change that makes 8-bit quantisation worse fails here. And every network misses the brief's
  // 0.1 N / 0.01 N*m (the torque by 2-7x), which is why the default is 16-bit: if 8-bit weights
  // ever meet it, this fails and the choice and the document need another look.
  constexpr double kEightBitForce_N = 0.4, kEightBitTorque_Nm = 0.1;
  const auto data = test::random_samples(4000, 11);
  std::uint64_t seed = 100;
  int within = 0, total = 0;
  double worst_force_N = 0.0, worst_torque_Nm = 0.0;
  for (const Case& c : cases()) {
    const DeployedNetwork net =
        test::make_network(c.features, c.hidden, c.activation, data, c.gain, ++seed, 8);
    const MaxError e = measure(net, 20000, seed + 1000);
    std::printf("   8-bit %-28s max |q - f|: %.2e N  %.2e N*m\n", c.name, e.force_N, e.torque_Nm);
    EXPECT_LE(e.force_N, kEightBitForce_N) << c.name;
    EXPECT_LE(e.torque_Nm, kEightBitTorque_Nm) << c.name;
    within += (e.force_N <= kForceBrief_N && e.torque_Nm <= kTorqueBrief_Nm) ? 1 : 0;
    worst_force_N = std::max(worst_force_N, e.force_N);
    worst_torque_Nm = std::max(worst_torque_Nm, e.torque_Nm);
    ++total;
  }
  std::printf(
      "   8-bit worst %.3f N, %.4f N*m (bound %.1f N, %.1f N*m); within 0.1 N / 0.01 N*m: "
      "%d of %d networks\n",
      worst_force_N, worst_torque_Nm, kEightBitForce_N, kEightBitTorque_Nm, within, total);
  EXPECT_EQ(within, 0);
}

// A network fitted here: 15 features → 32 tanh → 6, to a residual of cable-, friction- and
// attitude-like terms (N, N·m). Hidden layer random, output layer by ridge regression, then
// full-batch Adam on all weights.
DeployedNetwork fitted_network(const std::vector<model::FeatureSignals>& data, double* fit_rms) {
  std::vector<Feature> features = feature_range(Feature::sin_q4, Feature::sin_q6);
  for (Feature f : {Feature::cos_q4, Feature::cos_q5, Feature::cos_q6, Feature::sign_qd4,
                    Feature::sign_qd5, Feature::sign_qd6, Feature::gx, Feature::gy, Feature::gz,
                    Feature::wdx, Feature::wdy, Feature::wdz})
    features.push_back(f);
  const int n_in = static_cast<int>(features.size()), H = 32, N = static_cast<int>(data.size());
  const auto target = [](const model::FeatureSignals& s) {
    Eigen::Matrix<double, 6, 1> t;
    const double c4 = std::cos(s.joints_rad[3]), s5 = std::sin(s.joints_rad[4]);
    const double s6 = std::sin(s.joints_rad[5]);
    const double gx = -s.R_base_sensor[6], gy = -s.R_base_sensor[7];
    const double fr = std::tanh(s.joint_vel_radps[5] / 0.02);
    t << 2.5 * c4 + 1.2 * s5 * s6, -1.8 * s5 + 3.0 * gx * gy, 1.5 * c4 * s6 + 0.8,
        0.4 * s6 + 0.2 * gx, -0.3 * c4 * s5, 0.5 * fr + 0.05 * s.imu[8];
    return t;
  };
  DeployedNetwork net;
  net.features = features;
  net.output_axes = {0, 1, 2, 3, 4, 5};
  net.shape.width = {n_in, H, 6};
  net.shape.activation = {Activation::tanh, Activation::identity};
  net.normalisation = test::normalisation_for(features, data);
  Eigen::MatrixXd X(n_in, N), T(6, N);
  std::vector<double> x(static_cast<std::size_t>(n_in));
  for (int i = 0; i < N; ++i) {
    model::compute_features(data[i], features, x.data());
    for (int k = 0; k < n_in; ++k)
      X(k, i) = (x[k] - net.normalisation.input_mean[k]) / net.normalisation.input_scale[k];
    T.col(i) = target(data[i]);
  }
  for (int k = 0; k < 6; ++k) {
    const double mean = T.row(k).mean();
    const double sd = std::sqrt((T.row(k).array() - mean).square().mean());
    net.normalisation.output_mean[k] = mean;
    net.normalisation.output_scale[k] = sd;
    T.row(k) = (T.row(k).array() - mean) / sd;
  }
  std::mt19937_64 rng(7);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::MatrixXd W1(H, n_in), W2(6, H);
  Eigen::VectorXd b1(H), b2 = Eigen::VectorXd::Zero(6);
  for (int i = 0; i < W1.size(); ++i) W1.data()[i] = g(rng) / std::sqrt(double(n_in));
  for (int i = 0; i < H; ++i) b1[i] = 0.1 * g(rng);
  {  // ridge regression of the output layer on the random hidden features
    const Eigen::MatrixXd Hm = ((W1 * X).colwise() + b1).array().tanh().matrix();
    const Eigen::MatrixXd A = Hm * Hm.transpose() + 1e-3 * N * Eigen::MatrixXd::Identity(H, H);
    W2 = A.ldlt().solve(Hm * T.transpose()).transpose();
  }
  // Adam on all weights.
  struct Adam {
    Eigen::MatrixXd m, v;
  };
  auto step = [](Eigen::MatrixXd& w, const Eigen::MatrixXd& grad, Adam& a, int t) {
    if (a.m.size() == 0) a.m = a.v = Eigen::MatrixXd::Zero(w.rows(), w.cols());
    a.m = 0.9 * a.m + 0.1 * grad;
    a.v = 0.999 * a.v + 0.001 * grad.cwiseProduct(grad);
    const double c1 = 1.0 - std::pow(0.9, t), c2 = 1.0 - std::pow(0.999, t);
    w.array() -= 0.01 * (a.m.array() / c1) / ((a.v.array() / c2).sqrt() + 1e-8);
  };
  Adam aW1, ab1, aW2, ab2;
  Eigen::MatrixXd B1 = b1, B2 = b2;
  for (int t = 1; t <= 400; ++t) {
    const Eigen::MatrixXd Hm = ((W1 * X).colwise() + B1.col(0)).array().tanh().matrix();
    const Eigen::MatrixXd E = (W2 * Hm).colwise() + B2.col(0) - T;
    const Eigen::MatrixXd dY = 2.0 * E / double(N * 6);
    const Eigen::MatrixXd dZ =
        (W2.transpose() * dY).cwiseProduct((1.0 - Hm.array().square()).matrix());
    step(W2, dY * Hm.transpose(), aW2, t);
    step(B2, dY.rowwise().sum(), ab2, t);
    step(W1, dZ * X.transpose(), aW1, t);
    step(B1, dZ.rowwise().sum(), ab1, t);
  }
  const Eigen::MatrixXd Hm = ((W1 * X).colwise() + B1.col(0)).array().tanh().matrix();
  const Eigen::MatrixXd E = (W2 * Hm).colwise() + B2.col(0) - T;
  *fit_rms = std::sqrt(E.array().square().mean());  // in standard deviations of the target
  for (int r = 0; r < H; ++r)
    for (int c = 0; c < n_in; ++c) net.params.push_back(W1(r, c));
  for (int r = 0; r < H; ++r) net.params.push_back(B1(r, 0));
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < H; ++c) net.params.push_back(W2(r, c));
  for (int r = 0; r < 6; ++r) net.params.push_back(B2(r, 0));
  net.quantised = deploy::quantise_network(net.shape, net.normalisation, net.params);
  return net;
}

TEST(Quantise, FittedNetworkStaysWithinAnEighthOfTheSensorResolution) {
  const auto data = test::random_samples(3000, 21);
  double fit_rms = 1.0;
  const DeployedNetwork net = fitted_network(data, &fit_rms);
  std::printf("  fitted 15-32-6 tanh: training RMS %.3f target standard deviations\n", fit_rms);
  ASSERT_LT(fit_rms, 0.3) << "the quick fit did not learn the target";
  const MaxError e = measure(net, 20000, 99);
  std::printf("  16-bit fitted_15_32_tanh             max |q - f|: %.2e N  %.2e N*m\n", e.force_N,
              e.torque_Nm);
  EXPECT_LE(e.force_N, kForceBound_N);
  EXPECT_LE(e.torque_Nm, kTorqueBound_Nm);
}

TEST(Quantise, PerChannelScalesMapTheLargestWeightOfEachRowToFullScale) {
  const auto data = test::random_samples(500, 3);
  const DeployedNetwork net = test::make_network(feature_range(Feature::r11, Feature::r33), {16},
                                                 Activation::tanh, data, 1.0, 5, 8);
  const QuantisedLayer& l0 = net.quantised.layers[0];
  for (int r = 0; r < 16; ++r) {
    int wmax = 0;
    for (int c = 0; c < 9; ++c) wmax = std::max(wmax, std::abs(int{l0.weights[r * 9 + c]}));
    EXPECT_EQ(wmax, 127) << "row " << r;
  }
  EXPECT_DOUBLE_EQ(l0.input_scale, 8.0 / 32767.0);
  EXPECT_DOUBLE_EQ(l0.output_scale, 1.0 / 32767.0);  // tanh output range is ±1
}

TEST(Quantise, RejectsMalformedNetworks) {
  model::NetworkShape shape{{3, 200, 6}, {Activation::tanh, Activation::identity}};
  model::NetworkNormalisation norm{{0, 0, 0}, {1, 1, 1}, {0, 0, 0, 0, 0, 0}, {1, 1, 1, 1, 1, 1}};
  std::vector<double> p(static_cast<std::size_t>(shape.num_params()), 0.1);
  EXPECT_THROW(deploy::quantise_network(shape, norm, p), std::invalid_argument);  // too wide
  shape.width = {3, 4, 6};
  EXPECT_THROW(deploy::quantise_network(shape, norm, p), std::invalid_argument);  // param count
  p.resize(static_cast<std::size_t>(shape.num_params()));
  deploy::QuantiseOptions o;
  o.weight_bits = 12;
  EXPECT_THROW(deploy::quantise_network(shape, norm, p, o), std::invalid_argument);
  EXPECT_NO_THROW(deploy::quantise_network(shape, norm, p));
}

}  // namespace
}  // namespace zerog::infer
