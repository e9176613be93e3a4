#include "zerog/sim/simulator.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include "random.hpp"
#include "zerog/formats/detail/csv_scan.hpp"
#include "zerog/model/dictionary.hpp"
#include "zerog/model/rotation.hpp"

namespace zerog::sim {
namespace {

using model::Effect;
using Vec6 = Eigen::Matrix<double, 6, 1>;

// What the simulated truth puts in for each library effect it can switch (a new library effect
// fails to compile here until the simulator gives it a magnitude).
const char* library_magnitude(Effect e) {
  switch (e) {
    case Effect::bias:
    case Effect::gravity:
    case Effect::linear_inertia:
      return nullptr;  // always in the truth
    case Effect::rotational_inertia:
      return "on by default; 0.6 x 0.4 x 0.3 m box, tilted (products of inertia non-zero)";
    case Effect::base_tilt:
      return "alpha, beta +-(2..5) mrad";
    case Effect::imu_time_offset:
      return "IMU lags the F/T by tau = 8 ms";
    case Effect::bias_drift:
      return "+-(2..5) N and +-(0.2..0.5) N*m per 10 min, linear";
    case Effect::temperature_bias:
      return "+-(0.5..1.5) N/K, +-(0.05..0.15) N*m/K; T = 25 + 2(1-exp(-t/300)) + 3 sin(2 pi "
             "t/600) C";
    case Effect::crosstalk:
      return "gains +-(0.2..0.5) %, couplings +-(0.05..0.3) % (x or / 0.2 m across F and M)";
    case Effect::sensor_rotation:
      return "random axis, 5..10 mrad";
    case Effect::cable:
      return "per A4..A6 cos/sin coefficient +-(0.5..3) N, +-(0.1..0.5) N*m";
  }
  return nullptr;
}

const std::array<SimEffectInfo, kRigEffectCount> kRigEffects = {{
    {RigEffect::imu_lever_arm, "imu_lever_arm",
     "rig geometry: IMU at (0.045, -0.030, -0.035) m in S (else at the S origin)"},
    {RigEffect::joint6_friction, "joint6_friction",
     "outside the model: Mz += 1.5 N*m * tanh(qd6 / 0.02 rad/s)"},
    {RigEffect::swivel_viscous, "swivel_viscous",
     "outside the model: Mz -= 2.0 N*m*s/rad * wz_S (hose swivel's seal drag)"},
    {RigEffect::hose_drag, "hose_drag",
     "outside the model: F_S -= 25 N*s/m * v_S (supply hose dragged along)"},
    {RigEffect::dress_pack_bend, "dress_pack_bend",
     "outside the model: Fx += 8 N * sin(q4) * sin(q5) (dress pack bent by A5, wound by A4)"},
}};

std::array<SimEffectInfo, kSimEffectCount> make_sim_effects() {
  std::array<SimEffectInfo, kSimEffectCount> out{};
  std::size_t k = 0;
  for (Effect e : model::kAllEffects)
    if (switchable(e)) out.at(k++) = {e, model::info(e).name, library_magnitude(e)};
  for (const SimEffectInfo& r : kRigEffects) out.at(k++) = r;
  return out;
}

std::vector<JointVector> checked_points(std::vector<JointVector> points) {
  const JointLimits lim = kr210_table4_limits();
  for (std::size_t k = 0; k < points.size(); ++k)
    if (!within_limits(points[k], lim))
      throw std::invalid_argument("path point " + std::to_string(k + 1) +
                                  " is outside the joint ranges of Table 4");
  return points;
}

Eigen::Matrix3d symmetric_upper(const Eigen::Matrix3d& I) {
  Eigen::Matrix3d S = I;
  S(1, 0) = S(0, 1);
  S(2, 0) = S(0, 2);
  S(2, 1) = S(1, 2);
  return S;
}

// A named scalar of the configuration, for --set and --list-effects.
struct Binding {
  std::string key;
  double* value;
};

std::vector<Binding> bindings(SimConfig& c) {
  std::vector<Binding> b;
  for (Effect e : model::kAllEffects) {
    const auto& ei = model::info(e);
    if (e == Effect::gravity || e == Effect::rotational_inertia) continue;  // from the payload
    for (int i = 0; i < ei.num_params; ++i)
      b.push_back({std::string(ei.name) + "." + ei.params[i].name, c.params.block(e) + i});
  }
  b.push_back({"gravity.mass", &c.payload.mass_kg});
  b.push_back({"gravity.cx", &c.payload.com_sensor_m.x()});
  b.push_back({"gravity.cy", &c.payload.com_sensor_m.y()});
  b.push_back({"gravity.cz", &c.payload.com_sensor_m.z()});
  Eigen::Matrix3d& I = c.payload.inertia_com_sensor_kgm2;
  b.push_back({"rotational_inertia.Ixx", &I(0, 0)});
  b.push_back({"rotational_inertia.Iyy", &I(1, 1)});
  b.push_back({"rotational_inertia.Izz", &I(2, 2)});
  b.push_back({"rotational_inertia.Ixy", &I(0, 1)});
  b.push_back({"rotational_inertia.Ixz", &I(0, 2)});
  b.push_back({"rotational_inertia.Iyz", &I(1, 2)});
  b.push_back({"noise.force", &c.noise.force_N});
  b.push_back({"noise.torque", &c.noise.torque_Nm});
  b.push_back({"noise.accel", &c.noise.accel_mps2});
  b.push_back({"noise.gyro", &c.noise.gyro_radps});
  b.push_back({"noise.ft_ar1", &c.noise.ft_ar1});
  b.push_back({"noise.encoder", &c.noise.encoder_rad});
  b.push_back({"noise.gyro_bias", &c.noise.gyro_bias_radps});
  b.push_back({"noise.accel_bias", &c.noise.accel_bias_mps2});
  b.push_back({"noise.imu_bias_tau", &c.noise.imu_bias_tau_s});
  for (std::size_t i = 0; i < 6; ++i) {
    JointElasticity& j = c.elastic.joints[i];
    const std::string a = std::to_string(i + 1);
    b.push_back({"elastic.k" + a, &j.stiffness_Nm_per_rad});
    b.push_back({"elastic.f" + a, &j.mode_hz});
    b.push_back({"elastic.zeta" + a, &j.damping_ratio});
  }
  b.push_back({"joint6_friction.torque", &c.joint6_friction_Nm});
  b.push_back({"joint6_friction.rate", &c.joint6_friction_rate_radps});
  b.push_back({"swivel_viscous.damping", &c.swivel_damping_Nms_per_rad});
  b.push_back({"hose_drag.damping", &c.hose_drag_Ns_per_m});
  b.push_back({"dress_pack_bend.force", &c.dress_pack_bend_N});
  b.push_back({"imu_lever_arm.x", &c.imu_lever_arm_m.x()});
  b.push_back({"imu_lever_arm.y", &c.imu_lever_arm_m.y()});
  b.push_back({"imu_lever_arm.z", &c.imu_lever_arm_m.z()});
  b.push_back({"imu_mount.rx", &c.imu_mount_rotvec_rad.x()});
  b.push_back({"imu_mount.ry", &c.imu_mount_rotvec_rad.y()});
  b.push_back({"imu_mount.rz", &c.imu_mount_rotvec_rad.z()});
  b.push_back({"temperature.base", &c.temperature.base_C});
  b.push_back({"temperature.warmup", &c.temperature.warmup_K});
  b.push_back({"temperature.warmup_tau", &c.temperature.warmup_tau_s});
  b.push_back({"temperature.amplitude", &c.temperature.amplitude_K});
  b.push_back({"temperature.period", &c.temperature.period_s});
  return b;
}

nlohmann::json vec_json(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

// The basis names of the signal dictionary (firmware/model/include/zerog/model/dictionary.hpp).
std::string tanh_basis(const char* signal, double eps) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "tanh(%s/%g)", signal, eps);
  return buf;
}

nlohmann::json terms_json(const std::vector<OutsideTerm>& terms) {
  nlohmann::json out = nlohmann::json::array();
  for (const OutsideTerm& t : terms)
    out.push_back({{"axis", t.axis}, {"basis", t.basis}, {"coefficient", t.coefficient}});
  return out;
}

}  // namespace

