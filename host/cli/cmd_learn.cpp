// zerog train | results
#include <cstdio>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>

#include "commands.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/ident/compare.hpp"
#include "zerog/ident/dataset.hpp"
#include "zerog/io/model_file.hpp"
#include "zerog/learn/network_file.hpp"
#include "zerog/learn/predict.hpp"
#include "zerog/learn/results.hpp"
#include "zerog/learn/signals.hpp"
#include "zerog/learn/train.hpp"

namespace zerog::cli {
namespace {

void progress_line(const std::string& s) { std::fprintf(stderr, "%s\n", s.c_str()); }

struct TrainArgs {
  std::string log, out, kind = "residual", model, inputs, sweep;
  int hidden = 0;  // 0: the kind's default
  int sweep_repeats = 3;
  std::uint64_t seed = 1;
  int max_train_samples = learn::TrainOptions{}.max_train_samples;
  int max_iterations = learn::TrainOptions{}.max_iterations;
  int adam_iterations = learn::TrainOptions{}.adam_iterations;
  bool all_data = false;
  int threads = 2;
  bool json = false;
  bool quiet = false;
};

std::vector<int> parse_int_list(const std::string& s) {
  std::vector<int> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    try {
      std::size_t used = 0;
      const int v = std::stoi(item, &used);
      if (used != item.size() || v < 1) throw std::invalid_argument("");
      out.push_back(v);
    } catch (const std::exception&) {
      throw std::invalid_argument("--sweep: '" + item + "' is not a positive whole number");
    }
  }
  if (out.empty()) throw std::invalid_argument("--sweep: empty list");
  return out;
}

void run_train(const TrainArgs& a) {
  const auto kind = learn::kind_from_name(a.kind);
  if (!kind) throw std::invalid_argument("--kind must be paper-bp, paper-zp or residual");
  if (*kind == learn::NetworkKind::residual && a.model.empty())
    throw std::invalid_argument("--kind residual needs --model (the physics model from zerog fit)");
  if (*kind != learn::NetworkKind::residual && !a.inputs.empty())
    throw std::invalid_argument(
        "--inputs applies to --kind residual only (the paper kinds use "
        "their papers' inputs)");
  if (!a.sweep.empty() && *kind != learn::NetworkKind::paper_bp)
    throw std::invalid_argument("--sweep applies to --kind paper-bp only (000_… §4.3)");
  const formats::Log log = formats::read_log(a.log);
  const ident::Dataset data = ident::make_dataset(log);
  learn::TrainOptions o;
  o.kind = *kind;
  if (a.hidden > 0) o.hidden = a.hidden;
  o.seed = a.seed;
  if (!a.inputs.empty()) o.inputs = learn::parse_features(a.inputs);
  if (!a.model.empty()) o.physics = io::read_model(a.model);
  o.max_train_samples = a.max_train_samples;
  o.max_iterations = a.max_iterations;
  o.adam_iterations = a.adam_iterations;
  o.threads = a.threads;
  if (!a.quiet) o.progress = progress_line;
  const std::vector<std::uint8_t> test = ident::heldout_mask(data);
  std::vector<std::uint8_t> usable(test.size());
  for (std::size_t i = 0; i < test.size(); ++i) usable[i] = test[i] ? 0 : 1;
  if (!a.all_data) o.usable = &usable;

  nlohmann::json sweep_json;
  if (!a.sweep.empty()) {
    const auto rows = learn::sweep_hidden(data, log, o, parse_int_list(a.sweep), a.sweep_repeats);
    sweep_json = nlohmann::json::array();
    if (!a.json)
      std::printf(
          "hidden-layer sweep (000_… §4.3, Figure 12): validation MSE, normalised, mean "
          "of %d trainings\n%8s %14s %10s\n",
          a.sweep_repeats, "hidden", "validation", "time");
    for (const auto& r : rows) {
      sweep_json.push_back({{"hidden", r.hidden},
                            {"validation_mse", r.validation_mse},
                            {"mean", r.mean},
                            {"seconds", r.seconds}});
      if (!a.json) std::printf("%8d %14.5g %9.1fs\n", r.hidden, r.mean, r.seconds);
    }
  }
  learn::NetworkFile net = learn::train(data, log, o);
  if (!sweep_json.is_null()) net.training["sweep"] = sweep_json;
  // Held-out errors (the blocks kept out of training).
  nlohmann::json heldout;
  if (!a.all_data) {
    const auto pred = learn::predictions(net, data, log);
    std::vector<ident::Wrench> res(data.size());
    for (std::size_t i = 0; i < data.size(); ++i) res[i] = data.measured[i] - pred[i];
    const ident::Comparison c = ident::compare(res, data, &test, 1);
    heldout = {{"rule", "every 4th 60-s block (ident::heldout_mask), not used in training"},
               {"static", ident::to_json(c.stat)},
               {"moving", ident::to_json(c.moving)},
               {"all", ident::to_json(c.all)}};
    net.training["heldout"] = heldout;
  }
  net.training["log"] = a.log;
  std::vector<std::filesystem::path> inputs = {a.log, formats::rig_path_for(a.log)};
  if (!a.model.empty()) inputs.push_back(a.model);
  if (!a.out.empty()) learn::write_network(net, a.out, inputs);
  if (a.json) {
    nlohmann::json j = learn::to_json(net);
    j["output"] = a.out.empty() ? nlohmann::json(nullptr) : nlohmann::json(a.out);
    std::cout << j.dump(2) << "\n";
    return;
  }
  std::printf(
      "trained %s: %s, %d parameters, inputs %s, in %.1f s\n", learn::kind_name(net.kind),
      [&] {
        std::string s;
        for (int w : net.shape.width) s += (s.empty() ? "" : "-") + std::to_string(w);
        return s;
      }()
          .c_str(),
      net.shape.num_params(), learn::feature_list_string(net.inputs).c_str(),
      net.training.value("seconds_total", 0.0));
  if (net.tool_load)
    std::printf("least-squares tool load: %.3f kg, centre of gravity (%.4f, %.4f, %.4f) m in S\n",
                net.tool_load->mass_kg(), net.tool_load->cog_sensor_m.x(),
                net.tool_load->cog_sensor_m.y(), net.tool_load->cog_sensor_m.z());
  if (!heldout.is_null()) {
    for (const char* seg : {"static", "moving"}) {
      const auto& s = heldout[seg];
      std::printf("held-out %-6s (%zu samples): force RMS %.3f N, torque RMS %.3f N*m\n", seg,
                  s.value("count", std::size_t{0}), s.value("force_rms", 0.0),
                  s.value("torque_rms", 0.0));
    }
  }
  if (!a.out.empty()) std::printf("wrote %s\n", a.out.c_str());
}

}  // namespace

