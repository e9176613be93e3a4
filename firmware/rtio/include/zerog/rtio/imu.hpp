#pragma once
// An IMU as the loop sees it. Real: Stim300Imu (Sensonor STIM300 on a serial port); fake:
// FakeImu (scripted results; zerog/rtio/fake_imu.hpp in zerog::rtio_fakes, which only tests and
// the emulators link).
#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>

#include "zerog/samples/sensor_samples.hpp"

namespace zerog::rtio {

using samples::ImuSample;  ///< zerog/samples/sensor_samples.hpp (the loop's too)

enum class ImuStartStatus : std::uint8_t {
  ok,
  open_failed,  ///< no such tty, permission, busy
  bad_config,   ///< not a tty, unsupported baud rate, termios refused
};
const char* imu_start_status_name(ImuStartStatus status);

enum class ImuReadStatus : std::uint8_t {
  sample,        ///< `out` holds a new sample; check the *_valid flags
  timeout,       ///< no complete datagram in time (counted)
  disconnected,  ///< the device hung up (unplugged); call start() again outside the cycle
  io_error,      ///< a read error (counted)
  not_started,
  drained,  ///< read_sample_upto: the bytes asked for are read and complete no further sample
};
const char* imu_read_status_name(ImuReadStatus status);

struct ImuCounters {
  std::uint64_t samples = 0;          ///< good datagrams returned
  std::uint64_t invalid_samples = 0;  ///< … with any status bit set
  std::uint64_t bytes_read = 0;
  std::uint64_t bytes_skipped = 0;     ///< garbage skipped while (re)synchronising
  std::uint64_t crc_failures = 0;      ///< bad CRC where a datagram was due
  std::uint64_t sync_losses = 0;       ///< in sync, then not a good datagram
  std::uint64_t counter_gaps = 0;      ///< times the counter jumped
  std::uint64_t datagrams_missed = 0;  ///< sum of the jumps
  std::uint64_t timeouts = 0;
  std::uint64_t disconnects = 0;
  std::uint64_t io_errors = 0;
};

class Imu {
 public:
  virtual ~Imu() = default;
  /// Opens the device. Not real-time safe. Call again to recover after `disconnected`.
  virtual ImuStartStatus start() = 0;
  /// The next sample, waiting at most the device's configured read timeout. Real-time safe: no
  /// allocation, no exceptions, no locks.
  virtual ImuReadStatus read_sample(ImuSample& out) = 0;
  /// The next sample if the bytes already read from the device complete one; never waits and
  /// never reads the device (lockstep drains with it, proto/lockstep.md). Real-time safe.
  virtual bool pop_buffered(ImuSample& /*out*/) { return false; }
  /// Lockstep: the next sample from the device's bytes up to byte `bytes_limit` (counted as
  /// counters().bytes_read), waiting up to `timeout` for them; `drained` once they are read and
  /// complete no further sample. Never reads past the limit. Real-time safe.
  virtual ImuReadStatus read_sample_upto(ImuSample& out, std::uint64_t /*bytes_limit*/,
                                         std::chrono::nanoseconds /*timeout*/) {
    return read_sample(out);
  }
  /// A snapshot of the counters (call from the thread that reads samples).
  virtual ImuCounters counters() const = 0;
};

}  // namespace zerog::rtio
