#include "zerog/ident/diagnose.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <sstream>

#include <Eigen/Dense>
#include <limits>
#include <memory>
#include <optional>

#include "growing_fit.hpp"
#include "parallel.hpp"
#include "screening.hpp"
#include "zerog/ident/eiv.hpp"
#include "zerog/io/effect_file.hpp"
#include "zerog/io/model_file.hpp"

namespace zerog::ident {
namespace {

using model::Effect;

std::vector<std::uint8_t> invert(const std::vector<std::uint8_t>& m) {
  std::vector<std::uint8_t> out(m.size());
  for (std::size_t i = 0; i < m.size(); ++i) out[i] = m[i] ? 0 : 1;
  return out;
}

// Samples per task of the per-sample passes on several threads (parallel.hpp).
constexpr std::size_t kSampleChunk = 8192;

std::size_t sample_chunks(std::size_t n) { return (n + kSampleChunk - 1) / kSampleChunk; }

// Runs `rows(i0, i1)` on every chunk of kSampleChunk samples, on `threads` threads; each worker
// takes its chunks front to back and releases a spilled log's rows behind it with its own
// ResidentWindow (spill.hpp).
template <typename Rows>
void for_each_sample_chunk(const Dataset& data, int threads, const Rows& rows) {
  const std::size_t n = data.size();
  const std::size_t tasks = sample_chunks(n);
  std::vector<std::unique_ptr<ResidentWindow>> windows(
      static_cast<std::size_t>(parallel::workers(tasks, threads)));
  for (auto& w : windows) w = std::make_unique<ResidentWindow>(data);
  parallel::for_each(tasks, threads, [&](std::size_t chunk, int worker) {
    const std::size_t i0 = chunk * kSampleChunk, i1 = std::min(n, i0 + kSampleChunk);
    rows(i0, i1);
    windows[static_cast<std::size_t>(worker)]->advance(i1);
  });
}

// The residuals (measured − predicted) of the samples in `mask` (every sample without one; zero
// outside it in a new vector, left as they were in `out`), on `threads` threads: each sample's
// is its own, as residuals() forms it.
void residuals_into(std::vector<Wrench>& out, const model::ModelParams& params, const Dataset& data,
                    const std::vector<std::uint8_t>* mask, int threads) {
  const std::size_t n = data.size();
  out.resize(n, Wrench::Zero());
  for_each_sample_chunk(data, threads, [&](std::size_t i0, std::size_t i1) {
    for (std::size_t i = i0; i < i1; ++i)
      if (!mask || (*mask)[i]) out[i] = data.measured[i] - predict(params, data, i);
  });
}

std::vector<Wrench> residuals_of(const model::ModelParams& params, const Dataset& data,
                                 const std::vector<std::uint8_t>* mask, int threads) {
  std::vector<Wrench> out;
  residuals_into(out, params, data, mask, threads);
  return out;
}

HeldOut heldout_error(const std::vector<Wrench>& res, const std::vector<std::uint8_t>& mask,
                      const std::array<double, 6>& sigma) {
  ErrorAccumulator acc;
  double ws = 0.0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < res.size(); ++i) {
    if (!mask[i]) continue;
    acc.add(res[i]);
    for (int k = 0; k < 6; ++k) ws += (res[i][k] / sigma[k]) * (res[i][k] / sigma[k]);
    ++n;
  }
  HeldOut h;
  h.stats = acc.stats();
  h.whitened_mse = n ? ws / (6.0 * static_cast<double>(n)) : 0.0;
  return h;
}

std::array<double, 6> noise_estimate(const std::vector<Wrench>& res,
                                     const std::vector<std::uint8_t>& mask) {
  constexpr std::size_t kLag = 5;
  std::array<double, 6> dd{};
  std::size_t nd = 0;
  for (std::size_t i = kLag; i < res.size(); ++i) {
    if (!mask[i] || !mask[i - kLag]) continue;
    const Wrench diff = res[i] - res[i - kLag];
    for (int k = 0; k < 6; ++k) dd[k] += diff[k] * diff[k];
    ++nd;
  }
  std::array<double, 6> out{};
  for (int k = 0; k < 6; ++k)
    out[k] = std::max(std::sqrt(dd[k] / (2.0 * static_cast<double>(std::max<std::size_t>(nd, 1)))),
                      1e-9);
  return out;
}

std::string fmt(const char* f, double a) {
  char b[64];
  std::snprintf(b, sizeof b, f, a);
  return b;
}

struct Split {
  std::vector<std::uint8_t> heldout, train;
  BlockChoice blocks;
};

struct SplitCount {
  std::size_t heldout = 0, train = 0;
};

SplitCount count_split(const Dataset& data, double block_s, int every, int offset,
                       const std::vector<std::uint8_t>* exclude) {
  const auto mask = heldout_mask(data, block_s, every, offset);
  SplitCount n;
  for (std::size_t i = 0; i < mask.size(); ++i) {
    if (exclude && (*exclude)[i]) continue;
    (mask[i] ? n.heldout : n.train) += 1;
  }
  return n;
}

BlockChoice choose_blocks_excluding(const Dataset& data, double block_s, int every, int offset,
                                    const std::vector<std::uint8_t>* exclude) {
  BlockChoice c;
  const double duration = data.size() > 1 ? data.t_s.back() - data.t_s.front() : 0.0;
  const std::string log_words =
      std::to_string(data.size()) + " samples over " + fmt("%.1f", duration) + " s";
  const int keep = every > 0 ? every : 4;
  if (data.columns.static_rows) {
    c.block_s = 0.0;
    c.blocks = static_cast<int>(data.size());
    c.text = "rows without time: each row is its own block (every " + std::to_string(keep) +
             "th row held out)";
  } else if (block_s > 0.0) {
    c.block_s = block_s;
    c.automatic = false;
  } else if (duration >= kMinBlocks * kDefaultBlockS) {
    c.block_s = kDefaultBlockS;
  } else if (duration >= kMinBlocks * kMinBlockS) {
    // A hair longer than duration / 8, so that the last sample falls in block 8, not a 9th.
    c.block_s = duration / kMinBlocks * (1.0 + 1e-9);
  } else {
    throw std::runtime_error(
        "log too short for a time-blocked held-out split (" + log_words + "): it needs at least " +
        std::to_string(kMinBlocks) + " blocks of at least " + fmt("%.1f", kMinBlockS) +
        " s, i.e. " + fmt("%.0f", kMinBlocks * kMinBlockS) + " s of recording with at least " +
        std::to_string(kMinSplitSamples) +
        " samples held out; record longer, or import the poses as rows without time (static "
        "samples, one block each)");
  }
  if (!data.columns.static_rows) c.blocks = static_cast<int>(std::floor(duration / c.block_s)) + 1;
  const SplitCount n = count_split(data, c.block_s, keep, offset, exclude);
  c.heldout_samples = n.heldout;
  c.training_samples = n.train;
  if (data.columns.static_rows && (n.heldout < kMinSplitSamples || n.train < kMinSplitSamples)) {
    // A static table: no blocks to choose, only more poses (or a fit without a held-out split).
    throw std::runtime_error(
        "static table of " + std::to_string(data.size()) + " rows (no time): diagnose holds out " +
        "every " + std::to_string(keep) + "th row and needs at least " +
        std::to_string(kMinSplitSamples) + " held-out and " + std::to_string(kMinSplitSamples) +
        " training rows (here " + std::to_string(n.heldout) + " and " + std::to_string(n.train) +
        "), about " + std::to_string(static_cast<std::size_t>(keep) * kMinSplitSamples) +
        " poses: record more poses (a longer design, or several readings per pose), or use "
        "`zerog fit` on this table (it fits every row: bias, gravity and the payload, without "
        "a held-out split) and `zerog compare` for the residual of each pose");
  }
  if (n.heldout < kMinSplitSamples || n.train < kMinSplitSamples) {
    // What would work: the longest block that still gives both sides enough samples.
    std::string hint = "record longer";
    if (!data.columns.static_rows) {
      for (double b = std::min(block_s > 0 ? block_s : kDefaultBlockS, duration / 2);
           b >= kMinBlockS * 0.999; b *= 0.9) {
        const SplitCount m = count_split(data, b, keep, offset, exclude);
        if (m.heldout >= kMinSplitSamples && m.train >= kMinSplitSamples) {
          hint = "use --block " + fmt("%.3g", b) + " or shorter (or omit --block: zerog chooses)";
          break;
        }
      }
    }
    throw std::runtime_error("log too short for a time-blocked held-out split (" + log_words +
                             ", " +
                             (c.block_s > 0 ? "blocks of " + fmt("%.3g", c.block_s) + " s"
                                            : std::string("one row each")) +
                             ": " + std::to_string(n.heldout) + " held-out and " +
                             std::to_string(n.train) + " training samples, at least " +
                             std::to_string(kMinSplitSamples) + " each are needed): " + hint);
  }
  if (c.text.empty()) {
    c.text = "blocks of " + fmt("%.3g", c.block_s) + " s (" + std::to_string(c.blocks) +
             " blocks in " + fmt("%.1f", duration) + " s, every " + std::to_string(keep) +
             "th held out: " + std::to_string(n.heldout) + " held-out samples); " +
             (c.automatic ? (c.block_s == kDefaultBlockS
                                 ? std::string("the default")
                                 : "chosen for this short log (" + std::to_string(kMinBlocks) +
                                       " blocks; 60 s needs a log of " +
                                       fmt("%.0f", kMinBlocks * kDefaultBlockS) + " s)")
                          : std::string("given with --block"));
  }
  return c;
}

Split make_split(const Dataset& data, const DiagnoseOptions& o) {
  Split s;
  s.blocks = choose_blocks_excluding(data, o.block_s, o.every, o.heldout_offset, o.exclude);
  s.heldout = heldout_mask(data, s.blocks.block_s, o.every, o.heldout_offset);
  s.train = invert(s.heldout);
  if (o.exclude) {
    for (std::size_t i = 0; i < data.size(); ++i) {
      if ((*o.exclude)[i]) s.heldout[i] = 0, s.train[i] = 0;
    }
  }
  return s;
}

struct Baseline {
  FitResult fit;
  std::vector<Wrench> res;
  HeldOut heldout;
};

Baseline fit_baseline(const Dataset& data, const model::EffectSet& effects,
                      const model::UserEffects& user, const Split& split, const DiagnoseOptions& o,
                      const model::ModelParams* initial) {
  FitOptions fo = o.fit;
  fo.effects = effects;
  fo.user = user;
  fo.mask = &split.train;
  fo.covariance = false;
  fo.initial = initial;
  fo.progress = nullptr;
  Baseline b;
  b.fit = fit(data, fo);
  if (!b.fit.usable)
    throw std::runtime_error("the fit of the model " + io::effect_list_string(effects) +
                             " is not usable: " + b.fit.termination);
  b.res = residuals_of(b.fit.params, data, nullptr, o.fit.threads);
  b.heldout = heldout_error(b.res, split.heldout, b.fit.residual_rms);
  return b;
}

// Two held-out gains are indistinguishable if they differ by less than half a percentage point
// or 2 % of the larger.
bool gains_tie(double a, double b) {
  return std::abs(a - b) < std::max(0.005, 0.02 * std::max(a, b));
}

// A candidate to try: its name and model (library effects, and the user effects with it).
struct Trial {
  Candidate c;
  model::UserEffects user;
};

std::vector<Trial> candidate_trials(const Dataset& data, const Baseline& base,
                                    const DiagnoseOptions& o) {
  std::vector<Trial> out;
  for (Effect e : candidate_effects(base.fit.params.effects, data)) {
    Candidate c;
    c.effect = e;
    c.name = model::info(e).name;
    c.effects = base.fit.params.effects;
    c.effects.add(e);
    out.push_back({std::move(c), base.fit.params.user});
  }
  // The user-defined candidates the model does not hold yet (by name) and the log can feed.
  for (std::size_t u = 0; u < o.user_candidates.size(); ++u) {
    const model::UserEffects& cand = o.user_candidates[u].effect;
    bool held = false;
    for (int k = 0; k < base.fit.params.user.num_effects; ++k)
      held = held || io::user_effect_name(base.fit.params.user, k) == io::user_effect_name(cand, 0);
    if (held) continue;
    try {
      check_signals(cand, data);
    } catch (const std::runtime_error&) {
      continue;
    }
    Candidate c;
    c.user = static_cast<int>(u);
    c.name = "@" + io::user_effect_name(cand, 0);
    c.effects = base.fit.params.effects;
    model::UserEffects user = base.fit.params.user;
    io::append_user_effects(user, cand);
    out.push_back({std::move(c), std::move(user)});
  }
  return out;
}

// The held-out figures of a candidate from its residuals (every sample, or the held-out ones).
void score(Candidate& c, const Baseline& base, const std::vector<Wrench>& res, const Split& split,
           const std::array<double, 6>& scale) {
  c.heldout = heldout_error(res, split.heldout, scale);
  c.gain = 1.0 - c.heldout.whitened_mse / base.heldout.whitened_mse;
  for (int a = 0; a < 6; ++a) {
    const double b2 = base.heldout.stats.rms[a] * base.heldout.stats.rms[a];
    const double c2 = c.heldout.stats.rms[a] * c.heldout.stats.rms[a];
    c.axis_gain[a] = b2 > 0 ? 1.0 - c2 / b2 : 0.0;
  }
  c.delta_bic = c.fit.bic - base.fit.bic;
}

// Fits the model with one more candidate (warm-started at the baseline) and measures it on the
// held-out blocks; empty if the fit is not usable.
std::optional<Candidate> refit(const Dataset& data, const Baseline& base, const Split& split,
                               const DiagnoseOptions& o, const std::array<double, 6>& scale,
                               const Trial& t) {
  Candidate c = t.c;
  FitOptions fo = o.fit;
  fo.effects = c.effects;
  fo.user = t.user;
  fo.mask = &split.train;
  fo.covariance = false;
  fo.initial = &base.fit.params;
  fo.sigma = base.fit.sigma;
  fo.progress = nullptr;
  c.fit = fit(data, fo);
  if (!c.fit.usable) return std::nullopt;
  c.screened = false;
  score(c, base, residuals_of(c.fit.params, data, &split.heldout, o.fit.threads), split, scale);
  return c;
}

// Why the screening cannot stand in for refits with these options ("" if it can).
std::string screening_refused(const Dataset& data, const Baseline& base, const DiagnoseOptions& o) {
  if (o.exact_candidates) return "every candidate refitted, as asked (--exact-candidates)";
  if (o.fit.engine != "normal")
    return "every candidate refitted: the screening reuses the normal engine's equations, the "
           "engine is '" +
           o.fit.engine + "'";
  if (o.fit.loss != "none")
    return "every candidate refitted: with the robust loss '" + o.fit.loss +
           "' the weights move with the step, so a linearised step is not trusted";
  FitOptions fo = o.fit;
  fo.effects = base.fit.params.effects;
  std::string why;
  if (errors_in_variables_applies(fo, data, &why))
    return "every candidate refitted: errors in variables are on (" + why +
           "); the screening's step is of plain least squares";
  return "";
}

// Screening (issue 16): the model with the baseline and every candidate, at the baseline's
// solution with each candidate at its neutral value (zero: where fit() starts an effect the
// initial model lacks; user terms are linear, so their start value does not change the step),
// accumulated once on the training blocks. Each candidate then gets the Gauss–Newton step of
// baseline ∪ candidate from these normal equations (screening::BorderedSolver), its training
// cost (exact, at the step) for the BIC, and its held-out figures exactly at the step (the
// held-out error is per sample, as for a refit). Entries: empty where a candidate has no free
// columns (frozen, or no parameters); `trusted` false where the step's actual training decrease
// departs from the predicted one by more than kMaxModelError (the linearisation does not hold:
// refit it).
struct Screened {
  std::vector<std::optional<Candidate>> candidates;
  std::vector<bool> trusted;
};

// |actual / predicted training-cost decrease − 1| above which a screened step is refitted.
constexpr double kMaxModelError = 0.1;

Screened screen(const Dataset& data, const Baseline& base, const Split& split,
                const DiagnoseOptions& o, const std::array<double, 6>& scale,
                const std::vector<Trial>& trials, bool drop_coupling) {
  const model::ModelParams& b = base.fit.params;
  model::ModelParams point = b;
  std::vector<int> first_term(trials.size(), -1);  // a user candidate's first term in the union
  for (std::size_t t = 0; t < trials.size(); ++t) {
    const Candidate& c = trials[t].c;
    if (c.user < 0) {
      // An effect without parameters (linear_inertia) changes the prediction as it stands: it
      // has no neutral value, so it is refitted instead.
      if (model::info(c.effect).num_params == 0) continue;
      point.effects.add(c.effect);
      point.values[static_cast<std::size_t>(model::index(c.effect))].fill(0.0);
    } else {
      first_term[t] = point.user.num_terms;
      io::append_user_effects(point.user,
                              o.user_candidates[static_cast<std::size_t>(c.user)].effect);
      for (int j = first_term[t]; j < point.user.num_terms; ++j)
        point.user.coeff[static_cast<std::size_t>(j)] = 0.0;
    }
  }
  FitOptions fo = o.fit;
  fo.effects = point.effects;
  fo.user = point.user;
  fo.mask = &split.train;
  fo.sigma = base.fit.sigma;
  fo.initial = nullptr;
  const screening::TrainingProblem problem(data, fo, point);
  normal::NormalEquations ne;
  if (!problem.accumulate(o.fit.threads, ne))
    throw std::runtime_error("the model with every candidate is not finite at the baseline");
  // The union at the baseline must be the baseline's training problem: same blocks, whitening
  // and residuals (candidates neutral). Its BIC formula must give the baseline's BIC.
  const double n_res = 6.0 * static_cast<double>(problem.num_blocks());
  const double ssr0 = 2.0 * ne.cost;
  const double bic0 = n_res * std::log(ssr0 / n_res) + base.fit.num_params * std::log(n_res);
  if (!(std::abs(bic0 - base.fit.bic) <= 1e-6 * std::max(1.0, std::abs(base.fit.bic))))
    throw std::runtime_error(
        "the model with every candidate does not reproduce the baseline's "
        "training cost (BIC " +
        fmt("%.6g", bic0) + " against " + fmt("%.6g", base.fit.bic) + ")");
  const auto columns_of = [&](Effect e, std::vector<int>& into) {
    const int col = problem.column(e);
    if (col < 0) return false;
    for (int q = 0; q < model::info(e).num_params; ++q) into.push_back(col + q);
    return true;
  };
  std::vector<int> base_columns;
  for (Effect e : model::kAllEffects)
    if (b.effects.has(e)) columns_of(e, base_columns);
  const int user_column = problem.user_column();
  for (int j = 0; j < b.user.num_terms; ++j) base_columns.push_back(user_column + j);
  const screening::BorderedSolver solver(ne.JtJ, ne.Jtr, base_columns, drop_coupling);

  std::vector<Wrench> res;  // the held-out samples' residuals of the candidate at hand
  Screened out;
  for (std::size_t t = 0; t < trials.size(); ++t) {
    const Candidate& skeleton = trials[t].c;
    std::vector<int> cand_columns;
    int cand_terms = 0;
    if (skeleton.user < 0) {
      if (!columns_of(skeleton.effect, cand_columns)) {
        out.candidates.emplace_back();
        out.trusted.push_back(false);
        continue;
      }
    } else {
      cand_terms = o.user_candidates[static_cast<std::size_t>(skeleton.user)].effect.num_terms;
      for (int j = 0; j < cand_terms; ++j) cand_columns.push_back(user_column + first_term[t] + j);
    }
    const Eigen::VectorXd x = solver.step(cand_columns);
    const double ssr = problem.ssr_at(x, o.fit.threads);
    const double predicted = ssr0 + x.dot(ne.Jtr);  // ½|r + Jx|²·2 with H x = −g on the columns
    Candidate c = skeleton;
    c.screened = true;
    FitResult& f = c.fit;
    f.params = b;
    f.params.effects = c.effects;
    f.params.user = trials[t].user;
    for (Effect e : model::kAllEffects) {
      const int col = problem.column(e);
      if (!c.effects.has(e) || col < 0) continue;
      double* v = f.params.block(e);
      for (int q = 0; q < model::info(e).num_params; ++q) v[q] += x[col + q];
    }
    for (int j = 0; j < b.user.num_terms; ++j)
      f.params.user.coeff[static_cast<std::size_t>(j)] += x[user_column + j];
    for (int j = 0; j < cand_terms; ++j)
      f.params.user.coeff[static_cast<std::size_t>(b.user.num_terms + j)] =
          x[user_column + first_term[t] + j];
    f.usable = std::isfinite(ssr) && x.allFinite();
    f.engine = "normal";
    f.termination = "screened: one Gauss-Newton step from the baseline's solution";
    f.sigma = base.fit.sigma;
    f.samples = base.fit.samples;
    f.num_params = base.fit.num_params + static_cast<int>(cand_columns.size());
    f.bic = n_res * std::log(ssr / n_res) + f.num_params * std::log(n_res);
    const double decrease = ssr0 - predicted;
    // A decrease at rounding level carries no linearisation to check.
    const bool trusted = f.usable && (decrease <= 1e-9 * ssr0 ||
                                      std::abs((ssr0 - ssr) / decrease - 1.0) <= kMaxModelError);
    if (f.usable) {
      residuals_into(res, f.params, data, &split.heldout, o.fit.threads);
      score(c, base, res, split, scale);
      out.candidates.emplace_back(std::move(c));
    } else {
      out.candidates.emplace_back();
    }
    out.trusted.push_back(trusted);
  }
  return out;
}

// Beyond gains_tie's margin, a screened candidate is refitted while its screened gain is within
// this much of the best gain. On the hidden-effect runs (diagnose_screening_test) a screened
// gain is within 6e-4 of its refit's for candidates linear in their parameters and within 1e-4
// for the nonlinear ones that pass the kMaxModelError check; 0.02 (the ladder's smallest paying
// gain) is 30 times that, so a candidate left screened cannot overtake the refitted best.
constexpr double kScreeningSafety = 0.02;

bool could_be_best(double gain, double best) {
  return gain >= best - std::max(0.005, 0.02 * std::max(gain, best)) - kScreeningSafety;
}

std::vector<Candidate> evaluate_candidates(const Dataset& data, const Baseline& base,
                                           const Split& split, const DiagnoseOptions& o,
                                           const std::array<double, 6>& scale,
                                           CandidateEvaluation* how = nullptr) {
  const auto start = std::chrono::steady_clock::now();
  const std::vector<Trial> trials = candidate_trials(data, base, o);
  const std::size_t total = trials.size();
  std::vector<std::optional<Candidate>> results(total);
  std::vector<bool> refitted(total, false);
  int refits = 0;
  const auto do_refit = [&](std::size_t t) {
    if (o.progress)
      o.progress("  candidate " + std::to_string(t + 1) + "/" + std::to_string(total) + ": " +
                 trials[t].c.name);
    results[t] = refit(data, base, split, o, scale, trials[t]);
    refitted[t] = true;
    ++refits;
  };
  CandidateEvaluation eval;
  std::string why = screening_refused(data, base, o);
  Screened screened;
  if (why.empty() && total > 0) {
    try {
      if (o.progress)
        o.progress("  screening " + std::to_string(total) +
                   " candidates from one pass of the model with all of them");
      screened = screen(data, base, split, o, scale, trials, o.screening_drop_coupling);
    } catch (const std::exception& e) {
      why = std::string("every candidate refitted: the screening failed (") + e.what() + ")";
    }
  }
  if (!why.empty() || total == 0) {
    for (std::size_t t = 0; t < total; ++t) do_refit(t);
    eval.method = "refitted";
    eval.reason = why;
  } else {
    results = std::move(screened.candidates);
    // Candidates the screening could not take, or whose step left the linear range: refits.
    for (std::size_t t = 0; t < total; ++t)
      if (!results[t] || !screened.trusted[t]) do_refit(t);
    // Then every candidate that could still be the best, until the best is settled by refits.
    for (bool more = true; more;) {
      more = false;
      double best = -std::numeric_limits<double>::infinity();
      for (const auto& c : results)
        if (c) best = std::max(best, c->gain);
      for (std::size_t t = 0; t < total; ++t) {
        if (refitted[t] || !results[t] || !could_be_best(results[t]->gain, best)) continue;
        do_refit(t);
        more = true;
      }
    }
    eval.method = "screened";
    eval.reason =
        "screened from one accumulation pass of the model with every candidate (one "
        "Gauss-Newton step each); refitted: the candidates that could be the best (within " +
        fmt("%.3f", kScreeningSafety) +
        " of its gain beyond a tie) and any whose step left the linear range";
  }
  eval.refitted = refits;
  eval.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (how) *how = eval;
  std::vector<Candidate> out;
  for (auto& c : results)
    if (c) out.push_back(std::move(*c));
  std::sort(out.begin(), out.end(),
            [](const Candidate& a, const Candidate& b) { return a.gain > b.gain; });
  // Candidates that remove the same error (a general effect can mimic a specific one, e.g.
  // crosstalk can represent a sensor rotation) are tied; among tied ones the information
  // criterion decides, so the simpler explanation comes first.
  for (std::size_t g = 0; g < out.size();) {
    std::size_t end = g + 1;
    while (end < out.size() && gains_tie(out[g].gain, out[end].gain)) ++end;
    std::sort(out.begin() + static_cast<std::ptrdiff_t>(g),
              out.begin() + static_cast<std::ptrdiff_t>(end),
              [](const Candidate& a, const Candidate& b) { return a.delta_bic < b.delta_bic; });
    g = end;
  }
  return out;
}

// Candidate signals for residual correlation, in plain words.
// A signal the residual may follow: its values on samples [i0, i1) where `mask` is set, into
// out[i − i0] (the others are not read). Formed on demand, chunk by chunk: kept as columns, the
// forty-odd features of a 10^6-sample log held 320 MB (issue 16).
struct Feature {
  std::string name;
  std::function<void(std::size_t i0, std::size_t i1, const std::uint8_t* mask, double* out)> values;
};

std::vector<Feature> features(const Dataset& data) {
  std::vector<Feature> f;
  auto add = [&](std::string name, auto fn) {
    f.push_back({std::move(name),
                 [fn](std::size_t i0, std::size_t i1, const std::uint8_t* mask, double* out) {
                   for (std::size_t i = i0; i < i1; ++i)
                     if (mask[i]) out[i - i0] = fn(i);
                 }});
  };
  if (!data.columns.static_rows)
    add("time since start", [&](std::size_t i) { return data.pose(i).t_rel_s; });
  if (data.columns.temperature)
    add("sensor temperature", [&](std::size_t i) { return data.pose(i).temperature_C; });
  if (data.columns.joints) {
    for (int j = 0; j < 6; ++j) {
      const std::string a = "joint A" + std::to_string(j + 1);
      add(a + " angle (sine)", [&, j](std::size_t i) { return std::sin(data.joints_rad[i][j]); });
      add(a + " angle (cosine)", [&, j](std::size_t i) { return std::cos(data.joints_rad[i][j]); });
      if (data.columns.static_rows) continue;  // held poses: no velocities
      add(a + " velocity", [&, j](std::size_t i) { return data.joint_vel_radps(i)[j]; });
      add(a + " velocity direction (sign)", [&, j](std::size_t i) {
        const double v = data.joint_vel_radps(i)[j];
        return std::abs(v) < 1e-3 ? 0.0 : (v > 0 ? 1.0 : -1.0);
      });
    }
  }
  if (data.columns.any_imu()) {
    const char* ax = "xyz";
    for (int k = 0; k < 3; ++k) {
      if (data.columns.angular_rate) {
        add(std::string("angular rate about IMU ") + ax[k],
            [&, k](std::size_t i) { return data.imu[i * 9 + 3 + k]; });
        if (!data.columns.static_rows)
          add(std::string("angular acceleration about IMU ") + ax[k],
              [&, k](std::size_t i) { return data.imu[i * 9 + 6 + k]; });
      }
      if (data.columns.specific_force)
        add(std::string("specific force along IMU ") + ax[k],
            [&, k](std::size_t i) { return data.imu[i * 9 + k]; });
    }
    if (data.columns.angular_rate)
      add("squared angular rate", [&](std::size_t i) {
        return Eigen::Map<const Eigen::Vector3d>(&data.imu[i * 9 + 3]).squaredNorm();
      });
  }
  for (int k = 0; k < 3; ++k) {
    const char* ax = "xyz";
    add(std::string("gravity direction along sensor ") + ax[k], [&, k](std::size_t i) {
      return (data.pose(i).R_base_sensor.transpose() * Eigen::Vector3d(0, 0, -1))[k];
    });
  }
  return f;
}

std::vector<SignalCorrelation> correlate(const Dataset& data, const std::vector<Wrench>& res,
                                         const std::vector<std::uint8_t>& mask, int threads) {
  // Each feature's correlations on their own (one thread's sums each, in sample order, over the
  // masked samples), then in feature order. A feature's values are formed a chunk at a time as
  // its walk reaches them (releasing a spilled log's rows behind it).
  const std::vector<Feature> fs = features(data);
  std::vector<std::vector<SignalCorrelation>> per(fs.size());
  constexpr std::size_t kChunk = 4096;
  parallel::for_each(fs.size(), threads, [&](std::size_t q, int) {
    const Feature& f = fs[q];
    std::array<double, 6> sx{}, sy{}, sxx{}, syy{}, sxy{};
    double n = 0;
    std::vector<double> x(kChunk);
    ResidentWindow window(data);
    for (std::size_t i0 = 0; i0 < data.size(); i0 += kChunk) {
      const std::size_t i1 = std::min(data.size(), i0 + kChunk);
      window.advance(i1 - 1);
      f.values(i0, i1, mask.data(), x.data());
      for (std::size_t i = i0; i < i1; ++i) {
        if (!mask[i]) continue;
        const double xi = x[i - i0];
        for (int a = 0; a < 6; ++a) {
          const double y = res[i][a];
          sx[a] += xi, sy[a] += y, sxx[a] += xi * xi, syy[a] += y * y, sxy[a] += xi * y;
        }
        n += 1;
      }
    }
    for (int a = 0; a < 6; ++a) {
      const double vx = sxx[a] - sx[a] * sx[a] / n, vy = syy[a] - sy[a] * sy[a] / n;
      if (vx <= 1e-12 * n || vy <= 0) continue;
      per[q].push_back({f.name, a, (sxy[a] - sx[a] * sy[a] / n) / std::sqrt(vx * vy)});
    }
  });
  std::vector<SignalCorrelation> out;
  for (auto& p : per) out.insert(out.end(), p.begin(), p.end());
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
    return std::abs(a.correlation) > std::abs(b.correlation);
  });
  if (out.size() > 8) out.resize(8);
  return out;
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

