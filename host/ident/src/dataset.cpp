#include "zerog/ident/dataset.hpp"

#include "zerog/io/effect_file.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <stdexcept>
#include <string>
#include <utility>

namespace zerog::ident {

using model::Effect;

DatasetBuilder::DatasetBuilder(const formats::Columns& columns, std::size_t expected_samples) {
  d_.columns = columns;
  if (expected_samples == 0) return;
  d_.t_s.reserve(expected_samples);
  d_.q_base_sensor.reserve(expected_samples);
  if (columns.temperature) d_.temperature_C.reserve(expected_samples);
  d_.joints_rad.reserve(expected_samples);
  d_.measured.reserve(expected_samples);
  d_.imu.reserve(expected_samples * 9);
  d_.moving.reserve(expected_samples);
  d_.p_base_sensor_m.reserve(expected_samples);
  raw_moving_.reserve(expected_samples);
}

void DatasetBuilder::add(const formats::Sample& s) {
  const formats::Columns& columns = d_.columns;
  const std::size_t i = n_;
  d_.t_s.push_back(s.t_s);
  // Dataset::pose forms the matrix (toRotationMatrix) and t_rel_s from these.
  d_.q_base_sensor.push_back(s.q_base_sensor.normalized());
  if (columns.temperature) d_.temperature_C.push_back(s.temperature_C);
  d_.joints_rad.push_back(s.joints_rad);
  d_.measured.emplace_back() << s.force_sensor_N, s.torque_sensor_Nm;
  for (int k = 0; k < 3; ++k) d_.imu.push_back(s.specific_force_imu_mps2[k]);
  for (int k = 0; k < 3; ++k) d_.imu.push_back(s.angular_rate_imu_radps[k]);
  // ω̇ formed at import (the gyro by Savitzky–Golay, or the robot's): used as logged.
  for (int k = 0; k < 3; ++k)
    d_.imu.push_back(columns.angular_accel ? s.angular_accel_imu_radps2[k] : 0.0);
  d_.moving.push_back(0);
  d_.p_base_sensor_m.push_back(s.p_base_sensor_m);
  ++n_;
  // A spilled dataset keeps a window of rows behind the one added (differences read the previous
  // sample from previous_, not from the columns).
  if (const std::size_t w = spill::settings().window_rows; n_ % w == 0 && n_ >= 2 * w) {
    d_.release_rows(released_, n_ - w);
    released_ = n_ - w;
  }
  // Rows without time are independent held poses: nothing is differenced across them, rates
  // and accelerations not measured stay zero, and no row moves.
  if (columns.static_rows) return;
  const formats::Sample s0 = previous_;
  previous_ = s;
  // Motion: from the logged pose (the orientation always, the position if logged). Speeds by
  // differencing (dilated by 3 rows in finish()).
  raw_moving_.push_back(0);
  if (i >= 1) {
    const double dt = s.t_s - s0.t_s;
    const double v = (s.p_base_sensor_m - s0.p_base_sensor_m).norm() / dt;
    const double w = s0.q_base_sensor.angularDistance(s.q_base_sensor) / dt;
    raw_moving_[i] = (v > 1e-3 || w > 2e-3) ? 1 : 0;
  }
}

Dataset DatasetBuilder::finish(const formats::Rig& rig) {
  const std::size_t n = n_;
  if (n < 3) throw std::runtime_error("log has " + std::to_string(n) + " samples; need at least 3");
  Dataset& d = d_;
  d.rig.R_sensor_imu = rig.sensor_imu.q.normalized().toRotationMatrix();
  d.rig.p_sensor_imu_m = rig.sensor_imu.p_m;
  d.kinematics = rig.kinematics;
  d.imu_sampling = rig.imu_sampling;
  d.rows_in_recorded_order = rig.rows_in_recorded_order;
  d.dt_s = (d.t_s.back() - d.t_s.front()) / static_cast<double>(n - 1);
  d.release_rows(0, n);
  if (d.columns.static_rows) return std::move(d_);
  // Angular acceleration, unless the log has it (imu_dw*_radps2).
  if (differences_angular_rate(d)) angular_accel_from_rate(d);
  const std::size_t dilate = 3;
  ResidentWindow window(d);
  for (std::size_t i = 0; i < n; ++i) {
    window.advance(i + dilate);
    if (!raw_moving_[i]) continue;
    const std::size_t lo = i >= dilate ? i - dilate : 0;
    const std::size_t hi = std::min(n - 1, i + dilate);
    for (std::size_t k = lo; k <= hi; ++k) d.moving[k] = 1;
  }
  raw_moving_ = {};
  return std::move(d_);
}

Dataset make_dataset(const formats::Log& log) {
  DatasetBuilder builder(log.columns, log.samples.size());
  for (const formats::Sample& s : log.samples) builder.add(s);
  return builder.finish(log.rig);
}

namespace {

// Lines of a file (an upper bound of its rows), counted a buffer at a time.
std::size_t count_lines(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::vector<char> buffer(1 << 16);
  std::size_t lines = 1;
  while (in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    const auto got = static_cast<std::ptrdiff_t>(in.gcount());
    lines += static_cast<std::size_t>(std::count(buffer.data(), buffer.data() + got, '\n'));
  }
  return lines;
}

}  // namespace

Dataset read_dataset(const std::filesystem::path& csv, formats::Rig* rig, std::size_t chunk_rows,
                     std::size_t buffer_bytes) {
  formats::LogReader reader(csv, buffer_bytes);
  DatasetBuilder builder(reader.columns(), count_lines(csv));
  std::vector<formats::Sample> chunk;
  chunk.reserve(chunk_rows);
  for (;;) {
    chunk.clear();
    if (reader.read(chunk, chunk_rows) == 0) break;
    for (const formats::Sample& s : chunk) builder.add(s);
  }
  const formats::Rig log_rig = reader.read_rig();
  if (rig != nullptr) *rig = log_rig;
  return builder.finish(log_rig);
}

bool differences_angular_rate(const Dataset& d) {
  return d.columns.angular_rate && !d.columns.angular_accel && !d.columns.static_rows;
}

void angular_accel_from_rate(Dataset& d) {
  // 5-point central differences (4th order) of the angular rate, 3-point one row from the ends,
  // zero on the first and last row.
  const std::size_t n = d.size();
  ResidentWindow window(d);
  for (std::size_t i = 1; i + 1 < n; ++i) {
    window.advance(i + 2);
    const int order = (i >= 2 && i + 2 < n) ? 4 : 2;
    Eigen::Map<Eigen::Vector3d>(&d.imu[i * 9 + 6]) =
        model::angular_accel_central(&d.imu[i * 9 + 3], 9, order, d.dt_s);
  }
}

model::DictionarySignals Dataset::dictionary(std::size_t i) const {
  model::KinematicInputs in;
  model::FeatureSignals& f = in.features;
  const model::PoseSignals p = pose(i);
  f.joints_rad = p.joints_rad;
  if (!columns.static_rows && size() >= 3) {
    const std::size_t c = std::clamp<std::size_t>(i, 1, size() - 2);
    model::central_differences(p_base_sensor_m[c - 1].data(), p_base_sensor_m[c].data(),
                               p_base_sensor_m[c + 1].data(), 3, t_s[c - 1], t_s[c], t_s[c + 1],
                               in.v_base_sensor_mps.data(), nullptr);
    if (columns.joints)
      model::central_differences(joints_rad[c - 1].data(), joints_rad[c].data(),
                                 joints_rad[c + 1].data(), 6, t_s[c - 1], t_s[c], t_s[c + 1],
                                 f.joint_vel_radps.data(), in.joint_acc_radps2.data());
  }
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      f.R_base_sensor[static_cast<std::size_t>(3 * r + c)] = p.R_base_sensor(r, c);
  for (int k = 0; k < 3; ++k)
    f.p_base_sensor_m[static_cast<std::size_t>(k)] = p_base_sensor_m[i][k];
  for (std::size_t k = 0; k < 9; ++k) f.imu[k] = imu[i * 9 + k];
  f.temperature_C = p.temperature_C;
  f.t_s = p.t_rel_s;
  return model::dictionary_signals(in, rig);
}

void Dataset::release_rows(std::size_t first, std::size_t last) const {
  last = std::min(last, size());
  if (first >= last) return;
  const auto rows = [&](const auto& column, std::size_t width) {
    if (column.size() < last * width) return;
    spill::release(column.data() + first * width, column.data() + last * width);
  };
  rows(t_s, 1);
  rows(q_base_sensor, 1);
  rows(temperature_C, 1);
  rows(joints_rad, 1);
  rows(imu, 9);
  rows(measured, 1);
  rows(moving, 1);
  rows(p_base_sensor_m, 1);
}

void ResidentWindow::release_behind() {
  const std::size_t to = end_ - window_;
  data_->release_rows(released_, to);
  released_ = to;
}

ResidentWindow::~ResidentWindow() {
  if (!active_ || end_ <= released_) return;
  // The most rows this walk held unreleased (at most two windows while advance releases).
  std::size_t peak = spill::stats().peak_window_rows.load();
  const std::size_t held = end_ - released_;
  while (held > peak && !spill::stats().peak_window_rows.compare_exchange_weak(peak, held)) {
  }
  data_->release_rows(released_, end_);
  ++spill::stats().walks;
}

std::size_t Dataset::bytes() const {
  const auto held = [](const auto& v) { return v.capacity() * sizeof(v[0]); };
  return held(t_s) + held(q_base_sensor) + held(temperature_C) + held(joints_rad) + held(imu) +
         held(measured) + held(moving) + held(p_base_sensor_m);
}

Wrench predict(const model::ModelParams& params, const Dataset& data, std::size_t i) {
  const auto p = model::pointers(params);
  const double* tau =
      params.effects.has(Effect::imu_time_offset) ? params.block(Effect::imu_time_offset) : nullptr;
  const model::PoseSignals pose = data.pose(i);
  Wrench w =
      model::predict_wrench<double>(params.effects, p, pose, data.imu_at<double>(i, tau), data.rig);
  if (!params.user.empty())
    w += model::user_wrench(params.user, data.dictionary(i), pose.R_base_sensor);
  return w;
}

std::vector<std::uint8_t> heldout_mask(const Dataset& data, double block_s, int every, int offset) {
  if (offset < 0) offset = every - 1;
  std::vector<std::uint8_t> mask(data.size(), 0);
  const double t0 = data.t_s.front();
  ResidentWindow window(data);
  for (std::size_t i = 0; i < data.size(); ++i) {
    window.advance(i);
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
    const formats::Columns& c = data.columns;
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
    if (e == Effect::bias_drift && c.static_rows && !data.rows_in_recorded_order)
      throw std::runtime_error(effect +
                               "drifts over the table's row order, but the rig says the rows are "
                               "not in the order they were recorded (row_order = \"unknown\"): "
                               "nothing can drift over them (log time, or keep the rows in the "
                               "order recorded and set row_order = \"recorded\")");
    if (e == Effect::imu_time_offset && c.static_rows)
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
