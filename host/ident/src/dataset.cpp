#include "zerog/ident/dataset.hpp"

#include "zerog/io/effect_file.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace zerog::ident {

using model::Effect;

Dataset make_dataset(const io::Log& log) {
  Dataset d;
  const std::size_t n = log.samples.size();
  if (n < 3) throw std::runtime_error("log has " + std::to_string(n) + " samples; need at least 3");
  d.columns = log.columns;
  d.rig.R_sensor_imu = log.rig.sensor_imu.q.normalized().toRotationMatrix();
  d.rig.p_sensor_imu_m = log.rig.sensor_imu.p_m;
  d.kinematics = log.rig.kinematics;
  d.dt_s = (log.samples.back().t_s - log.samples.front().t_s) / static_cast<double>(n - 1);
  d.t_s.resize(n);
  d.pose.resize(n);
  d.measured.resize(n);
  d.imu.assign(n * 9, 0.0);
  d.moving.assign(n, 0);
  d.joint_vel_radps.assign(n, {});
  const double t0 = log.samples.front().t_s;
  for (std::size_t i = 0; i < n; ++i) {
    const io::Sample& s = log.samples[i];
    d.t_s[i] = s.t_s;
    model::PoseSignals& p = d.pose[i];
    p.R_base_sensor = s.q_base_sensor.normalized().toRotationMatrix();
    p.t_rel_s = log.columns.static_rows ? 0.0 : s.t_s - t0;
    p.temperature_C = log.columns.temperature ? s.temperature_C : model::kTemperatureReferenceC;
    p.joints_rad = s.joints_rad;
    d.measured[i] << s.force_sensor_N, s.torque_sensor_Nm;
    double* row = &d.imu[i * 9];
    for (int k = 0; k < 3; ++k) {
      row[k] = s.specific_force_imu_mps2[k];
      row[3 + k] = s.angular_rate_imu_radps[k];
      // ω̇ formed at import (the gyro by Savitzky–Golay, or the robot's): used as logged.
      if (log.columns.angular_accel) row[6 + k] = s.angular_accel_imu_radps2[k];
    }
  }
  // Rows without time are independent held poses: nothing is differenced across them, rates and
  // accelerations not measured stay zero, and no row moves.
  if (log.columns.static_rows) {
    d.p_base_sensor_m.resize(n);
    for (std::size_t i = 0; i < n; ++i) d.p_base_sensor_m[i] = log.samples[i].p_base_sensor_m;
    d.v_base_sensor_mps.assign(n, Eigen::Vector3d::Zero());
    d.joint_vel_central_radps.assign(n, {});
    d.joint_acc_radps2.assign(n, {});
    return d;
  }
  // Angular acceleration, unless the log has it (imu_dw*_radps2): 5-point central differences
  // (4th order) of the angular rate, 3-point one row from the ends, zero on the first and last
  // row.
  const bool difference_rate = log.columns.angular_rate && !log.columns.angular_accel;
  for (std::size_t i = 1; i + 1 < n && difference_rate; ++i) {
    const int order = (i >= 2 && i + 2 < n) ? 4 : 2;
    Eigen::Map<Eigen::Vector3d>(&d.imu[i * 9 + 6]) =
        model::angular_accel_central(&d.imu[i * 9 + 3], 9, order, d.dt_s);
  }
  // Motion: from the logged pose (the orientation always, the position if logged). Speeds by
  // differencing, dilated by 3 rows.
  std::vector<std::uint8_t> raw(n, 0);
  for (std::size_t i = 1; i < n; ++i) {
    const io::Sample& s0 = log.samples[i - 1];
    const io::Sample& s1 = log.samples[i];
    const double dt = s1.t_s - s0.t_s;
    const double v = (s1.p_base_sensor_m - s0.p_base_sensor_m).norm() / dt;
    const double w = s0.q_base_sensor.angularDistance(s1.q_base_sensor) / dt;
    raw[i] = (v > 1e-3 || w > 2e-3) ? 1 : 0;
    if (log.columns.joints) {
      for (int j = 0; j < 6; ++j)
        d.joint_vel_radps[i][j] = (s1.joints_rad[j] - s0.joints_rad[j]) / dt;
    }
  }
  if (n > 1) d.joint_vel_radps[0] = d.joint_vel_radps[1];
  // Dictionary signals: 3-point central differences (model::central_differences; at the first
  // and last row those of their neighbour), on the rows' own time stamps.
  d.p_base_sensor_m.resize(n);
  d.v_base_sensor_mps.assign(n, Eigen::Vector3d::Zero());
  d.joint_vel_central_radps.assign(n, {});
  d.joint_acc_radps2.assign(n, {});
  for (std::size_t i = 0; i < n; ++i) d.p_base_sensor_m[i] = log.samples[i].p_base_sensor_m;
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t c = std::clamp<std::size_t>(i, 1, n - 2);
    const io::Sample &s0 = log.samples[c - 1], &s1 = log.samples[c], &s2 = log.samples[c + 1];
    model::central_differences(s0.p_base_sensor_m.data(), s1.p_base_sensor_m.data(),
                               s2.p_base_sensor_m.data(), 3, s0.t_s, s1.t_s, s2.t_s,
                               d.v_base_sensor_mps[i].data(), nullptr);
    if (log.columns.joints)
      model::central_differences(s0.joints_rad.data(), s1.joints_rad.data(), s2.joints_rad.data(),
                                 6, s0.t_s, s1.t_s, s2.t_s, d.joint_vel_central_radps[i].data(),
                                 d.joint_acc_radps2[i].data());
  }
  const std::size_t dilate = 3;
  for (std::size_t i = 0; i < n; ++i) {
    if (!raw[i]) continue;
    const std::size_t lo = i >= dilate ? i - dilate : 0;
    const std::size_t hi = std::min(n - 1, i + dilate);
    for (std::size_t k = lo; k <= hi; ++k) d.moving[k] = 1;
  }
  return d;
}

