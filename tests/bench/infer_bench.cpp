// Google Benchmark: one inference of the deployed model (physics + quantised residual network)
// against the float reference (physics + model::network_forward<double>) and physics alone, per
// sample, for the papers' network shapes and the widest the firmware takes. BM_Ratio times both
// paths on the same samples and reports quantised/float.
#include <benchmark/benchmark.h>

#include <chrono>

#include "infer_fixtures.hpp"
#include "zerog/infer/deploy_file.hpp"
#include "zerog/infer/inference.hpp"

namespace {

using namespace zerog;
using infer::test::feature_range;
using model::Activation;
using model::Feature;

struct NetCase {
  const char* name;
  std::vector<Feature> features;
  std::vector<int> hidden;
  Activation activation;
};

const std::vector<NetCase>& net_cases() {
  static const std::vector<NetCase> cases = [] {
    std::vector<Feature> bp = feature_range(Feature::r11, Feature::wdz);
    bp.insert(bp.end(), {Feature::px, Feature::py, Feature::pz});
    return std::vector<NetCase>{
        {"bp_21_8_sigmoid", bp, {8}, Activation::sigmoid},
        {"residual_24_32_32_tanh",
         feature_range(Feature::sin_q1, Feature::sign_qd6),
         {32, 32},
         Activation::tanh},
        {"zp_9_45_90_leaky_relu",
         feature_range(Feature::r11, Feature::r33),
         {45, 90},
         Activation::leaky_relu},
        {"max_50_128x3_leaky_relu",
         feature_range(Feature::sin_q1, Feature::time),
         {128, 128, 128},
         Activation::leaky_relu},
    };
  }();
  return cases;
}

const std::vector<model::FeatureSignals>& samples() {
  static const auto s = infer::test::random_samples(1024, 42);
  return s;
}

infer::Inference make_inference(const NetCase& c) {
  infer::DeployedModel m;
  m.rig = infer::test::demo_rig();
  m.physics = infer::test::demo_physics();
  m.network = infer::test::make_network(c.features, c.hidden, c.activation, samples(), 1.0, 5);
  infer::Inference inf;
  if (!inf.configure(m).ok()) std::abort();
  return inf;
}

void run(benchmark::State& state, infer::Path path) {
  const NetCase& c = net_cases()[static_cast<std::size_t>(state.range(0))];
  infer::Inference inf = make_inference(c);
  const auto& s = samples();
  std::size_t i = 0;
  infer::Wrench w;
  for (auto _ : state) {
    const model::FeatureSignals& x = s[i++ & 1023];
    const model::ImuSignals<double> imu = infer::imu_signals(x);
    benchmark::DoNotOptimize(inf.evaluate(path, x, imu, w));
    benchmark::DoNotOptimize(w);
  }
  state.SetLabel(c.name);
}

void BM_Quantised(benchmark::State& state) { run(state, infer::Path::quantised); }
void BM_FloatReference(benchmark::State& state) { run(state, infer::Path::float_reference); }
void BM_PhysicsOnly(benchmark::State& state) { run(state, infer::Path::physics_only); }

// Both paths over the same 1024 samples, repeated; reports ns per sample and quantised/float.
void BM_Ratio(benchmark::State& state) {
  const NetCase& c = net_cases()[static_cast<std::size_t>(state.range(0))];
  infer::Inference inf = make_inference(c);
  const auto& s = samples();
  double q_ns = 0.0, f_ns = 0.0;
  std::size_t n = 0;
  infer::Wrench w;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    for (const auto& x : s) {
      benchmark::DoNotOptimize(inf.evaluate(x, w));
      benchmark::DoNotOptimize(w);
    }
    const auto t1 = std::chrono::steady_clock::now();
    for (const auto& x : s) {
      benchmark::DoNotOptimize(inf.evaluate_reference(x, w));
      benchmark::DoNotOptimize(w);
    }
    const auto t2 = std::chrono::steady_clock::now();
    q_ns += std::chrono::duration<double, std::nano>(t1 - t0).count();
    f_ns += std::chrono::duration<double, std::nano>(t2 - t1).count();
    n += s.size();
  }
  state.SetLabel(c.name);
  state.counters["quantised_ns"] = q_ns / static_cast<double>(n);
  state.counters["float_ns"] = f_ns / static_cast<double>(n);
  state.counters["quantised/float"] = q_ns / f_ns;
}

// Start-up: parse and check a deployed-model file (not real-time; for scale).
void BM_Load(benchmark::State& state) {
  const NetCase& c = net_cases()[static_cast<std::size_t>(state.range(0))];
  const std::string bytes = infer::serialise_deployed_model(make_inference(c).model());
  for (auto _ : state) {
    infer::LoadResult r = infer::load_deployed_model(bytes, infer::test::demo_rig());
    if (!r.ok()) std::abort();
    benchmark::DoNotOptimize(r);
  }
  state.SetLabel(std::string(c.name) + ", " + std::to_string(bytes.size()) + " bytes");
}

BENCHMARK(BM_PhysicsOnly)->Arg(0);
BENCHMARK(BM_Load)->DenseRange(0, 3)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_Quantised)->DenseRange(0, 3);
BENCHMARK(BM_FloatReference)->DenseRange(0, 3);
BENCHMARK(BM_Ratio)->DenseRange(0, 3);

}  // namespace

BENCHMARK_MAIN();
