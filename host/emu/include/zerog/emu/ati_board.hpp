#pragma once
// An emulated ATI NETCANOEM board (ATI manual 9610-05-1030, proto/netcanoem.md): answers the
// requests of rtio::NetcanoemSensor on a CAN bus with the codec's response encoders
// (zerog::proto::netcanoem). Its gauges come from a wrench set by a physics simulation, through
// the exact inverse of the sensor-side formula, so the sensor reports that wrench to within the
// gauge quantisation. Faults (silent, critical status, saturation, bus-error bit), a slow answer
// and the protocol quirks tests need (ignored requests, wrong echo, frames before a sample) can
// be switched on while it serves.
//
// Emulator code for tests and zerog-emu, not real-time code: every public member is thread-safe
// (one mutex), the constructor and set_wrench may throw.
#include <array>
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <mutex>
#include <random>

#include <Eigen/Core>

#include "zerog/proto/can_frame.hpp"
#include "zerog/proto/netcanoem.hpp"
#include "zerog/rtio/can_bus.hpp"
#include "zerog/rtio/fake_can_bus.hpp"

namespace zerog::emu {

/// What the board knows: the answers to the start-up read-out and its unloaded gauges.
struct AtiBoardConfig {
  std::uint8_t base_id = 0x20;  ///< 0–127
  proto::netcanoem::FirmwareVersion firmware{3, 8, 1201};
  std::array<char, proto::netcanoem::kSerialNumberLength> serial{'F', 'T', '4', '2',
                                                                 '0', '0', '7', 'A'};
  /// Calibration matrix C: rows Fx, Fy, Fz, Tx, Ty, Tz; columns SG0..SG5. Sent as float32 (the
  /// board uses what it sends). The default is well conditioned and exact in float32 (multiples
  /// of 1/4 below 2^20). With the default counts one gauge count is about 3 mN / 25 µN·m and
  /// the reachable range small (|Fz| of a few hundred N): for a heavy payload raise the counts'
  /// range with smaller counts_per_force / counts_per_torque (see AtiBoard::full_scale_si()).
  std::array<std::array<double, 6>, 6> matrix{{
      {1520.25, -12.5, 33.75, -1498.0, 8.25, 1.5},
      {-20.0, 1730.5, -5.25, 14.0, -1744.75, 6.0},
      {3002.5, 2998.75, 3010.0, 2990.25, 3005.5, 2995.0},
      {0.75, -8.5, 25.25, 2.0, -24.5, 5.75},
      {-28.0, 1.25, 13.5, -23.75, 14.25, 22.0},
      {-4.5, 18.0, -3.25, 19.5, -2.75, 17.25},
  }};
  /// Counts per force / torque unit (opcode 0x7). Firmware before 3.7 does not answer 0x7; the
  /// board then behaves as the sensor assumes (proto::netcanoem::kDefaultCounts each).
  std::uint32_t counts_per_force = 1'000'000;
  std::uint32_t counts_per_torque = 1'000'000;
  std::uint8_t force_unit = 2;   ///< proto::netcanoem::ForceUnit code (2: N)
  std::uint8_t torque_unit = 3;  ///< proto::netcanoem::TorqueUnit code (3: N·m)
  /// Gauges of the unloaded sensor (raw counts): the sensor's NetcanoemConfig::bias_gauges.
  std::array<std::int16_t, 6> gauge_bias{};
  /// White noise added to each gauge of each sample sent, standard deviation in counts (before
  /// rounding to int16); 0: none. Seeded by `seed`, so runs repeat.
  double gauge_noise_counts = 0.0;
  std::uint64_t seed = 1;
  /// The thermistor channel (opcode 0x9, diagnostic index 2) answers the temperature
  /// (set_temperature) through the inverse of this conversion (proto::netcanoem::
  /// thermistor_counts), so a sensor configured with the same numbers reads it back to within
  /// one count. UNVERIFIED: the emulator's own choice (−50 °C at 0 counts, 5 mK per count), not a
  /// datasheet fact about the board.
  proto::netcanoem::ThermistorConversion thermistor{-50.0, 0.005};
  double temperature_C = 25.0;  ///< the sensor temperature until set_temperature
};

enum class FtFault : std::uint8_t {
  none,
  silent,         ///< no answers at all (start-up requests included)
  critical,       ///< status word with a critical bit (bit 1) and bit 15
  saturated,      ///< gauge SG0 at 32767
  bus_error_bit,  ///< status bits 14 + 15: a warning, the data stay valid
};
const char* ft_fault_name(FtFault fault);

/// Misbehaviour for protocol tests (what the old test-only BoardState offered).
struct AtiBoardQuirks {
  int ignore_requests = 0;          ///< ignore this many requests first (counts down)
  bool wrong_echo = false;          ///< echo another calibration index than requested
  bool no_sample_response = false;  ///< answer a sample request with before_sample only
  /// Leave diagnostic reads (opcode 0x9, the thermistor among them) unanswered; samples go on.
  bool no_diagnostic_response = false;
  /// Sent before each sample response (strays, wrong lengths, error frames, …).
  std::array<proto::CanFrame, 4> before_sample{};
  std::size_t before_sample_count = 0;  ///< 0–4
};

class AtiBoard {
 public:
  static constexpr std::size_t kMaxResponseFrames = 8;
  using Response = std::array<proto::CanFrame, kMaxResponseFrames>;

