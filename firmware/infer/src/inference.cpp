#include "zerog/infer/inference.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "zerog/infer/deploy_file.hpp"
#include "zerog/infer/quant_math.hpp"
#include "zerog/model/signals.hpp"

namespace zerog::infer {
namespace {

using model::Activation;

std::vector<std::int32_t> make_lut(Activation a) {
  std::vector<std::int32_t> lut(kLutIntervals + 1);
  for (int i = 0; i <= kLutIntervals; ++i) {
    const double z = -kLutRange + std::ldexp(static_cast<double>(i), -kLutStepLog2);
    lut[static_cast<std::size_t>(i)] =
        static_cast<std::int32_t>(std::nearbyint(model::activate(a, z) * kActMax));
  }
  return lut;
}

// f(z) for z in Q16 from the table, in units of 1/32767.
inline std::int32_t lut_eval(const std::int32_t* lut, std::int64_t z_q16) {
  const std::int64_t u = std::clamp(z_q16, -kLutZMax, kLutZMax) + kLutZMax;
  std::int64_t i = u >> kLutShift;
  std::int64_t frac = u & ((std::int64_t{1} << kLutShift) - 1);
  if (i >= kLutIntervals) {
    i = kLutIntervals - 1;
    frac = std::int64_t{1} << kLutShift;
  }
  const std::int64_t a = lut[i], b = lut[i + 1];
  return static_cast<std::int32_t>(
      a + (((b - a) * frac + (std::int64_t{1} << (kLutShift - 1))) >> kLutShift));
}

inline std::int16_t narrow16(std::int64_t v, int& clipped) {
  if (v > kActMaxInt) {
    ++clipped;
    return static_cast<std::int16_t>(kActMaxInt);
  }
  if (v < -kActMaxInt) {
    ++clipped;
    return static_cast<std::int16_t>(-kActMaxInt);
  }
  return static_cast<std::int16_t>(v);
}

// Dot products. The int32 one vectorises to pmaddwd; the bounds in quant_math.hpp rule out
// overflow for each accumulator type.
inline std::int32_t dot32(const std::int16_t* w, const std::int16_t* x, int n) {
  std::int32_t acc = 0;
  for (int c = 0; c < n; ++c) acc += static_cast<std::int32_t>(w[c]) * x[c];
  return acc;
}
inline std::int64_t dot64(const std::int16_t* w, const std::int16_t* x, int n) {
  std::int64_t acc = 0;
  for (int c = 0; c < n; ++c)
    acc += static_cast<std::int64_t>(static_cast<std::int32_t>(w[c]) * x[c]);
  return acc;
}

model::PoseSignals pose_of(const model::FeatureSignals& s) {
  model::PoseSignals p;
  p.R_base_sensor =
      Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(s.R_base_sensor.data());
  p.t_rel_s = s.t_s;
  p.temperature_C = s.temperature_C;
  p.joints_rad = s.joints_rad;
  return p;
}

bool finite(const Wrench& w) { return w.allFinite(); }

}  // namespace

model::ImuSignals<double> imu_signals(const model::FeatureSignals& s) {
  model::ImuSignals<double> imu;
  imu.specific_force_imu = Eigen::Map<const Eigen::Vector3d>(&s.imu[0]);
  imu.angular_rate_imu = Eigen::Map<const Eigen::Vector3d>(&s.imu[3]);
  imu.angular_accel_imu = Eigen::Map<const Eigen::Vector3d>(&s.imu[6]);
  return imu;
}

const char* status_name(StatusCode c) {
  switch (c) {
    case StatusCode::ok:
      return "ok";
    case StatusCode::saturated:
      return "saturated";
    case StatusCode::non_finite:
      return "non_finite";
    case StatusCode::not_configured:
      break;
  }
  return "not_configured";
}

zerog::Status Inference::configure(DeployedModel model) {
  if (zerog::Status st = validate_model(model); !st.ok()) return st;
  // Build everything into a fresh object, then hand it over whole.
  Inference next;
  next.geometry_ = model.rig.geometry();
  if (model.network) {
    const DeployedNetwork& net = *model.network;
    const QuantisedNetwork& q = net.quantised;
    next.wide_acc_ = q.weight_bits == 16;
    const int L = net.shape.num_layers();
    const double s_in0 = q.layers.front().input_scale;
    next.input_inv_step_.resize(net.features.size());
    for (std::size_t k = 0; k < net.features.size(); ++k)
      next.input_inv_step_[k] = 1.0 / (net.normalisation.input_scale[k] * s_in0);
    for (int l = 0; l < L; ++l) {
      const QuantisedLayer& ql = q.layers[static_cast<std::size_t>(l)];
      Layer layer;
      layer.inputs = net.shape.width[l];
      layer.outputs = net.shape.width[l + 1];
      layer.activation = net.shape.activation[l];
      layer.last = l == L - 1;
      layer.weights = ql.weights;
      layer.bias = ql.bias;
      layer.bias32.resize(ql.bias.size());
      for (std::size_t r = 0; r < ql.bias.size(); ++r)
        layer.bias32[r] = static_cast<std::int32_t>(
            std::clamp<std::int64_t>(ql.bias[r], -bias_limit(8), bias_limit(8)));
      const auto m = static_cast<std::size_t>(layer.outputs);
      layer.m0.resize(m);
      layer.m0_neg.resize(m);
      layer.shift.resize(m);
      layer.shift_neg.resize(m);
      layer.dequant.resize(m);
      const bool lut =
          layer.activation == Activation::sigmoid || layer.activation == Activation::tanh;
      for (std::size_t r = 0; r < m; ++r) {
        const double unit = ql.weight_scale[r] * ql.input_scale;  // value of one acc unit
        layer.dequant[r] = unit;
        // LUT layers requantise to z in Q16; the others straight to the output scale.
        const double M = lut ? unit * std::ldexp(1.0, kLutFracBits) : unit / ql.output_scale;
        const Requant pos = make_requant(M);
        const Requant neg = make_requant(0.01 * M);  // leaky_relu slope (network.hpp)
        layer.m0[r] = pos.m0;
        layer.shift[r] = static_cast<std::int8_t>(pos.shift);
        layer.m0_neg[r] = neg.m0;
        layer.shift_neg[r] = static_cast<std::int8_t>(neg.shift);
      }
      if (layer.activation == Activation::sigmoid && next.lut_sigmoid_.empty())
        next.lut_sigmoid_ = make_lut(Activation::sigmoid);
      if (layer.activation == Activation::tanh && next.lut_tanh_.empty())
        next.lut_tanh_ = make_lut(Activation::tanh);
      next.layers_.push_back(std::move(layer));
    }
  }
  next.model_ = std::move(model);
  next.configured_ = true;
  *this = std::move(next);
  return {};
}

double Inference::imu_time_offset_s() const {
  return model_.physics.effects.has(model::Effect::imu_time_offset)
             ? model_.physics.block(model::Effect::imu_time_offset)[0]
             : 0.0;
}

Status Inference::network_quantised(const double* x, double* y) noexcept {
  const DeployedNetwork& net = *model_.network;
  int clipped = 0;
  const int n_in = net.shape.width.front();
  std::int16_t* in = act_a_.data();
  std::int16_t* out = act_b_.data();
  for (int k = 0; k < n_in; ++k) {
    const double v = std::nearbyint((x[k] - net.normalisation.input_mean[k]) * input_inv_step_[k]);
    in[k] = narrow16(static_cast<std::int64_t>(std::clamp(v, -1e9, 1e9)), clipped);
  }
  for (const Layer& layer : layers_) {
    const int n = layer.inputs;
    for (int r = 0; r < layer.outputs; ++r) {
      const std::int16_t* w = &layer.weights[static_cast<std::size_t>(r * n)];
      const std::int64_t acc = wide_acc_ ? layer.bias[r] + dot64(w, in, n)
                                         : std::int64_t{layer.bias32[r] + dot32(w, in, n)};
      switch (layer.activation) {
        case Activation::sigmoid:
        case Activation::tanh: {
          const std::int64_t z = apply(acc, {layer.m0[r], layer.shift[r]});
          const std::int32_t* lut =
              layer.activation == Activation::sigmoid ? lut_sigmoid_.data() : lut_tanh_.data();
          const std::int32_t a = lut_eval(lut, z);
          if (layer.last)
            y[r] = a / kActMax;
          else
            out[r] = narrow16(a, clipped);
          break;
        }
        case Activation::leaky_relu:
        case Activation::identity: {
          const bool negative_slope = layer.activation == Activation::leaky_relu && acc < 0;
          if (layer.last) {
            y[r] = static_cast<double>(acc) * layer.dequant[r] * (negative_slope ? 0.01 : 1.0);
          } else {
            const Requant rq = negative_slope ? Requant{layer.m0_neg[r], layer.shift_neg[r]}
                                              : Requant{layer.m0[r], layer.shift[r]};
            out[r] = narrow16(apply(acc, rq), clipped);
          }
          break;
        }
      }
    }
    std::swap(in, out);
  }
  for (std::size_t k = 0; k < net.output_axes.size(); ++k)
    y[k] = y[k] * net.normalisation.output_scale[k] + net.normalisation.output_mean[k];
  Status st;
  st.clipped_values = static_cast<std::uint16_t>(std::min(clipped, 65535));
  st.code = clipped > 0 ? StatusCode::saturated : StatusCode::ok;
  return st;
}

Status Inference::evaluate(Path path, const model::FeatureSignals& s,
                           const model::ImuSignals<double>& physics_imu, Wrench& out,
                           const model::KinematicInputs* kinematics) noexcept {
  if (!configured_) return {StatusCode::not_configured, 0};
  const auto p = model::pointers(model_.physics);
  Wrench w =
      model::predict_wrench<double>(model_.physics.effects, p, pose_of(s), physics_imu, geometry_);
  if (!model_.physics.user.empty()) {
    model::KinematicInputs fallback;
    if (kinematics == nullptr) fallback.features = s;
    const model::DictionarySignals d =
        model::dictionary_signals(kinematics ? *kinematics : fallback, geometry_);
    const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> R(s.R_base_sensor.data());
    w += model::user_wrench(model_.physics.user, d, R);
  }
  Wrench r;
  const Status st = residual(path, s, r);
  if (st.code == StatusCode::non_finite) return st;
  w += r;
  if (!finite(w)) return {StatusCode::non_finite, st.clipped_values};
  out = w;
  return st;
}

Status Inference::evaluate(const model::FeatureSignals& s, Wrench& out) noexcept {
  return evaluate(Path::quantised, s, imu_signals(s), out);
}
Status Inference::evaluate_reference(const model::FeatureSignals& s, Wrench& out) noexcept {
  return evaluate(Path::float_reference, s, imu_signals(s), out);
}
Status Inference::evaluate_physics(const model::FeatureSignals& s, Wrench& out) noexcept {
  return evaluate(Path::physics_only, s, imu_signals(s), out);
}

Status Inference::residual_quantised(const model::FeatureSignals& s, Wrench& out) noexcept {
  return residual(Path::quantised, s, out);
}

Status Inference::residual_reference(const model::FeatureSignals& s, Wrench& out) noexcept {
  return residual(Path::float_reference, s, out);
}

Status Inference::residual(Path path, const model::FeatureSignals& s, Wrench& out) noexcept {
  if (!configured_) return {StatusCode::not_configured, 0};
  out.setZero();
  if (!model_.network || path == Path::physics_only) return {};
  const DeployedNetwork& net = *model_.network;
  model::compute_features(s, net.features, features_.data());
  for (std::size_t k = 0; k < net.features.size(); ++k)
    if (!std::isfinite(features_[k])) return {StatusCode::non_finite, 0};
  Status st{};
  if (path == Path::quantised) {
    st = network_quantised(features_.data(), y_.data());
  } else {
    model::network_forward<double>(net.shape, net.normalisation, net.params.data(),
                                   features_.data(), y_.data(), ref_a_.data(), ref_b_.data());
  }
  for (std::size_t k = 0; k < net.output_axes.size(); ++k) out[net.output_axes[k]] = y_[k];
  if (!finite(out)) return {StatusCode::non_finite, st.clipped_values};
  return st;
}

std::size_t evaluate_sequence(Inference& inference, Path path,
                              std::span<const model::FeatureSignals> samples,
                              std::span<Wrench> out) {
  const std::size_t n = std::min(samples.size(), out.size());
  const double tau = inference.imu_time_offset_s();
  const double dt =
      n > 1 ? (samples[n - 1].t_s - samples[0].t_s) / static_cast<double>(n - 1) : 0.0;
  std::size_t not_ok = 0;
  for (std::size_t i = 0; i < n; ++i) {
    model::ImuSignals<double> imu = imu_signals(samples[i]);
    if (tau != 0.0 && dt > 0.0) {
      // The interpolation of ident::Dataset::imu_at (model::interpolate_uniform: index i + tau/dt,
      // clamped to the ends), written out because the rows are not one contiguous array.
      const double index = static_cast<double>(i) + tau / dt;
      const double clamped = std::clamp(index, 0.0, static_cast<double>(n - 1));
      std::size_t k = static_cast<std::size_t>(std::floor(clamped));
      if (k >= n - 1) k = n - 2;
      const double frac = clamped - static_cast<double>(k);
      for (int d = 0; d < 3; ++d) {
        const auto at = [&](std::size_t row, int c) { return samples[row].imu[c]; };
        imu.specific_force_imu[d] = at(k, d) + frac * (at(k + 1, d) - at(k, d));
        imu.angular_rate_imu[d] = at(k, 3 + d) + frac * (at(k + 1, 3 + d) - at(k, 3 + d));
        imu.angular_accel_imu[d] = at(k, 6 + d) + frac * (at(k + 1, 6 + d) - at(k, 6 + d));
      }
    }
    const Status st = inference.evaluate(path, samples[i], imu, out[i]);
    if (!st.written()) out[i].setConstant(std::numeric_limits<double>::quiet_NaN());
    if (st.code != StatusCode::ok) ++not_ok;
  }
  return not_ok;
}

}  // namespace zerog::infer