// ---- Discovery of a law in the signal dictionary (proto/user_effects.md, "Discovery") ----

// Blocks of `m` consecutive samples inside the mask (as the fit forms them).
std::vector<std::pair<std::size_t, std::size_t>> mask_blocks(const std::vector<std::uint8_t>& mask,
                                                             std::size_t m) {
  std::vector<std::pair<std::size_t, std::size_t>> out;
  std::size_t run = 0;
  for (std::size_t i = 0; i <= mask.size(); ++i) {
    if (i < mask.size() && mask[i]) {
      ++run;
      continue;
    }
    for (std::size_t b = i - run; b + m <= i; b += m) out.emplace_back(b, m);
    run = 0;
  }
  return out;
}

// One factor of a basis, tabulated over the samples.
struct FactorColumn {
  model::Factor factor;
  // Left uninitialised until dictionary_factors writes every sample: zeroing 74 columns of a
  // long log first cost a serial third of the tabulation (issue 16); written on the workers,
  // its pages are touched there.
  std::unique_ptr<double[]> v;
};

// The discovery dictionary's factors: every base signal the log has (its value), sin and cos of
// the joint angles, and tanh(x/eps) of the velocities (eps: 0.02 rad/s, 0.005 m/s).
std::vector<FactorColumn> dictionary_factors(const Dataset& data, int threads) {
  const std::size_t n = data.size();
  const unsigned have = available_sources(data);
  std::vector<FactorColumn> out;
  auto add = [&](model::Signal s, model::FactorOp op, double eps) {
    out.push_back({{s, op, eps}, std::make_unique_for_overwrite<double[]>(n)});
  };
  for (int k = 0; k < model::kSignalCount; ++k) {
    const auto s = static_cast<model::Signal>(k);
    const model::SignalInfo& si = model::signal_info(s);
    if (!(have >> static_cast<unsigned>(si.source) & 1u)) continue;
    if (si.angle) {
      add(s, model::FactorOp::sin, 0.0);
      add(s, model::FactorOp::cos, 0.0);
      continue;
    }
    add(s, model::FactorOp::value, 0.0);
    if (si.velocity)
      add(s, model::FactorOp::tanh, std::string_view(si.unit) == "m/s" ? 0.005 : 0.02);
  }
  // A batch of samples' signals at a time, then every factor's values on them (each sample on
  // its own: the same values on any thread). The batch's signals stay in cache while every
  // factor reads its own signal from them: a whole chunk's (8192 samples) did not, and each
  // factor's pass went to memory (issue 16).
  constexpr std::size_t kBatch = 256;
  for_each_sample_chunk(data, threads, [&](std::size_t i0, std::size_t i1) {
    std::vector<model::DictionarySignals> sig(std::min(kBatch, i1 - i0));
    for (std::size_t b0 = i0; b0 < i1; b0 += kBatch) {
      const std::size_t b1 = std::min(i1, b0 + kBatch);
      for (std::size_t i = b0; i < b1; ++i) sig[i - b0] = data.dictionary(i);
      for (FactorColumn& c : out) {
        model::Basis b;
        b.a = c.factor;
        for (std::size_t i = b0; i < b1; ++i) c.v[i] = model::basis_value(b, sig[i - b0]);
      }
    }
  });
  return out;
}

