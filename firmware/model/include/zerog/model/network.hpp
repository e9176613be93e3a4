#pragma once
// A small dense network (multi-layer perceptron) in floating point: the one definition of the
// forward pass, templated on the scalar so Ceres trains it (host, ceres::Jet) and the firmware
// evaluates it as the float reference of its quantised path. No allocation in `forward`:
// the caller provides the scratch buffers (sized once, at load).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

namespace zerog::model {

enum class Activation : std::uint8_t {
  identity,
  sigmoid,     ///< 1 / (1 + e^−x) (paper 000_… §3)
  leaky_relu,  ///< max(0.01 x, x) (paper 001_… §3.1)
  tanh,
};
const char* activation_name(Activation a);
bool activation_from_name(const char* name, Activation& out);

inline constexpr int kMaxNetworkWidth = 128;  ///< widest layer (paper-zp uses 90)
inline constexpr int kMaxNetworkLayers = 4;   ///< dense layers, output layer included

template <typename T>
T activate(Activation a, const T& x) {
  using std::exp, std::tanh;
  switch (a) {
    case Activation::sigmoid:
      // Two branches so neither exponential overflows (a plain 1 / (1 + e^−x) gives inf/inf =
      // NaN derivatives under autodiff for x < −709).
      if (x >= T(0)) return T(1) / (T(1) + exp(-x));
      {
        const T e = exp(x);
        return e / (T(1) + e);
      }
    case Activation::leaky_relu:
      return x > T(0) ? x : T(0.01) * x;
    case Activation::tanh:
      return tanh(x);
    case Activation::identity:
      break;
  }
  return x;
}

/// Shape of a network: input normalisation, then dense layers. Layer l maps width[l] inputs to
/// width[l+1] outputs with activation[l] (the last layer's is usually identity).
struct NetworkShape {
  std::vector<int> width;              ///< width[0] = inputs, width.back() = outputs
  std::vector<Activation> activation;  ///< one per layer (width.size() − 1)
  int num_layers() const { return static_cast<int>(activation.size()); }
  /// Number of parameters (weights and biases) of layer l, and in all.
  int layer_params(int l) const { return width[l + 1] * width[l] + width[l + 1]; }
  int num_params() const {
    int n = 0;
    for (int l = 0; l < num_layers(); ++l) n += layer_params(l);
    return n;
  }
};

/// Parameters laid out layer by layer: W (row-major, width[l+1] × width[l]) then b.
/// Inputs are normalised first: x_n = (x − input_mean) / input_scale; outputs are scaled
/// back: y = y_n * output_scale + output_mean.
struct NetworkNormalisation {
  std::vector<double> input_mean, input_scale, output_mean, output_scale;
};

/// Forward pass. `params` holds shape.num_params() values (layout above); `x` the raw inputs;
/// `y` receives the raw outputs; `scratch` two buffers of kMaxNetworkWidth each.
/// Real-time safe (no allocation, no exceptions) for any scalar type T.
template <typename T>
void network_forward(const NetworkShape& shape, const NetworkNormalisation& norm, const T* params,
                     const double* x, T* y, T* scratch_a, T* scratch_b) {
  const int n_in = shape.width.front();
  for (int i = 0; i < n_in; ++i)
    scratch_a[i] = T((x[i] - norm.input_mean[i]) / norm.input_scale[i]);
  T* in = scratch_a;
  T* out = scratch_b;
  const T* p = params;
  for (int l = 0; l < shape.num_layers(); ++l) {
    const int n = shape.width[l], m = shape.width[l + 1];
    const T* W = p;
    const T* b = p + m * n;
    for (int r = 0; r < m; ++r) {
      T acc = b[r];
      for (int c = 0; c < n; ++c) acc += W[r * n + c] * in[c];
      out[r] = activate(shape.activation[l], acc);
    }
    p += m * n + m;
    std::swap(in, out);
  }
  const int n_out = shape.width.back();
  for (int k = 0; k < n_out; ++k) y[k] = in[k] * T(norm.output_scale[k]) + T(norm.output_mean[k]);
}

}  // namespace zerog::model
