// zerog-telemetry-replay: publishes cycle records through a real TelemetryChannel, for testing
// subscribers (tests/telemetry/, `zerog watch`) without a robot. The records are either
// generated (--generate N: a scripted idle → zero-g push → fault run, written with
// --write-csv in the recorder's cycles.csv format so subscribers can be checked against it) or
// read from a zerog-rt cycles.csv (--csv; zerog/formats/cycles_csv.hpp, beside its writer). Paced
// at --period-s per record.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "zerog/formats/cycles_csv.hpp"
#include "zerog/proto/rsi_si.hpp"
#include "zerog/telemetry/channel.hpp"

namespace {

using zerog::loop::CycleRecord;

CycleRecord scripted_record(std::uint64_t cycle, double period_s) {
  CycleRecord r;
  const double t = static_cast<double>(cycle - 1) * period_s;
  const double k = static_cast<double>(cycle);
  r.cycle = cycle;
  r.ipoc = 1'000'000 + (cycle - 1) * static_cast<std::uint64_t>(std::lround(period_s * 1000.0));
  r.t_s = t;
  r.dt_s = period_s;
  r.state = cycle < 40 ? zerog::loop::State::idle : zerog::loop::State::zero_g;
  r.fault = zerog::loop::Fault::none;
  r.flags = cycle % 17 == 0 ? zerog::loop::kIpocGap : 0u;
  r.limit_flags = cycle % 23 == 0 ? 4u : 0u;
  r.model_status = zerog::infer::StatusCode::ok;
  for (int i = 0; i < 6; ++i) r.joints_rad[i] = 0.1 * (i + 1) + 0.001 * std::sin(0.1 * k + i);
  r.p_base_sensor_m = Eigen::Vector3d(1.2 + 1e-4 * k, -0.1, 1.5);
  r.q_base_sensor = Eigen::Quaterniond(Eigen::AngleAxisd(0.3 + 1e-3 * k, Eigen::Vector3d::UnitZ()));
  for (int i = 0; i < 6; ++i) {
    r.wrench_measured[i] = 10.0 * (i + 1) + std::sin(0.05 * k + i);
    r.wrench_at_eval[i] = 10.0 * (i + 1) + std::sin(0.05 * (k - 2) + i);
    r.predicted[i] = 10.0 * (i + 1) + 0.1 * std::cos(0.07 * k + i);
    r.contact[i] = r.wrench_at_eval[i] - r.predicted[i];
  }
  for (int i = 0; i < 3; ++i) {
    r.specific_force_imu[i] = (i == 2 ? 9.81 : 0.0) + 0.01 * std::sin(0.2 * k + i);
    r.rate_imu[i] = 0.002 * std::cos(0.3 * k + i);
  }
  r.ft_samples = 2;
  r.imu_samples = static_cast<std::uint16_t>(8 + cycle % 2);
  r.t_eval_s = t - 2.0 * period_s;
  zerog::proto::rsi::Reply rkorr;  // an RKorr in the wire's units (mm, degrees), kept in SI
  rkorr.ipoc = r.ipoc;
  rkorr.has_rkorr = true;
  rkorr.rkorr = {0.01 * std::sin(0.1 * k), -0.02, 0.005, 0.001 * k, -0.002, 0.0};
  r.reply = zerog::proto::rsi::correction_from_reply(rkorr);
  r.body.p_world_m = Eigen::Vector3d(1.0 + 1e-4 * k, 0.2, 1.4);
  r.body.q_world_body =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.01 * k, Eigen::Vector3d(1, 2, 3).normalized()));
  r.body.v_world_mps = Eigen::Vector3d(0.025, -0.001 * std::sin(k), 0.0);
  r.body.L_world_kgm2ps = Eigen::Vector3d(0.1, 0.02 * std::cos(0.1 * k), -0.05);
  r.compute_ns = 20'000 + static_cast<std::int64_t>(cycle % 7) * 1000;
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"zerog-telemetry-replay: publish cycle records over DDS (proto/telemetry.md)"};
  zerog::telemetry::TelemetryConfig config;
  int generate = 0;
  std::string csv_in, csv_out;
  double period_s = 0.004, wait_s = 5.0, linger_s = 0.5, mass_kg = 100.0;
  int wait_subscribers = 0;
  bool no_multicast = false;
  app.add_option("--domain", config.domain_id, "DDS domain id");
  app.add_option("--interface", config.interface, "network interface, e.g. lo");
  app.add_option("--peer", config.peers, "unicast discovery peer (repeatable)");
  app.add_flag("--no-multicast", no_multicast, "multicast off (needs --peer)");
  app.add_option("--health-period", config.health_period_s, "health period (s)");
  auto* gen = app.add_option("--generate", generate, "publish N scripted records");
  auto* csv = app.add_option("--csv", csv_in, "publish the records of a zerog-rt cycles.csv");
  gen->excludes(csv);
  app.add_option("--write-csv", csv_out, "write the generated records as cycles.csv here");
  app.add_option("--period-s", period_s, "time between records (s; 0: as fast as possible)");
  app.add_option("--mass-kg", mass_kg, "virtual body mass (inertia 5 kg·m² · identity)");
  app.add_option("--wait-subscribers", wait_subscribers,
                 "wait (at most --wait-s) until this many readers matched before publishing");
  app.add_option("--wait-s", wait_s, "longest wait for subscribers (s)");
  app.add_option("--linger-s", linger_s, "keep the publisher up after the last record (s)");
  CLI11_PARSE(app, argc, argv);
  config.allow_multicast = !no_multicast;
  if (generate <= 0 && csv_in.empty()) {
    std::cerr << "zerog-telemetry-replay: give --generate N or --csv FILE\n";
    return 2;
  }
  try {
    std::vector<CycleRecord> records;
    if (!csv_in.empty()) {
      records = zerog::formats::read_cycles_csv(csv_in);
    } else {
      for (int i = 1; i <= generate; ++i)
        records.push_back(
            scripted_record(static_cast<std::uint64_t>(i), period_s > 0 ? period_s : 0.004));
      if (!records.empty()) records.back().state = zerog::loop::State::fault;
      if (!records.empty()) records.back().fault = zerog::loop::Fault::contact_over_limit;
    }
    if (!csv_out.empty()) {
      std::string text;
      zerog::formats::append_record_header(text);
      for (const CycleRecord& r : records) zerog::formats::append_record_row(r, text);
      std::ofstream out(csv_out, std::ios::binary | std::ios::trunc);
      out << text;
      if (!out) throw std::runtime_error(csv_out + ": cannot be written");
    }
    zerog::infer::DeployedModel model;
    model.rig.name = "replay-rig";
    model.rig.robot = "KR 210 R2700";
    model.physics.effects = zerog::model::kDefaultModel;
    model.provenance_json = R"({"source":"zerog-telemetry-replay"})";
    zerog::control::BodyParams body;
    body.mass_kg = mass_kg;
    config.nominal_period_s = period_s > 0 ? period_s : 0.004;
    zerog::telemetry::TelemetryChannel channel(
        config, zerog::telemetry::model_identity(model, "replay.zgm", 0x12345678u), body);
    if (const zerog::Status st = channel.start(); !st.ok()) {
      std::cerr << "zerog-telemetry-replay: " << st.text() << "\n";
      return 1;
    }
    const auto t_wait = std::chrono::steady_clock::now();
    while (channel.subscribers() < wait_subscribers &&
           std::chrono::steady_clock::now() - t_wait < std::chrono::duration<double>(wait_s))
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    std::cerr << "zerog-telemetry-replay: " << channel.subscribers() << " subscriber(s), "
              << records.size() << " records\n";
    zerog::telemetry::RuntimeHealth health;
    auto next = std::chrono::steady_clock::now();
    for (const CycleRecord& r : records) {
      if ((r.flags & zerog::loop::kIpocGap) != 0) {
        ++health.ipoc_gaps;
        ++health.datagrams_lost;
        channel.set_health(health);
      }
      channel.offer(r);
      if (period_s > 0) {
        next += std::chrono::duration_cast<std::chrono::steady_clock::duration>(
            std::chrono::duration<double>(period_s));
        std::this_thread::sleep_until(next);
      }
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(linger_s));
    channel.stop();
    const zerog::telemetry::ChannelCounters c = channel.counters();
    std::cerr << "zerog-telemetry-replay: offered " << c.records_offered << ", published "
              << c.records_published << ", dropped " << c.telemetry_drops << ", write errors "
              << c.write_errors << ", health " << c.health_published << "\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "zerog-telemetry-replay: " << e.what() << "\n";
    return 1;
  }
}
