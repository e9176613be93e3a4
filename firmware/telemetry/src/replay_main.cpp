// zerog-telemetry-replay: publishes cycle records through a real TelemetryChannel, for testing
// subscribers (tests/telemetry/, `zerog watch`) without a robot. The records are either
// generated (--generate N: a scripted idle → zero-g push → fault run, written with
// --write-csv in the recorder's cycles.csv format so subscribers can be checked against it) or
// read from a zerog-rt cycles.csv (--csv). Paced at --period-s per record.
#include <CLI/CLI.hpp>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "zerog/rt/record_csv.hpp"
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
  r.rkorr = {0.01 * std::sin(0.1 * k), -0.02, 0.005, 0.001 * k, -0.002, 0.0};
  r.body.p_world_m = Eigen::Vector3d(1.0 + 1e-4 * k, 0.2, 1.4);
  r.body.q_world_body =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.01 * k, Eigen::Vector3d(1, 2, 3).normalized()));
  r.body.v_world_mps = Eigen::Vector3d(0.025, -0.001 * std::sin(k), 0.0);
  r.body.L_world_kgm2ps = Eigen::Vector3d(0.1, 0.02 * std::cos(0.1 * k), -0.05);
  r.compute_ns = 20'000 + static_cast<std::int64_t>(cycle % 7) * 1000;
  return r;
}

// --- cycles.csv (zerog::rt::append_record_row) back to records --------------------------------

template <typename Enum, int N>
Enum enum_from_name(const std::string& name, const char* (*name_of)(Enum), const char* what) {
  for (int i = 0; i < N; ++i)
    if (name == name_of(static_cast<Enum>(i))) return static_cast<Enum>(i);
  throw std::runtime_error(std::string("unknown ") + what + " \"" + name + "\"");
}

std::vector<CycleRecord> read_cycles_csv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot be read");
  std::string line;
  if (!std::getline(in, line)) throw std::runtime_error(path + ": empty");
  std::map<std::string, std::size_t> column;
  {
    std::stringstream ss(line);
    std::string name;
    for (std::size_t i = 0; std::getline(ss, name, ','); ++i) column[name] = i;
  }
  std::vector<CycleRecord> records;
  for (int line_no = 2; std::getline(in, line); ++line_no) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) f.push_back(cell);
    const std::string where = path + ":" + std::to_string(line_no);
    const auto cell = [&](const char* name) -> const std::string& {
      const auto it = column.find(name);
      if (it == column.end()) throw std::runtime_error(path + ": no column " + name);
      if (it->second >= f.size()) throw std::runtime_error(where + ": too few cells");
      return f[it->second];
    };
    const auto num = [&](const char* name) {
      const std::string& s = cell(name);
      double v = 0.0;
      const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
      if (r.ec != std::errc{} || r.ptr != s.data() + s.size())
        throw std::runtime_error(where + ": " + name + " \"" + s + "\" is not a number");
      return v;
    };
    const auto uint = [&](const char* name) {
      const std::string& s = cell(name);
      std::uint64_t v = 0;
      const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
      if (r.ec != std::errc{} || r.ptr != s.data() + s.size())
        throw std::runtime_error(where + ": " + name + " \"" + s + "\" is not an integer");
      return v;
    };
    CycleRecord r;
    r.cycle = uint("cycle");
    r.ipoc = uint("ipoc");
    r.t_s = num("t_s");
    r.dt_s = num("dt_s");
    r.state =
        enum_from_name<zerog::loop::State, 4>(cell("state"), zerog::loop::state_name, "state");
    r.fault =
        enum_from_name<zerog::loop::Fault, 8>(cell("fault"), zerog::loop::fault_name, "fault");
    r.flags = static_cast<std::uint32_t>(uint("flags"));
    r.limit_flags = static_cast<std::uint32_t>(uint("limit_flags"));
    r.model_status = enum_from_name<zerog::infer::StatusCode, 4>(
        cell("model_status"), zerog::infer::status_name, "model status");
    const char* q[] = {"q1_rad", "q2_rad", "q3_rad", "q4_rad", "q5_rad", "q6_rad"};
    for (int i = 0; i < 6; ++i) r.joints_rad[i] = num(q[i]);
    r.p_base_sensor_m = {num("px_m"), num("py_m"), num("pz_m")};
    r.q_base_sensor = Eigen::Quaterniond(num("qw"), num("qx"), num("qy"), num("qz"));
    const char* axes[] = {"Fx_N", "Fy_N", "Fz_N", "Mx_Nm", "My_Nm", "Mz_Nm"};
    for (int i = 0; i < 6; ++i) {
      const std::string a = axes[i];
      r.wrench_measured[i] = num(a.c_str());
      r.wrench_at_eval[i] = num(("eval_" + a).c_str());
      r.predicted[i] = num(("pred_" + a).c_str());
      r.contact[i] = num(("contact_" + a).c_str());
    }
    const char* imu[] = {"imu_fx_mps2",  "imu_fy_mps2",  "imu_fz_mps2",
                         "imu_wx_radps", "imu_wy_radps", "imu_wz_radps"};
    for (int i = 0; i < 3; ++i) {
      r.specific_force_imu[i] = num(imu[i]);
      r.rate_imu[i] = num(imu[3 + i]);
    }
    r.ft_samples = static_cast<std::uint16_t>(uint("ft_samples"));
    r.imu_samples = static_cast<std::uint16_t>(uint("imu_samples"));
    r.t_eval_s = num("t_eval_s");
    r.axis_reply = uint("axis_reply") != 0;
    r.rkorr = {num("rkorr_x_mm"),  num("rkorr_y_mm"),  num("rkorr_z_mm"),
               num("rkorr_a_deg"), num("rkorr_b_deg"), num("rkorr_c_deg")};
    const char* ak[] = {"akorr_a1_deg", "akorr_a2_deg", "akorr_a3_deg",
                        "akorr_a4_deg", "akorr_a5_deg", "akorr_a6_deg"};
    for (int i = 0; i < 6; ++i) r.akorr_deg[i] = num(ak[i]);
    r.body.p_world_m = {num("body_px_m"), num("body_py_m"), num("body_pz_m")};
    r.body.q_world_body =
        Eigen::Quaterniond(num("body_qw"), num("body_qx"), num("body_qy"), num("body_qz"));
    r.body.v_world_mps = {num("body_vx_mps"), num("body_vy_mps"), num("body_vz_mps")};
    r.body.L_world_kgm2ps = {num("body_Lx_kgm2ps"), num("body_Ly_kgm2ps"), num("body_Lz_kgm2ps")};
    const std::string& c = cell("compute_ns");
    std::int64_t ns = 0;
    std::from_chars(c.data(), c.data() + c.size(), ns);
    r.compute_ns = ns;
    records.push_back(r);
  }
  return records;
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
      records = read_cycles_csv(csv_in);
    } else {
      for (int i = 1; i <= generate; ++i)
        records.push_back(
            scripted_record(static_cast<std::uint64_t>(i), period_s > 0 ? period_s : 0.004));
      if (!records.empty()) records.back().state = zerog::loop::State::fault;
      if (!records.empty()) records.back().fault = zerog::loop::Fault::contact_over_limit;
    }
    if (!csv_out.empty()) {
      std::string text;
      zerog::rt::append_record_header(text);
      for (const CycleRecord& r : records) zerog::rt::append_record_row(r, text);
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
    if (std::string why = channel.start(); !why.empty()) {
      std::cerr << "zerog-telemetry-replay: " << why << "\n";
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
