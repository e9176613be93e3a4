#pragma once
// A simulated calibration run of the demo rig (KR 210 + 100 kg through the orthogonal-array
// path) with some effects hidden in the truth, for the acceptance tests.
#include <string>

#include "zerog/ident/compare.hpp"
#include "zerog/ident/dataset.hpp"
#include "zerog/sim/design.hpp"
#include "zerog/sim/simulator.hpp"

namespace zerog::test {

struct SimRun {
  sim::SimConfig config;
  sim::SimOutput out;
  ident::Dataset data;
};

inline SimRun simulate(const std::string& effects, std::uint64_t seed) {
  sim::SimConfig cfg = sim::default_sim_config(seed);
  cfg.effects = sim::parse_sim_effects(effects);
  sim::DesignOptions d;
  d.kind = sim::DesignKind::oa;
  d.workspace.floor_z_m = cfg.floor_z_m;
  const sim::Design design = sim::make_design(d);
  sim::RigSimulator simulator(cfg, design.points_rad);
  SimRun r{cfg, simulator.run(), {}};
  r.data = ident::make_dataset(r.out.log);
  return r;
}

/// The training blocks of diagnose's default split (every block but each 4th).
inline std::vector<std::uint8_t> training_mask(const ident::Dataset& data) {
  auto m = ident::heldout_mask(data);
  for (auto& v : m) v = v ? 0 : 1;
  return m;
}

/// Held-out error statistics of a model on the run.
inline ident::ErrorStats heldout_stats(const model::ModelParams& p, const ident::Dataset& data) {
  const auto mask = ident::heldout_mask(data);
  return ident::compare(ident::residuals(p, data), data, &mask).all;
}

/// RMS over the held-out samples of the difference of two models' predictions, force (N) and
/// torque (N·m) pooled per group: how far `a` is from `b`, free of the measurement noise.
struct PredictionGap {
  double force = 0.0, torque = 0.0;
};
inline PredictionGap prediction_gap(const model::ModelParams& a, const model::ModelParams& b,
                                    const ident::Dataset& data) {
  const auto mask = ident::heldout_mask(data);
  double f = 0.0, t = 0.0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < data.size(); ++i) {
    if (!mask[i]) continue;
    const ident::Wrench d = ident::predict(a, data, i) - ident::predict(b, data, i);
    f += d.head<3>().squaredNorm();
    t += d.tail<3>().squaredNorm();
    ++n;
  }
  return {std::sqrt(f / (3.0 * static_cast<double>(n))),
          std::sqrt(t / (3.0 * static_cast<double>(n)))};
}

}  // namespace zerog::test
