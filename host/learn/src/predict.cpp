#include "zerog/learn/predict.hpp"

#include <stdexcept>

#include "zerog/learn/signals.hpp"

namespace zerog::learn {

std::vector<double> network_outputs(const NetworkFile& net, const ident::Dataset& data,
                                    const formats::Log& log) {
  validate(net);
  check_feature_signals(net.inputs, data);
  if (log.samples.size() != data.size())
    throw std::invalid_argument("the dataset was not made from this log");
  const auto d = net.inputs.size();
  const auto k = net.output_axes.size();
  std::vector<double> out(data.size() * k), x(d);
  std::vector<double> sa(model::kMaxNetworkWidth), sb(model::kMaxNetworkWidth);
  for (std::size_t i = 0; i < data.size(); ++i) {
    model::compute_features(feature_signals(data, log, i), net.inputs, x.data());
    model::network_forward<double>(net.shape, net.normalisation, net.params.data(), x.data(),
                                   &out[i * k], sa.data(), sb.data());
  }
  return out;
}

ident::Wrench tool_wrench(const ToolLoad& tool, const Eigen::Matrix3d& R_base_sensor) {
  const Eigen::Vector3d g = R_base_sensor.transpose() * tool.gravity_base_N;  // eq. 15, ˢG
  Eigen::Matrix3d A;                                                          // eq. 8
  A << 0, g.z(), -g.y(), -g.z(), 0, g.x(), g.y(), -g.x(), 0;
  ident::Wrench w;
  w << g, A * tool.cog_sensor_m;
  return w;
}

std::vector<ident::Wrench> predictions(const NetworkFile& net, const ident::Dataset& data,
                                       const formats::Log& log) {
  const std::vector<double> y = network_outputs(net, data, log);
  const auto k = net.output_axes.size();
  if (net.physics) ident::check_signals(net.physics->params.effects, data);
  std::vector<ident::Wrench> out(data.size(), ident::Wrench::Zero());
  for (std::size_t i = 0; i < data.size(); ++i) {
    ident::Wrench& w = out[i];
    if (net.kind == NetworkKind::residual) w = ident::predict(net.physics->params, data, i);
    if (net.kind == NetworkKind::paper_zp)
      w = tool_wrench(*net.tool_load, data.pose(i).R_base_sensor);
    for (std::size_t o = 0; o < k; ++o) w[net.output_axes[o]] += y[i * k + o];
  }
  return out;
}

}  // namespace zerog::learn
