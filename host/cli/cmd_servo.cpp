// `zerog servo`: the robot's position servo (the bandwidth of [filter] servo_hz) from a zerog-rt
// recording (host/ident/include/zerog/ident/servo_fit.hpp has the method; docs/zerog-rt.md
// "Identifying the servo model").
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <stdexcept>
#include <string>

#include "commands.hpp"
#include "zerog/formats/cycles_csv.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/ident/servo_fit.hpp"
#include "zerog/rt/config.hpp"

namespace zerog::cli {

void add_servo_command(CLI::App& app) {
  struct Args {
    std::string cycles, rig, config;
    bool json = false;
  };
  auto a = std::make_shared<Args>();
  CLI::App* s = app.add_subcommand(
      "servo",
      "The robot's position servo ([filter] servo_hz of the motion estimator) from a zerog-rt "
      "recording of zero-g with pushes: the joints measured against the corrections sent "
      "(docs/zerog-rt.md, \"Identifying the servo model\")");
  s->add_option("cycles", a->cycles, "zerog-rt's cycles.csv (its [record] dir)")
      ->required()
      ->check(CLI::ExistingFile);
  s->add_option("--rig", a->rig,
                "The rig whose robot turns Cartesian corrections into joint increments (default: "
                "run.rig.toml beside cycles.csv, else the configuration's [rig] file)")
      ->check(CLI::ExistingFile);
  s->add_option("-c,--config", a->config,
                "zerog-rt's configuration: its servo_hz is compared, its rig used without --rig")
      ->check(CLI::ExistingFile);
  s->add_flag("--json", a->json, "JSON output");
  s->callback([a] {
    ident::ServoFitOptions o;
    std::filesystem::path rig = a->rig;
    if (!a->config.empty()) {
      const rt::RtConfig c = rt::read_config(a->config);
      o.configured_hz = c.motion.servo_hz;
      if (rig.empty()) rig = c.rig_file;
    }
    const std::filesystem::path beside =
        std::filesystem::path(a->cycles).parent_path() / "run.rig.toml";
    if (a->rig.empty() && std::filesystem::exists(beside)) rig = beside;
    if (!rig.empty()) o.robot = formats::read_rig(rig).robot_model;
    const ident::ServoFit fit = ident::fit_servo(formats::read_cycles_csv(a->cycles), o);
    if (a->json) {
      nlohmann::json j = ident::to_json(fit);
      j["kind"] = "zerog-servo";
      j["version"] = 1;
      j["cycles_csv"] = a->cycles;
      j["rig"] = rig.empty() ? nlohmann::json(nullptr) : nlohmann::json(rig.string());
      std::cout << j.dump(2) << "\n";
    } else {
      std::printf("%s", ident::format_servo_fit(fit).c_str());
    }
    // Not known: the reason, as the error (exit 1; the JSON and the text above say it too),
    // after what was printed.
    std::fflush(stdout);
    if (!fit.known) throw std::runtime_error(fit.note);
  });
}

}  // namespace zerog::cli