const std::array<SimEffectInfo, kSimEffectCount>& sim_effect_infos() {
  static const std::array<SimEffectInfo, kSimEffectCount> infos = make_sim_effects();
  return infos;
}
const SimEffectInfo& info(SimEffect e) {
  for (const SimEffectInfo& i : sim_effect_infos())
    if (i.id == e) return i;
  throw std::invalid_argument(
      "not a simulator effect: " + std::string(model::info(std::get<Effect>(e)).name) +
      " is always in the truth");
}

std::optional<SimEffect> sim_effect_from_name(std::string_view name) {
  for (const auto& i : sim_effect_infos())
    if (name == i.name) return i.id;
  return std::nullopt;
}

SimEffectSet parse_sim_effects(const std::string& list, SimEffectSet start) {
  SimEffectSet set = start;
  std::stringstream ss(list);
  std::string item;
  while (std::getline(ss, item, ',')) {
    item.erase(0, item.find_first_not_of(" \t"));
    item.erase(item.find_last_not_of(" \t") + 1);
    if (item.empty()) continue;
    if (item == "all" || item == "none") {
      for (const auto& i : sim_effect_infos()) {
        if (item == "all") {
          set.add(i.id);
        } else {
          set.remove(i.id);
        }
      }
      continue;
    }
    const bool off = item[0] == '-';
    const std::string name = off ? item.substr(1) : item;
    const auto e = sim_effect_from_name(name);
    if (const auto lib = model::effect_from_name(name); lib && !switchable(*lib))
      throw std::invalid_argument("simulator effect '" + name +
                                  "' cannot be switched: bias, gravity and linear_inertia are "
                                  "always in the truth (their parameters are set with --set)");
    if (!e) {
      std::string known;
      for (const auto& i : sim_effect_infos())
        known += std::string(known.empty() ? "" : ", ") + i.name;
      throw std::invalid_argument("unknown simulator effect '" + name + "' (known: " + known +
                                  ", all, none; '-name' switches one off)");
    }
    if (off) {
      set.remove(*e);
    } else {
      set.add(*e);
    }
  }
  return set;
}

std::string sim_effect_list_string(const SimEffectSet& effects) {
  std::string out;
  for (const auto& i : sim_effect_infos()) {
    if (!effects.has(i.id)) continue;
    out += (out.empty() ? "" : ",") + std::string(i.name);
  }
  return out;
}

std::vector<OutsideTerm> outside_terms(const SimConfig& config, SimEffect effect) {
  const SimConfig& c = config;
  const auto* rig = std::get_if<RigEffect>(&effect);
  if (rig == nullptr) return {};
  switch (*rig) {
    case RigEffect::joint6_friction:
      return {{"Mz", tanh_basis("qd6", c.joint6_friction_rate_radps), c.joint6_friction_Nm}};
    case RigEffect::swivel_viscous:
      return {{"Mz", "wz_S", -c.swivel_damping_Nms_per_rad}};
    case RigEffect::hose_drag:
      return {{"Fx", "vx_S", -c.hose_drag_Ns_per_m},
              {"Fy", "vy_S", -c.hose_drag_Ns_per_m},
              {"Fz", "vz_S", -c.hose_drag_Ns_per_m}};
    case RigEffect::dress_pack_bend:
      return {{"Fx", "sin(q4)*sin(q5)", c.dress_pack_bend_N}};
    case RigEffect::imu_lever_arm:
      break;  // geometry, not a wrench
  }
  return {};
}

std::vector<OutsideTerm> outside_terms(const SimConfig& config) {
  std::vector<OutsideTerm> out;
  for (const auto& i : sim_effect_infos()) {
    if (!config.effects.has(i.id)) continue;
    for (OutsideTerm& t : outside_terms(config, i.id)) out.push_back(std::move(t));
  }
  return out;
}

Eigen::Matrix3d box_inertia_kgm2(double mass_kg) {
  const double a = 0.6, b = 0.4, h = 0.3;
  const Eigen::Vector3d diag(mass_kg / 12.0 * (b * b + h * h), mass_kg / 12.0 * (a * a + h * h),
                             mass_kg / 12.0 * (a * a + b * b));
  const Eigen::Matrix3d R = model::rotation_from_vector(Eigen::Vector3d(0.10, -0.15, 0.20));
  const Eigen::Matrix3d I = R * diag.asDiagonal() * R.transpose();
  return 0.5 * (I + I.transpose());
}

double TemperatureProfile::at(double t_s) const {
  return base_C + warmup_K * (1.0 - std::exp(-t_s / warmup_tau_s)) +
         amplitude_K * std::sin(2.0 * std::numbers::pi * t_s / period_s);
}

