// Speed of identification (figures in docs/speed.md):
//  - zerog fit of the full effect list on 100,000 samples (issue 16's aims: at most 25 × the
//    reference, 30 × with covariance);
//  - zerog diagnose over all candidates on the same log (aim: at most 50 × the reference);
//  - a reference in the same run: one double evaluation of the model over all samples, so the
//    ratio fit / evaluation is comparable across machines.
// These headline benchmarks run three repetitions each; docs/speed.md quotes the median one.
// The fits use the default engine (the streamed normal equations, FitOptions::engine); the
// *BlockStatsEngine variants time Ceres on the block sufficient statistics (the same block
// evaluation, Ceres' dense normal equations), the *SamplesEngine variants the per-sample
// reference engine, in the same run.
// How cost grows with the work (BM_Scale*, argument `samples`: 10^4, 10^5, 10^6): the
// reference, the full and the default fit, diagnose and the ladder on logs of each length, each
// with the peak resident memory it reached (counters peak_rss_MB, peak_growth_MB). They run size
// by size (registered in main), so that only one size's log is held at a time. BM_ScaleReadLog:
// reading a log file of each length into a dataset, whole or streamed (issue 16).
// The tables of docs/speed.md are written from its JSON output: scripts/figures.py speed.
#include <benchmark/benchmark.h>
#include <malloc.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>

#include "zerog/ident/diagnose.hpp"
#include "zerog/ident/fit.hpp"
#include "zerog/sim/design.hpp"
#include "zerog/sim/simulator.hpp"

namespace {

using namespace zerog;

// The first `samples` samples of a random path with the given truth effects: 200 points per
// 100,000 samples (a longer path for a longer log, the same path up to 100,000 samples).
formats::Log simulated_log(const std::string& effects, std::size_t samples) {
  sim::SimConfig cfg = sim::default_sim_config(1);
  cfg.effects = sim::parse_sim_effects(effects);
  sim::DesignOptions d;
  d.kind = sim::DesignKind::random;
  d.points = 200 * static_cast<int>((samples + 99999) / 100000);
  d.workspace.floor_z_m = cfg.floor_z_m;
  sim::RigSimulator s(cfg, sim::make_design(d).points_rad);
  formats::Log log = s.run().log;
  if (log.samples.size() < samples)
    throw std::runtime_error("the simulated path gave " + std::to_string(log.samples.size()) +
                             " samples, fewer than " + std::to_string(samples));
  log.samples.resize(samples);
  return log;
}

ident::Dataset simulated(const std::string& effects, std::size_t samples = 100000) {
  return ident::make_dataset(simulated_log(effects, samples));
}

// Every effect the model library has (none of those outside it).
constexpr const char* kAllLibraryEffects =
    "all,-joint6_friction,-swivel_viscous,-hose_drag,-dress_pack_bend";

// The log of `samples` samples with every library effect; one length is held at a time (the
// previous one is freed first), so that a benchmark's peak memory holds its own log only.
const ident::Dataset& dataset(std::size_t samples = 100000) {
  static std::unique_ptr<ident::Dataset> data;
  static std::size_t held = 0;
  if (!data || held != samples) {
    data.reset();
    data = std::make_unique<ident::Dataset>(simulated(kAllLibraryEffects, samples));
    held = samples;
  }
  return *data;
}

// The value in kB of a line of /proc/self/status ("VmHWM:", "VmRSS:"); -1 if absent.
double status_kb(const std::string& key) {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(key, 0) != 0) continue;
    std::istringstream value(line.substr(key.size()));
    double kb = -1;
    value >> kb;
    return kb;
  }
  return -1;
}