model::DictionarySignals Dataset::dictionary(std::size_t i) const {
  model::KinematicInputs in;
  model::FeatureSignals& f = in.features;
  const model::PoseSignals& p = pose[i];
  f.joints_rad = p.joints_rad;
  f.joint_vel_radps = joint_vel_central_radps[i];
  in.joint_acc_radps2 = joint_acc_radps2[i];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      f.R_base_sensor[static_cast<std::size_t>(3 * r + c)] = p.R_base_sensor(r, c);
  for (int k = 0; k < 3; ++k) {
    f.p_base_sensor_m[static_cast<std::size_t>(k)] = p_base_sensor_m[i][k];
    in.v_base_sensor_mps[static_cast<std::size_t>(k)] = v_base_sensor_mps[i][k];
  }
  for (std::size_t k = 0; k < 9; ++k) f.imu[k] = imu[i * 9 + k];
  f.temperature_C = p.temperature_C;
  f.t_s = p.t_rel_s;
  return model::dictionary_signals(in, rig);
}

Wrench predict(const model::ModelParams& params, const Dataset& data, std::size_t i) {
  const auto p = model::pointers(params);
  const double* tau =
      params.effects.has(Effect::imu_time_offset) ? params.block(Effect::imu_time_offset) : nullptr;
  Wrench w = model::predict_wrench<double>(params.effects, p, data.pose[i],
                                           data.imu_at<double>(i, tau), data.rig);
  if (!params.user.empty())
    w += model::user_wrench(params.user, data.dictionary(i), data.pose[i].R_base_sensor);
  return w;
}

std::vector<std::uint8_t> heldout_mask(const Dataset& data, double block_s, int every, int offset) {
  if (offset < 0) offset = every - 1;
  std::vector<std::uint8_t> mask(data.size(), 0);
  const double t0 = data.t_s.front();
  for (std::size_t i = 0; i < data.size(); ++i) {
    const long block = data.columns.static_rows
                           ? static_cast<long>(i)
                           : static_cast<long>(std::floor((data.t_s[i] - t0) / block_s));
    mask[i] = (block % every) == offset ? 1 : 0;
  }
  return mask;
}