SimConfig default_sim_config(std::uint64_t seed) {
  SimConfig c;
  c.seed = seed;
  c.payload.inertia_com_sensor_kgm2 = box_inertia_kgm2(c.payload.mass_kg);
  detail::Rng rng(seed, 10);
  // Every block is drawn, in a fixed order, whether or not its effect is on: switching one
  // effect does not change the others' values for the same seed.
  double* bias = c.params.block(Effect::bias);
  for (int i = 0; i < 3; ++i) bias[i] = rng.signed_uniform(20.0, 60.0);
  for (int i = 3; i < 6; ++i) bias[i] = rng.signed_uniform(1.0, 5.0);
  double* tilt = c.params.block(Effect::base_tilt);
  for (int i = 0; i < 2; ++i) tilt[i] = rng.signed_uniform(0.002, 0.005);
  c.params.block(Effect::imu_time_offset)[0] = 0.008;
  double* drift = c.params.block(Effect::bias_drift);
  for (int i = 0; i < 3; ++i) drift[i] = rng.signed_uniform(2.0, 5.0) / 600.0;
  for (int i = 3; i < 6; ++i) drift[i] = rng.signed_uniform(0.2, 0.5) / 600.0;
  double* temp = c.params.block(Effect::temperature_bias);
  for (int i = 0; i < 3; ++i) temp[i] = rng.signed_uniform(0.5, 1.5);
  for (int i = 3; i < 6; ++i) temp[i] = rng.signed_uniform(0.05, 0.15);
  double* E = c.params.block(Effect::crosstalk);
  constexpr double kCouplingLength_m = 0.2;
  for (int r = 0; r < 6; ++r) {
    for (int k = 0; k < 6; ++k) {
      double x = r == k ? rng.signed_uniform(0.002, 0.005) : rng.signed_uniform(0.0005, 0.003);
      if (r < 3 && k >= 3) x /= kCouplingLength_m;  // force from torque, 1/m
      if (r >= 3 && k < 3) x *= kCouplingLength_m;  // torque from force, m
      E[r * 6 + k] = x;
    }
  }
  Eigen::Vector3d axis(rng.normal(), rng.normal(), rng.normal());
  axis.normalize();
  Eigen::Map<Eigen::Vector3d>(c.params.block(Effect::sensor_rotation)) =
      axis * rng.uniform(0.005, 0.010);
  double* cable = c.params.block(Effect::cable);
  for (int i = 0; i < 36; ++i)
    cable[i] = (i % 6) < 3 ? rng.signed_uniform(0.5, 3.0) : rng.signed_uniform(0.1, 0.5);
  return c;
}

void make_real_robot(SimConfig& config, bool sensors) {
  config.elastic = kr210_elasticity();
  if (!sensors) return;
  config.noise.encoder_rad = kRsiJointResolutionRad;
  config.noise.gyro_bias_radps = kStim300GyroBiasInstabilityRadps;
  config.noise.accel_bias_mps2 = kStim300AccelBiasInstabilityMps2;
}

void set_config_value(SimConfig& config, const std::string& key, double value) {
  if (!std::isfinite(value)) throw std::invalid_argument("--set " + key + ": value must be finite");
  if (key == "noise.quantize") {
    config.noise.quantize = value != 0.0;
    return;
  }
  if (key == "noise.imu_point_rows") {
    config.noise.imu_point_rows = value != 0.0;
    return;
  }
  if (key == "elastic.on") {  // the KR 210 defaults, unless joints were set already
    config.elastic.enabled = value != 0.0;
    bool any = false;
    for (const JointElasticity& j : config.elastic.joints)
      any = any || j.stiffness_Nm_per_rad > 0.0;
    if (config.elastic.enabled && !any) config.elastic.joints = kr210_elasticity().joints;
    return;
  }
  for (const Binding& b : bindings(config)) {
    if (b.key != key) continue;
    *b.value = value;
    config.payload.inertia_com_sensor_kgm2 =
        symmetric_upper(config.payload.inertia_com_sensor_kgm2);
    return;
  }
  std::string known;
  for (const Binding& b : bindings(config)) {
    const std::string group = b.key.substr(0, b.key.find('.'));
    if (known.find(group + ".") == std::string::npos)
      known += (known.empty() ? "" : ", ") + group + ".*";
  }
  throw std::invalid_argument("unknown --set key '" + key + "' (groups: " + known +
                              ", noise.quantize, noise.imu_point_rows, elastic.on; --list-effects "
                              "prints every key)");
}

std::vector<std::pair<std::string, double>> config_values(const SimConfig& config) {
  SimConfig copy = config;
  std::vector<std::pair<std::string, double>> out;
  for (const Binding& b : bindings(copy)) out.emplace_back(b.key, *b.value);
  out.emplace_back("noise.quantize", config.noise.quantize ? 1.0 : 0.0);
  out.emplace_back("noise.imu_point_rows", config.noise.imu_point_rows ? 1.0 : 0.0);
  out.emplace_back("elastic.on", config.elastic.enabled ? 1.0 : 0.0);
  return out;
}

RigSimulator::RigSimulator(SimConfig config, std::vector<JointVector> path_points_rad)
    : config_(std::move(config)),
      trajectory_(checked_points(std::move(path_points_rad)),
                  kr210_ptp_limits(config_.speed_fraction), config_.dwell_s) {
  const SimConfig& c = config_;
  if (!(c.period_s > 0.0)) throw std::invalid_argument("sample period must be positive");
  if (!(c.payload.mass_kg > 0.0)) throw std::invalid_argument("payload mass must be positive");
  if (c.duration_limit_s < 0.0) throw std::invalid_argument("duration limit must not be negative");
  R_world_base_ = Eigen::Matrix3d::Identity();
  if (c.effects.has(Effect::base_tilt)) {
    const double* tilt = c.params.block(Effect::base_tilt);
    R_world_base_ = model::rot_x(tilt[0]) * model::rot_y(tilt[1]);
  }
  R_nominal_true_ = Eigen::Matrix3d::Identity();
  if (c.effects.has(Effect::sensor_rotation))
    R_nominal_true_ = model::rotation_from_vector(Eigen::Vector3d(
        Eigen::Map<const Eigen::Vector3d>(c.params.block(Effect::sensor_rotation))));
  R_sensor_imu_ = model::rotation_from_vector(c.imu_mount_rotvec_rad);
  p_sensor_imu_m_ =
      c.effects.has(RigEffect::imu_lever_arm) ? c.imu_lever_arm_m : Eigen::Vector3d::Zero();
}

RigSimulator::RigSimulator(SimConfig config) : RigSimulator(std::move(config), {kr210_home()}) {}