// Peak resident memory while a benchmark runs. Freed heap memory is first returned to the system
// (glibc's malloc_trim), so that the resident size at the start is what is live. Linux resets the
// high-water mark VmHWM to the current resident size when "5" is written to /proc/self/clear_refs
// (since 4.0); then VmHWM at the end is this benchmark's own peak. Where that fails (no procfs, an
// older kernel), the peak is getrusage's ru_maxrss, the whole process's peak so far (an upper
// bound: it also holds earlier benchmarks). Counters: peak_rss_MB (the peak, with the log held) and
// peak_growth_MB (the peak above the resident size at the start: what the benchmarked call
// allocated); peak_reset is 1 when the peak is this benchmark's own.
class PeakMemory {
 public:
  PeakMemory() {
    malloc_trim(0);
    std::ofstream clear("/proc/self/clear_refs");
    clear << "5" << std::flush;
    reset_ = static_cast<bool>(clear) && status_kb("VmHWM:") >= 0;
    start_kb_ = status_kb("VmRSS:");
  }
  void report(benchmark::State& state) const {
    double peak_kb = reset_ ? status_kb("VmHWM:") : -1;
    if (peak_kb < 0) {
      rusage u{};
      getrusage(RUSAGE_SELF, &u);
      peak_kb = static_cast<double>(u.ru_maxrss);  // kB on Linux
    }
    state.counters["peak_rss_MB"] = peak_kb / 1024.0;
    state.counters["peak_growth_MB"] = start_kb_ >= 0 ? (peak_kb - start_kb_) / 1024.0 : -1;
    state.counters["peak_reset"] = reset_ ? 1 : 0;
  }

 private:
  bool reset_ = false;
  double start_kb_ = -1;
};

// The log of `samples` samples with every library effect as a file (zerog log format) in the
// temporary folder, one length at a time (the previous file is removed first); removed at exit.
struct LogFile {
  std::filesystem::path csv;
  std::size_t samples = 0;
  void remove() const {
    std::error_code ec;
    if (csv.empty()) return;
    std::filesystem::remove(csv, ec);
    std::filesystem::remove(formats::rig_path_for(csv), ec);
  }
  ~LogFile() { remove(); }
};
const std::filesystem::path& log_file(std::size_t samples) {
  static LogFile file;
  if (file.samples != samples) {
    file.remove();
    file.csv = std::filesystem::temp_directory_path() /
               ("zerog_ident_bench_" + std::to_string(::getpid()) + ".csv");
    formats::write_log(simulated_log(kAllLibraryEffects, samples), file.csv);
    file.samples = samples;
  }
  return file.csv;
}

// Bytes a dataset holds per sample (the capacity of its per-sample vectors).
double dataset_bytes_per_sample(const ident::Dataset& d) {
  return static_cast<double>(d.bytes()) / static_cast<double>(d.size());
}

model::EffectSet full_list() {
  model::EffectSet all;
  for (auto e : model::kAllEffects) all.add(e);
  return all;
}

void BM_ModelEvaluationAllSamples(benchmark::State& state) {
  const auto& data = dataset();
  model::ModelParams p;
  p.effects = full_list();
  p.block(model::Effect::gravity)[0] = 100.0;
  for (auto _ : state) {
    double sum = 0;
    for (std::size_t i = 0; i < data.size(); ++i) sum += ident::predict(p, data, i)[2];
    benchmark::DoNotOptimize(sum);
  }
  state.counters["samples"] = static_cast<double>(data.size());
}
BENCHMARK(BM_ModelEvaluationAllSamples)->Unit(benchmark::kMillisecond)->Repetitions(3);

// The timed loop of every fit benchmark: `o` fitted on `data`, with the counters iterations,
// parameters and samples, and with `peak_memory` the peak resident memory (PeakMemory; the
// BM_Scale* set).
void time_fit(benchmark::State& state, const ident::Dataset& data, const ident::FitOptions& o,
              bool peak_memory) {
  std::optional<PeakMemory> peak;
  if (peak_memory) peak.emplace();
  for (auto _ : state) {
    auto r = ident::fit(data, o);
    benchmark::DoNotOptimize(r.params);
    state.counters["iterations"] = r.iterations;
    state.counters["parameters"] = r.num_params;
  }
  if (peak) peak->report(state);
  state.counters["samples"] = static_cast<double>(data.size());
}

void fit_full_effect_list(benchmark::State& state, const std::string& engine) {
  ident::FitOptions o;
  o.effects = full_list();
  o.covariance = state.range(0) != 0;
  o.engine = engine;
  time_fit(state, dataset(), o, false);
}

void BM_FitFullEffectList(benchmark::State& state) { fit_full_effect_list(state, "normal"); }
BENCHMARK(BM_FitFullEffectList)
    ->Arg(0)
    ->Arg(1)
    ->ArgName("covariance")
    ->Unit(benchmark::kSecond)
    ->Iterations(1)
    ->Repetitions(3);

