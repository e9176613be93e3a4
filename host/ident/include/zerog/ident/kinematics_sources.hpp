#pragma once
// Which source fed which effect: the log's IMU columns may be logged by an IMU or derived by
// `zerog import` from the robot's joints or pose (the rig's [kinematics], proto/log_format.md).
// Every fit and diagnosis names, per effect, where its ω, ω̇ and specific force came from
// (issue 13 item 2; proto/json_output.md).
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "zerog/ident/dataset.hpp"
#include "zerog/model/effects.hpp"

namespace zerog::ident {

/// One inertial signal of an effect and its source.
struct SignalFeed {
  std::string signal;  ///< "omega", "omega_dot" or "specific_force"
  /// "imu" (logged), "joints" or "pose" (derived at import), or "none" (the log lacks it: taken
  /// as zero, e.g. linear_inertia's lever-arm terms without a rate).
  std::string source;
};

/// The signals one effect reads.
struct EffectFeeds {
  std::string effect;
  std::vector<SignalFeed> signals;
};

/// What zerog-rt's cycle computes ω̇ from: the 5-point central difference of the gyro
/// (model::angular_accel_central, firmware/loop), as host/ident does for a log without
/// imu_dw*_radps2 columns.
inline constexpr std::string_view kCycleOmegaDotSource = "gyro_5point";

/// Which ω̇ the dataset holds, as a key (JSON "omega_dot_source"): "gyro_5point" (host/ident's
/// difference of imu_w*_radps: what the cycle runs on), "gyro_savitzky_golay" (the gyro
/// differenced at import), "joints" or "pose" (the robot's second derivative at import),
/// "logged" (the recording's own ω̇), or "none" (no rate with time: taken as zero).
std::string omega_dot_source(const Dataset& data);

/// The inertial signals of `effects` that read the IMU columns (linear_inertia: specific force,
/// and ω, ω̇ for its lever-arm terms; rotational_inertia: ω, ω̇; imu_time_offset: the IMU groups
/// present), with their sources. ω̇ is the log's imu_dw*_radps2 columns when present (the
/// rig's [kinematics] angular_accel says from where), else host/ident's 5-point central
/// difference of the angular-rate column (dataset.cpp), which has the angular rate's source.
/// Effects that read none are left out.
std::vector<EffectFeeds> kinematics_feeds(const model::EffectSet& effects, const Dataset& data);

/// {"mode", "omega_dot": how it is formed, "differentiator": {…} when a column was derived
///  from the robot, "gyro_differentiator": {…} when ω̇ is the gyro differenced at import,
///  "effects": {effect: {signal: source}}}.
nlohmann::json kinematics_json(const std::vector<EffectFeeds>& feeds, const Dataset& data);

/// Plain text, one line an effect, e.g. "kinematics: rotational_inertia ω joints, ω̇ joints
/// (differenced)"; a line about the differentiator when a column was derived, and one on how
/// ω̇ was formed when an effect reads it. Empty when no effect reads the IMU columns.
std::string format_kinematics(const std::vector<EffectFeeds>& feeds, const Dataset& data);

}  // namespace zerog::ident
