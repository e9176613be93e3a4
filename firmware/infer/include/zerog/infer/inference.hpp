#pragma once
// Real-time evaluation of a deployed model: physics (model::predict_wrench<double>) plus the
// learned residual network in integer arithmetic (int16 activations, 8/16-bit weights with
// per-output-channel scales, int32/int64 accumulators, saturating narrowing, activation lookup
// tables with linear interpolation). The float reference (model::network_forward<double>) runs
// on the same object for comparison. Format and arithmetic: proto/deploy_format.md.
//
// Life cycle (docs/STYLE.md habit 3): configure() at start-up (allocates, may fail with a message);
// evaluate() every cycle (real-time safe: no allocation, no exceptions, no locks, bounded time —
// at most kMaxNetworkLayers × kMaxNetworkWidth² multiply-adds).
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "zerog/infer/deploy_model.hpp"
#include "zerog/model/dictionary.hpp"
#include "zerog/model/features.hpp"
#include "zerog/model/network.hpp"
#include "zerog/model/predict.hpp"
#include "zerog/status.hpp"

namespace zerog::infer {

using Wrench = Eigen::Matrix<double, 6, 1>;  ///< sensor frame: Fx Fy Fz (N), Mx My Mz (N·m)

enum class StatusCode : std::uint8_t {
  ok,              ///< output written, nothing clipped
  saturated,       ///< output written, but inputs or activations were clipped to their range
  non_finite,      ///< a signal or the result was NaN/inf: output not written
  not_configured,  ///< configure() has not succeeded: output not written
};
const char* status_name(StatusCode c);

/// Result of one evaluation (docs/STYLE.md habit 5: the cycle returns status, recovers outside).
struct Status {
  StatusCode code = StatusCode::ok;
  std::uint16_t clipped_values = 0;  ///< network inputs and activations that saturated
  /// True if the output was written (ok or saturated).
  bool written() const { return code == StatusCode::ok || code == StatusCode::saturated; }
};

/// The IMU signals a sample carries (s.imu: specific force, rate, angular acceleration), as the
/// physics reads them when they need no interpolation. Real-time safe.
model::ImuSignals<double> imu_signals(const model::FeatureSignals& s);

/// Which computation evaluate_sequence runs.
enum class Path : std::uint8_t { quantised, float_reference, physics_only };

class Inference {
 public:
  /// Start-up: validates `model` (same checks as the loader), sizes every buffer and builds the
  /// lookup tables and requantisation multipliers. Returns ok(), or invalid_setting with the
  /// loader's reason (about the model as a whole: no setting named); on failure the previous
  /// configuration is kept (never half-configured). Not real-time safe.
  zerog::Status configure(DeployedModel model);
  bool configured() const { return configured_; }
  const DeployedModel& model() const { return model_; }

  /// Physics + quantised residual for one sample. The IMU signals (s.imu) must already be aligned
  /// to the F/T sample (imu_time_offset: read at t + tau, see imu_time_offset_s()).
  /// Real-time safe.
  Status evaluate(const model::FeatureSignals& s, Wrench& out) noexcept;
  /// Same with the float network (model::network_forward<double>). Real-time safe.
  Status evaluate_reference(const model::FeatureSignals& s, Wrench& out) noexcept;
  /// Physics alone. Real-time safe.
  Status evaluate_physics(const model::FeatureSignals& s, Wrench& out) noexcept;
  /// The residual network alone (normalised → raw outputs, N and N·m). Real-time safe.
  Status residual_quantised(const model::FeatureSignals& s, Wrench& out) noexcept;
  Status residual_reference(const model::FeatureSignals& s, Wrench& out) noexcept;

  /// Physics with separately supplied IMU signals (e.g. interpolated at t + tau); the network
  /// still reads s.imu. User-defined terms (proto/user_effects.md) read `kinematics` (central
  /// differences at this row); without it they see s's joint velocities and no joint
  /// acceleration or sensor velocity. Real-time safe.
  Status evaluate(Path path, const model::FeatureSignals& s,
                  const model::ImuSignals<double>& physics_imu, Wrench& out,
                  const model::KinematicInputs* kinematics = nullptr) noexcept;

  /// The fitted IMU time offset tau (s), 0 without the imu_time_offset effect.
  double imu_time_offset_s() const;

 private:
  /// The network's part of the wrench along `path` (zero for physics_only or no network).
  Status residual(Path path, const model::FeatureSignals& s, Wrench& out) noexcept;
  struct Layer {
    int inputs = 0, outputs = 0;
    model::Activation activation = model::Activation::identity;
    bool last = false;
    std::vector<std::int16_t> weights;
    std::vector<std::int64_t> bias;
    std::vector<std::int32_t> bias32;
    std::vector<std::int64_t> m0, m0_neg;  ///< requantisation to the output (or to Q16 z)
    std::vector<std::int8_t> shift, shift_neg;
    std::vector<double> dequant;  ///< last layer: value of one accumulator unit
  };
  Status network_quantised(const double* features, double* y) noexcept;

  DeployedModel model_;
  model::RigGeometry geometry_;
  bool configured_ = false;
  bool wide_acc_ = true;  ///< int64 accumulators (16-bit weights), else int32
  std::vector<Layer> layers_;
  std::vector<std::int32_t> lut_sigmoid_, lut_tanh_;
  std::vector<double> input_inv_step_;  ///< per input: 1 / (input_scale_k · LSB)
  std::array<double, model::kMaxNetworkWidth> features_{}, y_{}, ref_a_{}, ref_b_{};
  std::array<std::int16_t, model::kMaxNetworkWidth> act_a_{}, act_b_{};
};

/// Host helper for results tables: evaluates `path` on every sample (out.size() == samples.size()).
/// With imu_time_offset the physics reads the IMU linearly interpolated at t_i + tau on the
/// samples' mean grid, clamped at the ends (as ident::predict does); the network reads s.imu.
/// Returns the number of samples whose status was not ok (saturated or not written; a sample
/// not written gets NaN). Allocation-free itself, but meant for host use.
std::size_t evaluate_sequence(Inference& inference, Path path,
                              std::span<const model::FeatureSignals> samples,
                              std::span<Wrench> out);

}  // namespace zerog::infer