// The first rank() columns of Q of a column-pivoted QR (never the full square Q).
Eigen::MatrixXd thin_q(const Eigen::ColPivHouseholderQR<Eigen::MatrixXd>& qr, Eigen::Index rows) {
  return qr.householderQ() * Eigen::MatrixXd::Identity(rows, qr.rank());
}

// z such that P(|N(0,1)| > z) = p.
double normal_two_sided_quantile(double p) {
  double lo = 0.0, hi = 40.0;
  for (int it = 0; it < 200; ++it) {
    const double mid = 0.5 * (lo + hi);
    (std::erfc(mid / std::sqrt(2.0)) > p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

struct Column {
  model::Basis basis;
  int axis = 0;
  std::vector<double> train, held;  // whitened block means on `axis` (other axes are zero)
  double score = 0.0;
};

std::string law_text(const model::UserEffects& u, int j, double sd) {
  const model::UserTerm& t = u.terms[static_cast<std::size_t>(j)];
  std::ostringstream os;
  os << io::term_axis_name(t) << " += " << fmt("%.4g", u.coeff[static_cast<std::size_t>(j)]);
  if (std::isfinite(sd)) os << " ± " << fmt("%.2g", sd);
  os << " " << io::coefficient_unit(t) << " · " << io::basis_text(t.basis);
  return os.str();
}

std::optional<Discovery> discover_law(const Dataset& data, const Baseline& base, const Split& split,
                                      const DiagnoseOptions& o,
                                      const std::array<double, 6>& scale) {
  const auto start = std::chrono::steady_clock::now();
  const auto since_start = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  const std::size_t m = static_cast<std::size_t>(std::max(1, o.fit.block_samples));
  const auto train_blocks = mask_blocks(split.train, m);
  const auto held_blocks = mask_blocks(split.heldout, m);
  const std::size_t nt = train_blocks.size(), nh = held_blocks.size();
  if (nt < 20 || nh < 5) return std::nullopt;
  const std::array<double, 6>& sigma = base.fit.sigma;  // block-mean whitening of the fit
  const std::vector<FactorColumn> factors = dictionary_factors(data, o.fit.threads);

  // Whitened block-mean residuals of the baseline, per axis: r[b * 6 + k].
  auto residual_means = [&](const std::vector<std::pair<std::size_t, std::size_t>>& blocks) {
    std::vector<double> r(blocks.size() * 6, 0.0);
    for (std::size_t b = 0; b < blocks.size(); ++b) {
      for (std::size_t i = blocks[b].first; i < blocks[b].first + blocks[b].second; ++i)
        for (int k = 0; k < 6; ++k) r[b * 6 + k] += base.res[i][k];
      for (int k = 0; k < 6; ++k) r[b * 6 + k] /= static_cast<double>(blocks[b].second) * sigma[k];
    }
    return r;
  };
  const std::vector<double> r_train = residual_means(train_blocks);
  const std::vector<double> r_held = residual_means(held_blocks);

  // The baseline's tangent space: whitened block-mean Jacobian of its free parameters, so that a
  // term the model can already absorb (a constant, a change of mass) scores nothing. By central
  // differences here (the fallback), or from the fit's block evaluation below.
  std::vector<double*> params;
  std::vector<double> steps;
  model::ModelParams p = base.fit.params;
  for (Effect e : model::kAllEffects) {
    if (!p.effects.has(e) || o.fit.frozen.has(e)) continue;
    for (int i = 0; i < model::info(e).num_params; ++i) params.push_back(p.block(e) + i);
  }
  for (int j = 0; j < p.user.num_terms; ++j)
    params.push_back(&p.user.coeff[static_cast<std::size_t>(j)]);
  const std::size_t np = params.size();
  auto jacobian = [&](const std::vector<std::pair<std::size_t, std::size_t>>& blocks) {
    Eigen::MatrixXd J = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(blocks.size() * 6),
                                              static_cast<Eigen::Index>(np));
    for (std::size_t q = 0; q < np; ++q) {
      const double x0 = *params[q];
      const double h = 1e-6 * std::max(1.0, std::abs(x0));
      for (int side = 0; side < 2; ++side) {
        *params[q] = x0 + (side == 0 ? h : -h);
        ResidentWindow window(data);
        for (std::size_t b = 0; b < blocks.size(); ++b) {
          window.advance(blocks[b].first + blocks[b].second);
          Wrench mean = Wrench::Zero();
          for (std::size_t i = blocks[b].first; i < blocks[b].first + blocks[b].second; ++i)
            mean += predict(p, data, i);
          mean /= static_cast<double>(blocks[b].second);
          for (int k = 0; k < 6; ++k)
            J(static_cast<Eigen::Index>(b * 6 + k), static_cast<Eigen::Index>(q)) +=
                (side == 0 ? 1.0 : -1.0) * mean[k] / (2.0 * h * sigma[k]);
        }
      }
      *params[q] = x0;
    }
    return J;
  };
  // The same Jacobian from the fit's own block evaluation: analytic derivatives of the block
  // means, one pass over the blocks instead of two model evaluations per parameter, which made a
  // quarter of discovery's time (issue 16). Its columns are packed as `params` (the effects in
  // library order without the frozen ones, then the user terms) and its blocks are mask_blocks'
  // (tests/integration/diagnose_screening_test.cpp, TrainingProblem); the residual's derivative
  // is the negated prediction's. Where the packing or the blocks differ (rows without time: the
  // fit's blocks are single rows) or the evaluation fails, the central differences stand in.
  auto analytic = [&](const std::vector<std::uint8_t>& mask,
                      const std::vector<std::pair<std::size_t, std::size_t>>& blocks)
      -> std::optional<Eigen::MatrixXd> {
    FitOptions fo = o.fit;
    fo.effects = p.effects;
    fo.user = p.user;
    fo.mask = &mask;
    fo.sigma = sigma;
    fo.initial = nullptr;
    try {
      const screening::TrainingProblem problem(data, fo, base.fit.params);
      if (problem.num_params() != static_cast<int>(np) || problem.num_blocks() != blocks.size())
        return std::nullopt;
      Eigen::MatrixXd J(static_cast<Eigen::Index>(blocks.size() * 6),
                        static_cast<Eigen::Index>(np));
      // Each block's rows on their own (the evaluation is concurrent: normal_equations.hpp).
      constexpr std::size_t kBlocksPerTask = 512;
      std::atomic<bool> ok{true};
      parallel::for_each((blocks.size() + kBlocksPerTask - 1) / kBlocksPerTask, o.fit.threads,
                         [&](std::size_t task, int) {
                           Eigen::Matrix<double, 6, Eigen::Dynamic, Eigen::RowMajor> jb(
                               6, static_cast<Eigen::Index>(np));
                           std::array<double, 6> r{};
                           const std::size_t b0 = task * kBlocksPerTask;
                           const std::size_t b1 = std::min(blocks.size(), b0 + kBlocksPerTask);
                           for (std::size_t b = b0; b < b1 && ok; ++b) {
                             if (!problem.evaluate(b, r.data(), jb.data())) ok = false;
                             J.middleRows(static_cast<Eigen::Index>(b * 6), 6) = -jb;
                           }
                         });
      if (!ok) return std::nullopt;
      return J;
    } catch (const std::exception&) {
      return std::nullopt;
    }
  };
  // The training and the held-out blocks' problems are set up side by side (each on its own).
  std::optional<Eigen::MatrixXd> J_train_a, J_held_a;
  parallel::for_each(2, o.fit.threads, [&](std::size_t side, int) {
    if (side == 0)
      J_train_a = analytic(split.train, train_blocks);
    else
      J_held_a = analytic(split.heldout, held_blocks);
  });
  if (!J_train_a) J_held_a.reset();
  const Eigen::MatrixXd J_train = J_held_a ? std::move(*J_train_a) : jacobian(train_blocks);
  const Eigen::MatrixXd J_held = J_held_a ? std::move(*J_held_a) : jacobian(held_blocks);
  // Orthonormal basis of the training tangent space (column-pivoted QR drops dependent ones).
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(J_train);
  const Eigen::Index rank = qr.rank();
  Eigen::MatrixXd Q = thin_q(qr, J_train.rows());
  // Its rows per axis, contiguous: Qk[k] is nt × rank.
  std::array<Eigen::MatrixXd, 6> Qk;
  std::array<Eigen::VectorXd, 6> rk;
  for (int k = 0; k < 6; ++k) {
    Qk[static_cast<std::size_t>(k)].resize(static_cast<Eigen::Index>(nt), rank);
    rk[static_cast<std::size_t>(k)].resize(static_cast<Eigen::Index>(nt));
    for (std::size_t t = 0; t < nt; ++t) {
      Qk[static_cast<std::size_t>(k)].row(static_cast<Eigen::Index>(t)) =
          Q.row(static_cast<Eigen::Index>(t * 6 + k));
      rk[static_cast<std::size_t>(k)][static_cast<Eigen::Index>(t)] = r_train[t * 6 + k];
    }
  }

  // Screening: every basis (factor, or product of two) on every axis, scored by the training
  // sum of squares it would remove alone after the model's own parameters (its squared
  // partial correlation with the residual); the best few per axis go on.
  constexpr int kKeepPerAxis = 10;
  std::array<std::vector<Column>, 6> kept;
  int searched = 0;
  const std::size_t nf = factors.size();
  // A basis's block means, the product fused in (no per-sample column is formed). Blocks hold
  // `m` samples each; the sums run over the blocks side by side, each block's in sample order as
  // before, so that consecutive additions are independent (a single running sum per block is
  // bound by the latency of the addition).
  auto basis_means = [&](std::size_t a, std::size_t b,
                         const std::vector<std::pair<std::size_t, std::size_t>>& blocks,
                         double* out) {
    const double* fa = factors[a].v.get();
    const double* fb = b < nf ? factors[b].v.get() : nullptr;
    constexpr std::size_t kChunk = 256;  // blocks per pass: their samples stay in cache
    for (std::size_t t0 = 0; t0 < blocks.size(); t0 += kChunk) {
      const std::size_t t1 = std::min(blocks.size(), t0 + kChunk);
      for (std::size_t t = t0; t < t1; ++t) out[t] = 0.0;
      for (std::size_t i = 0; i < m; ++i) {
        if (fb) {
          for (std::size_t t = t0; t < t1; ++t)
            out[t] += fa[blocks[t].first + i] * fb[blocks[t].first + i];
        } else {
          for (std::size_t t = t0; t < t1; ++t) out[t] += fa[blocks[t].first + i];
        }
      }
      for (std::size_t t = t0; t < t1; ++t) out[t] /= static_cast<double>(m);
    }
  };
  // Every basis's projections on the six axes' tangent spaces and on the residuals, by one
  // matrix product per batch of bases: one matrix-vector product per basis and axis dominated
  // discovery (issue 16). |Q_kᵀ c|² = Σ_j ((Q_k v_j)ᵀ c)² over the eigenvectors v_j of Q_kᵀ Q_k,
  // and an axis's slice of the tangent space has far fewer directions than the model has
  // parameters (a force axis sees only its bias and the mass), so only the directions with
  // weight (λ_j above 1e-14 of the largest: what is dropped is far below the 1e-9 cut on the
  // remaining part below) become rows. Rows: each axis's directions, then r_0ᵀ … r_5ᵀ.
  std::array<Eigen::Index, 7> row0{};
  std::array<Eigen::MatrixXd, 6> dirs;
  for (int k = 0; k < 6; ++k) {
    const Eigen::MatrixXd& q = Qk[static_cast<std::size_t>(k)];
    Eigen::MatrixXd& out = dirs[static_cast<std::size_t>(k)];
    if (rank == 0) {
      out.resize(0, static_cast<Eigen::Index>(nt));
    } else {
      const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(q.transpose() * q);
      const Eigen::VectorXd& l = eig.eigenvalues();  // ascending
      const double cut = 1e-14 * std::max(l.maxCoeff(), 0.0);
      Eigen::Index first = 0;
      while (first < l.size() && !(l[first] > cut)) ++first;
      out = (q * eig.eigenvectors().rightCols(l.size() - first)).transpose();
    }
    row0[static_cast<std::size_t>(k) + 1] = row0[static_cast<std::size_t>(k)] + out.rows();
  }
  const Eigen::Index nq = row0[6];
  Eigen::MatrixXd M(nq + 6, static_cast<Eigen::Index>(nt));
  for (int k = 0; k < 6; ++k) {
    const auto ks = static_cast<std::size_t>(k);
    M.middleRows(row0[ks], dirs[ks].rows()) = dirs[ks];
    M.row(nq + k) = rk[ks].transpose();
  }
  std::vector<std::pair<std::size_t, std::size_t>> bases;  // (a, b); b == nf: factor a alone
  for (std::size_t a = 0; a < nf; ++a)
    for (std::size_t b = a; b <= nf; ++b) bases.emplace_back(a, b);
  const auto nbases = static_cast<Eigen::Index>(bases.size());
  // Every basis's training block means, a chunk of blocks at a time: the chunk's samples of every
  // factor are copied together first (sample i of every block side by side), so that all bases
  // read them from cache rather than streaming two whole factor columns each. Each block's sum
  // still runs in sample order from zero (as a sum over a product column would), and the sums of
  // neighbouring blocks are independent. P accumulates the projections chunk by chunk.
  // The chunks run on the fit's threads (parallel.hpp): each forms its block means and its
  // products into its worker's scratch, and they are added into P and c2 in chunk order, so the
  // sums are those of one thread, chunk after chunk.
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(nq + 6, nbases);
  Eigen::VectorXd c2 = Eigen::VectorXd::Zero(nbases);
  constexpr std::size_t kChunk = 128;
  struct ChunkScratch {
    Eigen::MatrixXd C;
    std::vector<double> local;  // [(factor * m + sample) * kChunk + block]
  };
  struct ChunkResult {
    Eigen::MatrixXd P;
    Eigen::VectorXd c2;
  };
  const std::size_t chunks = (nt + kChunk - 1) / kChunk;
  std::vector<ChunkScratch> scratch(
      static_cast<std::size_t>(parallel::workers(chunks, o.fit.threads)));
  for (ChunkScratch& w : scratch) {
    w.C.resize(static_cast<Eigen::Index>(kChunk), nbases);
    w.local.resize(nf * m * kChunk);
  }
  constexpr std::size_t kWindow = 8;
  std::vector<ChunkResult> results(kWindow);
  const auto chunk_products = [&](std::size_t chunk, int worker, std::size_t slot) {
    ChunkScratch& w = scratch[static_cast<std::size_t>(worker)];
    ChunkResult& result = results[slot];
    Eigen::MatrixXd& C = w.C;
    std::vector<double>& local = w.local;
    const std::size_t t0 = chunk * kChunk;
    const std::size_t nb = std::min(kChunk, nt - t0);
    for (std::size_t f = 0; f < nf; ++f)
      for (std::size_t i = 0; i < m; ++i)
        for (std::size_t t = 0; t < nb; ++t)
          local[(f * m + i) * kChunk + t] = factors[f].v[train_blocks[t0 + t].first + i];
    for (Eigen::Index j = 0; j < nbases; ++j) {
      const auto [a, b] = bases[static_cast<std::size_t>(j)];
      double* out = C.col(j).data();
      std::fill(out, out + nb, 0.0);
      for (std::size_t i = 0; i < m; ++i) {
        const double* xa = &local[(a * m + i) * kChunk];
        if (b < nf) {
          const double* xb = &local[(b * m + i) * kChunk];
          for (std::size_t t = 0; t < nb; ++t) out[t] += xa[t] * xb[t];
        } else {
          for (std::size_t t = 0; t < nb; ++t) out[t] += xa[t];
        }
      }
      for (std::size_t t = 0; t < nb; ++t) out[t] /= static_cast<double>(m);
    }
    const auto rows = static_cast<Eigen::Index>(nb);
    result.P.noalias() = M.middleCols(static_cast<Eigen::Index>(t0), rows) * C.topRows(rows);
    result.c2 = C.topRows(rows).colwise().squaredNorm().transpose();
  };
  parallel::ordered(chunks, o.fit.threads, kWindow, chunk_products,
                    [&](std::size_t, std::size_t slot) {
                      P += results[slot].P;
                      c2 += results[slot].c2;
                    });
  // The best few per axis, in the order the bases were searched; only the final ones get their
  // columns.
  std::array<std::vector<std::pair<double, Eigen::Index>>, 6> top;  // (score, basis)
  for (Eigen::Index j = 0; j < nbases; ++j) {
    for (int k = 0; k < 6; ++k) {
      ++searched;
      const auto ks = static_cast<std::size_t>(k);
      const double w = 1.0 / sigma[k];
      const double rc = w * P(nq + k, j), cc = w * w * c2[j];
      const double qq = w * w * P.col(j).segment(row0[ks], row0[ks + 1] - row0[ks]).squaredNorm();
      const double perp = cc - qq;
      if (!(perp > 1e-9 * std::max(cc, 1e-300))) continue;
      const double score = rc * rc / perp;
      auto& list = top[ks];
      if (static_cast<int>(list.size()) == kKeepPerAxis && score <= list.back().first) continue;
      list.emplace_back(score, j);
      std::sort(list.begin(), list.end(),
                [](const auto& x, const auto& y) { return x.first > y.first; });
      if (static_cast<int>(list.size()) > kKeepPerAxis) list.pop_back();
    }
  }
  std::vector<double> mt(nt), mh(nh);
  for (int k = 0; k < 6; ++k) {
    for (const auto& [score, j] : top[static_cast<std::size_t>(k)]) {
      const auto [a, b] = bases[static_cast<std::size_t>(j)];
      Column col;
      col.basis.a = factors[a].factor;
      if (b < nf) {
        // A product of two; the same angle's sin·cos and a velocity's tanh·value repeat simpler
        // shapes, but are kept: the search decides.
        col.basis.b = factors[b].factor;
        col.basis.product = true;
      }
      col.axis = k;
      col.score = score;
      basis_means(a, b, train_blocks, mt.data());
      basis_means(a, b, held_blocks, mh.data());
      col.train.resize(nt);
      for (std::size_t t = 0; t < nt; ++t) col.train[t] = mt[t] / sigma[k];
      col.held.resize(nh);
      for (std::size_t t = 0; t < nh; ++t) col.held[t] = mh[t] / sigma[k];
      kept[static_cast<std::size_t>(k)].push_back(std::move(col));
    }
  }
  std::vector<Column> cand;
  for (auto& list : kept)
    for (auto& c : list) cand.push_back(std::move(c));

  // Orthogonal matching pursuit over the screened columns, in the full whitened space (all six
  // axes), with the model's tangent space always in the regression.
  const Eigen::Index Nt = static_cast<Eigen::Index>(nt * 6), Nh = static_cast<Eigen::Index>(nh * 6);
  const Eigen::Map<const Eigen::VectorXd> rt(r_train.data(), Nt), rh(r_held.data(), Nh);
  const double held_base = rh.squaredNorm();
  Discovery d;
  d.dictionary_size = searched;
  for (const Column& c : cand) d.column_scores.push_back(c.score);
  // Bonferroni over every column searched: a noise column passes with probability 1 %.
  d.z_threshold = normal_two_sided_quantile(o.discovery_alpha / std::max(1, searched));
  std::vector<std::size_t> chosen;
  double held_prev = held_base;
  // The current fit's columns on training, [J_sel, X] (J_sel: the tangent space's independent
  // columns, in its pivoted QR's order; X: the accepted terms), and every candidate with it
  // projected out, grown column by column (growing_fit.hpp): a fresh QR of [J, X] per step, its
  // thin Q, a second one for the held-out check and every candidate's projection on all of it
  // made half of the search (issue 16).
  const auto ncand = static_cast<Eigen::Index>(cand.size());
  GrowingFit gf(qr, Q, rt, o.max_discovered_terms, ncand);
  std::vector<double> x2(cand.size(), 0.0);  // |x|² of each candidate
  // Candidates a few at a time on the fit's threads (parallel.hpp): each candidate's data and
  // statistic are its own, and the best is taken in candidate order, so the results do not
  // depend on the thread count.
  constexpr Eigen::Index kColumnsPerTask = 8;
  const auto tasks = [&](Eigen::Index columns) {
    return static_cast<std::size_t>((columns + kColumnsPerTask - 1) / kColumnsPerTask);
  };
  // Every candidate projected out of the tangent space, by one matrix product per few: a column
  // is nonzero on one axis only, so Qᵀ x reads that axis's rows of Q.
  parallel::for_each(tasks(ncand), o.fit.threads, [&](std::size_t task, int) {
    const Eigen::Index j0 = static_cast<Eigen::Index>(task) * kColumnsPerTask;
    const Eigen::Index nj = std::min(kColumnsPerTask, ncand - j0);
    Eigen::MatrixXd G(rank, nj);
    for (Eigen::Index j = 0; j < nj; ++j) {
      const Column& c = cand[static_cast<std::size_t>(j0 + j)];
      const Eigen::Map<const Eigen::MatrixXd, 0, Eigen::Stride<Eigen::Dynamic, 6>> rows(
          Q.data() + c.axis, static_cast<Eigen::Index>(nt), rank,
          Eigen::Stride<Eigen::Dynamic, 6>(Q.outerStride(), 6));
      G.col(j).noalias() = rows.transpose() * Eigen::Map<const Eigen::VectorXd>(
                                                  c.train.data(), static_cast<Eigen::Index>(nt));
    }
    gf.projections().middleCols(j0, nj).noalias() = -Q * G;
    gf.coefficients().block(0, j0, rank, nj) = G;
    for (Eigen::Index j = 0; j < nj; ++j) {
      const Column& c = cand[static_cast<std::size_t>(j0 + j)];
      double& xx = x2[static_cast<std::size_t>(j0 + j)];
      for (std::size_t t = 0; t < nt; ++t) {
        gf.projections()(static_cast<Eigen::Index>(t * 6) + c.axis, j0 + j) += c.train[t];
        xx += c.train[t] * c.train[t];
      }
    }
  });
  for (int step = 0; step < o.max_discovered_terms; ++step) {
    std::vector<std::size_t> open;
    for (std::size_t c = 0; c < cand.size(); ++c)
      if (std::find(chosen.begin(), chosen.end(), c) == chosen.end()) open.push_back(c);
    const Eigen::Index nopen = static_cast<Eigen::Index>(open.size());
    const Eigen::VectorXd& r_cur = gf.residual();
    std::vector<double> zs(open.size(), 0.0);
    const auto statistics = [&](std::size_t task, int) {
      const Eigen::Index j0 = static_cast<Eigen::Index>(task) * kColumnsPerTask;
      const Eigen::Index nj = std::min(kColumnsPerTask, nopen - j0);
      for (Eigen::Index j = j0; j < j0 + nj; ++j) {
        const std::size_t c = open[static_cast<std::size_t>(j)];
        gf.refresh(static_cast<Eigen::Index>(c));
        const auto xp = gf.projections().col(static_cast<Eigen::Index>(c));
        const double xx = xp.squaredNorm();
        if (!(xx > 1e-9 * x2[c])) continue;
        // Heteroscedasticity-robust statistic of the coefficient (White's sandwich, HC0, on the
        // residual with the column in the fit): moving blocks carry more noise (IMU noise × mass)
        // than dwells.
        const double num = xp.dot(r_cur);
        const double var =
            (xp.array().square() * (r_cur.array() - (num / xx) * xp.array()).square()).sum();
        zs[static_cast<std::size_t>(j)] = var > 0 ? std::abs(num) / std::sqrt(var) : 0.0;
      }
    };
    parallel::for_each(tasks(nopen), o.fit.threads, statistics);
    double best_z = 0.0;
    std::size_t best = cand.size();
    for (std::size_t j = 0; j < open.size(); ++j)
      if (zs[j] > best_z) best_z = zs[j], best = open[j];
    if (best == cand.size() || best_z < d.z_threshold) break;
    // Held-out check: the linearised refit with the new column must lower the held-out error.
    // The tangent space's dependent columns (beyond its pivoted QR's rank) get no coefficient.
    const GrowingFit::Trial trial = gf.trial(static_cast<Eigen::Index>(best));
    Eigen::VectorXd theta_j = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(np));
    for (Eigen::Index i = 0; i < rank; ++i)
      theta_j[qr.colsPermutation().indices()[i]] = trial.theta[i];
    Eigen::VectorXd pred_held = J_held * theta_j;
    for (std::size_t i = 0; i <= chosen.size(); ++i) {
      const Column& c = cand[i < chosen.size() ? chosen[i] : best];
      const double w = trial.theta[rank + static_cast<Eigen::Index>(i)];
      for (std::size_t t = 0; t < nh; ++t)
        pred_held[static_cast<Eigen::Index>(t * 6) + c.axis] += w * c.held[t];
    }
    const double held_new = (rh - pred_held).squaredNorm();
    if (held_prev - held_new < o.min_term_gain * held_base) break;
    held_prev = held_new;
    gf.accept(trial);
    chosen.push_back(best);
    d.z.push_back(best_z);
  }
  d.search_seconds = since_start();
  if (chosen.empty()) return std::nullopt;

  // The effect: the chosen terms, refitted with the whole model on the training blocks. Named
  // "discovered", or "discovered_2", "_3", ... when the model already carries that name (the loop
  // iterates: a law found on top of an earlier one).
  model::UserEffects& u = d.effect;
  std::string name = "discovered";
  const auto taken = [&](const std::string& n) {
    for (int k = 0; k < base.fit.params.user.num_effects; ++k)
      if (io::user_effect_name(base.fit.params.user, k) == n) return true;
    return false;
  };
  for (int n = 2; taken(name); ++n) name = "discovered_" + std::to_string(n);
  u.num_effects = 1;
  std::copy(name.begin(), name.end(), u.names[0].begin());
  for (std::size_t c : chosen) {
    model::UserTerm t;
    t.basis = cand[c].basis;
    t.axis = static_cast<std::uint8_t>(cand[c].axis);
    u.terms[static_cast<std::size_t>(u.num_terms++)] = t;
  }
  FitOptions fo = o.fit;
  fo.effects = base.fit.params.effects;
  fo.user = base.fit.params.user;
  io::append_user_effects(fo.user, u);
  fo.mask = &split.train;
  fo.covariance = true;
  fo.initial = &base.fit.params;
  fo.progress = nullptr;
  d.fit = fit(data, fo);
  if (!d.fit.usable) return std::nullopt;
  const int offset = base.fit.params.user.num_terms;
  for (int j = 0; j < u.num_terms; ++j) {
    u.coeff[static_cast<std::size_t>(j)] =
        d.fit.params.user.coeff[static_cast<std::size_t>(offset + j)];
    d.std.push_back(static_cast<std::size_t>(offset + j) < d.fit.user_std.size()
                        ? d.fit.user_std[static_cast<std::size_t>(offset + j)]
                        : std::numeric_limits<double>::quiet_NaN());
    d.laws.push_back(law_text(u, j, d.std.back()));
  }
  d.heldout = heldout_error(residuals_of(d.fit.params, data, &split.heldout, o.fit.threads),
                            split.heldout, scale);
  d.gain = 1.0 - d.heldout.whitened_mse / base.heldout.whitened_mse;
  d.seconds = since_start();
  return d;
}

}  // namespace

