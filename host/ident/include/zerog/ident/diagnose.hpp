#pragma once
// Which physical effect is missing? Ranks candidate effects by how much they reduce the error on
// held-out (time-blocked) data, and climbs the ladder of effects from a minimal model.
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "zerog/ident/compare.hpp"
#include "zerog/ident/events.hpp"
#include "zerog/ident/fit.hpp"
#include "zerog/ident/kinematics_sources.hpp"

namespace zerog::ident {

struct HeldOut {
  ErrorStats stats;
  double whitened_mse = 0.0;  ///< mean over held-out samples and axes of (e_k / noise_k)^2
};

struct Candidate {
  model::Effect effect = model::Effect::bias;  ///< a library candidate (when user < 0)
  int user = -1;             ///< else: index into DiagnoseOptions::user_candidates
  std::string name;          ///< "cable", or "@name" for a user-defined effect
  model::EffectSet effects;  ///< the model with the candidate (and what it builds on)
  FitResult fit;
  HeldOut heldout;
  double gain = 0.0;  ///< fraction of the baseline's held-out noise-whitened MSE removed
  std::array<double, 6> axis_gain{};  ///< per-axis fraction of held-out MSE removed
  double delta_bic = 0.0;             ///< BIC(candidate) − BIC(baseline), on the training samples
  /// A table's diagnosis (diagnose_table): the share of rows the candidate predicts better in
  /// cross-validation (no BIC there: delta_bic is 0); -1 otherwise.
  double better_rows = -1.0;
  /// True: the figures (fit.params, heldout, gains, delta_bic) are the screening's: one
  /// Gauss–Newton step of the baseline plus this candidate from the baseline's solution
  /// (linearised, not iterated; fit.params is that step, held-out figures are exact for it).
  /// False: a warm-started fit() of the model with the candidate (a refit).
  bool screened = false;
};

/// How diagnose evaluated the candidates (Diagnosis::candidate_evaluation).
struct CandidateEvaluation {
  /// "screened": one accumulation pass of the model with every candidate, a Gauss–Newton step
  /// per candidate, and refits of the leading ones; "refitted": a fit per candidate.
  std::string method = "refitted";
  std::string
      reason;        ///< plain words: why refits (option, robust loss, ...), or what screening did
  int refitted = 0;  ///< candidates whose figures come from a refit
  double seconds = 0.0;  ///< wall time of evaluating the candidates (screening and refits)
};

struct SignalCorrelation {
  std::string signal;  ///< plain words, e.g. "joint A6 velocity direction (sign)"
  int axis = 0;
  double correlation = 0.0;
};

/// A law found in the signal dictionary when no library effect explains the residual
/// (proto/user_effects.md, "Discovery"): sure-independence screening of every basis and axis,
/// then orthogonal matching pursuit on the training blocks, each term validated on the held-out
/// blocks; the terms found are refitted with the whole model (Ceres) for values and deviations.
struct Discovery {
  model::UserEffects effect;  ///< one user effect ("discovered"), fitted coefficients
  std::vector<double> std;    ///< standard deviation of each coefficient
  std::vector<double> z;      ///< each term's screening statistic when it was chosen
  FitResult fit;              ///< the model with the discovered effect, on the training blocks
  HeldOut heldout;            ///< of that fit (noise-whitened MSE with the diagnosis' scale)
  double gain = 0.0;          ///< share of the baseline's held-out whitened MSE it removes
  /// The library effect the law was searched on top of ("" = the model as given): the best
  /// candidate, when it pays on its own but leaves structure; the proposal adds both, and
  /// `gain` is theirs together.
  std::string with_effect;
  model::EffectSet with_effects;  ///< the model with that effect (when with_effect is set)
  double law_gain = 0.0;          ///< the law's own share, over the model with with_effect
  int dictionary_size = 0;        ///< candidate columns (basis × axis) searched
  double z_threshold = 0.0;       ///< a term must pass this (Bonferroni over the dictionary)
  std::vector<std::string> laws;  ///< "Mz += 1.49 ± 0.01 N*m · tanh(qd6/0.02)"
  std::string path;               ///< the effect file written (empty if none)
  double search_seconds = 0.0;    ///< screening and pursuit (without the final refit)
  double seconds = 0.0;           ///< the whole discovery, refit included
  /// The screening score of every column the search went on with (per axis, best first): the
  /// sums of the scoring pass, which tests compare across thread counts.
  std::vector<double> column_scores;
};

/// A user-defined effect offered as a candidate (proto/user_effects.md): one effect, and the
/// file it came from (for the suggested command).
struct UserCandidate {
  model::UserEffects effect;
  std::string source;
};

/// The time blocks of the held-out split (every `every`-th block held out), as used for a log.
struct BlockChoice {
  double block_s = 60.0;  ///< block length, s (0 for rows without time: one row per block)
  int blocks = 0;         ///< blocks in the log
  bool automatic = true;  ///< chosen from the log's length, not given (--block)
  std::size_t heldout_samples = 0, training_samples = 0;
  std::string text;  ///< in words, e.g. "blocks of 0.75 s (8 blocks; the log is 6.0 s)"
};

/// Default block length; used whenever the log holds at least kMinBlocks of them.
inline constexpr double kDefaultBlockS = 60.0;
/// Blocks a log must hold when the length is chosen: with every 4th held out, 2 held-out blocks.
inline constexpr int kMinBlocks = 8;
/// Shortest block chosen: far longer than the 5-row difference stencils and the 3-row motion
/// dilation at any rate zerog reads (≥ 100 Hz), so a held-out block is not predicted by its
/// neighbours' samples.
inline constexpr double kMinBlockS = 0.5;
/// Samples each side of the split needs (held-out and training).
inline constexpr std::size_t kMinSplitSamples = 100;

/// The blocks of the held-out split. `block_s` > 0: that length (refused, naming what works, if
/// the log then lacks kMinSplitSamples on a side). `block_s` <= 0: chosen from the log: 60 s if
/// it holds at least 8 blocks of 60 s, else its duration / 8, not below 0.5 s. Throws
/// std::runtime_error (naming the log's length and what would work) when no split fits: a log
/// shorter than 8 × 0.5 s = 4 s, or with fewer than 100 samples on a side.
BlockChoice choose_blocks(const Dataset& data, double block_s, int every = 4, int offset = -1);

/// A pose of a static table that stands out of the cross-validated residual (diagnose_table).
struct Outlier {
  std::size_t row = 0;  ///< 0-based sample index (data row row + 1)
  double z = 0.0;       ///< largest |residual − median| / robust spread over the axes
  std::array<double, 6> residual{};  ///< its cross-validated residual, S (N, N·m)
};

struct Diagnosis {
  BlockChoice split;  ///< the held-out split's blocks
  /// Which source fed which effect of the model (JSON "kinematics_sources").
  std::vector<EffectFeeds> kinematics;
  nlohmann::json kinematics_json;  ///< kinematics_json() of the log
  std::string kinematics_text;     ///< format_kinematics() of the log
  model::EffectSet model;
  FitResult baseline;
  HeldOut baseline_heldout;
  /// White noise per axis, estimated from differences of held-out residuals 5 rows apart
  /// (structure is smooth over 60 ms, noise is not).
  std::array<double, 6> noise_rms{};
  /// Share of the noise-whitened held-out MSE above the noise: Σ_k max(0, mse_k/σ_k² − 1) / Σ_k
  /// mse_k/σ_k².
  double structured_fraction = 0.0;
  std::vector<Candidate> candidates;          ///< best first
  CandidateEvaluation candidate_evaluation;   ///< screened or refitted, and why
  std::vector<SignalCorrelation> correlated;  ///< strongest first
  std::optional<Discovery> discovery;         ///< when verdict is `discovered`
  /// The step detector's scan of the model's residual, refitted without the spans it found
  /// (events.hpp); `possible` false for a table without time or when switched off.
  SpanScan scan;
  /// Spans the verdict calls events: they stand out, are few, and no effect of the diagnosis
  /// fitted without them explains them. Not empty exactly when verdict is `event`; then every
  /// figure above (baseline, candidates, discovery) is of the log without them.
  std::vector<Span> events;
  /// Why the scan's spans are not events, when it found some (recurring, tied to the motion,
  /// explained by the physics); empty otherwise.
  std::string spans_note;
  /// The rows the diagnosis left out, as --exclude takes them: the user's and the events'.
  std::string exclude;
  /// A table's poses that stand out (verdict `outliers`; diagnose_table).
  std::vector<Outlier> outliers;
  enum class Verdict {
    effect,
    none,
    nothing_left,
    discovered,
    event,
    outliers
  } verdict = Verdict::none;
  std::string text;     ///< plain words
  std::string command;  ///< the command that adds the effect, if any
};

struct DiagnoseOptions {
  /// Time-block length for the held-out split, s; 0: chosen from the log (choose_blocks()).
  double block_s = 0.0;
  int every = 4;            ///< every n-th block is held out
  int heldout_offset = -1;  ///< which block of each `every` is held out (default the last)
  /// Samples neither fitted nor scored (e.g. a final test set kept for a later comparison, or
  /// --exclude).
  const std::vector<std::uint8_t>* exclude = nullptr;
  /// `exclude` as --exclude takes it, for the suggested command ("" if none or not expressible).
  std::string exclude_text;
  /// Look for events (a contact, a collision) before blaming the physics (events.hpp).
  bool events = true;
  EventOptions event_options;
  /// Test only: a mutant that takes every span the detector finds for an event (no recurrence,
  /// motion or physics check); the events tests must fail with it.
  bool events_mutant_every_span = false;
  FitOptions fit;                    ///< effects = the model to diagnose; mask is set internally
  std::string log_path = "run.csv";  ///< for the suggested command
  /// Where the suggested command writes its refitted model (zerog diagnose names a new file
  /// beside the log: never an input, never an existing file).
  std::string fit_out = "fitted.json";
  /// The model as given on the command line, for the suggested command (default: the effect
  /// names of `fit.effects` and `fit.user`).
  std::string model_text;
  /// User-defined effects tried as candidates beside the library's (diagnose --candidates).
  std::vector<UserCandidate> user_candidates;
  /// Refit every candidate (a warm-started fit each) instead of screening them all from one
  /// accumulation pass and refitting only those that could be the best (diagnose
  /// --exact-candidates).
  bool exact_candidates = false;
  /// Test only: a mutant of the screening that ignores the coupling of the candidate's columns
  /// with the baseline's (no Schur complement); the screening tests must fail with it.
  bool screening_drop_coupling = false;
  /// When no library effect explains the structure, search the signal dictionary for a law.
  bool discover = true;
  /// Where discovery writes the effect file it finds ("" = do not write).
  std::string discovery_path;
  int max_discovered_terms = 8;
  /// A term must remove at least this share of the baseline's held-out whitened MSE.
  double min_term_gain = 0.003;
  /// Family-wise error rate of the term statistic (Bonferroni over every column searched).
  double discovery_alpha = 0.01;
  /// A law must remove at least this share of the baseline's held-out whitened MSE.
  double min_law_gain = 0.02;
  std::function<void(const std::string&)> progress;
};

/// The effects a model may still add, given the signals in the log.
std::vector<model::Effect> candidate_effects(const model::EffectSet& model, const Dataset& data);

/// A diagnosis of `model` on `data` with nothing in it yet but the model and where its
/// kinematics come from (kinematics_feeds, their JSON and text).
Diagnosis start_diagnosis(const model::EffectSet& model, const Dataset& data);

/// A log with time: events first (events.hpp), then the held-out time blocks. A static table
/// (rows without time): diagnose_table.
Diagnosis diagnose(const Dataset& data, const DiagnoseOptions& options);

/// A static table of at least 10 poses (docs/insight-loop.md, "Small tables"): k-fold
/// cross-validation over the rows instead of time blocks (leave-one-out up to 30 rows, else 10
/// interleaved folds), poses that stand out of the cross-validated residual named as outliers
/// (and left out of what follows), and each effect the table can feed, a drift over the row
/// order (bias_drift, per row) among them, kept if it lowers the cross-validated error by 5 %
/// and for most rows. Throws std::runtime_error for fewer than 10 rows.
Diagnosis diagnose_table(const Dataset& data, const DiagnoseOptions& options);

struct LadderStep {
  model::EffectSet effects;
  model::UserEffects user;  ///< the user-defined effects of the step's model
  std::optional<model::Effect> added;
  std::string added_name;  ///< the library effect's name or "@name"; empty at the start
  HeldOut heldout;
  double bic = 0.0;
  double gain = 0.0;
};

struct LadderOptions {
  DiagnoseOptions diagnose;
  double min_gain = 0.02;  ///< an effect pays if it removes at least this share of held-out MSE
  int max_steps = 10;
};

/// From `options.diagnose.fit.effects` (default bias + gravity), adds the best effect while it
/// pays.
std::vector<LadderStep> ladder(const Dataset& data, const LadderOptions& options);

nlohmann::json to_json(const BlockChoice& b);
nlohmann::json to_json(const Diagnosis& d);
nlohmann::json to_json(const std::vector<LadderStep>& steps);
std::string format_diagnosis(const Diagnosis& d);
std::string format_ladder(const std::vector<LadderStep>& steps);

}  // namespace zerog::ident
