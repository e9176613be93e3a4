#include "zerog/ident/kinematics_sources.hpp"

#include <cstdio>

namespace zerog::ident {

namespace {

std::string source_of(bool present, formats::KinematicsOrigin origin) {
  return present ? formats::to_string(origin) : "none";
}

// How the dataset's ω̇ was formed (make_dataset): the log's imu_dw* columns, or host/ident's
// difference of the angular-rate column.
std::string omega_dot_method(const Dataset& data) {
  const formats::Columns& c = data.columns;
  const formats::KinematicsRecord& k = data.kinematics;
  if (c.angular_accel && k.angular_accel == formats::KinematicsOrigin::logged)
    return "the recording's own, logged (imu_dw*_radps2 columns)";
  if (!c.angular_rate || c.static_rows) return "none (no angular rate with time: taken as zero)";
  if (!c.angular_accel)
    return std::string(
               "5-point central difference of the angular-rate column (host/ident), "
               "whose source is ") +
           formats::to_string(k.angular_rate);
  if (k.angular_accel == formats::KinematicsOrigin::imu)
    return "the gyro differenced at import by Savitzky-Golay (imu_dw*_radps2 columns)";
  if (k.angular_accel == formats::KinematicsOrigin::fused)
    return "fused at import: the joints' Savitzky-Golay second derivative, the gyro below the "
           "crossover (imu_dw*_radps2 columns)";
  return std::string("the robot's Savitzky-Golay second derivative from the ") +
         formats::to_string(k.angular_accel) + " at import (imu_dw*_radps2 columns)";
}

}  // namespace

std::string omega_dot_source(const Dataset& data) {
  const formats::Columns& c = data.columns;
  if (c.angular_accel && data.kinematics.angular_accel == formats::KinematicsOrigin::logged)
    return "logged";
  if (!c.angular_rate || c.static_rows) return "none";
  if (!c.angular_accel) return std::string(kCycleOmegaDotSource);
  switch (data.kinematics.angular_accel) {
    case formats::KinematicsOrigin::imu:
      return "gyro_savitzky_golay";
    case formats::KinematicsOrigin::joints:
      return "joints";
    case formats::KinematicsOrigin::pose:
      return "pose";
    case formats::KinematicsOrigin::fused:
      return "fused";
    case formats::KinematicsOrigin::logged:
      break;
  }
  return "logged";
}

std::vector<EffectFeeds> kinematics_feeds(const model::EffectSet& effects, const Dataset& data) {
  using model::Effect;
  const formats::Columns& c = data.columns;
  const formats::KinematicsRecord& k = data.kinematics;
  const SignalFeed omega{"omega", source_of(c.angular_rate, k.angular_rate)};
  // No rate or no time: no ω̇ (taken as zero).
  const SignalFeed omega_dot{"omega_dot",
                             source_of((c.angular_rate && !c.static_rows) || c.angular_accel,
                                       c.angular_accel ? k.angular_accel : k.angular_rate)};
  const SignalFeed force{"specific_force", source_of(c.specific_force, k.specific_force)};
  std::vector<EffectFeeds> out;
  for (Effect e : model::kAllEffects) {
    if (!effects.has(e)) continue;
    EffectFeeds f{model::info(e).name, {}};
    if (e == Effect::linear_inertia) f.signals = {force, omega, omega_dot};
    if (e == Effect::rotational_inertia) f.signals = {omega, omega_dot};
    if (e == Effect::imu_time_offset) {
      if (c.specific_force) f.signals.push_back(force);
      if (c.angular_rate) f.signals.push_back(omega);
    }
    if (!f.signals.empty()) out.push_back(std::move(f));
  }
  return out;
}

nlohmann::json kinematics_json(const std::vector<EffectFeeds>& feeds, const Dataset& data) {
  const formats::KinematicsRecord& k = data.kinematics;
  nlohmann::json j;
  j["mode"] = k.mode;
  j["omega_dot"] = omega_dot_method(data);
  j["omega_dot_source"] = omega_dot_source(data);
  if (k.derived()) {
    j["differentiator"] = {{"method", "savitzky_golay"},
                           {"half_width", k.sg_half_width},
                           {"order", k.sg_order},
                           {"period_s", k.period_s},
                           {"bandwidth_hz", k.bandwidth_hz},
                           {"lag_s", k.lag_s},
                           {"noise_gain_rate_per_s", k.noise_gain_rate_per_s},
                           {"noise_gain_accel_per_s2", k.noise_gain_accel_per_s2},
                           {"cutoff_rate_hz", k.cutoff_rate_hz},
                           {"cutoff_accel_hz", k.cutoff_accel_hz}};
  } else {
    j["differentiator"] = nullptr;
  }
  if (data.columns.angular_accel && k.accel_sg_half_width > 0) {
    const bool gyro = k.angular_accel == formats::KinematicsOrigin::imu;
    j["omega_dot_differentiator"] = {
        {"method", "savitzky_golay"},
        {"derivative", gyro ? 1 : 2},
        {"half_width", k.accel_sg_half_width},
        {"order", k.accel_sg_order},
        {"period_s", k.accel_period_s},
        {"bandwidth_hz", k.accel_bandwidth_hz},
        {"lag_s", 0.0},
        {gyro ? "noise_gain_per_s" : "noise_gain_per_s2", k.accel_noise_gain},
        {"cutoff_hz", k.accel_cutoff_hz}};
  } else {
    j["omega_dot_differentiator"] = nullptr;
  }
  j["effects"] = nlohmann::json::object();
  for (const EffectFeeds& f : feeds) {
    nlohmann::json e = nlohmann::json::object();
    for (const SignalFeed& s : f.signals) e[s.signal] = s.source;
    j["effects"][f.effect] = std::move(e);
  }
  return j;
}

std::string format_kinematics(const std::vector<EffectFeeds>& feeds, const Dataset& data) {
  if (feeds.empty()) return {};
  std::string out;
  for (const EffectFeeds& f : feeds) {
    out += "kinematics: " + f.effect + " <-";
    for (std::size_t i = 0; i < f.signals.size(); ++i)
      out += std::string(i == 0 ? " " : ", ") + f.signals[i].signal + " " + f.signals[i].source;
    out += "\n";
  }
  const formats::KinematicsRecord& k = data.kinematics;
  if (k.derived()) {
    char line[300];
    std::snprintf(line, sizeof line,
                  "kinematics: derived at import (kinematics = \"%s\"): Savitzky-Golay M = %d, "
                  "order %d at %.4g s, lag 0, noise gain %.3g 1/s (rate), %.3g 1/s^2 "
                  "(acceleration)\n",
                  k.mode.c_str(), k.sg_half_width, k.sg_order, k.period_s, k.noise_gain_rate_per_s,
                  k.noise_gain_accel_per_s2);
    out += line;
  }
  // Said when the import chose (a simulator's log, all from the IMU, reads as before).
  bool omega_dot_fed = false;
  for (const EffectFeeds& f : feeds)
    for (const SignalFeed& s : f.signals) omega_dot_fed |= s.signal == "omega_dot";
  if (omega_dot_fed && (data.columns.angular_accel || k.mode != "imu")) {
    out += "kinematics: omega_dot is " + omega_dot_method(data);
    if (data.columns.angular_accel && k.accel_sg_half_width > 0) {
      const bool gyro = k.angular_accel == formats::KinematicsOrigin::imu;
      char line[200];
      std::snprintf(line, sizeof line,
                    " (M = %d, order %d at %.4g s, lag 0, -3 dB %.3g Hz, noise gain %.3g %s)",
                    k.accel_sg_half_width, k.accel_sg_order, k.accel_period_s, k.accel_cutoff_hz,
                    k.accel_noise_gain, gyro ? "1/s" : "1/s^2");
      out += line;
    }
    out += "\n";
  }
  return out;
}

}  // namespace zerog::ident