formats::Rig RigSimulator::rig() const {
  formats::Rig r;
  r.name = "kr210-omega191-stim300-sim";
  r.robot = "KR 210 R2700";
  r.flange_sensor.p_m = config_.p_flange_sensor_m;
  r.sensor_imu.p_m = p_sensor_imu_m_;
  r.sensor_imu.q = Eigen::Quaterniond(R_sensor_imu_).normalized();
  r.sample_period_s = config_.period_s;
  // The simulator evaluates the signals only at the row times.
  r.ft_rate_hz = 1.0 / config_.period_s;
  r.imu_rate_hz = 1.0 / config_.period_s;
  r.floor_z_m = config_.floor_z_m;
  // Point-sampled IMU rows are said, with the noise per row (NoiseConfig); mean rows are not, as
  // before.
  if (config_.noise.imu_point_rows)
    r.imu_sampling = {formats::ImuRows::point, config_.noise.gyro_radps, config_.noise.accel_mps2};
  return r;
}

model::EffectSet RigSimulator::truth_model_effects() const {
  model::EffectSet set = {Effect::bias, Effect::gravity, Effect::linear_inertia};
  for (const auto& i : sim_effect_infos())
    if (i.model_effect() && config_.effects.has(i.id)) set.add(*i.model_effect());
  return set;
}

io::ModelFile RigSimulator::truth() const {
  const SimConfig& c = config_;
  io::ModelFile m;
  m.params = c.params;
  m.params.effects = truth_model_effects();
  double* grav = m.params.block(Effect::gravity);
  grav[0] = c.payload.mass_kg;
  for (int i = 0; i < 3; ++i) grav[1 + i] = c.payload.com_sensor_m[i];
  double* rot = m.params.block(Effect::rotational_inertia);
  const Eigen::Matrix3d& I = c.payload.inertia_com_sensor_kgm2;
  const double elements[6] = {I(0, 0), I(1, 1), I(2, 2), I(0, 1), I(0, 2), I(1, 2)};
  std::copy(std::begin(elements), std::end(elements), rot);
  m.rig_name = rig().name;
  // The effects outside the library, as user-defined effects with their exact terms
  // (proto/user_effects.md), so that the truth predicts them too. They add after the crosstalk,
  // the simulator's before: with both on, the truth is off by the crosstalk of the outside
  // wrench (a fraction of a percent of it).
  for (const SimEffectInfo& i : sim_effect_infos()) {
    if (!c.effects.has(i.id)) continue;
    const std::vector<OutsideTerm> terms = outside_terms(c, i.id);
    if (terms.empty()) continue;
    model::UserEffects& u = m.params.user;
    const std::string name = i.name;
    std::copy(name.begin(), name.end(), u.names[static_cast<std::size_t>(u.num_effects)].begin());
    for (const OutsideTerm& t : terms) {
      model::UserTerm term;
      const char* error = nullptr;
      std::size_t pos = 0;
      if (!model::parse_basis(t.basis, term.basis, error, pos))
        throw std::logic_error("outside term basis '" + t.basis + "': " + error);
      const int axis = model::wrench_axis_from_name(t.axis);
      if (axis < 0) throw std::logic_error("outside term axis '" + t.axis + "'");
      term.axis = static_cast<std::uint8_t>(axis);
      term.effect = static_cast<std::uint8_t>(u.num_effects);
      u.terms[static_cast<std::size_t>(u.num_terms)] = term;
      u.coeff[static_cast<std::size_t>(u.num_terms)] = t.coefficient;
      ++u.num_terms;
    }
    ++u.num_effects;
  }

  nlohmann::json x;
  x["generator"] = "zerog sim";
  x["seed"] = c.seed;
  x["sim_effects"] = sim_effect_list_string(c.effects);
  x["noise"] = {{"force_N", c.noise.force_N},       {"torque_Nm", c.noise.torque_Nm},
                {"accel_mps2", c.noise.accel_mps2}, {"gyro_radps", c.noise.gyro_radps},
                {"quantize", c.noise.quantize},     {"resolution", kOmega191Resolution},
                {"ft_ar1", c.noise.ft_ar1}};
  // Only when on: truth files of the rigid robot stay as before.
  if (c.noise.encoder_rad > 0.0) x["noise"]["encoder_rad"] = c.noise.encoder_rad;
  if (c.noise.gyro_bias_radps > 0.0 || c.noise.accel_bias_mps2 > 0.0)
    x["noise"]["imu_bias"] = {{"gyro_radps", c.noise.gyro_bias_radps},
                              {"accel_mps2", c.noise.accel_bias_mps2},
                              {"tau_s", c.noise.imu_bias_tau_s},
                              {"process", "first-order Gauss-Markov per axis"}};
  if (c.elastic.enabled) {
    nlohmann::json joints = nlohmann::json::array();
    for (const JointElasticity& j : c.elastic.joints)
      joints.push_back({{"stiffness_Nm_per_rad", j.stiffness_Nm_per_rad},
                        {"mode_hz", j.mode_hz},
                        {"damping_ratio", j.damping_ratio}});
    x["elastic_robot"] = {
        {"joints", joints},
        {"model",
         "link = motor + deflection; deflection'' = w^2 (tau/k - deflection) - 2 zeta w "
         "deflection' - motor'' per joint (host/sim/include/zerog/sim/elastic.hpp); the log's "
         "joints and pose are the motor side, the clean log's the link side"}};
  }
  x["outside_model"]["joint6_friction"] = {
      {"enabled", c.effects.has(RigEffect::joint6_friction)},
      {"torque_Nm", c.joint6_friction_Nm},
      {"rate_radps", c.joint6_friction_rate_radps},
      {"formula", "Mz += torque_Nm * tanh(qd6 / rate_radps), added before crosstalk"},
      {"terms", terms_json(outside_terms(c, RigEffect::joint6_friction))}};
  x["outside_model"]["swivel_viscous"] = {
      {"enabled", c.effects.has(RigEffect::swivel_viscous)},
      {"damping_Nms_per_rad", c.swivel_damping_Nms_per_rad},
      {"formula",
       "Mz -= damping_Nms_per_rad * wz_S (payload angular velocity about z of the true sensor "
       "frame), added before crosstalk"},
      {"terms", terms_json(outside_terms(c, RigEffect::swivel_viscous))}};
  x["outside_model"]["hose_drag"] = {
      {"enabled", c.effects.has(RigEffect::hose_drag)},
      {"damping_Ns_per_m", c.hose_drag_Ns_per_m},
      {"formula",
       "F_S -= damping_Ns_per_m * v_S (velocity of the sensor origin in the true sensor frame), "
       "no torque about the sensor origin, added before crosstalk"},
      {"terms", terms_json(outside_terms(c, RigEffect::hose_drag))}};
  x["outside_model"]["dress_pack_bend"] = {
      {"enabled", c.effects.has(RigEffect::dress_pack_bend)},
      {"force_N", c.dress_pack_bend_N},
      {"formula",
       "Fx += force_N * sin(q4) * sin(q5) (joint angles A4, A5), added before crosstalk"},
      {"terms", terms_json(outside_terms(c, RigEffect::dress_pack_bend))}};
  x["rig_geometry"] = {{"imu_lever_arm_enabled", c.effects.has(RigEffect::imu_lever_arm)},
                       {"p_sensor_imu_m", vec_json(p_sensor_imu_m_)},
                       {"imu_mount_rotvec_rad", vec_json(c.imu_mount_rotvec_rad)},
                       {"p_flange_sensor_m", vec_json(c.p_flange_sensor_m)}};
  nlohmann::json inertia = nlohmann::json::array();
  for (int r = 0; r < 3; ++r) inertia.push_back({I(r, 0), I(r, 1), I(r, 2)});
  x["payload"] = {{"mass_kg", c.payload.mass_kg},
                  {"com_sensor_m", vec_json(c.payload.com_sensor_m)},
                  {"inertia_com_sensor_kgm2", inertia},
                  {"point_mass", !c.effects.has(Effect::rotational_inertia)}};
  x["temperature_profile"] = {{"base_C", c.temperature.base_C},
                              {"warmup_K", c.temperature.warmup_K},
                              {"warmup_tau_s", c.temperature.warmup_tau_s},
                              {"amplitude_K", c.temperature.amplitude_K},
                              {"period_s", c.temperature.period_s}};
  x["trajectory"] = {{"period_s", c.period_s},
                     {"dwell_s", c.dwell_s},
                     {"speed_fraction", c.speed_fraction},
                     {"path_points", trajectory_.num_points()},
                     {"duration_s", trajectory_.duration_s()}};
  m.extra = x;
  return m;
}

