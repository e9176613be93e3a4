#include "zerog/learn/results.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "zerog/ident/diagnose.hpp"
#include "zerog/ident/fit.hpp"
#include "zerog/io/model_file.hpp"
#include "zerog/learn/predict.hpp"
#include "zerog/learn/quantised.hpp"
#include "zerog/learn/signals.hpp"
#include "zerog/learn/train.hpp"
#include "zerog/sim/design.hpp"
#include "zerog/sim/simulator.hpp"

namespace zerog::learn {

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

std::string fmt(const char* f, double a, double b = 0.0) {
  char buf[128];
  std::snprintf(buf, sizeof buf, f, a, b);
  return buf;
}

void stats_into(MethodResult& m, const std::vector<ident::Wrench>& pred, const ident::Dataset& data,
                const std::vector<std::uint8_t>& test) {
  std::vector<ident::Wrench> res(data.size());
  for (std::size_t i = 0; i < data.size(); ++i) res[i] = data.measured[i] - pred[i];
  const ident::Comparison c = ident::compare(res, data, &test, 1);
  m.all = c.all;
  m.stat = c.stat;
  m.moving = c.moving;
}

double force_max(const ident::ErrorStats& s) {
  return std::max({s.max_abs[0], s.max_abs[1], s.max_abs[2]});
}
double torque_max(const ident::ErrorStats& s) {
  return std::max({s.max_abs[3], s.max_abs[4], s.max_abs[5]});
}

std::string cell(const MethodResult& m, const ident::ErrorStats& s, bool force) {
  if (!m.available) return "—";
  return force ? fmt("%.3g / %.3g", s.force_rms, force_max(s))
               : fmt("%.3g / %.3g", s.torque_rms, torque_max(s));
}

nlohmann::json stats_json(const ident::ErrorStats& s) {
  nlohmann::json j = ident::to_json(s);
  j["force_max"] = force_max(s);
  j["torque_max"] = torque_max(s);
  return j;
}

struct Quote {
  const char* source;
  const char* rig;
  const char* force;
  const char* torque;
};
const std::array<Quote, 2> kQuotes = {{
    {"000_… Table 5 (BP network, 21-8-6 as here)",
     "KUKA KR210, about 100 kg, Omega191 + STIM300; 10 s of static and moving data",
     "worst-axis RMS 9.3 N (Fy), max 39.8 N (Fy)",
     "worst-axis RMS 4.4 N·m (Tx), max 18.7 N·m (Tx)"},
    {"001_… Table 4 (NN + LSM, 9-45-90-5 + least squares as here)",
     "UR10, 0.57 kg vacuum chuck, own ±100 N sensor; 215 static poses",
     "worst-axis mean abs. error 0.502 N (Fz), max 1.418 N (Fz)",
     "worst-axis mean abs. error 0.011 N·m (My), max 0.042 N·m (My)"},
}};

void say(const ResultsOptions& o, const std::string& s) {
  if (o.progress) o.progress(s);
}

// 1. The simulated run: OA design, default truth + what the options add.
sim::SimOutput simulate_run(const ResultsOptions& o, Results& r) {
  sim::SimConfig cfg = sim::default_sim_config(o.seed);
  cfg.effects = sim::parse_sim_effects(o.truth_effects);
  r.truth_effects = sim::sim_effect_list_string(cfg.effects);
  sim::DesignOptions dopt;
  dopt.kind = sim::DesignKind::oa;
  dopt.workspace.floor_z_m = cfg.floor_z_m;
  const sim::Design design = sim::make_design(dopt);
  const sim::RigSimulator simulator(cfg, design.points_rad);
  return simulator.run();
}

// The run's files, as zerog sim writes them, into --keep.
void keep_run(const std::filesystem::path& dir, const sim::SimOutput& out) {
  std::filesystem::create_directories(dir);
  formats::write_log(out.log, dir / "run.csv");
  formats::write_log(out.clean_log, dir / "run.clean.csv");
  io::ModelFile truth = out.truth;
  truth.extra["clean_signals_log"] = "run.clean.csv";  // as zerog sim names it
  io::write_model(truth, dir / "run.truth.json");
}

// The held-out blocks (test) and the rest (usable for training and fitting).
struct Split {
  std::vector<std::uint8_t> test, usable;
};

Split split_heldout(const ident::Dataset& data, Results& r) {
  Split s;
  s.test = ident::heldout_mask(data);
  s.usable.resize(s.test.size());
  for (std::size_t i = 0; i < s.test.size(); ++i) {
    s.usable[i] = s.test[i] ? 0 : 1;
    if (s.test[i]) ++(data.moving[i] ? r.heldout_moving : r.heldout_static);
  }
  return s;
}

// 2. Physics: the model the ladder reaches, refitted on the training blocks.
struct Physics {
  std::vector<ident::LadderStep> steps;
  io::ModelFile model;
  double ladder_s = 0.0, fit_s = 0.0;
};

Physics fit_physics(const ResultsOptions& o, const ident::Dataset& data, const formats::Log& log,
                    const Split& split, Results& r) {
  Physics ph;
  auto t0 = Clock::now();
  // The ladder never sees the test blocks: it validates on another block of each four.
  ident::LadderOptions lo;
  lo.diagnose.fit.threads = o.threads;
  lo.diagnose.fit.covariance = false;
  lo.diagnose.exclude = &split.test;
  lo.diagnose.heldout_offset = 1;
  ph.steps = ident::ladder(data, lo);
  ph.ladder_s = since(t0);
  const model::EffectSet effects = ph.steps.back().effects;
  r.physics_effects = io::effect_list_string(effects);
  say(o, "results: the ladder reaches " + r.physics_effects + fmt(" (%.1f s)", ph.ladder_s));
  t0 = Clock::now();
  ident::FitOptions fo;
  fo.effects = effects;
  fo.mask = &split.usable;
  fo.covariance = false;
  fo.threads = o.threads;
  const ident::FitResult fit = ident::fit(data, fo);
  if (!fit.usable)
    throw std::runtime_error("results: the physics fit is not usable: " + fit.termination);
  ph.model.params = fit.params;
  ph.model.rig_name = log.rig.name;
  ph.fit_s = since(t0);
  if (!o.keep_dir.empty()) io::write_model(ph.model, o.keep_dir / "physics.json");
  return ph;
}

// 3. The three networks, trained on the training blocks.
struct Networks {
  NetworkFile bp, zp, res;
  double s_bp = 0, s_zp = 0, s_res = 0;
};

Networks train_networks(const ResultsOptions& o, const ident::Dataset& data,
                        const formats::Log& log, const io::ModelFile& physics, const Split& split) {
  TrainOptions to;
  to.seed = o.train_seed;
  to.usable = &split.usable;
  to.threads = o.threads;
  to.max_train_samples = o.max_train_samples;
  to.max_iterations = o.max_iterations;
  to.adam_iterations = o.adam_iterations;
  to.progress = o.progress;
  auto train_kind = [&](NetworkKind kind, double& seconds) {
    TrainOptions k = to;
    k.kind = kind;
    if (kind == NetworkKind::residual) k.physics = physics;
    const auto t = Clock::now();
    NetworkFile n = train(data, log, k);
    seconds = since(t);
    say(o, std::string("results: trained ") + kind_name(kind) + fmt(" in %.1f s", seconds));
    if (!o.keep_dir.empty())
      write_network(n, o.keep_dir / (std::string(kind_name(kind)) + ".network.json"));
    return n;
  };
  Networks n;
  n.bp = train_kind(NetworkKind::paper_bp, n.s_bp);
  n.zp = train_kind(NetworkKind::paper_zp, n.s_zp);
  n.res = train_kind(NetworkKind::residual, n.s_res);
  return n;
}

// 4. Every method's held-out error, the floors last.
void evaluate_methods(const ResultsOptions& o, const ident::Dataset& data, const formats::Log& log,
                      const sim::SimOutput& out, const Physics& ph, const Networks& n,
                      const std::vector<std::uint8_t>& test, Results& r) {
  auto add = [&](std::string key, std::string label, const std::vector<ident::Wrench>* pred,
                 double seconds, std::string note) {
    MethodResult m;
    m.key = std::move(key);
    m.label = std::move(label);
    m.train_seconds = seconds;
    m.note = std::move(note);
    if (pred)
      stats_into(m, *pred, data, test);
    else
      m.available = false;
    r.methods.push_back(std::move(m));
  };
  const auto p_bp = predictions(n.bp, data, log);
  const auto p_zp = predictions(n.zp, data, log);
  std::vector<ident::Wrench> p_phys(data.size());
  for (std::size_t i = 0; i < data.size(); ++i)
    p_phys[i] = ident::predict(ph.model.params, data, i);
  const auto p_res = predictions(n.res, data, log);
  // The truth holds the effects outside the library as user terms (joint A6 friction, …), so
  // it is the complete true model; the clean log has the run's rows with noise-free signals.
  const ident::Dataset clean = ident::make_dataset(out.clean_log);
  const ident::Floors floors = ident::floors(out.truth.params, data, &clean);
  std::vector<ident::Wrench> p_reference(data.size()), p_sensor(data.size());
  for (std::size_t i = 0; i < data.size(); ++i) {
    p_reference[i] = data.measured[i] - floors.reference_residuals[i];
    p_sensor[i] = data.measured[i] - floors.sensor_residuals[i];
  }
  add("paper-bp", "paper-bp: BP network 21-8-6, sigmoid (000_… §3–4)", &p_bp, n.s_bp,
      "random 60/20/20 split of the training blocks, Levenberg-Marquardt");
  add("paper-zp", "paper-zp: zero-point network 9-45-90-5 + least-squares tool (001_… §3)", &p_zp,
      n.s_zp,
      "static dwells only (medians); Adam, Table 2 schedule scaled to " +
          std::to_string(o.adam_iterations) + " iterations");
  add("physics", "physics: " + r.physics_effects + " (the ladder's model)", &p_phys, ph.fit_s,
      fmt("ladder %.0f s, not counted", ph.ladder_s));
  add("residual", "physics + residual network, float (" + r.residual_inputs + " → 12 tanh → 6)",
      &p_res, n.s_res, "inputs from the diagnosis");
  try {
    const auto p_q = quantised_prediction(n.res, data, log);
    r.quantised_vs_float_max_N = r.quantised_vs_float_max_Nm = 0.0;
    for (std::size_t i = 0; i < data.size(); ++i) {
      if (!test[i]) continue;
      const ident::Wrench d = (p_q[i] - p_res[i]).cwiseAbs();
      r.quantised_vs_float_max_N = std::max(r.quantised_vs_float_max_N, d.head<3>().maxCoeff());
      r.quantised_vs_float_max_Nm = std::max(r.quantised_vs_float_max_Nm, d.tail<3>().maxCoeff());
    }
    add("residual-quantised", "physics + residual network, quantised (firmware inference)", &p_q,
        0.0,
        fmt("differs from float by at most %.2g N", r.quantised_vs_float_max_N) +
            fmt(" and %.2g N*m on held-out samples", r.quantised_vs_float_max_Nm));
  } catch (const std::exception& e) {
    add("residual-quantised", "physics + residual network, quantised (firmware inference)", nullptr,
        0.0, e.what());
  }
  add("true-model-reference",
      "true-model reference (the complete true model, true parameters, same noisy signals)",
      &p_reference, 0.0, "the IMU's noise enters through the regressors; not a lower bound");
  add("sensor-floor",
      "sensor floor (true model on noise-free signals against the noisy wrench: F/T noise and "
      "quantisation)",
      &p_sensor, 0.0, "no model of the signals beats it on average");
}

}  // namespace

