#include "zerog/learn/quantised.hpp"

#include <stdexcept>

#include "zerog/infer/inference.hpp"
#include "zerog/learn/signals.hpp"

namespace zerog::learn {

infer::RigDescription rig_description(const formats::Rig& r) {
  infer::RigDescription d;
  d.name = r.name;
  d.robot = r.robot;
  d.p_flange_sensor_m = r.flange_sensor.p_m;
  d.q_flange_sensor = r.flange_sensor.q.normalized();
  d.p_sensor_imu_m = r.sensor_imu.p_m;
  d.q_sensor_imu = r.sensor_imu.q.normalized();
  d.sample_period_s = r.sample_period_s;
  return d;
}

infer::DeployedNetwork deploy_network(const NetworkFile& net, deploy::QuantiseOptions q,
                                      const ident::Dataset* data, const formats::Log* log) {
  // QuantiseOptions::calibration_inputs is a view: the rows must outlive the quantisation.
  // (They were a temporary once: ASan found the read after free.)
  std::vector<double> rows;
  if (data && log) {
    check_feature_signals(net.inputs, *data);
    std::vector<std::size_t> idx;
    const std::size_t n = data->size(), step = std::max<std::size_t>(1, n / 20000);
    for (std::size_t i = 0; i < n; i += step) idx.push_back(i);
    rows = feature_rows(*data, *log, net.inputs, idx);
    q.calibration_inputs = rows;
  }
  return deploy::make_deployed_network(net.inputs, net.output_axes, net.shape, net.normalisation,
                                       net.params, q);
}

std::vector<ident::Wrench> quantised_prediction(const NetworkFile& residual,
                                                const ident::Dataset& data,
                                                const formats::Log& log) {
  if (residual.kind != NetworkKind::residual || !residual.physics)
    throw std::runtime_error(
        "quantised prediction needs a residual network with its physics model");
  infer::DeployedModel m;
  m.rig = rig_description(log.rig);
  m.physics = residual.physics->params;
  m.network = deploy_network(residual, {}, &data, &log);
  infer::Inference inference;
  if (const Status st = inference.configure(std::move(m)); !st.ok())
    throw std::runtime_error("quantised inference: " + st.text());
  std::vector<model::FeatureSignals> signals(data.size());
  for (std::size_t i = 0; i < data.size(); ++i) signals[i] = feature_signals(data, log, i);
  std::vector<infer::Wrench> out(data.size());
  const std::size_t bad = infer::evaluate_sequence(inference, infer::Path::quantised, signals, out);
  if (bad != 0)
    throw std::runtime_error("quantised inference: " + std::to_string(bad) + " of " +
                             std::to_string(data.size()) + " samples saturated or not evaluated");
  std::vector<ident::Wrench> pred(data.size());
  for (std::size_t i = 0; i < data.size(); ++i) pred[i] = out[i];
  return pred;
}

}  // namespace zerog::learn
