#include "zerog/emu/physics.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace zerog::emu {

const char* push_profile_name(PushProfile profile) {
  switch (profile) {
    case PushProfile::half_sine:
      return "half_sine";
    case PushProfile::constant:
      return "constant";
  }
  return "?";
}

double Push::factor(double t_s) const {
  if (!(t_s >= start_s && t_s < start_s + duration_s)) return 0.0;
  if (profile == PushProfile::constant) return 1.0;
  return std::sin(std::numbers::pi * std::min((t_s - start_s) / duration_s, 1.0));
}

double Push::factor_integral_s() const {
  return profile == PushProfile::constant ? duration_s : duration_s * 2.0 / std::numbers::pi;
}

namespace {

std::vector<Push> checked(std::vector<Push> pushes) {
  if (pushes.size() > kMaxPushes)
    throw std::invalid_argument("at most " + std::to_string(kMaxPushes) + " pushes, got " +
                                std::to_string(pushes.size()));
  for (std::size_t k = 0; k < pushes.size(); ++k) {
    const Push& p = pushes[k];
    const std::string which = "push " + std::to_string(k + 1) + ": ";
    if (!(std::isfinite(p.start_s) && p.start_s >= 0.0))
      throw std::invalid_argument(which + "start must be finite and >= 0");
    if (!(std::isfinite(p.duration_s) && p.duration_s > 0.0))
      throw std::invalid_argument(which + "duration must be finite and > 0");
    if (!p.force_world_N.allFinite() || !p.torque_world_Nm.allFinite() ||
        (p.point_sensor_m && !p.point_sensor_m->allFinite()))
      throw std::invalid_argument(which + "force, torque and point must be finite");
  }
  return pushes;
}

}  // namespace

PayloadPhysics::PayloadPhysics(sim::SimConfig config, std::vector<Push> pushes,
                               double physics_rate_hz)
    : simulator_(std::move(config)),
      pushes_(checked(std::move(pushes))),
      rate_hz_(physics_rate_hz),
      arm_(simulator_.config().elastic) {
  if (!(std::isfinite(rate_hz_) && rate_hz_ > 0.0))
    throw std::invalid_argument("physics rate must be positive");
  delay_steps_ = static_cast<std::size_t>(std::llround(simulator_.imu_delay_s() * rate_hz_));
  history_.assign(delay_steps_ + 1, sim::JointState{});
  integrals_.assign(pushes_.size(), PushIntegral{});
  rng_.seed(simulator_.config().seed * 0x9E3779B97F4A7C15ull + 0x656D75ull);  // "emu"
}

std::size_t PayloadPhysics::active_pushes(double t_s, ActivePushes& active) const {
  std::size_t n = 0;
  const Eigen::Vector3d& com = simulator_.config().payload.com_sensor_m;
  for (std::size_t k = 0; k < pushes_.size(); ++k) {
    const double f = pushes_[k].factor(t_s);
    if (f == 0.0) continue;
    active[n] = {f * pushes_[k].force_world_N, pushes_[k].point_sensor_m.value_or(com),
                 f * pushes_[k].torque_world_Nm};
    ++n;
  }
  return n;
}

PhysicsSample PayloadPhysics::evaluate(const sim::JointState& js, const sim::JointState& js_imu,
                                       double t_s) const {
  ActivePushes active;
  return evaluate(js, js_imu, t_s, {active.data(), active_pushes(t_s, active)});
}

PhysicsSample PayloadPhysics::evaluate(const sim::JointState& js, const sim::JointState& js_imu,
                                       double t_s,
                                       std::span<const sim::ExternalWrench> active) const {
  const Eigen::Vector3d& com = simulator_.config().payload.com_sensor_m;
  PhysicsSample out;
  out.truth = simulator_.measure(js, js_imu, t_s, active);
  for (std::size_t i = 0; i < active.size(); ++i) {
    const Eigen::Vector3d lever_base_m = out.truth.R_base_sensor * (active[i].point_sensor_m - com);
    out.push_force_base_N += active[i].force_base_N;
    out.push_torque_com_base_Nm +=
        lever_base_m.cross(active[i].force_base_N) + active[i].torque_base_Nm;
  }
  for (int i = 0; i < 6; ++i) out.wrench_sensor_noisy[i] = out.truth.wrench_sensor[i];
  return out;
}

PhysicsSample PayloadPhysics::step(const sim::JointState& js) {
  const double t_s = static_cast<double>(steps_) / rate_hz_;
  const double h = 1.0 / rate_hz_;
  const sim::SimConfig& c = simulator_.config();
  // The payload moves with the link side (sim/elastic.hpp); the servo's js is the motor side.
  sim::JointState link = js;
  ActivePushes active;
  const std::span<const sim::ExternalWrench> now(active.data(), active_pushes(t_s, active));
  if (arm_.enabled()) {
    if (!settled_) {  // the static sag under the load it changes
      for (int pass = 0; pass < 3; ++pass) {
        sim::JointState sagged = js;
        for (std::size_t i = 0; i < 6; ++i) sagged.q_rad[i] += arm_.deflection_rad()[i];
        load_ = sim::payload_load(sagged.q_rad,
                                  evaluate(sagged, sagged, t_s, now).truth.R_base_sensor, c, now);
        arm_.settle(t_s, load_);
      }
      settled_ = true;
    }
    link = arm_.step(js, h, load_);
  }
  const std::size_t n = history_.size();
  history_[steps_ % n] = link;
  // The state delay_steps_ ago (the first state until there is one that old).
  const std::uint64_t back = steps_ >= delay_steps_ ? steps_ - delay_steps_ : 0;
  const sim::JointState& js_imu = history_[back % n];
  PhysicsSample s = evaluate(link, js_imu, t_s, now);
  if (arm_.enabled()) load_ = sim::payload_load(link.q_rad, s.truth.R_base_sensor, c, now);
  const sim::NoiseConfig& noise = c.noise;
  for (int i = 0; i < 6; ++i)
    s.wrench_sensor_noisy[i] += (i < 3 ? noise.force_N : noise.torque_Nm) * normal_(rng_);

  const Eigen::Vector3d& com = c.payload.com_sensor_m;
  for (std::size_t k = 0; k < pushes_.size(); ++k) {
    const double f = pushes_[k].factor(t_s);
    if (f == 0.0) continue;
    const Eigen::Vector3d force = f * pushes_[k].force_world_N;
    const Eigen::Vector3d lever_base_m =
        s.truth.R_base_sensor * (pushes_[k].point_sensor_m.value_or(com) - com);
    integrals_[k].impulse_N_s += force * h;
    integrals_[k].angular_impulse_com_Nms +=
        (lever_base_m.cross(force) + f * pushes_[k].torque_world_Nm) * h;
  }
  ++steps_;
  return s;
}

}  // namespace zerog::emu