const MethodResult& Results::method(const std::string& key) const {
  for (const auto& m : methods)
    if (m.key == key) return m;
  throw std::out_of_range("results: no method '" + key + "'");
}

Results run_results(const ResultsOptions& o) {
  Results r;
  r.seed = o.seed;
  const sim::SimOutput out = simulate_run(o, r);
  const formats::Log& log = out.log;
  const ident::Dataset data = ident::make_dataset(log);
  r.samples = data.size();
  r.duration_s = data.pose(data.size() - 1).t_rel_s;
  say(o,
      "results: simulated " + std::to_string(data.size()) + " samples, truth " + r.truth_effects);
  if (!o.keep_dir.empty()) keep_run(o.keep_dir, out);
  const Split split = split_heldout(data, r);
  const Physics ph = fit_physics(o, data, log, split, r);
  const Networks n = train_networks(o, data, log, ph.model, split);
  r.residual_inputs = feature_list_string(n.res.inputs);
  evaluate_methods(o, data, log, out, ph, n, split.test, r);

  r.details["ladder"] = ident::to_json(ph.steps);
  r.details["ladder_seconds"] = ph.ladder_s;
  r.details["physics_fit_seconds"] = ph.fit_s;
  const NetworkFile& zp = n.zp;
  r.details["tool_load"] = {{"mass_kg", zp.tool_load->mass_kg()},
                            {"gravity_base_N",
                             {zp.tool_load->gravity_base_N.x(), zp.tool_load->gravity_base_N.y(),
                              zp.tool_load->gravity_base_N.z()}},
                            {"cog_sensor_m",
                             {zp.tool_load->cog_sensor_m.x(), zp.tool_load->cog_sensor_m.y(),
                              zp.tool_load->cog_sensor_m.z()}}};
  r.details["training"] = {
      {"paper-bp", n.bp.training}, {"paper-zp", n.zp.training}, {"residual", n.res.training}};
  return r;
}

