#include "zerog/deploy/quantise.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "zerog/infer/quant_math.hpp"

namespace zerog::deploy {
namespace {

using infer::bias_limit;
using infer::DeployedNetwork;
using infer::kActMax;
using infer::QuantisedLayer;
using infer::QuantisedNetwork;

using model::Activation;

// The network made of layers 0..last of `shape`, with raw outputs (no output scaling): its
// forward pass yields the activations of layer `last` through the one model::network_forward.
model::NetworkShape prefix_shape(const model::NetworkShape& shape, int last) {
  model::NetworkShape s;
  s.width.assign(shape.width.begin(), shape.width.begin() + last + 2);
  s.activation.assign(shape.activation.begin(), shape.activation.begin() + last + 1);
  return s;
}

// Largest |output| of each layer over the box |x_n| ≤ clip (interval arithmetic; activations
// are monotone, so the bounds of the pre-activation map to bounds of the output).
std::vector<double> interval_bounds(const model::NetworkShape& shape, const double* params,
                                    double clip) {
  std::vector<double> lo(static_cast<std::size_t>(shape.width[0]), -clip);
  std::vector<double> hi(lo.size(), clip);
  std::vector<double> bound;
  const double* p = params;
  for (int l = 0; l < shape.num_layers(); ++l) {
    const int n = shape.width[l], m = shape.width[l + 1];
    std::vector<double> nlo(static_cast<std::size_t>(m)), nhi(static_cast<std::size_t>(m));
    double b = 0.0;
    for (int r = 0; r < m; ++r) {
      double zlo = p[m * n + r], zhi = zlo;
      for (int c = 0; c < n; ++c) {
        const double w = p[r * n + c];
        zlo += w > 0 ? w * lo[c] : w * hi[c];
        zhi += w > 0 ? w * hi[c] : w * lo[c];
      }
      nlo[r] = model::activate(shape.activation[l], zlo);
      nhi[r] = model::activate(shape.activation[l], zhi);
      b = std::max({b, std::abs(nlo[r]), std::abs(nhi[r])});
    }
    bound.push_back(b);
    lo.swap(nlo);
    hi.swap(nhi);
    p += m * n + m;
  }
  return bound;
}

}  // namespace

QuantisedNetwork quantise_network(const model::NetworkShape& shape,
                                  const model::NetworkNormalisation& norm,
                                  std::span<const double> params, const QuantiseOptions& options) {
  const int L = shape.num_layers();
  if (L < 1 || static_cast<int>(shape.width.size()) != L + 1)
    throw std::invalid_argument("network: need width.size() == layers + 1 and at least 1 layer");
  for (int w : shape.width)
    if (w < 1 || w > model::kMaxNetworkWidth)
      throw std::invalid_argument("network: layer width " + std::to_string(w) + " outside 1.." +
                                  std::to_string(model::kMaxNetworkWidth));
  if (static_cast<int>(params.size()) != shape.num_params())
    throw std::invalid_argument("network: " + std::to_string(params.size()) +
                                " parameters, the shape needs " +
                                std::to_string(shape.num_params()));
  const auto n_in = static_cast<std::size_t>(shape.width[0]);
  if (norm.input_mean.size() != n_in || norm.input_scale.size() != n_in)
    throw std::invalid_argument("network: input normalisation size differs from the inputs");
  if (options.weight_bits != 8 && options.weight_bits != 16)
    throw std::invalid_argument("quantisation: weight_bits must be 8 or 16");
  if (!(options.input_clip > 0.0) || !std::isfinite(options.input_clip))
    throw std::invalid_argument("quantisation: input_clip must be positive");
  if (!options.calibration_inputs.empty() && options.calibration_inputs.size() % n_in != 0)
    throw std::invalid_argument("quantisation: calibration inputs are not whole rows");

  QuantisedNetwork q;
  q.weight_bits = options.weight_bits;
  q.input_clip = options.input_clip;

  // Calibration: largest |activation| of each layer over synthetic and given inputs.
  const std::vector<double> box = interval_bounds(shape, params.data(), options.input_clip);
  std::vector<double> seen(static_cast<std::size_t>(L), 0.0);
  {
    std::mt19937_64 rng(options.seed);
    std::normal_distribution<double> gauss(0.0, 1.0);
    std::vector<double> x(n_in);
    std::vector<std::vector<double>> raw_rows;
    const std::size_t n_given = options.calibration_inputs.size() / n_in;
    const std::size_t total = static_cast<std::size_t>(options.synthetic_samples) + n_given;
    std::array<double, model::kMaxNetworkWidth> sa{}, sb{}, y{};
    model::NetworkNormalisation identity_out = norm;
    for (std::size_t i = 0; i < total; ++i) {
      if (i < static_cast<std::size_t>(options.synthetic_samples)) {
        for (std::size_t k = 0; k < n_in; ++k) {
          const double z = std::clamp(gauss(rng), -options.input_clip, options.input_clip);
          x[k] = norm.input_mean[k] + z * norm.input_scale[k];
        }
      } else {
        const double* row =
            &options.calibration_inputs[(i - static_cast<std::size_t>(options.synthetic_samples)) *
                                        n_in];
        std::copy(row, row + n_in, x.begin());
      }
      for (int l = 0; l < L; ++l) {
        const model::NetworkShape sub = prefix_shape(shape, l);
        const auto m = static_cast<std::size_t>(shape.width[l + 1]);
        identity_out.output_mean.assign(m, 0.0);
        identity_out.output_scale.assign(m, 1.0);
        model::network_forward<double>(sub, identity_out, params.data(), x.data(), y.data(),
                                       sa.data(), sb.data());
        for (std::size_t r = 0; r < m; ++r) seen[l] = std::max(seen[l], std::abs(y[r]));
      }
    }
  }

  double input_scale = options.input_clip / kActMax;
  const int qmax = options.weight_bits == 8 ? 127 : 32767;
  const double* p = params.data();
  for (int l = 0; l < L; ++l) {
    const int n = shape.width[l], m = shape.width[l + 1];
    QuantisedLayer layer;
    layer.input_scale = input_scale;
    layer.weights.resize(static_cast<std::size_t>(m * n));
    layer.weight_scale.resize(static_cast<std::size_t>(m));
    layer.bias.resize(static_cast<std::size_t>(m));
    for (int r = 0; r < m; ++r) {
      double wmax = 0.0;
      for (int c = 0; c < n; ++c) wmax = std::max(wmax, std::abs(p[r * n + c]));
      const double s = wmax > 0.0 ? wmax / qmax : 1.0;
      layer.weight_scale[r] = s;
      for (int c = 0; c < n; ++c) {
        const double v = std::clamp(std::nearbyint(p[r * n + c] / s), -double(qmax), double(qmax));
        layer.weights[r * n + c] = static_cast<std::int16_t>(v);
      }
      const double limit = static_cast<double>(bias_limit(options.weight_bits));
      const double b = std::nearbyint(p[m * n + r] / (s * input_scale));
      if (!std::isfinite(b) || std::abs(b) > limit)
        throw std::invalid_argument("quantisation: bias of layer " + std::to_string(l) +
                                    " output " + std::to_string(r) +
                                    " exceeds the accumulator range; use weight_bits 16 or a "
                                    "smaller input_clip");
      layer.bias[r] = static_cast<std::int64_t>(b);
    }
    const Activation a = shape.activation[l];
    double out_range = 0.0;
    if (a == Activation::sigmoid || a == Activation::tanh) {
      out_range = 1.0;
    } else {
      out_range = std::min(box[l], options.headroom * seen[l]);
      if (!(out_range > 0.0)) out_range = 1.0;  // a dead layer: any scale will do
    }
    layer.output_scale = out_range / kActMax;
    input_scale = layer.output_scale;
    q.layers.push_back(std::move(layer));
    p += m * n + m;
  }
  return q;
}

DeployedNetwork make_deployed_network(std::vector<model::Feature> features,
                                      std::vector<int> output_axes, model::NetworkShape shape,
                                      model::NetworkNormalisation norm, std::vector<double> params,
                                      const QuantiseOptions& options) {
  DeployedNetwork n;
  n.quantised = quantise_network(shape, norm, params, options);
  n.features = std::move(features);
  n.output_axes = std::move(output_axes);
  n.shape = std::move(shape);
  n.normalisation = std::move(norm);
  n.params = std::move(params);
  if (n.features.size() != static_cast<std::size_t>(n.shape.width.front()))
    throw std::invalid_argument("network: " + std::to_string(n.features.size()) + " features for " +
                                std::to_string(n.shape.width.front()) + " inputs");
  if (n.output_axes.size() != static_cast<std::size_t>(n.shape.width.back()))
    throw std::invalid_argument("network: " + std::to_string(n.output_axes.size()) +
                                " output axes for " + std::to_string(n.shape.width.back()) +
                                " outputs");
  return n;
}

}  // namespace zerog::deploy
