#pragma once
// Shared fixtures of infer_test and infer_bench: realistic random signals of a KR 210 wrist,
// networks with trained-like weights, a quickly fitted network, and a complete deployed model.
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "zerog/deploy/quantise.hpp"
#include "zerog/infer/deploy_model.hpp"
#include "zerog/model/features.hpp"
#include "zerog/model/network.hpp"

namespace zerog::infer::test {

using model::Activation;
using model::Feature;

/// One sample of a moving KR 210 R2700 with a 100 kg payload: joint angles within the axis
/// ranges, joint rates up to about 1 rad/s, the sensor anywhere in the workspace, IMU specific
/// force = gravity reaction plus up to a few m/s² of acceleration, angular rate and acceleration
/// of PTP moves, sensor temperature 20–35 °C, up to 20 min into the run.
inline model::FeatureSignals random_signals(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  constexpr double deg = std::numbers::pi / 180.0;
  const double lo[6] = {-185, -140, -120, -350, -125, -350};
  const double hi[6] = {185, -5, 168, 350, 125, 350};
  model::FeatureSignals s;
  for (int j = 0; j < 6; ++j) {
    s.joints_rad[j] = deg * (lo[j] + (hi[j] - lo[j]) * 0.5 * (u(rng) + 1.0));
    s.joint_vel_radps[j] = std::clamp(0.3 * g(rng), -1.5, 1.5);
  }
  const Eigen::Quaterniond q = Eigen::Quaterniond(g(rng), g(rng), g(rng), g(rng)).normalized();
  const Eigen::Matrix3d R = q.toRotationMatrix();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) s.R_base_sensor[r * 3 + c] = R(r, c);
  s.p_base_sensor_m = {1.5 + u(rng), 1.8 * u(rng), 0.8 + 1.2 * u(rng)};
  const Eigen::Vector3d f = R.transpose() * Eigen::Vector3d(0, 0, 9.80665) +
                            1.5 * Eigen::Vector3d(g(rng), g(rng), g(rng));
  for (int k = 0; k < 3; ++k) {
    s.imu[k] = f[k];
    s.imu[3 + k] = 0.3 * g(rng);
    s.imu[6 + k] = 1.0 * g(rng);
  }
  s.temperature_C = 27.5 + 7.5 * u(rng);
  s.t_s = 600.0 + 600.0 * u(rng);
  return s;
}

inline std::vector<model::FeatureSignals> random_samples(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<model::FeatureSignals> out(n);
  for (auto& s : out) s = random_signals(rng);
  return out;
}

inline std::vector<Feature> feature_range(Feature first, Feature last) {
  std::vector<Feature> f;
  for (int i = static_cast<int>(first); i <= static_cast<int>(last); ++i)
    f.push_back(static_cast<Feature>(i));
  return f;
}

/// Input normalisation as a trainer computes it (mean and standard deviation over the data);
/// output normalisation: the residual of the paper's default model on the demo run (README:
/// about 3 N and 0.7 N·m RMS).
inline model::NetworkNormalisation normalisation_for(
    const std::vector<Feature>& features, const std::vector<model::FeatureSignals>& data) {
  model::NetworkNormalisation n;
  const std::size_t k = features.size();
  n.input_mean.assign(k, 0.0);
  n.input_scale.assign(k, 0.0);
  std::vector<double> x(k);
  for (const auto& s : data) {
    model::compute_features(s, features, x.data());
    for (std::size_t i = 0; i < k; ++i) n.input_mean[i] += x[i];
  }
  for (double& m : n.input_mean) m /= static_cast<double>(data.size());
  for (const auto& s : data) {
    model::compute_features(s, features, x.data());
    for (std::size_t i = 0; i < k; ++i)
      n.input_scale[i] += (x[i] - n.input_mean[i]) * (x[i] - n.input_mean[i]);
  }
  for (double& v : n.input_scale)
    v = std::max(std::sqrt(v / static_cast<double>(data.size())), 1e-9);
  n.output_mean = {0.4, -0.3, 0.8, 0.05, -0.04, 0.02};
  n.output_scale = {3.0, 3.0, 3.0, 0.7, 0.7, 0.7};
  return n;
}