void BM_FitFullEffectListBlockStatsEngine(benchmark::State& state) {
  fit_full_effect_list(state, "block_stats");
}
BENCHMARK(BM_FitFullEffectListBlockStatsEngine)
    ->Arg(0)
    ->Arg(1)
    ->ArgName("covariance")
    ->Unit(benchmark::kSecond)
    ->Iterations(1);

void BM_FitFullEffectListSamplesEngine(benchmark::State& state) {
  fit_full_effect_list(state, "samples");
}
BENCHMARK(BM_FitFullEffectListSamplesEngine)
    ->Arg(0)
    ->Arg(1)
    ->ArgName("covariance")
    ->Unit(benchmark::kSecond)
    ->Iterations(1);

void fit_default_model(benchmark::State& state, const std::string& engine) {
  ident::FitOptions o;
  o.effects = model::kDefaultModel;
  o.engine = engine;
  time_fit(state, dataset(), o, false);
}

void BM_FitDefaultModel(benchmark::State& state) { fit_default_model(state, "normal"); }
BENCHMARK(BM_FitDefaultModel)->Unit(benchmark::kSecond)->Iterations(1)->Repetitions(3);

void BM_FitDefaultModelBlockStatsEngine(benchmark::State& state) {
  fit_default_model(state, "block_stats");
}
BENCHMARK(BM_FitDefaultModelBlockStatsEngine)->Unit(benchmark::kSecond)->Iterations(1);

void BM_FitDefaultModelSamplesEngine(benchmark::State& state) {
  fit_default_model(state, "samples");
}
BENCHMARK(BM_FitDefaultModelSamplesEngine)->Unit(benchmark::kSecond)->Iterations(1);

// Candidates screened from one accumulation pass (the default), or with exact_candidates every
// one refitted (what diagnose did before the screening: the reference of its speed-up).
void diagnose_all_candidates(benchmark::State& state, bool exact) {
  const auto& data = dataset();
  ident::DiagnoseOptions o;
  o.fit.effects = model::kDefaultModel;
  o.exact_candidates = exact;
  for (auto _ : state) {
    auto d = ident::diagnose(data, o);
    benchmark::DoNotOptimize(d.candidates);
    state.counters["candidates"] = static_cast<double>(d.candidates.size());
    // Where the time goes: the candidates (screening and refits) and discovery (if it ran).
    state.counters["candidates_s"] = d.candidate_evaluation.seconds;
    state.counters["refitted"] = d.candidate_evaluation.refitted;
    state.counters["discovery_s"] = d.discovery ? d.discovery->seconds : 0.0;
    state.counters["discovery_search_s"] = d.discovery ? d.discovery->search_seconds : 0.0;
    state.counters["discovery_terms"] = d.discovery ? d.discovery->effect.num_terms : 0.0;
  }
}
void BM_DiagnoseAllCandidates(benchmark::State& state) { diagnose_all_candidates(state, false); }
BENCHMARK(BM_DiagnoseAllCandidates)->Unit(benchmark::kSecond)->Iterations(1)->Repetitions(3);
void BM_DiagnoseAllCandidatesExact(benchmark::State& state) {
  diagnose_all_candidates(state, true);
}
BENCHMARK(BM_DiagnoseAllCandidatesExact)->Unit(benchmark::kSecond)->Iterations(1);

// Discovery over the full signal dictionary (proto/user_effects.md): the default model on a run
// with an effect outside the library; diagnose tries every library candidate, finds none, and
// searches the dictionary. Counters: the search alone and the whole discovery (refit included).
void BM_DiagnoseWithDiscovery(benchmark::State& state) {
  static const ident::Dataset data = simulated("joint6_friction");
  ident::DiagnoseOptions o;
  o.fit.effects = model::kDefaultModel;
  for (auto _ : state) {
    auto d = ident::diagnose(data, o);
    benchmark::DoNotOptimize(d.candidates);
    if (!d.discovery) {
      state.SkipWithError("nothing discovered");
      break;
    }
    state.counters["discovery_search_s"] = d.discovery->search_seconds;
    state.counters["discovery_s"] = d.discovery->seconds;
    state.counters["columns"] = d.discovery->dictionary_size;
    state.counters["terms"] = d.discovery->effect.num_terms;
  }
  state.counters["samples"] = static_cast<double>(data.size());
}
BENCHMARK(BM_DiagnoseWithDiscovery)->Unit(benchmark::kSecond)->Iterations(1)->Repetitions(3);