void add_learn_commands(CLI::App& app) {
  {
    auto a = std::make_shared<TrainArgs>();
    CLI::App* s = app.add_subcommand(
        "train",
        "Train a network: paper-bp (000_… BP network), paper-zp (001_… zero-point network + "
        "least-squares tool load) or residual (physics model + a small network on its residual)");
    s->add_option("log", a->log, "Log to read (zerog log format, NAME.csv with NAME.rig.toml)")
        ->required()
        ->check(CLI::ExistingFile);
    s->add_option("--kind", a->kind, "paper-bp | paper-zp | residual")
        ->check(CLI::IsMember({"paper-bp", "paper-zp", "residual"}))
        ->capture_default_str();
    s->add_option("-o,--out", a->out,
                  "Network file to write (JSON, proto/network_format.md, written atomically)");
    s->add_option("-m,--model", a->model, "residual: the physics model (from zerog fit)")
        ->check(CLI::ExistingFile);
    s->add_option("--inputs", a->inputs,
                  "residual: input features, comma separated (e.g. sign_qd6,qd6,wz); default: "
                  "the signals zerog diagnose finds the residual follows");
    s->add_option("--hidden", a->hidden,
                  "Hidden units (paper-bp: 8 as in 000_… §4.3; residual: 12; paper-zp: fixed 45 "
                  "and 90)")
        ->check(CLI::Range(1, 128));
    s->add_option("--sweep", a->sweep,
                  "paper-bp: validation sweep over hidden-layer sizes, e.g. 2,4,6,8,10,12 "
                  "(000_… §4.3, Figure 12); the --hidden network is still the one written");
    s->add_option("--sweep-repeats", a->sweep_repeats, "Trainings per size in the sweep")
        ->check(CLI::Range(1, 20))
        ->capture_default_str();
    s->add_option("--seed", a->seed, "Seed of the initial weights, split and subsample")
        ->capture_default_str();
    s->add_option("--max-train-samples", a->max_train_samples,
                  "Levenberg-Marquardt trains on a seeded subsample of at most this many samples")
        ->check(CLI::Range(10, 1000000))
        ->capture_default_str();
    s->add_option("--max-iterations", a->max_iterations, "Levenberg-Marquardt iterations")
        ->check(CLI::Range(1, 100000))
        ->capture_default_str();
    s->add_option("--adam-iterations", a->adam_iterations,
                  "paper-zp: Adam iterations (001_… used 100,000; Table 2's schedule is scaled)")
        ->check(CLI::Range(10, 10000000))
        ->capture_default_str();
    s->add_flag("--all-data", a->all_data,
                "Train on every sample (default: keep every 4th 60-s block out and report the "
                "error on it)");
    s->add_option("--threads", a->threads, "Threads")->check(CLI::Range(1, 64));
    s->add_flag("--json", a->json, "Print the network document (JSON) on stdout");
    s->add_flag("-q,--quiet", a->quiet, "No progress lines on stderr");
    s->callback([a] { run_train(*a); });
  }
  {
    auto o = std::make_shared<learn::ResultsOptions>();
    auto json = std::make_shared<bool>(false);
    auto quiet = std::make_shared<bool>(false);
    auto json_out = std::make_shared<std::string>();
    auto keep = std::make_shared<std::string>();
    CLI::App* s = app.add_subcommand(
        "results",
        "The results table: paper-bp, paper-zp, physics, physics + residual network (float, "
        "quantised), the true-model reference and the sensor floor on one simulated run, "
        "held-out data, static and moving");
    s->add_option("--seed", o->seed, "Simulation seed")->capture_default_str();
    s->add_option("--train-seed", o->train_seed, "Training seed")->capture_default_str();
    s->add_option("--truth-effects", o->truth_effects,
                  "Simulator effects on top of its default (see zerog sim --list-effects)")
        ->capture_default_str();
    s->add_option("--threads", o->threads, "Threads")->check(CLI::Range(1, 64));
    s->add_option("--max-train-samples", o->max_train_samples, "Levenberg-Marquardt subsample size")
        ->check(CLI::Range(10, 1000000))
        ->capture_default_str();
    s->add_option("--adam-iterations", o->adam_iterations, "paper-zp Adam iterations")
        ->check(CLI::Range(10, 10000000))
        ->capture_default_str();
    s->add_option("--keep", *keep, "Folder to write the run, the physics fit and the networks to");
    s->add_option("--json-out", *json_out, "Also write the JSON to this file (atomically)");
    s->add_flag("--json", *json, "Print JSON instead of Markdown on stdout");
    s->add_flag("-q,--quiet", *quiet, "No progress lines on stderr");
    s->callback([=] {
      learn::ResultsOptions ro = *o;
      if (!*quiet) ro.progress = progress_line;
      ro.keep_dir = *keep;
      const learn::Results r = learn::run_results(ro);
      const nlohmann::json j = learn::to_json(r);
      if (!json_out->empty()) formats::write_file_atomic(*json_out, j.dump(2) + "\n");
      if (*json)
        std::cout << j.dump(2) << "\n";
      else
        std::cout << learn::format_markdown(r);
    });
  }
}

}  // namespace zerog::cli
