// Runtime::summary_json: the counters of every owner (the cycle, the cycle thread, each device,
// the rings, the state machine, the recorder, telemetry, lockstep, Modbus) as one JSON document
// (proto/rt_config.md, "Summary"). One function per owner; summary_json assembles them.
#include <nlohmann/json.hpp>

#include "zerog/rt/runtime.hpp"

namespace zerog::rt {

namespace {

using nlohmann::json;

// Names of rsi::ParseStatus, in enum order (RobotLinkCounters::malformed_by_status).
constexpr const char* kParseStatusNames[] = {"ok",
                                             "too_long",
                                             "truncated",
                                             "syntax",
                                             "unsupported",
                                             "wrong_root",
                                             "unexpected_content",
                                             "too_deep",
                                             "duplicate_element",
                                             "missing_element",
                                             "missing_attribute",
                                             "unknown_attribute",
                                             "duplicate_attribute",
                                             "bad_number"};
static_assert(std::size(kParseStatusNames) == rtio::kParseStatusCount,
              "a ParseStatus was added: name it here");

nlohmann::json latency_json(const LatencyHistogram& h) {
  return {{"count", h.count()},
          {"median", h.quantile(0.5)},
          {"p99", h.quantile(0.99)},
          {"p99_9", h.quantile(0.999)},
          {"max", h.max()}};
}

template <typename Ring>
nlohmann::json ring_json(const Ring& r) {
  return {{"capacity", Ring::capacity()},
          {"pushed", r.pushed()},
          {"popped", r.popped()},
          {"dropped", r.dropped()}};
}

json cycles_json(const loop::CycleCounters& c) {
  return {{"messages", c.messages},
          {"robot_timeouts", c.robot_timeouts},
          {"robot_malformed", c.robot_malformed},
          {"ipoc_gaps", c.ipoc_gaps},
          {"datagrams_lost", c.datagrams_lost},
          {"ipoc_stale", c.ipoc_stale},
          {"ft_samples", c.ft_samples},
          {"ft_invalid", c.ft_invalid},
          {"ft_held_cycles", c.ft_held_cycles},
          {"imu_samples", c.imu_samples},
          {"imu_invalid", c.imu_invalid},
          {"imu_held_cycles", c.imu_held_cycles},
          {"sample_overflow", c.sample_overflow},
          {"model_saturated", c.model_saturated},
          {"commands_refused", c.commands_refused},
          {"black_boxes_lost", c.black_boxes_lost},
          {"poses_from_joints", c.poses_from_joints},
          {"pose_disagreements", c.pose_disagreements},
          {"poses_missing", c.poses_missing},
          {"temperature_stale_cycles", c.temperature_stale_cycles}};
}

json cycle_thread_json(const CycleThreadCounters& t) {
  return {{"receive_timeouts", t.receive_timeouts},   {"receive_malformed", t.receive_malformed},
          {"receive_errors", t.receive_errors},       {"replies_ok", t.replies_ok},
          {"replies_failed", t.replies_failed},       {"axis_replies", t.axis_replies},
          {"samples_discarded", t.samples_discarded}, {"black_box_releases", t.black_box_releases}};
}

json robot_json(const rtio::RobotLinkCounters& r) {
  json by_status = json::object();
  for (std::size_t i = 0; i < rtio::kParseStatusCount; ++i) {
    if (r.malformed_by_status[i] != 0) by_status[kParseStatusNames[i]] = r.malformed_by_status[i];
  }
  return {{"datagrams", r.datagrams},
          {"messages", r.messages},
          {"foreign", r.foreign},
          {"malformed", r.malformed},
          {"malformed_by_status", by_status},
          {"timeouts", r.timeouts},
          {"io_errors", r.io_errors},
          {"replies", r.replies},
          {"reply_would_block", r.reply_would_block},
          {"reply_errors", r.reply_errors},
          {"bad_corrections", r.bad_corrections},
          {"discarded_at_start", r.discarded}};
}

json ft_json(const rtio::FtCounters& f, const SensorThreadCounters& thread) {
  return {{"requests", f.requests},
          {"samples", f.samples},
          {"samples_warning", f.samples_warning},
          {"samples_critical", f.samples_critical},
          {"samples_saturated", f.samples_saturated},
          {"timeouts", f.timeouts},
          {"stale_frames", f.stale_frames},
          {"stray_frames", f.stray_frames},
          {"wrong_length", f.wrong_length},
          {"out_of_order", f.out_of_order},
          {"dropped_incomplete", f.dropped_incomplete},
          {"late_samples", f.late_samples},
          {"overtaken", f.overtaken},
          {"error_frames", f.error_frames},
          {"kernel_drops", f.kernel_drops},
          {"bad_length", f.bad_length},
          {"tx_would_block", f.tx_would_block},
          {"io_errors", f.io_errors},
          {"thermistor_requests", f.thermistor_requests},
          {"thermistor_readings", f.thermistor_readings},
          {"thermistor_lost", f.thermistor_lost},
          {"thermistor_expired", f.thermistor_expired},
          {"thermistor_wrong_length", f.thermistor_wrong_length},
          {"thermistor_unrequested", f.thermistor_unrequested},
          {"thread_reads", thread.ft_reads},
          {"thread_overruns", thread.ft_overruns}};
}

json imu_json(const rtio::ImuCounters& i, const SensorThreadCounters& thread) {
  return {{"samples", i.samples},
          {"invalid_samples", i.invalid_samples},
          {"bytes_read", i.bytes_read},
          {"bytes_skipped", i.bytes_skipped},
          {"crc_failures", i.crc_failures},
          {"sync_losses", i.sync_losses},
          {"counter_gaps", i.counter_gaps},
          {"datagrams_missed", i.datagrams_missed},
          {"timeouts", i.timeouts},
          {"disconnects", i.disconnects},
          {"io_errors", i.io_errors},
          {"thread_reads", thread.imu_reads},
          {"thread_disconnects", thread.imu_disconnects},
          {"reopen_attempts", thread.imu_reopen_attempts},
          {"reopens", thread.imu_reopens}};
}

json transitions_json(const loop::StateMachine& sm) {
  json transitions = json::array();
  for (std::size_t i = 0; i < sm.log_size(); ++i) {
    const loop::Transition& tr = sm.log_at(i);
    json j = {
        {"cycle", tr.cycle}, {"from", loop::state_name(tr.from)}, {"to", loop::state_name(tr.to)}};
    if (tr.by_fault) {
      j["fault"] = loop::fault_name(tr.fault);
    } else {
      j["command"] = loop::command_name(tr.command);
    }
    transitions.push_back(j);
  }
  return transitions;
}

json telemetry_json(const telemetry::TelemetryChannel& channel) {
  const telemetry::ChannelCounters tc = channel.counters();
  return {{"domain_id", channel.config().domain_id},   {"records_offered", tc.records_offered},
          {"records_published", tc.records_published}, {"dropped", tc.telemetry_drops},
          {"write_errors", tc.write_errors},           {"health_published", tc.health_published}};
}

json modbus_json(const modbus::ModbusServer& server) {
  const modbus::ServerCounters m = server.counters();
  json exceptions = json::object();
  for (std::size_t code = 1; code < m.exceptions.size(); ++code) {
    if (m.exceptions[code] != 0) exceptions[std::to_string(code)] = m.exceptions[code];
  }
  return {{"port", server.port()},
          {"requests", m.requests},
          {"replies", m.replies},
          {"exceptions_by_code", exceptions},
          {"writes_accepted", m.writes_accepted},
          {"writes_refused", m.writes_refused},
          {"commands_accepted", m.commands_accepted},
          {"clients_accepted", m.clients_accepted},
          {"clients_refused_allowlist", m.clients_refused_allowlist},
          {"clients_refused_limit", m.clients_refused_limit},
          {"clients_closed", m.clients_closed},
          {"request_timeouts", m.request_timeouts},
          {"idle_timeouts", m.idle_timeouts},
          {"framing_errors", m.framing_errors},
          {"send_errors", m.send_errors}};
}

json devices_json(const RuntimeDevices& devices, const SensorThreadCounters& threads) {
  json out = json::object();
  out["robot"] = robot_json(devices.robot->counters());
  if (devices.ft != nullptr) out["ft"] = ft_json(devices.ft->counters(), threads);
  if (devices.imu != nullptr) out["imu"] = imu_json(devices.imu->counters(), threads);
  return out;
}

/// null when nothing is recorded.
json recording_json(const Recorder* recorder, const std::string& error,
                    std::uint64_t records_dropped) {
  if (recorder == nullptr || !recorder->recording()) return nullptr;
  const RecorderCounters& rc = recorder->counters();
  return {{"log", recorder->log_path().string()},
          {"cycles", recorder->cycles_path().string()},
          {"records", rc.records},
          {"log_rows", rc.log_rows},
          {"skipped_stale", rc.skipped_stale},
          {"skipped_no_samples", rc.skipped_no_samples},
          {"skipped_no_temperature", rc.skipped_no_temperature},
          {"rejected", rc.rejected},
          {"records_dropped", records_dropped},
          {"error", error}};
}

json lockstep_json(const LockstepCounters& l, std::uint64_t bad_messages) {
  return {{"events", l.events},
          {"datagram_events", l.datagram_events},
          {"timeout_events", l.timeout_events},
          {"receive_retries", l.receive_retries},
          {"sensor_waits_over", l.sensor_waits_over},
          {"imu_rebases", l.imu_rebases},
          {"imu_reopen_attempts", l.imu_reopen_attempts},
          {"bad_messages", bad_messages},
          {"errors", l.errors},
          {"ended", l.ended},
          {"error", l.error != nullptr ? l.error : ""}};
}

}  // namespace

std::string Runtime::summary_json() const {
  const loop::StateMachine& sm = cycle_.state_machine();
  json boxes = json::array();
  for (const auto& p : recorder_side_.black_box_paths) boxes.push_back(p.string());
  json out = {{"format", "zerog-rt-summary"},
              {"version", 1},
              {"state", loop::state_name(sm.state())},
              {"fault", loop::fault_name(sm.fault())},
              {"cycles", cycles_json(cycle_.counters())},
              {"cycle_thread", cycle_thread_json(cycle_side_.counters)},
              {"devices", devices_json(devices_, sensors_.counters)},
              {"rings",
               {{"ft", ring_json(*handover_.ft)},
                {"imu", ring_json(*handover_.imu)},
                {"records", ring_json(*handover_.records)}}},
              {"transitions", transitions_json(sm)},
              {"transitions_total", sm.total_transitions()},
              {"compute_ns", latency_json(cycle_side_.compute_ns)},
              {"reply_latency_ns", latency_json(cycle_side_.reply_ns)},
              {"black_box_dumps", boxes},
              {"recording", recording_json(recorder_side_.recorder.get(), recorder_side_.error,
                                           handover_.records->dropped())}};
  if (supervision_.telemetry != nullptr) out["telemetry"] = telemetry_json(*supervision_.telemetry);
  if (devices_.lockstep != nullptr) {
    out["lockstep"] = lockstep_json(lockstep_.counters, devices_.lockstep->bad_messages());
  }
  if (supervision_.modbus != nullptr) out["modbus"] = modbus_json(*supervision_.modbus);
  return out.dump(1) + "\n";
}

}  // namespace zerog::rt