// --- How cost grows with the work: the same steps on logs of 10^4, 10^5 and 10^6 samples ------

std::size_t samples_arg(const benchmark::State& state, int index) {
  return static_cast<std::size_t>(state.range(index));
}

// The reference of its size: one double evaluation of the full model over every sample.
void BM_ScaleModelEvaluation(benchmark::State& state) {
  const auto& data = dataset(samples_arg(state, 0));
  model::ModelParams p;
  p.effects = full_list();
  p.block(model::Effect::gravity)[0] = 100.0;
  const PeakMemory peak;
  for (auto _ : state) {
    double sum = 0;
    for (std::size_t i = 0; i < data.size(); ++i) sum += ident::predict(p, data, i)[2];
    benchmark::DoNotOptimize(sum);
  }
  peak.report(state);
  state.counters["samples"] = static_cast<double>(data.size());
}

// Argument 0: covariance (0 or 1); 1: samples. The default engine (normal), or `engine`.
void scale_fit_full_effect_list(benchmark::State& state, const std::string& engine) {
  const auto& data = dataset(samples_arg(state, 1));
  ident::FitOptions o;
  o.effects = full_list();
  o.covariance = state.range(0) != 0;
  if (!engine.empty()) o.engine = engine;
  time_fit(state, data, o, true);
}

void BM_ScaleFitFullEffectList(benchmark::State& state) { scale_fit_full_effect_list(state, ""); }
void BM_ScaleFitFullEffectListBlockStatsEngine(benchmark::State& state) {
  scale_fit_full_effect_list(state, "block_stats");
}

void scale_fit_default_model(benchmark::State& state, const std::string& engine) {
  const auto& data = dataset(samples_arg(state, 0));
  ident::FitOptions o;
  o.effects = model::kDefaultModel;
  if (!engine.empty()) o.engine = engine;
  time_fit(state, data, o, true);
}

void BM_ScaleFitDefaultModel(benchmark::State& state) { scale_fit_default_model(state, ""); }
void BM_ScaleFitDefaultModelBlockStatsEngine(benchmark::State& state) {
  scale_fit_default_model(state, "block_stats");
}

void scale_diagnose(benchmark::State& state, bool exact) {
  const auto& data = dataset(samples_arg(state, 0));
  ident::DiagnoseOptions o;
  o.fit.effects = model::kDefaultModel;
  o.exact_candidates = exact;
  const PeakMemory peak;
  for (auto _ : state) {
    auto d = ident::diagnose(data, o);
    benchmark::DoNotOptimize(d.candidates);
    state.counters["candidates"] = static_cast<double>(d.candidates.size());
    // Where the time goes: the candidates (screening and refits) and discovery (if it ran).
    state.counters["candidates_s"] = d.candidate_evaluation.seconds;
    state.counters["refitted"] = d.candidate_evaluation.refitted;
    state.counters["discovery_s"] = d.discovery ? d.discovery->seconds : 0.0;
  }
  peak.report(state);
  state.counters["samples"] = static_cast<double>(data.size());
}

void BM_ScaleDiagnose(benchmark::State& state) { scale_diagnose(state, false); }
void BM_ScaleDiagnoseExactCandidates(benchmark::State& state) { scale_diagnose(state, true); }

// `zerog ladder`'s climb from bias + gravity, its first kLadderSteps steps (each a diagnosis
// over every candidate): the same work at every size.
constexpr int kLadderSteps = 3;

void scale_ladder(benchmark::State& state, bool exact) {
  const auto& data = dataset(samples_arg(state, 0));
  ident::LadderOptions o;
  o.diagnose.fit.effects = model::kMinimalModel;
  o.diagnose.exact_candidates = exact;
  o.max_steps = kLadderSteps;
  const PeakMemory peak;
  for (auto _ : state) {
    auto steps = ident::ladder(data, o);
    benchmark::DoNotOptimize(steps);
    state.counters["steps"] = static_cast<double>(steps.size()) - 1;  // effects added
  }
  peak.report(state);
  state.counters["samples"] = static_cast<double>(data.size());
}

