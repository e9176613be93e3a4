#pragma once
// A force/torque sensor as the loop sees it. Real: NetcanoemSensor (ATI NETCANOEM over CAN);
// fake: FakeFtSensor (scripted results; zerog/rtio/fake_ft_sensor.hpp in zerog::rtio_fakes, which
// only tests and the emulators link).
#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>

#include "zerog/samples/sensor_samples.hpp"

namespace zerog::rtio {

// The sample types are the loop's too (zerog/samples/sensor_samples.hpp, no I/O): the same
// names here.
using samples::FtSample;
using samples::FtSampleStatus;
const char* ft_sample_status_name(FtSampleStatus status);

enum class FtStartStatus : std::uint8_t {
  ok,
  bad_config,      ///< e.g. base id or calibration index out of range
  no_response,     ///< a start-up request got no answer after all retries (silent sensor)
  readout_failed,  ///< the calibration readout failed (echo mismatch, wrong length, …)
  unknown_units,   ///< the calibration's force or torque unit code is unknown
  io_error,        ///< the bus failed
};
const char* ft_start_status_name(FtStartStatus status);

enum class FtReadStatus : std::uint8_t {
  sample,       ///< `out` holds a new sample; check out.valid before using it
  timeout,      ///< no complete response in time (counted)
  not_started,  ///< start() has not succeeded
  tx_failed,    ///< the request could not be sent (TX queue full; counted)
  io_error,     ///< the bus failed (counted)
};
const char* ft_read_status_name(FtReadStatus status);

/// Everything a device counts. All counts since start-up (bus counters since the bus opened).
struct FtCounters {
  std::uint64_t requests = 0;            ///< sample requests sent
  std::uint64_t samples = 0;             ///< samples returned (any status)
  std::uint64_t samples_warning = 0;     ///< … with non-critical status bits
  std::uint64_t samples_critical = 0;    ///< … with a critical status bit (invalid)
  std::uint64_t samples_saturated = 0;   ///< … with a saturated gauge (invalid)
  std::uint64_t timeouts = 0;            ///< requests without a complete response in time
  std::uint64_t stale_frames = 0;        ///< frames already queued when a request went out
  std::uint64_t stray_frames = 0;        ///< other frames of the board's id range
  std::uint64_t wrong_length = 0;        ///< sample frames of the wrong length
  std::uint64_t out_of_order = 0;        ///< second half without a first half
  std::uint64_t dropped_incomplete = 0;  ///< first halves dropped before their second half came
  /// Complete samples that answer an earlier, timed-out request (their 0x1 was still on its
  /// way when the next request went out): paired correctly, then dropped as too old.
  std::uint64_t late_samples = 0;
  std::uint64_t overtaken = 0;  ///< samples whose second half was overtaken by a later first half
  std::uint64_t error_frames = 0;    ///< bus error frames seen (classes: on the bus)
  std::uint64_t kernel_drops = 0;    ///< frames the kernel dropped (SO_RXQ_OVFL)
  std::uint64_t bad_length = 0;      ///< reads that were not one classic CAN frame
  std::uint64_t tx_would_block = 0;  ///< requests refused by a full TX queue
  std::uint64_t io_errors = 0;       ///< failed bus reads/writes
  // The sensor's temperature channel (NETCANOEM: thermistor, opcode 0x9), read between samples.
  std::uint64_t thermistor_requests = 0;  ///< thermistor reads sent
  std::uint64_t thermistor_readings = 0;  ///< answers taken
  /// Reads unanswered when the next one was due (a late answer then counts as unrequested).
  std::uint64_t thermistor_lost = 0;
  /// Times the temperature went stale (FtSample::temperature_stale): the latest reading (or
  /// start-up, if none came) got older than the maximum age. Once per stale spell.
  std::uint64_t thermistor_expired = 0;
  std::uint64_t thermistor_wrong_length = 0;  ///< 0x9 frames neither request nor response
  std::uint64_t thermistor_unrequested = 0;   ///< 0x9 answers with no read of ours open
};

class FtSensor {
 public:
  virtual ~FtSensor() = default;
  /// Start-up: reads the device's calibration etc. Blocks (bounded by timeouts × retries); not
  /// real-time safe. May be called again to recover.
  virtual FtStartStatus start() = 0;
  /// Gets one sample. Real-time safe: no allocation, no exceptions, no locks; returns within the
  /// device's configured sample timeout.
  virtual FtReadStatus read_sample(FtSample& out) = 0;
  /// As read_sample, but waits for the answer up to `at_least` when that is longer than the
  /// device's own timeout: in lockstep (proto/lockstep.md) the emulator says which requests its
  /// board answers in time, and those must not miss the answer on a slow host.
  virtual FtReadStatus read_sample_waiting(FtSample& out, std::chrono::nanoseconds /*at_least*/) {
    return read_sample(out);
  }
  /// A snapshot of the counters (call from the thread that reads samples).
  virtual FtCounters counters() const = 0;
};

}  // namespace zerog::rtio
