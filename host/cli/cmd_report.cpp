// zerog report: measured vs predicted, residuals, the ladder and the diagnosis as an HTML page.
// C++ computes everything into a bundle (proto/report_bundle.md); matplotlib draws it
// (host/report/make_report.py). A diagnosis or ladder made for another model or log is refused
// (or, when allowed, labelled as such): their "made_for" (made_for.hpp) must match.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <random>
#include <string>

#include "commands.hpp"
#include "made_for.hpp"
#include "report_script.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/ident/compare.hpp"
#include "zerog/ident/dataset.hpp"
#include "zerog/io/effect_file.hpp"
#include "zerog/io/model_file.hpp"

namespace zerog::cli {
namespace {

namespace fs = std::filesystem;

nlohmann::json read_json(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open");
  try {
    return nlohmann::json::parse(in);
  } catch (const nlohmann::json::parse_error& e) {
    throw std::runtime_error(path + ": " + e.what());
  }
}

struct ReportOptions {
  std::string log, model, truth, ladder, diagnosis, out, title;  // out empty: beside the log
  bool allow_other_diagnosis = false, allow_other_ladder = false;
};

// A diagnosis or ladder document (zerog diagnose --json, zerog ladder --out) and what it was
// made for against the report's model and log (made_for.hpp). One made for another model or log
// is refused (exit status 2, naming both) unless `allow`; then the bundle labels it
// (proto/report_bundle.md, "diagnosis_for"), and the report never shows it as the verdict.
struct Document {
  nlohmann::json doc = nullptr;
  nlohmann::json made_for = nullptr;  // the bundle's {"match", "text"}
};

Document read_checked(const std::string& path, const char* kind, const char* what, bool check_model,
                      const nlohmann::json& model_id, const nlohmann::json& log_id, bool allow,
                      const std::string& rerun, const char* flag) {
  Document d;
  if (path.empty()) return d;
  d.doc = read_json(path);
  if (!d.doc.is_object() || (d.doc.contains("kind") && d.doc["kind"] != kind))
    throw formats::InputError(path, 0, 0,
                              std::string("not a ") + kind + " document (" + what + " of zerog)");
  const MadeForCheck c = check_made_for(d.doc, path, model_id, log_id, check_model);
  std::string text;
  const std::string which = check_model ? "model and log" : "log";
  switch (c.match) {
    case Match::same:
      text = "made " + c.made_for + ", the " + which + " of this report";
      break;
    case Match::other:
      if (!allow)
        throw formats::InputError(path, 0, 0,
                                  std::string("this ") + what + " was made " + c.made_for +
                                      ", the report is " + c.report_for + ": run `" + rerun +
                                      "` again, or pass " + flag + " to include it labelled");
      text = "made " + c.made_for + "; this report is " + c.report_for;
      break;
    case Match::unknown:
      text = "it does not say which " + which +
             " it was made for (written by an older zerog); this report is " + c.report_for;
      break;
  }
  const char* match[] = {"same", "other", "unknown"};
  d.made_for = {{"match", match[static_cast<int>(c.match)]}, {"text", text}};
  return d;
}

// The bundle's data.csv (proto/report_bundle.md): per row the measured and predicted wrench, the
// floors' predictions, the signals to plot the residual against, the held-out flag.
void write_data_csv(const fs::path& bundle, const ident::Dataset& data,
                    const std::vector<ident::Wrench>& res,
                    const std::optional<ident::Floors>& floors, bool with_sensor,
                    const std::vector<std::uint8_t>& heldout) {
  std::ofstream csv(bundle / "data.csv");
  csv << "t_s,moving";
  const char* ax[] = {"Fx", "Fy", "Fz", "Mx", "My", "Mz"};
  for (auto a : ax) csv << "," << a << "_meas";
  for (auto a : ax) csv << "," << a << "_pred";
  if (floors)
    for (auto a : ax) csv << "," << a << "_true";
  if (with_sensor)
    for (auto a : ax) csv << "," << a << "_true_clean";
  if (data.columns.joints) {
    for (int j = 1; j <= 6; ++j) csv << ",q" << j << "_rad";
    for (int j = 1; j <= 6; ++j) csv << ",qd" << j << "_radps";
  }
  if (data.columns.angular_rate) csv << ",omega_norm_radps,omega_dot_norm_radps2";
  if (data.columns.specific_force) csv << ",accel_norm_mps2";
  if (data.columns.temperature) csv << ",temp_C";
  csv << ",heldout\n";
  char buf[64];
  auto put = [&](double v) {
    std::snprintf(buf, sizeof buf, ",%.7g", v);
    csv << buf;
  };
  for (std::size_t i = 0; i < data.size(); ++i) {
    std::snprintf(buf, sizeof buf, "%.6f,%d", data.t_s[i], data.moving[i]);
    csv << buf;
    for (int k = 0; k < 6; ++k) put(data.measured[i][k]);
    for (int k = 0; k < 6; ++k) put(data.measured[i][k] - res[i][k]);
    if (floors)
      for (int k = 0; k < 6; ++k) put(data.measured[i][k] - floors->reference_residuals[i][k]);
    if (with_sensor)
      for (int k = 0; k < 6; ++k) put(data.measured[i][k] - floors->sensor_residuals[i][k]);
    if (data.columns.joints) {
      for (int j = 0; j < 6; ++j) put(data.joints_rad[i][j]);
      for (int j = 0; j < 6; ++j) put(data.joint_vel_radps(i)[j]);
    }
    const double* r = &data.imu[i * 9];
    if (data.columns.angular_rate) {
      put(Eigen::Map<const Eigen::Vector3d>(r + 3).norm());
      put(Eigen::Map<const Eigen::Vector3d>(r + 6).norm());
    }
    if (data.columns.specific_force)
      put(Eigen::Map<const Eigen::Vector3d>(r).norm() - model::kStandardGravity);
    if (data.columns.temperature) put(data.pose(i).temperature_C);
    csv << "," << int(heldout[i]) << "\n";
  }
  if (!csv) throw std::runtime_error((bundle / "data.csv").string() + ": write failed");
}

// The bundle's summary.json: what the report is of, and the documents it shows.
nlohmann::json bundle_summary(const ReportOptions& o, const io::ModelFile& m,
                              const ident::Comparison& cmp, const Document& ladder,
                              const Document& diagnosis, const std::optional<ident::Floors>& floors,
                              bool with_sensor) {
  nlohmann::json summary;
  summary["kind"] = "zerog-report-bundle";
  summary["version"] = 3;
  summary["title"] =
      o.title.empty() ? "zerog report: " + fs::path(o.log).filename().string() : o.title;
  summary["log"] = o.log;
  summary["model"] = o.model;
  summary["effects"] = nlohmann::json::array();
  for (auto e : model::kAllEffects)
    if (m.params.effects.has(e)) summary["effects"].push_back(model::info(e).name);
  // User-defined effects (proto/user_effects.md), one chip each with their terms.
  for (int k = 0; k < m.params.user.num_effects; ++k) {
    std::string terms;
    for (int j = 0; j < m.params.user.num_terms; ++j) {
      const model::UserTerm& t = m.params.user.terms[static_cast<std::size_t>(j)];
      if (t.effect != k) continue;
      terms += (terms.empty() ? "" : ", ") + io::term_axis_name(t) + "*" + io::basis_text(t.basis);
    }
    summary["effects"].push_back("@" + io::user_effect_name(m.params.user, k) + " (" + terms + ")");
  }
  summary["compare"] = ident::to_json(cmp);
  summary["ladder"] = ladder.doc;
  summary["ladder_for"] = ladder.made_for;
  summary["diagnosis"] = diagnosis.doc;
  summary["diagnosis_for"] = diagnosis.made_for;
  summary["true_model_reference"] =
      floors ? ident::to_json(floors->reference) : nlohmann::json(nullptr);
  summary["sensor_floor"] = with_sensor ? ident::to_json(*floors->sensor) : nlohmann::json(nullptr);
  summary["sensor_floor_note"] =
      floors && !with_sensor ? nlohmann::json(floors->sensor_note) : nlohmann::json(nullptr);
  return summary;
}

void run_report(const ReportOptions& o) {
  const formats::Log log = formats::read_log(o.log);
  const ident::Dataset data = ident::make_dataset(log);
  const io::ModelFile m = io::read_model(o.model);
  const nlohmann::json model_id = model_identity(m.params.effects, m.params.user, o.model);
  const nlohmann::json log_id = log_identity(o.log);
  const Document diagnosis = read_checked(
      o.diagnosis, "zerog-diagnosis", "diagnosis", true, model_id, log_id, o.allow_other_diagnosis,
      "zerog diagnose " + o.log + " --model " + o.model + " --json > " + o.diagnosis,
      "--allow-other-diagnosis");
  const Document ladder = read_checked(
      o.ladder, "zerog-ladder", "ladder", false, model_id, log_id, o.allow_other_ladder,
      "zerog ladder " + o.log + " --out " + o.ladder, "--allow-other-ladder");
  ident::check_signals(m.params.effects, data);
  ident::check_signals(m.params.user, data);
  const auto res = ident::residuals(m.params, data);
  const ident::Comparison cmp = ident::compare(res, data);
  std::optional<ident::Floors> floors;
  if (!o.truth.empty()) floors = ident::floors(o.truth, data);
  const bool with_sensor = floors && floors->sensor;
  const auto heldout = ident::heldout_mask(data);

  const fs::path out =
      fs::absolute(o.out.empty() ? formats::beside_input(o.log, ".report") : fs::path(o.out));
  if (fs::exists(out) && !fs::is_directory(out))
    throw std::runtime_error(out.string() + " exists and is not a folder");
  std::random_device rd;
  const fs::path bundle = out.parent_path() / (".zerog-bundle-" + std::to_string(rd()));
  fs::create_directories(bundle);
  struct Cleanup {
    fs::path p;
    ~Cleanup() {
      std::error_code ec;
      fs::remove_all(p, ec);
    }
  } cleanup{bundle};

  write_data_csv(bundle, data, res, floors, with_sensor, heldout);
  const nlohmann::json summary = bundle_summary(o, m, cmp, ladder, diagnosis, floors, with_sensor);
  {
    std::ofstream js(bundle / "summary.json");
    js << summary.dump(1) << "\n";
    if (!js) throw std::runtime_error((bundle / "summary.json").string() + ": write failed");
  }
  run_report_script({bundle.string(), out.string()});
  std::printf("report: %s\n", (out / "index.html").c_str());
}

}  // namespace

void add_report_command(CLI::App& app) {
  auto o = std::make_shared<ReportOptions>();
  CLI::App* s = app.add_subcommand(
      "report", "Write an HTML report: measured vs predicted, residuals, ladder, diagnosis");
  s->add_option("log", o->log, "Log (zerog log format)")->required()->check(CLI::ExistingFile);
  s->add_option("-m,--model", o->model, "Model file (from zerog fit)")
      ->required()
      ->check(CLI::ExistingFile);
  s->add_option("--truth", o->truth,
                "Truth model (from zerog sim), for the true-model reference and the sensor floor")
      ->check(CLI::ExistingFile);
  s->add_option("--ladder", o->ladder, "Ladder JSON (zerog ladder --out) on the same log")
      ->check(CLI::ExistingFile);
  s->add_option("--diagnosis", o->diagnosis,
                "Diagnosis JSON (zerog diagnose --json) of the same model (--model) on the same "
                "log; one made for another model or log is refused")
      ->check(CLI::ExistingFile);
  s->add_flag("--allow-other-diagnosis", o->allow_other_diagnosis,
              "Include a diagnosis made for another model or log, labelled as such (never as "
              "this model's verdict) instead of refusing it");
  s->add_flag("--allow-other-ladder", o->allow_other_ladder,
              "Include a ladder made on another log, labelled as such, instead of refusing it");
  s->add_option("--title", o->title, "Report title");
  s->add_option("-o,--out", o->out,
                "Report folder (replaced atomically); default: beside the log, LOG's name with "
                ".report");
  s->callback([o] { run_report(*o); });
}

}  // namespace zerog::cli