void BM_ScaleLadder(benchmark::State& state) { scale_ladder(state, false); }
void BM_ScaleLadderExactCandidates(benchmark::State& state) { scale_ladder(state, true); }

// Reading a log file into a dataset, as `zerog fit` does (argument 0): 0 the whole file first
// (formats::read_log, then make_dataset: text, parsed rows and dataset held at once), 1 streamed
// (ident::read_dataset: rows in chunks into the dataset). Counter dataset_B_per_sample: what the
// dataset itself holds.
void BM_ScaleReadLog(benchmark::State& state) {
  const bool streamed = state.range(0) != 0;
  const std::filesystem::path& csv = log_file(samples_arg(state, 1));
  const PeakMemory peak;
  std::size_t samples = 0;
  double bytes_per_sample = 0.0;
  for (auto _ : state) {
    const ident::Dataset data =
        streamed ? ident::read_dataset(csv) : ident::make_dataset(formats::read_log(csv));
    samples = data.size();
    bytes_per_sample = dataset_bytes_per_sample(data);
  }
  peak.report(state);
  state.counters["samples"] = static_cast<double>(samples);
  state.counters["dataset_B_per_sample"] = bytes_per_sample;
}

// Size by size, so that one log is simulated and held at a time (dataset()).
void register_scale_benchmarks() {
  for (const std::int64_t n : {10'000, 100'000, 1'000'000}) {
    benchmark::RegisterBenchmark("BM_ScaleModelEvaluation", BM_ScaleModelEvaluation)
        ->Arg(n)
        ->ArgName("samples")
        ->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark("BM_ScaleFitFullEffectList", BM_ScaleFitFullEffectList)
        ->Args({0, n})
        ->Args({1, n})
        ->ArgNames({"covariance", "samples"})
        ->Unit(benchmark::kSecond)
        ->Iterations(1);
    benchmark::RegisterBenchmark("BM_ScaleFitFullEffectListBlockStatsEngine",
                                 BM_ScaleFitFullEffectListBlockStatsEngine)
        ->Args({0, n})
        ->Args({1, n})
        ->ArgNames({"covariance", "samples"})
        ->Unit(benchmark::kSecond)
        ->Iterations(1);
    benchmark::RegisterBenchmark("BM_ScaleFitDefaultModel", BM_ScaleFitDefaultModel)
        ->Arg(n)
        ->ArgName("samples")
        ->Unit(benchmark::kSecond)
        ->Iterations(1);
    benchmark::RegisterBenchmark("BM_ScaleFitDefaultModelBlockStatsEngine",
                                 BM_ScaleFitDefaultModelBlockStatsEngine)
        ->Arg(n)
        ->ArgName("samples")
        ->Unit(benchmark::kSecond)
        ->Iterations(1);
    benchmark::RegisterBenchmark("BM_ScaleDiagnose", BM_ScaleDiagnose)
        ->Arg(n)
        ->ArgName("samples")
        ->Unit(benchmark::kSecond)
        ->Iterations(1);
    benchmark::RegisterBenchmark("BM_ScaleDiagnoseExactCandidates", BM_ScaleDiagnoseExactCandidates)
        ->Arg(n)
        ->ArgName("samples")
        ->Unit(benchmark::kSecond)
        ->Iterations(1);
    benchmark::RegisterBenchmark("BM_ScaleLadder", BM_ScaleLadder)
        ->Arg(n)
        ->ArgName("samples")
        ->Unit(benchmark::kSecond)
        ->Iterations(1);
    benchmark::RegisterBenchmark("BM_ScaleLadderExactCandidates", BM_ScaleLadderExactCandidates)
        ->Arg(n)
        ->ArgName("samples")
        ->Unit(benchmark::kSecond)
        ->Iterations(1);
    benchmark::RegisterBenchmark("BM_ScaleReadLog", BM_ScaleReadLog)
        ->Args({0, n})
        ->Args({1, n})
        ->ArgNames({"streamed", "samples"})
        ->Unit(benchmark::kSecond)
        ->Iterations(1);
  }
}

}  // namespace

int main(int argc, char** argv) {
  register_scale_benchmarks();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
