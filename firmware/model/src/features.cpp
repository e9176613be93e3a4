#include "zerog/model/features.hpp"

#include <cmath>

namespace zerog::model {

namespace {

constexpr std::array<const char*, kFeatureCount> kNames = {
    "sin_q1",      "sin_q2", "sin_q3",   "sin_q4",   "sin_q5",   "sin_q6",   "cos_q1",   "cos_q2",
    "cos_q3",      "cos_q4", "cos_q5",   "cos_q6",   "qd1",      "qd2",      "qd3",      "qd4",
    "qd5",         "qd6",    "sign_qd1", "sign_qd2", "sign_qd3", "sign_qd4", "sign_qd5", "sign_qd6",
    "px",          "py",     "pz",       "gx",       "gy",       "gz",       "r11",      "r12",
    "r13",         "r21",    "r22",      "r23",      "r31",      "r32",      "r33",      "fx",
    "fy",          "fz",     "wx",       "wy",       "wz",       "wdx",      "wdy",      "wdz",
    "temperature", "time"};

}  // namespace

const char* feature_name(Feature f) {
  const int i = static_cast<int>(f);
  return (i >= 0 && i < kFeatureCount) ? kNames[static_cast<std::size_t>(i)] : "unknown";
}

bool feature_from_name(std::string_view name, Feature& out) {
  for (int i = 0; i < kFeatureCount; ++i) {
    if (name == kNames[static_cast<std::size_t>(i)]) {
      out = static_cast<Feature>(i);
      return true;
    }
  }
  return false;
}

double feature_value(const FeatureSignals& s, Feature f) {
  const int i = static_cast<int>(f);
  const auto at = [](int k) { return static_cast<std::size_t>(k); };
  if (f <= Feature::sin_q6)
    return std::sin(s.joints_rad[at(i - static_cast<int>(Feature::sin_q1))]);
  if (f <= Feature::cos_q6)
    return std::cos(s.joints_rad[at(i - static_cast<int>(Feature::cos_q1))]);
  if (f <= Feature::qd6) return s.joint_vel_radps[at(i - static_cast<int>(Feature::qd1))];
  if (f <= Feature::sign_qd6)
    return std::tanh(s.joint_vel_radps[at(i - static_cast<int>(Feature::sign_qd1))] /
                     kSignVelocityScale_radps);
  if (f <= Feature::pz) return s.p_base_sensor_m[at(i - static_cast<int>(Feature::px))];
  if (f <= Feature::gz) {
    // g_S = R_base_sensorᵀ (0, 0, −1): minus the third row of R_base_sensor.
    return -s.R_base_sensor[at(6 + i - static_cast<int>(Feature::gx))];
  }
  if (f <= Feature::r33) return s.R_base_sensor[at(i - static_cast<int>(Feature::r11))];
  if (f <= Feature::wdz) return s.imu[at(i - static_cast<int>(Feature::fx))];
  if (f == Feature::temperature) return s.temperature_C;
  return s.t_s;
}

void compute_features(const FeatureSignals& s, std::span<const Feature> features, double* out) {
  for (std::size_t k = 0; k < features.size(); ++k) out[k] = feature_value(s, features[k]);
}

}  // namespace zerog::model
