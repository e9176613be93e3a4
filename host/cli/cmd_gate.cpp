// `zerog gate`: the contact gate's threshold from the noise zerog-rt measured at rest in zero-g
// (host/ident/include/zerog/ident/gate_rule.hpp has the rule; docs/zerog-rt.md "Setting the
// contact gate").
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>

#include "commands.hpp"
#include "zerog/formats/cycles_csv.hpp"
#include "zerog/ident/gate_rule.hpp"
#include "zerog/rt/config.hpp"

namespace zerog::cli {

void add_gate_command(CLI::App& app) {
  struct Args {
    std::string cycles, config;
    double false_per_hour = 0.01;
    bool json = false;
  };
  auto a = std::make_shared<Args>();
  CLI::App* s = app.add_subcommand(
      "gate",
      "The contact gate's thresholds (force_deadband_N, torque_deadband_Nm) from the contact "
      "wrench zerog-rt recorded at rest in zero-g: the smallest that keeps false confirms below "
      "a rate, replayed on the recording (docs/zerog-rt.md, \"Setting the contact gate\")");
  s->add_option("cycles", a->cycles,
                "zerog-rt's cycles.csv (its [record] dir), with zero-g at rest")
      ->required()
      ->check(CLI::ExistingFile);
  s->add_option("-c,--config", a->config,
                "zerog-rt's configuration: the virtual centre of mass, contact_confirm_cycles "
                "and the thresholds configured now (without it: the defaults, the centre of mass "
                "at the sensor origin)")
      ->check(CLI::ExistingFile);
  s->add_option("--false-per-hour", a->false_per_hour,
                "Expected false confirms per hour of zero-g at the threshold, cycles taken as "
                "independent")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  s->add_flag("--json", a->json, "JSON output");
  s->callback([a] {
    ident::GateRuleOptions o;
    o.false_per_hour = a->false_per_hour;
    if (!a->config.empty()) {
      const rt::RtConfig c = rt::read_config(a->config);
      o.com_sensor_m = c.com_sensor_m;
      o.confirm_cycles = c.limits.contact_confirm_cycles;
      o.release_fraction = c.limits.contact_release_fraction;
      o.force_now_N = c.limits.force_deadband_N;
      o.torque_now_Nm = c.limits.torque_deadband_Nm;
    }
    const ident::GateAdvice advice = ident::gate_rule(formats::read_cycles_csv(a->cycles), o);
    if (a->json) {
      nlohmann::json j = ident::to_json(advice, o);
      j["kind"] = "zerog-gate";
      j["version"] = 1;
      j["cycles_csv"] = a->cycles;
      j["config"] = a->config.empty() ? nlohmann::json(nullptr) : nlohmann::json(a->config);
      std::cout << j.dump(2) << "\n";
    } else if (advice.known) {
      std::printf("%s", ident::format_gate_advice(advice, o).c_str());
    }
    // Not known: the reason once, as the error (exit 1; the JSON above says it too).
    if (!advice.known) throw std::runtime_error(advice.note);
  });
}

}  // namespace zerog::cli
