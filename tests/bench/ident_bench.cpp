// Speed of identification (figures in the README):
//  - zerog fit of the full effect list on 100,000 samples (aim: under 2 s on 2 cores);
//  - zerog diagnose over all candidates on the same log (aim: under 20 s);
//  - a reference in the same run: one double evaluation of the model over all samples, so the
//    ratio fit / evaluation is comparable across machines.
// The fits use the default engine (block sufficient statistics, FitOptions::engine); the
// *SamplesEngine variants time the per-sample reference engine in the same run.
// The README's tables are written from its JSON output: scripts/figures.py speed.
#include <benchmark/benchmark.h>

#include <string>

#include "zerog/ident/diagnose.hpp"
#include "zerog/ident/fit.hpp"
#include "zerog/sim/design.hpp"
#include "zerog/sim/simulator.hpp"

namespace {

using namespace zerog;

// 100,000 samples of a random 200-point path with the given truth effects.
ident::Dataset simulated(const std::string& effects) {
  sim::SimConfig cfg = sim::default_sim_config(1);
  cfg.effects = sim::parse_sim_effects(effects);
  sim::DesignOptions d;
  d.kind = sim::DesignKind::random;
  d.points = 200;
  d.workspace.floor_z_m = cfg.floor_z_m;
  sim::RigSimulator s(cfg, sim::make_design(d).points_rad);
  io::Log log = s.run().log;
  if (log.samples.size() > 100000) log.samples.resize(100000);
  return ident::make_dataset(log);
}

const ident::Dataset& dataset() {
  // Every effect the model library has (none of those outside it).
  static const ident::Dataset data =
      simulated("all,-joint6_friction,-swivel_viscous,-hose_drag,-dress_pack_bend");
  return data;
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
BENCHMARK(BM_ModelEvaluationAllSamples)->Unit(benchmark::kMillisecond);

void fit_full_effect_list(benchmark::State& state, const std::string& engine) {
  const auto& data = dataset();
  ident::FitOptions o;
  o.effects = full_list();
  o.covariance = state.range(0) != 0;
  o.engine = engine;
  for (auto _ : state) {
    auto r = ident::fit(data, o);
    benchmark::DoNotOptimize(r.params);
    state.counters["iterations"] = r.iterations;
    state.counters["parameters"] = r.num_params;
  }
  state.counters["samples"] = static_cast<double>(data.size());
}

void BM_FitFullEffectList(benchmark::State& state) { fit_full_effect_list(state, "block_stats"); }
BENCHMARK(BM_FitFullEffectList)
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
  const auto& data = dataset();
  ident::FitOptions o;
  o.effects = model::kDefaultModel;
  o.engine = engine;
  for (auto _ : state) {
    auto r = ident::fit(data, o);
    benchmark::DoNotOptimize(r.params);
    state.counters["iterations"] = r.iterations;
    state.counters["parameters"] = r.num_params;
  }
}

void BM_FitDefaultModel(benchmark::State& state) { fit_default_model(state, "block_stats"); }
BENCHMARK(BM_FitDefaultModel)->Unit(benchmark::kSecond)->Iterations(1);

void BM_FitDefaultModelSamplesEngine(benchmark::State& state) {
  fit_default_model(state, "samples");
}
BENCHMARK(BM_FitDefaultModelSamplesEngine)->Unit(benchmark::kSecond)->Iterations(1);

void BM_DiagnoseAllCandidates(benchmark::State& state) {
  const auto& data = dataset();
  ident::DiagnoseOptions o;
  o.fit.effects = model::kDefaultModel;
  for (auto _ : state) {
    auto d = ident::diagnose(data, o);
    benchmark::DoNotOptimize(d.candidates);
    state.counters["candidates"] = static_cast<double>(d.candidates.size());
  }
}
BENCHMARK(BM_DiagnoseAllCandidates)->Unit(benchmark::kSecond)->Iterations(1);

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
BENCHMARK(BM_DiagnoseWithDiscovery)->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
