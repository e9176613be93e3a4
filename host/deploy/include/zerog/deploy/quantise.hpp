#pragma once
// Post-training quantisation of a float network (model::network_forward layout) into the integer
// form the firmware evaluates (proto/deploy_format.md "Quantisation"). Host side (export and
// tests): allocates, throws std::invalid_argument on a malformed network. Not real-time safe.
#include <cstdint>
#include <span>

#include "zerog/infer/deploy_model.hpp"

namespace zerog::deploy {

struct QuantiseOptions {
  int weight_bits = 16;     ///< 8 or 16, per-output-channel scales either way
  double input_clip = 8.0;  ///< normalised inputs beyond ±input_clip saturate (standard scores)
  /// Hidden identity/leaky_relu layers: their int16 range is headroom × the largest |activation|
  /// seen on the calibration inputs, capped by the interval bound over the input box.
  double headroom = 2.0;
  int synthetic_samples = 4096;  ///< calibration inputs drawn as N(0, 1) normalised features
  std::uint64_t seed = 1;
  /// Optional real calibration inputs: raw (un-normalised) feature vectors, row-major,
  /// n × width[0]. Used together with the synthetic ones.
  std::span<const double> calibration_inputs;
};

/// Quantises the float network `params` (shape.num_params() values). Weights: symmetric, one
/// scale per output channel (max |w| of the row maps to 2^(bits−1) − 1). Activations: int16, one
/// scale per layer (inputs: input_clip; sigmoid/tanh outputs: 1/32767; identity/leaky_relu
/// hidden outputs: calibrated). Throws std::invalid_argument if the network is malformed.
infer::QuantisedNetwork quantise_network(const model::NetworkShape& shape,
                                         const model::NetworkNormalisation& norm,
                                         std::span<const double> params,
                                         const QuantiseOptions& options = {});

/// Packages a trained float network for deployment: the float reference as given plus its
/// quantised form. `output_axes` as in DeployedNetwork. Throws std::invalid_argument if the
/// parts do not fit together. Host side.
infer::DeployedNetwork make_deployed_network(std::vector<model::Feature> features,
                                             std::vector<int> output_axes,
                                             model::NetworkShape shape,
                                             model::NetworkNormalisation norm,
                                             std::vector<double> params,
                                             const QuantiseOptions& options = {});

}  // namespace zerog::deploy
