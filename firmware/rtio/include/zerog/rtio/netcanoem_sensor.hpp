#pragma once
// ATI F/T sensor on a NETCANOEM board (proto/netcanoem.md) behind the FtSensor interface. Uses
// the codec of zerog::proto::netcanoem: CalibrationReadout at start-up, SampleAssembler and
// gauges_to_wrench_si per sample. The bus is not owned: main opens a CanSocket with
// socket_config() and passes it; tests pass a FakeCanBus.
#include <array>
#include <chrono>
#include <cstdint>
#include <optional>

#include "zerog/proto/netcanoem.hpp"
#include "zerog/rtio/can_bus.hpp"
#include "zerog/rtio/can_socket.hpp"
#include "zerog/rtio/ft_sensor.hpp"

namespace zerog::rtio {

struct NetcanoemConfig {
  std::uint8_t base_id = 0x20;         ///< board base id (0–127); to check on the hardware
  std::uint8_t calibration_index = 0;  ///< active calibration to select (0–15)
  /// From sending a sample request to both response frames (the board answers in well under
  /// 1 ms at 1 Mbit/s).
  std::chrono::nanoseconds sample_timeout = std::chrono::milliseconds(2);
  /// Per start-up request, and how often each is tried before start() gives up.
  std::chrono::nanoseconds startup_timeout = std::chrono::milliseconds(50);
  int startup_attempts = 3;
  /// Gauge readings of the unloaded sensor (raw counts), subtracted before the matrix.
  std::array<double, proto::netcanoem::kGaugeCount> bias_gauges{};
  /// At most this many frames already queued are drained (and counted stale) per request.
  int max_stale_frames = 64;
  /// Read the thermistor (opcode 0x9, diagnostic index 2) with the first sample request after
  /// start() and then every this many (500: about 1 Hz at 500 Hz); 0: never. Its request goes out
  /// right after that poll's sample request, so the gauge answer is not delayed.
  int thermistor_every_polls = 500;
  /// Thermistor counts → °C. Empty: the readings stay raw counts (FtSample::thermistor_counts)
  /// and no temperature is reported. UNVERIFIED: there is no datasheet conversion to default to.
  std::optional<proto::netcanoem::ThermistorConversion> thermistor;
  /// With a conversion and reads on: a reading older than this many sample requests (or none
  /// this many requests after start()) is stale (FtSample::temperature_stale, temperature_valid
  /// false; counted thermistor_expired), until the next reading. Must exceed
  /// thermistor_every_polls (1500: three reads at the default).
  int thermistor_max_age_polls = 1500;
};

class NetcanoemSensor final : public FtSensor {
 public:
  /// `bus` must outlive the sensor. Nothing is sent until start().
  NetcanoemSensor(CanBus& bus, const NetcanoemConfig& config);

  /// Socket settings for this board: a kernel filter for its 16 ids, all error classes, a
  /// receive buffer for `buffer_frames` frames.
  static CanSocketConfig socket_config(std::uint8_t base_id, int buffer_frames = 256);

  /// Selects the active calibration (checks the echo), reads firmware version, serial number,
  /// the matrix, counts per unit (default 1 000 000 before firmware 3.7) and units. Each
  /// request is retried on timeout (startup_attempts). Not real-time safe (but does not
  /// allocate either).
  FtStartStatus start() override;
  /// Feeds frames already queued to the assembler (a late answer to an earlier request
  /// completes its own first half there and is dropped, counted late_samples), sends one sample
  /// request and waits for both response frames of this request; the gauges become a wrench in
  /// N and N·m. First halves pair with second halves in order (SampleAssembler), so a 0x1 still
  /// on its way from a timed-out request never completes this request's 0x0. Error frames,
  /// stray and wrong-length frames are counted and waited past. Real-time safe; returns within
  /// sample_timeout.
  FtReadStatus read_sample(FtSample& out) override;
  FtReadStatus read_sample_waiting(FtSample& out, std::chrono::nanoseconds at_least) override;
  FtCounters counters() const override;

  /// Valid after a successful start().
  const proto::netcanoem::Calibration& calibration() const { return calibration_; }
  /// Why the last start() failed with readout_failed.
  proto::netcanoem::ReadoutError readout_error() const { return readout_error_; }
  /// Start-up requests that timed out and were retried (all start() calls).
  std::uint64_t startup_retries() const { return startup_retries_; }
  /// Frames the last readout ignored (other ids, sample stream, …).
  std::uint32_t startup_ignored_frames() const { return startup_ignored_; }
  bool started() const { return started_; }
  const NetcanoemConfig& config() const { return config_; }

 private:
  void drain_stale();
  // Feeds one received frame; true when it completed a sample of the current poll (in `out`).
  // A 0x9 frame goes to take_diagnostic, never to the gauge assembler.
  bool feed(const CanRxFrame& rx, proto::netcanoem::GaugeSample& out);
  // A 0x9 frame of this board: our looped-back request, or the thermistor's answer.
  void take_diagnostic(const CanRxFrame& rx);
  // After poll_'s sample request: sends the thermistor read when one is due.
  void request_thermistor();
  void fill_temperature(FtSample& out) const;
  // After poll_'s sample request: the reading (or start()) older than the maximum age is stale.
  void check_thermistor_age();

  CanBus& bus_;
  NetcanoemConfig config_;
  proto::netcanoem::SampleAssembler assembler_;
  proto::netcanoem::Calibration calibration_{};
  proto::CanFrame request_{};
  proto::netcanoem::ReadoutError readout_error_ = proto::netcanoem::ReadoutError::none;
  bool started_ = false;
  std::uint64_t sequence_ = 0;
  std::uint64_t poll_ = 0;     // requests sent since start(); tags this poll's 0x0 halves
  bool in_poll_ = false;       // a request of poll_ is out and its answer awaited
  bool late_pairing_ = false;  // this poll completed a sample of an earlier one
  std::uint64_t late_samples_ = 0;
  std::uint64_t startup_retries_ = 0;
  std::uint32_t startup_ignored_ = 0;
  FtCounters own_;  // requests, samples, timeouts, stale frames, tx/io failures, thermistor
  proto::CanFrame thermistor_request_{};
  int polls_to_thermistor_ = 0;   // sample polls until the next thermistor read
  bool thermistor_open_ = false;  // a thermistor read is out and its answer awaited
  bool have_thermistor_ = false;  // a reading came since start()
  std::uint16_t thermistor_counts_ = 0;
  std::int64_t thermistor_rx_ns_ = 0;  // receive time of that reading
  std::uint64_t thermistor_poll_ = 0;  // poll_ when that reading (or start()) came
  bool thermistor_stale_ = false;      // older than thermistor_max_age_polls
};

}  // namespace zerog::rtio