std::string format_markdown(const Results& r) {
  std::string s;
  s += "Simulated KR 210 R2700 + 100 kg (`zerog sim`, OA design, seed " + std::to_string(r.seed) +
       ", " + std::to_string(r.samples) + " samples, " + fmt("%.0f s", r.duration_s) +
       "), truth: " + r.truth_effects +
       " (joint6_friction is outside the physics library). "
       "Held out: every 4th 60-s block (" +
       std::to_string(r.heldout_static) + " static, " + std::to_string(r.heldout_moving) +
       " moving samples); every method is trained on the "
       "other blocks only. Cells: RMS / max error; force RMS pools Fx, Fy, Fz and max is the "
       "largest |error| on any force axis (torque likewise, N·m).\n\n";
  s += "| method | static force (N) | static torque (N·m) | moving force (N) | moving torque (N·m) "
       "| training |\n|---|---|---|---|---|---|\n";
  for (const auto& m : r.methods) {
    std::string train = m.train_seconds <= 0
                            ? std::string()
                            : fmt(m.train_seconds < 10 ? "%.1f s" : "%.0f s", m.train_seconds);
    if (!m.available) train = "**not available yet**: " + m.note;
    s += "| " + m.label + " | " + cell(m, m.stat, true) + " | " + cell(m, m.stat, false) + " | " +
         cell(m, m.moving, true) + " | " + cell(m, m.moving, false) + " | " + train + " |\n";
  }
  if (r.quantised_vs_float_max_N >= 0)
    s +=
        "\nQuantised (int16 weights, per-channel scales) against float on the held-out samples: at "
        "most " +
        fmt("%.2g N and ", r.quantised_vs_float_max_N) +
        fmt("%.2g N·m apart (bound 0.1 N, 0.01 N·m).\n", r.quantised_vs_float_max_Nm);
  s += "\nThe papers' own figures, on other rigs and data (quoted, not comparable one to one):\n\n"
       "| source | rig and data | force | torque |\n|---|---|---|---|\n";
  for (const auto& q : kQuotes)
    s += std::string("| ") + q.source + " | " + q.rig + " | " + q.force + " | " + q.torque + " |\n";
  return s;
}