std::vector<Effect> candidate_effects(const model::EffectSet& m, const Dataset& data) {
  std::vector<Effect> out;
  for (Effect e : model::kAllEffects) {
    if (m.has(e)) continue;
    model::EffectSet with = m;
    with.add(e);
    try {
      check_signals(with, data);
    } catch (const std::runtime_error&) {
      continue;  // needs a signal the log lacks, or an effect the model lacks
    }
    out.push_back(e);
  }
  return out;
}

namespace {

// A discovered law's effect file (at o.discovery_path, if set) and the command that adds it. Apart
// from the diagnosis, so that diagnose() writes it only when the verdict is the law's (not for a
// diagnosis it consulted on the way to an event).
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

// A library effect pays on its own when it removes at least this share of the held-out error
// and the information criterion takes it; the law is then searched on top of it.
constexpr double kPaysOnItsOwn = 0.10;
// ...and it stays in the proposal only if the model with the law but without it is worse by at
// least this share of the baseline's held-out error.
constexpr double kStillNeeded = 0.02;

// The law when no library effect explains the residual. If the best library candidate pays on its
// own but leaves structure (a library effect and a law outside the library hidden together), the
// law is searched on top of it: searched alone, in a residual the effect dominates, it comes out
// mangled (a cable's gravity seen as sin(q2)·tanh(qd6)) and the loop needs a turn per confusion.
// Both are proposed together if each is needed; otherwise the law on top of the model as given.
std::optional<Discovery> discover_beyond(const Dataset& data, const Baseline& base,
                                         const Split& split, const DiagnoseOptions& o,
                                         const Diagnosis& d) {
  if (!d.candidates.empty() && d.candidates[0].user < 0 && d.candidates[0].gain >= kPaysOnItsOwn &&
      d.candidates[0].delta_bic < 0) {
    const Candidate& c = d.candidates[0];
    if (o.progress)
      o.progress("diagnose: " + c.name + " pays on its own; searching the law on top of it");
    Baseline on = fit_baseline(data, c.effects, o.fit.user, split, o, &c.fit.params);
    on.heldout = heldout_error(on.res, split.heldout, d.noise_rms);
    std::optional<Discovery> x = discover_law(data, on, split, o, d.noise_rms);
    if (x && x->gain >= o.min_law_gain) {
      // Without the library effect, the law alone: is the effect still needed?
      FitOptions fo = o.fit;
      fo.effects = base.fit.params.effects;
      fo.user = base.fit.params.user;
      io::append_user_effects(fo.user, x->effect);
      fo.mask = &split.train;
      fo.covariance = false;
      fo.initial = nullptr;
      fo.progress = nullptr;
      const FitResult alone = fit(data, fo);
      const double alone_mse =
          alone.usable
              ? heldout_error(residuals_of(alone.params, data, &split.heldout, o.fit.threads),
                              split.heldout, d.noise_rms)
                    .whitened_mse
              : std::numeric_limits<double>::infinity();
      if ((alone_mse - x->heldout.whitened_mse) / base.heldout.whitened_mse >= kStillNeeded) {
        x->with_effect = c.name;
        x->with_effects = c.effects;
        x->law_gain = x->gain;
        x->gain = 1.0 - x->heldout.whitened_mse / base.heldout.whitened_mse;
        return x;
      }
    }
  }
  std::optional<Discovery> x = discover_law(data, base, split, o, d.noise_rms);
  if (x && x->gain < o.min_law_gain) x.reset();
  if (x) x->law_gain = x->gain;
  return x;
}

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

namespace {
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
}  // namespace

BlockChoice choose_blocks(const Dataset& data, double block_s, int every, int offset) {
  return choose_blocks_excluding(data, block_s, every, offset, nullptr);
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
