#pragma once
// TelemetryChannel: zerog-rt's cycle → DDS (proto/telemetry.md). The cycle thread offer()s each
// CycleRecord into a lock-free SPSC ring and never waits; a publisher thread drains the ring,
// converts (convert.hpp) and writes the high-rate topics (best-effort, keep-last), Health on
// every change and every health period, and the model identity once (reliable, transient-local:
// late subscribers get the last Health and the identity). A full ring drops the record; drops
// and failed writes are counted and published in Health. With config.ros2 the same thread
// writes each record again as ROS 2 messages on `rt/` topics (ros2.hpp), and Health and the
// identity as a diagnostic_msgs/DiagnosticArray; the cycle's work is the same one offer().
//
//   TelemetryChannel channel(config, model_identity(model, file, crc), cycle_config.body);
//   channel.start();                      // start-up: creates the DDS domain and the thread
//   channel.offer(record, received_ns);   // cycle thread, every cycle: real-time safe
//   channel.set_health(counters);         // one thread (e.g. the cycle's): real-time safe
//   channel.stop();                       // drains, final Health, waits for acknowledgements
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>

#include "zerog/control/virtual_body.hpp"
#include "zerog/handover/latest_value.hpp"
#include "zerog/handover/spsc_ring.hpp"
#include "zerog/loop/cycle.hpp"
#include "zerog/telemetry/config.hpp"
#include "zerog/telemetry/convert.hpp"
#include "zerog/telemetry/ros2.hpp"

namespace zerog::telemetry {

/// A record as the ring holds it, with the cycle thread's receive time (CLOCK_MONOTONIC ns;
/// 0: unknown). Eigen members copy without throwing but do not say so (noexcept).
struct RecordSlot {
  loop::CycleRecord record;
  std::int64_t received_ns = 0;
  RecordSlot() noexcept {}
  RecordSlot(const RecordSlot&) = default;
  RecordSlot& operator=(const RecordSlot& other) noexcept {
    record = other.record;
    received_ns = other.received_ns;
    return *this;
  }
};

/// The virtual body's mass properties as plain values (handover::LatestValue needs trivially
/// copyable types).
struct BodyParamsValue {
  double mass_kg = 0.0;
  double inertia_body_kgm2[9] = {};  ///< row-major
};

class TelemetryChannel {
 public:
  /// 1024 records: 4 s at 4 ms, 12 s at 12 ms.
  using Ring = handover::SpscRing<RecordSlot, 1024>;

  /// `body`: the virtual body's mass properties (for ω and the kinetic energy); change them
  /// with set_body_params(). Nothing starts yet.
  TelemetryChannel(TelemetryConfig config, ModelIdentityInfo model, control::BodyParams body);
  ~TelemetryChannel();  ///< stop()
  TelemetryChannel(const TelemetryChannel&) = delete;
  TelemetryChannel& operator=(const TelemetryChannel&) = delete;

  /// Checks the configuration, creates the DDS domain (cyclone_xml), participant, topics and
  /// writers, publishes the model identity and starts the publisher thread. ok(), or
  /// check_config's invalid_setting, or system_error naming the DDS call that failed.
  /// Idempotent while started. Not real-time.
  Status start();
  /// Stops the publisher thread after it has drained the ring, writes a last Health, waits up
  /// to `ack_timeout_s` for reliable readers to acknowledge, deletes the DDS entities.
  /// Idempotent. Not real-time safe.
  void stop(double ack_timeout_s = 1.0);
  bool started() const { return started_; }

  /// Cycle thread (the only producer): hands the record to the publisher. Real-time safe:
  /// no allocation, no lock, no system call. False (and counted) when the ring is full.
  /// `received_ns`: when the cycle's datagram arrived (CLOCK_MONOTONIC), for the period and
  /// the jitter; 0: use the robot time t_s instead.
  bool offer(const loop::CycleRecord& record, std::int64_t received_ns = 0) noexcept;
  /// The runtime's counters (one writer thread). Real-time safe.
  void set_health(const RuntimeHealth& health) noexcept { runtime_health_.publish(health); }
  /// New virtual-body parameters (one writer thread, e.g. when tunables are accepted).
  /// Real-time safe.
  void set_body_params(const control::BodyParams& body) noexcept;

  /// Readers matched to the wrench topics now (zerog/wrench and, with ros2, the rt/ one; 0
  /// before start()). Not real-time safe.
  int subscribers() const;
  /// Counters so far (any thread; a snapshot).
  ChannelCounters counters() const;
  const TelemetryConfig& config() const { return config_; }
  /// Topic name of `suffix` ("wrench", "health", …) with the configured prefix.
  std::string topic_name(const char* suffix) const { return config_.topic_prefix + suffix; }

  /// Test hook: while paused the publisher thread takes nothing from the ring.
  void pause_publisher_for_test(bool paused) noexcept {
    paused_.store(paused, std::memory_order_relaxed);
  }

 private:
  struct Dds;
  void publisher_loop();
  bool drain_one();
  void publish_health(bool force);

  TelemetryConfig config_;
  ModelIdentityInfo model_;
  std::unique_ptr<Ring> ring_;
  handover::LatestValue<RuntimeHealth> runtime_health_;
  handover::LatestValue<BodyParamsValue> body_params_;
  std::unique_ptr<Dds> dds_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<bool> paused_{false};
  bool started_ = false;

  RecordSlot offer_slot_;  // cycle thread

  // Publisher thread (and stop(), after the thread has ended): the record in hand and the one
  // before it (for the received-time and t_s checks), the body's parameters, the health inputs,
  // and the ROS 2 messages (config_.ros2; made in start()).
  struct Publisher {
    RecordSlot slot;
    loop::CycleRecord newest;
    bool have_newest = false;
    std::int64_t previous_received_ns = 0;
    double previous_t_s = 0.0;
    std::uint64_t previous_cycle = 0;
    control::BodyParams body;
    RuntimeHealth health_in;
    std::unique_ptr<Ros2Frames> ros_frames;
    std::unique_ptr<Ros2CycleMessages> ros_messages;
    Ros2DiagnosticsStorage ros_diagnostics_storage;
  } pub_;
  // Publisher thread: what the last health message said, to publish on a change.
  struct LastHealth {
    std::uint64_t seq = 0;
    std::int64_t ns = 0;
    std::uint8_t state = 0xFF, fault = 0xFF;
    RuntimeHealth runtime;
    std::uint64_t drops = 0, write_errors = 0;
  } last_health_;
  // Written by the publisher thread, read by any (counters()).
  struct Published {
    std::atomic<std::uint64_t> records{0};
    std::atomic<std::uint64_t> write_errors{0};
    std::atomic<std::uint64_t> health{0};
  } published_;
};

}  // namespace zerog::telemetry
