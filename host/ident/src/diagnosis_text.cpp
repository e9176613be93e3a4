// What a diagnosis writes: its numbers in words (fmt, a candidate's parameters, a law), the
// effect file of a discovered law and the command that adds it, the JSON and text reports of a
// diagnosis and of the ladder.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "diagnose_internal.hpp"
#include "zerog/io/effect_file.hpp"
#include "zerog/io/model_file.hpp"

namespace zerog::ident::diagnosis {

std::string fmt(const char* f, double a) {
  char b[64];
  std::snprintf(b, sizeof b, f, a);
  return b;
}

std::string param_summary(const Candidate& c) {
  if (c.user >= 0) {
    // The candidate's terms are the last ones of the fitted model's user effects.
    const model::UserEffects& u = c.fit.params.user;
    const int k = u.num_effects - 1;
    std::string s;
    for (int j = 0; j < u.num_terms; ++j) {
      const model::UserTerm& t = u.terms[static_cast<std::size_t>(j)];
      if (t.effect != k) continue;
      s += (s.empty() ? "" : ", ") + io::term_axis_name(t) + "*" + io::basis_text(t.basis) + " = " +
           fmt("%.4g", u.coeff[static_cast<std::size_t>(j)]) + " " + io::coefficient_unit(t);
    }
    return s;
  }
  const auto& ei = model::info(c.effect);
  std::string s;
  const double* v = c.fit.params.block(c.effect);
  // The largest few parameters (by magnitude) in their units.
  std::vector<int> idx(ei.num_params);
  for (int i = 0; i < ei.num_params; ++i) idx[i] = i;
  std::sort(idx.begin(), idx.end(), [&](int a, int b) { return std::abs(v[a]) > std::abs(v[b]); });
  for (int q = 0; q < std::min(ei.num_params, 6); ++q) {
    const int i = idx[q];
    s += (s.empty() ? "" : ", ") + std::string(ei.params[i].name) + " = " + fmt("%.4g", v[i]) +
         " " + ei.params[i].unit;
  }
  if (ei.num_params > 6) s += ", … (" + std::to_string(ei.num_params) + " parameters)";
  return s;
}

std::string law_text(const model::UserEffects& u, int j, double sd) {
  const model::UserTerm& t = u.terms[static_cast<std::size_t>(j)];
  std::ostringstream os;
  os << io::term_axis_name(t) << " += " << fmt("%.4g", u.coeff[static_cast<std::size_t>(j)]);
  if (std::isfinite(sd)) os << " ± " << fmt("%.2g", sd);
  os << " " << io::coefficient_unit(t) << " · " << io::basis_text(t.basis);
  return os.str();
}

// The --effects text of the model as given with `effects` in place of its library effects: the
// library names first, then the model's effect files (as the user wrote them).
std::string model_with(const model::EffectSet& effects, const Diagnosis& d,
                       const DiagnoseOptions& o) {
  const std::string model =
      o.model_text.empty() ? io::model_spec_string(d.model, o.fit.user) : o.model_text;
  const std::string files = model.find(",@") != std::string::npos
                                ? model.substr(model.find(",@"))
                                : (model.rfind('@', 0) == 0 ? "," + model : std::string());
  return io::effect_list_string(effects) + files;
}

// A discovered law's effect file (at o.discovery_path, if set) and the command that adds it. Apart
// from the diagnosis, so that diagnose() writes it only when the verdict is the law's (not for a
// diagnosis it consulted on the way to an event).
void write_discovery(Diagnosis& d, const DiagnoseOptions& o) {
  if (d.verdict != Diagnosis::Verdict::discovered || !d.discovery || o.discovery_path.empty())
    return;
  Discovery& x = *d.discovery;
  std::vector<std::string> comment = {
      "Discovered by zerog diagnose on " + o.log_path + " (proto/user_effects.md).",
      "Held-out error removed: " + fmt("%.1f", 100 * x.gain) + " %" +
          (x.with_effect.empty() ? "."
                                 : " with " + x.with_effect + " (the law alone: " +
                                       fmt("%.1f", 100 * x.law_gain) + " % beyond it).")};
  for (const std::string& law : x.laws) comment.push_back(law);
  io::write_effect_file(o.discovery_path,
                        io::effect_file_text(x.effect, 0, &x.std,
                                             "found by zerog diagnose: no library effect "
                                             "explained the residual",
                                             comment),
                        {o.log_path});
  x.path = o.discovery_path;
  const std::string model =
      x.with_effect.empty()
          ? (o.model_text.empty() ? io::model_spec_string(d.model, o.fit.user) : o.model_text)
          : model_with(x.with_effects, d, o);
  d.command =
      "zerog fit " + o.log_path + " --effects " + model + ",@" + x.path + " --out " + o.fit_out;
}

}  // namespace zerog::ident::diagnosis

