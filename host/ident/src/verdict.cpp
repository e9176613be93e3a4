// The diagnosis of the physics (diagnose() looks for events first): the model's held-out error
// and its structured share, the candidates, the signals the residual follows, and the verdict:
// nothing left, a missing library effect, or none (with a discovered law if there is one).
#include <algorithm>
#include <cmath>
#include <sstream>

#include "diagnose_internal.hpp"
#include "zerog/io/effect_file.hpp"
#include "zerog/io/model_file.hpp"

namespace zerog::ident::diagnosis {
namespace {

// The verdict "effect": the best candidate pays and explains at least half the structure. Its
// sentence goes to `os` (after nothing), and the command that fits it to d.command.
void effect_verdict(Diagnosis& d, const DiagnoseOptions& o, const ErrorStats& h,
                    std::ostringstream& os) {
  const Candidate& c = d.candidates[0];
  d.verdict = Diagnosis::Verdict::effect;
  const auto& ch = c.heldout.stats;
  const std::string summary =
      c.user >= 0 ? "your effect file " + o.user_candidates[static_cast<std::size_t>(c.user)].source
                  : std::string(model::info(c.effect).summary);
  const int num_params = c.user >= 0
                             ? o.user_candidates[static_cast<std::size_t>(c.user)].effect.num_terms
                             : model::info(c.effect).num_params;
  auto params_of = [&](const Candidate& x) {
    return x.user >= 0 ? o.user_candidates[static_cast<std::size_t>(x.user)].effect.num_terms
                       : model::info(x.effect).num_params;
  };
  os << "Missing effect: " << c.name << " (" << summary << "). Adding it removes "
     << fmt("%.0f", 100 * c.gain) << "% of the held-out error (force RMS "
     << fmt("%.3f", h.force_rms) << " -> " << fmt("%.3f", ch.force_rms) << " N, torque RMS "
     << fmt("%.3f", h.torque_rms) << " -> " << fmt("%.3f", ch.torque_rms) << " N*m)";
  if (d.candidates.size() > 1 && gains_tie(c.gain, d.candidates[1].gain)) {
    const Candidate& alt = d.candidates[1];
    os << "; " << alt.name << " removes as much (" << fmt("%.0f", 100 * alt.gain)
       << "%) because it can mimic it, but with " << params_of(alt) << " parameters against "
       << num_params << ": the information criterion prefers " << c.name;
  } else if (d.candidates.size() > 1) {
    os << "; the next best, " << d.candidates[1].name << ", removes "
       << fmt("%.0f", 100 * d.candidates[1].gain) << "%";
  }
  os << ". Estimated: " << param_summary(c) << ".";
  {
    // The model as given plus the candidate: a library name goes before the files.
    std::string library = model_with(c.effects, d, o);
    if (c.user >= 0) library += ",@" + o.user_candidates[static_cast<std::size_t>(c.user)].source;
    d.command = "zerog fit " + o.log_path + " --effects " + library + " --out " + o.fit_out;
  }
}

// The verdict "discovered": the sentence on the dictionary law, after the "none" sentence in `os`.
void discovered_verdict(Diagnosis& d, const ErrorStats& h, std::ostringstream& os) {
  Discovery& x = *d.discovery;
  d.verdict = Diagnosis::Verdict::discovered;
  os << " Discovered in the signal dictionary";
  if (!x.with_effect.empty())
    os << " on top of " << x.with_effect << " (which pays on its own but leaves structure)";
  os << " (" << x.dictionary_size << " basis-axis columns searched, each term |z| > "
     << fmt("%.1f", x.z_threshold) << " and validated on held-out blocks): ";
  for (std::size_t j = 0; j < x.laws.size(); ++j) os << (j ? "; " : "") << x.laws[j];
  if (!x.with_effect.empty())
    os << ". Adding " << x.with_effect << " and the law (each is needed; the law removes "
       << fmt("%.0f", 100 * x.law_gain) << "% of what " << x.with_effect << " leaves) removes "
       << fmt("%.0f", 100 * x.gain);
  else
    os << ". Adding it removes " << fmt("%.0f", 100 * x.gain);
  os << "% of the held-out error (force RMS " << fmt("%.3f", h.force_rms) << " -> "
     << fmt("%.3f", x.heldout.stats.force_rms) << " N, torque RMS " << fmt("%.3f", h.torque_rms)
     << " -> " << fmt("%.3f", x.heldout.stats.torque_rms) << " N*m).";
}

}  // namespace

// The diagnosis of the physics: the model's held-out error, the candidates, a law (diagnose()
// looks for events first).
Diagnosis diagnose_physics(const Dataset& data, const DiagnoseOptions& o) {
  Diagnosis d = start_diagnosis(o.fit.effects, data);
  const Split split = make_split(data, o);
  d.split = split.blocks;
  if (o.progress) o.progress("diagnose: held-out split: " + split.blocks.text);
  if (o.progress)
    o.progress("diagnose: fitting " + io::effect_list_string(d.model) + " on the training blocks");
  Baseline base = fit_baseline(data, d.model, o.fit.user, split, o, o.fit.initial);
  d.baseline = base.fit;
  d.baseline_heldout = base.heldout;

  // White noise per axis from differences of held-out residuals 5 rows apart: structure is
  // smooth over 60 ms, and the 5-point gyro difference makes the noise correlated over 4 rows
  // (lag 1: −0.12, lag 2: −0.49), so shorter lags would misjudge it. var(r[i] − r[i−5]) = 2σ².
  d.noise_rms = noise_estimate(base.res, split.heldout);
  // Everything below in noise-whitened units, so each axis counts by its signal-to-noise.
  base.heldout = heldout_error(base.res, split.heldout, d.noise_rms);
  d.baseline_heldout = base.heldout;
  double total = 0.0, structure = 0.0;
  for (int k = 0; k < 6; ++k) {
    const double ratio = std::pow(base.heldout.stats.rms[k] / d.noise_rms[k], 2);
    total += ratio;
    structure += std::max(0.0, ratio - 1.0);
  }
  d.structured_fraction = structure / total;

  if (o.progress) o.progress("diagnose: trying each candidate effect");
  d.candidates = evaluate_candidates(data, base, split, o, d.noise_rms, &d.candidate_evaluation);
  d.correlated = correlate(data, base.res, split.heldout, o.fit.threads);

  const auto& h = base.heldout.stats;
  std::ostringstream os;
  const double explained = d.candidates.empty() || d.structured_fraction <= 0
                               ? 0.0
                               : d.candidates[0].gain / d.structured_fraction;
  if (d.structured_fraction < 0.05 && (d.candidates.empty() || d.candidates[0].gain < 0.02)) {
    d.verdict = Diagnosis::Verdict::nothing_left;
    os << "The residual is at the noise level (held-out force RMS " << fmt("%.3f", h.force_rms)
       << " N, torque RMS " << fmt("%.3f", h.torque_rms) << " N*m; "
       << fmt("%.0f", 100 * d.structured_fraction)
       << "% of it is structured): nothing is missing that the library could add.";
  } else if (!d.candidates.empty() && d.candidates[0].gain > 0.02 && explained >= 0.5) {
    effect_verdict(d, o, h, os);
  } else {
    d.verdict = Diagnosis::Verdict::none;
    if (o.discover) {
      if (o.progress)
        o.progress("diagnose: no library effect explains it; searching the signal dictionary");
      d.discovery = discover_beyond(data, base, split, o, d);
    }
    os << "No library effect explains the remaining structure: "
       << fmt("%.0f", 100 * d.structured_fraction) << "% of the held-out error is structured, ";
    if (!d.candidates.empty())
      os << "but the best candidate, " << d.candidates[0].name << ", removes only "
         << fmt("%.0f", 100 * std::max(0.0, d.candidates[0].gain)) << "% ("
         << fmt("%.0f", 100 * std::max(0.0, explained)) << "% of the structure). ";
    else
      os << "and no candidate is left to try. ";
    if (!d.correlated.empty()) {
      os << "The residual correlates with: ";
      for (std::size_t q = 0; q < std::min<std::size_t>(3, d.correlated.size()); ++q) {
        const auto& s = d.correlated[q];
        os << (q ? "; " : "") << s.signal << " on " << kAxisNames[s.axis]
           << " (rho = " << fmt("%.2f", s.correlation) << ")";
      }
      os << ". Look for a physical cause tied to " << d.correlated[0].signal << ".";
    }
    if (d.discovery) {
      discovered_verdict(d, h, os);
      write_discovery(d, o);
    }
  }
  d.text = os.str();
  return d;
}

// The parameters of the diagnosis' answer: the model with the effect or law it proposes, else
// the baseline.
const model::ModelParams& answer_params(const Diagnosis& d) {
  if (d.verdict == Diagnosis::Verdict::effect && !d.candidates.empty())
    return d.candidates[0].fit.params;
  if (d.verdict == Diagnosis::Verdict::discovered && d.discovery) return d.discovery->fit.params;
  return d.baseline.params;
}

}  // namespace zerog::ident::diagnosis