double RigSimulator::imu_delay_s() const {
  return config_.effects.has(Effect::imu_time_offset)
             ? config_.params.block(Effect::imu_time_offset)[0]
             : 0.0;
}

ImuTruth RigSimulator::imu_of(const robot::FlangeMotion& fm) const {
  // The IMU is fixed to the flange side: nominal sensor frame, rig pose of the IMU in it.
  const Eigen::Matrix3d R_base_imu = fm.R_base_flange * R_sensor_imu_;
  const Eigen::Vector3d lever_base_m =
      fm.R_base_flange * (config_.p_flange_sensor_m + p_sensor_imu_m_);
  const Eigen::Vector3d g_base =
      R_world_base_.transpose() * Eigen::Vector3d(0.0, 0.0, -model::kStandardGravity);
  ImuTruth out;
  out.specific_force_imu_mps2 =
      R_base_imu.transpose() * (fm.acceleration_of(lever_base_m) - g_base);
  out.angular_rate_imu_radps = R_base_imu.transpose() * fm.omega_base_radps;
  out.angular_accel_imu_radps2 = R_base_imu.transpose() * fm.omega_dot_base_radps2;
  return out;
}

Vec6 RigSimulator::wrench_of(const JointState& js, const robot::FlangeMotion& fm, double t_s,
                             std::span<const ExternalWrench> pushes,
                             Measurement* kinematics) const {
  const SimConfig& c = config_;
  const Eigen::Matrix3d R_base_sensor = fm.R_base_flange * R_nominal_true_;  // true S
  const Eigen::Vector3d& com = c.payload.com_sensor_m;
  const Eigen::Vector3d lever_base_m = fm.R_base_flange * c.p_flange_sensor_m + R_base_sensor * com;
  const Eigen::Vector3d g_base =
      R_world_base_.transpose() * Eigen::Vector3d(0.0, 0.0, -model::kStandardGravity);
  const Eigen::Vector3d g_sensor = R_base_sensor.transpose() * g_base;
  const Eigen::Vector3d a_com_sensor = R_base_sensor.transpose() * fm.acceleration_of(lever_base_m);
  const Eigen::Vector3d omega = R_base_sensor.transpose() * fm.omega_base_radps;
  const Eigen::Vector3d omega_dot = R_base_sensor.transpose() * fm.omega_dot_base_radps2;
  if (kinematics != nullptr) {
    kinematics->R_base_sensor = R_base_sensor;
    kinematics->p_base_sensor_m = fm.p_base_flange_m + fm.R_base_flange * c.p_flange_sensor_m;
    kinematics->v_com_base_mps = fm.velocity_of(lever_base_m);
  }

  // Newton–Euler for the payload (paper 000_… eq. 1, 4, 5): the sensor holds the payload
  // against gravity and accelerates it; the payload's reaction is what the sensor reads.
  Vec6 w;
  const Eigen::Vector3d force = c.payload.mass_kg * (g_sensor - a_com_sensor);
  Eigen::Vector3d torque = com.cross(force);
  if (c.effects.has(Effect::rotational_inertia)) {
    const Eigen::Matrix3d& I = c.payload.inertia_com_sensor_kgm2;
    torque -= I * omega_dot + omega.cross(I * omega);
  }
  w << force, torque;
  // A push on the payload is carried to the sensor through the payload like its weight.
  for (const ExternalWrench& push : pushes) {
    const Eigen::Vector3d force_sensor =
        R_base_sensor.transpose() * push.force_base_N + push.force_sensor_N;
    w.head<3>() += force_sensor;
    w.tail<3>() += push.point_sensor_m.cross(force_sensor) +
                   R_base_sensor.transpose() * push.torque_base_Nm + push.torque_sensor_Nm;
  }
  if (c.effects.has(Effect::cable)) {
    const double* k = c.params.block(Effect::cable);
    for (int j = 0; j < 3; ++j) {
      const double q = js.q_rad[model::kCableJoints[j]];
      for (int i = 0; i < 6; ++i)
        w[i] += k[12 * j + i] * std::cos(q) + k[12 * j + 6 + i] * std::sin(q);
    }
  }
  // Outside the model library: loads on the payload that the sensor carries like the others.
  w += outside_wrench_of(js, fm, R_base_sensor);
  if (c.effects.has(Effect::crosstalk)) {
    const Eigen::Map<const Eigen::Matrix<double, 6, 6, Eigen::RowMajor>> E(
        c.params.block(Effect::crosstalk));
    w = (Eigen::Matrix<double, 6, 6>::Identity() + E) * w;
  }
  w += Eigen::Map<const Vec6>(c.params.block(Effect::bias));
  if (c.effects.has(Effect::bias_drift))
    w += Eigen::Map<const Vec6>(c.params.block(Effect::bias_drift)) * t_s;
  if (c.effects.has(Effect::temperature_bias))
    w += Eigen::Map<const Vec6>(c.params.block(Effect::temperature_bias)) *
         (c.temperature.at(t_s) - model::kTemperatureReferenceC);
  return w;
}