unsigned available_sources(const Dataset& data) {
  using model::SignalSource;
  auto bit = [](SignalSource s) { return 1u << static_cast<unsigned>(s); };
  unsigned m = bit(SignalSource::pose);
  if (data.columns.position) m |= bit(SignalSource::position);
  if (!data.columns.static_rows) m |= bit(SignalSource::time);
  if (data.columns.joints) m |= bit(SignalSource::joints);
  // The dictionary's IMU signals combine specific force, rate and its derivative.
  if (data.columns.full_imu() && !data.columns.static_rows) m |= bit(SignalSource::imu);
  if (data.columns.temperature) m |= bit(SignalSource::temperature);
  return m;
}

void check_signals(const model::UserEffects& user, const Dataset& data) {
  const unsigned have = available_sources(data);
  static constexpr const char* kColumns[] = {
      "joint angles (q1_rad..q6_rad)",
      "sensor position (px_m..pz_m; 'position' in the import mapping)",
      "IMU columns (imu_f*_mps2, imu_w*_radps, with t_s; 'specific_force' and 'angular_rate' "
      "in the import mapping)",
      "sensor attitude",
      "temperature (temp_C)",
      "time (t_s; 'time' in the import mapping)"};
  for (int j = 0; j < user.num_terms; ++j) {
    const unsigned need = model::basis_sources(user.terms[static_cast<std::size_t>(j)].basis);
    for (unsigned s = 0; s < 6; ++s) {
      if ((need >> s & 1u) && !(have >> s & 1u))
        throw std::runtime_error("user term " + io::term_label(user, j) + " needs " + kColumns[s] +
                                 ", which the log lacks");
    }
  }
}

void check_signals(const model::EffectSet& effects, const Dataset& data) {
  for (Effect e : model::kAllEffects) {
    if (!effects.has(e)) continue;
    const auto& ei = model::info(e);
    const std::string effect = std::string("effect '") + ei.name + "' ";
    const io::Columns& c = data.columns;
    // linear_inertia: the accelerometer (a rate, if logged, adds the lever-arm terms).
    if (e == Effect::linear_inertia && !c.specific_force)
      throw std::runtime_error(
          effect +
          "needs the accelerometer columns imu_fx_mps2..imu_fz_mps2 that the log lacks (map "
          "'specific_force' in the import, or derive it there with kinematics = \"auto\" from "
          "the joints and the rig's robot, or from the pose with position)");
    // rotational_inertia: the gyroscope and time, to differentiate it into ω̇.
    if (e == Effect::rotational_inertia && !c.angular_rate)
      throw std::runtime_error(
          effect +
          "needs the gyroscope columns imu_wx_radps..imu_wz_radps that the log lacks (map "
          "'angular_rate' in the import, or derive it there with kinematics = \"auto\" from "
          "the joints and the rig's robot, or from the orientation)");
    if (e == Effect::rotational_inertia && c.static_rows)
      throw std::runtime_error(effect +
                               "needs angular acceleration, which rows without time (static "
                               "samples) do not give: log time (t_s) while the payload moves");
    if (e == Effect::imu_time_offset && !c.any_imu())
      throw std::runtime_error(effect +
                               "needs IMU columns (imu_f*_mps2 or imu_w*_radps) that the log "
                               "lacks (map 'specific_force' or 'angular_rate' in the import)");
    if ((e == Effect::imu_time_offset || e == Effect::bias_drift) && c.static_rows)
      throw std::runtime_error(effect +
                               "needs time (t_s), which this log of static rows lacks (map "
                               "'time' in the import)");
    if (e == Effect::temperature_bias && !data.columns.temperature)
      throw std::runtime_error(
          "effect 'temperature_bias' needs the temp_C column that the log lacks");
    if (e == Effect::cable && !data.columns.joints)
      throw std::runtime_error(
          "effect 'cable' needs joint angles (q1_rad..q6_rad) that the log lacks");
    for (const auto& req : ei.requires_effects) {
      if (req && !effects.has(*req))
        throw std::runtime_error(std::string("effect '") + ei.name + "' builds on '" +
                                 model::info(*req).name + "': add it to the model too");
    }
  }
}

}  // namespace zerog::ident
