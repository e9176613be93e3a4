// zerog::telemetry: TelemetryChannel::offer() (what the cycle thread pays per cycle) against the
// reference of the same run: pushing the record into a plain SPSC ring of the same kind. Three
// cases: no DDS (channel not started), the publisher thread running and draining each record
// before the next offer (DDS writes on the other core, nobody subscribed), and a full ring (the
// drop path). Measured, never asserted.
#include <benchmark/benchmark.h>
#include <unistd.h>

#include "zerog/telemetry/channel.hpp"

namespace {

using zerog::telemetry::TelemetryChannel;

zerog::loop::CycleRecord record() {
  zerog::loop::CycleRecord r;
  r.cycle = 1;
  r.wrench_measured = {1, 2, 3, 4, 5, 6};
  return r;
}

zerog::telemetry::TelemetryConfig config() {
  zerog::telemetry::TelemetryConfig c;
  c.domain_id = 200 + static_cast<int>(::getpid() % 30);
  c.interface = "lo";
  c.allow_multicast = false;
  c.peers = {"127.0.0.1"};
  return c;
}

void BM_ReferenceRingPush(benchmark::State& state) {
  auto ring = std::make_unique<TelemetryChannel::Ring>();
  zerog::telemetry::RecordSlot slot, out;
  slot.record = record();
  for (auto _ : state) {
    ring->try_push(slot);
    ring->try_pop(out);  // keep it from filling (same thread: cache-hot, the optimistic case)
    benchmark::DoNotOptimize(out);
  }
}
BENCHMARK(BM_ReferenceRingPush);

void BM_OfferNoDds(benchmark::State& state) {
  TelemetryChannel channel(config(), {}, zerog::control::BodyParams{});
  const zerog::loop::CycleRecord r = record();
  for (auto _ : state) {
    benchmark::DoNotOptimize(channel.offer(r, 1));
  }
}
BENCHMARK(BM_OfferNoDds)->Iterations(1000);  // at most a ring's worth: no drops

void BM_OfferWithPublisher(benchmark::State& state) {
  TelemetryChannel channel(config(), {}, zerog::control::BodyParams{});
  if (!channel.start().ok()) {
    state.SkipWithError("DDS start failed");
    return;
  }
  const zerog::loop::CycleRecord r = record();
  std::uint64_t refused = 0, offered = 0;
  for (auto _ : state) {
    if (!channel.offer(r, 1)) ++refused;
    ++offered;
    // As in zerog-rt, the publisher has taken the last record before the next cycle comes
    // (not timed): each offer() finds the consumer's index on the other core.
    state.PauseTiming();
    while (channel.counters().records_published + refused < offered) {
    }
    state.ResumeTiming();
  }
  state.counters["dropped"] = static_cast<double>(refused);
  channel.stop();
}
BENCHMARK(BM_OfferWithPublisher)->Iterations(3000);

void BM_OfferRingFull(benchmark::State& state) {
  TelemetryChannel channel(config(), {}, zerog::control::BodyParams{});
  const zerog::loop::CycleRecord r = record();
  while (channel.offer(r)) {
  }
  for (auto _ : state) benchmark::DoNotOptimize(channel.offer(r));
}
BENCHMARK(BM_OfferRingFull);

}  // namespace

BENCHMARK_MAIN();