Vec6 RigSimulator::outside_wrench_of(const JointState& js, const robot::FlangeMotion& fm,
                                     const Eigen::Matrix3d& R_base_sensor) const {
  const SimConfig& c = config_;
  Vec6 w = Vec6::Zero();
  // A6 bearing friction, smoothed through zero rate.
  if (c.effects.has(RigEffect::joint6_friction))
    w[5] += c.joint6_friction_Nm * std::tanh(js.qd_radps[5] / c.joint6_friction_rate_radps);
  // A rotary hose swivel on the z_S axis whose housing the hose holds still: its seal drags
  // viscously against the payload's angular velocity about that axis.
  if (c.effects.has(RigEffect::swivel_viscous)) {
    const Eigen::Vector3d omega_sensor = R_base_sensor.transpose() * fm.omega_base_radps;
    w[5] -= c.swivel_damping_Nms_per_rad * omega_sensor.z();
  }
  // A supply hose clamped at the sensor origin and dragged along: a viscous force against the
  // origin's velocity, no torque about it.
  if (c.effects.has(RigEffect::hose_drag)) {
    const Eigen::Vector3d v_sensor =
        R_base_sensor.transpose() * fm.velocity_of(fm.R_base_flange * c.p_flange_sensor_m);
    w.head<3>() -= c.hose_drag_Ns_per_m * v_sensor;
  }
  // The dress pack over the wrist: its pull grows with the A5 bend, and A4 winds it round the
  // forearm towards x_S.
  if (c.effects.has(RigEffect::dress_pack_bend))
    w[0] += c.dress_pack_bend_N * std::sin(js.q_rad[3]) * std::sin(js.q_rad[4]);
  return w;
}

Vec6 RigSimulator::outside_wrench_at(double t_s) const {
  const JointState js = trajectory_.at(t_s);
  const robot::FlangeMotion fm =
      robot::flange_motion(kr210(), js.q_rad, js.qd_radps, js.qdd_radps2);
  Vec6 w = outside_wrench_of(js, fm, fm.R_base_flange * R_nominal_true_);
  if (config_.effects.has(Effect::crosstalk)) {
    const Eigen::Map<const Eigen::Matrix<double, 6, 6, Eigen::RowMajor>> E(
        config_.params.block(Effect::crosstalk));
    w = (Eigen::Matrix<double, 6, 6>::Identity() + E) * w;
  }
  return w;
}

Measurement RigSimulator::measure(const JointState& js, const JointState& js_imu, double t_s,
                                  std::span<const ExternalWrench> pushes) const {
  Measurement m;
  m.flange = robot::flange_motion(kr210(), js.q_rad, js.qd_radps, js.qdd_radps2);
  m.wrench_sensor = wrench_of(js, m.flange, t_s, pushes, &m);
  m.imu =
      &js_imu == &js
          ? imu_of(m.flange)
          : imu_of(robot::flange_motion(kr210(), js_imu.q_rad, js_imu.qd_radps, js_imu.qdd_radps2));
  return m;
}

Measurement RigSimulator::measure(const JointState& js, double t_s,
                                  std::span<const ExternalWrench> pushes) const {
  return measure(js, js, t_s, pushes);
}

ImuTruth RigSimulator::imu_at(double t_s) const {
  const JointState js = trajectory_.at(t_s - imu_delay_s());
  return imu_of(robot::flange_motion(kr210(), js.q_rad, js.qd_radps, js.qdd_radps2));
}

Vec6 RigSimulator::wrench_at(double t_s) const {
  const JointState js = trajectory_.at(t_s);
  return wrench_of(js, robot::flange_motion(kr210(), js.q_rad, js.qd_radps, js.qdd_radps2), t_s, {},
                   nullptr);
}

double Contact::factor_at(double t_s) const {
  const double u = t_s - start_s;
  if (u < 0.0 || u > duration_s || duration_s <= 0.0) return 0.0;
  if (shape == Shape::spike) return std::sin(std::numbers::pi * u / duration_s);
  const double ramp = std::min(ramp_s, 0.5 * duration_s);
  const double edge = std::min(u, duration_s - u);
  if (ramp <= 0.0 || edge >= ramp) return 1.0;
  return 0.5 - 0.5 * std::cos(std::numbers::pi * edge / ramp);
}

Contact parse_contact(const std::string& text) {
  const std::string what = "--contact '" + text + "'";
  std::vector<std::string> parts;
  for (std::size_t a = 0;;) {
    const std::size_t b = text.find(':', a);
    parts.push_back(text.substr(a, b == std::string::npos ? std::string::npos : b - a));
    if (b == std::string::npos) break;
    a = b + 1;
  }
  if (parts.size() < 3 || parts.size() > 5)
    throw std::invalid_argument(
        what + ": wants START:DURATION:FX,FY,FZ[,MX,MY,MZ][:sensor|base][:plateau|spike]");
  auto number = [&](const std::string& s, const char* name) {
    double x = 0.0;
    if (formats::detail::parse_number(s, x) != formats::detail::NumberStatus::ok)
      throw std::invalid_argument(what + ": " + name + " '" + s + "' is not a number");
    return x;
  };
  Contact c;
  c.start_s = number(parts[0], "START");
  c.duration_s = number(parts[1], "DURATION");
  if (c.start_s < 0.0 || c.duration_s <= 0.0)
    throw std::invalid_argument(what + ": START must be >= 0 s and DURATION > 0 s");
  std::vector<std::string> w;
  for (std::size_t a = 0;;) {
    const std::size_t b = parts[2].find(',', a);
    w.push_back(parts[2].substr(a, b == std::string::npos ? std::string::npos : b - a));
    if (b == std::string::npos) break;
    a = b + 1;
  }
  if (w.size() != 3 && w.size() != 6)
    throw std::invalid_argument(what + ": the wrench wants 3 forces (N) or 3 forces and 3 " +
                                "torques (N*m), got " + std::to_string(w.size()) + " values");
  for (std::size_t i = 0; i < w.size(); ++i)
    c.wrench[static_cast<Eigen::Index>(i)] = number(w[i], i < 3 ? "force" : "torque");
  for (std::size_t i = 3; i < parts.size(); ++i) {
    if (parts[i] == "sensor" || parts[i] == "base")
      c.base_frame = parts[i] == "base";
    else if (parts[i] == "plateau" || parts[i] == "spike")
      c.shape = parts[i] == "spike" ? Contact::Shape::spike : Contact::Shape::plateau;
    else
      throw std::invalid_argument(what + ": '" + parts[i] +
                                  "' is neither a frame (sensor, base) nor a shape (plateau, "
                                  "spike)");
  }
  return c;
}

