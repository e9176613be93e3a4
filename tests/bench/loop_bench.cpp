// Google Benchmark: the compute time of one zerog-rt cycle (zerog::loop::Cycle::step in zero-g,
// after 6 F/T and 24 IMU samples were handed in, as at 12 ms with a 500 Hz F/T and a 2 kHz IMU),
// against the model evaluation alone for the same deployed model, in the same run. Reported:
// ns per cycle and the ratio cycle / model. Speed is measured, never asserted.
//
// BM_CycleStep/0,1 step with the RSI message in KUKA units (test::step_rsi(Cycle&, RobotMessage,
// RsiReply&), tests/common/rsi_step.hpp: the border's conversions both ways included);
// BM_CycleStepSi/0,1 step with the SI sample as zerog-rt's RSI endpoint hands it
// (Cycle::step(RobotSample, RobotCorrection&): the cycle alone, conversions excluded, as in
// zerog-rt where rtio converts). BM_CycleStepFused/0,1: as BM_CycleStepSi with the motion estimator
// ([filter] motion = "fused") on the elastic KR 210 (its deflection stepped every cycle, the servo
// model fed every cycle's correction, proto/loop.md "Motion estimator"; the contact's tare on, as
// in the elastic HIL cases: the alternating pushes restart it): its cost is the ratio to
// BM_CycleStepSi of the same run.
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "infer_fixtures.hpp"
#include "rsi_step.hpp"
#include "zerog/formats/robot_toml.hpp"
#include "zerog/loop/cycle.hpp"
#include "zerog/proto/rsi_si.hpp"
#include "zerog/robot/robot_model.hpp"

namespace {

using namespace zerog;
using model::Activation;
using model::Feature;

infer::DeployedModel make_model(int kind) {
  infer::DeployedModel m;
  m.rig = infer::test::demo_rig();
  m.physics = infer::test::demo_physics();
  if (kind == 1) {
    static const auto samples = infer::test::random_samples(1024, 42);
    m.network =
        infer::test::make_network(infer::test::feature_range(Feature::sin_q1, Feature::sign_qd6),
                                  {32, 32}, Activation::tanh, samples, 1.0, 5);
  }
  return m;
}

const char* kind_name(int kind) { return kind == 0 ? "physics" : "physics+residual_24_32_32"; }

void BM_ModelOnly(benchmark::State& state) {
  const int kind = static_cast<int>(state.range(0));
  infer::Inference inf;
  if (!inf.configure(make_model(kind)).ok()) std::abort();
  const auto samples = infer::test::random_samples(1024, 7);
  const infer::Path path = kind == 0 ? infer::Path::physics_only : infer::Path::quantised;
  std::size_t i = 0;
  infer::Wrench w;
  for (auto _ : state) {
    const model::FeatureSignals& x = samples[i++ & 1023];
    const model::ImuSignals<double> imu = infer::imu_signals(x);
    benchmark::DoNotOptimize(inf.evaluate(path, x, imu, w));
    benchmark::DoNotOptimize(w);
  }
  state.SetLabel(kind_name(kind));
}

// `si`: step with the SI sample (the conversion to it made once, up front), else with the message.
void cycle_step(benchmark::State& state, bool si, bool fused = false) {
  const int kind = static_cast<int>(state.range(0));
  loop::CycleConfig config;
  config.period_s = 0.012;
  config.p_sensor_com_m = Eigen::Vector3d(0.03, -0.02, 0.25);
  if (fused) {
    config.motion.source = loop::MotionSource::fused;
    config.motion.ft_rate_hz = 500.0;
    config.motion.imu_rate_hz = 2000.0;
    config.motion.servo_hz = 8.0;  // the servo model fed every cycle's correction
    robot::RobotModel arm = formats::kr210_r2700();
    for (int i = 0; i < 6; ++i) arm.elasticity[i] = {1e6, 8.0, 0.05};
    config.robot = arm;
    config.tare_s = 1.5;  // [filter] tare_s, as the elastic HIL cases
  }
  loop::Cycle cycle;
  if (!cycle.configure(config, make_model(kind)).ok()) std::abort();
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 1.0);
  proto::rsi::RobotMessage m;
  m.actual_pose = {1500.0, 0.0, 1400.0, 0.0, 90.0, 0.0};
  m.joints_deg = {0.0, -90.0, 90.0, 0.0, 45.0, 0.0};
  m.ipoc = 1000;
  // Sensor samples made up front, so the loop times the cycle and not the random numbers.
  std::vector<samples::FtSample> fts(4096);
  std::vector<samples::ImuSample> imus(4096);
  for (auto& ft : fts) {
    ft.valid = true;
    for (int k = 0; k < 6; ++k) ft.wrench_si[k] = noise(rng);
    ft.wrench_si[2] += -980.0;
  }
  for (auto& imu : imus) {
    imu.rate_valid = imu.accel_valid = true;
    for (int k = 0; k < 3; ++k) {
      imu.accel_m_s2[k] = 0.01 * noise(rng);
      imu.rate_rad_s[k] = 1e-3 * noise(rng);
    }
    imu.accel_m_s2[2] += 9.81;
  }
  std::size_t next_ft = 0, next_imu = 0;
  test::RsiReply reply;
  samples::RobotCorrection correction;
  samples::RobotSample sample = proto::rsi::robot_sample_from_message(m);
  auto one_cycle = [&](double push_N) {
    for (int i = 0; i < 6; ++i) {
      samples::FtSample ft = fts[next_ft++ & 4095];
      ft.wrench_si[0] += push_N;
      cycle.add_ft(ft);
    }
    for (int i = 0; i < 24; ++i) cycle.add_imu(imus[next_imu++ & 4095]);
    if (si) {
      cycle.step(sample, correction);
      sample.ipoc += 12;
    } else {
      test::step_rsi(cycle, m, reply);
    }
    m.ipoc += 12;
  };
  for (int i = 0; i < 10; ++i) one_cycle(0.0);
  if (!cycle.request(loop::Command::enable_zero_g)) std::abort();
  one_cycle(0.0);
  if (cycle.state_machine().state() != loop::State::zero_g) std::abort();
  std::int64_t n = 0;
  for (auto _ : state) {
    // Alternating pushes keep the body moving slowly without reaching a limit.
    one_cycle(((n++ / 50) % 2) ? 20.0 : -20.0);
    benchmark::DoNotOptimize(reply);
    benchmark::DoNotOptimize(correction);
  }
  if (cycle.state_machine().state() != loop::State::zero_g) state.SkipWithError("cycle faulted");
  state.SetLabel(kind_name(kind));
  state.counters["ns_per_cycle"] =
      benchmark::Counter(static_cast<double>(state.iterations()),
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

void BM_CycleStep(benchmark::State& state) { cycle_step(state, false); }
void BM_CycleStepSi(benchmark::State& state) { cycle_step(state, true); }
void BM_CycleStepFused(benchmark::State& state) { cycle_step(state, true, true); }

}  // namespace

BENCHMARK(BM_ModelOnly)->Arg(0)->Arg(1);
BENCHMARK(BM_CycleStep)->Arg(0)->Arg(1);
BENCHMARK(BM_CycleStepSi)->Arg(0)->Arg(1);
BENCHMARK(BM_CycleStepFused)->Arg(0)->Arg(1);
BENCHMARK_MAIN();