  /// Throws std::invalid_argument (naming the field) for a base id above 127, counts of 0 (from
  /// firmware 3.7 on), a non-finite or singular matrix, or a negative noise σ. Unknown unit codes
  /// are accepted (the sensor must refuse them), but then set_wrench throws.
  explicit AtiBoard(const AtiBoardConfig& config = {});
  AtiBoard(const AtiBoard&) = delete;
  AtiBoard& operator=(const AtiBoard&) = delete;

  const AtiBoardConfig& config() const { return config_; }
  /// The calibration as a sensor reads it: float32 matrix, the counts the sensor will use.
  const proto::netcanoem::Calibration& calibration() const { return calibration_; }
  /// Wrench (N, N·m) that one count on each gauge, in the worst sign combination, changes:
  /// Σ_j |A_ij| with A the sensor-side gauge → SI wrench matrix. Zero for unknown unit codes.
  std::array<double, 6> count_resolution_si() const;
  /// The largest |wrench component| (N, N·m) reachable on each axis alone, either sign, before
  /// a gauge reaches a rail: min_j (32766 − |bias_j|) / |G_ji| (G = A⁻¹). Zero for unknown unit
  /// codes.
  std::array<double, 6> full_scale_si() const;

  /// The wrench the sensor should report (sensor frame S; Fx, Fy, Fz in N, Tx, Ty, Tz in N·m
  /// about the sensor origin). Gauges = bias + G · wrench, G = A⁻¹ (A as above, so the
  /// sensor-side formula reproduces it to quantisation); rounded and clamped to [−32768, 32767]
  /// when sent (a clamped value is a saturated gauge, as on the real sensor). Throws
  /// std::logic_error when the unit codes are unknown.
  void set_wrench(const std::array<double, 6>& wrench_sensor_si);
  /// Lockstep (proto/lockstep.md): queues the wrench of one sample produced in emulated time.
  /// From the first call on, each sample request takes the next queued sample (a silent board
  /// takes it too: its time passed); an empty queue answers with the last one (counted).
  void queue_sample(const std::array<double, 6>& wrench_sensor_si);
  /// Samples queued and not yet requested.
  std::size_t samples_queued() const;
  /// Whether a sample request now gets its answer within `timeout` (not silent, no ignored
  /// requests, a response delay below it): what lockstep tells zerog-rt.
  bool answers_within(std::chrono::nanoseconds timeout) const;
  /// Sets the gauges directly (raw counts; replaced by the next set_wrench).
  void set_gauges(const std::array<std::int16_t, 6>& gauges);
  /// The gauges the next sample carries, before noise and faults.
  std::array<std::int16_t, 6> gauges() const;
  /// The sensor temperature the thermistor channel answers from now on, °C. Throws
  /// std::invalid_argument when it is not finite or maps outside 0–65535 counts.
  void set_temperature(double temperature_C);
  /// The thermistor channel's raw counts now.
  std::uint16_t thermistor_counts() const;
  /// Raw status word of the samples, OR-ed with the fault's bits (default 0).
  void set_status_word(std::uint16_t status);
  void set_fault(FtFault fault);
  FtFault fault() const;
  /// "Slow sensor": serve() sends each sample response this long after the request came in
  /// (respond() itself never waits). Negative values count as 0.
  void set_response_delay(std::chrono::microseconds delay);
  /// Throws std::invalid_argument for a before_sample_count above 4.
  void set_quirks(const AtiBoardQuirks& quirks);
  /// The quirks now (ignore_requests counts down as requests are ignored).
  AtiBoardQuirks quirks() const;