namespace {

// The pose the controller reports for joint angles q: nominal kinematics, nominal mounting.
void set_nominal_pose(formats::Sample& s, const JointVector& q, const SimConfig& c) {
  const robot::Pose fp = robot::flange_pose(kr210(), q);
  s.p_base_sensor_m = fp.p_m + fp.R * c.p_flange_sensor_m;
  s.q_base_sensor = Eigen::Quaterniond(fp.R).normalized();
  if (s.q_base_sensor.w() < 0.0) s.q_base_sensor.coeffs() *= -1.0;
}

// IMU bias instability per axis: b_k = a b_{k−1} + σ sqrt(1 − a²) ε, a = exp(−T/τ), started from
// its stationary distribution (a random turn-on value of the same σ).
struct ImuBias {
  ImuBias(const NoiseConfig& n, double period_s, detail::Rng& rng)
      : a_(n.imu_bias_tau_s > 0.0 ? std::exp(-period_s / n.imu_bias_tau_s) : 1.0),
        gyro_sigma_(n.gyro_bias_radps),
        accel_sigma_(n.accel_bias_mps2),
        rng_(rng) {
    for (int i = 0; i < 3; ++i) {
      gyro_radps[i] = gyro_sigma_ > 0.0 ? gyro_sigma_ * rng_.normal() : 0.0;
      accel_mps2[i] = accel_sigma_ > 0.0 ? accel_sigma_ * rng_.normal() : 0.0;
    }
  }
  void step() {
    const double g = std::sqrt(1.0 - a_ * a_);
    for (int i = 0; i < 3; ++i) {
      if (gyro_sigma_ > 0.0) gyro_radps[i] = a_ * gyro_radps[i] + gyro_sigma_ * g * rng_.normal();
      if (accel_sigma_ > 0.0) accel_mps2[i] = a_ * accel_mps2[i] + accel_sigma_ * g * rng_.normal();
    }
  }
  Eigen::Vector3d gyro_radps = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_mps2 = Eigen::Vector3d::Zero();

 private:
  double a_, gyro_sigma_, accel_sigma_;
  detail::Rng& rng_;
};

// The contacts of a run as the truth file lists them (outside the payload model).
nlohmann::json contacts_json(const std::vector<Contact>& contacts) {
  nlohmann::json list = nlohmann::json::array();
  for (const Contact& k : contacts)
    list.push_back({{"start_s", k.start_s},
                    {"duration_s", k.duration_s},
                    {"wrench", std::vector<double>(k.wrench.data(), k.wrench.data() + 6)},
                    {"frame", k.base_frame ? "base" : "sensor"},
                    {"shape", k.shape == Contact::Shape::spike ? "spike" : "plateau"},
                    {"ramp_s", k.ramp_s}});
  return list;
}

// Contacts active at t into `pushes`, each at its shape's share (at most a few: no allocation);
// returns how many.
std::size_t active_pushes(const std::vector<Contact>& contacts, double t,
                          std::array<ExternalWrench, 8>& pushes) {
  std::size_t active = 0;
  for (const Contact& contact : contacts) {
    const double f = contact.factor_at(t);
    if (f == 0.0 || active == pushes.size()) continue;
    ExternalWrench& p = pushes[active++];
    const Eigen::Vector3d force = f * contact.wrench.head<3>();
    const Eigen::Vector3d torque = f * contact.wrench.tail<3>();
    (contact.base_frame ? p.force_base_N : p.force_sensor_N) = force;
    (contact.base_frame ? p.torque_base_Nm : p.torque_sensor_Nm) = torque;
  }
  return active;
}

}  // namespace

JointVector payload_load(const JointVector& link_q_rad, const Eigen::Matrix3d& R_base_sensor,
                         const SimConfig& c, std::span<const ExternalWrench> pushes) {
  JointVector tau = weight_load(link_q_rad, R_base_sensor, c.p_flange_sensor_m,
                                c.payload.com_sensor_m, c.payload.mass_kg);
  if (pushes.empty()) return tau;
  // The pushes as one wrench at the S origin (B axes), then one Jᵀ.
  Eigen::Vector3d force = Eigen::Vector3d::Zero(), torque = Eigen::Vector3d::Zero();
  for (const ExternalWrench& w : pushes) {
    const Eigen::Vector3d f = w.force_base_N + R_base_sensor * w.force_sensor_N;
    force += f;
    torque += (R_base_sensor * w.point_sensor_m).cross(f) + w.torque_base_Nm +
              R_base_sensor * w.torque_sensor_Nm;
  }
  const JointVector push = wrench_load(link_q_rad, R_base_sensor, c.p_flange_sensor_m, force,
                                       Eigen::Vector3d::Zero(), torque);
  for (std::size_t i = 0; i < tau.size(); ++i) tau[i] += push[i];
  return tau;
}

namespace {

// The elastic arm's static sag at the run's start, under the load it changes (three passes);
// returns that load.
JointVector settle_at_start(const RigSimulator& sim, ElasticArm& arm) {
  const SimConfig& c = sim.config();
  const JointState start = sim.trajectory().at(0.0);
  std::array<ExternalWrench, 8> pushes;
  const std::span<const ExternalWrench> at_start(pushes.data(),
                                                 active_pushes(c.contacts, 0.0, pushes));
  JointVector load{};
  for (int pass = 0; pass < 3; ++pass) {
    JointState link = start;
    for (std::size_t i = 0; i < 6; ++i) link.q_rad[i] += arm.deflection_rad()[i];
    load =
        payload_load(link.q_rad, sim.measure(link, link, 0.0, at_start).R_base_sensor, c, at_start);
    arm.settle(0.0, load);
  }
  return load;
}

}  // namespace

