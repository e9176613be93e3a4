// diagnose()'s entry points: the events first (spans of the residual that stand out in time,
// events.hpp), then the physics of the rest of the log (verdict.cpp); and the ladder of effects
// from a minimal model. What they share with the other files of diagnose: diagnose_internal.hpp.
#include "zerog/ident/diagnose.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <sstream>

#include "diagnose_internal.hpp"
#include "zerog/io/effect_file.hpp"
#include "zerog/io/model_file.hpp"

namespace zerog::ident {

using diagnosis::answer_params;
using diagnosis::Baseline;
using diagnosis::diagnose_physics;
using diagnosis::evaluate_candidates;
using diagnosis::fit_baseline;
using diagnosis::fmt;
using diagnosis::heldout_error;
using diagnosis::make_split;
using diagnosis::noise_estimate;
using diagnosis::Split;
using diagnosis::write_discovery;

namespace {

// How far a span's mean residual stands from the level around it (the rows within two windows
// before and after it that `skip` does not exclude), in the scan's scale units.
double span_deviation(const std::vector<Wrench>& res, const Span& s, std::size_t window,
                      const std::vector<std::uint8_t>& skip, const std::array<double, 6>& scale) {
  std::array<double, 6> in{}, out{};
  double n_in = 0.0, n_out = 0.0;
  for (std::size_t i = s.first; i <= s.last; ++i) {
    for (int k = 0; k < 6; ++k) in[static_cast<std::size_t>(k)] += res[i][k];
    n_in += 1.0;
  }
  const std::size_t lo = s.first > 2 * window ? s.first - 2 * window : 0;
  const std::size_t hi = std::min(res.size(), s.last + 1 + 2 * window);
  for (std::size_t i = lo; i < hi; ++i) {
    if ((i >= s.first && i <= s.last) || skip[i]) continue;
    for (int k = 0; k < 6; ++k) out[static_cast<std::size_t>(k)] += res[i][k];
    n_out += 1.0;
  }
  if (n_in == 0.0 || n_out == 0.0) return std::numeric_limits<double>::infinity();
  double z = 0.0;
  for (std::size_t k = 0; k < 6; ++k)
    z = std::max(z, std::abs(in[k] / n_in - out[k] / n_out) / scale[k]);
  return z;
}

std::string join_exclude(const std::string& a, const std::string& b) {
  if (a.empty()) return b;
  if (b.empty()) return a;
  return a + "," + b;
}

}  // namespace

Diagnosis start_diagnosis(const model::EffectSet& model, const Dataset& data) {
  Diagnosis d;
  d.model = model;
  d.kinematics = kinematics_feeds(d.model, data);
  d.kinematics_json = kinematics_json(d.kinematics, data);
  d.kinematics_text = format_kinematics(d.kinematics, data);
  return d;
}

namespace {

// The event scan's outcome: the last scan, and the model it scanned.
struct EventScan {
  SpanScan scan;
  model::ModelParams params;
  bool fitted = false;  // false: the model could not be fitted on the rows kept
};

// The model on every row kept, its residual scanned for spans that stand out (events.hpp),
// refitted without the spans found and scanned again until the spans stay, at most three times.
EventScan scan_events(const Dataset& data, const DiagnoseOptions& o,
                      const std::vector<std::uint8_t>& user) {
  const std::size_t n = data.size();
  FitOptions fo = o.fit;
  fo.progress = nullptr;
  fo.covariance = false;  // only the residual is scanned
  std::vector<std::uint8_t> use(n), in_spans(n, 0);
  EventScan out;
  SpanScan& scan = out.scan;
  for (int turn = 0; turn < 3; ++turn) {
    for (std::size_t i = 0; i < n; ++i) use[i] = (user[i] || in_spans[i]) ? 0 : 1;
    fo.mask = &use;
    const FitResult f = fit(data, fo);
    if (!f.usable) break;
    out.fitted = true;
    out.params = f.params;
    SpanScan next = find_spans(residuals(f.params, data), data, &user, o.event_options);
    bool same = turn > 0 && next.spans.size() == scan.spans.size();
    for (std::size_t q = 0; same && q < next.spans.size(); ++q)
      same = next.spans[q].first + next.window_rows >= scan.spans[q].first &&
             scan.spans[q].first + next.window_rows >= next.spans[q].first &&
             next.spans[q].last + next.window_rows >= scan.spans[q].last &&
             scan.spans[q].last + next.window_rows >= next.spans[q].last;
    scan = std::move(next);
    in_spans = span_mask(data, scan.spans);
    if (same || scan.spans.empty() || scan.recurring) break;
  }
  return out;
}

// The spans taken for events, and why the others are not.
struct SpanSort {
  std::vector<Span> events;
  std::string note;
};

SpanSort sort_spans(const SpanScan& scan, const DiagnoseOptions& o) {
  SpanSort out;
  if (o.events_mutant_every_span) {
    out.events = scan.spans;
  } else if (scan.recurring) {
    out.note = std::to_string(scan.spans.size()) + " spans stand out, covering " +
               fmt("%.0f", 100 * scan.coverage) +
               "% of the log: a pattern that recurs is the model's, not events";
  } else {
    std::size_t tied = 0;
    for (const Span& s : scan.spans) {
      if (s.tied_to_motion())
        ++tied;
      else
        out.events.push_back(s);
    }
    if (tied)
      out.note =
          std::to_string(tied) +
          " span(s) start and end with the robot's motion: physics of the motion, not events";
  }
  return out;
}

// The whole log's answer (`physics()` gives its diagnosis), with its best library candidate too
// when that pays something (a law can take the verdict while a library effect explains part of
// the rest); none if it proposes nothing or cannot be diagnosed.
template <class Physics>
std::optional<model::ModelParams> whole_log_answer(Physics& physics) {
  try {
    const Diagnosis& whole = physics();
    model::ModelParams p = answer_params(whole);
    bool any = whole.verdict == Diagnosis::Verdict::effect ||
               whole.verdict == Diagnosis::Verdict::discovered;
    if (!whole.candidates.empty() && whole.candidates[0].user < 0 &&
        whole.candidates[0].gain > 0.02 && !p.effects.has(whole.candidates[0].effect)) {
      const model::Effect e = whole.candidates[0].effect;
      p.effects.add(e);
      p.values[model::index(e)] = whole.candidates[0].fit.params.values[model::index(e)];
      any = true;
    }
    if (any) return p;
  } catch (const std::exception&) {
    // Nothing the whole log asks for: the rest's diagnosis alone decides.
  }
  return std::nullopt;
}

// The residual of `answer` refitted on the rows not `without`; empty if it cannot be fitted.
std::vector<Wrench> residuals_without(const Dataset& data, const DiagnoseOptions& o,
                                      const model::ModelParams& answer,
                                      const std::vector<std::uint8_t>& without) {
  const std::size_t n = data.size();
  std::vector<Wrench> res_whole;
  std::vector<std::uint8_t> keep(n);
  for (std::size_t i = 0; i < n; ++i) keep[i] = without[i] ? 0 : 1;
  FitOptions wo = o.fit;
  wo.effects = answer.effects;
  wo.user = answer.user;
  wo.initial = &answer;
  wo.mask = &keep;
  wo.covariance = false;
  wo.progress = nullptr;
  try {
    const FitResult r = fit(data, wo);
    if (r.usable) res_whole = residuals(r.params, data);
  } catch (const std::exception&) {
    // The whole log's effect cannot be fitted without the spans: the rest decides.
  }
  return res_whole;
}

// The verdict "event": the spans, and the rest's diagnosis (`rest`, or why there is none).
Diagnosis event_diagnosis(const Dataset& data, const DiagnoseOptions& o,
                          std::optional<Diagnosis> rest, const std::string& rest_error,
                          const model::ModelParams& scanned_params, SpanScan scan,
                          std::vector<Span> events, std::string note) {
  Diagnosis d;
  if (rest) {
    d = std::move(*rest);
  } else {
    d = start_diagnosis(o.fit.effects, data);
    d.baseline.params = scanned_params;
  }
  d.scan = std::move(scan);
  d.events = events;
  d.spans_note = std::move(note);
  d.exclude = join_exclude(o.exclude_text, exclude_text(events));
  const std::string outside_verdict = d.text;
  d.verdict = Diagnosis::Verdict::event;
  std::ostringstream os;
  os << "Events, not physics: " << events.size()
     << (events.size() == 1 ? " span where" : " spans where")
     << " the residual leaves its level and comes back (a contact, a collision or a snag: a "
        "wrench from outside the payload). No effect or law is proposed for "
     << (events.size() == 1 ? "it" : "them") << ":\n"
     << format_spans(events, "  ");
  if (rest)
    os << "Without " << (events.size() == 1 ? "it" : "them") << ": " << outside_verdict;
  else
    os << "The rest of the log cannot be diagnosed on its own (" << rest_error
       << "); refit without the spans, and record a longer log to diagnose the physics.";
  d.text = os.str();
  const std::string model =
      o.model_text.empty() ? io::model_spec_string(d.model, o.fit.user) : o.model_text;
  d.command = !d.command.empty() ? d.command + " --exclude " + d.exclude
                                 : "zerog fit " + o.log_path + " --effects " + model +
                                       " --exclude " + d.exclude + " --out " + o.fit_out;
  return d;
}

}  // namespace

Diagnosis diagnose(const Dataset& data, const DiagnoseOptions& o) {
  const std::size_t n = data.size();
  // Every command printed keeps the rows the user left out.
  auto finish = [&](Diagnosis d) {
    if (d.exclude.empty()) d.exclude = o.exclude_text;
    if (!d.command.empty() && d.command.find(" --exclude ") == std::string::npos &&
        !d.exclude.empty())
      d.command += " --exclude " + d.exclude;
    return d;
  };
  if (data.columns.static_rows) return finish(diagnose_table(data, o));
  if (!o.events) return finish(diagnose_physics(data, o));
  std::vector<std::uint8_t> user(n, 0);
  if (o.exclude) user = *o.exclude;

  // The model on every row kept; its residual scanned for spans that stand out (events.hpp);
  // refitted without the spans found and scanned again (a long contact pulls the first fit
  // towards itself) until the spans stay, at most three times.
  if (o.progress) o.progress("diagnose: looking for events (spans that stand out in time)");
  EventScan first;
  try {
    first = scan_events(data, o, user);
  } catch (const std::exception&) {
    // A model that cannot be fitted on all kept rows: the physics diagnosis says why.
    return finish(diagnose_physics(data, o));
  }
  if (!first.fitted) return finish(diagnose_physics(data, o));
  SpanScan scan = std::move(first.scan);
  const model::ModelParams& scanned_params = first.params;

  SpanSort sorted = sort_spans(scan, o);
  std::vector<Span>& events = sorted.events;
  std::string& note = sorted.note;
  // The whole log's physics diagnosis, once, and without writing a law's file: that is written
  // only when it is the verdict (plain()).
  std::optional<Diagnosis> whole_log;
  auto physics = [&]() -> const Diagnosis& {
    if (!whole_log) {
      DiagnoseOptions all = o;
      all.discovery_path.clear();
      whole_log = diagnose_physics(data, all);
    }
    return *whole_log;
  };
  auto plain = [&](std::string why) {
    Diagnosis d = physics();
    write_discovery(d, o);
    d.scan = scan;
    d.spans_note = std::move(why);
    return finish(std::move(d));
  };
  if (events.empty()) {
    // A missing effect's residual can hide an event (its steps at every move set the scale):
    // with the effect or law the diagnosis proposes, the residual is scanned once more.
    const Diagnosis& d = physics();
    if (d.verdict == Diagnosis::Verdict::effect || d.verdict == Diagnosis::Verdict::discovered) {
      SpanScan again = find_spans(residuals(answer_params(d), data), data, &user, o.event_options);
      if (!again.recurring && !again.spans.empty()) {
        for (const Span& s : again.spans)
          if (!s.tied_to_motion() || o.events_mutant_every_span) events.push_back(s);
        if (!events.empty()) scan = std::move(again);
      }
    }
    if (events.empty()) return plain(note);
  }

  // The physics the whole log asks for: the effect or law of its diagnosis with the spans in
  // (a long pose-dependent residual, a missing cable in a short run, can look like an
  // excursion, and leaving it out can leave the rest without what identifies the effect).
  const std::optional<model::ModelParams> whole_answer =
      o.events_mutant_every_span ? std::nullopt : whole_log_answer(physics);
  // The rest of the log diagnosed without them; a span that the answer (the model with what it
  // proposes: the rest's, or the whole log's), fitted elsewhere, predicts is physics after all.
  std::optional<Diagnosis> rest;
  std::string rest_error;
  for (int turn = 0; turn < 2 && !events.empty(); ++turn) {
    const std::vector<std::uint8_t> without = span_mask(data, events, user);
    DiagnoseOptions inner = o;
    inner.exclude = &without;
    inner.discovery_path.clear();  // the command below refits first; a later turn writes it
    inner.progress = nullptr;
    rest.reset();
    rest_error.clear();
    try {
      rest = diagnose_physics(data, inner);
    } catch (const std::exception& e) {
      rest_error = e.what();
    }
    if (o.events_mutant_every_span) break;
    const std::vector<Wrench> res = residuals(rest ? answer_params(*rest) : scanned_params, data);
    const std::vector<Wrench> res_whole =
        whole_answer ? residuals_without(data, o, *whole_answer, without) : std::vector<Wrench>{};
    std::vector<Span> kept;
    for (const Span& s : events)
      if (span_deviation(res, s, scan.window_rows, without, scan.scale) >= scan.z_step &&
          (res_whole.empty() ||
           span_deviation(res_whole, s, scan.window_rows, without, scan.scale) >= scan.z_step))
        kept.push_back(s);
    if (kept.size() == events.size()) break;
    note = std::to_string(events.size() - kept.size()) +
           " span(s) that stood out are predicted by the model fitted without them: physics";
    events = std::move(kept);
  }
  if (events.empty()) return plain(note);

  return event_diagnosis(data, o, std::move(rest), rest_error, scanned_params, std::move(scan),
                         std::move(events), std::move(note));
}

std::vector<LadderStep> ladder(const Dataset& data, const LadderOptions& o) {
  std::vector<LadderStep> steps;
  const Split split = make_split(data, o.diagnose);
  model::EffectSet effects =
      o.diagnose.fit.effects.size() ? o.diagnose.fit.effects : model::kMinimalModel;
  if (o.diagnose.progress)
    o.diagnose.progress("ladder: step 0, " + io::effect_list_string(effects));
  Baseline base = fit_baseline(data, effects, o.diagnose.fit.user, split, o.diagnose, nullptr);
  steps.push_back(
      {effects, base.fit.params.user, std::nullopt, "", base.heldout, base.fit.bic, 0.0});
  for (int s = 0; s < o.max_steps; ++s) {
    // Gains are measured against the noise of this step's residuals.
    const auto scale = noise_estimate(base.res, split.heldout);
    base.heldout = heldout_error(base.res, split.heldout, scale);
    const auto cands = evaluate_candidates(data, base, split, o.diagnose, scale);
    if (cands.empty()) break;
    const Candidate& best = cands[0];
    if (best.gain < o.min_gain || best.delta_bic >= 0) break;
    effects = best.effects;
    const std::string added_name = best.name;
    if (o.diagnose.progress)
      o.diagnose.progress("ladder: step " + std::to_string(s + 1) + ", adds " + added_name);
    // Refit so the next step's whitening matches the new model.
    base = fit_baseline(data, effects, best.fit.params.user, split, o.diagnose, &best.fit.params);
    LadderStep step{effects,      base.fit.params.user, std::nullopt, added_name,
                    base.heldout, base.fit.bic,         best.gain};
    if (best.user < 0) step.added = best.effect;
    steps.push_back(step);
  }
  return steps;
}

}  // namespace zerog::ident
