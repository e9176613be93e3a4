// `zerog export`: the deployed-model file for the cabinet PC (proto/deploy_format.md): physics
// effects and parameters, the rig, and optionally the residual network, float and quantised.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "commands.hpp"
#include "zerog/deploy/quantise.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/ident/dataset.hpp"
#include "zerog/ident/kinematics_sources.hpp"
#include "zerog/infer/deploy_file.hpp"
#include "zerog/infer/inference.hpp"
#include "zerog/io/model_file.hpp"
#include "zerog/learn/network_file.hpp"
#include "zerog/learn/predict.hpp"
#include "zerog/learn/quantised.hpp"
#include "zerog/learn/signals.hpp"

namespace zerog::cli {
namespace {

namespace fs = std::filesystem;

struct ExportArgs {
  std::string model, network, rig, out, calibration;
  int weight_bits = 16;
  double input_clip = 8.0;
  bool quiet = false;
};

// The residual network was trained on the residual of one physics model: deploying it on top of
// another would add a correction for errors that model does not make.
void check_same_physics(const model::ModelParams& deployed, const model::ModelParams& trained,
                        const std::string& network_path) {
  if (deployed.effects != trained.effects)
    throw std::runtime_error(network_path +
                             ": the network corrects the physics model with effects '" +
                             io::effect_list_string(trained.effects) + "', --model has '" +
                             io::effect_list_string(deployed.effects) + "'");
  for (model::Effect e : model::kAllEffects) {
    if (!deployed.effects.has(e)) continue;
    const model::EffectInfo& info = model::info(e);
    for (int k = 0; k < info.num_params; ++k) {
      const double a = deployed.block(e)[k], b = trained.block(e)[k];
      if (std::abs(a - b) > 1e-9 * std::max({1.0, std::abs(a), std::abs(b)}))
        throw std::runtime_error(network_path + ": the network was trained on the residual of " +
                                 "another fit (" + info.name + "." + info.params[k].name + " " +
                                 std::to_string(b) + " there, " + std::to_string(a) +
                                 " in --model); retrain it on this model or export that one");
    }
  }
}

// The ω̇ a model was fitted on against the one zerog-rt's cycle computes (the 5-point central
// difference of the gyro, model::angular_accel_central): an import may have formed it otherwise
// (the gyro's Savitzky–Golay derivative, the robot's, or a logged one; proto/log_format.md), and
// the effects that read ω̇ then run on another signal than they were fitted on. The cycle is not
// changed here: the deploy file records both and export says so (proto/deploy_format.md).
struct OmegaDotCheck {
  std::string fit_source = "not recorded";  ///< kinematics_sources.omega_dot_source, if any
  std::string fit_method;                   ///< kinematics_sources.omega_dot (a sentence)
  std::vector<std::string> effects;         ///< the model's effects that read ω̇
  bool recorded() const { return fit_source != "not recorded"; }
  bool matches() const { return fit_source == ident::kCycleOmegaDotSource; }
};

OmegaDotCheck omega_dot_check(const io::ModelFile& fit) {
  OmegaDotCheck c;
  const nlohmann::json* sources = nullptr;
  if (fit.extra.contains("fit") && fit.extra["fit"].is_object() &&
      fit.extra["fit"].contains("kinematics_sources"))
    sources = &fit.extra["fit"]["kinematics_sources"];
  if (sources != nullptr && sources->is_object()) {
    if (sources->contains("omega_dot_source") && (*sources)["omega_dot_source"].is_string())
      c.fit_source = (*sources)["omega_dot_source"].get<std::string>();
    if (sources->contains("omega_dot") && (*sources)["omega_dot"].is_string())
      c.fit_method = (*sources)["omega_dot"].get<std::string>();
    if (sources->contains("effects") && (*sources)["effects"].is_object())
      for (const auto& [effect, feeds] : (*sources)["effects"].items())
        if (feeds.is_object() && feeds.contains("omega_dot") && feeds["omega_dot"] != "none")
          c.effects.push_back(effect);
    return c;
  }
  // Without the record (a truth file, an older fit): the effects that would read ω̇.
  for (model::Effect e : {model::Effect::linear_inertia, model::Effect::rotational_inertia})
    if (fit.params.effects.has(e)) c.effects.emplace_back(model::info(e).name);
  return c;
}

// What makes a fit unfit to deploy on this rig, said before anything is built.
void check_exportable(const ExportArgs& a, const io::ModelFile& fit, const formats::Rig& rig) {
  if (!fit.rig_name.empty() && fit.rig_name != rig.name)
    throw std::runtime_error(a.model + ": fitted on rig '" + fit.rig_name + "', but " + a.rig +
                             " describes rig '" + rig.name + "'");
  // A drift fitted over a static table's rows is per row, not per second (docs/insight-loop.md,
  // "Small tables"): the cycle would read it as a drift in time.
  if (fit.params.effects.has(model::Effect::bias_drift) && fit.extra.contains("fit") &&
      fit.extra["fit"].value("static_rows", false))
    throw std::runtime_error(a.model +
                             ": its bias_drift was fitted over a static table's rows (per row, not "
                             "per second); fit the drift on a log with time, or export the model "
                             "without bias_drift");
}

// The calibration log of --calibration (the quantisation's ranges and the checks below).
struct Calibration {
  std::optional<formats::Log> log;
  std::optional<ident::Dataset> data;
};

// --network: the residual network, checked against the fit and quantised into m.
void add_network(const ExportArgs& a, const io::ModelFile& fit, learn::NetworkFile& net,
                 Calibration& calib, infer::DeployedModel& m, nlohmann::json& provenance,
                 std::vector<fs::path>& inputs) {
  net = learn::read_network(a.network);
  inputs.emplace_back(a.network);
  if (net.kind != learn::NetworkKind::residual)
    throw std::runtime_error(a.network + ": a '" + learn::kind_name(net.kind) +
                             "' network predicts the whole wrench; zerog export deploys "
                             "'residual' networks on top of the physics model");
  if (net.physics) check_same_physics(fit.params, net.physics->params, a.network);
  deploy::QuantiseOptions q;
  q.weight_bits = a.weight_bits;
  q.input_clip = a.input_clip;
  if (!a.calibration.empty()) {
    calib.log = formats::read_log(a.calibration);
    calib.data = ident::make_dataset(*calib.log);
    inputs.emplace_back(a.calibration);
    provenance["calibration"] = fs::path(a.calibration).filename().string();
  }
  m.network = learn::deploy_network(net, q, calib.data ? &*calib.data : nullptr,
                                    calib.log ? &*calib.log : nullptr);
  provenance["network"] = fs::path(a.network).filename().string();
}

// The warning that the deployed model runs on another ω̇ than it was fitted on.
void warn_omega_dot(const ExportArgs& a, const OmegaDotCheck& omega_dot) {
  std::string effects;
  for (const std::string& e : omega_dot.effects) effects += (effects.empty() ? "" : ", ") + e;
  std::fprintf(stderr,
               "zerog export: warning: %s was fitted on the angular acceleration from '%s' "
               "(%s), but zerog-rt's cycle computes it as '%s' (the 5-point central "
               "difference of the gyro, model::angular_accel_central): %s will run on "
               "another omega_dot than they were fitted on. To deploy what the cycle "
               "computes, import with kinematics = \"imu\" (no imu_dw* columns) and refit; "
               "%s records both (provenance.omega_dot)\n",
               a.model.c_str(), omega_dot.fit_source.c_str(), omega_dot.fit_method.c_str(),
               std::string(ident::kCycleOmegaDotSource).c_str(), effects.c_str(), a.out.c_str());
}

// On the calibration samples: quantised against float, and the firmware's float path against
// the host's prediction (same physics, features and forward pass; a difference means the
// deployed model would not be the trained one: an error).
void check_on_calibration(const ExportArgs& a, const infer::DeployedModel& model,
                          const learn::NetworkFile& net, const Calibration& calib) {
  infer::Inference inf;
  if (const Status st = inf.configure(model); !st.ok())
    throw std::runtime_error("internal: " + st.text());
  double max_f = 0.0, max_m = 0.0;
  std::size_t saturated = 0;
  for (std::size_t i = 0; i < calib.data->size(); ++i) {
    const model::FeatureSignals s = learn::feature_signals(*calib.data, *calib.log, i);
    infer::Wrench q, f;
    if (inf.residual_quantised(s, q).code != infer::StatusCode::ok) ++saturated;
    inf.residual_reference(s, f);
    const infer::Wrench d = (q - f).cwiseAbs();
    max_f = std::max(max_f, d.head<3>().maxCoeff());
    max_m = std::max(max_m, d.tail<3>().maxCoeff());
  }
  std::fprintf(stderr,
               "  quantised vs float on %zu calibration samples: max %.2g N, %.2g N*m "
               "(%zu samples saturated)\n",
               calib.data->size(), max_f, max_m, saturated);
  // The firmware's float path must reproduce the host's prediction (same physics, features
  // and forward pass); a difference means the deployed model would not be the trained one.
  std::vector<model::FeatureSignals> signals(calib.data->size());
  for (std::size_t i = 0; i < signals.size(); ++i)
    signals[i] = learn::feature_signals(*calib.data, *calib.log, i);
  std::vector<infer::Wrench> firmware(signals.size());
  infer::evaluate_sequence(inf, infer::Path::float_reference, signals, firmware);
  const std::vector<ident::Wrench> host = learn::predictions(net, *calib.data, *calib.log);
  double worst = 0.0;
  for (std::size_t i = 0; i < host.size(); ++i)
    worst = std::max(worst, (firmware[i] - host[i]).cwiseAbs().maxCoeff());
  std::fprintf(stderr, "  firmware float path vs zerog train's prediction: max %.2g\n", worst);
  if (!(worst < 1e-6))
    throw std::runtime_error(
        "the deployed float path differs from the trained model's "
        "prediction by " +
        std::to_string(worst) + " on " + a.calibration);
}

void run_export(const ExportArgs& a) {
  const io::ModelFile fit = io::read_model(a.model);
  const formats::Rig rig = formats::read_rig(a.rig);
  check_exportable(a, fit, rig);
  infer::DeployedModel m;
  m.rig = learn::rig_description(rig);
  m.physics = fit.params;
  nlohmann::json provenance = {{"model", fs::path(a.model).filename().string()},
                               {"rig_file", fs::path(a.rig).filename().string()},
                               {"zerog", "0.1.0"}};
  std::vector<fs::path> inputs = {a.model, a.rig};
  learn::NetworkFile net;
  Calibration calib;
  if (!a.network.empty()) add_network(a, fit, net, calib, m, provenance, inputs);
  const OmegaDotCheck omega_dot = omega_dot_check(fit);
  provenance["omega_dot"] = {{"fit", omega_dot.fit_source},
                             {"cycle", ident::kCycleOmegaDotSource},
                             {"matches", omega_dot.recorded() ? nlohmann::json(omega_dot.matches())
                                                              : nlohmann::json(nullptr)},
                             {"effects", omega_dot.effects}};
  if (!omega_dot.fit_method.empty()) provenance["omega_dot"]["fit_method"] = omega_dot.fit_method;
  m.provenance_json = provenance.dump();
  const std::string bytes = infer::serialise_deployed_model(m);
  // Check what we are about to write loads, on this rig, before it replaces anything.
  const infer::LoadResult check = infer::load_deployed_model(bytes, m.rig, a.out);
  if (!check.ok())
    throw std::runtime_error("internal: the exported file does not load: " + check.message);
  formats::write_file_atomic(a.out, bytes, inputs);
  // Said even with --quiet: the deployed model may not run on the signal it was fitted on.
  if (!omega_dot.effects.empty() && omega_dot.recorded() && !omega_dot.matches())
    warn_omega_dot(a, omega_dot);
  if (a.quiet) return;
  std::fprintf(stderr, "zerog export: %s (%zu bytes, CRC-32 %s) for rig '%s'\n", a.out.c_str(),
               bytes.size(), bytes.substr(bytes.find("crc32=") + 6, 8).c_str(), rig.name.c_str());
  std::fprintf(stderr, "  physics: %s\n", io::effect_list_string(m.physics.effects).c_str());
  if (!omega_dot.effects.empty())
    std::fprintf(stderr, "  omega_dot: fitted on '%s', the cycle computes '%s'%s\n",
                 omega_dot.fit_source.c_str(), std::string(ident::kCycleOmegaDotSource).c_str(),
                 !omega_dot.recorded() ? " (the model does not record its source)"
                 : omega_dot.matches() ? " (the same)"
                                       : " (differs: see the warning above)");
  if (!m.network) {
    std::fprintf(stderr, "  network: none (physics only)\n");
    return;
  }
  std::string shape;
  for (int w : m.network->shape.width) shape += (shape.empty() ? "" : "-") + std::to_string(w);
  std::fprintf(stderr,
               "  network: %s, %d-bit weights (per-output-channel scales), int16 activations\n",
               shape.c_str(), a.weight_bits);
  if (calib.data) check_on_calibration(a, *check.model, net, calib);
}

}  // namespace

void add_export_command(CLI::App& app) {
  auto a = std::make_shared<ExportArgs>();
  CLI::App* s = app.add_subcommand(
      "export", "Write the deployed-model file for the cabinet PC (proto/deploy_format.md)");
  s->add_option("--model", a->model, "Fitted model (zerog fit)")
      ->required()
      ->check(CLI::ExistingFile);
  s->add_option("--network", a->network, "Residual network (zerog train --kind residual)")
      ->check(CLI::ExistingFile);
  s->add_option("--rig", a->rig, "Rig description (.rig.toml) the model was fitted for")
      ->required()
      ->check(CLI::ExistingFile);
  s->add_option("--out", a->out, "Deployed-model file to write (atomically), e.g. deploy.zgm")
      ->required();
  s->add_option("--calibration", a->calibration,
                "A log whose samples calibrate the activation ranges and measure the "
                "quantisation error (optional)")
      ->check(CLI::ExistingFile);
  s->add_option("--weight-bits", a->weight_bits, "Weight precision: 16 (default) or 8")
      ->check(CLI::IsMember({8, 16}))
      ->capture_default_str();
  s->add_option("--input-clip", a->input_clip,
                "Normalised inputs saturate beyond this many standard deviations")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  s->add_flag("-q,--quiet", a->quiet, "No summary on stderr");
  s->callback([a] { run_export(*a); });
}

}  // namespace zerog::cli
