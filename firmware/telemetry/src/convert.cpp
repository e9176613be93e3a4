#include "zerog/telemetry/convert.hpp"

#include <cstddef>

#include "zerog/proto/rsi_si.hpp"

namespace zerog::telemetry {

namespace {

// The codes of proto/telemetry.idl are the firmware enums' values.
static_assert(static_cast<int>(loop::State::idle) == 0 &&
                  static_cast<int>(loop::State::collecting) == 1 &&
                  static_cast<int>(loop::State::zero_g) == 2 &&
                  static_cast<int>(loop::State::fault) == 3,
              "loop::State changed: update proto/telemetry.idl and telemetry.md");
static_assert(static_cast<int>(loop::Fault::none) == 0 &&
                  static_cast<int>(loop::Fault::ft_stale) == 1 &&
                  static_cast<int>(loop::Fault::ft_critical) == 2 &&
                  static_cast<int>(loop::Fault::ft_saturated) == 3 &&
                  static_cast<int>(loop::Fault::imu_stale) == 4 &&
                  static_cast<int>(loop::Fault::robot_late) == 5 &&
                  static_cast<int>(loop::Fault::contact_over_limit) == 6 &&
                  static_cast<int>(loop::Fault::model_invalid) == 7,
              "loop::Fault changed: update proto/telemetry.idl and telemetry.md");
static_assert(static_cast<int>(infer::StatusCode::ok) == 0 &&
                  static_cast<int>(infer::StatusCode::saturated) == 1 &&
                  static_cast<int>(infer::StatusCode::non_finite) == 2 &&
                  static_cast<int>(infer::StatusCode::not_configured) == 3,
              "infer::StatusCode changed: update proto/telemetry.idl and telemetry.md");
constexpr std::uint8_t kStateCount = 4;
constexpr std::uint8_t kFaultCount = 8;

template <std::size_t N, typename Source>
void copy_to(double (&out)[N], const Source& in) {
  for (std::size_t i = 0; i < N; ++i) out[i] = in[static_cast<decltype(in.size())>(i)];
}

void copy_quat(double (&out)[4], const Eigen::Quaterniond& q) {
  out[0] = q.w();
  out[1] = q.x();
  out[2] = q.y();
  out[3] = q.z();
}

}  // namespace

WrenchSample to_wrench(const loop::CycleRecord& r) noexcept {
  WrenchSample s{};
  s.cycle = r.cycle;
  s.t_s = r.t_s;
  copy_to(s.measured, r.wrench_measured);
  s.ft_samples = r.ft_samples;
  s.t_eval_s = r.t_eval_s;
  copy_to(s.measured_at_eval, r.wrench_at_eval);
  copy_to(s.predicted, r.predicted);
  copy_to(s.contact, r.contact);
  s.model_status = static_cast<std::uint8_t>(r.model_status);
  s.flags = r.flags;
  return s;
}

ImuSample to_imu(const loop::CycleRecord& r) noexcept {
  ImuSample s{};
  s.cycle = r.cycle;
  s.t_s = r.t_s;
  copy_to(s.specific_force_imu_mps2, r.specific_force_imu);
  copy_to(s.rate_imu_radps, r.rate_imu);
  s.imu_samples = r.imu_samples;
  return s;
}

RobotSample to_robot(const loop::CycleRecord& r) noexcept {
  RobotSample s{};
  s.cycle = r.cycle;
  s.t_s = r.t_s;
  s.ipoc = r.ipoc;
  copy_to(s.joints_rad, r.joints_rad);
  copy_to(s.p_base_sensor_m, r.p_base_sensor_m);
  copy_quat(s.q_base_sensor_wxyz, r.q_base_sensor);
  return s;
}

CommandSample to_command(const loop::CycleRecord& r, const control::BodyParams& body) noexcept {
  CommandSample s{};
  s.cycle = r.cycle;
  s.t_s = r.t_s;
  s.dt_s = r.dt_s;
  // The record's reply is SI; RKorr's angles are KUKA's A, B, C (in rad here), from the RSI
  // border's one function. Each part is zero unless the reply is of its kind.
  using Kind = samples::RobotCorrection::Kind;
  s.axis_reply = r.reply.axis();
  const bool cartesian = r.reply.kind == Kind::cartesian;
  for (std::size_t i = 0; i < 3; ++i)
    s.rkorr_translation_m[i] = cartesian ? r.reply.translation_m[i] : 0.0;
  copy_to(s.rkorr_abc_rad, proto::rsi::rkorr_abc_rad(r.reply));
  for (std::size_t i = 0; i < 6; ++i) s.akorr_rad[i] = s.axis_reply ? r.reply.axes_rad[i] : 0.0;
  const control::VirtualBody virtual_body(body, r.body);
  copy_to(s.v_world_mps, r.body.v_world_mps);
  copy_to(s.omega_world_radps, virtual_body.omega_world());
  s.limit_flags = r.limit_flags;
  return s;
}

BodySample to_body(const loop::CycleRecord& r, const control::BodyParams& body) noexcept {
  BodySample s{};
  s.cycle = r.cycle;
  s.t_s = r.t_s;
  const control::VirtualBody virtual_body(body, r.body);
  copy_to(s.p_world_m, r.body.p_world_m);
  copy_quat(s.q_world_body_wxyz, r.body.q_world_body);
  copy_to(s.v_world_mps, r.body.v_world_mps);
  copy_to(s.omega_world_radps, virtual_body.omega_world());
  copy_to(s.momentum_world_kgmps, virtual_body.linear_momentum_world());
  copy_to(s.L_world_kgm2ps, r.body.L_world_kgm2ps);
  s.kinetic_energy_J = virtual_body.kinetic_energy_J();
  s.mass_kg = body.mass_kg;
  return s;
}

TimingSample to_timing(const loop::CycleRecord& r, double period_s, double nominal_period_s,
                       std::uint64_t datagrams_lost) noexcept {
  TimingSample s{};
  s.cycle = r.cycle;
  s.t_s = r.t_s;
  s.ipoc = r.ipoc;
  s.dt_s = r.dt_s;
  s.period_s = period_s;
  s.jitter_s = period_s > 0.0 ? period_s - nominal_period_s : 0.0;
  s.compute_s = static_cast<double>(r.compute_ns) * 1e-9;
  s.ipoc_gap = (r.flags & loop::kIpocGap) != 0;
  s.robot_late = (r.flags & loop::kRobotDelayGrew) != 0;
  s.robot_lost = (r.flags & loop::kRobotLost) != 0;
  s.datagrams_lost = datagrams_lost;
  return s;
}

HealthSample to_health(std::uint64_t health_seq, const loop::CycleRecord* newest,
                       const ChannelCounters& channel, const RuntimeHealth& runtime) noexcept {
  HealthSample s{};
  s.health_seq = health_seq;
  if (newest != nullptr) {
    s.cycle = newest->cycle;
    s.t_s = newest->t_s;
    s.state = static_cast<std::uint8_t>(newest->state);
    s.fault = static_cast<std::uint8_t>(newest->fault);
    s.flags = newest->flags;
  }
  s.records_offered = channel.records_offered;
  s.records_published = channel.records_published;
  s.telemetry_drops = channel.telemetry_drops;
  s.write_errors = channel.write_errors;
  s.robot_lost = runtime.robot_lost;
  s.datagrams_lost = runtime.datagrams_lost;
  s.ipoc_gaps = runtime.ipoc_gaps;
  s.ft_held_cycles = runtime.ft_held_cycles;
  s.imu_held_cycles = runtime.imu_held_cycles;
  s.replies_failed = runtime.replies_failed;
  s.record_drops = runtime.record_drops;
  s.commands_refused = runtime.commands_refused;
  s.transitions = runtime.transitions;
  s.poses_from_joints = runtime.poses_from_joints;
  s.pose_disagreements = runtime.pose_disagreements;
  s.poses_missing = runtime.poses_missing;
  return s;
}

ModelIdentityInfo model_identity(const infer::DeployedModel& model, std::string deploy_file,
                                 std::uint32_t deploy_crc32) {
  ModelIdentityInfo info;
  info.rig_name = model.rig.name;
  info.robot = model.rig.robot;
  for (model::Effect e : model::kAllEffects)
    if (model.physics.effects.has(e)) info.effects.emplace_back(model::info(e).name);
  if (model.network) {
    const infer::DeployedNetwork& n = *model.network;
    info.has_network = true;
    for (int w : n.shape.width) info.network_width.push_back(w);
    for (model::Activation a : n.shape.activation)
      info.network_activations.emplace_back(model::activation_name(a));
    for (model::Feature f : n.features) info.network_features.emplace_back(model::feature_name(f));
    for (int axis : n.output_axes)
      info.network_outputs.emplace_back(axis >= 0 && axis < 6 ? infer::kAxisNames[axis] : "?");
    info.weight_bits = n.quantised.weight_bits;
  }
  info.deploy_file = std::move(deploy_file);
  info.deploy_crc32 = deploy_crc32;
  info.provenance_json = model.provenance_json;
  return info;
}

zerog_telemetry_ModelIdentity model_identity_sample(const ModelIdentityInfo& info,
                                                    std::vector<char*>& storage) {
  const std::size_t n_strings = info.effects.size() + info.network_activations.size() +
                                info.network_features.size() + info.network_outputs.size();
  storage.clear();
  storage.reserve(n_strings);  // no reallocation below: the pointers into it stay valid
  const auto strings = [&storage](const std::vector<std::string>& in) {
    dds_sequence_string seq{};
    seq._maximum = seq._length = static_cast<std::uint32_t>(in.size());
    seq._buffer = in.empty() ? nullptr : storage.data() + storage.size();
    for (const std::string& s : in) storage.push_back(const_cast<char*>(s.c_str()));
    seq._release = false;
    return seq;
  };
  zerog_telemetry_ModelIdentity s{};
  // dds_write only reads the sample: the casts drop const for the generated C types.
  s.rig_name = const_cast<char*>(info.rig_name.c_str());
  s.robot = const_cast<char*>(info.robot.c_str());
  s.effects = strings(info.effects);
  s.has_network = info.has_network;
  s.network_width._maximum = s.network_width._length =
      static_cast<std::uint32_t>(info.network_width.size());
  s.network_width._buffer = const_cast<std::int32_t*>(info.network_width.data());
  s.network_width._release = false;
  s.network_activations = strings(info.network_activations);
  s.network_features = strings(info.network_features);
  s.network_outputs = strings(info.network_outputs);
  s.weight_bits = info.weight_bits;
  s.deploy_file = const_cast<char*>(info.deploy_file.c_str());
  s.deploy_crc32 = info.deploy_crc32;
  s.provenance_json = const_cast<char*>(info.provenance_json.c_str());
  return s;
}

const char* state_code_name(std::uint8_t code) noexcept {
  return code < kStateCount ? loop::state_name(static_cast<loop::State>(code)) : "?";
}

const char* fault_code_name(std::uint8_t code) noexcept {
  return code < kFaultCount ? loop::fault_name(static_cast<loop::Fault>(code)) : "?";
}

}  // namespace zerog::telemetry
