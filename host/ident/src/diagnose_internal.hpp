#pragma once
// What diagnose's files share (diagnose.hpp): the held-out split and the baseline on it
// (heldout.cpp), the candidates (candidates.cpp), the signals the residual follows
// (correlation.cpp), discovery of a law (discovery.cpp), the verdict of the physics (verdict.cpp)
// and the words they write (diagnosis_text.cpp); diagnose.cpp holds the entry points (the event
// scan before the physics, the ladder). Host only: allocates.
#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "parallel.hpp"
#include "zerog/ident/diagnose.hpp"

namespace zerog::ident::diagnosis {

// ---- The held-out split and the baseline (heldout.cpp) ----

// Samples per task of the per-sample passes on several threads (parallel.hpp).
inline constexpr std::size_t kSampleChunk = 8192;

inline std::size_t sample_chunks(std::size_t n) { return (n + kSampleChunk - 1) / kSampleChunk; }

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
// outside it in a new vector, left as they were in `out`), on `threads` threads.
void residuals_into(std::vector<Wrench>& out, const model::ModelParams& params, const Dataset& data,
                    const std::vector<std::uint8_t>* mask, int threads);
std::vector<Wrench> residuals_of(const model::ModelParams& params, const Dataset& data,
                                 const std::vector<std::uint8_t>* mask, int threads);

// The error of the residuals `res` on the samples in `mask`, and its mean square whitened by
// `sigma`.
HeldOut heldout_error(const std::vector<Wrench>& res, const std::vector<std::uint8_t>& mask,
                      const std::array<double, 6>& sigma);

// White noise per axis of the residuals on the samples in `mask` (from differences 5 rows apart).
std::array<double, 6> noise_estimate(const std::vector<Wrench>& res,
                                     const std::vector<std::uint8_t>& mask);

// The held-out and the training samples (each without the rows the user left out).
struct Split {
  std::vector<std::uint8_t> heldout, train;
  BlockChoice blocks;
};

Split make_split(const Dataset& data, const DiagnoseOptions& o);

// A model fitted on the training blocks, its residuals on every sample and its held-out error.
struct Baseline {
  FitResult fit;
  std::vector<Wrench> res;
  HeldOut heldout;
};

// The model (`effects`, `user`) fitted on the split's training blocks from `initial` (null: the
// fit's start); throws if the fit is not usable.
Baseline fit_baseline(const Dataset& data, const model::EffectSet& effects,
                      const model::UserEffects& user, const Split& split, const DiagnoseOptions& o,
                      const model::ModelParams* initial);

// ---- The candidates (candidates.cpp) ----

// Two held-out gains are indistinguishable if they differ by less than half a percentage point
// or 2 % of the larger.
bool gains_tie(double a, double b);

// Every candidate the baseline lacks, measured on the held-out blocks (gains against `scale`),
// best first; how they were measured in `how` if given.
std::vector<Candidate> evaluate_candidates(const Dataset& data, const Baseline& base,
                                           const Split& split, const DiagnoseOptions& o,
                                           const std::array<double, 6>& scale,
                                           CandidateEvaluation* how = nullptr);

// ---- The signals the residual follows (correlation.cpp) ----

// The signals most correlated with the residuals `res` on the samples in `mask` (at most 8, by
// |correlation|).
std::vector<SignalCorrelation> correlate(const Dataset& data, const std::vector<Wrench>& res,
                                         const std::vector<std::uint8_t>& mask, int threads);

// ---- Discovery (discovery.cpp) ----

// The law when no library effect explains the residual of `base` (the diagnosis `d` so far:
// its candidates and noise), on top of the best library candidate if that pays on its own; none
// if no law gains at least o.min_law_gain.
std::optional<Discovery> discover_beyond(const Dataset& data, const Baseline& base,
                                         const Split& split, const DiagnoseOptions& o,
                                         const Diagnosis& d);

// ---- The verdict (verdict.cpp) ----

// The diagnosis of the physics: the model's held-out error, the candidates, a law (diagnose()
// looks for events first).
Diagnosis diagnose_physics(const Dataset& data, const DiagnoseOptions& o);

// The parameters of the diagnosis' answer: the model with the effect or law it proposes, else
// the baseline.
const model::ModelParams& answer_params(const Diagnosis& d);

// ---- Words (diagnosis_text.cpp) ----

// `a` formatted by the printf format `f`.
std::string fmt(const char* f, double a);

// A candidate's estimated parameters (the largest few, in their units).
std::string param_summary(const Candidate& c);

// User term j of `u` as a law ("Fz += c ± sd N · basis"; sd NaN: no ±).
std::string law_text(const model::UserEffects& u, int j, double sd);

// The --effects text of the model as given with `effects` in place of its library effects.
std::string model_with(const model::EffectSet& effects, const Diagnosis& d,
                       const DiagnoseOptions& o);

// A discovered law's effect file (at o.discovery_path, if set and the verdict is the law's) and
// the command that adds it.
void write_discovery(Diagnosis& d, const DiagnoseOptions& o);

}  // namespace zerog::ident::diagnosis