nlohmann::json to_json(const Results& r) {
  nlohmann::json j;
  j["kind"] = "zerog-results";
  j["version"] = 2;  // 2: method "noise-floor" became "true-model-reference" + "sensor-floor"
  j["seed"] = r.seed;
  j["truth_effects"] = r.truth_effects;
  j["samples"] = r.samples;
  j["duration_s"] = r.duration_s;
  j["quantised_vs_float_max"] = {{"force_N", r.quantised_vs_float_max_N},
                                 {"torque_Nm", r.quantised_vs_float_max_Nm}};
  j["heldout"] = {{"static", r.heldout_static},
                  {"moving", r.heldout_moving},
                  {"rule", "every 4th 60-s block (ident::heldout_mask)"}};
  j["physics_effects"] = r.physics_effects;
  j["residual_inputs"] = r.residual_inputs;
  j["methods"] = nlohmann::json::array();
  for (const auto& m : r.methods) {
    nlohmann::json x = {{"key", m.key},
                        {"label", m.label},
                        {"available", m.available},
                        {"note", m.note},
                        {"train_seconds", m.train_seconds}};
    if (m.available) {
      x["static"] = stats_json(m.stat);
      x["moving"] = stats_json(m.moving);
      x["all"] = stats_json(m.all);
    }
    j["methods"].push_back(x);
  }
  j["papers"] = nlohmann::json::array();
  for (const auto& q : kQuotes)
    j["papers"].push_back(
        {{"source", q.source}, {"rig", q.rig}, {"force", q.force}, {"torque", q.torque}});
  j["details"] = r.details;
  return j;
}

}  // namespace zerog::learn