namespace zerog::ident {

using diagnosis::fmt;
using model::Effect;

nlohmann::json heldout_json(const HeldOut& h) {
  return {{"force_rms", h.stats.force_rms},
          {"torque_rms", h.stats.torque_rms},
          {"rms", h.stats.rms},
          {"max", h.stats.max_abs},
          {"count", h.stats.count}};
}
nlohmann::json names(const model::EffectSet& s, const model::UserEffects& user = {}) {
  nlohmann::json a = nlohmann::json::array();
  for (Effect e : model::kAllEffects)
    if (s.has(e)) a.push_back(model::info(e).name);
  for (int k = 0; k < user.num_effects; ++k) a.push_back("@" + io::user_effect_name(user, k));
  return a;
}

nlohmann::json to_json(const BlockChoice& b) {
  return {{"block_s", b.block_s},
          {"blocks", b.blocks},
          {"chosen", b.automatic ? "auto" : "given"},
          {"heldout_samples", b.heldout_samples},
          {"training_samples", b.training_samples},
          {"text", b.text}};
}

nlohmann::json to_json(const Diagnosis& d) {
  nlohmann::json j;
  j["kind"] = "zerog-diagnosis";
  j["version"] = 1;
  j["split"] = to_json(d.split);
  j["kinematics_sources"] = d.kinematics_json;
  j["model"] = names(d.model, d.baseline.params.user);
  j["baseline"] = heldout_json(d.baseline_heldout);
  j["noise_rms"] = d.noise_rms;
  j["structured_fraction"] = d.structured_fraction;
  j["candidate_evaluation"] = {{"method", d.candidate_evaluation.method},
                               {"reason", d.candidate_evaluation.reason},
                               {"refitted", d.candidate_evaluation.refitted},
                               {"seconds", d.candidate_evaluation.seconds}};
  j["candidates"] = nlohmann::json::array();
  for (const auto& c : d.candidates) {
    nlohmann::json cj;
    cj["effect"] = c.name;
    cj["heldout"] = heldout_json(c.heldout);
    cj["gain"] = c.gain;
    cj["axis_gain"] = c.axis_gain;
    cj["delta_bic"] = c.delta_bic;
    cj["better_rows"] =
        c.better_rows >= 0.0 ? nlohmann::json(c.better_rows) : nlohmann::json(nullptr);
    cj["figures"] = c.screened ? "screened" : "refitted";
    nlohmann::json p = nlohmann::json::object();
    if (c.user >= 0) {
      const model::UserEffects& u = c.fit.params.user;
      for (int t = 0; t < u.num_terms; ++t)
        if (u.terms[static_cast<std::size_t>(t)].effect == u.num_effects - 1)
          p[io::term_axis_name(u.terms[static_cast<std::size_t>(t)]) + "*" +
            io::basis_text(u.terms[static_cast<std::size_t>(t)].basis)] =
              u.coeff[static_cast<std::size_t>(t)];
    } else {
      const auto& ei = model::info(c.effect);
      for (int i = 0; i < ei.num_params; ++i)
        p[ei.params[i].name] = c.fit.params.block(c.effect)[i];
    }
    cj["params"] = p;
    j["candidates"].push_back(cj);
  }
  const char* kinds[] = {"effect", "none", "nothing_left", "discovered", "event", "outliers"};
  if (d.discovery) {
    const Discovery& x = *d.discovery;
    nlohmann::json dj;
    dj["terms"] = nlohmann::json::array();
    for (int t = 0; t < x.effect.num_terms; ++t) {
      const model::UserTerm& term = x.effect.terms[static_cast<std::size_t>(t)];
      dj["terms"].push_back({{"axis", io::term_axis_name(term)},
                             {"basis", io::basis_text(term.basis)},
                             {"unit", io::coefficient_unit(term)},
                             {"value", x.effect.coeff[static_cast<std::size_t>(t)]},
                             {"std", x.std[static_cast<std::size_t>(t)]},
                             {"z", x.z[static_cast<std::size_t>(t)]},
                             {"law", x.laws[static_cast<std::size_t>(t)]}});
    }
    dj["heldout"] = heldout_json(x.heldout);
    dj["gain"] = x.gain;
    dj["law_gain"] = x.law_gain;
    dj["with_effect"] =
        x.with_effect.empty() ? nlohmann::json(nullptr) : nlohmann::json(x.with_effect);
    dj["seconds"] = x.seconds;
    dj["dictionary_size"] = x.dictionary_size;
    dj["z_threshold"] = x.z_threshold;
    dj["effect_file"] = x.path.empty() ? nlohmann::json(nullptr) : nlohmann::json(x.path);
    j["discovery"] = dj;
  } else {
    j["discovery"] = nullptr;
  }
  j["verdict"] = {
      {"kind", kinds[static_cast<int>(d.verdict)]},
      {"effect", d.verdict == Diagnosis::Verdict::effect ? nlohmann::json(d.candidates[0].name)
                                                         : nlohmann::json(nullptr)},
      {"effect_file", d.verdict == Diagnosis::Verdict::discovered && !d.discovery->path.empty()
                          ? nlohmann::json(d.discovery->path)
                          : nlohmann::json(nullptr)},
      {"text", d.text},
      {"command", d.command.empty() ? nlohmann::json(nullptr) : nlohmann::json(d.command)}};
  j["events"] = nlohmann::json::array();
  for (const Span& s : d.events) j["events"].push_back(to_json(s));
  j["outliers"] = nlohmann::json::array();
  for (const Outlier& x : d.outliers)
    j["outliers"].push_back({{"row", x.row + 1}, {"z", x.z}, {"residual", x.residual}});
  j["span_scan"] = to_json(d.scan);
  j["spans_note"] = d.spans_note.empty() ? nlohmann::json(nullptr) : nlohmann::json(d.spans_note);
  j["exclude"] = d.exclude.empty() ? nlohmann::json(nullptr) : nlohmann::json(d.exclude);
  j["correlated_signals"] = nlohmann::json::array();
  for (const auto& s : d.correlated)
    j["correlated_signals"].push_back(
        {{"signal", s.signal}, {"axis", kAxisNames[s.axis]}, {"correlation", s.correlation}});
  return j;
}

nlohmann::json to_json(const std::vector<LadderStep>& steps) {
  nlohmann::json j;
  j["kind"] = "zerog-ladder";
  j["version"] = 1;
  j["steps"] = nlohmann::json::array();
  for (const auto& s : steps) {
    j["steps"].push_back(
        {{"effects", names(s.effects, s.user)},
         {"added", s.added_name.empty() ? nlohmann::json(nullptr) : nlohmann::json(s.added_name)},
         {"heldout", heldout_json(s.heldout)},
         {"bic", s.bic},
         {"gain", s.gain}});
  }
  return j;
}

std::string format_diagnosis(const Diagnosis& d) {
  std::ostringstream os;
  os << "model: " << io::effect_list_string(d.model) << "\n";
  if (d.verdict == Diagnosis::Verdict::event && d.split.blocks == 0) {
    // Events in a log too short to diagnose without them: no held-out figures to show.
    os << d.kinematics_text << "\n" << d.text << "\n";
    os << "refit without them:  " << d.command << "\n";
    return os.str();
  }
  os << "held-out split: " << d.split.text << "\n";
  os << d.kinematics_text;
  if (d.split.text.rfind("k-fold", 0) == 0) {  // a static table (diagnose_table)
    os << "cross-validated error: force RMS " << fmt("%.3f", d.baseline_heldout.stats.force_rms)
       << " N, torque RMS " << fmt("%.3f", d.baseline_heldout.stats.torque_rms) << " N*m\n\n";
  } else {
    os << "held-out error: force RMS " << fmt("%.3f", d.baseline_heldout.stats.force_rms)
       << " N, torque RMS " << fmt("%.3f", d.baseline_heldout.stats.torque_rms)
       << " N*m; white-noise estimate force "
       << fmt("%.3f", std::sqrt((d.noise_rms[0] * d.noise_rms[0] + d.noise_rms[1] * d.noise_rms[1] +
                                 d.noise_rms[2] * d.noise_rms[2]) /
                                3))
       << " N, torque "
       << fmt("%.3f", std::sqrt((d.noise_rms[3] * d.noise_rms[3] + d.noise_rms[4] * d.noise_rms[4] +
                                 d.noise_rms[5] * d.noise_rms[5]) /
                                3))
       << " N*m (" << fmt("%.0f", 100 * d.structured_fraction) << "% structured)\n\n";
  }
  char line[200];
  const bool table = !d.candidates.empty() && d.candidates[0].better_rows >= 0.0;
  std::snprintf(line, sizeof line, "%-4s %-20s %8s %11s %12s %11s  %s\n", "rank", "effect", "gain",
                "force rms", "torque rms", table ? "better rows" : "dBIC",
                "per-axis gain Fx Fy Fz Mx My Mz");
  os << line;
  int r = 0;
  for (const auto& c : d.candidates) {
    std::snprintf(line, sizeof line, "%-4d %-20s %7.1f%% %9.3f N %8.3f N*m %11.0f%s ", ++r,
                  c.name.c_str(), 100 * c.gain, c.heldout.stats.force_rms,
                  c.heldout.stats.torque_rms, table ? 100 * c.better_rows : c.delta_bic,
                  table ? "%" : " ");
    os << line;
    for (double g : c.axis_gain) os << fmt(" %4.0f%%", 100 * g);
    os << (c.screened ? "  screened" : "") << "\n";
  }
  if (d.candidate_evaluation.method == "screened") {
    os << "candidates: " << d.candidate_evaluation.refitted << " of " << d.candidates.size()
       << " refitted; 'screened' figures are linearised (one Gauss-Newton step from the "
          "baseline; --exact-candidates refits every one)\n";
  } else if (!d.candidate_evaluation.reason.empty()) {
    os << "candidates: " << d.candidate_evaluation.reason << "\n";
  }
  if (!d.correlated.empty()) {
    os << "\nresidual correlates with (held-out):\n";
    for (const auto& s : d.correlated)
      os << "  " << fmt("%+.2f", s.correlation) << "  " << kAxisNames[s.axis] << " ~ " << s.signal
         << "\n";
  }
  if (d.discovery) {
    os << "\ndiscovered in the signal dictionary (" << d.discovery->dictionary_size
       << " columns, |z| > " << fmt("%.1f", d.discovery->z_threshold) << "):\n";
    for (std::size_t t = 0; t < d.discovery->laws.size(); ++t)
      os << "  " << d.discovery->laws[t] << "   (z " << fmt("%.1f", d.discovery->z[t]) << ")\n";
    if (!d.discovery->path.empty()) os << "effect file: " << d.discovery->path << "\n";
  }
  if (!d.spans_note.empty()) os << "\nspans in time: " << d.spans_note << "\n";
  if (!d.exclude.empty()) os << "\nleft out (--exclude): " << d.exclude << "\n";
  os << "\n" << d.text << "\n";
  if (!d.command.empty())
    os << (d.verdict == Diagnosis::Verdict::event || d.verdict == Diagnosis::Verdict::outliers
               ? "refit without them:  "
               : "add it:  ")
       << d.command << "\n";
  return os.str();
}

std::string format_ladder(const std::vector<LadderStep>& steps) {
  std::ostringstream os;
  char line[200];
  std::snprintf(line, sizeof line, "%-4s %-20s %12s %14s %8s\n", "step", "added", "force rms",
                "torque rms", "gain");
  os << line;
  int k = 0;
  for (const auto& s : steps) {
    std::snprintf(line, sizeof line, "%-4d %-20s %10.3f N %10.3f N*m %7.1f%%\n", k++,
                  s.added_name.empty() ? "(start)" : s.added_name.c_str(),
                  s.heldout.stats.force_rms, s.heldout.stats.torque_rms, 100 * s.gain);
    os << line;
  }
  os << "final model: " << io::model_spec_string(steps.back().effects, steps.back().user) << "\n";
  return os.str();
}

}  // namespace zerog::ident
