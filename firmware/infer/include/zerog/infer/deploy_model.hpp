#pragma once
// The deployed model (proto/deploy_format.md): what `zerog export` writes and the cabinet PC
// loads — physics effects and parameters, the rig it was fitted for, and optionally the learned
// residual network (float reference and its quantised form). Plain data; start-up only (it owns
// vectors and strings: never copy it inside the cycle).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "zerog/model/effects.hpp"
#include "zerog/model/features.hpp"
#include "zerog/model/network.hpp"
#include "zerog/model/predict.hpp"

namespace zerog::infer {

/// Version of the deployed-model file this code writes and the only one it loads.
inline constexpr int kDeployFormatVersion = 1;

/// The rig a model was fitted for, or the rig the firmware runs on (the loader compares them).
/// Same content as the `.rig.toml` (proto/log_format.md) minus the design-only keys.
struct RigDescription {
  std::string name;                                                     ///< e.g. "kr210-omega191"
  std::string robot;                                                    ///< e.g. "KR 210 R2700"
  Eigen::Vector3d p_flange_sensor_m = Eigen::Vector3d::Zero();          ///< S origin in F, m
  Eigen::Quaterniond q_flange_sensor = Eigen::Quaterniond::Identity();  ///< S axes in F
  Eigen::Vector3d p_sensor_imu_m = Eigen::Vector3d::Zero();             ///< I origin in S, m
  Eigen::Quaterniond q_sensor_imu = Eigen::Quaterniond::Identity();     ///< I axes in S
  double sample_period_s = 0.012;                                       ///< nominal row period

  /// What the force model takes from the rig (IMU pose in the sensor frame).
  model::RigGeometry geometry() const;
};

/// Tolerances of the rig check: positions (m), rotation angle (rad), sample period (s).
inline constexpr double kRigPositionTolerance_m = 1e-6;
inline constexpr double kRigAngleTolerance_rad = 1e-6;
inline constexpr double kRigPeriodTolerance_s = 1e-9;

/// Empty if `fitted` and `running` are the same rig; otherwise a sentence naming the first
/// difference (name, robot, or which pose/period and by how much).
std::string rig_mismatch(const RigDescription& fitted, const RigDescription& running);

/// One dense layer in integers (proto/deploy_format.md "Quantisation"). Input activations are
/// int16 with one scale per layer (`input_scale`, the value of one LSB); weights are integers of
/// `weight_bits` bits with one scale per output channel; the bias is in accumulator units
/// (weight_scale[r] × input_scale).
struct QuantisedLayer {
  std::vector<std::int16_t> weights;  ///< outputs × inputs, row-major, |w| ≤ 2^(bits−1) − 1
  std::vector<double> weight_scale;   ///< per output channel: real weight = w × weight_scale[r]
  std::vector<std::int64_t> bias;     ///< per output channel, accumulator units
  double input_scale = 1.0;           ///< value of one LSB of this layer's int16 input
  /// Value of one LSB of this layer's int16 output (the next layer's input_scale). Unused for
  /// the last layer, whose accumulator is dequantised directly.
  double output_scale = 1.0;
};

/// Settings shared by all layers of a quantised network.
struct QuantisedNetwork {
  int weight_bits = 16;     ///< 8 or 16
  double input_clip = 8.0;  ///< normalised inputs are clipped to ±input_clip (= 32767 LSB)
  std::vector<QuantisedLayer> layers;
};

/// Names of the wrench axes (sensor frame): Fx Fy Fz (N), Mx My Mz (N·m), index 0..5.
inline constexpr const char* kAxisNames[6] = {"Fx", "Fy", "Fz", "Mx", "My", "Mz"};

/// The learned residual: network output k (N or N·m) is added to wrench axis output_axes[k] of
/// the physics prediction.
struct DeployedNetwork {
  std::vector<model::Feature> features;  ///< one per network input, in input order
  std::vector<int> output_axes;          ///< one per output: 0..5 = Fx..Mz, each at most once
  model::NetworkShape
      shape;  ///< width.front() = features.size(), width.back() = output_axes.size()
  model::NetworkNormalisation normalisation;
  std::vector<double> params;  ///< float weights, layout of model::network_forward (reference)
  QuantisedNetwork quantised;
};

/// Everything the firmware needs to predict the payload wrench.
struct DeployedModel {
  RigDescription rig;                      ///< the rig the model was fitted for
  model::ModelParams physics;              ///< effects and parameter values
  std::optional<DeployedNetwork> network;  ///< absent for a physics-only model
  std::string provenance_json = "{}";      ///< free-form JSON object (source files, fit stats)
};

}  // namespace zerog::infer
