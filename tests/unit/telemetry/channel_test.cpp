// TelemetryChannel with a real Cyclone DDS participant in this process: a scripted sequence of
// records goes through offer() → ring → publisher thread → DDS, and readers made with Cyclone's
// C API check the values, the QoS (best-effort streams refuse a reliable reader; a late reader
// still gets the transient-local model identity and the last health), the drop counting with
// the publisher stalled, and that offer() never allocates. Loopback, unicast, one domain id per
// test derived from the process id (no crosstalk between parallel test runs).
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "alloc_count.hpp"
#include "dds/dds.h"
#include "zerog/telemetry/channel.hpp"

namespace zerog::telemetry {
namespace {

int unique_domain(int test_index) {
  return 10 + static_cast<int>((static_cast<unsigned>(::getpid()) * 7u + test_index * 53u) % 90u);
}

TelemetryConfig loopback_config(int test_index) {
  TelemetryConfig c;
  c.domain_id = unique_domain(test_index);
  c.interface = "lo";
  c.allow_multicast = false;
  c.peers = {"127.0.0.1"};
  c.health_period_s = 0.1;
  c.nominal_period_s = 0.004;
  return c;
}

loop::CycleRecord scripted(std::uint64_t cycle) {
  loop::CycleRecord r;
  r.cycle = cycle;
  r.ipoc = 1000 + 4 * cycle;
  r.t_s = 0.004 * static_cast<double>(cycle - 1);
  r.dt_s = 0.004;
  r.state = cycle < 20 ? loop::State::idle : loop::State::zero_g;
  for (int i = 0; i < 6; ++i) {
    r.wrench_measured[i] = static_cast<double>(cycle) + 0.1 * i;
    r.predicted[i] = static_cast<double>(cycle) - 0.1 * i;
  }
  r.rate_imu = {0.001 * static_cast<double>(cycle), 0.0, 0.0};
  r.joints_rad[0] = 0.01 * static_cast<double>(cycle);
  r.body.v_world_mps = {0.01, 0.0, 0.0};
  r.body.L_world_kgm2ps = {0.0, 0.0, 0.1};
  r.reply.kind = samples::RobotCorrection::Kind::cartesian;
  r.reply.translation_m[0] = 0.04e-3;
  r.compute_ns = 1000 * static_cast<std::int64_t>(cycle);
  return r;
}

ModelIdentityInfo test_identity() {
  infer::DeployedModel m;
  m.rig.name = "test-rig";
  m.rig.robot = "KR 210 R2700";
  m.physics.effects = model::kDefaultModel;
  return model_identity(m, "test.zgm", 0xCAFEF00Du);
}

template <typename Pred>
bool wait_for(Pred pred, double timeout_s = 10.0) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < end) {
    if (pred()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return pred();
}

/// A reader of one topic in its own participant (same domain as the channel's).
class Reader {
 public:
  Reader(int domain, const dds_topic_descriptor_t* desc, const std::string& name, bool reliable,
         bool transient_local) {
    participant_ = dds_create_participant(static_cast<dds_domainid_t>(domain), nullptr, nullptr);
    EXPECT_GT(participant_, 0);
    dds_qos_t* q = dds_create_qos();
    dds_qset_reliability(q, reliable ? DDS_RELIABILITY_RELIABLE : DDS_RELIABILITY_BEST_EFFORT,
                         DDS_SECS(1));
    dds_qset_durability(q,
                        transient_local ? DDS_DURABILITY_TRANSIENT_LOCAL : DDS_DURABILITY_VOLATILE);
    dds_qset_history(q, DDS_HISTORY_KEEP_LAST, 4096);
    const dds_entity_t topic = dds_create_topic(participant_, desc, name.c_str(), q, nullptr);
    EXPECT_GT(topic, 0);
    reader_ = dds_create_reader(participant_, topic, q, nullptr);
    EXPECT_GT(reader_, 0);
    dds_delete_qos(q);
  }
  ~Reader() { dds_delete(participant_); }
  int matched() const {
    dds_subscription_matched_status_t s{};
    dds_get_subscription_matched_status(reader_, &s);
    return static_cast<int>(s.current_count);
  }
  /// Takes every valid sample (fixed-size types only) and appends them to `out`.
  template <typename T>
  void take(std::vector<T>& out) {
    void* samples[64] = {};
    dds_sample_info_t infos[64];
    for (;;) {
      const dds_return_t n = dds_take(reader_, samples, infos, 64, 64);
      if (n <= 0) break;
      for (int i = 0; i < n; ++i)
        if (infos[i].valid_data) out.push_back(*static_cast<const T*>(samples[i]));
      dds_return_loan(reader_, samples, n);
    }
  }
  dds_entity_t reader() const { return reader_; }

 private:
  dds_entity_t participant_ = 0;
  dds_entity_t reader_ = 0;
};

TEST(TelemetryChannel, PublishesEveryTopicWithTheRecordsValues) {
  const TelemetryConfig config = loopback_config(1);
  control::BodyParams body;
  body.mass_kg = 50.0;
  TelemetryChannel channel(config, test_identity(), body);
  ASSERT_EQ(channel.start().text(), "");
  EXPECT_EQ(channel.start().text(), "");  // idempotent
  Reader wrench(config.domain_id, &zerog_telemetry_WrenchSample_desc, "zerog/wrench", false, false);
  Reader imu(config.domain_id, &zerog_telemetry_ImuSample_desc, "zerog/imu", false, false);
  Reader robot(config.domain_id, &zerog_telemetry_RobotSample_desc, "zerog/robot", false, false);
  Reader command(config.domain_id, &zerog_telemetry_CommandSample_desc, "zerog/command", false,
                 false);
  Reader body_reader(config.domain_id, &zerog_telemetry_BodySample_desc, "zerog/body", false,
                     false);
  Reader timing(config.domain_id, &zerog_telemetry_TimingSample_desc, "zerog/timing", false, false);
  // QoS: a reliable reader cannot match a best-effort stream.
  Reader reliable_wrench(config.domain_id, &zerog_telemetry_WrenchSample_desc, "zerog/wrench", true,
                         false);
  ASSERT_TRUE(wait_for([&] { return channel.subscribers() >= 1 && timing.matched() == 1; }));

  RuntimeHealth h;
  h.datagrams_lost = 3;
  channel.set_health(h);
  constexpr int kRecords = 60;
  for (int i = 1; i <= kRecords; ++i)
    ASSERT_TRUE(channel.offer(scripted(static_cast<std::uint64_t>(i)),
                              1'000'000'000 + static_cast<std::int64_t>(i) * 4'100'000));
  std::vector<WrenchSample> w;
  std::vector<ImuSample> im;
  std::vector<RobotSample> ro;
  std::vector<CommandSample> co;
  std::vector<BodySample> bo;
  std::vector<TimingSample> ti;
  ASSERT_TRUE(wait_for([&] {
    wrench.take(w);
    imu.take(im);
    robot.take(ro);
    command.take(co);
    body_reader.take(bo);
    timing.take(ti);
    return w.size() == kRecords && im.size() == kRecords && ro.size() == kRecords &&
           co.size() == kRecords && bo.size() == kRecords && ti.size() == kRecords;
  })) << w.size()
      << " " << im.size() << " " << ro.size() << " " << co.size() << " " << bo.size() << " "
      << ti.size();
  for (int i = 0; i < kRecords; ++i) {
    const loop::CycleRecord r = scripted(static_cast<std::uint64_t>(i + 1));
    ASSERT_EQ(w[i].cycle, r.cycle);
    EXPECT_EQ(w[i].measured[3], r.wrench_measured[3]);
    EXPECT_EQ(w[i].predicted[5], r.predicted[5]);
    EXPECT_EQ(im[i].rate_imu_radps[0], r.rate_imu[0]);
    EXPECT_EQ(ro[i].joints_rad[0], r.joints_rad[0]);
    EXPECT_EQ(ro[i].ipoc, r.ipoc);
    EXPECT_NEAR(co[i].rkorr_translation_m[0], 0.04e-3, 1e-18);
    EXPECT_EQ(bo[i].mass_kg, 50.0);
    EXPECT_NEAR(bo[i].momentum_world_kgmps[0], 0.5, 1e-12);
    EXPECT_EQ(ti[i].compute_s, static_cast<double>(r.compute_ns) * 1e-9);
    EXPECT_EQ(ti[i].datagrams_lost, 3u);
    if (i == 0) {
      EXPECT_EQ(ti[i].period_s, 0.0);
    } else {
      EXPECT_NEAR(ti[i].period_s, 0.0041, 1e-12);  // from the receive times given to offer()
      EXPECT_NEAR(ti[i].jitter_s, 0.0001, 1e-12);
    }
  }
  std::vector<WrenchSample> none;
  reliable_wrench.take(none);
  EXPECT_EQ(reliable_wrench.matched(), 0);
  EXPECT_TRUE(none.empty());

  // New body parameters reach the next samples.
  body.mass_kg = 70.0;
  channel.set_body_params(body);
  ASSERT_TRUE(channel.offer(scripted(kRecords + 1)));
  ASSERT_TRUE(wait_for([&] {
    body_reader.take(bo);
    return bo.size() == kRecords + 1;
  }));
  EXPECT_EQ(bo.back().mass_kg, 70.0);

  const ChannelCounters c = channel.counters();
  EXPECT_EQ(c.records_offered, kRecords + 1u);
  EXPECT_EQ(c.records_published, kRecords + 1u);
  EXPECT_EQ(c.telemetry_drops, 0u);
  EXPECT_EQ(c.write_errors, 0u);
}

TEST(TelemetryChannel, LateReaderGetsModelIdentityAndLastHealth) {
  const TelemetryConfig config = loopback_config(2);
  TelemetryChannel channel(config, test_identity(), control::BodyParams{});
  ASSERT_EQ(channel.start().text(), "");
  for (int i = 1; i <= 30; ++i) ASSERT_TRUE(channel.offer(scripted(static_cast<std::uint64_t>(i))));
  ASSERT_TRUE(wait_for([&] { return channel.counters().records_published == 30; }));
  // Health follows the state change (idle → zero_g at cycle 20) and the period.
  ASSERT_TRUE(wait_for([&] { return channel.counters().health_published >= 3; }));

  // Readers made only now (transient-local, reliable).
  Reader health(config.domain_id, &zerog_telemetry_Health_desc, "zerog/health", true, true);
  Reader model(config.domain_id, &zerog_telemetry_ModelIdentity_desc, "zerog/model", true, true);
  std::vector<HealthSample> hs;
  ASSERT_TRUE(wait_for([&] {
    health.take(hs);
    return !hs.empty() && hs.back().cycle == 30;
  }));
  EXPECT_EQ(hs.back().state, static_cast<std::uint8_t>(loop::State::zero_g));
  EXPECT_EQ(hs.back().records_offered, 30u);
  EXPECT_EQ(hs.back().records_published, 30u);

  bool got_model = false;
  ASSERT_TRUE(wait_for([&] {
    void* samples[1] = {nullptr};
    dds_sample_info_t info;
    if (dds_take(model.reader(), samples, &info, 1, 1) == 1) {
      if (info.valid_data) {
        const auto* m = static_cast<const zerog_telemetry_ModelIdentity*>(samples[0]);
        EXPECT_STREQ(m->rig_name, "test-rig");
        EXPECT_EQ(m->deploy_crc32, 0xCAFEF00Du);
        EXPECT_STREQ(m->deploy_file, "test.zgm");
        EXPECT_EQ(m->effects._length, 4u);
        if (m->effects._length > 0) {
          EXPECT_STREQ(m->effects._buffer[0], "bias");
        }
        EXPECT_FALSE(m->has_network);
        got_model = true;
      }
      dds_return_loan(model.reader(), samples, 1);
    }
    return got_model;
  }));
  channel.stop();
  channel.stop();  // idempotent
  EXPECT_FALSE(channel.started());
}

TEST(TelemetryChannel, CountsDropsWhenThePublisherStallsAndDrainsOnStop) {
  const TelemetryConfig config = loopback_config(3);
  TelemetryChannel channel(config, test_identity(), control::BodyParams{});
  ASSERT_EQ(channel.start().text(), "");
  Reader health(config.domain_id, &zerog_telemetry_Health_desc, "zerog/health", true, true);
  channel.pause_publisher_for_test(true);
  constexpr std::size_t kCapacity = TelemetryChannel::Ring::capacity();
  std::size_t refused = 0;
  for (std::size_t i = 1; i <= kCapacity + 25; ++i)
    if (!channel.offer(scripted(i))) ++refused;
  EXPECT_EQ(refused, 25u);
  ChannelCounters c = channel.counters();
  EXPECT_EQ(c.telemetry_drops, 25u);
  EXPECT_EQ(c.records_offered, kCapacity + 25);
  EXPECT_EQ(c.records_published, 0u);
  // Health says so even while the queue is stalled.
  std::vector<HealthSample> hs;
  ASSERT_TRUE(wait_for([&] {
    health.take(hs);
    return !hs.empty() && hs.back().telemetry_drops == 25;
  }));
  channel.pause_publisher_for_test(false);
  ASSERT_TRUE(wait_for([&] { return channel.counters().records_published == kCapacity; }));
  // The ring has room again.
  channel.pause_publisher_for_test(true);
  for (std::size_t i = 0; i < 10; ++i) ASSERT_TRUE(channel.offer(scripted(kCapacity + 26 + i)));
  channel.stop();  // drains what is queued, even paused
  c = channel.counters();
  EXPECT_EQ(c.records_published, kCapacity + 10);
  EXPECT_EQ(c.records_published + c.telemetry_drops, c.records_offered);
}

TEST(TelemetryChannel, OfferDoesNotAllocate) {
  const TelemetryConfig config = loopback_config(4);
  TelemetryChannel channel(config, test_identity(), control::BodyParams{});
  const loop::CycleRecord r = scripted(1);
  // Before start (nothing but the ring) and with DDS running, the publisher paused. The count
  // is the calling (cycle) thread's own: DDS threads do not add to it.
  std::size_t before = zerog::test::allocation_count();
  for (int i = 0; i < 100; ++i) channel.offer(r, i);
  RuntimeHealth h;
  channel.set_health(h);
  channel.set_body_params(control::BodyParams{});
  EXPECT_EQ(zerog::test::allocation_count() - before, 0u);

  ASSERT_EQ(channel.start().text(), "");
  channel.pause_publisher_for_test(true);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  before = zerog::test::allocation_count();
  for (int i = 0; i < 2000; ++i) channel.offer(r, i);  // overflows: the drop path too
  for (int i = 0; i < 100; ++i) {
    h.robot_lost = static_cast<std::uint64_t>(i);
    channel.set_health(h);
  }
  EXPECT_EQ(zerog::test::allocation_count() - before, 0u);
  EXPECT_GT(channel.counters().telemetry_drops, 0u);
  channel.stop();
}

TEST(TelemetryChannel, StartRefusesABadConfigurationNamingTheSetting) {
  TelemetryConfig config = loopback_config(5);
  config.peers.clear();
  TelemetryChannel channel(config, test_identity(), control::BodyParams{});
  const Status st = channel.start();
  EXPECT_EQ(st.code(), StatusCode::invalid_setting) << st.text();
  EXPECT_EQ(st.setting(), "peers") << st.text();
  EXPECT_NE(st.message().find("unicast peer"), std::string::npos) << st.text();
  EXPECT_FALSE(channel.started());
}

}  // namespace
}  // namespace zerog::telemetry