  /// The pure protocol step: the frames the board sends for `request` (0 for frames that are not
  /// its requests: other ids, its own responses, remote/error/extended frames, a silent board).
  /// Does not allocate.
  std::size_t respond(const proto::CanFrame& request, Response& out);

  /// Serves requests on `bus` (rtio::CanSocket on vcan, or any CanBus) until `stop` becomes
  /// true: reads with a 5 ms timeout, answers each request (sample responses after the response
  /// delay), counts failed writes. Blocks; run it in its own thread.
  void serve(rtio::CanBus& bus, const std::atomic<bool>& stop);

  struct Counters {
    std::uint64_t requests = 0;         ///< well-formed requests to this board
    std::uint64_t sample_requests = 0;  ///< … of them sample requests (opcode 0x0, no data)
    /// Sample response pairs made (by serve(): a pair still waiting out its delay at stop is
    /// counted but not sent).
    std::uint64_t samples_sent = 0;
    std::uint64_t ignored = 0;  ///< requests not answered (silent, ignore_requests, no answer)
    /// … of them sample requests (what a sensor's timeouts must match; thermistor reads not)
    std::uint64_t sample_requests_ignored = 0;
    std::uint64_t saturated_samples = 0;  ///< samples sent with a gauge at a rail
    std::uint64_t critical_samples = 0;   ///< samples sent with a critical status bit
    std::uint64_t other_frames = 0;       ///< frames that were not requests to this board
    std::uint64_t tx_failed = 0;          ///< serve(): responses the bus refused
    std::uint64_t queued = 0;             ///< lockstep: samples queued
    std::uint64_t queue_underruns = 0;    ///< lockstep: sample requests with an empty queue
    std::uint64_t diagnostic_reads = 0;   ///< 0x9 requests answered (any channel)
    std::uint64_t thermistor_reads = 0;   ///< … of them the thermistor (index 2)
  };
  Counters counters() const;

 private:
  struct Step {
    std::size_t frames = 0;
    bool sample = false;  // a sample response (delayed by serve())
  };
  Step respond_locked(const proto::CanFrame& request, Response& out);
  std::array<double, 6> gauges_of(const std::array<double, 6>& wrench_sensor_si) const;

  AtiBoardConfig config_;
  proto::netcanoem::Calibration calibration_{};
  bool si_known_ = false;                // unit codes known: forward_/inverse_ valid
  Eigen::Matrix<double, 6, 6> forward_;  // A: gauge counts → SI wrench
  Eigen::Matrix<double, 6, 6> inverse_;  // G = A⁻¹

  mutable std::mutex mutex_;
  std::array<double, 6> gauges_exact_{};     // bias + G · wrench, before rounding
  std::uint16_t thermistor_counts_ = 0;      // the thermistor channel's reading
  bool lockstep_ = false;                    // queue_sample() was called
  std::deque<std::array<double, 6>> queue_;  // lockstep: gauges of the samples to come
  std::uint16_t status_word_ = 0;
  FtFault fault_ = FtFault::none;
  std::chrono::microseconds delay_{0};
  AtiBoardQuirks quirks_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  Counters counters_;
};

/// Connects an AtiBoard to a single-threaded rtio::FakeCanBus: every frame written to the bus is
/// handed to AtiBoard::respond and the answers are queued for read(). FakeCanBus has no clock,
/// so the i-th frame of an answer arrives at `arrived_ns + i`; the response delay
/// does not apply. For unit tests.
class AtiBoardResponder final : public rtio::CanResponder {
 public:
  explicit AtiBoardResponder(AtiBoard& board, std::int64_t arrived_ns = 0)
      : board_(board), arrived_ns_(arrived_ns) {}
  void on_write(const proto::CanFrame& frame, rtio::FakeCanBus& bus) override;
  AtiBoard& board() { return board_; }

 private:
  AtiBoard& board_;
  std::int64_t arrived_ns_;
};

}  // namespace zerog::emu
