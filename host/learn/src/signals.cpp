#include "zerog/learn/signals.hpp"

#include <cmath>
#include <stdexcept>

namespace zerog::learn {

using model::Feature;

model::FeatureSignals feature_signals(const ident::Dataset& data, const formats::Log& log,
                                      std::size_t i) {
  model::FeatureSignals s;
  const model::PoseSignals p = data.pose(i);
  s.joints_rad = p.joints_rad;
  s.joint_vel_radps = data.joint_vel_radps(i);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      s.R_base_sensor[static_cast<std::size_t>(3 * r + c)] = p.R_base_sensor(r, c);
  const Eigen::Vector3d& pos = log.samples[i].p_base_sensor_m;
  s.p_base_sensor_m = {pos.x(), pos.y(), pos.z()};
  for (std::size_t k = 0; k < 9; ++k) s.imu[k] = data.imu[i * 9 + k];
  s.temperature_C = p.temperature_C;
  s.t_s = p.t_rel_s;
  return s;
}

std::vector<Feature> parse_features(const std::string& list) {
  std::vector<Feature> out;
  std::size_t start = 0;
  while (start <= list.size()) {
    const std::size_t comma = std::min(list.find(',', start), list.size());
    std::string name = list.substr(start, comma - start);
    while (!name.empty() && name.front() == ' ') name.erase(name.begin());
    while (!name.empty() && name.back() == ' ') name.pop_back();
    if (!name.empty()) {
      Feature f;
      if (!model::feature_from_name(name, f)) {
        std::string valid;
        for (int k = 0; k < model::kFeatureCount; ++k)
          valid += std::string(k ? ", " : "") + model::feature_name(static_cast<Feature>(k));
        throw std::invalid_argument("unknown feature '" + name + "'; valid features: " + valid);
      }
      for (Feature g : out)
        if (g == f) throw std::invalid_argument("feature '" + name + "' is listed twice");
      out.push_back(f);
    }
    start = comma + 1;
  }
  if (out.empty()) throw std::invalid_argument("the feature list is empty");
  return out;
}

std::string feature_list_string(std::span<const Feature> features) {
  std::string s;
  for (Feature f : features) s += std::string(s.empty() ? "" : ",") + model::feature_name(f);
  return s;
}

void check_feature_signals(std::span<const Feature> features, const ident::Dataset& data) {
  for (Feature f : features) {
    const char* missing = nullptr;
    if (f <= Feature::sign_qd6 && !data.columns.joints) missing = "joint angles (q1..q6)";
    if (f >= Feature::fx && f <= Feature::fz && !data.columns.specific_force)
      missing = "accelerometer (imu_f*_mps2)";
    if (f >= Feature::wx && f <= Feature::wdz && !data.columns.angular_rate)
      missing = "gyroscope (imu_w*_radps)";
    if (f == Feature::temperature && !data.columns.temperature) missing = "temperature";
    if (missing)
      throw std::runtime_error(std::string("feature '") + model::feature_name(f) +
                               "' needs the log's " + missing + " columns, which it lacks");
  }
}

std::vector<double> feature_rows(const ident::Dataset& data, const formats::Log& log,
                                 std::span<const Feature> features,
                                 std::span<const std::size_t> samples) {
  const std::size_t d = features.size();
  std::vector<double> out(samples.size() * d);
  for (std::size_t r = 0; r < samples.size(); ++r)
    model::compute_features(feature_signals(data, log, samples[r]), features, &out[r * d]);
  return out;
}

std::vector<std::uint8_t> time_block_mask(const ident::Dataset& data, double block_s, int every,
                                          int offset) {
  if (!(block_s > 0) || every < 1 || offset < 0 || offset >= every)
    throw std::invalid_argument("time blocks: need block_s > 0 and 0 <= offset < every");
  std::vector<std::uint8_t> m(data.size(), 0);
  for (std::size_t i = 0; i < data.size(); ++i) {
    const auto b = static_cast<long long>(std::floor(data.pose(i).t_rel_s / block_s));
    m[i] = (b % every) == offset ? 1 : 0;
  }
  return m;
}

std::vector<Feature> features_for_signal(const std::string& signal) {
  auto ends_with = [&](const std::string& tail) {
    return signal.size() >= tail.size() &&
           signal.compare(signal.size() - tail.size(), tail.size(), tail) == 0;
  };
  auto axis = [&]() { return signal.empty() ? -1 : std::string("xyz").find(signal.back()); };
  auto idx = [](Feature first, std::size_t k) {
    return static_cast<Feature>(static_cast<int>(first) + static_cast<int>(k));
  };
  if (signal == "time since start") return {Feature::time};
  if (signal == "sensor temperature") return {Feature::temperature};
  if (signal.rfind("joint A", 0) == 0 && signal.size() > 8) {
    const int j = signal[7] - '1';
    if (j < 0 || j > 5) return {};
    const auto k = static_cast<std::size_t>(j);
    if (ends_with("angle (sine)")) return {idx(Feature::sin_q1, k)};
    if (ends_with("angle (cosine)")) return {idx(Feature::cos_q1, k)};
    if (ends_with("velocity direction (sign)")) return {idx(Feature::sign_qd1, k)};
    if (ends_with("velocity")) return {idx(Feature::qd1, k)};
    return {};
  }
  const std::size_t a = axis();
  if (a < 3) {
    if (signal.rfind("angular rate about IMU", 0) == 0) return {idx(Feature::wx, a)};
    if (signal.rfind("angular acceleration about IMU", 0) == 0) return {idx(Feature::wdx, a)};
    if (signal.rfind("specific force along IMU", 0) == 0) return {idx(Feature::fx, a)};
    if (signal.rfind("gravity direction along sensor", 0) == 0) return {idx(Feature::gx, a)};
  }
  if (signal == "squared angular rate") return {Feature::wx, Feature::wy, Feature::wz};
  return {};
}

std::vector<Dwell> static_dwells(const ident::Dataset& data, const std::vector<std::uint8_t>* mask,
                                 std::size_t min_samples) {
  std::vector<Dwell> out;
  const std::size_t n = data.size();
  std::size_t i = 0;
  while (i < n) {
    auto ok = [&](std::size_t k) { return !data.moving[k] && (!mask || (*mask)[k]); };
    if (!ok(i)) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j < n && ok(j)) ++j;
    if (j - i >= min_samples) out.push_back({i, j});
    i = j;
  }
  return out;
}

}  // namespace zerog::learn
