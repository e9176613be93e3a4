// `zerog watch`: subscribes to zerog-rt's live telemetry (proto/telemetry.md) and prints, every
// N cycles, the state, the measured vs predicted wrench and the contact wrench; the model
// identity when it arrives, and health changes (state, fault, drops). --csv writes the wrench
// samples received with cycles.csv's column names (proto/loop.md), to compare offline.
#include <chrono>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "commands.hpp"
#include "dds/dds.h"
#include "zerog/formats/log.hpp"
#include "zerog/telemetry/config.hpp"
#include "zerog/telemetry/convert.hpp"

namespace zerog::cli {
namespace {

struct WatchArgs {
  telemetry::TelemetryConfig net;
  int every = 50;
  double duration_s = 0.0;
  std::string csv;
};

class Participant {
 public:
  explicit Participant(const telemetry::TelemetryConfig& c) {
    const std::string xml = telemetry::cyclone_xml(c);
    domain_ = dds_create_domain(static_cast<dds_domainid_t>(c.domain_id), xml.c_str());
    if (domain_ < 0)
      throw std::runtime_error(std::string("dds_create_domain failed: ") + dds_strretcode(domain_));
    participant_ =
        dds_create_participant(static_cast<dds_domainid_t>(c.domain_id), nullptr, nullptr);
    if (participant_ < 0)
      throw std::runtime_error(std::string("dds_create_participant failed: ") +
                               dds_strretcode(participant_));
  }
  ~Participant() {
    if (participant_ > 0) dds_delete(participant_);
    if (domain_ > 0) dds_delete(domain_);
  }
  /// A reader with the topic's QoS (proto/telemetry.md): streams best-effort, state reliable
  /// and transient-local.
  dds_entity_t reader(const dds_topic_descriptor_t* desc, const std::string& name, bool state) {
    dds_qos_t* q = dds_create_qos();
    if (state) {
      dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
      dds_qset_durability(q, DDS_DURABILITY_TRANSIENT_LOCAL);
      dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 16);
    } else {
      dds_qset_reliability(q, DDS_RELIABILITY_BEST_EFFORT, 0);
      dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 1024);
    }
    const dds_entity_t topic = dds_create_topic(participant_, desc, name.c_str(), q, nullptr);
    const dds_entity_t r = topic < 0 ? topic : dds_create_reader(participant_, topic, q, nullptr);
    dds_delete_qos(q);
    if (r < 0) throw std::runtime_error("cannot subscribe to " + name + ": " + dds_strretcode(r));
    return r;
  }

 private:
  dds_entity_t domain_ = 0, participant_ = 0;
};

/// Calls f(sample) for every valid sample waiting on `reader`.
template <typename T, typename F>
int take_each(dds_entity_t reader, F&& f) {
  void* samples[64] = {};
  dds_sample_info_t infos[64];
  int count = 0;
  for (;;) {
    const dds_return_t n = dds_take(reader, samples, infos, 64, 64);
    if (n <= 0) break;
    for (int i = 0; i < n; ++i)
      if (infos[i].valid_data) {
        f(*static_cast<const T*>(samples[i]));
        ++count;
      }
    dds_return_loan(reader, samples, n);
  }
  return count;
}

std::string join(const dds_sequence_string& s) {
  std::string out;
  for (std::uint32_t i = 0; i < s._length; ++i) out += (i ? "," : "") + std::string(s._buffer[i]);
  return out;
}

void append_numbers(std::string& out, const double* v, int n) {
  char buffer[32];
  for (int i = 0; i < n; ++i) {
    std::snprintf(buffer, sizeof buffer, ",%.17g", v[i]);
    out += buffer;
  }
}

