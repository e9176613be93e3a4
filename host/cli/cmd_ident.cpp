// zerog fit | compare | diagnose | ladder
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>

#include "commands.hpp"
#include "made_for.hpp"
#include "report_script.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/ident/compare.hpp"
#include "zerog/ident/diagnose.hpp"
#include "zerog/ident/events.hpp"
#include "zerog/ident/fit.hpp"
#include "zerog/ident/ft_floor.hpp"
#include "zerog/ident/kinematics_sources.hpp"
#include "zerog/io/effect_file.hpp"
#include "zerog/io/model_file.hpp"

namespace zerog::cli {
namespace {

using model::Effect;

void progress_line(const std::string& s) { std::fprintf(stderr, "%s\n", s.c_str()); }

struct Common {
  std::string log;
  bool json = false;
  bool quiet = false;
  int threads = 2;
  std::string engine = ident::FitOptions{}.engine;  ///< --engine (fit, diagnose, ladder)
  /// --errors-in-variables (fit, diagnose, ladder): ident::FitOptions::errors_in_variables
  std::string errors_in_variables = ident::FitOptions{}.errors_in_variables;
  std::string exclude;  ///< --exclude (fit, compare, diagnose, ladder): ident::ExcludeSpec
};

void add_exclude(CLI::App* c, Common& o) {
  c->add_option("--exclude", o.exclude,
                "Leave rows out: log-time spans START:END (s, as the log's time column says) and "
                "data rows rows:A-B or row:A (1 is the first data row), comma separated; e.g. "
                "the events zerog diagnose names (a contact is not payload physics)")
      ->type_name("SPANS");
}

// The rows --exclude leaves out (1 = out), or empty for none.
std::vector<std::uint8_t> excluded_rows(const Common& c, const ident::Dataset& data) {
  if (c.exclude.empty()) return {};
  return ident::exclude_mask(data, ident::parse_exclude(c.exclude), c.log);
}

std::size_t count_set(const std::vector<std::uint8_t>& m) {
  std::size_t k = 0;
  for (std::uint8_t v : m) k += v ? 1 : 0;
  return k;
}

void add_common(CLI::App* c, Common& o) {
  c->add_option("log", o.log, "Log to read (zerog log format, NAME.csv with NAME.rig.toml)")
      ->required()
      ->check(CLI::ExistingFile);
  c->add_flag("--json", o.json,
              "Print machine-readable JSON on stdout (schema: proto/json_output.md)");
  c->add_flag("-q,--quiet", o.quiet, "No progress lines on stderr");
  c->add_option("--threads", o.threads, "Solver threads")->check(CLI::Range(1, 64));
}

// --engine: how the fit evaluates the block means it compares (ident::FitOptions::engine).
void add_engine(CLI::App* c, Common& o) {
  c->add_option("--engine", o.engine,
                "Fit engine: normal (the block means as block_stats, streamed into the normal "
                "equations and solved without Ceres; a robust --loss runs block_stats), "
                "block_stats (Ceres on each block mean of the prediction from the block's "
                "sufficient statistics, one model evaluation per block) or samples (Ceres with "
                "the model on every sample: the reference, slower); all give the same fit within "
                "1e-6")
      ->check(CLI::IsMember({"normal", "block_stats", "samples"}))
      ->capture_default_str();
}

// --errors-in-variables: the fit corrected for the IMU regressors' noise (ident/eiv.hpp).
void add_errors_in_variables(CLI::App* c, Common& o) {
  c->add_option("--errors-in-variables", o.errors_in_variables,
                "Correct the fit for the noise of the IMU signals it regresses on (corrected "
                "least squares, proto/effects.md): off, on, or auto (on where the log's rig says "
                "its IMU rows are point samples)")
      ->check(CLI::IsMember({"off", "on", "auto"}))
      ->capture_default_str();
}

std::function<void(const std::string&)> progress(const Common& o) {
  if (o.quiet) return nullptr;
  return progress_line;
}

nlohmann::json fit_json(const ident::FitResult& r) {
  nlohmann::json j;
  j["usable"] = r.usable;
  j["termination"] = r.termination;
  j["engine"] = r.engine;
  j["iterations"] = r.iterations;
  j["seconds"] = r.seconds;
  j["samples"] = r.samples;
  j["residual_rms"] = r.residual_rms;
  j["sigma"] = r.sigma;
  j["bic"] = r.bic;
  const ident::EivSummary& e = r.errors_in_variables;
  j["errors_in_variables"] = {{"mode", e.mode}, {"applied", e.applied}, {"reason", e.reason}};
  if (e.applied) {
    j["errors_in_variables"]["gyro_noise_radps"] = e.noise.gyro_radps;
    j["errors_in_variables"]["accel_noise_mps2"] = e.noise.accel_mps2;
    j["errors_in_variables"]["noise_source"] = e.noise_source;
    j["errors_in_variables"]["draws"] = e.draws;
    j["errors_in_variables"]["iterations"] = e.iterations;
    j["errors_in_variables"]["corrected_params"] = e.corrected_params;
    j["errors_in_variables"]["max_shift_std"] = e.max_shift_std;
    j["errors_in_variables"]["max_shift_param"] = e.max_shift_param;
  }
  j["std_kind"] = r.std_kind.empty() ? nlohmann::json(nullptr) : nlohmann::json(r.std_kind);
  j["clusters"] = r.clusters;
  j["warnings"] = nlohmann::json::array();
  for (const auto& w : r.warnings)
    j["warnings"].push_back({{"kind", w.kind}, {"message", w.message}});
  return j;
}

// What the printed +- is (docs/calibrating.md, "What +- means").
std::string std_meaning(const ident::FitResult& r, double cluster_s) {
  if (r.std_kind == "robust" && r.clusters > 1) {
    char b[256];
    std::snprintf(b, sizeof b,
                  "std: the larger of the model-based and the cluster-robust (sandwich, %d "
                  "clusters of %g s) standard deviation",
                  r.clusters, cluster_s);
    return b;
  }
  return "std: model-based ((J^T J)^-1 s^2), right only for white, correctly modelled noise";
}

nlohmann::json consistency_json(const ident::Consistency& c) {
  auto half = [](const ident::Consistency::Half& h) {
    return nlohmann::json{
        {"first_row", h.first_row + 1},
        {"last_row", h.last_row + 1},
        {"usable", h.usable},
        {"note", h.note.empty() ? nlohmann::json(nullptr) : nlohmann::json(h.note)},
        {"mass_kg", h.usable && h.params.effects.has(model::Effect::gravity)
                        ? nlohmann::json(h.params.block(model::Effect::gravity)[0])
                        : nlohmann::json(nullptr)}};
  };
  nlohmann::json j = {{"first_half", half(c.first)},
                      {"second_half", half(c.second)},
                      {"max_half_z", std::isfinite(c.max_half_z) ? nlohmann::json(c.max_half_z)
                                                                 : nlohmann::json(nullptr)},
                      {"max_half_param", c.max_half_param},
                      {"weighting_usable", c.weighting_usable},
                      {"max_weight_shift_std", c.max_weight_shift},
                      {"max_weight_param", c.max_weight_param},
                      {"warnings", nlohmann::json::array()}};
  for (const auto& w : c.warnings)
    j["warnings"].push_back({{"kind", w.kind}, {"message", w.message}});
  return j;
}

void print_consistency(const ident::Consistency& c, const ident::FitResult& r) {
  const bool grav = r.params.effects.has(model::Effect::gravity);
  auto half = [&](const char* name, const ident::Consistency::Half& h) {
    std::printf("  %s half (rows %zu-%zu): ", name, h.first_row + 1, h.last_row + 1);
    if (!h.note.empty() && !h.usable) {
      std::printf("cannot tell: %s\n", h.note.c_str());
      return;
    }
    if (grav && h.std) {
      const double* g = h.params.block(model::Effect::gravity);
      const auto& sd = (*h.std)[model::index(model::Effect::gravity)];
      std::printf("mass %.4f +- %.4f kg, c %.3f %.3f %.3f +- %.3f %.3f %.3f mm", g[0], sd[0],
                  1e3 * g[1], 1e3 * g[2], 1e3 * g[3], 1e3 * sd[1], 1e3 * sd[2], 1e3 * sd[3]);
    }
    if (!h.note.empty()) std::printf(" (%s)", h.note.c_str());
    std::printf("\n");
  };
  std::printf("consistency (fit again on each half of the rows, and with plain weights):\n");
  half("first", c.first);
  half("second", c.second);
  if (std::isfinite(c.max_half_z))
    std::printf("  largest difference between the halves: %.1f std (%s)\n", c.max_half_z,
                c.max_half_param.c_str());
  if (c.weighting_usable)
    std::printf(
        "  plain weights (1 N, 0.1 N*m) instead of the per-axis noise: largest shift %.1f "
        "std (%s)\n",
        c.max_weight_shift, c.max_weight_param.c_str());
  for (const auto& w : c.warnings)
    std::printf("warning (%s): %s\n", w.kind.c_str(), w.message.c_str());
}

std::string param_table(const model::ModelParams& p, const std::optional<ident::ParamArray>& std,
                        const model::ModelParams* truth, const std::vector<double>& user_std = {}) {
  std::string out;
  char line[256];
  std::snprintf(line, sizeof line, "%-20s %-10s %14s %12s %-8s%s\n", "effect", "parameter", "value",
                "std", "unit", truth ? "        truth   (est-truth)/std" : "");
  out += line;
  for (Effect e : model::kAllEffects) {
    if (!p.effects.has(e)) continue;
    const auto& ei = model::info(e);
    if (ei.num_params == 0) {
      std::snprintf(line, sizeof line, "%-20s (no parameters of its own)\n", ei.name);
      out += line;
    }
    for (int i = 0; i < ei.num_params; ++i) {
      const double v = p.block(e)[i];
      const double s = std ? (*std)[model::index(e)][i] : std::nan("");
      std::snprintf(line, sizeof line, "%-20s %-10s %14.6g %12.3g %-8s", i == 0 ? ei.name : "",
                    ei.params[i].name, v, s, ei.params[i].unit);
      out += line;
      if (truth) {
        const double t = truth->effects.has(e) ? truth->block(e)[i] : 0.0;
        std::snprintf(line, sizeof line, " %12.6g %10.2f", t, (v - t) / s);
        out += line;
      }
      out += "\n";
    }
  }
  // User-defined effects (proto/user_effects.md): one row per term.
  const model::UserEffects& u = p.user;
  for (int j = 0; j < u.num_terms; ++j) {
    const model::UserTerm& t = u.terms[static_cast<std::size_t>(j)];
    const double v = u.coeff[static_cast<std::size_t>(j)];
    const double s = static_cast<std::size_t>(j) < user_std.size()
                         ? user_std[static_cast<std::size_t>(j)]
                         : std::nan("");
    const std::string name = "@" + io::user_effect_name(u, t.effect);
    const std::string term = io::term_axis_name(t) + "*" + io::basis_text(t.basis);
    std::snprintf(line, sizeof line, "%-20s %-10s %14.6g %12.3g %s\n", name.c_str(), term.c_str(),
                  v, s, io::coefficient_unit(t).c_str());
    out += line;
  }
  return out;
}

// A usable fit as a model file; an unusable one is refused, so nothing gets written.
io::ModelFile fitted_model_file(const ident::FitResult& r, const formats::Rig& rig,
                                const std::string& log_path, const ident::Dataset& data) {
  if (!r.usable)
    throw std::runtime_error("the fit is not usable (" + r.termination + "); nothing written");
  io::ModelFile m;
  m.params = r.params;
  m.std = r.std;
  m.user_std = r.user_std;
  m.rig_name = rig.name;
  m.extra["fit"] = fit_json(r);
  m.extra["fit"]["log"] = log_path;
  // Rows without time: a drift is per row there (zerog export refuses to deploy it).
  m.extra["fit"]["static_rows"] = data.columns.static_rows;
  // Which source (IMU, or the robot's joints or pose) fed which effect (proto/json_output.md).
  m.extra["fit"]["kinematics_sources"] =
      ident::kinematics_json(ident::kinematics_feeds(r.params.effects, data), data);
  return m;
}

// Writes the model (if `out` is given, never over `inputs`) and, with --json, prints it.
// Returns true when JSON was printed (then nothing else goes to stdout).
bool write_fitted_model(const Common& c, const io::ModelFile& m, const std::string& out,
                        const std::vector<std::filesystem::path>& inputs) {
  if (!out.empty()) io::write_model(m, out, inputs);
  if (!c.json) return false;
  nlohmann::json j = io::to_json(m);
  j["kind"] = "zerog-fit";
  j["output"] = out.empty() ? nlohmann::json(nullptr) : nlohmann::json(out);
  std::cout << j.dump(2) << "\n";
  return true;
}

// The solver settings `zerog fit` and `zerog fit --tool-change` take alike from the command line
// (ident::FitOptions, ident::ToolChangeOptions).
template <typename Options>
void set_solver_options(Options& o, const Common& c, const std::string& loss, double loss_scale,
                        int max_iter, int block_samples) {
  o.loss = loss;
  o.loss_scale = loss_scale;
  o.max_iterations = max_iter;
  o.block_samples = block_samples;
  o.threads = c.threads;
  o.engine = c.engine;
  o.errors_in_variables = c.errors_in_variables;
  o.progress = progress(c);
}

void run_fit(const Common& c, const std::string& effects, const std::string& out,
             const std::string& loss, double loss_scale, int max_iter, int block_samples,
             const std::string& truth_path, const std::string& std_kind, double cluster_s,
             bool consistency) {
  // Streamed: the log's rows go straight into the dataset, never held whole (issue 16).
  formats::Rig rig;
  const ident::Dataset data = ident::read_dataset(c.log, &rig);
  ident::FitOptions o;
  const io::ModelSpec spec = io::parse_model_spec(effects);
  o.effects = spec.effects;
  o.user = spec.user;
  set_solver_options(o, c, loss, loss_scale, max_iter, block_samples);
  o.std_kind = std_kind;
  o.cluster_s = cluster_s;
  const std::vector<std::uint8_t> out_rows = excluded_rows(c, data);
  std::vector<std::uint8_t> keep;
  if (!out_rows.empty()) {
    keep.resize(out_rows.size());
    for (std::size_t i = 0; i < keep.size(); ++i) keep[i] = out_rows[i] ? 0 : 1;
    o.mask = &keep;
  }
  const ident::FitResult r = ident::fit(data, o);
  io::ModelFile m = fitted_model_file(r, rig, c.log, data);
  // The model remembers what its fit left out: zerog diagnose of it on the same log leaves it
  // out too (the loop goes on without the events).
  if (!out_rows.empty())
    m.extra["fit"]["exclude"] = {{"spans", c.exclude}, {"rows", count_set(out_rows)}};
  std::optional<ident::Consistency> cons;
  if (consistency && r.usable) {
    if (o.progress) o.progress("fit: consistency: each half of the rows, and plain weights");
    cons = ident::check_consistency(data, o, r);
    m.extra["fit"]["consistency"] = consistency_json(*cons);
  }
  std::optional<io::ModelFile> truth;
  if (!truth_path.empty()) truth = io::read_model(truth_path);
  if (write_fitted_model(c, m, out, {c.log, formats::rig_path_for(c.log)})) return;
  std::printf("fitted %s on %zu samples in %.2f s (%d iterations): %s\n",
              io::model_spec_string(r.params.effects, r.params.user, spec.files).c_str(), r.samples,
              r.seconds, r.iterations, r.termination.c_str());
  if (!out_rows.empty())
    std::printf("left out (--exclude %s): %zu of %zu rows\n", c.exclude.c_str(),
                count_set(out_rows), data.size());
  std::printf("%s",
              param_table(r.params, r.std, truth ? &truth->params : nullptr, r.user_std).c_str());
  std::printf("%s\n", std_meaning(r, cluster_s).c_str());
  std::printf("residual RMS: Fx %.3f  Fy %.3f  Fz %.3f N   Mx %.3f  My %.3f  Mz %.3f N*m\n",
              r.residual_rms[0], r.residual_rms[1], r.residual_rms[2], r.residual_rms[3],
              r.residual_rms[4], r.residual_rms[5]);
  std::printf(
      "%s",
      ident::format_kinematics(ident::kinematics_feeds(r.params.effects, data), data).c_str());
  const ident::EivSummary& eiv = r.errors_in_variables;
  if (eiv.applied)
    std::printf(
        "errors in variables: %s; IMU row noise (%s) gyro %.3g %.3g %.3g rad/s, accel %.3g %.3g "
        "%.3g m/s^2; largest shift %.2f std (%s)\n",
        eiv.reason.c_str(), eiv.noise_source.c_str(), eiv.noise.gyro_radps[0],
        eiv.noise.gyro_radps[1], eiv.noise.gyro_radps[2], eiv.noise.accel_mps2[0],
        eiv.noise.accel_mps2[1], eiv.noise.accel_mps2[2], eiv.max_shift_std,
        eiv.max_shift_param.c_str());
  else if (eiv.mode != "auto")
    std::printf("errors in variables: not applied (%s)\n", eiv.reason.c_str());
  for (const auto& w : r.warnings)
    std::printf("warning (%s): %s\n", w.kind.c_str(), w.message.c_str());
  if (cons) print_consistency(*cons, r);
  if (!out.empty()) std::printf("wrote %s\n", out.c_str());
}

// `zerog fit --tool-change`: re-identify the payload (gravity: mass, centre of mass) on the
// static samples of a log with the rest of a previous fit frozen (paper 001_… §3.2, Appendix A).
void run_tool_change(const Common& c, const std::string& base_path, const std::string& out,
                     const std::string& loss, double loss_scale, int max_iter, int block_samples,
                     const std::string& truth_path) {
  if (base_path.empty())
    throw std::invalid_argument(
        "--tool-change needs --base: the previous fit whose sensor model "
        "(bias and other effects) stays frozen");
  formats::Rig rig;
  const ident::Dataset data = ident::read_dataset(c.log, &rig);
  const io::ModelFile base = io::read_model(base_path);
  ident::ToolChangeOptions o;
  set_solver_options(o, c, loss, loss_scale, max_iter, block_samples);
  const ident::ToolChangeResult tc = ident::fit_tool_change(data, base.params, o);
  const ident::FitResult& r = tc.fit;
  io::ModelFile m = fitted_model_file(r, rig, c.log, data);
  std::optional<io::ModelFile> truth;
  if (!truth_path.empty()) truth = io::read_model(truth_path);
  // Frozen effects carry the base fit's values and so its standard deviations.
  if (m.std && base.std) {
    for (Effect e : model::kAllEffects)
      if (tc.frozen.has(e)) (*m.std)[model::index(e)] = (*base.std)[model::index(e)];
  }
  m.extra["fit"]["tool_change"] = {{"base", base_path},
                                   {"frozen", io::effect_list_string(tc.frozen)},
                                   {"static_samples", tc.static_samples},
                                   {"dwells", tc.dwells},
                                   {"gravity_spread_deg", tc.spread_deg}};
  if (write_fitted_model(c, m, out, {c.log, formats::rig_path_for(c.log), base_path})) return;
  std::printf(
      "tool change: %zu of %zu samples static (%zu dwells), %zu fitted; frozen from %s: %s\n",
      tc.static_samples, data.size(), tc.dwells, r.samples, base_path.c_str(),
      io::effect_list_string(tc.frozen).c_str());
  std::printf("gravity directions in the sensor frame spread %.1f deg\n", tc.spread_deg);
  std::printf("fitted gravity in %.2f s (%d iterations): %s\n", r.seconds, r.iterations,
              r.termination.c_str());
  const double* g = r.params.block(Effect::gravity);
  const double* tg = truth ? truth->params.block(Effect::gravity) : nullptr;
  auto sd = [&](int k) {
    return r.std ? (*r.std)[model::index(Effect::gravity)][k] : std::nan("");
  };
  std::printf("  mass %12.4f +- %.4f kg", g[0], sd(0));
  if (tg) std::printf("   truth %.4f kg, error %+.3f %%", tg[0], 100.0 * (g[0] - tg[0]) / tg[0]);
  std::printf("\n");
  for (int k = 1; k < 4; ++k) {
    std::printf("  c%c   %12.3f +- %.3f mm", "xyz"[k - 1], 1000.0 * g[k], 1000.0 * sd(k));
    if (tg)
      std::printf("   truth %.3f mm, error %+.3f mm", 1000.0 * tg[k], 1000.0 * (g[k] - tg[k]));
    std::printf("\n");
  }
  std::printf(
      "residual RMS (static samples): Fx %.3f  Fy %.3f  Fz %.3f N   Mx %.3f  My %.3f  Mz %.3f "
      "N*m\n",
      r.residual_rms[0], r.residual_rms[1], r.residual_rms[2], r.residual_rms[3], r.residual_rms[4],
      r.residual_rms[5]);
  for (const auto& w : r.warnings)
    std::printf("warning (%s): %s\n", w.kind.c_str(), w.message.c_str());
  if (!out.empty()) std::printf("wrote %s\n", out.c_str());
}

// The floors' keys of compare and ladder --json (proto/json_output.md): null without --truth;
// the sensor floor is null, and sensor_floor_note says why, when the truth names no clean log.
void floors_into(nlohmann::json& j, const ident::Floors* f) {
  j["true_model_reference"] = f ? ident::to_json(f->reference) : nlohmann::json(nullptr);
  j["sensor_floor"] = f && f->sensor ? ident::to_json(*f->sensor) : nlohmann::json(nullptr);
  j["clean_signals_log"] = f && f->sensor ? nlohmann::json(f->clean_log) : nlohmann::json(nullptr);
  j["sensor_floor_note"] =
      f && !f->sensor ? nlohmann::json(f->sensor_note) : nlohmann::json(nullptr);
}

void run_compare(const Common& c, const std::string& model_path, const std::string& truth_path,
                 int bins) {
  const ident::Dataset data = ident::read_dataset(c.log);
  const io::ModelFile m = io::read_model(model_path);
  ident::check_signals(m.params.effects, data);
  ident::check_signals(m.params.user, data);
  const auto res = ident::residuals(m.params, data);
  const std::vector<std::uint8_t> out_rows = excluded_rows(c, data);
  std::vector<std::uint8_t> keep;
  for (std::uint8_t v : out_rows) keep.push_back(v ? 0 : 1);
  const std::vector<std::uint8_t>* kept = out_rows.empty() ? nullptr : &keep;
  const ident::Comparison cmp = ident::compare(res, data, kept, bins);
  // Where it fails, in time: the residual over the log, and the spans that stand out.
  const auto line = ident::timeline(res, data, out_rows.empty() ? nullptr : &out_rows);
  const ident::SpanScan scan = ident::find_spans(res, data, out_rows.empty() ? nullptr : &out_rows);
  std::optional<ident::Floors> floors;
  if (!truth_path.empty()) floors = ident::floors(truth_path, data, kept);
  const ident::FtFloor ft = ident::ft_floor(data);
  const ident::ErrorVsFloor error{cmp.stat.force_rms, cmp.stat.torque_rms, cmp.moving.force_rms,
                                  cmp.moving.torque_rms};
  if (c.json) {
    nlohmann::json j = ident::to_json(cmp);
    j["kind"] = "zerog-compare";
    j["ft_floor"] = ident::to_json(ft, &error);
    j["version"] = 2;
    j["log"] = c.log;
    j["model"] = model_path;
    j["effects"] = io::effect_list_string(m.params.effects);
    j["exclude"] = c.exclude.empty() ? nlohmann::json(nullptr) : nlohmann::json(c.exclude);
    j["timeline"] = ident::to_json(line);
    j["span_scan"] = ident::to_json(scan);
    floors_into(j, floors ? &*floors : nullptr);
    std::cout << j.dump(2) << "\n";
    return;
  }
  std::printf("model %s (%s) against %s, %zu samples (%zu static, %zu moving)\n",
              model_path.c_str(), io::effect_list_string(m.params.effects).c_str(), c.log.c_str(),
              cmp.all.count, cmp.stat.count, cmp.moving.count);
  if (!out_rows.empty())
    std::printf("left out (--exclude %s): %zu rows\n", c.exclude.c_str(), count_set(out_rows));
  std::printf("%s", ident::format_comparison(cmp, floors ? &*floors : nullptr).c_str());
  std::printf("%s", ident::format_ft_floor(ft, &error).c_str());
  if (!scan.possible) {
    std::printf("in time: %s\n", scan.note.c_str());
  } else if (scan.spans.empty()) {
    std::printf("in time: no span stands out (steps above %.1f of their spread over %.2f s)\n",
                scan.z_step, scan.window_s);
  } else {
    std::printf("in time: %zu span(s) stand out%s:\n%s", scan.spans.size(),
                scan.recurring ? " (recurring through the log: the model's, not events)" : "",
                ident::format_spans(scan.spans).c_str());
    if (!scan.recurring)
      std::printf("zerog diagnose %s -m %s tells events from physics\n", c.log.c_str(),
                  model_path.c_str());
  }
}

// "@a.toml,@b.toml": each file one candidate (diagnose and ladder --candidates).
std::vector<ident::UserCandidate> user_candidates(const std::string& list) {
  std::vector<ident::UserCandidate> out;
  for (const std::string& item : io::split_list(list)) {
    if (item.front() != '@')
      throw std::invalid_argument("--candidates takes effect files as @FILE, not '" + item + "'");
    ident::UserCandidate c;
    c.source = item.substr(1);
    io::read_effect_file(c.source, c.effect);
    out.push_back(std::move(c));
  }
  return out;
}

// A new file beside the log (proto/paths.md): LOG's name with STEM and EXT, STEM2, STEM3, ...
// when that exists. The suggested command's output (.fit.json) thus never overwrites a file, the
// model given to diagnose included, and a discovered law (.discovered.toml) never replaces the
// law of an earlier turn.
std::string new_file_beside(const std::string& log, const std::string& stem, const char* ext) {
  for (int n = 1;; ++n) {
    const std::filesystem::path p =
        formats::beside_input(log, stem + (n == 1 ? std::string() : std::to_string(n)) + ext);
    std::error_code ec;
    if (!std::filesystem::exists(p, ec) && !ec) return p.string();
  }
}

std::string suggested_fit_out(const std::string& log) {
  return new_file_beside(log, ".fit", ".json");
}

// The options of `zerog diagnose` and `zerog ladder` (add_*_command below).
struct DiagnoseArgs {
  Common c;
  std::string model_path, effects, candidates;
  std::string discovered_out;  // empty: beside the log
  double block = 0.0;          // 0: chosen from the log
  bool no_discover = false, exact_candidates = false;
};

struct LadderArgs {
  Common c;
  std::string start = io::effect_list_string(model::kMinimalModel);
  double min_gain = 0.02;
  double block = 0.0;  // 0: chosen from the log
  std::string out, truth, plot, candidates;
  bool exact_candidates = false;
};

// What diagnose leaves out: --exclude, else what the model's own fit on this log left out.
std::string inherited_exclude(const DiagnoseArgs& a, std::optional<io::ModelFile>& m) {
  std::string exclude = a.c.exclude;
  if (exclude.empty() && m && m->extra.contains("fit") && m->extra["fit"].contains("exclude") &&
      m->extra["fit"].contains("log") && m->extra["fit"]["log"].is_string()) {
    std::error_code ec;
    const std::string fitted_log = m->extra["fit"]["log"].get<std::string>();
    if (std::filesystem::equivalent(fitted_log, a.c.log, ec) && !ec) {
      exclude = m->extra["fit"]["exclude"].value("spans", std::string());
      if (!exclude.empty() && !a.c.quiet)
        std::fprintf(stderr, "diagnose: leaving out what %s's fit left out: %s\n",
                     a.model_path.c_str(), exclude.c_str());
    }
  }
  return exclude;
}

void run_diagnose(const DiagnoseArgs& a) {
  const ident::Dataset data = ident::read_dataset(a.c.log);
  ident::DiagnoseOptions o;
  o.block_s = a.block;
  o.log_path = a.c.log;
  o.progress = progress(a.c);
  o.fit.threads = a.c.threads;
  o.fit.engine = a.c.engine;
  o.fit.errors_in_variables = a.c.errors_in_variables;
  o.discover = !a.no_discover;
  o.exact_candidates = a.exact_candidates;
  o.fit_out = suggested_fit_out(a.c.log);
  // By default a new file: a law of an earlier turn of the loop keeps its file.
  o.discovery_path = a.discovered_out.empty() ? new_file_beside(a.c.log, ".discovered", ".toml")
                                              : a.discovered_out;
  o.user_candidates = user_candidates(a.candidates);
  std::optional<io::ModelFile> m;
  if (!a.model_path.empty()) {
    m = io::read_model(a.model_path);
    o.fit.effects = m->params.effects;
    o.fit.user = m->params.user;
    o.fit.initial = &m->params;
    // The suggested command names the model file for its user effects (@fit.json).
    o.model_text = io::model_spec_string(m->params.effects, m->params.user,
                                         m->params.user.empty()
                                             ? std::vector<std::filesystem::path>{}
                                             : std::vector<std::filesystem::path>{a.model_path});
  } else {
    // A static table feeds no inertia: its default model is bias and gravity.
    const std::string fallback = data.columns.static_rows
                                     ? std::string("bias,gravity")
                                     : io::effect_list_string(model::kDefaultModel);
    const io::ModelSpec spec = io::parse_model_spec(a.effects.empty() ? fallback : a.effects);
    o.fit.effects = spec.effects;
    o.fit.user = spec.user;
    o.model_text = io::model_spec_string(spec.effects, spec.user, spec.files);
  }
  // What this diagnosis is of (zerog report checks it): the model, its file, the log.
  nlohmann::json made_for = {
      {"model", model_identity(o.fit.effects, o.fit.user, m ? a.model_path : std::string())},
      {"log", log_identity(a.c.log)}};
  const std::string exclude = inherited_exclude(a, m);
  std::vector<std::uint8_t> out_rows;
  if (!exclude.empty())
    out_rows = ident::exclude_mask(data, ident::parse_exclude(exclude), a.c.log);
  if (!out_rows.empty()) {
    o.exclude = &out_rows;
    o.exclude_text = exclude;
  }
  const ident::Diagnosis d = ident::diagnose(data, o);
  if (a.c.json) {
    nlohmann::json j = ident::to_json(d);
    j["version"] = 3;  // "made_for", events (proto/json_output.md)
    j["made_for"] = std::move(made_for);
    std::cout << j.dump(2) << "\n";
  } else {
    std::printf("%s", ident::format_diagnosis(d).c_str());
  }
}

// The F/T-only floor against the last step's held-out error (ft_floor.hpp): into j, and its text.
std::string ladder_ft_floor(nlohmann::json& j, const std::vector<ident::LadderStep>& steps,
                            const ident::Dataset& data) {
  const ident::FtFloor ft = ident::ft_floor(data);
  j["ft_floor"] = ident::to_json(ft, nullptr);
  std::string ft_text = ident::format_ft_floor(ft, nullptr);
  if (ft.known && !steps.empty() && ft.force_rms > 0.0 && ft.torque_rms > 0.0) {
    const ident::ErrorStats& last = steps.back().heldout.stats;
    j["ft_floor"]["heldout_ratio"] = {{"force", last.force_rms / ft.force_rms},
                                      {"torque", last.torque_rms / ft.torque_rms}};
    char line[200];
    std::snprintf(line, sizeof line,
                  "  the last step's held-out error against it: %.2fx (force) / %.2fx "
                  "(torque)\n",
                  last.force_rms / ft.force_rms, last.torque_rms / ft.torque_rms);
    ft_text += line;
  }
  return ft_text;
}

// The ladder's plot (matplotlib, through the report script) into `plot`, never over an input.
void plot_ladder(const nlohmann::json& j, const std::string& plot,
                 const std::vector<std::filesystem::path>& inputs) {
  for (const auto& in : inputs)
    if (std::filesystem::weakly_canonical(in) == std::filesystem::weakly_canonical(plot))
      throw std::runtime_error(plot + " is an input of this run; refusing to overwrite it");
  const std::string tmp = plot + ".ladder.json.tmp";
  formats::write_file_atomic(tmp, j.dump() + "\n", inputs);
  try {
    run_report_script({"--ladder-plot", tmp, plot});
  } catch (...) {
    std::filesystem::remove(tmp);
    throw;
  }
  std::filesystem::remove(tmp);
}

void run_ladder(const LadderArgs& a) {
  const ident::Dataset data = ident::read_dataset(a.c.log);
  ident::LadderOptions o;
  o.min_gain = a.min_gain;
  o.diagnose.block_s = a.block;
  o.diagnose.log_path = a.c.log;
  o.diagnose.progress = progress(a.c);
  o.diagnose.fit.threads = a.c.threads;
  o.diagnose.fit.engine = a.c.engine;
  o.diagnose.fit.errors_in_variables = a.c.errors_in_variables;
  o.diagnose.exact_candidates = a.exact_candidates;
  const io::ModelSpec spec = io::parse_model_spec(a.start);
  o.diagnose.fit.effects = spec.effects;
  o.diagnose.fit.user = spec.user;
  o.diagnose.user_candidates = user_candidates(a.candidates);
  const std::vector<std::uint8_t> out_rows = excluded_rows(a.c, data);
  if (!out_rows.empty()) {
    o.diagnose.exclude = &out_rows;
    o.diagnose.exclude_text = a.c.exclude;
  }
  const ident::BlockChoice split = ident::choose_blocks(data, a.block);
  if (o.diagnose.progress) o.diagnose.progress("ladder: held-out split: " + split.text);
  const auto steps = ident::ladder(data, o);
  nlohmann::json j = ident::to_json(steps);
  j["split"] = ident::to_json(split);
  // Which source fed which effect of the ladder's last (largest) model.
  const auto feeds =
      ident::kinematics_feeds(steps.empty() ? o.diagnose.fit.effects : steps.back().effects, data);
  j["kinematics_sources"] = ident::kinematics_json(feeds, data);
  std::optional<ident::Floors> floors;
  if (!a.truth.empty()) {
    const auto mask = ident::heldout_mask(data, split.block_s);
    floors = ident::floors(a.truth, data, &mask);
  }
  j["version"] = 3;  // the floors' keys below, "made_for" (proto/json_output.md)
  floors_into(j, floors ? &*floors : nullptr);
  const std::string ft_text = ladder_ft_floor(j, steps, data);
  // A ladder is made for its log; it climbs from its own start, not from one model.
  j["made_for"] = {{"model", nullptr},
                   {"start", model_identity(spec.effects, spec.user)["effects"]},
                   {"log", log_identity(a.c.log)}};
  const std::vector<std::filesystem::path> inputs = {a.c.log, formats::rig_path_for(a.c.log)};
  if (!a.out.empty()) formats::write_file_atomic(a.out, j.dump(2) + "\n", inputs);
  if (!a.plot.empty()) plot_ladder(j, a.plot, inputs);
  if (a.c.json) {
    std::cout << j.dump(2) << "\n";
    return;
  }
  std::printf("held-out split: %s\n", split.text.c_str());
  std::printf("%s", ident::format_ladder(steps).c_str());
  std::printf("%s", ident::format_kinematics(feeds, data).c_str());
  if (floors) std::printf("%s", ident::format_floors(*floors, "held-out").c_str());
  std::printf("%s", ft_text.c_str());
  if (!a.out.empty()) std::printf("wrote %s\n", a.out.c_str());
  if (!a.plot.empty()) std::printf("plotted %s\n", a.plot.c_str());
}

void add_fit_command(CLI::App& app) {
  auto c = std::make_shared<Common>();
  auto effects = std::make_shared<std::string>(io::effect_list_string(model::kDefaultModel));
  auto out = std::make_shared<std::string>();
  auto loss = std::make_shared<std::string>("none");
  auto loss_scale = std::make_shared<double>(3.0);
  auto max_iter = std::make_shared<int>(50);
  auto truth = std::make_shared<std::string>();
  auto block_samples = std::make_shared<int>(8);
  auto tool_change = std::make_shared<bool>(false);
  auto std_kind = std::make_shared<std::string>("robust");
  auto cluster_s = std::make_shared<double>(10.0);
  auto no_consistency = std::make_shared<bool>(false);
  auto base = std::make_shared<std::string>();
  CLI::App* s = app.add_subcommand("fit", "Fit a model (a list of effects) to a log with Ceres");
  add_common(s, *c);
  add_exclude(s, *c);
  add_engine(s, *c);
  add_errors_in_variables(s, *c);
  auto* effects_opt =
      s->add_option("-e,--effects", *effects,
                    "Comma-separated effects (proto/effects.md); @FILE adds a user-defined "
                    "effect (proto/user_effects.md)")
          ->capture_default_str();
  s->add_flag("--tool-change", *tool_change,
              "After an end-effector change: fit only the payload (gravity: mass, centre of "
              "mass) on the static samples of LOG, every other effect of --base held at its "
              "values (paper 001 section 3.2)")
      ->excludes(effects_opt);
  s->add_option("--base", *base, "With --tool-change: the previous fit (model file) to keep")
      ->check(CLI::ExistingFile);
  s->add_option("-o,--out", *out, "Model file to write (JSON, written atomically)");
  s->add_option("--loss", *loss, "Robust loss: none, huber, cauchy")
      ->check(CLI::IsMember({"none", "huber", "cauchy"}))
      ->capture_default_str();
  s->add_option("--loss-scale", *loss_scale, "Robust loss scale, in per-axis noise units")
      ->capture_default_str();
  s->add_option("--max-iterations", *max_iter, "Solver iterations per pass")->capture_default_str();
  s->add_option("--block-samples", *block_samples,
                "Compare model and measurement on means of this many consecutive samples (1 = "
                "each sample)")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  s->add_option("--truth", *truth, "Truth model (from zerog sim) to print beside the estimates");
  s->add_option("--std", *std_kind,
                "What +- is: robust (the larger of the model-based and a cluster-robust "
                "sandwich standard deviation: coloured noise, a model that misses something) or "
                "white (model-based only: white, correctly modelled noise)")
      ->check(CLI::IsMember({"robust", "white"}))
      ->capture_default_str();
  s->add_option("--cluster", *cluster_s,
                "Cluster length of the robust standard deviation, s of log time (a table's rows "
                "are each a cluster)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  s->add_flag("--no-consistency", *no_consistency,
              "Skip the check that fits each half of the rows and plain weights again");
  s->callback([=] {
    if (*tool_change) {
      run_tool_change(*c, *base, *out, *loss, *loss_scale, *max_iter, *block_samples, *truth);
      return;
    }
    if (!base->empty()) throw std::invalid_argument("--base is for --tool-change");
    run_fit(*c, *effects, *out, *loss, *loss_scale, *max_iter, *block_samples, *truth, *std_kind,
            *cluster_s, !*no_consistency);
  });
}

void add_compare_command(CLI::App& app) {
  auto c = std::make_shared<Common>();
  auto model_path = std::make_shared<std::string>();
  auto truth = std::make_shared<std::string>();
  auto bins = std::make_shared<int>(6);
  CLI::App* s = app.add_subcommand(
      "compare",
      "Measured against predicted per axis: RMS and max error, static/moving, by joint angle");
  add_common(s, *c);
  add_exclude(s, *c);
  s->add_option("-m,--model", *model_path, "Model file (from zerog fit)")
      ->required()
      ->check(CLI::ExistingFile);
  s->add_option("--truth", *truth,
                "Truth model (from zerog sim): also print the true-model reference and the "
                "sensor floor")
      ->check(CLI::ExistingFile);
  s->add_option("--bins", *bins, "Joint-angle bins per joint")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  s->callback([=] { run_compare(*c, *model_path, *truth, *bins); });
}

// --exact-candidates, for diagnose and ladder.
void add_exact_candidates(CLI::App* s, bool& exact) {
  s->add_flag(
      "--exact-candidates", exact,
      "Refit every candidate effect (a warm-started fit each) instead of screening them from "
      "one pass of the model with all of them and refitting only those that could be the "
      "best (slower; the screened figures are linearised)");
}

void add_diagnose_command(CLI::App& app) {
  auto a = std::make_shared<DiagnoseArgs>();
  CLI::App* s = app.add_subcommand(
      "diagnose",
      "Rank the effects a model lacks by how much they reduce the error on held-out data");
  add_common(s, a->c);
  add_exclude(s, a->c);
  add_engine(s, a->c);
  add_errors_in_variables(s, a->c);
  s->add_option("-m,--model", a->model_path,
                "Fitted model to diagnose (its effects and start values)")
      ->check(CLI::ExistingFile);
  s->add_option("-e,--effects", a->effects,
                "Or: the effects of the model to diagnose (@FILE: a user-defined effect); "
                "default bias,gravity,linear_inertia,rotational_inertia (a static table: "
                "bias,gravity)");
  s->add_option("--candidates", a->candidates,
                "User-defined effects to try beside the library's: @FILE,@FILE "
                "(proto/user_effects.md)");
  s->add_flag("--no-discover", a->no_discover,
              "When no library effect explains the residual, do not search the signal "
              "dictionary for a law");
  add_exact_candidates(s, a->exact_candidates);
  s->add_option("--discovered-out", a->discovered_out,
                "Where to write a discovered law as an effect file (proto/user_effects.md); "
                "default: beside the log, LOG's name with .discovered.toml");
  s->add_option("--block", a->block,
                "Length of the held-out time blocks, s (every 4th block is held out); default: "
                "60 s when the log holds 8 such blocks, else the log's length / 8 (at least "
                "0.5 s)");
  s->callback([a] { run_diagnose(*a); });
}

void add_ladder_command(CLI::App& app) {
  auto a = std::make_shared<LadderArgs>();
  CLI::App* s = app.add_subcommand("ladder",
                                   "From a minimal model, add the best effect step by step while "
                                   "it pays; print the error at each step");
  add_common(s, a->c);
  add_exclude(s, a->c);
  add_engine(s, a->c);
  add_errors_in_variables(s, a->c);
  s->add_option("--start", a->start, "Effects to start from (@FILE: a user-defined effect)")
      ->capture_default_str();
  s->add_option("--candidates", a->candidates,
                "User-defined effects the ladder may add beside the library's: @FILE,@FILE");
  add_exact_candidates(s, a->exact_candidates);
  s->add_option("--min-gain", a->min_gain,
                "Smallest share of held-out error an effect must remove to be added")
      ->capture_default_str();
  s->add_option("--block", a->block,
                "Length of the held-out time blocks, s; default: 60 s when the log holds 8 "
                "such blocks, else the log's length / 8 (at least 0.5 s)");
  s->add_option("-o,--out", a->out, "Write the ladder as JSON (for zerog report)");
  s->add_option("--truth", a->truth,
                "Truth model (from zerog sim): add the true-model reference and the sensor "
                "floor (held-out blocks)")
      ->check(CLI::ExistingFile);
  s->add_option("--plot", a->plot, "Plot the error at each step into this PNG (matplotlib)");
  s->callback([a] { run_ladder(*a); });
}

}  // namespace

void add_ident_commands(CLI::App& app) {
  add_fit_command(app);
  add_compare_command(app);
  add_diagnose_command(app);
  add_ladder_command(app);
}

}  // namespace zerog::cli