/// Weights as training leaves them: He/Glorot scale (2/fan_in for leaky_relu, 1/fan_in else)
/// times `gain` (trained weights grow beyond their initial scale), biases of 0.1 × gain.
inline std::vector<double> random_params(const model::NetworkShape& shape, double gain,
                                         std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<double> p;
  for (int l = 0; l < shape.num_layers(); ++l) {
    const int n = shape.width[l], m = shape.width[l + 1];
    const double var = (shape.activation[l] == Activation::leaky_relu ? 2.0 : 1.0) / n;
    for (int i = 0; i < m * n; ++i) p.push_back(gain * std::sqrt(var) * g(rng));
    for (int i = 0; i < m; ++i) p.push_back(0.1 * gain * g(rng));
  }
  return p;
}

/// A network in the deployed form (float and quantised), for `features`.
inline DeployedNetwork make_network(const std::vector<Feature>& features,
                                    const std::vector<int>& hidden, Activation act,
                                    const std::vector<model::FeatureSignals>& data, double gain,
                                    std::uint64_t seed, int weight_bits = 16) {
  DeployedNetwork net;
  net.features = features;
  net.output_axes = {0, 1, 2, 3, 4, 5};
  net.shape.width.push_back(static_cast<int>(features.size()));
  for (int h : hidden) {
    net.shape.width.push_back(h);
    net.shape.activation.push_back(act);
  }
  net.shape.width.push_back(6);
  net.shape.activation.push_back(Activation::identity);
  net.normalisation = normalisation_for(features, data);
  net.params = random_params(net.shape, gain, seed);
  // Training fits standardised targets, so a trained network's normalised outputs have a
  // standard deviation of about 1 whatever its hidden weights: rescale the last layer to that.
  {
    const int L = net.shape.num_layers();
    const int n = net.shape.width[L - 1];
    std::vector<double> x(features.size());
    std::array<double, model::kMaxNetworkWidth> y{}, sa{}, sb{};
    model::NetworkNormalisation raw = net.normalisation;
    raw.output_mean.assign(6, 0.0);
    raw.output_scale.assign(6, 1.0);
    std::array<double, 6> sum{}, sum2{};
    for (const auto& s : data) {
      model::compute_features(s, features, x.data());
      model::network_forward<double>(net.shape, raw, net.params.data(), x.data(), y.data(),
                                     sa.data(), sb.data());
      for (int k = 0; k < 6; ++k) {
        sum[k] += y[k];
        sum2[k] += y[k] * y[k];
      }
    }
    const double N = static_cast<double>(data.size());
    double* last = net.params.data() + net.params.size() - (6 * n + 6);
    for (int k = 0; k < 6; ++k) {
      const double sd = std::sqrt(std::max(sum2[k] / N - (sum[k] / N) * (sum[k] / N), 1e-12));
      for (int c = 0; c < n; ++c) last[k * n + c] /= sd;
      last[6 * n + k] /= sd;
    }
  }
  deploy::QuantiseOptions o;
  o.weight_bits = weight_bits;
  net.quantised = deploy::quantise_network(net.shape, net.normalisation, net.params, o);
  return net;
}

/// A rig like the demo's (proto/log_format.md example).
inline RigDescription demo_rig() {
  RigDescription r;
  r.name = "kr210-omega191-stim300";
  r.robot = "KR 210 R2700";
  r.p_flange_sensor_m = {0.0, 0.0, 0.06};
  r.p_sensor_imu_m = {0.0, 0.0, -0.03};
  r.q_sensor_imu =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.5 * std::numbers::pi, Eigen::Vector3d::UnitZ()));
  r.sample_period_s = 0.012;
  return r;
}

/// The paper's default model with a 100 kg payload, plus cable and temperature terms.
inline model::ModelParams demo_physics() {
  using model::Effect;
  model::ModelParams p;
  p.effects = {Effect::bias,
               Effect::gravity,
               Effect::linear_inertia,
               Effect::rotational_inertia,
               Effect::temperature_bias,
               Effect::cable};
  const double bias[6] = {12.3, -4.5, 7.8, 0.9, -0.4, 0.2};
  std::copy(bias, bias + 6, p.block(Effect::bias));
  const double grav[4] = {100.0, 0.01, -0.02, 0.25};
  std::copy(grav, grav + 4, p.block(Effect::gravity));
  const double inertia[6] = {4.1, 3.9, 2.2, 0.05, -0.03, 0.02};
  std::copy(inertia, inertia + 6, p.block(Effect::rotational_inertia));
  for (int k = 0; k < 6; ++k) p.block(Effect::temperature_bias)[k] = 0.01 * (k + 1);
  for (int k = 0; k < 36; ++k) p.block(Effect::cable)[k] = 0.5 * std::sin(1.7 * k);
  return p;
}

}  // namespace zerog::infer::test