int run_watch(const WatchArgs& a) {
  if (const Status st = telemetry::check_config(a.net); !st.ok()) {
    // The field as this command's option.
    const std::string& f = st.setting();
    const std::string option = f == "domain_id"      ? "--domain"
                               : f == "interface"    ? "--interface"
                               : f == "peers"        ? "--peer"
                               : f == "topic_prefix" ? "--prefix"
                                                     : "telemetry." + f;
    throw std::invalid_argument(option + ": " + st.message());
  }
  if (a.every < 1) throw std::invalid_argument("--every: must be at least 1");
  Participant p(a.net);
  const std::string& prefix = a.net.topic_prefix;
  const dds_entity_t wrench =
      p.reader(&zerog_telemetry_WrenchSample_desc, prefix + "wrench", false);
  const dds_entity_t health = p.reader(&zerog_telemetry_Health_desc, prefix + "health", true);
  const dds_entity_t model = p.reader(&zerog_telemetry_ModelIdentity_desc, prefix + "model", true);
  std::fprintf(stderr, "zerog watch: domain %d, topics %s*; Ctrl-C to stop\n", a.net.domain_id,
               prefix.c_str());

  std::string csv;
  if (!a.csv.empty()) {
    csv = "cycle,t_s,Fx_N,Fy_N,Fz_N,Mx_Nm,My_Nm,Mz_Nm,ft_samples,t_eval_s";
    for (const char* group : {"eval_", "pred_", "contact_"})
      for (const char* axis : {"Fx_N", "Fy_N", "Fz_N", "Mx_Nm", "My_Nm", "Mz_Nm"})
        csv += std::string(",") + group + axis;
    csv += ",model_status,flags\n";
  }
  const char* state = "?";
  std::uint8_t last_state = 0xFF, last_fault = 0xFF;
  std::uint64_t last_drops = 0, last_errors = 0, wrench_count = 0;
  const auto start = std::chrono::steady_clock::now();
  for (;;) {
    take_each<zerog_telemetry_ModelIdentity>(model, [](const zerog_telemetry_ModelIdentity& m) {
      std::printf("model: rig %s (%s), effects %s, network %s, file %s crc32 %08x\n", m.rig_name,
                  m.robot, join(m.effects).c_str(), m.has_network ? "yes" : "no", m.deploy_file,
                  m.deploy_crc32);
    });
    take_each<telemetry::HealthSample>(health, [&](const telemetry::HealthSample& h) {
      state = telemetry::state_code_name(h.state);
      if (h.state != last_state || h.fault != last_fault || h.telemetry_drops != last_drops ||
          h.write_errors != last_errors) {
        std::printf(
            "health: cycle %llu state %s fault %s, telemetry drops %llu, write errors %llu, "
            "datagrams lost %llu, robot lost %llu\n",
            static_cast<unsigned long long>(h.cycle), state, telemetry::fault_code_name(h.fault),
            static_cast<unsigned long long>(h.telemetry_drops),
            static_cast<unsigned long long>(h.write_errors),
            static_cast<unsigned long long>(h.datagrams_lost),
            static_cast<unsigned long long>(h.robot_lost));
        last_state = h.state;
        last_fault = h.fault;
        last_drops = h.telemetry_drops;
        last_errors = h.write_errors;
      }
    });
    take_each<telemetry::WrenchSample>(wrench, [&](const telemetry::WrenchSample& w) {
      ++wrench_count;
      if (w.cycle % static_cast<std::uint64_t>(a.every) == 0) {
        std::printf(
            "cycle %llu t %.3f s %s | F meas %.2f %.2f %.2f pred %.2f %.2f %.2f contact %.2f "
            "%.2f %.2f N | M meas %.3f %.3f %.3f pred %.3f %.3f %.3f contact %.3f %.3f %.3f "
            "N*m\n",
            static_cast<unsigned long long>(w.cycle), w.t_s, state, w.measured_at_eval[0],
            w.measured_at_eval[1], w.measured_at_eval[2], w.predicted[0], w.predicted[1],
            w.predicted[2], w.contact[0], w.contact[1], w.contact[2], w.measured_at_eval[3],
            w.measured_at_eval[4], w.measured_at_eval[5], w.predicted[3], w.predicted[4],
            w.predicted[5], w.contact[3], w.contact[4], w.contact[5]);
      }
      if (!a.csv.empty()) {
        csv += std::to_string(w.cycle);
        append_numbers(csv, &w.t_s, 1);
        append_numbers(csv, w.measured, 6);
        csv += "," + std::to_string(w.ft_samples);
        append_numbers(csv, &w.t_eval_s, 1);
        append_numbers(csv, w.measured_at_eval, 6);
        append_numbers(csv, w.predicted, 6);
        append_numbers(csv, w.contact, 6);
        csv += "," + std::to_string(w.model_status) + "," + std::to_string(w.flags) + "\n";
      }
    });
    std::fflush(stdout);
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (a.duration_s > 0.0 && elapsed >= a.duration_s) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  std::fprintf(stderr, "zerog watch: %llu wrench samples\n",
               static_cast<unsigned long long>(wrench_count));
  if (!a.csv.empty()) formats::write_file_atomic(a.csv, csv);
  return 0;
}

}  // namespace

void add_watch_command(CLI::App& app) {
  auto args = std::make_shared<WatchArgs>();
  CLI::App* cmd = app.add_subcommand(
      "watch", "print zerog-rt's live telemetry (DDS): measured vs predicted, state, health");
  cmd->add_option("--domain", args->net.domain_id, "DDS domain id")->default_val(0);
  cmd->add_option("--interface", args->net.interface, "network interface, e.g. lo");
  cmd->add_option("--peer", args->net.peers,
                  "unicast discovery peer (repeatable); with peers, multicast is off");
  cmd->add_option("--prefix", args->net.topic_prefix, "topic prefix")->default_val("zerog/");
  cmd->add_option("--every", args->every, "print one line every N cycles")->default_val(50);
  cmd->add_option("--duration", args->duration_s, "stop after S seconds (0: run until killed)");
  cmd->add_option("--csv", args->csv,
                  "write the wrench samples received here (cycles.csv columns)");
  cmd->callback([args] {
    args->net.allow_multicast = args->net.peers.empty();
    const int rc = run_watch(*args);
    if (rc != 0) throw CLI::RuntimeError(rc);
  });
}

}  // namespace zerog::cli