SimOutput RigSimulator::run(const std::function<void(double)>& progress) const {
  const SimConfig& c = config_;
  double t_end = trajectory_.duration_s();
  if (c.duration_limit_s > 0.0) t_end = std::min(t_end, c.duration_limit_s);
  const auto n = static_cast<std::size_t>(std::floor(t_end / c.period_s + 1e-9)) + 1;

  SimOutput out;
  out.log.rig = rig();
  out.log.columns = {
      .joints = true, .specific_force = true, .angular_rate = true, .temperature = true};
  out.log.samples.reserve(n);
  out.clean_log.rig = out.log.rig;
  out.clean_log.columns = out.log.columns;
  out.clean_log.samples.reserve(n);
  out.angular_accel_imu_radps2.reserve(n);
  out.truth = truth();
  if (c.contacts.size() > 8)
    throw std::invalid_argument("at most 8 contacts in one run, got " +
                                std::to_string(c.contacts.size()));
  // Outside the payload model: listed for the user and the tests, never predicted by the truth.
  if (!c.contacts.empty()) out.truth.extra["contacts"] = contacts_json(c.contacts);
  out.stats.samples = n;
  out.stats.trajectory_duration_s = trajectory_.duration_s();
  out.stats.lowest_point_z_m = std::numeric_limits<double>::infinity();

  Workspace ws;
  ws.p_flange_sensor_m = c.p_flange_sensor_m;
  ws.R_flange_sensor = R_nominal_true_;
  ws.com_sensor_m = c.payload.com_sensor_m;

  detail::Rng noise(c.seed, 20);
  if (!(c.noise.ft_ar1 >= 0.0 && c.noise.ft_ar1 < 1.0))
    throw std::invalid_argument("noise.ft_ar1 must lie in [0, 1), got " +
                                std::to_string(c.noise.ft_ar1));
  std::array<double, 6> ft_noise{};  // AR(1) state per axis (white when ft_ar1 is 0)
  const double ar1_gain = std::sqrt(1.0 - c.noise.ft_ar1 * c.noise.ft_ar1);
  const std::size_t report_every = std::max<std::size_t>(n / 20, 1);
  // A robot that is not rigid (elastic.hpp): the payload moves with the link side, the encoders
  // and the controller's pose report the motor side.
  ElasticArm arm(c.elastic);
  JointVector load{};
  if (c.elastic.enabled) load = settle_at_start(*this, arm);
  // IMU bias instability: a first-order Gauss–Markov process per axis (NoiseConfig).
  ImuBias bias(c.noise, c.period_s, noise);
  for (std::size_t k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) * c.period_s;
    formats::Sample s;
    s.t_s = t;
    const JointState motor = trajectory_.at(t);
    const JointState js = c.elastic.enabled ? arm.advance(t, trajectory_, load) : motor;
    s.joints_rad = motor.q_rad;
    if (c.noise.encoder_rad > 0.0)
      for (double& q : s.joints_rad) q = c.noise.encoder_rad * std::round(q / c.noise.encoder_rad);
    // Logged pose: what the controller reports from its encoders, nominal (no tilt, no mounting
    // error, no elasticity).
    set_nominal_pose(s, s.joints_rad, c);

    std::array<ExternalWrench, 8> pushes;
    const std::size_t active = active_pushes(c.contacts, t, pushes);
    // With elasticity the IMU delay shifts the motor path and keeps the link's deflection at t.
    JointState js_imu = trajectory_.at(t - imu_delay_s());
    if (c.elastic.enabled)
      for (std::size_t i = 0; i < 6; ++i) {
        js_imu.q_rad[i] += js.q_rad[i] - motor.q_rad[i];
        js_imu.qd_radps[i] += js.qd_radps[i] - motor.qd_radps[i];
        js_imu.qdd_radps2[i] += js.qdd_radps2[i] - motor.qdd_radps2[i];
      }
    const std::span<const ExternalWrench> now(pushes.data(), active);
    const Measurement m = measure(js, js_imu, t, now);
    if (c.elastic.enabled) load = payload_load(js.q_rad, m.R_base_sensor, c, now);
    Vec6 w = m.wrench_sensor;
    out.stats.max_force_N = std::max(out.stats.max_force_N, w.head<3>().norm());
    out.stats.max_torque_Nm = std::max(out.stats.max_torque_Nm, w.tail<3>().norm());
    for (int i = 0; i < 6; ++i) {
      ft_noise[i] = c.noise.ft_ar1 * ft_noise[i] + ar1_gain * noise.normal();
      w[i] += (i < 3 ? c.noise.force_N : c.noise.torque_Nm) * ft_noise[i];
      if (c.noise.quantize)
        w[i] = kOmega191Resolution[i] * std::round(w[i] / kOmega191Resolution[i]);
    }
    s.force_sensor_N = w.head<3>();
    s.torque_sensor_Nm = w.tail<3>();

    const ImuTruth& imu = m.imu;
    s.specific_force_imu_mps2 = imu.specific_force_imu_mps2;
    s.angular_rate_imu_radps = imu.angular_rate_imu_radps;
    s.temperature_C = c.temperature.at(t);
    // The clean log: noise-free signals (the link's joints and pose when the robot is elastic),
    // the noisy wrench.
    formats::Sample& clean = out.clean_log.samples.emplace_back(s);
    if (c.elastic.enabled || c.noise.encoder_rad > 0.0) {
      clean.joints_rad = js.q_rad;
      set_nominal_pose(clean, js.q_rad, c);
    }
    bias.step();
    for (int i = 0; i < 3; ++i)
      s.specific_force_imu_mps2[i] += c.noise.accel_mps2 * noise.normal() + bias.accel_mps2[i];
    for (int i = 0; i < 3; ++i)
      s.angular_rate_imu_radps[i] += c.noise.gyro_radps * noise.normal() + bias.gyro_radps[i];

    const double z = lowest_point_z(js.q_rad, ws);
    out.stats.lowest_point_z_m = std::min(out.stats.lowest_point_z_m, z);
    if (z < c.floor_z_m) ++out.stats.samples_below_floor;

    out.log.samples.push_back(s);
    out.angular_accel_imu_radps2.push_back(imu.angular_accel_imu_radps2);
    if (progress && (k % report_every == 0 || k + 1 == n))
      progress(static_cast<double>(k + 1) / static_cast<double>(n));
  }
  out.stats.duration_s = static_cast<double>(n - 1) * c.period_s;
  return out;
}

}  // namespace zerog::sim
