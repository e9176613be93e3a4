// `zerog sim`: simulate a calibration run of the rig and write the log, its rig sidecar, the
// truth (a model file with the exact parameters of the simulated effects) and the noise-free copy
// of the log (for the sensor floor).
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "commands.hpp"
#include "zerog/formats/detail/csv_scan.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/io/model_file.hpp"
#include "zerog/sim/design.hpp"
#include "zerog/sim/simulator.hpp"

namespace zerog::cli {
namespace {

namespace fs = std::filesystem;

struct SimArgs {
  std::string design;
  std::string kind;
  int points = 0;
  std::uint64_t design_seed = 1;
  std::string effects;
  bool point_mass = false;
  bool no_noise = false;
  bool real_robot = false;
  std::vector<std::string> sets;
  std::vector<std::string> contacts;
  std::uint64_t seed = 1;
  double period_s = 0.012;
  double mass_kg = 100.0;
  double duration_limit_s = 0.0;
  double dwell_s = 2.0;
  double speed_fraction = 0.3;
  std::string out;
  bool list_effects = false;
  bool quiet = false;
};

fs::path truth_path_for(const fs::path& csv) {
  fs::path p = csv;
  p.replace_extension();
  p += ".truth.json";
  return p;
}

// The noise-free copy of the log (SimOutput::clean_log): NAME.csv → NAME.clean.csv.
fs::path clean_path_for(const fs::path& csv) {
  fs::path p = csv;
  p.replace_extension();
  p += ".clean.csv";
  return p;
}

bool same_file(const fs::path& a, const fs::path& b) {
  std::error_code ec;
  return fs::weakly_canonical(a, ec) == fs::weakly_canonical(b, ec);
}

sim::SimConfig make_config(const SimArgs& a) {
  sim::SimConfig c = sim::default_sim_config(a.seed);
  c.payload.mass_kg = a.mass_kg;
  c.payload.inertia_com_sensor_kgm2 = sim::box_inertia_kgm2(a.mass_kg);
  c.effects = sim::parse_sim_effects(a.effects);
  if (a.point_mass) c.effects.remove(model::Effect::rotational_inertia);
  if (a.no_noise) c.noise = sim::NoiseConfig::none();
  if (a.real_robot) sim::make_real_robot(c, !a.no_noise);
  c.period_s = a.period_s;
  c.dwell_s = a.dwell_s;
  c.speed_fraction = a.speed_fraction;
  c.duration_limit_s = a.duration_limit_s;
  for (const std::string& text : a.contacts) c.contacts.push_back(sim::parse_contact(text));
  for (const std::string& kv : a.sets) {
    const auto eq = kv.find('=');
    if (eq == std::string::npos)
      throw std::invalid_argument("--set wants key=value, got '" + kv + "'");
    const std::string value = kv.substr(eq + 1);
    double x = 0.0;
    if (formats::detail::parse_number(value, x) != formats::detail::NumberStatus::ok)
      throw std::invalid_argument("--set " + kv + ": '" + value + "' is not a number");
    sim::set_config_value(c, kv.substr(0, eq), x);
  }
  return c;
}

void list_effects(const SimArgs& a) {
  const sim::SimConfig c = make_config(a);
  std::printf(
      "Always in the truth: bias (seeded F0 +-(20..60) N, M0 +-(1..5) N*m), gravity "
      "(payload mass and centre), linear_inertia.\n");
  std::printf("Switchable effects (--effects a,b,-c; 'all', 'none'; on now: %s):\n",
              sim::sim_effect_list_string(c.effects).c_str());
  for (const auto& e : sim::sim_effect_infos())
    std::printf("  %-19s %-15s %s\n", e.name, e.model_effect() ? "(model)" : "(not in model)",
                e.default_magnitude);
  std::printf("\nValues for --set KEY=VALUE (seed %llu):\n",
              static_cast<unsigned long long>(c.seed));
  for (const auto& [key, value] : sim::config_values(c))
    std::printf("  %-28s %.9g\n", key.c_str(), value);
}

void run_sim(const SimArgs& a) {
  if (a.list_effects) {
    list_effects(a);
    return;
  }
  if (a.out.empty()) throw std::invalid_argument("--out is required");
  const fs::path out = a.out;
  if (out.extension() != ".csv") throw std::invalid_argument("--out must name a .csv file");
  const fs::path rig_out = formats::rig_path_for(out);
  const fs::path truth_out = truth_path_for(out);
  const fs::path clean_out = clean_path_for(out);

  std::vector<sim::JointVector> points;
  nlohmann::json design_info;
  std::vector<fs::path> inputs;
  if (!a.design.empty()) {
    if (!a.kind.empty()) throw std::invalid_argument("give either --design or --kind, not both");
    inputs.push_back(a.design);
    for (const fs::path& o : {out, rig_out, truth_out, clean_out, formats::rig_path_for(clean_out)})
      if (same_file(o, a.design))
        throw std::invalid_argument("refusing to overwrite the input " + a.design);
    points = sim::read_design(a.design);
    design_info = {{"file", a.design}, {"points", points.size()}};
  } else {
    const auto kind = sim::design_kind_from_name(a.kind.empty() ? "oa" : a.kind);
    if (!kind) throw std::invalid_argument("unknown design kind '" + a.kind + "'");
    sim::DesignOptions o;
    o.kind = *kind;
    o.points = a.points;
    if (*kind != sim::DesignKind::oa && o.points == 0) o.points = 121;
    o.seed = a.design_seed;
    const sim::Design d = sim::make_design(o);
    points = d.points_rad;
    design_info = {{"kind", sim::design_kind_name(d.kind)},
                   {"points", points.size()},
                   {"seed", d.seed},
                   {"rejected", d.rejected}};
    if (d.rejected > 0 && !a.quiet)
      std::fprintf(stderr, "sim: design dropped %d infeasible points (floor)\n", d.rejected);
  }

  const sim::RigSimulator simulator(make_config(a), std::move(points));
  const bool tty = isatty(STDERR_FILENO) != 0;
  const auto t0 = std::chrono::steady_clock::now();
  int last_percent = -1;
  sim::SimOutput result = simulator.run([&](double fraction) {
    if (a.quiet || !tty) return;
    const int percent = static_cast<int>(100.0 * fraction);
    if (percent == last_percent) return;
    last_percent = percent;
    std::fprintf(stderr, "\rsim: %3d %%", percent);
    if (fraction >= 1.0) std::fprintf(stderr, "\n");
  });
  const double sim_wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  result.truth.extra["design"] = design_info;
  // Relative to the truth file's folder (both lie beside the log); zerog compare, ladder and
  // report --truth read it for the sensor floor (proto/model_format.md).
  result.truth.extra["clean_signals_log"] = clean_out.filename().string();

  formats::write_log(result.log, out, inputs);
  formats::write_log(result.clean_log, clean_out, inputs);
  io::write_model(result.truth, truth_out, inputs);  // last: it names the other files

  const sim::SimStats& s = result.stats;
  if (s.samples_below_floor > 0)
    std::fprintf(stderr, "sim: warning: %zu samples with the payload below the floor (%.3f m)\n",
                 s.samples_below_floor, s.lowest_point_z_m);
  if (!a.quiet) {
    std::printf("sim: %zu samples, %.1f s (%.1f min) simulated in %.2f s; effects: %s\n", s.samples,
                s.duration_s, s.duration_s / 60.0, sim_wall_s,
                sim::sim_effect_list_string(simulator.config().effects).c_str());
    std::printf("sim: max |F| %.1f N, max |M| %.1f N*m, lowest point z %.3f m in base\n",
                s.max_force_N, s.max_torque_Nm, s.lowest_point_z_m);
    std::printf("wrote %s, %s, %s, %s (noise-free signals, the same noisy wrench)\n",
                out.string().c_str(), rig_out.string().c_str(), truth_out.string().c_str(),
                clean_out.string().c_str());
  }
}

}  // namespace

void add_sim_command(CLI::App& app) {
  auto args = std::make_shared<SimArgs>();
  CLI::App* cmd = app.add_subcommand(
      "sim",
      "Simulate a calibration run: KR 210 R2700 PTP moves through path points (2 s dwells, 30 % "
      "speed), a payload on an Omega191 F/T sensor and a STIM300-like IMU, with switchable "
      "effects. Writes OUT.csv, OUT.rig.toml (proto/log_format.md), OUT.truth.json (model "
      "file with the true parameters) and OUT.clean.csv (+ OUT.clean.rig.toml: the same rows "
      "with noise-free signals and the noisy wrench, for the sensor floor)");
  auto* design = cmd->add_option("--design", args->design, "design CSV (from `zerog design`)")
                     ->check(CLI::ExistingFile);
  cmd->add_option("--kind", args->kind, "inline design instead of --design: oa | random | sobol")
      ->check(CLI::IsMember({"oa", "random", "sobol"}))
      ->excludes(design);
  cmd->add_option("--points", args->points, "inline design: number of points (oa: 121)");
  cmd->add_option("--design-seed", args->design_seed, "inline design: seed")->capture_default_str();
  cmd->add_option("--effects", args->effects,
                  "effects to switch on, comma separated; '-name' switches off, 'all', 'none' "
                  "(default: rotational_inertia only; see --list-effects)");
  cmd->add_flag("--point-mass", args->point_mass,
                "payload as a point mass (no rotational inertia)");
  cmd->add_flag("--no-noise", args->no_noise, "no sensor noise and no quantisation");
  cmd->add_flag("--real-robot", args->real_robot,
                "a robot that is not rigid (proto/sim_robot.md): elastic joints of a KR 210 "
                "class arm, encoder quantisation of the logged joints, the STIM300's bias "
                "instability (the last two not with --no-noise); --set elastic.*, noise.encoder, "
                "noise.*_bias change them");
  cmd->add_option("--set", args->sets,
                  "override a value, KEY=VALUE, e.g. imu_time_offset.tau=0.01 (repeatable; keys: "
                  "--list-effects)");
  cmd->add_option("--contact", args->contacts,
                  "a contact during the run, outside the payload model (repeatable, at most 8): "
                  "START:DURATION:FX,FY,FZ[,MX,MY,MZ][:sensor|base][:plateau|spike] in s, N and "
                  "N*m at the sensor origin; default sensor frame, plateau (0.1 s ramps); spike: "
                  "one half-sine (a collision). Listed in OUT.truth.json's extra.contacts")
      ->type_name("SPEC");
  cmd->add_option("--seed", args->seed, "seed of effect magnitudes and noise")
      ->capture_default_str();
  cmd->add_option("--period", args->period_s, "sample period, s")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--mass", args->mass_kg, "payload mass, kg (inertia scales with it)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--duration-limit", args->duration_limit_s,
                  "stop after this much simulated time, s (0: whole trajectory)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--dwell", args->dwell_s, "dwell at each path point, s")->capture_default_str();
  cmd->add_option("--speed", args->speed_fraction, "speed override, fraction of the axis speeds")
      ->check(CLI::Range(0.01, 1.0))
      ->capture_default_str();
  cmd->add_option("--out", args->out,
                  "log to write: OUT.csv (+ OUT.rig.toml, OUT.truth.json, OUT.clean.csv)");
  cmd->add_flag("--list-effects", args->list_effects,
                "print the effects, their default magnitudes and every --set key, then exit");
  cmd->add_flag("-q,--quiet", args->quiet, "no progress or summary");
  cmd->callback([args]() { run_sim(*args); });
}

}  // namespace zerog::cli
